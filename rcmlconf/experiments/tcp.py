"""Fixed-size packets over TCP, in simulated time: the baseline of the paper's Fig. 11.

The paper compares RSP with "TCP using the fixed packet size" and says nothing of that TCP.
This is a model of one, message by message, with what makes TCP slow for control:

- *Reliable, in order*: the receiver hands a message to the application only when every byte
  before it has come (head-of-line blocking). Messages are `message_size` bytes each, written
  to a byte stream that is cut into segments of at most `mss` bytes (1,448: Ethernet's 1,500
  less 20 of IPv4, 20 of TCP and 12 of timestamps) when they are sent, each costing `OVERHEAD`
  (52) bytes of headers on the wire. `TCP_NODELAY` is assumed (no Nagle: what is written goes
  at once if the window allows), and data waiting in the send queue is sent in full segments
  (Linux coalesces it), so a stalled stream of small messages catches up a segment at a time.
- *Retransmission timeout* (RFC 6298 with Linux's figures): SRTT and RTTVAR from every ACK that
  advances the window (RTT samples from TCP timestamps, RFC 7323, so retransmitted segments
  give samples too); RTO = SRTT + max(4 x RTTVAR, 200 ms) (Linux bounds the variance term by
  `tcp_rto_min`, 200 ms), 1 s before the first sample, at most 120 s, doubled at each expiry
  (backoff) until a new sample; on expiry the earliest unacknowledged segment is sent again
  (RFC 6298 §5.4) and the timer restarts; an ACK that advances the window restarts it
  (§5.3).
- *Loss recovery*, one of:
  - `rto` (the default, the plainest TCP): the timeout is the only recovery;
  - `rack`: what Linux does by default, SACK (RFC 2018; an ACK reports the 3 segments received
    most recently, as SACK's 3 blocks would) with RACK's time-based loss detection (RFC 8985):
    a segment is lost once a segment sent after it was delivered and a reordering window
    (a quarter of the minimum RTT) has passed; lost segments go again at once, ahead of new
    data, and a lost retransmission is found the same way. A timeout marks everything
    outstanding lost (go-back-N over the SACK scoreboard).
- *Congestion control* (`congestion=True`): a window of segments in flight, 10 to start
  (RFC 6928), growing by one a segment in slow start and one a window after, only while it
  limits the sender; on loss (once per window of data) it shrinks to 0.7 x itself, at least 2
  (CUBIC's β, Linux's default algorithm; CUBIC's cubic growth is not modelled: Reno's linear
  growth after the cut), and to 1 segment after a timeout. Without it the sender sends
  whatever is written at once and the bottleneck's queue absorbs it.
- ACKs: one per segment received (no delayed ACKs), 52 bytes on the reverse path.

`TcpSender` and `TcpReceiver` are the two ends of one direction; `TcpSimulation` joins a local
system and a robot with one each way, over a `simulation.Path` each way, each path carrying one
direction's segments and the other's ACKs.
"""

from __future__ import annotations

import heapq
import math
from collections import OrderedDict, deque
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from rcmlconf.experiments.simulation import NO_IMPAIRMENT, Clock, Path
from rcmlconf.impair import Impairment, derive_seed

#: IPv4 (20), TCP (20) and the timestamp option (12, padded).
OVERHEAD = 52
MSS = 1448
MIN_RTO = 0.2
INITIAL_RTO = 1.0
MAX_RTO = 120.0
INITIAL_WINDOW = 10
#: CUBIC's multiplicative decrease (Linux's default congestion control).
BETA = 0.7
#: SACK blocks an ACK carries (at most 3 with timestamps, RFC 2018).
SACK_BLOCKS = 3
RECOVERIES = ("rto", "rack")


@dataclass(frozen=True, slots=True)
class TcpSettings:
    mss: int = MSS
    min_rto: float = MIN_RTO
    initial_rto: float = INITIAL_RTO
    max_rto: float = MAX_RTO
    recovery: str = "rto"
    congestion: bool = False
    initial_window: int = INITIAL_WINDOW

    def __post_init__(self) -> None:
        if self.recovery not in RECOVERIES:
            raise ValueError(f"recovery is one of {RECOVERIES}, not {self.recovery!r}")


