"""`rcmlconf rsp generate`: the Robot API module a robot model gives (paper §II.B, Fig. 4).

The generated classes are driven against a fake `DeviceAccess` that records what it is asked and
answers what the test tells it: this tests the generator, not the simulacrum behind the protocol.
The modules are also checked as an application's code would be: `mypy --strict` on them and on
scripts that use them (rightly and wrongly), `ruff format --check` and `ruff check` on the text.
"""

from __future__ import annotations

import importlib.util
import subprocess
import sys
import textwrap
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest
from mypy import api as mypy_api
from support.rsp_models import CUBO, EVERY_KIND, ROOT

from rcmlconf.rsp.api import DeviceAccess, Values
from rcmlconf.rsp.generate import generate_module
from rcmlconf.rsp.generate_names import NameClash, pascal_name, snake_name
from rcmlconf.rsp.model import DeviceKind, RobotModel
from rcmlconf.validate.validator import load_robot_model

SCRIPT = Path(sys.executable).parent / "rcmlconf"
COMMAND = [str(SCRIPT)] if SCRIPT.exists() else [sys.executable, "-m", "rcmlconf"]
PYPROJECT = ROOT / "pyproject.toml"
INVALID = ROOT / "vectors" / "xml" / "invalid" / "rmodel-fields.rmodel"
BOUND = 60.0

#: Names a generator could get wrong: keywords, names the module uses itself, `-`, `.` and `:`,
#: another script, a device and a monitor whose classes would clash, a name long enough that its
#: lines must be split, and a model name that is a keyword once in PascalCase.
ODD = """<?xml version="1.0" encoding="UTF-8"?>
<robotModel version="1" name="none" modelId="7" title="A &quot;quoted&quot; title, \\ and \u2713">
  <module name="class">
    <effector name="a-b.c">
      <field name="self" type="int8" unit="\u03bcs"/>
      <field name="index" type="float" count="3"/>
      <field name="count" type="bool"/>
    </effector>
    <sensor name="setActive"><field name="int" type="uint8"/></sensor>
  </module>
  <sensor name="_x"><field name="from" type="string" size="4"/></sensor>
  <sensor name="a:b"><field name="lambda" type="bool"/></sensor>
  <event name="\uc67c\ucabd\ubc14\ud034"><field name="\uc18d\ub3c4" type="uint8"/></event>
  <memoryEvent name="fooMonitor"><field name="x" type="uint8"/></memoryEvent>
  <monitor name="aMonitor" of="a-b.c"/>
  <monitor name="a" of="a-b.c"/>
  <command name="aCommandWhoseNameIsLongEnoughToSplitEveryLineOfIt">
    <field name="aFieldWhoseNameIsLongEnoughToSplitLinesToo" type="uint64" count="2"/>
    <field name="anotherFieldWhoseNameIsLongEnoughToSplit" type="bytes" size="3"/>
  </command>
  <sensor name="aSensorWhoseNameIsLongEnoughToSplitEveryLineOfIt">
    <field name="aFieldWhoseNameIsLongEnoughToSplitLinesToo" type="float64"/>
  </sensor>
</robotModel>
"""


# -- the fake middleware --------------------------------------------------------------------------


@dataclass
class Recorder:
    """A DeviceAccess that records every call and answers from `latest_values` and `next_values`."""

    calls: list[tuple[Any, ...]] = field(default_factory=list)
    latest_values: dict[str, Values | None] = field(default_factory=dict)
    next_values: dict[str, Values] = field(default_factory=dict)
    listeners: dict[str, Callable[[Values], None]] = field(default_factory=dict)
    next_id: int = 0

    def write(self, device: str, values: Values) -> None:
        self.calls.append(("write", device, dict(values)))

    def set_active(self, device: str, active: bool) -> None:
        self.calls.append(("set_active", device, active))

    def latest(self, device: str) -> Values | None:
        self.calls.append(("latest", device))
        return self.latest_values.get(device)

    def read(self, device: str, timeout: float | None = None) -> Values:
        self.calls.append(("read", device, timeout))
        return self.next_values[device]

    def issue(self, device: str, values: Values) -> int:
        self.calls.append(("issue", device, dict(values)))
        self.next_id += 1
        return self.next_id - 1

    def listen(self, device: str, listener: Callable[[Values], None]) -> Callable[[], None]:
        self.calls.append(("listen", device))
        self.listeners[device] = listener
        return lambda: self.calls.append(("stop", device))


