"""The run's reports: JUnit XML valid against the schema CI reporters read, the JSON report, the
baseline of known failures, the pcap of a case's traffic."""

from __future__ import annotations

import io
import json
from dataclasses import replace
from pathlib import Path

import pytest
from lxml import etree
from scapy.layers.inet import IP, TCP, UDP
from scapy.utils import rdpcap
from support.report_schemas import assert_junit_valid, assert_run_report_valid

from rcmlconf.conformance.registry import all_cases
from rcmlconf.conformance.reports.baseline import BaselineError, load_baseline, mark_known
from rcmlconf.conformance.reports.json_report import to_json
from rcmlconf.conformance.reports.junit import to_junit
from rcmlconf.conformance.reports.summary import explain
from rcmlconf.conformance.verdicts import Result, Verdict
from rcmlconf.pcap.writer import MSS, Payload, write_pcap

SPAN = (0.0, 1.0)


def failure(case: str, exchange: tuple[str, ...]) -> Result:
    """A failure of R-RCTP-9 by `case`, after `exchange`."""
    return Result(
        case=case,
        verdict=Verdict.FAIL,
        duration=0.2,
        reason="expected 501; got 200 OK",
        requirement="R-RCTP-9",
        expected=("501",),
        actual="200 OK",
        exchange=exchange,
    )


def results() -> list[Result]:
    ids = list(all_cases())
    failed = failure(ids[1], ("  0.001  -> FROB / RCTP/2.0\x01⏎",))
    return [
        Result(case=ids[0], verdict=Verdict.PASS, duration=0.01, ended=100.0),
        failed,
        Result(case=ids[2], verdict=Verdict.ERROR, duration=0.0, reason="network error: refused"),
        Result(
            case=ids[3],
            verdict=Verdict.NOT_APPLICABLE,
            duration=0.0,
            reason="the robot has no stream access",
        ),
        Result(
            case=ids[4],
            verdict=Verdict.INCONCLUSIVE,
            duration=0.1,
            reason="CONNECT was answered 503",
        ),
        replace(failed, reason="again", exchange=(), run=2),
    ]


def test_junit_is_valid_for_jenkins_and_counts_every_verdict() -> None:
    cases = all_cases()
    written = to_junit(results(), cases, 10.0, 12.5)
    assert_junit_valid(written)
    document = etree.fromstring(written)
    assert document.get("tests") == "6"
    assert (document.get("failures"), document.get("errors")) == ("2", "1")
    assert document.get("skipped") is None  # Jenkins' schema refuses it on <testsuites>
    assert sum(int(s.get("skipped", "0")) for s in document.iter("testsuite")) == 2
    assert document.get("time") == "2.500"  # the run's wall time, not the sum of the cases'
    skipped = document.find(".//testcase/skipped")
    assert skipped is not None
    assert not skipped.attrib  # text alone, as Jenkins' schema has it
    assert (skipped.text or "").startswith(("not applicable: ", "inconclusive: "))
    failure = document.find(".//testcase/failure")
    assert failure is not None
    assert failure.get("type") == "R-RCTP-9"
    assert "\\x01" in (failure.text or "")  # a control character of the transcript, escaped
    names = [c.get("name") for c in document.iter("testcase")]
    assert f"{results()[1].case} (run 2)" in names
    classnames = {c.get("classname") for c in document.iter("testcase")}
    assert classnames == {cases[r.case].area for r in results()}


def test_an_area_s_suite_time_is_the_span_its_cases_ran_in_not_their_sum() -> None:
    """Cases run side by side: two of 1 s and 1.5 s that overlap took 1.5 s of the run."""
    cases = all_cases()
    first, second = [c.id for c in cases.values() if c.area == "rctp/msg"][:2]
    both = [
        Result(case=first, verdict=Verdict.PASS, duration=1.0, ended=11.0),
        Result(case=second, verdict=Verdict.PASS, duration=1.5, ended=11.2),
    ]
    suite = etree.fromstring(to_junit(both, cases, 9.0, 12.0)).find("testsuite")
    assert suite is not None
    assert suite.get("time") == "1.500"
    assert suite.get("timestamp") == "1970-01-01T00:00:09"


