"""The reference RSP robot on asyncio: one UDP socket and a control loop around `RobotEndpoint`.

Nothing here decides anything about RSP. Each datagram goes to the endpoint; after anything
reaches it, what it has to send is sent and its timer moved (`LoopTimer`; or, for a process that
hosts many endpoints, a socket and a timer of a `batch.Batch`, `start(batch)`). Every control period
the body (a simulated CUBO, or a generic body for any other model) gets the motion filter's
output, moves, and the sensors and monitors the next UPLINK carries go back to the endpoint, with
the events and memory events that happened (`Body.occurrences`: the endpoint reports those the
local system requested); memory commands are executed one after another (D-RSP-19), each taking
its `duration` field in milliseconds if it has one. In a session the control tick falls on the
UPLINK beat, just before it: the UPLINK carries what was measured that instant, and one wake-up of
the loop serves both.

Audio effectors (D-RSP-22: a `uint16` fragment number and `bytes` of samples, CUBO's speaker) go
through the audio processor (`rsp.audio.AudioReceiver`) rather than the motion filter: every
fragment a newer DOWNLINK brings is played in order, a late one dropped, the missing ones counted
(R-RSP-39), and the body gets the fragment played last, which its monitor reports (D-RSP-23).
"""

from __future__ import annotations

import asyncio
import logging
from collections import deque
from dataclasses import dataclass
from functools import partial

from rcmlconf.reference.datagrams import DataSocket
from rcmlconf.reference.faults import Fault, describe
from rcmlconf.reference.rsp.batch import Batch, Datagrams, Timer
from rcmlconf.reference.rsp.bodies import Body, body_for
from rcmlconf.reference.rsp.faulty_session import FaultyRobotEndpoint
from rcmlconf.reference.rsp.log_text import event_text, values_text
from rcmlconf.reference.throttled import Throttled
from rcmlconf.reference.timers import LoopTimer
from rcmlconf.rsp.audio import AudioReceiver
from rcmlconf.rsp.codec import Encryption
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel
from rcmlconf.rsp.reliable import Backlog, Occurrence
from rcmlconf.rsp.session import events
from rcmlconf.rsp.session.robot import RobotEndpoint
from rcmlconf.values import Kind, Value

log = logging.getLogger("rcmlconf.robot")

#: D-RSP-9.
DEFAULT_PORT = 7340


@dataclass(frozen=True, slots=True)
class RobotSettings:
    host: str = "127.0.0.1"
    #: 0 picks a free port.
    port: int = DEFAULT_PORT
    encryptions: frozenset[Encryption] = frozenset({Encryption.NONE})
    psk: bytes | None = None
    seed: int = 0
    #: Misbehaviours, none but to test a conformance harness (`reference.faults`).
    faults: frozenset[Fault] = frozenset()


