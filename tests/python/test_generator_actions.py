"""Actions (.haction): the model an action stands for, its identity, describe, and the C++, Python
and IDL that horus-gen writes for it (tests/schemas/test_actions/navigate.haction)."""
from __future__ import annotations

import hashlib
import json
import subprocess

import pytest

from generator_testing import ROOT, SCHEMAS, run_horus_gen
from horus_gen.diagnostics import Reporter
from horus_gen.loader import Options
from horus_gen.model import FixedArray, FixedString, Primitive
from horus_gen.resolve import Resolver

NAVIGATE = SCHEMAS / "test_actions" / "navigate.haction"
PACKAGE = "horus_test.action"
OWNED = ["Goal", "Result", "Feedback", "SendGoalRequest", "SendGoalResponse", "SendGoal", "CancelGoalRequest",
         "CancelGoalResponse", "CancelGoal", "GetResultRequest", "ResultMessage", "GetResult", "FeedbackMessage",
         "Status"]


def resolve(*files: str, includes=()):
    reporter = Reporter()
    model = Resolver(reporter, Options(list(includes), None)).run(list(files))
    return model, reporter


@pytest.fixture(scope="module")
def model():
    found, reporter = resolve(str(NAVIGATE))
    assert not reporter.has_errors, reporter.render()
    return found


@pytest.fixture(scope="module")
def generated(tmp_path_factory):
    out = tmp_path_factory.mktemp("actions")
    result = run_horus_gen("generate", "--lang", "cpp,python,idl", "--out", str(out), str(NAVIGATE))
    assert result.returncode == 0, result.stderr
    return out


def test_an_action_is_ordinary_messages_and_services_generated_in_order(model):
    names = [q.rsplit(".", 1)[1] for q in model.generated]
    assert names[:15] == [f"Navigate{s}" for s in OWNED] + ["Navigate"]
    action = model.actions[f"{PACKAGE}.Navigate"]
    assert (action.goal.name, action.result.name, action.feedback.name) == ("NavigateGoal", "NavigateResult",
                                                                          "NavigateFeedback")
    assert [s.wire_name for s in action.services] == ["Navigate.send_goal", "Navigate.cancel_goal",
                                                       "Navigate.get_result"]
    assert action.get_result.response is action.result_message
    assert [t for t, _ in action.topics] == ["Navigate.feedback", "Navigate.status", "Navigate.result"]
    assert action.docs == ("Drive to a point; the feedback is the distance left.",)
    for suffix in OWNED:
        owned = model.types.get(f"{PACKAGE}.Navigate{suffix}") or model.services[f"{PACKAGE}.Navigate{suffix}"]
        assert owned.action == f"{PACKAGE}.Navigate", suffix
    assert model.types[f"{PACKAGE}.NavigateSendGoalRequest"].service == f"{PACKAGE}.NavigateSendGoal"
    assert model.types[f"{PACKAGE}.NavigateResultMessage"].service is None  # a topic's message too
    plain = model.services[f"{PACKAGE}.NavigateSendGoal"]
    assert (plain.request_topic, plain.response_topic) == ("Navigate.send_goal.request", "Navigate.send_goal.response")


def test_wrappers_carry_the_goal_id_state_stamp_and_reason(model):
    status = model.message(f"{PACKAGE}.NavigateStatus")
    assert [(f.name, f.type) for f in status.fields] == [
        ("goal_id", FixedArray(Primitive("u8", 1), 16)), ("state", Primitive("u8", 1)),
        ("stamp_ns", Primitive("u64", 8)), ("reason", FixedString(192))]
    response = model.message(f"{PACKAGE}.NavigateSendGoalResponse")
    assert [f.name for f in response.fields] == ["accepted", "stamp_ns", "reason"]
    cancel = model.message(f"{PACKAGE}.NavigateCancelGoalResponse")
    assert [f.spelling for f in cancel.fields] == ["u8", "u32"]
    result = model.message(f"{PACKAGE}.NavigateResultMessage")
    assert [f.name for f in result.fields] == ["goal_id", "state", "stamp_ns", "reason", "result"]
    # POD when their blocks are; the status and the cancel service never hold a block.
    assert all(model.message(f"{PACKAGE}.Navigate{s}").is_pod for s in ("SendGoalRequest", "ResultMessage",
                                                                        "FeedbackMessage"))
    assert not model.message(f"{PACKAGE}.EchoSendGoalRequest").is_pod
    assert model.message(f"{PACKAGE}.EchoStatus").is_pod and model.message(f"{PACKAGE}.EchoCancelGoalRequest").is_pod


def test_the_fingerprint_is_that_of_the_three_blocks(model):
    action = model.actions[f"{PACKAGE}.Navigate"]
    text = "".join(f"  {role}: {m.qualified}#{m.fingerprint:016x},\n"
                   for role, m in (("goal", action.goal), ("result", action.result), ("feedback", action.feedback)))
    canonical = f"action {PACKAGE}.Navigate {{\n{text}}}\n"
    assert action.fingerprint == int.from_bytes(hashlib.sha256(canonical.encode()).digest()[:8], "big")
    # Pinned: a change here changes what every running client and server of the action agrees on.
    assert action.fingerprint == 0x9e067099eb5084f1
    assert action.goal.fingerprint == 0xf4744b83cba4fef7
    assert model.services[f"{PACKAGE}.NavigateSendGoal"].fingerprint == 0x46737b36ac98a28b