def _typed(access: DeviceAccess) -> DeviceAccess:
    return access


# -- generating and importing ---------------------------------------------------------------------


@dataclass
class Generated:
    model: RobotModel
    path: Path
    module: ModuleType

    def robot(self) -> tuple[Any, Recorder]:
        access = Recorder()
        return self.module.__dict__[_model_class(self.module)](_typed(access)), access


def _model_class(module: ModuleType) -> str:
    """The class the module ends with: the model's."""
    classes = [
        n
        for n, v in vars(module).items()
        if isinstance(v, type) and v.__module__ == module.__name__
    ]
    return classes[-1]


def _load(path: Path, name: str) -> ModuleType:
    spec = importlib.util.spec_from_file_location(name, path)
    assert spec is not None
    assert spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    spec.loader.exec_module(module)
    return module


@pytest.fixture(scope="module")
def out_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("generated")


def _generate(out_dir: Path, source: Path, name: str) -> Iterator[Generated]:
    model = load_robot_model(source)
    path = out_dir / f"{name}.py"
    path.write_text(generate_module(model, source.name), encoding="utf-8")
    module = _load(path, name)
    yield Generated(model, path, module)
    sys.modules.pop(name, None)


@pytest.fixture(scope="module")
def cubo(out_dir: Path) -> Iterator[Generated]:
    yield from _generate(out_dir, CUBO, "cubo_api")


@pytest.fixture(scope="module")
def every(out_dir: Path) -> Iterator[Generated]:
    yield from _generate(out_dir, EVERY_KIND, "every_kind_api")


@pytest.fixture(scope="module")
def odd(out_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> Iterator[Generated]:
    source = tmp_path_factory.mktemp("odd") / "odd.rmodel"
    source.write_text(ODD, encoding="utf-8")
    yield from _generate(out_dir, source, "odd_api")


# -- names ----------------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("name", "snake", "pascal"),
    [
        ("leftWheel", "left_wheel", "LeftWheel"),
        ("irFire", "ir_fire", "IrFire"),
        ("IRFire", "ir_fire", "IrFire"),
        ("lcd2Left", "lcd2_left", "Lcd2Left"),
        ("a-b.c", "a_b_c", "ABC"),
        ("a:b_c", "a_b_c", "ABC"),
        ("_x", "x", "X"),
        ("class", "class_", "Class"),
        ("none", "none", "None_"),
        ("\ufb01eld", "field", "field"),  # Python reads the ligature as `fi`
    ],
)
def test_names(name: str, snake: str, pascal: str) -> None:
    assert snake_name(name) == snake
    assert pascal_name(name) == pascal


def test_cubo_classes(cubo: Generated) -> None:
    module = cubo.module
    expected = {
        "base": "BaseModule",
        "leftWheel": "LeftWheelEffector",
        "leftWheelMonitor": "LeftWheelMonitor",
        "position": "PositionSensor",
        "serviceButton": "ServiceButtonEvent",
        "irFire": "IrFireCommand",
        "motion": "MotionMemoryCommand",
        "lowBattery": "LowBatteryMemoryEvent",
    }
    assert [getattr(module, cls).NAME for cls in expected.values()] == list(expected)
    assert module.MODEL_ID == 1
    assert module.MODEL_NAME == "CUBO"
    assert _model_class(module) == "Cubo"


