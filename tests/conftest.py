"""Test-wide settings."""

import os
import signal

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
