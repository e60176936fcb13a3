"""The robot model as loaded (specs/rsp.md §1): model order, monitors, sizes; CUBO (D-RSP-8)."""

from __future__ import annotations

import pytest
from support.rsp_models import CUBO, EVERY_KIND, robot_model

from rcmlconf.rsp.layout import HEADER_SIZE, MapPacket, largest_payload
from rcmlconf.rsp.model import DeviceKind, OnLoss
from rcmlconf.validate.validator import InvalidRobot, load_robot_model


def test_model_order_puts_a_module_before_its_members() -> None:
    model = robot_model(CUBO)
    names = [device.name for device in model.devices]
    assert names[:5] == ["base", "leftWheel", "rightWheel", "leftWheelMonitor", "rightWheelMonitor"]
    assert [device.position for device in model.devices] == list(range(len(names)))
    assert model.members("base") == model.devices[1:5]
    assert model.device("lip") is model.devices[names.index("lip")]


def test_cubo_has_the_papers_devices() -> None:
    model = robot_model(CUBO)
    kinds = [device.kind for device in model.devices]
    assert kinds.count(DeviceKind.SENSOR) == 7  # the six sensors and the microphone
    assert kinds.count(DeviceKind.EVENT) == 2  # the two buttons
    assert model.model_id == 1
    assert model.period == 0.02
    assert model.map_size == 4
    wheel = model.device("leftWheel")
    assert wheel is not None
    assert wheel.on_loss is OnLoss.ZERO


def test_a_monitor_has_its_effectors_fields() -> None:
    model = robot_model(CUBO)
    monitor, wheel = model.device("leftWheelMonitor"), model.device("leftWheel")
    assert monitor is not None
    assert wheel is not None
    assert monitor.of == "leftWheel"
    assert monitor.fields == wheel.fields


def test_the_music_packet_is_the_papers_size() -> None:
    """D-RSP-8: lips, both arms and a full speaker fragment make the paper's 1,992 bytes."""
    model = robot_model(CUBO)
    payloads = sum(
        largest_payload(model, device, MapPacket.DOWNLINK)
        for device in model.devices
        if device.name in ("lip", "leftArm", "rightArm", "speaker")
    )
    assert HEADER_SIZE + model.map_size + payloads == 1992


def test_the_model_attributes_and_defaults() -> None:
    model = robot_model(EVERY_KIND)
    assert (model.model_id, model.id_length, model.command_buffers) == (42, 2, 127)
    assert model.period == pytest.approx(0.005)
    field = model.devices[1].fields[0]
    assert (field.minimum, field.maximum, field.unit, field.type.count) == (-1000, 1000, "mm/s", 2)


def test_an_invalid_model_is_refused_with_its_report() -> None:
    path = CUBO.parents[4] / "vectors" / "xml" / "invalid" / "rmodel-monitors.rmodel"
    with pytest.raises(InvalidRobot, match="not a valid RSP robot model") as caught:
        load_robot_model(path)
    assert caught.value.report is not None
    assert caught.value.report.errors == 5


def test_an_rcml_file_is_not_a_model() -> None:
    with pytest.raises(InvalidRobot, match="not a valid RSP robot model"):
        load_robot_model(CUBO.parents[1] / "rover" / "rover.rcml")
