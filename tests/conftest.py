"""Test-wide settings."""

import compileall
import os
import signal
from pathlib import Path

import pytest
from hypothesis import HealthCheck, settings

# The machine is shared and noisy: no per-example deadline. CI runs more examples.
settings.register_profile(
    "default", deadline=None, max_examples=200, suppress_health_check=[HealthCheck.too_slow]
)
settings.register_profile(
    "ci",
    deadline=None,
    # 300, not 500: the 15-minute budget (each codec's properties still see 1.5 times the
    # examples of a developer's run).
    max_examples=300,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile(os.environ.get("HYPOTHESIS_PROFILE", "default"))

# The tests that stop a process as Ctrl-C does need SIGINT to reach it. A shell without job
# control that starts the suite in the background hands it an ignored SIGINT, which every child
# keeps across exec; a handler here is reset to the default in each child instead.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


#: The sources that the tests start as processes, hundreds of times over.
STARTED = [Path(__file__).parents[1] / "rcmlconf", Path(__file__).parent / "foreign"]


def pytest_sessionstart(session: pytest.Session) -> None:
    """Compile the started sources to bytecode once, before any test (in the controller only).

    An editable install leaves them uncompiled, and where PYTHONDONTWRITEBYTECODE is set (many
    CI images set it) no process writes the bytecode it compiles. Each `rcmlconf` process then
    compiles its 300 modules again: 1.0 s of CPU a `rcmlconf run`, against 0.33 s from
    bytecode. The variable stops only writing: a process still reads what is here.
    """
    if hasattr(session.config, "workerinput"):  # an xdist worker: the controller did it
        return
    for folder in STARTED:
        compileall.compile_dir(folder, quiet=1, workers=0)
