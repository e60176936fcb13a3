"""The map of states reached against mutation kinds (D-FUZZ-5): where the fuzzer has been, and
where it should go next.

Each cell counts the test cases that reached a state (its prefix answered as it should) and
then sent a kind of mutation there. The next cell is drawn with weight 1 / (1 + count), so
effort goes where the map is thin, as AFLNet favours the states it has exercised least. Effort
is time: a state whose cases take longer than the quickest state's (its prefix waits out a
timer), by the median of its last cases, is drawn as many times less; a rare slow case (a
hang) does not move a median. A state whose prefix keeps failing is tried less,
never dropped: a target may refuse it only now.
"""

from __future__ import annotations

import itertools
import random
import shutil
import statistics
import subprocess
from collections import Counter, defaultdict, deque
from pathlib import Path
from typing import Any

#: How many of each state's last case times the map keeps, for their median.
TIMES_KEPT = 50


class StateMap:
    def __init__(self, kinds: dict[str, tuple[str, ...]]) -> None:
        #: state -> the kinds that apply there.
        self.kinds = kinds
        self.reached: Counter[tuple[str, str]] = Counter()
        self.missed: Counter[str] = Counter()
        #: (state, the answers' status codes): AFLNet's response-code feedback.
        self.seen: set[tuple[str, tuple[int, ...]]] = set()
        #: Findings fired per cell: a cell that keeps firing a known finding is drawn less.
        self.fired: Counter[tuple[str, str]] = Counter()
        self.fired_kinds: Counter[str] = Counter()
        #: The seconds the last cases of each state took, reached or not.
        self.took: dict[str, deque[float]] = defaultdict(lambda: deque(maxlen=TIMES_KEPT))

    def pick(self, rng: random.Random) -> tuple[str, str]:
        cells = [(s, k) for s, kinds in self.kinds.items() for k in kinds]
        slower = self._slower()
        weights = [
            1.0
            / (1 + self.reached[cell])
            / (1 + self.missed[cell[0]] / 10)
            / (1 + 4 * self.fired[cell] + self.fired_kinds[cell[1]])
            / slower.get(cell[0], 1.0)
            for cell in cells
        ]
        return rng.choices(cells, weights)[0]

    def _slower(self) -> dict[str, float]:
        """How many times longer each state's cases take than the quickest state's, by their
        medians (1 at the least, and for a state not yet run)."""
        medians = {state: statistics.median(times) for state, times in self.took.items() if times}
        quickest = min((median for median in medians.values() if median > 0), default=0.0)
        if not quickest:
            return {}
        return {state: max(1.0, median / quickest) for state, median in medians.items()}

    def found(self, state: str, kind: str) -> None:
        """A finding fired in this cell: draw it, and its kind elsewhere, less from now on."""
        self.fired[(state, kind)] += 1
        self.fired_kinds[kind] += 1

    def record(
        self, state: str, kind: str, reached: bool, statuses: tuple[int, ...], seconds: float = 0.0
    ) -> bool:
        """Count a case that took `seconds`; True when its answers were new in that state (the
        corpus keeps it)."""
        self.took[state].append(seconds)
        if not reached:
            self.missed[state] += 1
            return False
        self.reached[(state, kind)] += 1
        key = (state, statuses)
        if key in self.seen:
            return False
        self.seen.add(key)
        return True

    @property
    def states_reached(self) -> int:
        return len({state for state, _ in self.reached})

    def table(self) -> list[list[str]]:
        """Rows of state, then cases per kind, for a report; the first row names the columns."""
        kinds = sorted({k for ks in self.kinds.values() for k in ks})
        rows = [["state", "missed", *kinds]]
        for state in self.kinds:
            counts = [
                str(self.reached[(state, k)]) if k in self.kinds[state] else "" for k in kinds
            ]
            rows.append([state, str(self.missed[state]), *counts])
        return rows

    def dot(self, order: tuple[str, ...]) -> str:
        """Graphviz: the states as the prefixes chain them, each labelled with its cases."""
        lines = ["digraph states {", "  rankdir=LR;", '  node [shape=box, fontname="Helvetica"];']
        for state in order:
            total = sum(n for (s, _), n in self.reached.items() if s == state)
            thin = min((self.reached[(state, k)] for k in self.kinds.get(state, ())), default=0)
            missed = self.missed[state]
            label = f"{state}\\n{total} cases, thinnest kind {thin}\\nprefix failed {missed}"
            lines.append(f'  "{state}" [label="{label}"];')
        for before, after in itertools.pairwise(order):
            lines.append(f'  "{before}" -> "{after}";')
        lines.append("}")
        return "\n".join(lines) + "\n"

    def write(self, directory: Path, order: tuple[str, ...]) -> list[Path]:
        """states.dot, and states.png where Graphviz's `dot` is installed."""
        dot = directory / "states.dot"
        dot.write_text(self.dot(order), encoding="utf-8")
        written = [dot]
        program = shutil.which("dot")
        if program is not None:
            png = directory / "states.png"
            done = subprocess.run(
                [program, "-Tpng", str(dot), "-o", str(png)], capture_output=True, timeout=30
            )
            if done.returncode == 0:
                written.append(png)
        return written

    def to_json(self) -> dict[str, Any]:
        return {
            "reached": [[s, k, n] for (s, k), n in sorted(self.reached.items())],
            "missed": dict(self.missed),
            "seen": [[s, list(codes)] for s, codes in sorted(self.seen)],
            "took": {state: [round(t, 6) for t in times] for state, times in self.took.items()},
        }

    def load(self, item: dict[str, Any]) -> None:
        for state, kind, count in item["reached"]:
            self.reached[(str(state), str(kind))] += int(count)
        self.missed.update({str(k): int(v) for k, v in item["missed"].items()})
        self.seen |= {(str(s), tuple(int(c) for c in codes)) for s, codes in item["seen"]}
        for state, times in item.get("took", {}).items():  # absent before it was kept
            self.took[str(state)].extend(float(t) for t in times)
