"""`rcmlconf wireshark`: the plugin's text, its fields as Wireshark registers them, its options."""

from __future__ import annotations

import json
import os
import subprocess
import tempfile
from pathlib import Path

import pytest
from click.testing import CliRunner
from support.rsp_models import CUBO, EVERY_KIND, robot_model
from support.wireshark_pcaps import VECTORS, need_tshark, udp_pcap

from rcmlconf.cli.wireshark import wireshark
from rcmlconf.rctp.messages import METHODS, REASONS
from rcmlconf.rsp.codec import PacketType
from rcmlconf.wireshark.lua import abbreviation, field_abbreviations, generate_lua, lua_literal
from rcmlconf.wireshark.tshark import run_tshark, tshark_path

#: The fields every plugin has, and their Wireshark types.
FIELDS = {
    "rctp.method": "FT_STRING",
    "rctp.target": "FT_STRING",
    "rctp.status": "FT_UINT16",
    "rctp.cseq": "FT_UINT32",
    "rctp.session.id": "FT_STRING",
    "rctp.transport.tag": "FT_UINT32",
    "rctp.body": "FT_BYTES",
    "rctp.malformed": "FT_STRING",
    "rctpds.seq": "FT_UINT16",
    "rctpds.tag": "FT_UINT32",
    "rctpds.timestamp": "FT_UINT64",
    "rctpds.time": "FT_ABSOLUTE_TIME",
    "rctpds.payload.type": "FT_UINT8",
    "rctpds.data": "FT_BYTES",
    "rctpds.flow.operation": "FT_UINT8",
    "rctpds.flow.t1": "FT_UINT64",
    "rctpds.flow.t3_time": "FT_ABSOLUTE_TIME",
    "rctpds.flow.interval": "FT_UINT32",
    "rctpds.flow.reason": "FT_UINT8",
    "rcmlrsp.type": "FT_UINT8",
    "rcmlrsp.seq": "FT_UINT16",
    "rcmlrsp.session_id": "FT_UINT64",
    "rcmlrsp.buffer": "FT_UINT8",
    "rcmlrsp.malformed.rule": "FT_STRING",
}


def _write(tmp_path: Path, model: Path | None = None) -> str:
    out = tmp_path / "rcml.lua"
    arguments = ["-o", str(out)] + (["--model", str(model)] if model else [])
    result = CliRunner().invoke(wireshark, arguments)
    assert result.exit_code == 0, result.output
    return out.read_text(encoding="utf-8")


def test_the_same_text_for_the_same_model(tmp_path: Path) -> None:
    assert _write(tmp_path, CUBO) == generate_lua(robot_model(CUBO))
    assert generate_lua(robot_model(CUBO)) == generate_lua(robot_model(CUBO))
    assert _write(tmp_path) == generate_lua(None)
    standard = CliRunner().invoke(wireshark, [])
    assert standard.exit_code == 0
    assert standard.stdout == generate_lua(None)


def test_generated_from_the_codecs_tables() -> None:
    text = generate_lua(robot_model(CUBO))
    for method in METHODS:
        assert f'"{method}"' in text
    for status, phrase in REASONS.items():
        assert f'[{status}] = "{phrase}"' in text
    for kind in PacketType:
        assert f'[{int(kind)}] = "{kind.name}"' in text
    for device in robot_model(CUBO).devices:
        assert f'name = "{device.name}"' in text
    assert "model = nil" in generate_lua(None)


def test_usage_errors(tmp_path: Path) -> None:
    invalid = VECTORS / "xml" / "invalid" / "rmodel-duplicates.rmodel"
    result = CliRunner().invoke(wireshark, ["--model", str(invalid), "-o", str(tmp_path / "x")])
    assert result.exit_code == 1
    assert "R-RSP-6" in result.output
    assert not (tmp_path / "x").exists()
    result = CliRunner().invoke(wireshark, ["--model", str(tmp_path / "none.rmodel")])
    assert result.exit_code == 2
    result = CliRunner().invoke(wireshark, ["-o", str(tmp_path / "no" / "such" / "dir.lua")])
    assert result.exit_code == 2
    assert "cannot write" in result.output
    rcml = Path(__file__).resolve().parents[2] / "rcmlconf/reference/robots/rover/rover.rcml"
    result = CliRunner().invoke(wireshark, ["--model", str(rcml)])
    assert result.exit_code == 1
    assert "not the one this command takes" in result.output