def test_block_docs_and_attributes_go_to_the_blocks_message(tmp_path):
    path = tmp_path / "dock.haction"
    path.write_text("package p;\nDock {\n  /// Where to dock.\n  #[summary = \"station {self.station}\"]\n"
                    "  goal { station: u32 }\n  feedback { }\n  result { }\n}\n")
    found, reporter = resolve(str(path))
    assert not reporter.has_errors, reporter.render()
    goal = found.message("p.DockGoal")
    assert goal.docs == ("Where to dock.",) and goal.summary
    assert found.message("p.DockFeedback").fields == ()


def test_the_macro_form_and_an_import_of_an_action(tmp_path):
    (tmp_path / "dock.haction").write_text("package p;\naction! { Dock { goal { } result { ok: bool } feedback { } } }\n")
    (tmp_path / "uses.hmsg").write_text('package p;\nimport "dock.haction";\nLast { result: DockResult }\n')
    found, reporter = resolve(str(tmp_path / "uses.hmsg"))
    assert not reporter.has_errors, reporter.render()
    assert found.generated == ["p.Last"] and "p.Dock" in found.actions


def test_topic_is_refused_on_a_block(tmp_path):
    # A block travels on the action's own topics and services, never on one of its own.
    path = tmp_path / "dock.haction"
    path.write_text("package p;\nDock { #[topic = \"x\"] goal { } result { } feedback { } }\n")
    _, reporter = resolve(str(path))
    assert "error: unknown attribute 'topic' on 'DockGoal'" in reporter.render()


def test_describe_lists_the_owned_entries_then_the_action(model):
    result = run_horus_gen("describe", str(NAVIGATE))
    assert result.returncode == 0, result.stderr
    assert ("horus_test.action.Navigate  action  goal horus_test.action.NavigateGoal  result "
            "horus_test.action.NavigateResult  feedback horus_test.action.NavigateFeedback  "
            "fingerprint 0x9e067099eb5084f1\n") in result.stdout
    assert "    service Navigate.send_goal: horus_test.action.NavigateSendGoal\n" in result.stdout
    assert "    topic Navigate.status: horus_test.action.NavigateStatus\n" in result.stdout
    assert result.stdout.index("NavigateStatus  message") < result.stdout.index("Navigate  action")


def test_describe_json_has_an_action_entry_and_marks_what_it_owns():
    result = run_horus_gen("describe", "--json", str(NAVIGATE))
    assert result.returncode == 0, result.stderr
    entries = {e["name"]: e for e in json.loads(result.stdout)["types"]}
    action = entries["horus_test.action.Navigate"]
    assert action == {
        "kind": "action", "name": "horus_test.action.Navigate", "package": PACKAGE,
        "fingerprint": "0x9e067099eb5084f1", "goal": "horus_test.action.NavigateGoal",
        "result": "horus_test.action.NavigateResult", "feedback": "horus_test.action.NavigateFeedback",
        "services": {"send_goal": {"name": "Navigate.send_goal", "type": "horus_test.action.NavigateSendGoal"},
                     "cancel_goal": {"name": "Navigate.cancel_goal", "type": "horus_test.action.NavigateCancelGoal"},
                     "get_result": {"name": "Navigate.get_result", "type": "horus_test.action.NavigateGetResult"}},
        "topics": {"feedback": {"name": "Navigate.feedback", "type": "horus_test.action.NavigateFeedbackMessage"},
                   "status": {"name": "Navigate.status", "type": "horus_test.action.NavigateStatus"},
                   "result": {"name": "Navigate.result", "type": "horus_test.action.NavigateResultMessage"}},
        "docs": ["Drive to a point; the feedback is the distance left."]}
    assert entries["horus_test.action.NavigateGoal"]["action"] == "horus_test.action.Navigate"
    send_goal = entries["horus_test.action.NavigateSendGoal"]
    assert send_goal["action"] == "horus_test.action.Navigate"
    assert send_goal["request_topic"] == "Navigate.send_goal.request"


def test_cpp_header_names_the_members_and_is_in_the_umbrella(generated):
    header = (generated / "cpp" / "horus_test" / "action" / "navigate.hpp").read_text()
    for line in ("struct Navigate {", "using Goal = NavigateGoal;", "using ResultMessage = NavigateResultMessage;",
                 'static constexpr ::std::string_view name() noexcept { return "Navigate"; }',
                 'static constexpr ::std::string_view feedback_topic() noexcept { return "Navigate.feedback"; }',
                 "static constexpr ::std::uint64_t fingerprint() noexcept { return 0x9e067099eb5084f1ULL; }"):
        assert line in header, line
    assert '#include "horus_test/action/navigate.hpp"' in (generated / "cpp" / "horus_test" / "action.hpp").read_text()
    service = (generated / "cpp" / "horus_test" / "action" / "navigate_get_result.hpp").read_text()
    assert 'name() noexcept { return "Navigate.get_result"; }' in service
    assert "using Response = NavigateResultMessage;" in service


