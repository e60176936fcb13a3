"""The client cases the MUST-by-MUST audit added or tightened (bench/audit_rctp_client.md): each
fails a reference client made to make the fault it is aimed at, naming the requirement that
fault breaks (the reference and the independent client of tests/foreign/rctp_client pass them:
tests/foreign/test_foreign.py). The faulty client is a copy of the package with one line changed
(`mutated`), started by the installed harness for the case (`--client-command`) as a client
author's CI starts theirs. Real processes on loopback."""

from __future__ import annotations

import json
import shlex
import sys
from pathlib import Path

import pytest
from support.mutants import mutated
from support.processes import free_pair, run_command

#: (module under rcmlconf/, the line, the line as the fault reads, the case, the requirement it
#: must fail naming).
FAULTS = {
    # The read timeout's owner takes any timeout (D-RCTP-22, R-RCTP-47's second half).
    "any-timeout-set": (
        "rctp/datastream/endpoint.py",
        "        if request.timeout < 2 * stream.intervals[request.direction]:  # R-RCTP-47",
        "        if False:  # R-RCTP-47",
        "rctp/client/flow-answers",
        "R-RCTP-47",
    ),
    # A decoder that stops at the last value and takes the body whatever follows.
    "trailing-bytes-ignored": (
        "rctp/bodies.py",
        "        if not buf.eof():",
        "        if False:",
        "rctp/client/stream-undecodable-not-taken",
        "R-RCTP-58",
    ),
    # A packet parser that takes the payloads it found, whatever follows them.
    "stray-bytes-ignored": (
        "rctp/datastream/packets.py",
        "    if position != size:",
        "    if False:",
        "rctp/client/stream-broken-framing-dropped",
        "R-RCTP-42",
    ),
    # Sequence numbers compared as plain integers, not serial numbers (D-RCTP-21, RFC 1982).
    "plain-comparison": (
        "rctp/datastream/order.py",
        "        if self._seen[sequence]:",
        "        if sequence > highest & _MASK:\n            return _NEWER\n"
        "        if self._seen[sequence]:",
        "rctp/client/stream-stale-not-taken",
        "R-RCTP-43",
    ),
    # A request line's limit off by one: 4,096 bytes refused (414).
    "start-line-off-by-one": (
        "rctp/reader.py",
        "        if len(lines[0]) > self.limits.start_line:",
        "        if len(lines[0]) >= self.limits.start_line:",
        "rctp/client/request-at-limits",
        "R-RCTP-68",
    ),
    # Only CSeq checked for repetition among the fields that appear once.
    "only-cseq-once": (
        "rctp/request_checks.py",
        "        if names.count(name.lower()) > 1:",
        '        if name == "CSeq" and names.count(name.lower()) > 1:',
        "rctp/client/session-twice",
        "R-RCTP-11",
    ),
    # A STOP taken only while playing, not while paused (D-RCTP-14).
    "stop-of-ready-refused": (
        "rctp/states.py",
        '    (_T.READY, "STOP"): _T.INIT,\n',
        "",
        "rctp/client/stop-while-paused",
        "R-RCTP-24",
    ),
    # A push must list every node of its access (D-RCTP-27 lists those changed).
    "push-of-all-nodes-only": (
        "reference/client/session.py",
        "        if not set(names) <= by_name.keys():",
        "        if set(names) != by_name.keys():",
        "rctp/client/event-push-one-node",
        "R-RCTP-24",
    ),
    # A FLOW request whose fields do not fit its operation answered as an unknown operation.
    "nack-1-for-malformed": (
        "rctp/datastream/packets.py",
        "        return NackReason.MALFORMED\n",
        "        return NackReason.UNKNOWN_OPERATION\n",
        "rctp/client/flow-answers",
        "R-RCTP-53",
    ),
    # A target's segments not checked for XML Names (D-RCTP-7).
    "target-names-unchecked": (
        "rctp/targets.py",
        "        if not is_name(name):",
        "        if not name:",
        "rctp/client/bad-target",
        "R-RCTP-15",
    ),
    # Nodes checked for repeated names, not for their order (D-RCTP-17).
    "nodes-order-unchecked": (
        "rctp/fields.py",
        "    if list(names) != sorted(set(names)):",
        "    if len(names) != len(set(names)):",
        "rctp/client/event-push-nodes-backwards",
        "R-RCTP-30",
    ),
    # An answer when nothing is waiting for one skipped, not taken for the end of the connection.
    "answer-to-nothing-skipped": (
        "rctp/connection.py",
        "        if not self._sent:\n",
        "        if not self._sent:\n            return None\n        if False:\n",
        "rctp/client/answer-to-nothing",
        "R-RCTP-12",
    ),
    # A reader that drops what follows an answer in the same segment.
    "rest-after-answer-dropped": (
        "rctp/reader.py",
        "        if not body:\n            return message\n",
        "        if not body:\n            if isinstance(message, Response):\n"
        "                self._buffer.clear()\n            return message\n",
        "rctp/client/answer-and-request-together",
        "R-RCTP-13",
    ),
    # The answer to its own BYE awaited 30 s, not 5 (R-RCTP-23); the core's deadline too (ALSO).
    "bye-answer-awaited-long": (
        "reference/client/scenario.py",
        "                await client.close(min(timeout, BYE_WAIT))",
        "                await client.close(30.0)",
        "rctp/client/bye-unanswered-closes",
        "R-RCTP-23",
    ),
    # The connection closed as soon as its own BYE is sent, not once answered or after 5 s.
    "bye-answer-not-awaited": (
        "reference/client/scenario.py",
        "                await client.close(min(timeout, BYE_WAIT))",
        "                await client.close(0.1)",
        "rctp/client/bye-unanswered-closes",
        "R-RCTP-23",
    ),
    # A FLOW request about any stream id answered for the stream set up (D-RCTP-22: NACK 2).
    "any-stream-answered": (
        "rctp/datastream/endpoint.py",
        "        stream = self.streams.get(stream_id)\n        if stream is None or",
        "        stream = self.streams.get(stream_id) or next(iter(self.streams.values()), None)\n"
        "        if stream is None or",
        "rctp/client/flow-answers",
        "R-RCTP-46",
    ),
    # A packet read no further once a FLOW body that is no request proves broken.
    "broken-answer-ends-packet": (
        "rctp/datastream/endpoint.py",
        "            _RECEIVE[type(payload)](self, packet, index, arrival, now)\n",
        "            if isinstance(payload, MalformedFlowPayload) and payload.answer is None:\n"
        "                break\n"
        "            _RECEIVE[type(payload)](self, packet, index, arrival, now)\n",
        "rctp/client/stream-broken-flow-beside-data",
        "R-RCTP-53",
    ),
    # A server WRITE taken while its access is paused, not only while it plays (D-RCTP-26).
    "push-while-paused-taken": (
        "rctp/states.py",
        "PUSH_STATES = frozenset({_T.PLAYING})",
        "PUSH_STATES = frozenset({_T.PLAYING, _T.READY})",
        "rctp/client/event-push-paused",
        "R-RCTP-68",
    ),
    # Nodes checked for their order alone: a name twice in a row passes (R-RCTP-30: each once).
    "nodes-repeat-unchecked": (
        "rctp/fields.py",
        "    if list(names) != sorted(set(names)):",
        "    if list(names) != sorted(names):",
        "rctp/client/event-push-nodes-repeated",
        "R-RCTP-30",
    ),
    # A set of the interval taken whoever owns it (D-RCTP-22: its sender, else NACK 4).
    "interval-set-of-either-direction": (
        "rctp/datastream/endpoint.py",
        "            if request.direction is not self.sends:",
        "            if False:",
        "rctp/client/flow-answers",
        "R-RCTP-46",
    ),
}
#: The line of another module some faults change too: (module, the line, as the fault reads).
ALSO = {
    # The reference client's core closes a connection 5 s after an unanswered BYE by itself.
    "bye-answer-awaited-long": (
        "rctp/connection.py",
        "            self._bye_deadline = now + BYE_WAIT\n",
        "            self._bye_deadline = now + 30.0\n",
    ),
}


@pytest.mark.parametrize("fault", sorted(FAULTS))
def test_the_case_fails_a_client_with_the_fault(fault: str, tmp_path: Path) -> None:
    module, line, wrong, case, requirement = FAULTS[fault]
    copy = mutated(tmp_path, module, (line, wrong))
    if fault in ALSO:
        also, line, wrong = ALSO[fault]
        source = copy / "rcmlconf" / also
        assert source.read_text().count(line) == 1, f"{also} no longer has {line!r} once"
        source.write_text(source.read_text().replace(line, wrong))
    # -P: the copy, not the package of the directory the harness runs in (D-RCTP-31's client).
    client = ["env", f"PYTHONPATH={copy}", sys.executable, "-P", "-m", "rcmlconf", "client"]
    report = tmp_path / "report.json"
    run_command(
        "run",
        *("--role", "client", "--listen", str(free_pair())),
        *("--client-command", shlex.join(client) + " {url} scenario"),
        *("--only", case, "--json", str(report)),
    )
    (result,) = json.loads(report.read_text())["results"]
    assert (result["verdict"], result["requirement"]) == ("fail", requirement), result
