#!/usr/bin/python3
"""Builds examples/custom_messages against an installed horus, exactly as a user would.

    project_test.py installed --build HORUS_BUILD --source EXAMPLE --work DIR [--generator G]
        install horus into DIR/prefix, configure, build and run the example against it, check
        the installed horus-gen and the installation of the example's own generated code;
    project_test.py rebuild --build HORUS_BUILD --source EXAMPLE --work DIR [--generator G]
        in a copy of the example, check what each kind of edit regenerates and recompiles:
        comment-only schema edits, generator and template changes recompile nothing, a field
        added to the imported schema recompiles its users, unrelated files change nothing;
    project_test.py depends ... (same options)
        the same across two message libraries (tests/cmake/two_libraries, DEPENDS);
    project_test.py usage ... (same options)
        horus_generate() misused or given a wrong schema fails configuration with a clear error;
    project_test.py dds --build HORUS_BUILD --source tests/cmake/dds_program --work DIR ...
        a program whose scheduler calls network(), linking horus::dds from the installation,
        builds and starts the DDS bridge in its process;
    project_test.py view --build HORUS_BUILD --source tests/cmake/view_program --work DIR ...
        a program whose scheduler calls view(), linking horus::view from the installation,
        builds, says where its live view listens and serves the built-in page there.

Every check prints what it expected and what came; the exit status is 1 on the first failure.
"""
from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import time
import urllib.request
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "support"))
from dds_domains import claimed_domain  # noqa: E402  (tests/support, put on the path above)

PYTHON = "/usr/bin/python3"
TARGET = "demo_msgs"


class Failure(Exception):
    pass


