"""The simulated robots: valid values at any time, exact change reports, and their physics."""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Literal

import pytest
from hypothesis import given
from hypothesis import strategies as st
from support.robots import CAMERA, ROVER, TESTBOT, robot
from support.xml_vectors import XML_VECTORS

from rcmlconf.errors import RcmlconfError
from rcmlconf.rcml.model import DataNode, Permission, RcmlDocument
from rcmlconf.reference.drivers import DRIVERS, DriverError, choose_driver
from rcmlconf.reference.drivers.nodes import bounds
from rcmlconf.reference.drivers.rover import BODY_RADIUS, CONTACT
from rcmlconf.reference.drivers.wander import ITEMS_PER_ADVANCE
from rcmlconf.validate.validator import Validator, load_robot
from rcmlconf.values import Kind, Scalar, Value
from rcmlconf.values.binary import decode_value, encode_value

T0 = 1_700_000_000.0
HOURS_10 = 36_000.0
#: Seconds after T0: small steps, a repeated time, and a jump of ten hours.
OFFSETS = (0.0, 0.02, 0.04, 0.5, 1.0, 3.0, 3.0, 7.5, 60.0, HOURS_10, HOURS_10 + 0.02, HOURS_10 + 61)

#: Every valid RCML vector (misnamed-panel.rcml is a panel under an RCML name).
VALID_RCML = [
    path
    for path in sorted((XML_VECTORS / "valid").glob("*.rcml"))
    if Validator().validate_file(path).kind == "rcml"
]
CASES = [
    *(pytest.param("sim", path, id=f"sim-{path.name}") for path in (CAMERA, ROVER, *VALID_RCML)),
    pytest.param("camera", CAMERA, id="camera"),
    pytest.param("rover", ROVER, id="rover"),
]
PYTHON_TYPES = {Kind.BOOL: bool, Kind.INTEGER: int, Kind.FLOAT: float, Kind.STRING: str}


class Robot:
    """A started driver, and what a client has heard of it: the first values, then each change
    a call reported. Every call checks its report."""

    def __init__(
        self, name: str, model: Path | RcmlDocument, seed: int = 7, now: float = T0
    ) -> None:
        self.model = robot(model) if isinstance(model, Path) else model
        self.driver = DRIVERS[name]()
        self.driver.start(self.model, now, seed)
        self.heard = dict(self.driver.values())

    @property
    def values(self) -> Mapping[str, Value]:
        return self.driver.values()

    def advance(self, now: float) -> set[str]:
        """Advance; the report names exactly what changed since the client last heard."""
        changed = self._hear(self.driver.advance(now))
        assert self.heard == dict(self.values)
        return changed

    def command(self, values: Mapping[str, Value], now: float) -> set[str]:
        """Write; what the report names did change (the move to `now` waits for an advance)."""
        return self._hear(self.driver.command(values, now))

    def run(self, offsets: Iterable[float]) -> list[dict[str, Value]]:
        """Advance through T0 + each offset; the values after each."""
        snapshots = []
        for offset in offsets:
            self.advance(T0 + offset)
            snapshots.append(dict(self.values))
        return snapshots

    def _hear(self, report: Iterable[str]) -> set[str]:
        changed = list(report)
        assert len(changed) == len(set(changed))
        for path in changed:
            assert not same(self.values[path], self.heard[path]), path
            self.heard[path] = self.values[path]
        return set(changed)


def load_text(directory: Path, text: str) -> RcmlDocument:
    path = directory / "robot.rcml"
    path.write_text(f'<?xml version="1.0" encoding="UTF-8"?>\n{text}', encoding="utf-8")
    return load_robot(path)


def data_node(model: RcmlDocument, path: str) -> DataNode:
    node = model.node(path)
    assert isinstance(node, DataNode), path
    return node


def same(a: Value, b: Value) -> bool:
    """The drivers' test of a change: the same object or equal (a NaN held is not a change)."""
    return a is b or a == b


