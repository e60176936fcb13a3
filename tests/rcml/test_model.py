"""The RCML model: paths, canonical order, effective permission, and the two walks agreeing."""

from __future__ import annotations

import random

from hypothesis import given
from hypothesis import strategies as st
from support.xml_vectors import XML_VECTORS

from rcmlconf.markup.document import XmlDocument, parse_document
from rcmlconf.markup.structure import Checker
from rcmlconf.rcml.loader import RcmlWalk, load_rcml
from rcmlconf.rcml.model import (
    AccessNode,
    AccessType,
    DataNode,
    GroupNode,
    Permission,
    RcmlDocument,
)
from rcmlconf.rcml.schema import ELEMENTS


def load(text: str) -> RcmlDocument:
    document = parse_document(text.encode())
    assert isinstance(document, XmlDocument)
    checker = Checker(document, "t.rcml", ELEMENTS)
    model = load_rcml(checker)
    assert model is not None, [d.to_text() for d in checker.diagnostics()]
    return model


def load_testbot() -> RcmlDocument:
    return load((XML_VECTORS / "valid" / "testbot.rcml").read_text())


def test_paths_types_and_permissions() -> None:
    bot = load_testbot()
    left = bot.node("/drive/wheels/left")
    assert isinstance(left, DataNode)
    assert str(left.type) == "float32"
    assert (left.minimum, left.maximum) == (-1.5, 1.5)
    assert left.permission == Permission.READ | Permission.WRITE
    assert left.meta[0].content == "m/s"
    odometry = bot.node("/drive/wheels/odometry")
    assert isinstance(odometry, DataNode)
    assert odometry.permission == Permission.READ
    assert str(odometry.type) == "float64[3]"
    label = bot.node("/drive/settings/label")
    assert isinstance(label, DataNode)
    assert str(label.type) == "string(32)"
    assert bot.node("/sensors/bumpers/front").permission == Permission.READ
    assert bot.node("/head/control/pose").permission == Permission.NONE


def test_access_defaults_and_directions() -> None:
    bot = load_testbot()
    wheels = bot.node("/drive/wheels")
    assert isinstance(wheels, AccessNode)
    assert wheels.type is AccessType.STREAM
    assert (wheels.read_interval, wheels.write_interval) == (0.02, 0.02)
    assert [d.name for d in wheels.writable()] == ["left", "right"]
    assert [d.name for d in wheels.readable()] == ["left", "odometry", "right"]
    control = bot.node("/head/control")
    assert isinstance(control, AccessNode)
    assert control.type is AccessType.NORMAL
    assert (control.read_timeout, control.write_timeout) == (10.0, 10.0)


def test_root_attributes() -> None:
    bot = load_testbot()
    assert (bot.site.host, bot.site.port, bot.site.path) == ("testbot.example", 5000, "/")
    assert (bot.time_source, bot.time_precision) == ("NTP", 1e-3)
    assert [link.kind for link in bot.links] == ["UserInterface", "Documentation"]


def test_the_top_grants_read_and_write() -> None:
    model = load(
        '<rcml version="2.0" site="rctp://r">'
        '<access name="a"><data name="d" type="bool"/></access></rcml>'
    )
    assert model.node("/a/d").permission == Permission.READ | Permission.WRITE


def test_sibling_order_means_nothing() -> None:
    """R-RCML-29: documents differing only in sibling order make equal models."""
    source = (XML_VECTORS / "valid" / "testbot.rcml").read_text()
    first = load(source)
    lines = source.splitlines()
    start = next(i for i, line in enumerate(lines) if '<data name="tilt"' in line)
    block = lines[start : start + 10]
    shuffled = block[:]
    random.Random(7).shuffle(shuffled)
    second = load("\n".join(lines[:start] + shuffled + lines[start + 10 :]))
    assert shuffled != block
    assert second.children == first.children
    control = second.node("/head/control")
    assert isinstance(control, AccessNode)
    assert [d.name for d in control.data] == sorted(d.name for d in control.data)


def test_groups_hold_their_children_in_canonical_order() -> None:
    model = load(
        '<rcml version="2.0" site="rctp://r"><group name="b"/><group name="a"/>'
        '<access name="B"/><group name="ä"/></rcml>'
    )
    assert [child.name for child in model.children] == ["B", "a", "b", "ä"]
    assert all(isinstance(child, GroupNode | AccessNode) for child in model.children)


# -- the fast path for plain data nodes builds what the element-by-element path builds ----------

names = st.from_regex(r"[A-Za-z_][A-Za-z0-9_.-]{0,12}", fullmatch=True)
plain_data = st.fixed_dictionaries(
    {"name": names},
    optional={
        "type": st.sampled_from(
            ["int", "float", "bool", "uint8", "string", "bytes", "double", "x"]
        ),
        "count": st.sampled_from(["1", "3", "0", "+2", "70000"]),
        "size": st.sampled_from(["1", "16", "0"]),
        "permission": st.sampled_from(["r", "w", "rw", "none", "x"]),
        "min": st.sampled_from(["-1", "0", "1.5", "300", "INF", "x"]),
        "max": st.sampled_from(["-1", "0", "10", "1e3", "NaN"]),
    },
)


@given(st.lists(plain_data, max_size=8), st.sampled_from(["r", "w", "rw", "none"]))
def test_fast_path_agrees_with_the_element_walk(
    elements: list[dict[str, str]], ceiling: str
) -> None:
    body = "".join("<data " + " ".join(f'{k}="{v}"' for k, v in e.items()) + "/>" for e in elements)
    document = parse_document(
        f'<rcml version="2.0" site="rctp://r"><access name="a">{body}</access></rcml>'.encode()
    )
    assert isinstance(document, XmlDocument)
    access = document.root.children[0]
    checker = Checker(document, "t.rcml", ELEMENTS)
    walk = RcmlWalk(checker, None)
    inherited = Permission.from_text(ceiling)
    fast = walk._plain_data(access.children, "/a", inherited)
    names_seen: set[str] = set()
    slow = [walk._data(e, "/a", inherited, names_seen) for e in access.children]
    if fast is not None:  # accepted: the element walk finds nothing wrong and builds the same
        assert checker.error_count == 0
        assert fast == slow
    else:  # declined: only ever because something is wrong (the names here are all ASCII)
        assert checker.error_count > 0
