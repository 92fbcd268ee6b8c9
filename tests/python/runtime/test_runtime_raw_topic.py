"""The type description a topic segment stores beside the schema: written from the generated
class's `__horus__["description"]` when a Python handle creates the topic, given as bytes to a
handle opened by identity (`horus.introspection.open_topic`), and listed by `list_topics`."""
from __future__ import annotations

import horus
from horus import introspection
from horus.msg import CmdVel


def _listed(name: str) -> dict:
    return {t["name"]: t for t in introspection.list_topics()}[name]


def _description_of(message_class) -> bytes:
    # Classes generated before type descriptions carry none: the segment then stores none.
    return getattr(message_class.__horus__, "description", None) or b""


def test_a_typed_topic_stores_its_classes_description_beside_the_schema():
    topic = horus.Topic(CmdVel, "cmd_vel")
    listed = _listed("cmd_vel")
    assert listed["schema"] == CmdVel.__horus__.schema
    assert listed["description"] == _description_of(CmdVel)
    assert isinstance(listed["description"], bytes)
    del topic


def test_a_handle_opened_by_identity_stores_the_description_bytes_it_is_given():
    meta = CmdVel.__horus__
    description = b"\x81\xa4root\xa8any\x00text"
    topic = introspection.open_topic("by_identity", meta.name, meta.fingerprint, meta.schema, True,
                                     meta.size, meta.alignment, 8, 0, False, description)
    assert _listed("by_identity")["description"] == description
    assert topic.send(CmdVel(linear=1.0).to_bytes())


def test_a_handle_opened_without_a_description_lists_an_empty_one():
    meta = CmdVel.__horus__
    topic = introspection.open_topic("undescribed", meta.name, meta.fingerprint, meta.schema, True,
                                     meta.size, meta.alignment, 8, 0, False)
    assert _listed("undescribed")["description"] == b""
    del topic


def test_a_later_opener_adopts_the_description_the_creator_stored():
    meta = CmdVel.__horus__
    creator = introspection.open_topic("adopted", meta.name, meta.fingerprint, meta.schema, True,
                                       meta.size, meta.alignment, 8, 0, False, b"\x90first")
    later = horus.Topic(CmdVel, "adopted")
    assert _listed("adopted")["description"] == b"\x90first"
    del creator, later
