"""Experiment 1 of the RSP paper (§IV.B, Fig. 10): the variable packet size.

"Simple motions composed of lip and arm movement and music were transferred to the remote robot
in 2 minutes. The motions were transferred with or without music according to scenario. During
the playing of music, the motion was always transferred. [...] the packet size in section A was
only 34 bytes, and in section B 1992 bytes [...] The amount of decreasing rate was about
38.65%." T was 20 ms.

Here a simulated local system (`LocalEndpoint`) sends to a simulated CUBO (`RobotEndpoint` and
`CuboBody`) for `duration` seconds at T = 20 ms:

- *motion*, always: the lips and both arms, new values every T (`write`), with the `head` and
  `arms` modules active (a module's bit activates its devices, D-RSP-14; it has no payload);
- *music*, in sections B only: a synthetic 8-bit melody fed through `FragmentSender` into the
  `speaker` effector at the rate that fills one 1,959-byte fragment every T (97,950 bytes/s:
  8-bit stereo at 48,975 Hz, or mono at twice that); outside B the speaker is not active, so its
  bit is 0 and its payload is left out;
- the local system requests the robot's `position` (a flag: no DOWNLINK payload), as the paper's
  robot "returned global position values".

The schedule alternates A (motion only) and B (motion and music): A B A B A B A, four equal As
and three equal Bs in whole periods. The paper gives neither the schedule nor the share of
music, but its figures fix the share: with every packet as large as the largest (1,992 B), a
saving s means 1 - s = f_A x 34/1992 + (1 - f_A), so f_A = s / (1 - 34/1992) = 0.3865 / 0.98293
= 39.32 %: music played for 60.68 % of the two minutes (72.8 s). `schedule()` uses that share.

Every DOWNLINK's size is measured as `datagrams_to_send` gives it, not computed. The saving is
against fixed-size packets as large as the largest one the scenario sends (the paper's
comparison), and against the largest DOWNLINK the model allows (every effector, the command and
the memory command: 4,060 bytes for CUBO, 4,076 with a tag).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

from rcmlconf.experiments.simulation import NO_IMPAIRMENT, UDP_OVERHEAD, RspSimulation
from rcmlconf.impair import Impairment
from rcmlconf.reference.rsp.cubo import CuboBody
from rcmlconf.rsp.audio import AudioReceiver, FragmentSender
from rcmlconf.rsp.codec import Encryption, PacketType
from rcmlconf.rsp.layout import HEADER_SIZE, TAG_SIZE, MapPacket, largest_packet
from rcmlconf.rsp.model import RobotModel
from rcmlconf.rsp.session import events

#: The paper's figures (§IV.B, Fig. 10).
PAPER_PERIOD = 0.02
PAPER_DURATION = 120.0
PAPER_MOTION_SIZE = 34
PAPER_MUSIC_SIZE = 1992
PAPER_SAVING = 0.3865
#: The share of time with music that the paper's three figures imply (module docstring).
PAPER_MUSIC_SHARE = 1 - PAPER_SAVING / (1 - PAPER_MOTION_SIZE / PAPER_MUSIC_SIZE)

#: The devices of the scenario (CUBO, D-RSP-8).
MOTION_DEVICES = ("leftArm", "rightArm", "lip")
MOTION_MODULES = ("arms", "head")
SPEAKER = "speaker"
POSITION = "position"

MOTION, MUSIC = "A", "B"
#: The melody: (note, beats); a beat is 12 periods (0.24 s). C major, a children's tune.
MELODY = (
    ("C5", 1), ("C5", 1), ("G5", 1), ("G5", 1), ("A5", 1), ("A5", 1), ("G5", 2),
    ("F5", 1), ("F5", 1), ("E5", 1), ("E5", 1), ("D5", 1), ("D5", 1), ("C5", 2),
)  # fmt: skip
NOTES = {"C5": 523.25, "D5": 587.33, "E5": 659.26, "F5": 698.46, "G5": 783.99, "A5": 880.0}
BEAT_PERIODS = 12


@dataclass(frozen=True, slots=True)
class Section:
    kind: str  # MOTION (A) or MUSIC (B)
    #: Seconds from the start of the scenario.
    start: float
    end: float


def schedule(
    duration: float, period: float = PAPER_PERIOD, music_share: float = PAPER_MUSIC_SHARE
) -> list[Section]:
    """A B A B A B A over `duration`: the Bs take `music_share` of it, in whole periods."""
    total = round(duration / period)
    music = round(total * music_share)
    kinds = [MOTION, MUSIC] * 3 + [MOTION]
    shares = {MOTION: _split(total - music, 4), MUSIC: _split(music, 3)}
    sections = []
    at = 0
    for kind in kinds:
        length = shares[kind].pop(0)
        sections.append(Section(kind, at * period, (at + length) * period))
        at += length
    return sections


def _split(total: int, parts: int) -> list[int]:
    return [total // parts + (1 if i < total % parts else 0) for i in range(parts)]


class Music:
    """A synthetic melody as 8-bit unsigned samples, `chunk` bytes a period, looping."""

    def __init__(self, chunk: int) -> None:
        self.chunk = chunk
        self.rate = chunk / PAPER_PERIOD
        notes: dict[tuple[str, int], bytes] = {}
        self._score: list[bytes] = []
        for note, beats in MELODY:
            key = (note, beats)
            if key not in notes:
                notes[key] = self._tone(NOTES[note], beats * BEAT_PERIODS * chunk)
            self._score.append(notes[key])
        self._note = 0
        self._offset = 0

    def _tone(self, frequency: float, length: int) -> bytes:
        step = 2 * math.pi * frequency / self.rate
        fade = 3.0 / length  # a plucked note: it dies away
        return bytes(
            round(128 + 100 * math.exp(-fade * i) * math.sin(step * i)) for i in range(length)
        )

    def next_chunk(self) -> bytes:
        note = self._score[self._note]
        data = note[self._offset : self._offset + self.chunk]
        self._offset += self.chunk
        if self._offset >= len(note):
            self._note = (self._note + 1) % len(self._score)
            self._offset = 0
        return data


def motion(t: float) -> dict[str, dict[str, int]]:
    """The lips talk (3 Hz), the arms swing in opposition (0.5 Hz): new values every T."""
    swing = round(450 * math.sin(2 * math.pi * 0.5 * t))
    lip = round(50 + 50 * math.sin(2 * math.pi * 3 * t))
    return {
        "leftArm": {"angle": swing},
        "rightArm": {"angle": -swing},
        "lip": {"opening": lip},
    }


@dataclass
class PacketSizeRun:
    """One run of the scenario: every DOWNLINK of it, and what it adds up to."""

    encryption: Encryption
    duration: float
    period: float
    sections: list[Section]
    #: Seconds from the start of the scenario, and bytes of the UDP payload.
    times: list[float] = field(default_factory=list)
    sizes: list[int] = field(default_factory=list)
    #: The section (A or B) of each packet.
    kinds: list[str] = field(default_factory=list)
    #: Packets of other types sent by the local system during the scenario (none expected).
    others: dict[str, int] = field(default_factory=dict)
    uplink_sizes: list[int] = field(default_factory=list)
    #: What the motion-only DOWNLINK must be, from the model alone.
    expected_motion_size: int = 0
    expected_music_size: int = 0
    model_largest: int = 0
    #: Devices of the model: bits of its Device Map.
    device_count: int = 0
    fragments_sent: int = 0
    fragments_played: int = 0
    fragment_gaps: int = 0

    @property
    def total(self) -> int:
        return sum(self.sizes)

    @property
    def largest(self) -> int:
        return max(self.sizes)

    def sizes_in(self, kind: str) -> dict[int, int]:
        """Each size seen in sections of `kind`, and how many packets had it."""
        found: dict[int, int] = {}
        for size, k in zip(self.sizes, self.kinds, strict=True):
            if k == kind:
                found[size] = found.get(size, 0) + 1
        return dict(sorted(found.items()))

    def saving(self, fixed: int, overhead: int = 0) -> float:
        """1 - RSP's bytes / the bytes of as many packets of `fixed` bytes each."""
        count = len(self.sizes)
        return 1 - (self.total + overhead * count) / ((fixed + overhead) * count)

    def summary(self) -> dict[str, Any]:
        """The figures of the run (JSON-ready)."""
        count = len(self.sizes)
        share = sum(1 for k in self.kinds if k == MUSIC) / count
        return {
            "encryption": self.encryption.name,
            "packets": count,
            "music_share": share,
            "sizes_motion_only": self.sizes_in(MOTION),
            "sizes_with_music": self.sizes_in(MUSIC),
            "expected_motion_size": self.expected_motion_size,
            "expected_music_size": self.expected_music_size,
            "total_bytes": self.total,
            "largest_sent": self.largest,
            "model_largest_downlink": self.model_largest,
            "fixed_bytes_largest_sent": self.largest * count,
            "fixed_bytes_model_largest": self.model_largest * count,
            "saving_vs_largest_sent": self.saving(self.largest),
            "saving_vs_model_largest": self.saving(self.model_largest),
            "saving_vs_largest_sent_with_udp_ip": self.saving(self.largest, UDP_OVERHEAD),
            "paper_sizes_on_this_schedule": 1
            - (share * PAPER_MUSIC_SIZE + (1 - share) * PAPER_MOTION_SIZE) / PAPER_MUSIC_SIZE,
            "other_packets": self.others,
            "uplink_sizes": sorted(set(self.uplink_sizes)),
            "fragments_sent": self.fragments_sent,
            "fragments_played": self.fragments_played,
            "fragment_gaps": self.fragment_gaps,
            "runs": _runs(self.times, self.sizes),
        }