_METHODS = {
    DeviceKind.MODULE: {"set_active"},
    DeviceKind.EFFECTOR: {"write", "read", "set_active"},
    DeviceKind.SENSOR: {"read", "latest", "set_active", "listen"},
    DeviceKind.MONITOR: {"read", "latest", "set_active", "listen"},
    DeviceKind.COMMAND: {"issue"},
    DeviceKind.MEMORY_COMMAND: {"issue"},
    DeviceKind.EVENT: {"read", "listen", "set_active"},
    DeviceKind.MEMORY_EVENT: {"read", "listen", "set_active"},
}


@pytest.mark.parametrize("which", ["cubo", "every", "odd"])
def test_an_attribute_per_device_with_the_methods_of_its_kind(
    which: str, request: pytest.FixtureRequest
) -> None:
    generated: Generated = request.getfixturevalue(which)
    robot, _ = generated.robot()
    apis = {api.NAME: api for api in vars(robot).values()}
    assert list(apis) == [d.name for d in generated.model.devices]  # in model order
    for device in generated.model.devices:
        api = apis[device.name]
        public = {n for n in vars(type(api)) if not n.startswith("_") and n != "NAME"}
        assert public == _METHODS[device.kind], device.name
        if device.kind is DeviceKind.MODULE:  # its devices are its attributes, the same objects
            members = {a.NAME: a for a in vars(api).values() if hasattr(a, "NAME")}
            assert members == {d.name: apis[d.name] for d in generated.model.members(device.name)}


# -- driving the classes --------------------------------------------------------------------------


def test_effector(cubo: Generated) -> None:
    robot, access = cubo.robot()
    robot.left_wheel.write(speed=100)
    robot.left_wheel.set_active(False)
    robot.base.set_active(True)
    assert access.calls == [
        ("write", "leftWheel", {"speed": 100}),
        ("set_active", "leftWheel", False),
        ("set_active", "base", True),
    ]
    with pytest.raises(LookupError, match="leftWheel"):
        robot.left_wheel.read()
    access.latest_values["leftWheel"] = {"speed": -5}
    value = robot.left_wheel.read()
    assert value == cubo.module.LeftWheelValues(speed=-5)
    assert value.speed == -5


def test_sensor_and_monitor(cubo: Generated) -> None:
    robot, access = cubo.robot()
    assert robot.position.latest() is None
    access.next_values["position"] = {"x": 1.5, "y": -2, "heading": 0.25}
    where = robot.position.read(timeout=0.5)
    assert where == (1.5, -2.0, 0.25)
    assert type(where.y) is float  # an int from the middleware becomes the float the field is
    access.latest_values["position"] = {"x": 0.0, "y": 0.0, "heading": 3.0}
    assert robot.position.latest().heading == 3.0
    robot.position.set_active(True)
    # A monitor's values are its effector's.
    access.next_values["leftWheelMonitor"] = {"speed": 7}
    assert type(robot.left_wheel_monitor.read()) is cubo.module.LeftWheelValues
    assert ("read", "position", 0.5) in access.calls
    assert ("read", "leftWheelMonitor", None) in access.calls
    assert ("set_active", "position", True) in access.calls


def test_listen(cubo: Generated) -> None:
    robot, access = cubo.robot()
    pressed: list[object] = []
    stop = robot.service_button.listen(pressed.append)
    access.listeners["serviceButton"]({"pressed": True})
    assert pressed == [cubo.module.ServiceButtonValues(pressed=True)]
    stop()
    assert access.calls == [("listen", "serviceButton"), ("stop", "serviceButton")]
    access.next_values["lowBattery"] = {"charge": 9}
    assert robot.low_battery.read(1.0).charge == 9


def test_commands_send_the_model_s_field_names(cubo: Generated) -> None:
    robot, access = cubo.robot()
    assert robot.ir_fire.issue(code=0x20DF) == 0
    assert robot.motion.issue(duration=500, left_arm=1, right_arm=-1, head_tilt=0) == 1
    assert access.calls == [
        ("issue", "irFire", {"code": 0x20DF}),
        ("issue", "motion", {"duration": 500, "leftArm": 1, "rightArm": -1, "headTilt": 0}),
    ]