@dataclass(slots=True)
class Segment:
    index: int
    size: int
    #: The messages this segment ends.
    messages: tuple[Any, ...]
    #: When it was last sent.
    sent: float = 0.0
    transmissions: int = 0


@dataclass(frozen=True, slots=True)
class Transmission:
    """A segment as one transmission of it carries it (what the path delivers)."""

    index: int
    size: int
    messages: tuple[Any, ...]
    sent: float


@dataclass(frozen=True, slots=True)
class Ack:
    #: The next segment expected in order: every one before it has come.
    cumulative: int
    #: Segments received most recently (SACK).
    recent: tuple[int, ...]
    #: The send time of the segment that made this ACK (the timestamp echoed, RFC 7323).
    echo: float


@dataclass(slots=True)
class StreamStats:
    messages_written: int = 0
    segments_sent: int = 0
    retransmissions: int = 0
    timeouts: int = 0


class TcpSender:
    """The sending half of one direction (sans-IO: `write`, `on_ack`, `to_send`, timers)."""

    def __init__(self, message_size: int, settings: TcpSettings) -> None:
        """Messages of `message_size` bytes each."""
        self.settings = settings
        self.message_size = message_size
        self._segments: list[Segment] = []
        #: Bytes written, and bytes already cut into segments.
        self._written = 0
        self._cut = 0
        #: Messages not yet in a segment: where each ends in the byte stream.
        self._ends: deque[tuple[int, Any]] = deque()
        #: The first segment not cumulatively acknowledged, and the next never sent.
        self.una = 0
        self.nxt = 0
        #: Sent and neither acknowledged nor SACKed nor marked lost, by send order (RACK).
        self._outstanding: OrderedDict[int, Segment] = OrderedDict()
        self._sacked: set[int] = set()
        #: Marked lost, waiting to go again (lowest first).
        self._lost: list[int] = []
        self._lost_set: set[int] = set()
        self.srtt: float | None = None
        self.rttvar = 0.0
        self.min_rtt = math.inf
        self.rto = settings.initial_rto
        self._rto_at: float | None = None
        self._rack_at: float | None = None
        #: RACK: the send time and RTT of the most recently sent segment known delivered.
        self._rack_sent = -math.inf
        self._rack_rtt = 0.0
        self.cwnd = float(settings.initial_window)
        self.ssthresh = math.inf
        self._recovery_until = -1
        self._limited = False
        self.stats = StreamStats()

    # -- the application -----------------------------------------------------------------------

    def write(self, message: Any, now: float) -> None:
        """A message of `message_size` bytes, queued behind those written before."""
        self._written += self.message_size
        self._ends.append((self._written, message))
        self.stats.messages_written += 1

    # -- sending -------------------------------------------------------------------------------

    @property
    def in_flight(self) -> int:
        return len(self._outstanding)

    def to_send(self, now: float) -> list[Transmission]:
        """Segments to put on the path now: lost ones first, then new ones, as the window
        allows."""
        out: list[Transmission] = []
        congestion = self.settings.congestion
        while self._lost or self._cut < self._written:
            if congestion and self.in_flight >= self.cwnd:
                self._limited = True
                break
            if self._lost:
                index = heapq.heappop(self._lost)
                self._lost_set.discard(index)
                if index < self.una or index in self._sacked:
                    continue
                self.stats.retransmissions += 1
            else:
                index = self._new_segment()
            out.append(self._transmit(index, now))
        return out

    def _new_segment(self) -> int:
        """Cut the next segment from the bytes written: up to an MSS of whatever is queued
        (Linux coalesces data waiting in its send queue, even with TCP_NODELAY)."""
        size = min(self.settings.mss, self._written - self._cut)
        self._cut += size
        ends = []
        while self._ends and self._ends[0][0] <= self._cut:
            ends.append(self._ends.popleft()[1])
        index = len(self._segments)
        self._segments.append(Segment(index, size, tuple(ends)))
        self.nxt = index + 1
        return index

    def _transmit(self, index: int, now: float) -> Transmission:
        segment = self._segments[index]
        segment.sent = now
        segment.transmissions += 1
        self._outstanding[index] = segment
        self._outstanding.move_to_end(index)
        self.stats.segments_sent += 1
        if self._rto_at is None:
            self._rto_at = now + self.rto  # RFC 6298 (5.1)
        return Transmission(index, segment.size, segment.messages, now)

    # -- ACKs ----------------------------------------------------------------------------------

    def on_ack(self, ack: Ack, now: float) -> None:
        delivered: list[Segment] = []
        advanced = ack.cumulative > self.una
        if advanced:
            for index in range(self.una, ack.cumulative):
                segment = self._outstanding.pop(index, None)
                if segment is not None:
                    delivered.append(segment)
                self._sacked.discard(index)
            self.una = ack.cumulative
            self._sample(now - ack.echo)
        for index in ack.recent:
            if index >= self.una and index not in self._sacked and index < self.nxt:
                self._sacked.add(index)
                segment = self._outstanding.pop(index, None)
                if segment is not None:
                    delivered.append(segment)
        if advanced:  # RFC 6298 (5.2), (5.3)
            self._rto_at = now + self.rto if self.una < self.nxt else None
        if self.settings.congestion and delivered:
            self._grow(len(delivered))
        if self.settings.recovery == "rack":
            for segment in delivered:
                if segment.sent > self._rack_sent:
                    self._rack_sent = segment.sent
                    self._rack_rtt = now - segment.sent
            self._detect(now)

    def _sample(self, rtt: float) -> None:
        """RFC 6298 (2.2), (2.3) with Linux's floor; a sample ends the backoff."""
        rtt = max(rtt, 1e-6)
        self.min_rtt = min(self.min_rtt, rtt)
        if self.srtt is None:
            self.srtt, self.rttvar = rtt, rtt / 2
        else:
            self.rttvar = 0.75 * self.rttvar + 0.25 * abs(self.srtt - rtt)
            self.srtt = 0.875 * self.srtt + 0.125 * rtt
        rto = self.srtt + max(4 * self.rttvar, self.settings.min_rto)
        self.rto = min(rto, self.settings.max_rto)

    def _grow(self, acked: int) -> None:
        if not self._limited or self.una <= self._recovery_until:
            return
        if self.cwnd < self.ssthresh:
            self.cwnd += acked
        else:
            self.cwnd += acked / self.cwnd
        self._limited = False

    def _detect(self, now: float) -> None:
        """RACK (RFC 8985 §6.2): lost = sent before a delivered segment, and overdue."""
        window = self.min_rtt / 4 if math.isfinite(self.min_rtt) else 0.0
        self._rack_at = None
        lost = False
        for index, segment in list(self._outstanding.items()):
            if segment.sent >= self._rack_sent:
                break
            deadline = segment.sent + self._rack_rtt + window
            if now >= deadline:
                self._mark_lost(index)
                lost = True
            else:
                self._rack_at = deadline if self._rack_at is None else min(self._rack_at, deadline)
                break
        if lost:
            self._on_loss()

    def _mark_lost(self, index: int) -> None:
        self._outstanding.pop(index, None)
        if index not in self._lost_set:
            self._lost_set.add(index)
            heapq.heappush(self._lost, index)

    def _on_loss(self) -> None:
        """Cut the window once per window of data (RFC 5681's fast recovery)."""
        if not self.settings.congestion or self.una <= self._recovery_until:
            return
        self.ssthresh = max(BETA * self.cwnd, 2.0)
        self.cwnd = self.ssthresh
        self._recovery_until = self.nxt

    # -- timers --------------------------------------------------------------------------------

    def get_timer(self) -> float | None:
        times = [t for t in (self._rto_at, self._rack_at) if t is not None]
        return min(times) if times else None

    def handle_timer(self, now: float) -> None:
        if self._rack_at is not None and now >= self._rack_at:
            self._detect(now)
        if self._rto_at is None or now < self._rto_at:
            return
        self.stats.timeouts += 1
        self.rto = min(self.rto * 2, self.settings.max_rto)  # (5.5)
        if self.settings.recovery == "rack":
            for index in list(self._outstanding):
                self._mark_lost(index)
        elif self.una < self.nxt:
            self._outstanding.pop(self.una, None)
            self._mark_lost(self.una)  # (5.4): the earliest unacknowledged
        if self.settings.congestion:
            self.ssthresh = max(BETA * self.cwnd, 2.0)
            self.cwnd = 1.0
            self._recovery_until = self.nxt
        self._rto_at = now + self.rto  # (5.6)