def _runs(times: list[float], sizes: list[int]) -> list[list[float]]:
    """The packet sizes as runs: [start time, size, packets], for the JSON."""
    runs: list[list[float]] = []
    for t, size in zip(times, sizes, strict=True):
        if runs and runs[-1][1] == size:
            runs[-1][2] += 1
        else:
            runs.append([round(t, 6), size, 1])
    return runs


def expected_sizes(model: RobotModel, encryption: Encryption) -> tuple[int, int, int]:
    """From the model alone: the motion-only DOWNLINK (header, Device Map, the three motion
    payloads; module and request bits bring nothing), the one with a full speaker fragment,
    and the largest DOWNLINK the model allows (D-RSP-7)."""
    tag = TAG_SIZE if encryption is not Encryption.NONE else 0
    payload = sum(
        f.type.max_encoded_size for name in MOTION_DEVICES for f in model.by_name[name].fields
    )
    speaker = sum(f.type.max_encoded_size for f in model.by_name[SPEAKER].fields)
    motion_size = HEADER_SIZE + model.map_size + payload + tag
    largest = largest_packet(model, MapPacket.DOWNLINK) - TAG_SIZE + tag
    return motion_size, motion_size + speaker, largest


def run_packet_size(
    model: RobotModel,
    *,
    duration: float = PAPER_DURATION,
    seed: int = 0,
    encryption: Encryption = Encryption.NONE,
    impairment: Impairment = NO_IMPAIRMENT,
    music_share: float = PAPER_MUSIC_SHARE,
) -> PacketSizeRun:
    """The scenario at T = 20 ms over an `impairment` each way (none by default: the sizes are
    the sender's)."""
    period = PAPER_PERIOD
    sim = RspSimulation(
        model,
        downlink=impairment,
        uplink=impairment,
        seed=seed,
        period=period,
        encryption=encryption,
        body=CuboBody(model, seed=seed),
    )
    sections = schedule(duration, period, music_share)
    run = PacketSizeRun(encryption, duration, period, sections)
    run.expected_motion_size, run.expected_music_size, run.model_largest = expected_sizes(
        model, encryption
    )
    run.device_count = len(model.devices)
    local = sim.local
    speaker_field = model.by_name[SPEAKER].fields[1]
    fragments = FragmentSender(speaker_field.type.size)
    music = Music(speaker_field.type.size)
    receiver = AudioReceiver()

    def heard(event: events.Event, now: float) -> None:
        if isinstance(event, events.StateReceived) and event.device == SPEAKER:
            number, samples = event.values["fragment"], event.values["samples"]
            assert isinstance(number, int)
            assert isinstance(samples, bytes)
            receiver.receive(number, samples)

    sim.robot_listeners.append(heard)
    opened = sim.open()
    start = opened + period  # the first beat after the one at opening
    for name, values in motion(0.0).items():
        local.write(name, values)
    for module in MOTION_MODULES:
        local.set_active(module, True)
    local.set_active(POSITION, True)
    playing = False

    def scenario(now: float) -> None:
        nonlocal playing
        t = now - start
        for name, values in motion(t).items():
            local.write(name, values)
        if _section(sections, t).kind == MUSIC:
            for number, samples in fragments.feed(music.next_chunk()):
                local.write(SPEAKER, {"fragment": number, "samples": samples})
                run.fragments_sent += 1
            playing = True
        elif playing:
            local.set_active(SPEAKER, False)
            playing = False

    sim.every(period, scenario, start)
    first = len(sim.sent_down.times)
    first_up = len(sim.sent_up.times)
    sim.run_until(start + duration - period / 2)
    down = sim.sent_down
    for t, size, kind in zip(
        down.times[first:], down.sizes[first:], down.types[first:], strict=True
    ):
        if kind == PacketType.DOWNLINK:
            run.times.append(t - start)
            run.sizes.append(size)
            run.kinds.append(_section(sections, t - start).kind)
        else:
            name = PacketType(kind).name
            run.others[name] = run.others.get(name, 0) + 1
    up = sim.sent_up
    run.uplink_sizes = [
        s for s, k in zip(up.sizes[first_up:], up.types[first_up:], strict=True) if k == 5
    ]
    sim.run_until(sim.now + 1.0)  # the last fragments arrive
    run.fragments_played = receiver.counts.played
    run.fragment_gaps = receiver.counts.gaps
    return run


