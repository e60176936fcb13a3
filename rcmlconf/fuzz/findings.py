"""Findings as files (D-FUZZ-6): `finding-N.json`, as `fuzz-finding.schema.json` in the
package says, and `finding-N.pcap`, the minimised case's traffic for `rcmlconf dissect` and
Wireshark."""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from rcmlconf.fuzz.oracles import Verdict
from rcmlconf.fuzz.steps import TestCase
from rcmlconf.pcap.writer import Payload, write_pcap

SCHEMA = "rcmlconf-fuzz-finding/1"
#: The most bytes of one message a finding's log keeps (its pcap keeps them all).
LOGGED = 4096


@dataclass(slots=True, kw_only=True)
class Finding:
    number: int
    verdict: Verdict
    role: str
    case: TestCase
    original: TestCase
    #: How many of the re-runs of the minimised case fired the oracle, of how many.
    stable: tuple[int, int]
    #: Whether the minimiser could run: a dead target without --target-command cannot.
    minimised: bool
    #: Seconds into the campaign it was first seen.
    at: float
    target: dict[str, Any]
    #: How the target's process ended, and its stderr's tail (--target-command).
    output: dict[str, Any] | None = None
    #: The minimised case's last run: what went each way, when.
    payloads: list[Payload] = field(default_factory=list)
    count: int = 1

    @property
    def key(self) -> tuple[str, str, str, tuple[str, ...]]:
        """One bug, one finding: the oracle, the requirement, the state, the shape."""
        return (self.verdict.oracle, self.verdict.rule, self.case.state, self.case.shape)

    @property
    def name(self) -> str:
        return f"finding-{self.number}"

    def to_json(self) -> dict[str, Any]:
        start = self.payloads[0].at if self.payloads else 0.0
        return {
            "schema": SCHEMA,
            "number": self.number,
            "oracle": self.verdict.oracle,
            "requirement": self.verdict.rule,
            "text": self.verdict.text,
            "role": self.role,
            "state": self.case.state,
            "path": [s.data.split(b" ", 1)[0].decode("latin-1") for s in self.case.prefix],
            "count": self.count,
            "stable": {"fired": self.stable[0], "runs": self.stable[1]},
            "minimised": self.minimised,
            "first_seen": round(self.at, 3),
            "target": self.target,
            "target_output": self.output,
            "case": self.case.to_json(),
            "original": self.original.to_json(),
            "log": [
                {
                    "at": round(p.at - start, 6),
                    "transport": p.transport,
                    "source": f"{p.source[0]}:{p.source[1]}",
                    "destination": f"{p.destination[0]}:{p.destination[1]}",
                    "size": len(p.data),
                    "hex": p.data[:LOGGED].hex(),
                }
                for p in self.payloads
            ],
        }

    def write(self, directory: Path) -> tuple[Path, Path]:
        report = directory / f"{self.name}.json"
        report.write_text(json.dumps(self.to_json(), indent=1) + "\n", encoding="utf-8")
        capture = directory / f"{self.name}.pcap"
        with capture.open("wb") as file:
            write_pcap(file, self.payloads)
        return report, capture


class FindingFileError(ValueError):
    """A finding file that cannot be replayed: not JSON, or not of this schema."""


def load_finding(path: Path) -> tuple[TestCase, dict[str, Any]]:
    """The minimised case of a finding file, and the file's fields."""
    try:
        item = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise FindingFileError(f"{path}: {error}") from None
    if not isinstance(item, dict) or item.get("schema") != SCHEMA:
        raise FindingFileError(f"{path}: not a finding of {SCHEMA}")
    try:
        return TestCase.from_json(item["case"]), item
    except (KeyError, TypeError, ValueError) as error:
        raise FindingFileError(f"{path}: the case cannot be read: {error!r}") from None