def assert_valid(values: Mapping[str, Value], model: RcmlDocument) -> None:
    """Every node has a value of its type, in its range, that the binary form gives back."""
    assert values.keys() == {node.path for node in model.data_nodes()}
    for node in model.data_nodes():
        value = values[node.path]
        items = value if node.type.is_array else (value,)
        assert isinstance(items, tuple)
        assert len(items) == node.type.count, node.path
        wanted = PYTHON_TYPES.get(node.type.base.kind, bytes)
        assert all(type(item) is wanted for item in items), (node.path, value)
        data = encode_value(node.type, value)
        back = decode_value(node.type, data)
        assert back == value or any(item != item for item in items), node.path  # NaN != NaN
        assert encode_value(node.type, back) == data
        assert node.out_of_range(value) is None


# -- any driver, any model -------------------------------------------------------------------


@pytest.mark.parametrize(("name", "path"), CASES)
def test_values_are_valid_at_any_time(name: str, path: Path) -> None:
    bot = Robot(name, path)
    assert bot.driver.name == name
    assert_valid(bot.values, bot.model)
    for offset in OFFSETS:
        bot.advance(T0 + offset)
        assert_valid(bot.values, bot.model)


@pytest.mark.parametrize(("name", "path"), CASES)
def test_same_seed_same_times_same_values(name: str, path: Path) -> None:
    assert Robot(name, path, seed=3).run(OFFSETS) == Robot(name, path, seed=3).run(OFFSETS)


def test_another_seed_wanders_elsewhere() -> None:
    assert Robot("sim", TESTBOT, seed=1).run(OFFSETS) != Robot("sim", TESTBOT, seed=2).run(OFFSETS)


# -- sim ---------------------------------------------------------------------------------------


def test_sim_first_values() -> None:
    values = Robot("sim", TESTBOT).values
    assert values["/drive/wheels/left"] == 0.0
    assert values["/drive/wheels/odometry"] == (0.0, 0.0, 0.0)
    assert values["/drive/settings/label"] == "label"
    assert values["/head/control/lcd"] == b""
    assert values["/sensors/bumpers/front"] is False
    assert values["/head/control/pose"] == (0.0, 0.0)


def test_sim_first_values_clamp_zero_and_cut_names(tmp_path: Path) -> None:
    text = """<rcml version="2.0" site="rctp://robot.example"><access name="a">
        <data name="hot" type="int8" min="20" max="90"/>
        <data name="cold" type="float32" min="-9.5" max="-0.1" count="2"/>
        <data name="\u00e9\u00e9\u00e9" type="string" size="3"/>
      </access></rcml>"""
    bot = Robot("sim", load_text(tmp_path, text))
    assert bot.values["/a/hot"] == 20
    cold = bot.values["/a/cold"]
    assert isinstance(cold, tuple)
    assert cold[0] == data_node(bot.model, "/a/cold").maximum  # -0.1 as float32
    assert bot.values["/a/\u00e9\u00e9\u00e9"] == "\u00e9"  # 3 bytes hold one é and a half
    assert_valid(bot.values, bot.model)


def test_sim_holds_what_is_written_and_wanders_what_is_read_only() -> None:
    bot = Robot("sim", TESTBOT)
    written: dict[str, Value] = {
        "/drive/wheels/left": 1.25,
        "/drive/wheels/right": 0.0,  # already 0: not a change
        "/drive/settings/mode": 2,
        "/drive/settings/label": "hello",
        "/head/control/lcd": b"\x01\x02",
    }
    assert bot.command(written, T0) == set(written) - {"/drive/wheels/right"}
    assert bot.command(written, T0) == set()
    seen: set[str] = set()
    for offset in range(1, 200):
        seen |= bot.advance(T0 + offset * 0.7)
    assert all(bot.values[path] == value for path, value in written.items())
    read_only = {
        node.path
        for node in bot.model.data_nodes()
        if node.permission is Permission.READ and node.type.base.kind is not Kind.STRING
    }
    assert seen == read_only


def test_sim_command_reports_its_own_changes_and_advance_the_rest() -> None:
    bot = Robot("sim", TESTBOT)
    assert bot.command({"/head/control/led": 9}, T0 + 30) == {"/head/control/led"}
    # The read-only nodes wandered in those 30 s: the next call reports it, though no time passed.
    assert "/drive/wheels/odometry" in bot.advance(T0 + 30)