def _section(sections: list[Section], t: float) -> Section:
    for section in sections:
        if t < section.end - 1e-9:
            return section
    return sections[-1]


# -- the report ------------------------------------------------------------------------------


def report(runs: list[PacketSizeRun], figure: str | None) -> str:
    """The Markdown report: our figures beside the paper's, and why they differ."""
    plain = next(r for r in runs if r.encryption is Encryption.NONE)
    s = plain.summary()
    motion_sizes = ", ".join(f"{v:,} packets of {k:,} B" for k, v in s["sizes_motion_only"].items())
    music_sizes = ", ".join(f"{v:,} packets of {k:,} B" for k, v in s["sizes_with_music"].items())
    lines = [
        "# Experiment 1: variable packet size (paper Fig. 10)",
        "",
        f"{plain.duration:g} s at T = {plain.period * 1000:g} ms: {s['packets']:,} DOWNLINKs, "
        f"music in {s['music_share'] * 100:.2f} % of them. Schedule (A: motion only, "
        "B: motion and music): "
        + ", ".join(f"{x.kind} {x.start:.2f}-{x.end:.2f} s" for x in plain.sections)
        + ".",
        "",
    ]
    if figure:
        lines += [f"![packet size over time]({figure})", ""]
    lines += [
        "| | paper | ours, no encryption | ours, AES-256-GCM |",
        "| --- | --- | --- | --- |",
    ]
    secured = [r for r in runs if r.encryption is not Encryption.NONE]
    columns = [plain, *secured[:1]]

    def row(label: str, paper: str, cell: Any) -> None:
        lines.append(f"| {label} | {paper} | " + " | ".join(cell(r) for r in columns) + " |")

    def one_size(r: PacketSizeRun, kind: str) -> str:
        return " / ".join(f"{k:,} B" for k in r.sizes_in(kind))

    row("section A (motion only)", "34 B", lambda r: one_size(r, MOTION))
    row("section B (motion + music)", "1,992 B", lambda r: one_size(r, MUSIC))
    row(
        "total DOWNLINK bytes",
        "—",
        lambda r: f"{r.total:,}",
    )
    row(
        "saving vs every packet as large as the largest sent",
        "38.65 %",
        lambda r: f"{r.saving(r.largest) * 100:.2f} % (vs {r.largest:,} B)",
    )
    row(
        "saving vs the model's largest DOWNLINK",
        "—",
        lambda r: f"{r.saving(r.model_largest) * 100:.2f} % (vs {r.model_largest:,} B)",
    )
    row(
        "the same with UDP/IPv4 headers (28 B a packet)",
        "—",
        lambda r: f"{r.saving(r.largest, UDP_OVERHEAD) * 100:.2f} %",
    )
    map_size = plain.expected_motion_size - HEADER_SIZE - 5
    lines += [
        "",
        f"Sizes seen, no encryption: A {motion_sizes}; B {music_sizes}. Other packets from the "
        f"local system during the scenario: {s['other_packets'] or 'none'}. UPLINK sizes: "
        f"{', '.join(str(x) for x in s['uplink_sizes'])} B (the position, every T). Speaker "
        f"fragments sent {plain.fragments_sent:,}, played by the robot {plain.fragments_played:,}, "
        f"gaps {plain.fragment_gaps}.",
        "",
        "## Why our figures differ from the paper's",
        "",
        f"- **Section A: {plain.expected_motion_size} B, not 34.** Ours is the 20-byte header of "
        f"Table II, a {map_size}-byte Device Map ({map_size * 8} bits' room for CUBO's "
        f"{plain.device_count} devices, D-RSP-14) and the payloads of the three motion "
        "effectors: two `int16` arm angles and a `uint8` lip opening (5 bytes). The module "
        "bits (`arms`, `head`) and the position request are flags with no payload. The paper "
        'gives no field sizes. Its 34 bytes fit, for example, a 2-byte map ("if user selects '
        'sixteen devices, the device bits become 16 bits", §III) and 12 bytes of motion (three '
        "4-byte values), or our 4-byte map and 10 bytes (five 16-bit values: two arms, the lip "
        "and two more, e.g. the head tilt and a wheel). The header is the same 20 bytes.",
        f"- **Section B: {plain.expected_music_size:,} B, as the paper's 1,992.** CUBO's model "
        "sizes the speaker's fragment (1,959 bytes of samples, a 2-byte length and a 2-byte "
        "fragment number, D-RSP-22) so that section B matches the paper; the paper's B packet is "
        "its A packet plus 1,958 bytes, ours A plus 1,963, because our A is 5 bytes smaller.",
        f"- **Saving {plain.saving(plain.largest) * 100:.2f} %, paper 38.65 %.** Against "
        "packets all as large as the largest, only the A packets save, each 1 - A/B of a "
        "packet, so the paper's figures fix the share of music: 1 - 0.3865 / (1 - 34/1992) "
        f"= {PAPER_MUSIC_SHARE * 100:.2f} %, which our schedule has (in whole periods). With "
        "the paper's sizes on our schedule the saving is "
        f"{s['paper_sizes_on_this_schedule'] * 100:.2f} %; our A packet, 5 bytes smaller, "
        "saves a little more. The paper does not say what its fixed-size packet was; as "
        "large as the largest one sent is the comparison its 38.65 % implies. Against the "
        "largest DOWNLINK CUBO's model allows (every effector, with the LCD's 2 KB, plus the "
        "command and the memory command) the saving is far larger.",
        "- **No keep-alives, no ACKs.** Values flow every T, so no beat is empty "
        "(D-RSP-13's empty map every 5 periods never happens) and nothing reliable is sent.",
        "- **Encryption** adds the 16-byte AEAD tag to every packet (D-RSP-21): "
        + (
            f"{one_size(secured[0], MOTION)} in A and {one_size(secured[0], MUSIC)} in B; the "
            f"saving is {secured[0].saving(secured[0].largest) * 100:.2f} %, a little less "
            "(the tag is a larger share of the small packets)."
            if secured
            else "not run."
        ),
        "- **The UDP and IP headers** (28 bytes a datagram) are not in the paper's sizes nor in "
        "ours; with them the saving shrinks a little (table).",
        "- **Music.** The paper's music is unspecified; ours is a synthetic 8-bit melody at the "
        "rate that fills one fragment every T (97,950 bytes/s, 8-bit stereo at 48,975 Hz). "
        "The packet sizes do not depend on the samples.",
        "- **The network.** The paper ran over the real Internet; sizes are the sender's, so "
        "ours are measured where they are made (`datagrams_to_send`), over a simulated path.",
    ]
    return "\n".join(lines) + "\n"
