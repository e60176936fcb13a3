"""--html: the run as one self-contained HTML page (no file, font or script fetched: it works
offline and as a CI artifact), made from the JSON report (`json_report.to_json`).

A summary of verdicts by area; filters by verdict, area and requirement; and for each result
its case's purpose and requirements (with their text), what was expected and what happened,
the exchange (every message and datagram, with its time), and for a case that received
datagrams a small plot of their intervals (the jitter) and of the losses. A run with --verify
lists its unstable cases first, and each of their results says so."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from html import escape
from typing import Any

from rcmlconf.conformance.reports.plot import interval_plot

#: One verdict's colour, as the terminal's table has them.
_COLOURS = {
    "pass": "#1a7f37",
    "fail": "#cf222e",
    "inconclusive": "#9a6700",
    "not applicable": "#6e7781",
    "error": "#8250df",
}
#: Hex digits of a payload shown under its line (80 bytes; --json has them all).
_SHOWN_HEX = 160
#: Nothing is fetched, whatever a report holds: the page's own style and script only.
_POLICY = "default-src 'none'; style-src 'unsafe-inline'; script-src 'unsafe-inline'; img-src data:"
_STYLE = """
body { font: 14px system-ui, sans-serif; margin: 1.5em; color: #1f2328; }
h1 { font-size: 1.4em; } table { border-collapse: collapse; }
td, th { padding: 2px 10px; text-align: right; }
th:first-child, td:first-child { text-align: left; }
.badge { display: inline-block; min-width: 8em; color: #fff; border-radius: 3px; padding: 0 6px; }
details.case { border-bottom: 1px solid #d0d7de; padding: 3px 0; }
details.case > summary { cursor: pointer; }
.filters { margin: 1em 0; display: flex; gap: 1em; align-items: center; }
dl { display: grid; grid-template-columns: max-content auto; gap: 2px 12px; margin: .5em 1em; }
dt { color: #57606a; } dd { margin: 0; }
table.exchange td { text-align: left; font: 12px ui-monospace, monospace; vertical-align: top; }
table.exchange .sent { color: #0550ae; } table.exchange .received { color: #116329; }
table.exchange .withheld { color: #cf222e; } table.exchange .note { color: #57606a; }
.bytes { color: #6e7781; word-break: break-all; }
"""
_SCRIPT = """
const cases = [...document.querySelectorAll('details.case')];
const [verdict, area, requirement] = ['verdict', 'area', 'requirement'].map(
  (id) => document.getElementById(id));
function apply() {
  const wanted = requirement.value.trim().toLowerCase();
  let shown = 0;
  for (const item of cases) {
    const fits = (!verdict.value || item.dataset.verdict === verdict.value)
      && (!area.value || item.dataset.area === area.value)
      && (!wanted || item.dataset.requirements.toLowerCase().includes(wanted));
    item.hidden = !fits;
    shown += fits;
  }
  document.getElementById('shown').textContent = shown + ' of ' + cases.length + ' results';
}
for (const control of [verdict, area, requirement]) control.addEventListener('input', apply);
apply();
"""


def to_html(report: Mapping[str, Any], requirements: Mapping[str, str]) -> str:
    """The page of a JSON report; `requirements`: each requirement's ID to its text."""
    results: Sequence[Mapping[str, Any]] = report["results"]
    areas = sorted({_area(r["case"]) for r in results})
    verdicts = list(_COLOURS)
    title = f"rcmlconf run: {report['target']}"
    counts = ", ".join(f"{n} {v}" for v, n in report["counts"].items() if n)
    shaky = {u["case"]: _counted(u) for u in report.get("unstable", [])}
    parts = [
        "<!DOCTYPE html>",
        '<html lang="en"><head><meta charset="utf-8">',
        f'<meta http-equiv="Content-Security-Policy" content="{_POLICY}">',
        f"<title>{escape(title)}</title><style>{_STYLE}</style></head><body>",
        f"<h1>{escape(title)}</h1>",
        f"<p>Started {escape(report['started'])}, {report['duration']:g} s:"
        f" {len(results)} results: {escape(counts)}.</p>",
        _summary(results, areas, verdicts),
        _unstable(report),
        '<div class="filters">',
        _select("verdict", "every verdict", verdicts),
        _select("area", "every area", areas),
        '<label>requirement or case <input id="requirement" type="search"'
        ' placeholder="R-RCTP-9"></label>',
        '<span id="shown"></span></div>',
        *(_result(r, requirements, shaky.get(r["case"])) for r in results),
        f"<script>{_SCRIPT}</script></body></html>",
    ]
    return "\n".join(parts) + "\n"


def _area(case: str) -> str:
    return case.rsplit("/", 1)[0]


def _summary(results: Sequence[Mapping[str, Any]], areas: list[str], verdicts: list[str]) -> str:
    """Verdicts by area: one row an area, one column a verdict."""
    head = "".join(f"<th>{escape(v)}</th>" for v in verdicts)
    rows = [f'<table class="summary"><tr><th>area</th>{head}</tr>']
    for area in areas:
        found = [r["verdict"] for r in results if _area(r["case"]) == area]
        cells = "".join(f"<td>{found.count(v) or ''}</td>" for v in verdicts)
        rows.append(f"<tr><td>{escape(area)}</td>{cells}</tr>")
    rows.append("</table>")
    return "\n".join(rows)


def _counted(unstable: Mapping[str, Any]) -> str:
    """An unstable case's verdicts, such as `unstable: 9 pass, 1 inconclusive`."""
    return "unstable: " + ", ".join(f"{n} {v}" for v, n in unstable["verdicts"].items())


def _unstable(report: Mapping[str, Any]) -> str:
    """What --verify found; nothing for a run without it."""
    if "unstable" not in report:
        return ""
    found = report["unstable"]
    runs = report["settings"].get("verify")
    if not found:
        return f"<p>--verify: every case gave the same verdict in each of its {runs} runs.</p>"
    items = "".join(
        f'<li><b>{escape(u["case"])}</b> <span style="color:{_COLOURS["fail"]}">'
        f"{escape(_counted(u))}</span></li>"
        for u in found
    )
    return f"<h2>{len(found)} unstable (--verify {runs})</h2><ul>{items}</ul>"


def _select(name: str, everything: str, choices: list[str]) -> str:
    options = "".join(f'<option value="{escape(c)}">{escape(c)}</option>' for c in choices)
    return (
        f'<label>{name} <select id="{name}"><option value="">{everything}</option>'
        f"{options}</select></label>"
    )


def _result(
    result: Mapping[str, Any], requirements: Mapping[str, str], unstable: str | None
) -> str:
    """`unstable`: the verdicts of the case's runs if --verify found it unstable."""
    verdict = result["verdict"]
    ids = [*result["requirements"], *([result["requirement"]] if result["requirement"] else [])]
    searched = " ".join([result["case"], *ids])
    run = f" (run {result['run']})" if result["run"] > 1 else ""
    known = " (known)" if result["known"] else ""
    badge = f'<span class="badge" style="background:{_COLOURS[verdict]}">{verdict}{known}</span>'
    facts = [("purpose", escape(result["purpose"]))]
    if unstable is not None:
        facts.append(("verify", escape(unstable)))
    facts += [("requirement", _requirement(i, requirements)) for i in result["requirements"]]
    if result["requirement"]:
        facts.append(("broken", _requirement(result["requirement"], requirements)))
    if result["expected"]:
        facts.append(("expected", escape(" | ".join(result["expected"]))))
    if result["actual"] is not None:
        facts.append(("actual", escape(result["actual"])))
    if result["reason"]:
        facts.append(("why", escape(result["reason"])))
    if result["used"]:
        facts.append(("used", escape(", ".join(result["used"]))))
    if result["left_out"]:
        facts.append(("left out", escape("; ".join(_left_out(gap) for gap in result["left_out"]))))
    listed = "".join(f"<dt>{name}</dt><dd>{text}</dd>" for name, text in facts)
    exchange = result["exchange"]
    return "".join(
        [
            f'<details class="case" data-verdict="{escape(verdict)}"'
            f' data-area="{escape(_area(result["case"]))}" data-requirements="{escape(searched)}">',
            f"<summary>{badge} <b>{escape(result['case'])}</b>{run}"
            f" <small>{result['duration']:.3f} s</small></summary>",
            f"<dl>{listed}</dl>",
            interval_plot(exchange),
            _exchange(exchange) if exchange else "",
            "</details>",
        ]
    )


def _left_out(gap: Mapping[str, Any]) -> str:
    """What the exchange shown left out in one place (the JSON report's `left_out`)."""
    if gap["what"] == "lines":
        return f"{gap['count']} lines"
    where = f" {gap['source']} -> {gap['destination']}" if gap["source"] else " past 64 flows"
    return f"{gap['count']} {gap['what']} payloads ({gap['bytes']} bytes){where}"


def _requirement(identifier: str, requirements: Mapping[str, str]) -> str:
    text = requirements.get(identifier, "(not in specs/)")
    return f"<b>{escape(identifier)}</b> {escape(text)}"


def _exchange(entries: Sequence[Mapping[str, Any]]) -> str:
    rows = ['<table class="exchange">']
    for entry in entries:
        channel = escape(entry["channel"] or "")
        data = entry["bytes"] or ""
        more = "…" if len(data) > _SHOWN_HEX else ""
        shown = f'<div class="bytes">{data[:_SHOWN_HEX]}{more}</div>' if data else ""
        rows.append(
            f'<tr class="{entry["direction"]}"><td>{entry["time"]:.3f}</td>'
            f"<td>{escape(entry['direction'])}</td><td>{channel}</td>"
            f"<td>{escape(entry['summary'])}{shown}</td></tr>"
        )
    rows.append("</table>")
    return "\n".join(rows)
