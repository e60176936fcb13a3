"""`python -m cProfile -o F -m rcmlconf ...`: the console wrapper ends a profiled run through the
interpreter's shutdown, so the profile is written (unprofiled, it leaves without that shutdown,
which would only free objects one by one)."""

from __future__ import annotations

import pstats
import subprocess
import sys
from pathlib import Path

from support.processes import BOUND

ROOT = Path(__file__).resolve().parents[2]


def test_a_profiled_run_writes_its_profile(tmp_path: Path) -> None:
    profile = tmp_path / "validate.prof"
    invalid = ROOT / "vectors" / "xml" / "invalid" / "appendix-a-as-printed.rcml"
    profiled = [sys.executable, "-m", "cProfile", "-o", str(profile), "-m", "rcmlconf"]
    done = subprocess.run(
        [*profiled, "validate", str(invalid)],
        capture_output=True,
        text=True,
        timeout=BOUND,
        check=False,
    )
    # cProfile's own main() ends 0 whatever the script's status: only the output tells.
    assert "R-XML-1" in done.stdout, done.stderr
    functions = pstats.Stats(str(profile)).get_stats_profile().func_profiles
    assert "validate_file" in functions