def test_every_type(every: Generated) -> None:
    robot, access = every.robot()
    robot.wheels.write(speed=(100, -100))
    robot.display.write(text="hi", picture=b"\x00\xff")
    robot.arm.write(shoulder=-90, elbow=180, grip=True)
    robot.pose.issue(duration=10, shoulder=5)
    assert access.calls == [
        ("write", "wheels", {"speed": (100, -100)}),
        ("write", "display", {"text": "hi", "picture": b"\x00\xff"}),
        ("write", "arm", {"shoulder": -90, "elbow": 180, "grip": True}),
        ("issue", "pose", {"duration": 10, "shoulder": 5}),
    ]
    counters = {"a": -1, "b": 2**32 - 1, "c": (-(2**63), 2**63 - 1), "d": 2**64 - 1, "e": 0}
    access.next_values["counters"] = {**counters, "f": tuple(range(100))}
    value = robot.counters.read()
    assert value.c == (-(2**63), 2**63 - 1)
    assert value.f == tuple(range(100))
    access.next_values["bumped"] = {"where": "front"}
    assert robot.bumped.read().where == "front"
    access.latest_values["display"] = {"text": "hi", "picture": b"\x01"}
    assert robot.display.read() == ("hi", b"\x01")
    access.next_values["wheelsActual"] = {"speed": (1, 2)}
    assert robot.wheels_actual.read() == every.module.WheelsValues(speed=(1, 2))


@pytest.mark.parametrize(
    ("device", "values"),
    [
        ("wheelsActual", {"speed": 3}),  # an array's value is a tuple
        ("wheelsActual", {"speed": (1, True)}),  # a bool is not an int
        ("odometry", {"x": "1", "y": 0.0, "heading": 0.0}),
        ("bumped", {"where": b"front"}),
    ],
)
def test_a_value_not_of_the_field_s_type_is_refused(
    every: Generated, device: str, values: Values
) -> None:
    robot, access = every.robot()
    access.next_values[device] = values
    with pytest.raises(TypeError, match="expected"):
        getattr(robot, snake_name(device)).read()


def test_odd_names(odd: Generated) -> None:
    robot, access = odd.robot()
    assert _model_class(odd.module) == "None_"
    robot.class_.a_b_c.write(self_=1, index_=(0.5, 1.0, 2.0), count_=True)
    robot.class_.set_active_.set_active(True)
    robot.a_command_whose_name_is_long_enough_to_split_every_line_of_it.issue(
        a_field_whose_name_is_long_enough_to_split_lines_too=(1, 2),
        another_field_whose_name_is_long_enough_to_split=b"abc",
    )
    access.next_values["\uc67c\ucabd\ubc14\ud034"] = {"\uc18d\ub3c4": 3}
    assert vars(robot)["\uc67c\ucabd\ubc14\ud034"].read() == (3,)
    assert access.calls[:3] == [
        ("write", "a-b.c", {"self": 1, "index": (0.5, 1.0, 2.0), "count": True}),
        ("set_active", "setActive", True),
        (
            "issue",
            "aCommandWhoseNameIsLongEnoughToSplitEveryLineOfIt",
            {
                "aFieldWhoseNameIsLongEnoughToSplitLinesToo": (1, 2),
                "anotherFieldWhoseNameIsLongEnoughToSplit": b"abc",
            },
        ),
    ]
    # `aMonitor` would be AMonitor, which `a`'s class is: both keep their kind in full.
    assert odd.module.AMonitorMonitor.NAME == "aMonitor"
    assert odd.module.AMonitor.NAME == "a"
    assert odd.module.FooMonitorMemoryEvent.NAME == "fooMonitor"
    assert odd.module.MODEL_NAME == "none"


def _model(devices: str) -> RobotModel:
    from rcmlconf.validate.validator import Validator

    text = f'<robotModel version="1" name="clash" modelId="1">{devices}</robotModel>'
    report, model = Validator().load_bytes(text.encode(), "clash.rmodel", suffix=".rmodel")
    assert isinstance(model, RobotModel), report.diagnostics
    return model


