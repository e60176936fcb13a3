"""`rcmlconf dissect FILE`: what went over the wire, and what went wrong (rcmlconf.dissect)."""

from __future__ import annotations

import os
import sys
from collections.abc import Callable
from pathlib import Path

import click

from rcmlconf.cli.console import Output, printable
from rcmlconf.cli.models import load_or_exit
from rcmlconf.cli.stdin import standard_input
from rcmlconf.diagnostics import Diagnostic
from rcmlconf.dissect import Dissector, Options, Record, Severity
from rcmlconf.dissect.classify import parse_decode_as
from rcmlconf.dissect.output.analysis_json import analysis_json
from rcmlconf.dissect.output.analysis_text import analysis_lines
from rcmlconf.dissect.output.record_json import JsonFormat
from rcmlconf.dissect.output.record_text import TextFormat
from rcmlconf.pcap.reader import Capture
from rcmlconf.pcap.records import CaptureError
from rcmlconf.rcml.model import RcmlDocument
from rcmlconf.rsp.model import RobotModel
from rcmlconf.validate.validator import InvalidRobot, Validator
from rcmlconf.wording import plural

#: Lines written to the console at once: one write per batch, not per message.
BATCH = 2048

#: --format json's last line, {"version": N, "analysis": {...}}, says which shape its lines
#: have: N grows by one whenever a field changes meaning or goes (a field added keeps it).
JSON_VERSION = 1


def _decode_as(
    ctx: click.Context, param: click.Parameter, values: tuple[str, ...]
) -> tuple[tuple[str, int], ...]:
    try:
        return tuple(parse_decode_as(value) for value in values)
    except ValueError as error:
        raise click.BadParameter(str(error)) from None