def run(cmd: list, env: dict | None = None, check: bool = True) -> subprocess.CompletedProcess:
    proc = subprocess.run([str(c) for c in cmd], env=env, text=True, stdin=subprocess.DEVNULL,
                          stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    if check and proc.returncode != 0:
        raise Failure(f"command failed (exit {proc.returncode}): {' '.join(map(str, cmd))}\n"
                      f"{proc.stdout}")
    return proc


def expect(condition: bool, what: str, came: str = "") -> None:
    if not condition:
        raise Failure(f"expected {what}" + (f"\n--- came:\n{came}" if came else ""))
    print(f"ok: {what}")


def install_horus(horus_build: Path, prefix: Path) -> None:
    shutil.rmtree(prefix, ignore_errors=True)
    run(["cmake", "--install", horus_build, "--prefix", prefix])


def configure(source: Path, build: Path, prefix: Path, generator: str, *extra: str) -> str:
    return run(["cmake", "-S", source, "-B", build, "-G", generator,
                f"-DCMAKE_PREFIX_PATH={prefix}", "-DCMAKE_BUILD_TYPE=Debug", *extra]).stdout


def build(build_dir: Path, check: bool = True) -> subprocess.CompletedProcess:
    return run(["cmake", "--build", build_dir, "--parallel", str(os.cpu_count() or 2)],
               check=check)


def run_example(build_dir: Path, *expected: str) -> str:
    out = run([build_dir / "custom_messages"]).stdout
    for text in expected:
        expect(text in out, f"the example's output to contain {text!r}", out)
    expect("DIFFERENT" not in out, "every message to decode unchanged", out)
    return out


# ---------------------------------------------------------------------------------------------
def installed(args: argparse.Namespace) -> None:
    prefix = args.work / "prefix"
    install_horus(args.build, prefix)
    for path in ["lib/cmake/horus/horusConfig.cmake", "lib/cmake/horus/HorusGenerate.cmake",
                 "include/horus/message.hpp", "include/horus/msg.hpp", "lib/libhorus_msgs.a",
                 "bin/horus-gen",
                 "share/horus/generator/horus_gen/cli.py", "share/horus/templates/cpp",
                 "share/horus/python/_horus_gen_support_v1.py"]:
        expect((prefix / path).exists(), f"the installation to hold {path}")

    schemas = sorted((args.source / "msg").glob("*.hmsg"))
    checked = run([prefix / "bin/horus-gen", "check", "--package", "demo_robot.msg",
                   "-I", args.source / "msg", *schemas], check=False)
    expect(checked.returncode == 0, "the installed horus-gen to accept the example's schemas",
           checked.stdout)

    build_dir = args.work / "build"
    shutil.rmtree(build_dir, ignore_errors=True)
    configured = configure(args.source, build_dir, prefix, args.generator,
                           f"-DCMAKE_INSTALL_PREFIX={args.work / 'app-prefix'}")
    build(build_dir)
    run_example(build_dir, "demo_robot.msg.MotorFeedback", "demo_robot.msg.Pose2D",
                "demo_robot.msg.MotorStatus", "(padding)", "left_front")

    app_prefix = args.work / "app-prefix"
    shutil.rmtree(app_prefix, ignore_errors=True)
    run(["cmake", "--install", build_dir])
    expect((app_prefix / "include/demo_robot/msg/motor_feedback.hpp").is_file(),
           "the generated headers to install under include/")
    expect((app_prefix / "lib/libdemo_msgs.a").is_file(),
           "the library of the generated code to install under lib/")
    sources = sorted(str(p.relative_to(app_prefix)) for p in app_prefix.rglob("*.cpp"))
    expect(not sources, "no generated source to be installed", "\n".join(sources))
    if re.search(r"LANGUAGES[^)]*python", (args.source / "CMakeLists.txt").read_text()):
        check_python(configured, app_prefix)
    else:
        print("note: the example generates no Python: its Python package is not checked")


def dds(args: argparse.Namespace) -> None:
    prefix = args.work / "prefix"
    install_horus(args.build, prefix)
    for path in ["include/horus/dds_bridge.hpp", "include/horus/bridge/topic_policy.hpp",
                 "lib/libhorus_dds.a", "lib/libhorus_bridge_core.a",
                 "share/horus/dds/register_network_bridge.cpp"]:
        expect((prefix / path).exists(), f"the installation to hold {path}")
    build_dir = args.work / "build"
    shutil.rmtree(build_dir, ignore_errors=True)
    configure(args.source, build_dir, prefix, args.generator)
    build(build_dir)
    env = dict(os.environ, HORUS_NAMESPACE=f"dds_program_{os.getpid()}")
    # A domain of its own, so that no other test's DDS traffic is met.
    with claimed_domain() as domain:
        ran = run([build_dir / "dds_program", domain], env=env, check=False)
    expect(ran.returncode == 0, "the program to run its scheduler with the bridge", ran.stdout)
    expect(f"bridge on DDS domain {domain}: exporting ['dds_program_nothing']" in ran.stdout,
           "the bridge to start in the program's process (its first line)", ran.stdout)


def view(args: argparse.Namespace) -> None:
    prefix = args.work / "prefix"
    install_horus(args.build, prefix)
    for path in ["include/horus/live_view.hpp", "include/horus/live_view_options.hpp",
                 "lib/libhorus_view.a", "lib/libhorus_view_codecs.a",
                 "share/horus/view/register_scheduler_view.cpp"]:
        expect((prefix / path).exists(), f"the installation to hold {path}")
    build_dir = args.work / "build"
    shutil.rmtree(build_dir, ignore_errors=True)
    configure(args.source, build_dir, prefix, args.generator)
    build(build_dir)
    env = dict(os.environ, HORUS_NAMESPACE=f"view_program_{os.getpid()}")
    program = subprocess.Popen([build_dir / "view_program"], env=env, text=True,
                               stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT)
    try:
        line = program.stdout.readline().strip()
        found = re.fullmatch(r"live view: ws://127\.0\.0\.1:(\d+)/", line)
        expect(found is not None, "the program to say where its live view listens "
               "('live view: ws://127.0.0.1:PORT/')", line)
        with urllib.request.urlopen(f"http://127.0.0.1:{found.group(1)}/", timeout=10) as reply:
            page = reply.read().decode()
        expect("<title>HORUS live view</title>" in page,
               "an HTTP GET of / to return the built-in page", page[:500])
    finally:
        program.terminate()
        out, _ = program.communicate(timeout=30)
    expect(program.returncode == 0, "the program to stop on SIGTERM with status 0",
           f"status {program.returncode}\n{out}")


def check_python(configured: str, app_prefix: Path) -> None:
    """The example prints ${demo_msgs_PYTHON_DIR} when it configures."""
    found = re.search(r"PYTHONPATH=(\S+)", configured)
    expect(found is not None, "the example to print its <TARGET>_PYTHON_DIR", configured)
    version = run([PYTHON, "-c", "import sys; print('%d.%d' % sys.version_info[:2])"]).stdout
    python_install = app_prefix / "lib" / f"python{version.strip()}" / "dist-packages"
    script = ("from demo_robot.msg import MotorFeedback as M\n"
              "print(M.__horus__.name, M.from_bytes(M(motor_id=2).to_bytes()).motor_id)")
    for where, path in [("<TARGET>_PYTHON_DIR", found.group(1)),
                        (str(python_install.relative_to(app_prefix)), str(python_install))]:
        imported = run([PYTHON, "-c", script], env={**os.environ, "PYTHONPATH": path}, check=False)
        expect(imported.returncode == 0 and "demo_robot.msg.MotorFeedback 2" in imported.stdout,
               f"the generated Python package to work from {where}", imported.stdout)


# ---------------------------------------------------------------------------------------------
def mtimes(root: Path, pattern: str) -> dict[Path, int]:
    return {p: p.stat().st_mtime_ns for p in root.rglob(pattern) if p.is_file()}


class Project:
    """A copy of a project with its own horus installation, so that touching the installed
    generator and templates disturbs no other test."""

    def __init__(self, args: argparse.Namespace, source: Path, targets: list[str]) -> None:
        self.root = args.work
        shutil.rmtree(self.root, ignore_errors=True)
        self.prefix = self.root / "prefix"
        install_horus(args.build, self.prefix)
        self.source = self.root / "project"
        shutil.copytree(source, self.source)
        self.build_dir = self.root / "build"
        self.generated = self.build_dir / "horus_gen"
        self.stamps = {t: self.generated / f"{t}.stamp" for t in targets}
        configure(self.source, self.build_dir, self.prefix, args.generator)

    def snapshot(self) -> dict[str, dict]:
        return {"objects": mtimes(self.build_dir, "*.o"), "generated": mtimes(self.generated, "*"),
                "stamps": {t: p.stat().st_mtime_ns for t, p in self.stamps.items()}}

    def rebuild(self, step: str, *, generated: set[str], recompiled: set[str],
                rewritten: bool) -> None:
        """Builds, then checks which targets horus-gen ran for, which objects were recompiled (by
        source file name) and whether any generated file was rewritten."""
        print(f"--- {step}")
        before = self.snapshot()
        out = build(self.build_dir).stdout
        after = self.snapshot()
        ran = {t for t in self.stamps if before["stamps"][t] != after["stamps"][t]}
        expect(ran == generated, f"horus-gen to run for {sorted(generated) or 'no target'}, "
               f"ran for {sorted(ran) or 'none'}", out)
        changed = {p.name.removesuffix(".o") for p, t in after["objects"].items()
                   if before["objects"].get(p) != t}
        expect(changed == recompiled, f"recompiled objects to be {sorted(recompiled) or 'none'}, "
               f"were {sorted(changed) or 'none'}", out)
        touched = sorted(str(p.relative_to(self.generated)) for p, t in after["generated"].items()
                         if before["generated"].get(p) != t and p.suffix != ".stamp")
        expect(bool(touched) == rewritten, f"generated files {'to be' if rewritten else 'not to be'}"
               f" rewritten (rewritten: {touched})", out)

    def expect_no_work(self, generator: str) -> None:
        """Ninja's own verdict on an unchanged tree: nothing to run, and nothing it would explain
        as dirty (a depfile entry that never exists, an output older than its inputs)."""
        if generator != "Ninja":
            return
        dry = run(["ninja", "-C", self.build_dir, "-n", "-d", "explain"], check=False)
        expect(dry.returncode == 0 and "ninja: no work to do." in dry.stdout and "ninja explain" not in dry.stdout,
               "a second build with nothing changed to do no work", dry.stdout)

    def edit(self, relative: str, old: str, new: str) -> None:
        path = self.source / relative
        text = path.read_text()
        if old not in text:
            raise Failure(f"test set-up: {old!r} not found in {path}")
        path.write_text(text.replace(old, new, 1))
        self.touch(path)

    def touch(self, path: Path) -> None:
        """Marks `path` changed, strictly after everything the last build wrote. File times come
        from the kernel's coarse clock (several ms per step), so a change made right after a
        build can carry the very time of its outputs, and Ninja and Make see nothing to do."""
        snapshot = self.snapshot()
        newest = max([0, *snapshot["objects"].values(), *snapshot["stamps"].values()])
        when = max(time.time_ns(), newest + 10_000_000)
        os.utime(path, ns=(when, when))


def rebuild(args: argparse.Namespace) -> None:
    p = Project(args, args.source, [TARGET])
    everything = {TARGET}
    print("--- first build")
    build(p.build_dir)
    run_example(p.build_dir, "demo_robot.msg.Pose2D")

    p.rebuild("nothing changed", generated=set(), recompiled=set(), rewritten=False)
    p.expect_no_work(args.generator)

    (p.source / "notes.txt").write_text("a file no target uses\n")
    p.touch(p.source / "CMakeLists.txt")
    p.rebuild("unrelated file added, CMakeLists.txt touched", generated=set(), recompiled=set(),
              rewritten=False)

    p.touch(p.source / "main.cpp")
    p.rebuild("main.cpp touched", generated=set(), recompiled={"main.cpp"}, rewritten=False)

    p.edit("msg/geometry.hmsg", "// Geometry shared", "// Planar geometry shared")
    p.edit("msg/motor.hmsg", "/// How the motor",
           "// The enum below is used by MotorFeedback.\n/// How the motor")
    p.rebuild("comments edited in both schemas", generated=everything, recompiled=set(),
              rewritten=False)

    for changed in [next((p.prefix / "share/horus/templates").rglob("*.j2"), None),
                    p.prefix / "share/horus/generator/horus_gen/model.py"]:
        expect(changed is not None and changed.is_file(),
               f"an installed generator file to touch ({changed})")
        p.touch(changed)
        p.rebuild(f"{changed.relative_to(p.prefix)} touched", generated=everything,
                  recompiled=set(), rewritten=False)

    p.edit("msg/geometry.hmsg", "    theta: f64,\n", "    theta: f64,\n    stamp_ns: u64,\n")
    # The library's one source is the package's (demo_robot/msg.cpp): it and the program that
    # includes the changed header recompile.
    p.rebuild("field added to the imported schema", generated=everything,
              recompiled={"main.cpp", "msg.cpp"}, rewritten=True)
    run_example(p.build_dir, "stamp_ns")

    print("--- schema error")
    before = p.snapshot()
    p.edit("msg/geometry.hmsg", "stamp_ns: u64,", "stamp_ns: u64\n    broken: f63,")
    failed = build(p.build_dir, check=False)
    expect(failed.returncode != 0, "the build to fail on a schema error", failed.stdout)
    expect("geometry.hmsg:" in failed.stdout and "error:" in failed.stdout,
           "the error to name the schema file", failed.stdout)
    expect(p.snapshot()["generated"] == before["generated"],
           "a failed generation to leave the generated files alone")
    p.edit("msg/geometry.hmsg", "stamp_ns: u64\n    broken: f63,", "stamp_ns: u64,")
    p.rebuild("schema error fixed", generated=everything, recompiled=set(), rewritten=False)

    p.edit("msg/motor.hmsg", "/// A motor's health",
           "MotorLimits {\n    max_current: f32,\n}\n\n/// A motor's health")
    p.rebuild("message added", generated=everything, recompiled={"main.cpp", "msg.cpp"},
              rewritten=True)
    expect((p.generated / TARGET / "cpp/demo_robot/msg/motor_limits.hpp").is_file(),
           "a header for the added message")


def depends(args: argparse.Namespace) -> None:
    """base_msgs and app_msgs (DEPENDS base_msgs, using robot_base::Point by qualified name)."""
    source = Path(__file__).resolve().parent / "two_libraries"
    p = Project(args, source, ["base_msgs", "app_msgs"])
    print("--- first build")
    build(p.build_dir)
    out = run([p.build_dir / "route_main"]).stdout
    expect("goal: Point{x: 0 m, y: 4 m}" in out, "route_main to print the nested points", out)
    expect("start_pose: Pose2D{" in out, "route_main to print the standard library's Pose2D", out)

    p.rebuild("nothing changed", generated=set(), recompiled=set(), rewritten=False)
    p.expect_no_work(args.generator)

    p.edit("schemas/robot_base/point.hmsg", "// A point", "// A 2-D point")
    p.rebuild("comment edited in the depended-on schema", generated={"base_msgs", "app_msgs"},
              recompiled=set(), rewritten=False)

    p.edit("schemas/robot_app/route.hmsg", "    speed: f32,\n", "    speed: f32,\n    lane: u8,\n")
    p.rebuild("field added to the depending schema", generated={"app_msgs"},
              recompiled={"route_main.cpp", "robot_app.cpp"}, rewritten=True)

    p.edit("schemas/robot_base/point.hmsg", "    y: f64,\n", "    y: f64,\n    z: f64,\n")
    p.rebuild("field added to the depended-on schema", generated={"base_msgs", "app_msgs"},
              recompiled={"base_main.cpp", "route_main.cpp", "robot_base.cpp", "robot_app.cpp"},
              rewritten=True)
    out = run([p.build_dir / "route_main"]).stdout
    expect("z: 0" in out, "route_main to print the new field of robot_base::Point", out)


def usage(args: argparse.Namespace) -> None:
    """horus_generate() misused, or given a wrong schema: configuration fails with a message that
    says what is wrong and where."""
    shutil.rmtree(args.work, ignore_errors=True)
    prefix = args.work / "prefix"
    install_horus(args.build, prefix)
    source = args.work / "project"
    (source / "msg").mkdir(parents=True)
    (source / "msg/good.hmsg").write_text("Good {\n    value: u32,\n}\n")
    (source / "msg/bad.hmsg").write_text("Bad {\n    value: u32,\n    speed: f63,\n}\n")
    cases = [
        ("FILES msg/good.hmsg LANGUAGES cpp python", None),
        ("FILES msg/missing.hmsg", "schema file 'msg/missing.hmsg' not found"),
        ("FILES msg/good.hmsg LANGUAGES rust", "unknown language 'rust'"),
        ("BOGUS FILES msg/good.hmsg", "unknown arguments: BOGUS"),
        ("FILES msg/good.hmsg LANGAUGES cpp", "is 'LANGAUGES' a misspelled keyword?"),
        ("FILES msg/good.hmsg INCLUDE_DIRS nowhere", "include directory 'nowhere' not found"),
        ("FILES msg/good.hmsg DEPENDS Threads::Threads",
         "DEPENDS 'Threads::Threads' was not made by horus_generate()"),
        ("FILES msg/bad.hmsg", "bad.hmsg:3:12: error: unknown type 'f63'"),
    ]
    for arguments, error in cases:
        (source / "CMakeLists.txt").write_text(
            "cmake_minimum_required(VERSION 3.22)\nproject(usage LANGUAGES CXX)\n"
            "find_package(horus CONFIG REQUIRED)\n"
            f"horus_generate(TARGET my_msgs PACKAGE my_robot.msg {arguments})\n"
            "get_target_property(property my_msgs HORUS_PYTHON_DIR)\n"
            'message(STATUS "python: ${property} ${my_msgs_PYTHON_DIR}")\n')
        proc = run(["cmake", "-S", source, "-B", args.work / "build", "-G", args.generator,
                    f"-DCMAKE_PREFIX_PATH={prefix}"], check=False)
        if error is None:
            expect(proc.returncode == 0, f"horus_generate({arguments}) to configure", proc.stdout)
            found = re.search(r"python: (\S+) (\S+)", proc.stdout)
            expect(found is not None and found.group(1) == found.group(2)
                   and found.group(1).endswith("/horus_gen/my_msgs/python"),
                   "HORUS_PYTHON_DIR and my_msgs_PYTHON_DIR to name the Python folder", proc.stdout)
        else:
            unwrapped = " ".join(proc.stdout.split())  # CMake wraps its messages
            expect(proc.returncode != 0 and error in unwrapped,
                   f"horus_generate({arguments}) to fail with {error!r}", proc.stdout)

    # LANGUAGES jsonschema idl: the build writes each message's JSON Schema into the folder that the
    # target property HORUS_JSONSCHEMA_DIR names, and its IDL under the include root that the target
    # property HORUS_IDL_DIR and the variable <TARGET>_IDL_DIR name.
    shutil.rmtree(args.work / "build", ignore_errors=True)
    (source / "CMakeLists.txt").write_text(
        "cmake_minimum_required(VERSION 3.22)\nproject(usage LANGUAGES CXX)\n"
        "find_package(horus CONFIG REQUIRED)\n"
        "horus_generate(TARGET my_msgs PACKAGE my_robot.msg FILES msg/good.hmsg "
        "LANGUAGES jsonschema idl)\n"
        "get_target_property(property my_msgs HORUS_JSONSCHEMA_DIR)\n"
        'message(STATUS "jsonschema: ${property}")\n'
        "get_target_property(property my_msgs HORUS_IDL_DIR)\n"
        'message(STATUS "idl: ${property} ${my_msgs_IDL_DIR}")\n')
    configured = configure(source, args.work / "build", prefix, args.generator)
    build(args.work / "build")
    found = re.search(r"jsonschema: (\S+)", configured)
    expect(found is not None, "HORUS_JSONSCHEMA_DIR to be set", configured)
    schema = Path(found.group(1)) / "my_robot" / "msg" / "Good.schema.json"
    expect(schema.is_file() and json.loads(schema.read_text())["title"] == "my_robot.msg.Good",
           f"{schema} to hold the JSON Schema of my_robot.msg.Good")
    found = re.search(r"idl: (\S+) (\S+)", configured)
    expect(found is not None and found.group(1) == found.group(2),
           "HORUS_IDL_DIR and my_msgs_IDL_DIR to name the IDL folder", configured)
    idl = Path(found.group(1)) / "my_robot" / "msg" / "Good.idl"
    expect(idl.is_file() and "struct Good_ {" in idl.read_text(),
           f"{idl} to hold the IDL of my_robot.msg.Good (my_robot::msg::dds_::Good_)")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("mode", choices=["installed", "rebuild", "depends", "usage", "dds",
                                         "view"])
    parser.add_argument("--build", type=Path, required=True, help="the horus build folder")
    parser.add_argument("--source", type=Path, required=True, help="examples/custom_messages")
    parser.add_argument("--work", type=Path, required=True, help="scratch folder (emptied)")
    parser.add_argument("--generator", default="Ninja", help="CMake generator for the project")
    args = parser.parse_args()
    args.work.mkdir(parents=True, exist_ok=True)
    try:
        modes = {"installed": installed, "rebuild": rebuild, "depends": depends, "usage": usage,
                 "dds": dds, "view": view}
        modes[args.mode](args)
    except Failure as failure:
        print(f"FAILED: {failure}", file=sys.stderr)
        return 1
    print("passed")
    return 0


if __name__ == "__main__":
    sys.exit(main())