def test_sim_work_per_advance_is_bounded(tmp_path: Path) -> None:
    scalars, items = 600, 1000
    text = (
        '<rcml version="2.0" site="rctp://robot.example"><group name="g" permission="r">'
        '<access name="a">'
        + "".join(f'<data name="n{i}" type="int16"/>' for i in range(scalars))
        + f'<data name="wide" type="uint8" count="{items}"/>'
        '<data name="still" type="uint8" min="7" max="7"/>'
        '<data name="text" type="string" size="9"/>'
        "</access></group></rcml>"
    )
    bot = Robot("sim", load_text(tmp_path, text))
    seen: set[str] = set()
    rounds = math.ceil((scalars + items + 2) / ITEMS_PER_ADVANCE)
    for step in range(1, rounds + 1):
        changed = bot.advance(T0 + step * 7.3)
        assert len(changed) <= ITEMS_PER_ADVANCE
        seen |= changed
    assert seen == {f"/g/a/n{i}" for i in range(scalars)} | {"/g/a/wide"}
    assert_valid(bot.values, bot.model)


# -- camera ----------------------------------------------------------------------------------

PAN, TILT, ZOOM = "/stream/control/pan", "/stream/control/tilt", "/stream/control/zoom"
MOVING = "/status/lens/moving"


def test_camera_axes_move_to_their_set_points_at_their_rates() -> None:
    camera = Robot("camera", CAMERA)
    assert camera.values["/status/lens/model"]
    assert camera.command({PAN: 90, TILT: -45, ZOOM: 100}, T0) == {MOVING}
    assert camera.values[MOVING] is True
    expected = {  # seconds after the command: pan at 60 deg/s, tilt too, zoom at 50 %/s
        0.5: (30, -30, 25, True),
        1.0: (60, -45, 50, True),
        1.5: (90, -45, 75, True),
        2.0: (90, -45, 100, False),
        9.0: (90, -45, 100, False),
    }
    for offset, (pan, tilt, zoom, moving) in expected.items():
        camera.advance(T0 + offset)
        assert (camera.values[PAN], camera.values[TILT], camera.values[ZOOM]) == (pan, tilt, zoom)
        assert camera.values[MOVING] is moving
    assert camera.advance(T0 + 10) == set()


def test_camera_new_set_point_turns_an_axis_where_it_is() -> None:
    camera = Robot("camera", CAMERA)
    camera.command({PAN: 180}, T0)
    assert camera.command({PAN: -30}, T0 + 1) == set()  # still moving
    assert camera.advance(T0 + 1) == {PAN}  # it got to 60 before turning back
    assert camera.values[PAN] == 60
    camera.advance(T0 + 2.5)
    assert (camera.values[PAN], camera.values[MOVING]) == (-30, False)


# -- rover -----------------------------------------------------------------------------------

LEFT, RIGHT = "/drive/wheels/left", "/drive/wheels/right"
MAX_SPEED, MODE = "/drive/settings/maxSpeed", "/drive/settings/mode"
POSE, RANGE = "/sensors/odometry/pose", "/sensors/odometry/range"
BUMPERS = ("/sensors/events/bumperLeft", "/sensors/events/bumperRight")
BATTERY = "/sensors/events/battery"


def pose(rover: Robot) -> tuple[float, ...]:
    value = rover.values[POSE]
    assert isinstance(value, tuple)
    return tuple(float(v) for v in value)


def ranges(rover: Robot) -> tuple[int, ...]:
    value = rover.values[RANGE]
    assert isinstance(value, tuple)
    return tuple(int(v) for v in value)


def wheels(rover: Robot) -> tuple[Value, Value]:
    return rover.values[LEFT], rover.values[RIGHT]


def bumpers(rover: Robot) -> tuple[Value, ...]:
    return tuple(rover.values[bumper] for bumper in BUMPERS)


def drive(rover: Robot, left: float, right: float, seconds: float, step: float = 0.1) -> None:
    """Command the wheels at T0 and advance in steps for `seconds`."""
    rover.command({LEFT: left, RIGHT: right}, T0)
    for index in range(1, round(seconds / step) + 1):
        rover.advance(T0 + index * step)


