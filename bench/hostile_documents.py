"""How long do hostile documents take? (issue: foundation, "every file finishes in well under
a second")

Each document is built to defeat a shortcut: a finding on every one of 100,000 elements, names
and values megabytes long, a one-line document with its findings at the far end, thousands of
entity references. Goal: each well under a second, whole process included. Anchor: xmllint
--noout on the same file, in the same run. Figures are the median of --runs runs.

    python bench/hostile_documents.py [--runs 3]
"""

from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

HEAD = '<rcml version="2.0" site="rctp://r"><access name="a">'
TAIL = "</access></rcml>\n"
N = 100_000


def elements(template: str, count: int = N, sep: str = "\n") -> str:
    return sep.join(template.format(i=i) for i in range(count))


DOCUMENTS: dict[str, Callable[[], str]] = {
    "unknown element x100k": lambda: HEAD + elements('<dta name="d{i}" type="int"/>') + TAIL,
    "bad name x100k": lambda: HEAD + elements('<data name="{i}d" type="int"/>') + TAIL,
    "same name x100k": lambda: HEAD + elements('<data name="d" type="int"/>') + TAIL,
    "unknown attribute x100k": lambda: (
        HEAD + elements('<data name="d{i}" type="int" t="1"/>') + TAIL
    ),
    "3 MB attribute name": lambda: (
        HEAD + f'<data name="d" type="int" {"x" * 3_000_000}="1"/>' + TAIL
    ),
    "3 MB attribute value": lambda: HEAD + f'<data name="{"x" * 3_000_000}" type="int"/>' + TAIL,
    "one line, findings at its end": lambda: (
        HEAD
        + elements('<data name="d{i}" type="int"/>', sep="")
        + elements('<dta name="d{i}"/>', count=1000, sep="")
        + TAIL
    ),
    "entity references x40k": lambda: (
        '<!DOCTYPE rcml SYSTEM "rcml.dtd">\n'
        + HEAD
        + elements('<data name="d{i}" type="int">&x;</data>', count=40_000)
        + TAIL
    ),
    "billion laughs": lambda: (
        '<!DOCTYPE rcml [<!ENTITY a "aaaaaaaaaa">'
        + "".join(f'<!ENTITY {chr(98 + i)} "{("&" + chr(97 + i) + ";") * 10}">' for i in range(9))
        + ']><rcml title="&j;"/>'
    ),
    "256 levels": lambda: "<rcml>" + "<group>" * 255 + "</group>" * 255 + "</rcml>",
}


def median_time(command: list[str], runs: int) -> float:
    times = []
    for _ in range(runs):
        start = time.perf_counter()
        subprocess.run(
            command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, check=False, timeout=120
        )
        times.append(time.perf_counter() - start)
    return statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=3)
    args = parser.parse_args()
    rcmlconf = shutil.which("rcmlconf") or str(Path(sys.executable).parent / "rcmlconf")
    xmllint = shutil.which("xmllint")
    print(
        f"rcmlconf validate on hostile documents, median of {args.runs} runs "
        "(goal: well under a second each); anchor: xmllint --noout"
    )
    print(f"{'document':<32} {'bytes':>11} {'rcmlconf':>9} {'xmllint':>9}")
    with tempfile.TemporaryDirectory() as tmp:
        for name, build in DOCUMENTS.items():
            path = Path(tmp) / "hostile.rcml"
            path.write_text(build())
            ours = median_time([rcmlconf, "validate", "-q", str(path)], args.runs)
            theirs = median_time([xmllint, "--noout", str(path)], args.runs) if xmllint else None
            lint = f"{theirs:9.3f}" if theirs is not None else "        -"
            print(f"{name:<32} {path.stat().st_size:>11,} {ours:9.3f} {lint}")


if __name__ == "__main__":
    main()
