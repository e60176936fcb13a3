"""How fast is `rcmlconf validate`? (issue: foundation, "Speed")

Goals: a small file in <= 0.30 s wall, interpreter start included; a 100,000-data-node file in
<= 0.60 s, where "xmllint parses it in about 0.1 s": at most 6 times xmllint. Anchor: xmllint
--noout on the same files, measured in the same run (the machine is shared and noisy, so only
figures taken side by side compare; the ratio is the figure that travels). Each figure is the
median of --runs whole-process runs, with the fastest run beside it.

    python bench/validate_speed.py [--runs 9]
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
SMALL = ROOT / "vectors" / "xml" / "valid" / "appendix-a-corrected.rcml"


def big_document(groups: int = 100, per_access: int = 1000) -> bytes:
    """100 groups of one stream access with 1,000 data nodes: 100,000 data nodes, ~3.5 MB."""
    types = ("int", "float32", "uint8", "bool", "double")
    parts = [
        '<?xml version="1.0" encoding="UTF-8"?>',
        '<rcml version="2.0" site="rctp://robot.example:5000/" title="bench">',
    ]
    for g in range(groups):
        parts.append(f'<group name="g{g}" permission="rw">')
        parts.append('  <access name="sensors" type="normal" permission="r">')
        parts.extend(
            f'    <data name="s{d}" type="{types[d % len(types)]}"/>' for d in range(per_access)
        )
        parts.append("  </access>")
        parts.append("</group>")
    parts.append("</rcml>")
    return "\n".join(parts).encode()


def timed(command: list[str], runs: int) -> tuple[float, float]:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        done = subprocess.run(
            command, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, check=False
        )
        times.append(time.perf_counter() - start)
        if done.returncode not in (0,):
            sys.exit(f"{' '.join(command)} failed ({done.returncode}): {done.stderr.decode()}")
    return statistics.median(times), min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=9)
    args = parser.parse_args()
    rcmlconf = shutil.which("rcmlconf") or str(Path(sys.executable).parent / "rcmlconf")
    xmllint = shutil.which("xmllint")
    with tempfile.TemporaryDirectory() as tmp:
        big = Path(tmp) / "big.rcml"
        big.write_bytes(big_document())
        rows = []
        for label, path, goal in (("small file", SMALL, 0.30), ("100,000 data nodes", big, 0.60)):
            median, best = timed([rcmlconf, "validate", "-q", str(path)], args.runs)
            anchor = timed([xmllint, "--noout", str(path)], args.runs) if xmllint else None
            rows.append((label, path.stat().st_size, median, best, goal, anchor))
    print(f"rcmlconf validate, median (fastest) of {args.runs} runs; anchor: xmllint --noout")
    print("goal for 100,000 data nodes: 0.60 s, i.e. at most 6.0x xmllint (the issue's 0.1 s)")
    print(f"{'file':<20} {'bytes':>10} {'rcmlconf':>16} {'goal':>7} {'xmllint':>16} {'ratio':>6}")
    for label, size, median, best, goal, anchor in rows:
        mark = "ok" if median <= goal else "OVER"
        lint = f"{anchor[0]:.3f} ({anchor[1]:.3f})" if anchor else "not installed"
        ratio = f"{median / anchor[0]:.1f}x" if anchor else "-"
        print(
            f"{label:<20} {size:>10,} {median:>7.3f} ({best:.3f}) {goal:>5.2f} {mark:<4}"
            f" {lint:>16} {ratio:>6}"
        )


if __name__ == "__main__":
    main()