def test_python_class_has_the_same_members(generated):
    code = ("import numpy, sys\nfrom horus_test.action import Navigate, Echo\n"
            "assert Navigate.Goal().feedback_count == 20 and Navigate.SendGoal.name == 'Navigate.send_goal'\n"
            "assert Navigate.SendGoal.request_topic == 'Navigate.send_goal.request'\n"
            "assert Navigate.GetResult.Response is Navigate.ResultMessage\n"
            "assert (Navigate.name, Navigate.type_name) == ('Navigate', 'horus_test.action.Navigate')\n"
            "assert (Navigate.feedback_topic, Navigate.status_topic, Navigate.result_topic) == "
            "('Navigate.feedback', 'Navigate.status', 'Navigate.result')\n"
            "assert Navigate.goal_type_name == 'horus_test.action.NavigateGoal'\n"
            "assert Navigate.fingerprint == 0x9e067099eb5084f1\n"
            "m = Echo.FeedbackMessage(goal_id=list(range(16)), feedback=Echo.Feedback(partial=['a']))\n"
            "assert Echo.FeedbackMessage.from_bytes(m.to_bytes()) == m\n"
            "r = Navigate.ResultMessage(state=4, reason='done')\n"
            "assert Navigate.ResultMessage.from_bytes(r.to_bytes()).reason == 'done'\n")
    result = subprocess.run(["/usr/bin/python3", "-c", code], cwd=generated / "python", capture_output=True, text=True)
    assert result.returncode == 0, result.stderr


def test_idl_has_ros2s_action_shapes(generated):
    idl = (generated / "idl" / "horus_test" / "action" / "navigate_action.idl").read_text()
    for line in ('#include "unique_identifier_msgs/msg/UUID.idl"', "struct Navigate_Goal_ {", "struct Navigate_Result_ {",
                 "struct Navigate_Feedback_ {", "struct Navigate_SendGoal_Request_ {",
                 "  ::unique_identifier_msgs::msg::dds_::UUID_ goal_id;",
                 "  ::horus_test::action::dds_::Navigate_Goal_ goal;",
                 "  ::builtin_interfaces::msg::dds_::Time_ stamp;", "  int8 status;",
                 "  ::horus_test::action::dds_::Navigate_Result_ result;", "struct Navigate_FeedbackMessage_ {",
                 "  ::horus_test::action::dds_::Navigate_Feedback_ feedback;"):
        assert line in idl, line
    assert (generated / "idl" / "horus_test" / "action" / "NavigateStatus.idl").is_file()


def test_idlc_compiles_the_action_idl(generated, tmp_path):
    idlc = subprocess.run(["which", "idlc"], capture_output=True, text=True).stdout.strip()
    if not idlc:
        pytest.fail("idlc (Debian cyclonedds-tools) is needed: run scripts/install-deps")
    # ROS 2's UUID as unique_identifier_msgs defines it (the DDS bridge keeps its own copy).
    uuid = tmp_path / "ros" / "unique_identifier_msgs" / "msg" / "UUID.idl"
    uuid.parent.mkdir(parents=True)
    uuid.write_text("module unique_identifier_msgs { module msg { module dds_ {\n"
                    "  @final struct UUID_ { uint8 uuid[16]; };\n}; }; };\n")
    roots = [str(generated / "idl"), str(tmp_path / "ros"), str(ROOT / "bridges" / "dds" / "ros2_idl")]
    source = generated / "idl" / "horus_test" / "action" / "navigate_action.idl"
    result = subprocess.run([idlc, *(a for r in roots for a in ("-I", r)), "-o", str(tmp_path), str(source)],
                            capture_output=True, text=True)
    assert result.returncode == 0, result.stderr
    header = (tmp_path / "navigate_action.h").read_text()
    assert "horus_test_action_dds__Navigate_SendGoal_Request_" in header


def test_an_action_named_like_a_member_of_its_type_is_refused(tmp_path):
    # C++ refuses `struct Status { using Status = StatusStatus; }`.
    path = tmp_path / "status.haction"
    path.write_text("package p;\nStatus { goal { } result { } feedback { } }\n")
    _, reporter = resolve(str(path))
    assert "error: action 'Status' is named like a member of the type generated for it" in reporter.render()


def test_a_qualified_name_finds_an_action_in_its_package_folder(tmp_path):
    (tmp_path / "robot" / "actions").mkdir(parents=True)
    (tmp_path / "robot" / "actions" / "dock.haction").write_text(
        "package robot.actions;\nDock { goal { } result { ok: bool } feedback { } }\n")
    (tmp_path / "uses.hmsg").write_text("package other;\nLast { result: robot::actions::DockResult }\n")
    found, reporter = resolve(str(tmp_path / "uses.hmsg"), includes=[str(tmp_path)])
    assert not reporter.has_errors, reporter.render()
    assert "robot.actions.Dock" in found.actions