def test_rover_first_values() -> None:
    rover = Robot("rover", ROVER)
    assert pose(rover) == (0.0, 0.0, 0.0)
    assert (rover.values[MAX_SPEED], rover.values[MODE], rover.values[BATTERY]) == (0.5, 1, 100.0)
    assert (rover.values["/identity/info/name"], *wheels(rover)) == ("rover", 0.0, 0.0)
    assert bumpers(rover) == (False, False)
    # 2 m to the walls ahead, less the 0.15 m from the centre to the rim; the diagonals see far
    assert ranges(rover) == (1921, 2000, 1921, 1921, 2000, 1921)


def test_rover_drives_straight_ahead() -> None:
    rover = Robot("rover", ROVER)
    drive(rover, 0.2, 0.2, 2.0)
    x, y, heading = pose(rover)
    assert x == pytest.approx(0.4, abs=1e-6)
    assert (y, heading) == (0.0, 0.0)


def test_rover_turns_in_place() -> None:
    rover = Robot("rover", ROVER)
    drive(rover, -0.15, 0.15, 1.0)  # 0.3 m/s apart over a 0.3 m wheel base: 1 rad/s
    x, y, heading = pose(rover)
    assert heading == pytest.approx(1.0, abs=1e-6)
    assert (x, y) == pytest.approx((0.0, 0.0), abs=1e-9)
    drive(rover, -0.15, 0.15, 4.0)
    assert pose(rover)[2] == pytest.approx(4.0 - 2 * math.pi, abs=1e-6)  # within [-pi, pi]


def test_rover_stops_at_a_wall_with_its_bumpers_pressed() -> None:
    rover = Robot("rover", ROVER)
    rover.command({LEFT: 0.5, RIGHT: 0.5}, T0)
    ahead = [ranges(rover)[2:4]]
    for index in range(1, 101):
        rover.advance(T0 + index * 0.1)
        ahead.append(ranges(rover)[2:4])
        if pose(rover)[0] < 1.6:
            assert bumpers(rover) == (False, False)
    assert bumpers(rover) == (True, True)
    # The front corners, 0.15 m from the centre at 45 degrees, stop CONTACT from the wall at 2 m.
    stop = 2 - CONTACT - BODY_RADIUS * math.cos(math.pi / 4)
    assert pose(rover)[0] == pytest.approx(stop, abs=1e-4)
    assert rover.advance(T0 + 20) <= {BATTERY}  # pushing on, it stays
    approach = list(dict.fromkeys(ahead))  # until it stopped
    assert all(later < earlier for earlier, later in itertools.pairwise(approach))
    assert approach[-1][0] < 200
    rover.command({LEFT: -0.2, RIGHT: -0.2}, T0 + 20)
    rover.advance(T0 + 21)
    assert bumpers(rover) == (False, False)


def test_rover_limits_written_speeds() -> None:
    rover = Robot("rover", ROVER)
    rover.command({LEFT: 1.0, RIGHT: 0.5}, T0)  # scaled together to maxSpeed 0.5: same curve
    assert wheels(rover) == (0.5, 0.25)
    assert rover.command({MODE: 2}, T0) == {MODE, LEFT, RIGHT}
    assert wheels(rover) == (0.25, 0.125)
    rover.command({MODE: 0, LEFT: 1.0}, T0)  # stopped: wheel commands are ignored
    assert wheels(rover) == (0.0, 0.0)
    assert rover.command({MODE: 1}, T0) == {MODE}  # it stays stopped until told to drive
    rover.command({MAX_SPEED: 1.0, LEFT: 0.75, RIGHT: math.nan}, T0)
    assert wheels(rover) == (0.75, 0.0)


def test_rover_battery_drains_faster_while_moving() -> None:
    idle, moving = Robot("rover", ROVER), Robot("rover", ROVER)
    drive(idle, 0.0, 0.0, 1000, step=100)
    drive(moving, 0.2, 0.3, 1000, step=100)  # a circle 0.75 m in radius: never at a wall
    assert [idle.values[BATTERY], moving.values[BATTERY]] == pytest.approx([99.0, 96.5], abs=0.1)
    moving.advance(T0 + 1000 + HOURS_10)
    assert moving.values[BATTERY] == 0.0


