"""How long a run waits, by default, for what its target does in its own time: `run
--session-wait` and `run --connect-timeout`. Light: `rcmlconf run`'s options read it before the
harness is imported."""

from __future__ import annotations

#: The longest session timeout (D-RCTP-11) the cases that wait one out wait for, by default
#: (`run --session-wait`): a server that announces longer makes them inconclusive.
SESSION_WAIT = 5.0
#: How long a client or local system started for a case has to connect, by default (`run
#: --connect-timeout`).
CONNECT_TIMEOUT = 10.0