def test_json_report_holds_every_result_with_its_case() -> None:
    report = to_json(results(), all_cases(), "the target", {"seed": 3}, (10.0, 12.5))
    assert_run_report_valid(report)
    assert (report["version"], report["duration"]) == (2, 2.5)
    assert report["started"] == "1970-01-01T00:00:10.000+00:00"
    assert report["counts"]["fail"] == 2
    assert report["settings"] == {"seed": 3}
    failed = report["results"][1]
    assert failed["verdict"] == "fail"
    assert failed["requirement"] == "R-RCTP-9"
    assert failed["expected"] == ["501"]
    json.dumps(report)


def test_a_baseline_of_ids_or_of_a_report_marks_those_failures_known(tmp_path: Path) -> None:
    found = results()
    listed = tmp_path / "known.txt"
    listed.write_text(f"# known\n{found[1].case}  # flaky\n\n")
    assert load_baseline(listed) == {found[1].case}
    report = tmp_path / "report.json"
    report.write_text(json.dumps(to_json(found, all_cases(), "t", {}, SPAN)))
    assert load_baseline(report) == {found[1].case, found[2].case}
    marked = mark_known(found, frozenset({found[1].case, found[0].case}))
    assert [r.known for r in marked] == [False, True, False, False, False, True]
    broken = tmp_path / "broken.json"
    broken.write_text('{"results": 3}')
    with pytest.raises(BaselineError, match="not a report"):
        load_baseline(broken)


def test_a_capture_reads_back_as_the_connection_and_datagrams_it_was() -> None:
    client, server = ("127.0.0.1", 40000), ("127.0.0.1", 7330)
    big = bytes(range(256)) * 12  # more than one segment
    payloads = [
        Payload(1.5, "tcp", client, server, b"CONNECT / RCTP/2.0\r\nCSeq: 1\r\n\r\n"),
        Payload(1.6, "tcp", server, client, big),
        Payload(1.7, "udp", client, ("127.0.0.1", 7331), b"\x02\x00datagram"),
    ]
    file = io.BytesIO()
    write_pcap(file, payloads)
    file.seek(0)
    packets = list(rdpcap(file))
    flags = [str(p[TCP].flags) for p in packets if TCP in p]
    assert flags[:3] == ["S", "SA", "A"]
    data = [bytes(p[TCP].payload) for p in packets if TCP in p and p[TCP].payload]
    assert data[0] == payloads[0].data
    assert b"".join(data[1:]) == big
    assert max(len(d) for d in data) == MSS
    replies = [p for p in packets if TCP in p and p[TCP].sport == server[1] and p[TCP].payload]
    assert replies[1][TCP].seq == replies[0][TCP].seq + MSS
    assert bytes(packets[-1][UDP].payload) == payloads[2].data
    for packet in packets:  # every checksum as the kernel would have computed it
        raw = bytes(packet)
        again = IP(raw)
        del again.chksum
        del again[TCP if TCP in again else UDP].chksum
        assert bytes(again) == raw


def test_a_long_exchange_is_whole_in_json_and_its_end_in_the_text_report() -> None:
    case = next(iter(all_cases().values()))
    lines = tuple(f"{i:7.3f}  c1 -> line {i}" for i in range(100))
    failed = failure(case.id, lines)
    exchange = to_json([failed], all_cases(), "t", {}, SPAN)["results"][0]["exchange"]
    assert [(e["time"], e["direction"], e["channel"], e["summary"]) for e in exchange] == [
        (float(i), "sent", "c1", f"line {i}") for i in range(100)
    ]
    shown = [text for name, text in explain(failed, case, {}) if name == "exchange"]
    assert shown[0] == "... 60 lines before (--json has them)"
    assert shown[1:] == list(lines[-40:])
