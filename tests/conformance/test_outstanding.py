"""Every answer a probe reads is matched to the oldest of its requests waiting (D-RCTP-6): its
CSeq must be that request's (R-RCTP-3), a later one's is an answer out of order (R-RCTP-5), and
one when none waits answers nothing (D-RCTP-10). What was sent broken is judged as far as it can
be. Bytes in, verdicts out: `Outstanding` is sans-IO."""

from __future__ import annotations

import pytest

from rcmlconf.conformance.probes.outstanding import Outstanding
from rcmlconf.conformance.verdicts import Failed
from rcmlconf.rctp.messages import Headers, Request, Response


def _request(method: str, target: str, *fields: str) -> bytes:
    return "\r\n".join([f"{method} {target} RCTP/2.0", *fields, "", ""]).encode()


def _answer(*cseqs: str, status: int = 200) -> Response:
    reason = {200: "OK", 400: "Bad Request"}[status]
    return Response(status, reason, Headers(tuple(("CSeq", cseq) for cseq in cseqs)))


def _sent(*requests: bytes) -> Outstanding:
    outstanding = Outstanding()
    for data in requests:
        outstanding.sent(data)
    return outstanding


def test_answers_in_order_pass_split_or_pipelined() -> None:
    connect = _request("CONNECT", "/rover", "CSeq: 1")
    outstanding = _sent(connect[:7], connect[7:] + _request("READ", "/a", "cseq:\t2"))
    outstanding.answered(_answer("1"))
    outstanding.answered(_answer("2"))
    assert outstanding.failure is None


def test_a_later_requests_cseq_is_an_answer_out_of_order() -> None:
    outstanding = _sent(_request("READ", "/a", "CSeq: 1") + _request("READ", "/b", "CSeq: 2"))
    with pytest.raises(Failed) as failed:
        outstanding.answered(_answer("2"))
    assert failed.value.requirement == "R-RCTP-5"
    assert failed.value.reason == (
        "expected the answer to CSeq 1 (READ /a); got 200 OK with CSeq 2 (READ /b, sent after"
        " it: answered out of order)"
    )


def test_a_second_answer_answers_no_request() -> None:
    outstanding = _sent(_request("CONNECT", "/rover", "CSeq: 1"))
    outstanding.answered(_answer("1"))
    with pytest.raises(Failed) as failed:
        outstanding.answered(_answer("1"))
    assert failed.value.requirement == "R-RCTP-3"
    assert "no request waits for one (D-RCTP-10)" in failed.value.reason
    assert "CSeq 1 (CONNECT /rover, answered already)" in failed.value.reason


def test_the_first_wrong_answer_is_kept_and_nothing_judged_after() -> None:
    outstanding = _sent(_request("ACQUIRE", "/", "CSeq: 3"))
    with pytest.raises(Failed) as failed:
        outstanding.answered(_answer("1"))
    assert (
        failed.value.reason == "expected the answer to CSeq 3 (ACQUIRE /); got 200 OK with CSeq 1"
    )
    outstanding.answered(_answer("9"))
    assert outstanding.failure is failed.value


def test_a_case_names_the_requirement_it_judges_the_cseq_under() -> None:
    outstanding = _sent(_request("WRITE", "/a", "CSeq: 4"))
    with pytest.raises(Failed) as failed:
        outstanding.answered(_answer("99"), "R-RCTP-6")
    assert failed.value.requirement == "R-RCTP-6"


def test_an_answer_without_cseq_to_a_request_that_has_one_fails() -> None:
    outstanding = _sent(_request("READ", "/a", "CSeq: 2"))
    with pytest.raises(Failed, match="got 200 OK without CSeq"):
        outstanding.answered(_answer())


def test_a_request_without_cseq_is_answered_without_one() -> None:
    _sent(_request("CONNECT", "/rover")).answered(_answer(status=400))
    with pytest.raises(Failed) as failed:
        _sent(_request("BYE", "*")).answered(_answer("1", status=400))
    assert failed.value.requirement == "R-RCTP-3"
    assert "BYE *, sent without one readable CSeq" in failed.value.reason