@pytest.mark.parametrize(
    ("devices", "message"),
    [
        (
            '<sensor name="leftWheel"><field name="a" type="int8"/></sensor>'
            '<effector name="left-wheel"><field name="a" type="int8"/></effector>',
            "devices 'leftWheel' and 'left-wheel' both become the Python name 'left_wheel'",
        ),
        (
            '<sensor name="s"><field name="class" type="int8"/>'
            '<field name="class_" type="int8"/></sensor>',
            "fields of 's': 'class' and 'class_' both become the Python name 'class_'",
        ),
    ],
)
def test_names_that_clash_are_refused(devices: str, message: str) -> None:
    with pytest.raises(NameClash, match=message):
        generate_module(_model(devices), "clash.rmodel")


# -- the text -------------------------------------------------------------------------------------


def test_deterministic() -> None:
    first = generate_module(load_robot_model(CUBO), "cubo.rmodel")
    second = generate_module(load_robot_model(CUBO), "cubo.rmodel")
    assert first == second
    assert first.startswith("# Generated by `rcmlconf rsp generate` from cubo.rmodel: do not edit")
    assert "model ID 1" in first.splitlines()[2]
    assert first.isascii()


def _ruff(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-m", "ruff", *args, "--no-cache", "--config", str(PYPROJECT)],
        capture_output=True,
        text=True,
        timeout=BOUND,
        check=False,
    )


def test_ruff_format_and_check_find_nothing(
    cubo: Generated, every: Generated, odd: Generated
) -> None:
    paths = [str(g.path) for g in (cubo, every, odd)]
    formatted = _ruff("format", "--check", "--diff", *paths)
    assert formatted.returncode == 0, formatted.stdout + formatted.stderr
    checked = _ruff("check", *paths)
    assert checked.returncode == 0, checked.stdout + checked.stderr


GOOD = """
from __future__ import annotations

from cubo_api import Cubo, LeftWheelValues, PositionValues
from every_kind_api import EveryKind
from odd_api import None_

from rcmlconf.rsp.api import DeviceAccess


def drive(access: DeviceAccess) -> float:
    cubo = Cubo(access)
    cubo.left_wheel.write(speed=100)
    cubo.base.set_active(True)
    mine: LeftWheelValues = cubo.left_wheel.read()
    where: PositionValues = cubo.position.read(timeout=1.0)
    latest = cubo.position.latest()
    heading = latest.heading if latest is not None else 0.0
    stop = cubo.service_button.listen(lambda v: print(v.pressed))
    stop()
    occurrence: int = cubo.motion.issue(duration=1, left_arm=0, right_arm=0, head_tilt=0)
    every = EveryKind(access)
    every.wheels.write(speed=(1, 2))
    counts: tuple[int, ...] = every.counters.read().f
    text: str = every.bumped.read().where
    None_(access).class_.a_b_c.write(self_=1, index_=(1.0,), count_=False)
    return mine.speed + where.x + heading + occurrence + len(counts) + len(text)
"""

BAD = """
from __future__ import annotations

from cubo_api import Cubo

from rcmlconf.rsp.api import DeviceAccess


def drive(access: DeviceAccess) -> None:
    cubo = Cubo(access)
    cubo.left_wheel.write(sped=100)
    cubo.left_wheel.write(speed="fast")
    cubo.position.read().z
    cubo.ir_fire.write(code=1)
    cubo.left_wheel = cubo.right_wheel
"""


def _mypy(tmp_path: Path, *paths: Path) -> tuple[str, int]:
    out, err, status = mypy_api.run(
        [
            "--strict",
            "--config-file",
            str(PYPROJECT),
            "--cache-dir",
            str(tmp_path / ".mypy_cache"),
            "--no-error-summary",
            *map(str, paths),
        ]
    )
    return out + err, status


