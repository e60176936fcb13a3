"""Seeds to splice with (D-FUZZ-3): the client's messages of the RCTP transcripts in
`vectors/rctp/transcripts/`, where the package runs from a checkout that has them. An installed
package has no vectors; the fuzzer's own valid requests stand in (`RctpCases`)."""

from __future__ import annotations

import json
from pathlib import Path

VECTORS = Path(__file__).resolve().parents[2] / "vectors" / "rctp" / "transcripts"
#: The most seeds kept.
MOST = 200


def control_seeds(folder: Path = VECTORS) -> list[bytes]:
    seeds: list[bytes] = []
    for path in sorted(folder.glob("*.json")) if folder.is_dir() else []:
        try:
            steps = json.loads(path.read_text(encoding="utf-8")).get("steps", [])
        except (OSError, ValueError):
            continue
        for step in steps:
            wire = step.get("wire") if isinstance(step, dict) else None
            if step.get("from") == "client" and isinstance(wire, str) and "send" in step:
                seeds.append(wire.encode("latin-1", "replace"))
    return seeds[:MOST]


RSP_VECTORS = Path(__file__).resolve().parents[2] / "vectors" / "rsp" / "packets.json"


def rsp_seeds(model_id: int, path: Path = RSP_VECTORS) -> list[bytes]:
    """The valid RSP datagrams of `vectors/rsp/packets.json` whose header names `model_id`."""
    try:
        valid = json.loads(path.read_text(encoding="utf-8")).get("valid", [])
    except (OSError, ValueError):
        return []
    found = [bytes.fromhex(item["hex"]) for item in valid if isinstance(item.get("hex"), str)]
    return [d for d in found if len(d) > 3 and int.from_bytes(d[1:3], "big") == model_id][:MOST]