def test_an_unreadable_cseq_may_be_echoed() -> None:
    _sent(_request("READ", "/a", "CSeq: abc")).answered(_answer(status=400))
    _sent(_request("READ", "/a", "CSeq: abc")).answered(_answer("abc", status=400))
    _sent(_request("BYE", "*", "CSeq: 1", "CSeq: 1")).answered(_answer("1", status=400))
    with pytest.raises(Failed):
        _sent(_request("READ", "/a", "CSeq: abc")).answered(_answer("7", status=400))


def test_what_did_not_frame_is_not_judged() -> None:
    """D-RCTP-10: a request that does not frame may be answered with any CSeq (which its
    receiver may have read); what was sent after it is not known."""
    outstanding = _sent(_request("READ", "/a", "CSeq: 1"), b"READ /b RCTP/2.0\nCSeq: 2\n\n")
    outstanding.answered(_answer("1"))
    outstanding.answered(_answer("2", status=400))
    outstanding.answered(_answer("2", status=400))
    assert outstanding.failure is None
    # A broken answer of the probe's own is owed no answer; what follows it is not known.
    outstanding = _sent(b"RCTP/2.0 200 OK\nCSeq: 1\n\n")
    outstanding.answered(_answer("5"))
    assert outstanding.failure is None


def test_a_request_not_yet_whole_may_be_answered() -> None:
    """A receiver may refuse a head past a limit before its end (D-RCTP-9)."""
    outstanding = _sent(b"READ /a RCTP/2.0\r\nCSeq: 1\r\nX-Long: xxx")
    outstanding.answered(_answer(status=400))
    assert outstanding.failure is None


def test_answers_of_the_probes_own_do_not_wait_for_answers() -> None:
    outstanding = _sent(b"RCTP/2.0 200 OK\r\nCSeq: 1\r\n\r\n")
    with pytest.raises(Failed, match="no request waits"):
        outstanding.answered(_answer("1"))


def test_a_servers_request_before_the_session_is_refused_454() -> None:
    """D-RCTP-13: in idle only CONNECT is valid, as the core's checks say, for a client too."""
    bye = Request("BYE", "*", Headers((("CSeq", "1"),)))
    outstanding = _sent(_request("CONNECT", "/rover", "CSeq: 1"))
    assert outstanding.idle_refusal(bye) == (454, "Session Not Found")
    outstanding.answered(_answer("1", status=400))
    assert outstanding.idle_refusal(bye) == (454, "Session Not Found")
    outstanding.sent(_request("CONNECT", "/rover", "CSeq: 2"))
    outstanding.answered(_answer("2"))
    assert outstanding.idle_refusal(bye) is None


def test_an_answer_that_says_the_request_did_not_frame_is_a_doubt_not_a_failure() -> None:
    """A 400 without CSeq to a request the harness framed: its receiver says it could not
    frame it. The case judges the status first; the missing CSeq fails it only if nothing else
    does (`doubt`). What follows is not judged: the receiver closes after it (D-RCTP-10)."""
    outstanding = _sent(
        _request("CONNECT", "/rover", "CSeq: 1") + _request("READ", "/a", "CSeq: 2")
    )
    outstanding.answered(_answer(status=400))
    outstanding.answered(_answer("7"))
    assert outstanding.failure is None
    assert outstanding.doubt is not None
    assert outstanding.doubt.requirement == "R-RCTP-3"
    assert outstanding.doubt.reason == (
        "expected the answer to CSeq 1 (CONNECT /rover); got 400 Bad Request without CSeq"
    )


def test_a_200_without_cseq_is_a_failure_at_once() -> None:
    outstanding = _sent(_request("CONNECT", "/rover", "CSeq: 1"))
    with pytest.raises(Failed) as failed:
        outstanding.answered(_answer())
    assert failed.value.requirement == "R-RCTP-3"
    assert outstanding.doubt is None