def test_mypy_strict(
    cubo: Generated, every: Generated, odd: Generated, tmp_path_factory: pytest.TempPathFactory
) -> None:
    work = tmp_path_factory.mktemp("mypy")
    good = cubo.path.parent / "user_good.py"
    good.write_text(textwrap.dedent(GOOD), encoding="utf-8")
    report, status = _mypy(work, cubo.path, every.path, odd.path, good)
    assert status == 0, report
    bad = cubo.path.parent / "user_bad.py"
    bad.write_text(textwrap.dedent(BAD), encoding="utf-8")
    report, status = _mypy(work, bad)
    assert status == 1
    lines = [line for line in report.splitlines() if "user_bad.py" in line and "error" in line]
    assert any('Unexpected keyword argument "sped"' in line for line in lines), report
    assert any('"speed"' in line and 'incompatible type "str"' in line for line in lines), report
    assert any('has no attribute "z"' in line for line in lines), report
    assert any('has no attribute "write"' in line for line in lines), report
    assert any("Cannot assign to final attribute" in line for line in lines), report


# -- the command ----------------------------------------------------------------------------------


def _run(*args: str, cwd: Path = ROOT) -> subprocess.CompletedProcess[str]:
    done = subprocess.run(
        [*COMMAND, "rsp", "generate", *args],
        capture_output=True,
        text=True,
        timeout=BOUND,
        check=False,
        cwd=cwd,
    )
    assert "Traceback" not in done.stderr, done.stderr
    return done


def test_cli_writes_the_module(tmp_path: Path) -> None:
    source = CUBO.relative_to(ROOT).as_posix()
    target = tmp_path / "x.py"
    done = _run(source, "-o", str(target))
    assert done.returncode == 0, done.stderr
    assert done.stdout == ""
    assert f"wrote {target}" in done.stderr
    expected = generate_module(load_robot_model(CUBO), source)
    assert target.read_text(encoding="utf-8") == expected
    printed = _run(source)
    assert printed.returncode == 0
    assert printed.stdout == expected


def test_cli_invalid_model_exits_1_with_located_diagnostics() -> None:
    done = _run(str(INVALID))
    assert done.returncode == 1
    assert done.stdout == ""  # standard output is for the module alone
    assert f"{INVALID}:4:21: error: [R-RSP-8]" in done.stderr
    assert "1 invalid" in done.stderr.splitlines()[-1]


def test_cli_name_clash_exits_1(tmp_path: Path) -> None:
    source = tmp_path / "clash.rmodel"
    source.write_text(
        '<robotModel version="1" name="clash" modelId="1">'
        '<sensor name="a-b"><field name="x" type="int8"/></sensor>'
        '<sensor name="a.b"><field name="x" type="int8"/></sensor></robotModel>',
        encoding="utf-8",
    )
    done = _run(str(source))
    assert done.returncode == 1
    assert done.stderr.splitlines() == [
        f"rcmlconf rsp generate: {source}: devices 'a-b' and 'a.b' both become the Python name"
        " 'a_b'; rename one"
    ]


def test_cli_missing_file_and_usage_errors_exit_2(tmp_path: Path) -> None:
    missing = _run(str(tmp_path / "nope.rmodel"))
    assert missing.returncode == 2
    assert len(missing.stderr.splitlines()) == 1
    assert "nope.rmodel: cannot be read" in missing.stderr
    assert _run().returncode == 2
    unwritable = _run(str(CUBO), "-o", str(tmp_path / "no" / "such" / "dir.py"))
    assert unwritable.returncode == 2
    assert unwritable.stderr.startswith("rcmlconf rsp generate: cannot write")


def test_cli_help_shows_how_to_use_the_module() -> None:
    done = _run("--help")
    assert done.returncode == 0
    assert "cubo = Cubo(access)" in done.stdout
    assert "cubo.left_wheel.write(speed=120)" in done.stdout
    listed = subprocess.run(
        [*COMMAND, "--help"], capture_output=True, text=True, timeout=BOUND, check=False
    )
    assert "rsp " in listed.stdout
