"""The Markdown report of experiment 2 (`path_following`): our figures beside the paper's
(Fig. 11), and why they differ."""

from __future__ import annotations

import math

from rcmlconf.experiments.path_controller import LOOKAHEAD, SPEED
from rcmlconf.experiments.path_following import (
    PERIOD,
    WARMUP,
    PathExperiment,
    fixed_sizes,
    rsp_sizes,
)
from rcmlconf.experiments.path_reference import HEIGHT, RADIUS, WIDTH, ReferencePath
from rcmlconf.experiments.path_run import PathRun, Setting
from rcmlconf.rsp.model import RobotModel


def mathis_rate(rtt: float, loss: float, mss: int = 1448) -> float:
    """Bytes/s a Reno-like TCP sustains at `loss` and `rtt` (Mathis, Semke, Mahdavi and Ott,
    1997: MSS * 1.22 / (RTT * √p))."""
    return mss * 1.22 / (rtt * math.sqrt(loss)) if loss > 0 else math.inf


def _cell(run: PathRun | None) -> str:
    if run is None:
        return "—"
    text = f"{run.mean_error * 100:.2f}"
    if run.completion < 0.99:
        text += f" ({run.completion * 100:.0f} %)"
    return text


def _megabits(bits: float | None) -> str:
    return "unlimited" if bits is None else f"{bits / 1e6:g} Mbit/s"