class ReferenceRobot:
    """A robot serving one RSP session at a time on a UDP port."""

    def __init__(
        self, model: RobotModel, settings: RobotSettings, body: Body | None = None
    ) -> None:
        self.model = model
        self.settings = settings
        faults = settings.faults  # the endpoint of a faulty robot (faulty_session)
        make = partial(FaultyRobotEndpoint, faults) if faults else RobotEndpoint
        self.endpoint: RobotEndpoint = make(
            model, encryptions=settings.encryptions, psk=settings.psk
        )
        self.body = body if body is not None else body_for(model, settings.seed)
        self.transport: Datagrams | None = None
        self._timer: Timer | None = None
        #: The deadline the timer was last set to, None once it fired: a flush that finds the
        #: same one (most do: a DOWNLINK received moves no beat, D-RSP-13) leaves the timer be.
        self._timer_at: float | None = None
        #: When the control loop ticks next (loop time).
        self._tick_at = 0.0
        #: The memory command being executed, and when it is done (D-RSP-19).
        self._executing: Occurrence | None = None
        self._done_at = 0.0
        #: The endpoint's events but states, for tests and the command's log (bounded).
        self.history: deque[events.Event] = deque(maxlen=10_000)
        #: D-RSP-22: each audio effector's audio processor, and the fragment it played last.
        self.audio = {d.name: AudioReceiver() for d in model.devices if audio_effector(d)}
        self._played: dict[str, dict[str, Value]] = {}
        #: A flood of hostile datagrams is a line in the log now and then, not a line each.
        self._dropped = Throttled(log, "packets dropped")

    # -- lifetime ------------------------------------------------------------------------------

    async def start(self, batch: Batch | None = None) -> None:
        """Listen: on a transport and a timer of its own, or on a `Batch`'s, shared with many
        other endpoints."""
        if self.settings.faults:
            log.warning(
                "running with faults, to test a conformance harness: %s",
                describe(self.settings.faults),
            )
        loop = asyncio.get_running_loop()
        local = (self.settings.host, self.settings.port)
        if batch is None:
            # Read several datagrams a wake-up: a flood at the port must not fill its buffer,
            # or the kernel drops the session's DOWNLINKs with the rest (issue 18).
            self.transport = await DataSocket.bind(*local, self.datagram_received, log)
            self._timer = LoopTimer(loop, self._timer_fired)
        else:
            self.transport = batch.open(self.datagram_received, local=local)
            self._timer = batch.timer(self._timer_fired)
        self._timer_at = None
        self._tick_at = loop.time()
        self._set_timer(self._tick_at)

    @property
    def address(self) -> tuple[str, int]:
        assert self.transport is not None
        host, port = self.transport.get_extra_info("sockname")[:2]
        return host, port

    def stop(self) -> None:
        """BYE (reason 2) to the session, if one is open, and close the socket."""
        loop = asyncio.get_running_loop()
        self.endpoint.close(loop.time())
        self._set_timer(None)
        self._timer = None
        self._flush()
        if self.transport is not None:
            self.transport.close()

    # -- the socket --------------------------------------------------------------------------

    def datagram_received(self, data: bytes, addr: tuple[str, int]) -> None:
        now = self._now()
        self.endpoint.receive_datagram(data, (addr[0], addr[1]), now)
        self._flush(now)

    def _now(self) -> float:
        return asyncio.get_running_loop().time()

    def _timer_fired(self) -> None:
        self._timer_at = None
        now = self._now()
        ticked = now >= self._tick_at
        if ticked:
            self._control_tick(now)
        self.endpoint.handle_timer(now)
        if ticked:
            self._tick_at = self._next_tick(now)
        self._flush(now)

    def _flush(self, now: float | None = None) -> None:
        """What the endpoint has to send sent, its events handled, the timer moved; `now`, when
        the caller just read the clock (a datagram or a timer handled), else read here."""
        endpoint = self.endpoint
        transport = self.transport
        if transport is not None:
            for data, addr in endpoint.datagrams_to_send(self._now() if now is None else now):
                transport.sendto(data, addr)
        debug: bool | None = None  # asked at the first state: most flushes have none
        while (event := endpoint.next_event()) is not None:
            if type(event) is events.StateReceived:
                if event.device in self.audio:
                    self._hear(event)
                # Two a period: kept out of the history, whose objects would cost the loop full
                # garbage collections (bench/rsp_pairs_scale.py saw 50 ms pauses).
                if debug is None:
                    debug = log.isEnabledFor(logging.DEBUG)
                if debug:
                    log.debug("%s", event_text(self.model, event))
                continue
            if isinstance(event, events.SessionOpened | events.SessionClosed):
                self._forget()
                # The control loop keeps the pace of the period in force, not of the session
                # before: after one at T = 1.2 s, the next at 20 ms must not wait 1.2 s for its
                # first tick (and its sensors for their first UPLINK).
                self._tick_at = min(self._tick_at, self._now() + endpoint.period)
            self._log(event)
        if self._timer is not None:
            deadline = endpoint.get_timer()
            tick = self._tick_at
            self._set_timer(tick if deadline is None or tick < deadline else deadline)

    def _set_timer(self, at: float | None) -> None:
        if self._timer is not None and at != self._timer_at:
            self._timer_at = at
            self._timer.set(at)

    def _log(self, event: events.Event) -> None:
        """An event but a state: into the history and the log (a packet dropped, once in a
        while: they may come in floods)."""
        self.history.append(event)
        if isinstance(event, events.PacketDropped):
            self._dropped.happened(self._now(), event_text(self.model, event))
        elif log.isEnabledFor(logging.INFO):
            log.info("%s", event_text(self.model, event))

    def _forget(self) -> None:
        """A session opens or ends, and what the one before asked for with it: the memory command
        being executed (the endpoint drops those not started, D-RSP-19) and the sound, whose
        next sender numbers its fragments afresh (D-RSP-22)."""
        self._executing = None
        for name in self.audio:
            self.audio[name] = AudioReceiver()
        self._played.clear()

    # -- the control loop ----------------------------------------------------------------------

    def _control_tick(self, now: float) -> None:
        """One control period: effectors out, the body on, sensors and monitors back, and what
        happened raised."""
        endpoint = self.endpoint
        effectors = endpoint.effectors(now)
        if self._played:
            effectors = {**effectors, **self._played}
        self.body.apply(effectors, now)
        self.body.advance(now)
        for name, values in self.body.sensors(now, endpoint.reporting()).items():
            endpoint.set_state(name, values)
        for name, values in self.body.occurrences(now):
            try:
                ident = endpoint.occur(name, values)  # None: not requested, not reported
            except Backlog:  # a local system that requests memory events and never acknowledges
                log.debug("%s: too many occurrences waiting, one dropped", name)
                continue
            if ident is not None and log.isEnabledFor(logging.DEBUG):
                log.debug("%s #%d -> %s", name, ident, values_text(self.model, name, values))
        self._execute(now)

    def _next_tick(self, now: float) -> float:
        """On the next UPLINK beat if one falls within a period; else a period on."""
        period = self.endpoint.period
        beat = self.endpoint.next_beat()
        return beat if beat is not None and now < beat <= now + period else now + period

    def _execute(self, now: float) -> None:
        """D-RSP-19: memory commands in the order taken, each when the one before is done."""
        if self._executing is not None and now < self._done_at:
            return
        self._executing = self.endpoint.take_memory_command()
        if self._executing is not None:
            duration = self._executing.values.get("duration", 0)
            self._done_at = now + (duration / 1000 if isinstance(duration, int | float) else 0)
            log.info("executing %s #%d", self._executing.device.name, self._executing.id)

    # -- the audio processor (D-RSP-22) --------------------------------------------------------

    def _hear(self, event: events.StateReceived) -> None:
        """A newer DOWNLINK's fragment: played if it comes after the one played last."""
        number, sound = self.model.by_name[event.device].fields
        fragment, samples = event.values[number.name], event.values[sound.name]
        assert isinstance(fragment, int)
        assert isinstance(samples, bytes)
        if self.audio[event.device].receive(fragment, samples):
            self._played[event.device] = dict(event.values)


def audio_effector(found: Device) -> bool:
    """D-RSP-22: an effector whose fields are a `uint16` fragment number and `bytes` of samples."""
    fields = found.fields
    return (
        found.kind is DeviceKind.EFFECTOR
        and len(fields) == 2
        and fields[0].type.base.name == "uint16"
        and not fields[0].type.is_array
        and fields[1].type.base.kind is Kind.BYTES
        and not fields[1].type.is_array
    )