# -- choosing a driver -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("path", "name"),
    [
        (CAMERA, "camera"),
        (ROVER, "rover"),
        (TESTBOT, "sim"),
        (XML_VECTORS / "valid" / "appendix-a-corrected.rcml", "sim"),  # no lens status
    ],
)
def test_auto_picks_the_driver_that_fits(path: Path, name: str) -> None:
    assert choose_driver("auto", robot(path)).name == name
    assert choose_driver(name, robot(path)).name == name
    assert choose_driver("sim", robot(path)).name == "sim"


def test_a_driver_that_does_not_fit_is_refused_with_the_reason() -> None:
    with pytest.raises(DriverError) as caught:
        choose_driver("camera", robot(ROVER))
    message = str(caught.value)
    assert "/stream/control/pan" in message
    assert "auto, camera, rover, sim" in message
    assert isinstance(caught.value, RcmlconfError)


def test_a_node_of_the_wrong_type_does_not_fit(tmp_path: Path) -> None:
    text = (CAMERA.read_text(encoding="utf-8").split("\n", 1)[1]).replace(
        'name="tilt" type="int"', 'name="tilt" type="float"'
    )
    model = load_text(tmp_path, text)
    with pytest.raises(DriverError, match=r"/stream/control/tilt is float32, not integer"):
        choose_driver("camera", model)
    assert choose_driver("auto", model).name == "sim"


def test_an_unknown_driver_is_refused_with_the_names() -> None:
    with pytest.raises(
        DriverError, match=r"no driver 'robot': choose one of auto, camera, rover, sim"
    ):
        choose_driver("robot", robot(TESTBOT))


# -- property: whatever clients write, whenever ----------------------------------------------


def written_values(node: DataNode) -> st.SearchStrategy[Value]:
    """Values a server lets through to the driver: of the type, not outside min/max (NaN is
    outside every range, D-RCML-12, but gets through to a node without one)."""
    base = node.type.base
    item: st.SearchStrategy[Scalar]
    if base.kind is Kind.BOOL:
        item = st.booleans()
    elif base.kind is Kind.INTEGER:
        low, high = bounds(node)
        item = st.integers(int(low), int(high))
    elif base.kind is Kind.FLOAT:
        low, high = bounds(node)
        width: Literal[32, 64] = 32 if base.name == "float32" else 64
        finite = math.isfinite(low) and math.isfinite(high)
        item = st.floats(low, high, width=width) if finite else st.floats(width=width)
    elif base.kind is Kind.STRING:
        size = node.type.size
        item = st.text(st.characters(codec="utf-8"), max_size=size).filter(
            lambda text: len(text.encode()) <= size
        )
    else:
        item = st.binary(max_size=min(node.type.size, 64))
    if node.type.is_array:
        count = node.type.count
        return st.tuples(*[item] * count)
    return item


def commands(model: RcmlDocument) -> st.SearchStrategy[dict[str, Value]]:
    writable = [node for node in model.data_nodes() if Permission.WRITE in node.permission]
    return st.fixed_dictionaries(
        {}, optional={node.path: written_values(node) for node in writable}
    )


ROBOTS = [("sim", TESTBOT), ("camera", CAMERA), ("rover", ROVER), ("sim", ROVER)]
steps = st.one_of(st.floats(0, 2), st.floats(0, 1e5))


@given(data=st.data(), which=st.sampled_from(ROBOTS), seed=st.integers(0, 2**32))
def test_any_commands_at_any_times_keep_values_valid(
    data: st.DataObject, which: tuple[str, Path], seed: int
) -> None:
    name, path = which
    bot = Robot(name, path, seed)
    now = T0
    for dt, written in data.draw(st.lists(st.tuples(steps, commands(bot.model)), max_size=6)):
        now += dt
        assert all(data_node(bot.model, p).out_of_range(v) is None for p, v in written.items())
        bot.command(written, now)
        assert_valid(bot.values, bot.model)
        bot.advance(now + dt / 2)
        assert_valid(bot.values, bot.model)