def test_lua_literals() -> None:
    assert lua_literal('a"b\\c\n') == '"a\\"b\\\\c\\010"'
    assert lua_literal("é") == '"\\195\\169"'
    assert (
        lua_literal({"and": 1, 2: [True, None]}) == '{\n    ["and"] = 1,\n    [2] = {true, nil},\n}'
    )
    assert lua_literal(-0.5) == "-0.5"
    assert lua_literal(float("inf")) == "math.huge"


ODD_NAMES = """<?xml version="1.0" encoding="UTF-8"?>
<robotModel version="1" name="Odd" modelId="7">
  <effector name="arm.left">
    <field name="x.y" type="int8"/><field name="x_y" type="int8"/>
  </effector>
  <effector name="arm_left"><field name="a" type="uint8"/></effector>
  <effector name="arm-left"><field name="a" type="uint8"/></effector>
  <sensor name="bräcke"><field name="ß" type="float64"/></sensor>
</robotModel>
"""


def test_names_become_distinct_abbreviations(tmp_path: Path) -> None:
    assert abbreviation("arm.left") == "arm_left"
    assert abbreviation("bräcke") == "br_cke"
    path = tmp_path / "odd.rmodel"
    path.write_text(ODD_NAMES, encoding="utf-8")
    model = robot_model(path)
    names = field_abbreviations(model)
    assert names == [
        ("arm_left_0", ["x_y_0", "x_y_1"]),
        ("arm_left_1", ["a"]),
        ("arm-left", ["a"]),
        ("br_cke", ["_"]),
    ]
    if tshark_path() is None:
        return
    fields = _registered(tmp_path, generate_lua(model))
    for device, device_fields in names:
        assert f"rcmlrsp.map.{device}" in fields
        for field in device_fields:
            assert f"rcmlrsp.dev.{device}.{field}" in fields


def _registered(tmp_path: Path, text: str) -> dict[str, str]:
    """The fields tshark registers with the plugin loaded: abbreviation -> type."""
    lua = tmp_path / "plugin.lua"
    lua.write_text(text, encoding="utf-8")
    with tempfile.TemporaryDirectory() as config:
        done = subprocess.run(
            [str(tshark_path()), "-G", "fields", "-X", f"lua_script:{lua}"],
            capture_output=True,
            text=True,
            env={**os.environ, "WIRESHARK_CONFIG_DIR": config},
            check=True,
        )
    problems = [line for line in done.stderr.splitlines() if "Running as user" not in line]
    assert problems == []
    fields = {}
    for line in done.stdout.splitlines():
        parts = line.split("\t")
        if parts[0] == "F":
            fields[parts[2]] = parts[3]
    return fields


@pytest.mark.parametrize("model", [None, CUBO, EVERY_KIND])
def test_wireshark_registers_the_fields(model: Path | None, tmp_path: Path) -> None:
    need_tshark()
    robot = robot_model(model) if model else None
    fields = _registered(tmp_path, generate_lua(robot))
    for name, kind in FIELDS.items():
        assert fields.get(name) == kind, name
    if robot is None:
        assert not any(name.startswith("rcmlrsp.dev.") for name in fields)
        return
    for (device, device_fields), real in zip(
        field_abbreviations(robot), robot.devices, strict=True
    ):
        assert fields[f"rcmlrsp.map.{device}"] == "FT_BOOLEAN"
        for field, declared in zip(device_fields, real.fields, strict=True):
            assert f"rcmlrsp.dev.{device}.{field}" in fields, (device, declared)


def test_other_ports_by_preference(tmp_path: Path) -> None:
    """A robot on another port: found by the heuristic, by the port preference, or not at all."""
    need_tshark()
    lua = tmp_path / "rcml.lua"
    lua.write_text(generate_lua(robot_model(CUBO)), encoding="utf-8")
    vectors = json.loads((VECTORS / "rsp" / "packets.json").read_text(encoding="utf-8"))
    datagrams = [bytes.fromhex(v["hex"]) for v in vectors["valid"] if v["model"] == "CUBO"]
    pcap = udp_pcap(tmp_path / "other.pcap", datagrams, 9000)

    def shown(*options: str) -> int:
        frames = run_tshark(pcap, lua, options).frames
        return sum(1 for frame in frames if frame.of("rcmlrsp"))

    assert shown() == len(datagrams)
    assert shown("-o", "rcmlrsp.heuristic:FALSE") == 0
    assert shown("-o", "rcmlrsp.heuristic:FALSE", "-o", "rcmlrsp.udp_ports:9000") == len(datagrams)