def _writable(ctx: click.Context, param: click.Parameter, path: Path | None) -> Path | None:
    """--plot's FILE, once it is known to open for writing: refused before the capture is read,
    not after a long dissection. The file is not emptied; one made by the test is removed."""
    if path is None:
        return None
    try:
        try:
            os.close(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
        except FileExistsError:
            # O_NONBLOCK: a FIFO without a reader is refused, not waited for.
            os.close(os.open(path, os.O_WRONLY | os.O_NONBLOCK))
        else:
            path.unlink()
    except OSError as exc:
        raise click.BadParameter(
            f"'{printable(str(path))}' cannot be written: {exc.strerror or exc}"
        ) from None
    return path


def _load_model(path: Path, warnings: list[Diagnostic]) -> RobotModel | RcmlDocument:
    """A robot model (.rmodel) or an RCML document (.rcml), whichever the file is."""
    try:
        report, model = Validator().load_file(path)
    except OSError as exc:
        raise InvalidRobot(f"{path}: cannot be read: {exc.strerror}") from None
    if not isinstance(model, RobotModel | RcmlDocument):
        raise InvalidRobot(
            f"{path}: not a valid robot model or RCML document; `rcmlconf validate {path}` says"
            " why",
            report,
        )
    warnings.extend(report.diagnostics)
    return model


def _models(
    output: Output, paths: tuple[Path, ...]
) -> tuple[RobotModel | None, RcmlDocument | None]:
    """--model's robot model and RCML, each loaded and checked. Two of a kind are refused: only one
    of them could be used."""
    rsp_model: RobotModel | None = None
    rcml: RcmlDocument | None = None
    first: dict[str, Path] = {}
    for path in paths:
        model = load_or_exit(output, "dissect", path, _load_model)
        what = "robot model" if isinstance(model, RobotModel) else "RCML document"
        if what in first:
            raise click.BadParameter(
                f"'{printable(str(first[what]))}' and '{printable(str(path))}' are both a {what}:"
                " give one robot model and one RCML at most",
                param_hint="'--model'",
            )
        first[what] = path
        if isinstance(model, RobotModel):
            rsp_model = model
        else:
            rcml = model
    return rsp_model, rcml


@click.command()
@click.argument(
    "capture", metavar="FILE", type=click.Path(dir_okay=False, allow_dash=True, path_type=Path)
)
@click.option(
    "--model",
    "models",
    multiple=True,
    metavar="FILE",
    type=click.Path(exists=True, dir_okay=False, path_type=Path),
    help="The robot model (.rmodel) to decode RSP payloads with, and/or the robot's RCML (.rcml)"
    " to decode data-stream values and READ/WRITE bodies with. Repeatable: one of each at most.",
)
@click.option(
    "--format",
    "output_format",
    type=click.Choice(["text", "json"]),
    default="text",
    show_default=True,
    help="text: a summary line per message, then the analysis; json: JSON Lines, an object per"
    ' message, then {"analysis": ...}.',
)
@click.option(
    "--decode-as",
    multiple=True,
    metavar="PROTO=PORT",
    callback=_decode_as,
    help="Decode the traffic of PORT as PROTO: rctp (TCP), rctp-data or rsp (UDP). Repeatable.",
)
@click.option(
    "--no-heuristics",
    is_flag=True,
    help="Recognise our protocols only by port (defaults, --decode-as, SETUP's Transport),"
    " not by the look of a flow's first packet.",
)
@click.option(
    "--plot",
    type=click.Path(dir_okay=False, path_type=Path),
    callback=_writable,
    metavar="FILE.png",
    help="Also draw inter-arrival time and latency over time per stream, as a PNG image written"
    " to FILE.png as named (needs matplotlib: the `plot` extra).",
)
@click.option("-q", "--quiet", is_flag=True, help="Print the analysis only, no line per message.")
@click.option(
    "-V",
    "verbose",
    is_flag=True,
    help="The full field tree of each message (the scapy layers), as text and without the"
    " analysis: not with --plot or --format json.",
)
def dissect(
    capture: Path,
    models: tuple[Path, ...],
    output_format: str,
    decode_as: tuple[tuple[str, int], ...],
    no_heuristics: bool,
    plot: Path | None,
    quiet: bool,
    verbose: bool,
) -> None:
    """Decode a pcap or pcapng capture of RCTP/2.0 and RSP, and analyse it.

    FILE is a capture file, or a pipe: - for standard input (tcpdump -w - | rcmlconf dissect -),
    which is read whole first (1 GiB at most).

    RCTP control connections (TCP 7330), the data stream (UDP: the ports SETUP's Transport
    names, and 7330) and RSP (UDP 7340) are found by port, by --decode-as, and by the look of
    each flow's first packet. Each message is one summary line (time, endpoints, protocol,
    method/status or packet type, sequence number, key fields); the analysis follows: sessions
    and streams, loss, reordering, duplicates, TCP retransmissions, request-to-response times,
    heartbeat round trips and clock offsets, jitter, methods sent in a state that does not allow
    them, and malformed messages with their offset — each finding with the requirement of
    specs/ it concerns.

    RSP payloads need the robot model (--model cubo.rmodel): without one they are shown as
    bytes. The values of data-stream packets and of READ and WRITE bodies need the robot's
    RCML (--model rover.rcml).

    \b
    Exit status: 0 when the analysis finds no error; 1 when it finds one
    (a MUST of specs/ broken on the wire); 2 for a usage error or a file
    that is not a readable capture (or breaks before its end).

    \b
    Examples:
      rcmlconf dissect run.pcap
      rcmlconf dissect --model cubo.rmodel --format json cubo.pcapng > cubo.jsonl
      rcmlconf dissect --decode-as rsp=9000 --plot streams.png -q lab.pcap
    """
    if verbose and (plot is not None or output_format == "json"):
        raise click.UsageError(
            "-V prints each message's field tree as text, and no analysis:"
            " leave out --plot and --format json, or -V"
        )
    output = Output()
    rsp_model, rcml = _models(output, models)
    options = Options(rsp_model, rcml, decode_as, not no_heuristics, plot is not None)
    try:
        opened = _open(capture)
    except OSError as exc:
        output.problem("dissect", f"cannot read {capture}: {exc.strerror or exc}")
        sys.exit(2)
    except CaptureError as exc:
        output.problem("dissect", f"{capture}: {exc.reason} (byte {exc.offset})")
        sys.exit(2)
    with opened:
        if verbose:
            sys.exit(_verbose(opened, options, output))
        lines = RecordLines(output, output_format, rsp_model, quiet, opened)
        dissector = Dissector(options, lines.emit)
        analysis = dissector.run(opened)
        lines.flush()
    if output_format == "json":
        lines.json({"version": JSON_VERSION, "analysis": analysis_json(analysis)})
    else:
        for text, style in analysis_lines(analysis):
            output.out.line([(text, style)])
    status = 1 if analysis.errors else 0
    if analysis.capture.error is not None:
        offset, reason = analysis.capture.error
        output.problem("dissect", f"{capture}: {reason} (byte {offset}); read up to there")
        status = 2
    if plot is not None:
        status = max(status, _plot(output, dissector, plot, capture))
    warnings = sum(1 for f in analysis.findings if f.severity is Severity.WARNING)
    messages = sum(analysis.capture.messages.values())
    counts = (
        (analysis.capture.frames, "frame"),
        (messages, "message"),
        (analysis.errors, "error"),
        (warnings, "warning"),
    )
    output.summary(
        f"{capture}: {', '.join(plural(count, noun) for count, noun in counts)}", ok=status == 0
    )
    sys.exit(status)


def _open(capture: Path) -> Capture:
    """The capture FILE names: - is standard input."""
    if str(capture) != "-":
        return Capture.open(capture)
    return Capture.read(standard_input(), "-")


class RecordLines:
    """Each record's line (or JSON object), written in batches."""

    def __init__(
        self,
        output: Output,
        output_format: str,
        model: RobotModel | None,
        quiet: bool,
        capture: Capture,
    ) -> None:
        self.output = output
        self._batch: list[str] = []
        decimals = capture.decimals
        self._form: Callable[[Record], str] = (
            TextFormat(model, capture.first_time(), decimals).line
            if output_format == "text"
            else JsonFormat(model, decimals).line
        )
        #: What the dissector calls with each record.
        self.emit: Callable[[Record], None] = self._nothing if quiet else self._append

    def _nothing(self, record: Record) -> None:
        pass

    def _append(self, record: Record) -> None:
        batch = self._batch
        batch.append(self._form(record))
        if len(batch) >= BATCH:
            self.flush()

    def json(self, document: object) -> None:
        import json

        text = json.dumps(document, ensure_ascii=False, separators=(",", ":"))
        self.output.out.line([(text, "")])

    def flush(self) -> None:
        if self._batch:
            self.output.out.lines(self._batch)
            self._batch.clear()


def _plot(output: Output, dissector: Dissector, path: Path, capture: Path) -> int:
    try:
        from rcmlconf.dissect.plot import plot_streams
    except ImportError:  # pragma: no cover - the plot extra is missing
        output.problem("dissect", "--plot needs matplotlib: pip install 'rcmlconf[plot]'")
        return 2
    try:
        drawn = plot_streams(dissector.streams, path, f"rcmlconf dissect {capture.name}")
    except ImportError:
        output.problem("dissect", "--plot needs matplotlib: pip install 'rcmlconf[plot]'")
        return 2
    except OSError as exc:  # /dev/full, a disk that fills: known only once written
        output.problem("dissect", f"--plot {path}: cannot be written: {exc.strerror or exc}")
        return 2
    output.notice(f"{path}: {plural(drawn, 'stream')} drawn")
    return 0


def _verbose(capture: Capture, options: Options, output: Output) -> int:
    """-V: each message's summary and whole field tree, from the scapy layers (imported only
    here: the summary and json paths never build a scapy packet)."""
    from rcmlconf.scapy_layers import capture as layers

    found = layers.messages(capture, options.rsp_model, options.decode_as, options.heuristics)
    try:
        for message in found:
            output.live([(layers.summary(message), "bold")])
            tree = layers.render(message.packet)
            output.out.file.write(tree if tree.endswith("\n") else tree + "\n")
    except BrokenPipeError:
        raise  # `| head`: the command's own handler ends quietly
    except CaptureError as exc:
        output.problem(
            "dissect", f"{capture.name}: {exc.reason} (byte {exc.offset}); read up to there"
        )
        return 2
    return 0