class TcpReceiver:
    """The receiving half: in-order delivery, one ACK per segment."""

    def __init__(self) -> None:
        self.expected = 0
        self._held: dict[int, Transmission] = {}
        self._recent: deque[int] = deque(maxlen=SACK_BLOCKS)

    def on_segment(self, segment: Transmission) -> tuple[Ack, list[Any]]:
        """The ACK to send, and the messages now delivered in order."""
        delivered: list[Any] = []
        if segment.index >= self.expected:
            self._held[segment.index] = segment
            if segment.index not in self._recent:
                self._recent.append(segment.index)
        while self.expected in self._held:
            done = self._held.pop(self.expected)
            delivered.extend(done.messages)
            self.expected += 1
        recent = tuple(i for i in self._recent if i >= self.expected)
        return Ack(self.expected, recent, segment.sent), delivered


class TcpSimulation(Clock):
    """A local system and a robot joined by one TCP connection (a `TcpSender` and a
    `TcpReceiver` each way) over a `Path` each way; the applications write messages
    (`send_down`, `send_up`) and hear of them in order (`robot_listeners`, `local_listeners`)."""

    def __init__(
        self,
        *,
        down_size: int,
        up_size: int,
        downlink: Impairment = NO_IMPAIRMENT,
        uplink: Impairment = NO_IMPAIRMENT,
        seed: int = 0,
        bandwidth: float | None = None,
        settings: TcpSettings = TcpSettings(),
    ) -> None:
        super().__init__()
        self.down_path = Path(
            downlink, derive_seed(seed, "downlink"), bandwidth=bandwidth, overhead=OVERHEAD
        )
        self.up_path = Path(
            uplink, derive_seed(seed, "uplink"), bandwidth=bandwidth, overhead=OVERHEAD
        )
        self.down = TcpSender(down_size, settings)
        self.up = TcpSender(up_size, settings)
        self._down_rx = TcpReceiver()
        self._up_rx = TcpReceiver()
        #: Called with each message delivered, in order, and the time.
        self.robot_listeners: list[Callable[[Any, float], None]] = []
        self.local_listeners: list[Callable[[Any, float], None]] = []
        self._objects: dict[bytes, Transmission | Ack] = {}
        self._token = 0

    def send_down(self, message: Any, now: float) -> None:
        self.down.write(message, now)

    def send_up(self, message: Any, now: float) -> None:
        self.up.write(message, now)

    def _post(self, path: Path, item: Transmission | Ack, now: float) -> None:
        token = self._token.to_bytes(8, "big")
        self._token += 1
        self._objects[token] = item
        path.send(token, now, item.size if isinstance(item, Transmission) else 0)

    # -- the clock's parts ---------------------------------------------------------------------

    def _timers(self) -> list[float | None]:
        return [
            self.down.get_timer(),
            self.up.get_timer(),
            self.down_path.get_timer(),
            self.up_path.get_timer(),
        ]

    def _deliver(self, now: float) -> None:
        for path, receiver, sender, reverse, listeners in (
            (self.down_path, self._down_rx, self.up, self.up_path, self.robot_listeners),
            (self.up_path, self._up_rx, self.down, self.down_path, self.local_listeners),
        ):
            for token in path.due(now):
                item = self._objects.pop(token)
                if isinstance(item, Ack):
                    sender.on_ack(item, now)
                    continue
                ack, messages = receiver.on_segment(item)
                self._post(reverse, ack, now)
                for message in messages:
                    for listener in listeners:
                        listener(message, now)

    def _fire(self, now: float) -> None:
        for sender, path in ((self.down, self.down_path), (self.up, self.up_path)):
            timer = sender.get_timer()
            if timer is not None and timer <= now:
                sender.handle_timer(now)
            for transmission in sender.to_send(now):
                self._post(path, transmission, now)
