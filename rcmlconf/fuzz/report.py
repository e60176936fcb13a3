"""The campaign's report: JSON (`fuzz-report.schema.json`) and JUnit, a testcase a finding."""

from __future__ import annotations

import json
from collections.abc import Sequence
from pathlib import Path
from typing import Any
from xml.etree import ElementTree as ET

from rcmlconf.fuzz.campaign import Stats
from rcmlconf.fuzz.findings import Finding
from rcmlconf.fuzz.statemap import StateMap

SCHEMA = "rcmlconf-fuzz-report/1"


def report(
    stats: Stats,
    findings: Sequence[Finding],
    states: StateMap,
    settings: dict[str, Any],
    stopped: str | None,
) -> dict[str, Any]:
    return {
        "schema": SCHEMA,
        "settings": settings,
        "cases": stats.cases,
        "seconds": round(stats.elapsed, 3),
        "cases_per_second": round(stats.rate, 1),
        "restarts": stats.restarts,
        "states_reached": states.states_reached,
        "stopped": stopped,
        "state_map": states.table(),
        "timeline": [list(point) for point in stats.timeline],
        "findings": [
            {
                "file": f"{f.name}.json",
                "oracle": f.verdict.oracle,
                "requirement": f.verdict.rule,
                "state": f.case.state,
                "text": f.verdict.text,
                "count": f.count,
                "stable": f"{f.stable[0]}/{f.stable[1]}",
            }
            for f in findings
        ],
    }


def write_json(path: Path, document: dict[str, Any]) -> None:
    path.write_text(json.dumps(document, indent=1) + "\n", encoding="utf-8")


def write_junit(path: Path, document: dict[str, Any]) -> None:
    """One testsuite; a failing testcase a finding, or one passing testcase when none."""
    found = document["findings"]
    suite = ET.Element(
        "testsuite",
        name="rcmlconf fuzz",
        tests=str(max(len(found), 1)),
        failures=str(len(found)),
        time=f"{document['seconds']:.3f}",
    )
    for finding in found:
        case = ET.SubElement(
            suite,
            "testcase",
            classname=f"fuzz.{finding['oracle']}",
            name=f"{finding['file']} {finding['requirement']} in {finding['state']}",
        )
        failure = ET.SubElement(
            case, "failure", type=finding["oracle"], message=finding["text"][:500]
        )
        failure.text = (
            f"{finding['text']}\nrequirement {finding['requirement']}, state {finding['state']},"
            f" fired {finding['count']} times, stable {finding['stable']}"
        )
    if not found:
        ET.SubElement(suite, "testcase", classname="fuzz", name=f"{document['cases']} cases")
    ET.ElementTree(suite).write(path, encoding="utf-8", xml_declaration=True)