def report(experiment: PathExperiment, model: RobotModel, figure: str | None) -> str:
    """The Markdown report: our figures beside the paper's, and why they differ."""
    runs = experiment.runs
    transports = list(dict.fromkeys(r.transport for r in runs))
    settings = list(dict.fromkeys(r.setting for r in runs))
    down_fixed, up_fixed = fixed_sizes(model)
    down_rsp, up_rsp = rsp_sizes(model)
    segments = math.ceil(down_fixed / 1448)
    wire = down_fixed + 52 * segments
    need = wire * 8 / PERIOD
    bandwidth = experiment.bandwidth
    lines = [
        "# Experiment 2: path following (paper Fig. 11)",
        "",
        f"A simulated CUBO drives one lap of a {WIDTH:g} m x {HEIGHT:g} m rectangle with "
        f"{RADIUS:g} m corners ({ReferencePath().length:.2f} m) under a pure-pursuit "
        f"controller ({SPEED:g} m/s, look-ahead {LOOKAHEAD:g} m) fed only by the positions it "
        f"receives, T = {PERIOD * 1000:g} ms, after {WARMUP:g} s of zero commands; "
        f"{experiment.duration:g} s a run, seed {experiment.seed}; bottleneck "
        f"{_megabits(bandwidth)} each way; the same delay, jitter (a fifth of the delay) "
        "and loss each way.",
        "",
        "Transports: `rsp` RSP over UDP with the motion filter "
        f"({down_rsp}-byte DOWNLINK, {up_rsp}-byte UPLINK); `tcp` fixed-size packets (the "
        f"model's largest: {down_fixed:,}-byte DOWNLINK, {up_fixed:,}-byte UPLINK) over a TCP "
        "whose timeout is its only recovery (RFC 6298, Linux's 200 ms floor, backoff) with "
        "head-of-line blocking and no congestion window; `tcp-linux` the same packets over "
        "SACK/RACK recovery and a congestion window (CUBIC's β); `tcp-small` RSP's packet "
        "sizes over that TCP, to tell the packet size's share from the transport's.",
        "",
    ]
    if figure:
        lines += [f"![paths]({figure})", ""]
    lines += [
        "Mean path error in cm (the distance of the robot's true position from the path, "
        "every 20 ms of the run); in brackets the share of the lap the robot covered when it "
        "did not go round:",
        "",
        "| delay ± jitter | loss | " + " | ".join(f"`{t}`" for t in transports) + " |",
        "| --- | --- |" + " --- |" * len(transports),
    ]
    for where in settings:
        cells = [_cell(experiment.find(t, where.delay, where.loss)) for t in transports]
        lines.append(
            f"| {where.delay * 1000:g} ± {where.jitter * 1000:g} ms | {where.loss * 100:g} % | "
            + " | ".join(cells)
            + " |"
        )
    rsp_runs = [r for r in runs if r.transport == "rsp"]
    tcp_runs = [r for r in runs if r.transport == "tcp"]
    lossy = [w for w in settings if w.loss > 0]
    rsp_better = sum(
        1
        for w in lossy
        if (a := experiment.find("rsp", w.delay, w.loss)) is not None
        and (b := experiment.find("tcp", w.delay, w.loss)) is not None
        and (a.mean_error < b.mean_error or b.completion < a.completion)
    )
    clean = [w for w in settings if w.loss == 0]
    gaps = [
        abs(a.mean_error - b.mean_error)
        for w in clean
        if (a := experiment.find("rsp", w.delay, w.loss)) is not None
        and (b := experiment.find("tcp", w.delay, w.loss)) is not None
    ]
    worst_rsp = max(rsp_runs, key=lambda r: r.max_error) if rsp_runs else None
    standing: dict[str, list[str]] = {}
    for r in runs:
        if r.transport != "rsp" and r.completion == 0 and max(r.errors) < 0.01:
            place = f"{r.setting.delay * 1000:g} ms/{r.setting.loss * 100:g} %"
            standing.setdefault(r.transport, []).append(place)
    stalled = [f"`{t}` at {', '.join(w)}" for t, w in standing.items()]
    lines += [
        "",
        "| | paper (Fig. 11) | ours |",
        "| --- | --- | --- |",
        "| RSP's path error against fixed-size TCP | smaller (no numbers) | "
        f"smaller or TCP's robot fell behind in {rsp_better} of {len(lossy)} settings with "
        f"loss; within {max(gaps, default=0) * 100:.2f} cm without loss |",
        "| RSP's path error | not given | "
        + (
            f"{min(r.mean_error for r in rsp_runs) * 100:.2f} to "
            f"{max(r.mean_error for r in rsp_runs) * 100:.2f} cm mean, at most "
            f"{max(r.max_error for r in rsp_runs) * 100:.2f} cm; every lap done |"
            if rsp_runs
            else "not run |"
        ),
        "| fixed-size TCP | a larger path error | "
        + (
            f"laps done in {sum(1 for r in tcp_runs if r.completion >= 0.99)} of "
            f"{len(tcp_runs)} settings; commands up to "
            f"{max(r.summary()['max_command_age'] for r in tcp_runs):.1f} s old |"
            if tcp_runs
            else "not run |"
        ),
        "",
        "Full figures (errors in cm; ages: how old the command the robot applied was, and "
        "the position the controller used, mean over the run; TCP: DOWNLINK retransmissions "
        "and timeouts):",
        "",
        "| delay | loss | transport | mean | RMS | max | lap | lap time | command age | "
        "position age | retx / RTO |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for run in [*runs, *experiment.extra]:
        s = run.summary()
        lap = f"{run.lap_time:.2f} s" if run.lap_time is not None else "—"
        retx = f"{s['retransmissions']} / {s['timeouts']}" if "retransmissions" in s else "—"
        transport = run.transport
        if run.bandwidth != bandwidth:
            transport += f" @ {_megabits(run.bandwidth)}"
        lines.append(
            f"| {run.setting.delay * 1000:g} ms | {run.setting.loss * 100:g} % | {transport} | "
            f"{run.mean_error * 100:.2f} | {run.rms_error * 100:.2f} | "
            f"{run.max_error * 100:.2f} | {run.completion * 100:.0f} % | {lap} | "
            f"{s['mean_command_age'] * 1000:.0f} ms | {s['mean_pose_age'] * 1000:.0f} ms | "
            f"{retx} |"
        )
    serialise = wire * 8 / bandwidth if bandwidth else 0.0
    rtt = 2 * 0.1 + serialise  # 100 ms each way, and the DOWNLINK serialised
    lines += [
        "",
        "## Why our figures differ from the paper's",
        "",
        "- **The paper gives no numbers** for Fig. 11: not the path, the speed, the controller, "
        'the delay or the loss of its "real Internet". Ours are stated above and swept; the '
        "claim to compare is qualitative: RSP's path error was smaller than TCP's with fixed "
        "packets.",
        "- **RSP's error is the controller's.** With RSP the robot stays within "
        + (f"{worst_rsp.max_error * 100:.1f} cm" if worst_rsp else "a few cm")
        + " of the path in every setting, and the error hardly changes with delay or loss: it "
        "is pure pursuit cutting the corners. At 0.25 m/s a 200 ms delay is 5 cm of travel "
        "the controller does not know of, which a 0.3 m look-ahead absorbs (delay makes the "
        "robot turn a little late, against the inward cut, so the error may even shrink). A "
        "lost DOWNLINK only means the wheels hold their speed one period longer (the motion "
        "filter's hold, D-RSP-20), a lost UPLINK that the controller steers by a position 20 ms "
        "older; nothing waits for a retransmission, and the link was never silent for the 25 "
        "periods that stop the wheels. The paper's robot had real sensors and wheels; our "
        "position is exact (float32) and our wheels slip-free.",
        f"- **Without loss, TCP and RSP are equal** (within {max(gaps, default=0) * 100:.2f} "
        f"cm): the fixed {down_fixed:,}-byte DOWNLINK costs {serialise * 1000:.0f} ms of "
        f"serialisation at {_megabits(bandwidth)} ({segments} segments, {wire:,} bytes "
        "with headers), so its commands are that much older, which the controller absorbs as "
        "it absorbs delay. The paper's \"RSP is more robust than TCP ... in the transmission "
        'delay" is, in our runs, robustness to loss, not to delay.',
        f"- **With loss, fixed-size TCP cannot keep up.** The stream needs {need / 1e6:.2f} "
        f"Mbit/s ({wire:,} bytes every 20 ms). A TCP with a congestion window carries about "
        "MSS * 1.22 / (RTT * √p) (Mathis et al., 1997): at 1 % loss and an RTT of "
        f"{rtt * 1000:.0f} ms that is {mathis_rate(rtt, 0.01) * 8 / 1e6:.2f} Mbit/s, at 10 % "
        f"{mathis_rate(rtt, 0.1) * 8 / 1e6:.2f} Mbit/s. What it cannot send waits in its "
        "queue, in order, so the robot executes commands ever older (seconds, then tens of "
        "seconds) and drives off on them. The timeout-only TCP (`tcp`, no window) repairs "
        "one lost segment per timeout, each at least SRTT + 200 ms after the one before "
        "(about two a second, fewer while retransmissions are lost and the timeout doubles); "
        f"its {segments * 50} segments a second lose {segments * 50 * 0.01:g} a second at 1 % "
        f"loss, which it follows with long stalls, and {segments * 50 * 0.05:g} at 5 %, which "
        "it cannot. "
        + (
            "Where the queue after the warm-up already holds more than the whole run ("
            + "; ".join(stalled)
            + ") the TCP robot never leaves the start: its path error is 0, for it stands on "
            "the path. That is why the table gives the share of the lap done: a path error "
            "alone rewards a robot that does not move."
            if stalled
            else ""
        ),
        _small_bullet(experiment),
        _bandwidth_bullet(experiment, need),
        "- **Warm-up.** Both transports send zero commands for "
        f"{WARMUP:g} s before the lap, so that TCP's slow start (10 segments, doubling each "
        "RTT) is over when the robot sets off; without it the fixed-size stream builds a "
        "queue in its first second that the bandwidth left over drains only slowly.",
        "- **TCP's robot** applies the newest command it has each control period (as one "
        "reading its socket dry would); one applying each command for a period in turn would "
        'fall further behind (Fig. 5\'s "cumulative commands").',
    ]
    return "\n".join(lines) + "\n"


def _pair(experiment: PathExperiment, transport: str, where: Setting) -> tuple[PathRun, PathRun]:
    rsp = experiment.find("rsp", where.delay, where.loss)
    other = experiment.find(transport, where.delay, where.loss)
    assert rsp is not None
    assert other is not None
    return rsp, other


def _small_bullet(experiment: PathExperiment) -> str:
    """What `tcp-small` shows, from the runs."""
    settings = [
        r.setting
        for r in experiment.runs
        if r.transport == "tcp-small" and experiment.find("rsp", r.setting.delay, r.setting.loss)
    ]
    if not settings:
        return "- **Packet size or transport?** (`tcp-small` not run.)"
    good: list[str] = []
    bad: list[str] = []
    for where in settings:
        rsp, small = _pair(experiment, "tcp-small", where)
        near = small.completion >= 0.99 and small.mean_error <= rsp.mean_error + 0.005
        (good if near else bad).append(f"{where.delay * 1000:g} ms/{where.loss * 100:g} %")
    return (
        "- **Packet size or transport?** `tcp-small` sends RSP's small packets over the "
        "Linux-like TCP. It goes round within half a centimetre of RSP's error in "
        f"{len(good)} of {len(settings)} settings ({', '.join(good) or 'none'}): a stalled "
        "stream of small messages catches up with one full segment, so most of the gap in "
        "the paper's comparison is the fixed size. Where it does not ("
        + (", ".join(bad) or "none")
        + "), head-of-line blocking and timeouts (doubled while retransmissions are lost) "
        "hold every newer command behind a lost one: TCP's reliability, which a controller "
        "does not want for states that the next packet replaces (D-RSP-18)."
    )


def _bandwidth_bullet(experiment: PathExperiment, need: float) -> str:
    text = (
        f"- **Bandwidth.** We chose {_megabits(experiment.bandwidth)} each way: the "
        f"fixed-size DOWNLINK stream ({need / 1e6:.2f} Mbit/s with headers) fits, and its size "
        "costs serialisation as it would on a slow uplink."
    )
    for run in experiment.extra:
        if run.transport == "rsp":
            continue
        s = run.summary()
        text += (
            f" At {_megabits(run.bandwidth)}, {run.setting.delay * 1000:g} ms and "
            f"{run.setting.loss * 100:g} % loss, `{run.transport}` covered "
            f"{run.completion * 100:.0f} % of the lap with commands {s['mean_command_age']:.2f} "
            "s old on average."
        )
    if experiment.extra:
        text += (
            " A DOWNLINK stream larger than the bottleneck queues from the first second; "
            "a faster bottleneck does not save TCP from loss, whose cost is its window and "
            "its recovery."
        )
    return text
