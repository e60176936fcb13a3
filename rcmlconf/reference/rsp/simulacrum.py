"""The simulacrum: the local middleware of the paper's Fig. 2 on asyncio, around `LocalEndpoint`.

- *Robot Device Manager* and *downlink handler*: the endpoint holds effector values, requests and
  occurrences, and sends a DOWNLINK every T (`set_period` changes T while running);
- *uplink handler* and *Robot Environment Data Buffer*: every value and occurrence the robot
  reports is kept here — the newest of each sensor and monitor, the occurrences of each event not
  yet read — with blocking reads (`read`, with a timeout) and listeners;
- *Robot API*: this object is `rcmlconf.rsp.api.DeviceAccess`, which the typed modules of
  `rcmlconf rsp generate` drive.

It runs in an asyncio loop: `await Simulacrum(...).open()` inside one (`open(batch=...)`: on a
`batch.Batch`'s socket and clock, for a process that hosts many endpoints), or
`Simulacrum.start(...)` from plain code, which runs the loop in a thread of its own. Every
DeviceAccess method may be called from any thread: the endpoint is only touched under a lock, and
listeners are called from the loop's thread.
"""

from __future__ import annotations

import asyncio
import threading
from collections import deque
from collections.abc import Callable
from concurrent.futures import Future
from typing import cast

from rcmlconf.errors import RcmlconfError
from rcmlconf.reference.rsp.batch import Batch, Datagrams, Timer
from rcmlconf.reference.timers import LoopTimer
from rcmlconf.rsp.api import Values
from rcmlconf.rsp.codec import ByeReason, Encryption
from rcmlconf.rsp.model import Device, DeviceKind, RobotModel
from rcmlconf.rsp.session import events
from rcmlconf.rsp.session.devices import device
from rcmlconf.rsp.session.local import LocalEndpoint
from rcmlconf.rsp.session.timing import SESSION_TIMEOUT

Address = tuple[str, int]
#: A listener and the values it is to be called with.
Call = tuple[Callable[[Values], None], Values]
#: Occurrences kept per device for `read` (the oldest go first when an application reads none).
MAX_UNREAD = 1024
_STATES = (DeviceKind.SENSOR, DeviceKind.MONITOR)
_OCCURRENCES = (DeviceKind.EVENT, DeviceKind.MEMORY_EVENT)
#: What the robot reports, which `read` and `listen` take.
_REPORTED = (*_STATES, *_OCCURRENCES)


class NoSession(RcmlconfError):
    """The robot refused the session, never answered, or ended it."""


class Simulacrum:
    """A local system's session with one robot, as the Robot API sees it."""

    def __init__(
        self,
        model: RobotModel,
        robot: Address,
        *,
        period: float | None = None,
        encryption: Encryption = Encryption.NONE,
        psk: bytes | None = None,
    ) -> None:
        self.model = model
        self.robot = robot
        self.endpoint = LocalEndpoint(model, period=period, encryption=encryption, psk=psk)
        self._lock = threading.RLock()
        self._changed = threading.Condition(self._lock)
        #: Threads in `read`, waiting on `_changed` or about to.
        self._readers = 0
        #: The Robot Environment Data Buffer: newest values, how many came, occurrences unread.
        self._latest: dict[str, Values] = {}
        self._counts: dict[str, int] = {}
        self._read_counts: dict[str, int] = {}
        self._unread: dict[str, deque[Values]] = {}
        self._listeners: dict[str, list[Callable[[Values], None]]] = {}
        self._written: dict[str, Values] = {}
        self._loop: asyncio.AbstractEventLoop | None = None
        self._transport: Datagrams | None = None
        self._timer: Timer | None = None
        #: The deadline the timer was last set to, None once it fired or was stopped: a flush
        #: that finds the same one (most do: an UPLINK received moves no beat, D-RSP-13) leaves
        #: it be.
        self._timer_at: float | None = None
        self._opened: asyncio.Future[events.SessionOpened] | None = None
        self.closed: events.SessionClosed | events.SessionRefused | None = None
        #: Set once `closed` is: what `ended` waits for.
        self._over = asyncio.Event()
        #: Every event except states, for those who watch the session (bounded).
        self.history: deque[events.Event] = deque(maxlen=10_000)
        #: Told every datagram the session sends, as it goes (under the session's lock: keep it
        #: short): a recording of what crossed the wire, e.g. packets to replay at a robot.
        self.tap: Callable[[bytes], None] | None = None
        self._thread: threading.Thread | None = None

    # -- lifetime ------------------------------------------------------------------------------

    async def open(
        self, timeout: float = 3.0, *, batch: Batch | None = None
    ) -> events.SessionOpened:
        """Connect, send HELLO and wait for WELCOME (D-RSP-12); NoSession when refused. On a
        transport and a timer of its own, or on a `Batch`'s, shared with many other endpoints."""
        loop = self._loop = asyncio.get_running_loop()
        self._opened = loop.create_future()
        if batch is None:
            await loop.create_datagram_endpoint(lambda: _Protocol(self), remote_addr=self.robot)
            self._timer = LoopTimer(loop, self._timer_fired)
        else:
            self._transport = batch.open(self._datagram, remote=self.robot)
            self._timer = batch.timer(self._timer_fired)
        self._timer_at = None
        with self._lock:
            self.endpoint.connect(loop.time())
        self._flush()
        try:
            return await asyncio.wait_for(self._opened, timeout)
        except TimeoutError:
            self._close_socket()
            raise NoSession(f"no answer from {self.robot[0]}:{self.robot[1]}") from None
        except NoSession:
            self._close_socket()
            raise

    async def ended(self) -> events.SessionClosed | events.SessionRefused:
        """Once the session is over: BYE from either side, or its timeout (D-RSP-13); or once
        it was refused."""
        await self._over.wait()
        assert self.closed is not None
        return self.closed

    async def aclose(self) -> None:
        """BYE, and the socket closed."""
        if self._loop is None:
            return
        with self._lock:
            self.endpoint.close(self._loop.time())
        self._flush()
        self._close_socket()

    @classmethod
    def start(cls, model: RobotModel, robot: Address, **options: object) -> Simulacrum:
        """A simulacrum running in a thread of its own, its session open; `stop()` ends it."""
        simulacrum = cls(model, robot, **options)  # type: ignore[arg-type]
        ready: Future[None] = Future()

        def run() -> None:
            loop = asyncio.new_event_loop()
            try:
                loop.run_until_complete(simulacrum.open())
            except BaseException as exc:
                ready.set_exception(exc)
                loop.close()
                return
            ready.set_result(None)
            loop.run_forever()
            loop.run_until_complete(simulacrum.aclose())
            loop.close()

        simulacrum._thread = threading.Thread(target=run, name="rsp-simulacrum", daemon=True)
        simulacrum._thread.start()
        ready.result()
        return simulacrum

    def stop(self) -> None:
        """End a simulacrum that `start` began: BYE, and its thread joined."""
        loop, thread = self._loop, self._thread
        if loop is None or thread is None:
            return
        loop.call_soon_threadsafe(loop.stop)
        thread.join(timeout=5.0)

    def _close_socket(self) -> None:
        self._set_timer(None)
        if self._transport is not None:
            self._transport.close()

    # -- DeviceAccess (rcmlconf.rsp.api) -------------------------------------------------------

    def write(self, device: str, values: Values) -> None:
        with self._lock:
            self.endpoint.write(device, values)
            self._written[device] = dict(values)

    def set_active(self, device: str, active: bool) -> None:
        with self._lock:
            self.endpoint.set_active(device, active)

    def latest(self, device: str) -> Values | None:
        with self._lock:
            self._known(device, tuple(DeviceKind), "be looked up")
            if device in self._written:
                return self._written[device]
            return self._latest.get(device)

    def read(self, device: str, timeout: float | None = None) -> Values:
        found = self._known(device, _REPORTED, "be read")
        with self._changed:
            self._readers += 1
            try:
                return self._read(found, timeout)
            finally:
                self._readers -= 1

    def _read(self, found: Device, timeout: float | None) -> Values:
        """`read`, under the lock."""
        device = found.name
        if found.kind in _OCCURRENCES:
            unread = self._unread.setdefault(device, deque(maxlen=MAX_UNREAD))
            if not self._changed.wait_for(lambda: bool(unread) or self._ended(), timeout):
                raise TimeoutError(f"no {device} within {timeout} s")
            if not unread:
                raise NoSession(self._ending())
            return unread.popleft()
        seen = self._read_counts.get(device, 0)
        if not self._changed.wait_for(
            lambda: self._counts.get(device, 0) > seen or self._ended(), timeout
        ):
            raise TimeoutError(f"no new value of {device} within {timeout} s")
        if self._counts.get(device, 0) == seen:
            raise NoSession(self._ending())
        self._read_counts[device] = self._counts[device]
        return self._latest[device]

    def issue(self, device: str, values: Values) -> int:
        with self._lock:
            return self.endpoint.issue(device, values)

    def listen(self, device: str, listener: Callable[[Values], None]) -> Callable[[], None]:
        self._known(device, _REPORTED, "be listened to")
        with self._lock:
            self._listeners.setdefault(device, []).append(listener)

        def stop() -> None:
            with self._lock:
                listeners = self._listeners.get(device, [])
                if listener in listeners:
                    listeners.remove(listener)

        return stop

    # -- more of the Device Manager ------------------------------------------------------------

    def set_period(self, seconds: float) -> None:
        """T from now on (D-RSP-13)."""
        loop = self._loop
        with self._lock:
            self.endpoint.set_period(seconds, loop.time() if loop is not None else 0.0)
        self._soon()

    def clear_buffer(self) -> None:
        with self._lock:
            self.endpoint.clear_buffer()

    # -- the packet handlers -------------------------------------------------------------------

    def _known(self, name: str, kinds: tuple[DeviceKind, ...], what: str) -> Device:
        return device(self.endpoint.codec, name, kinds, what)

    def _ended(self) -> bool:
        return self.closed is not None

    def _ending(self) -> str:
        assert self.closed is not None
        return session_end(self.closed)

    def _soon(self) -> None:
        """Flush from the loop's thread, whichever thread asked."""
        loop = self._loop
        if loop is not None and not loop.is_closed():
            loop.call_soon_threadsafe(self._flush)

    def _timer_fired(self) -> None:
        loop = self._loop
        assert loop is not None
        calls: list[Call] = []
        with self._lock:
            self._timer_at = None
            now = loop.time()
            self.endpoint.handle_timer(now)
            self._drain(now, calls)
        _call(calls)

    def _datagram(self, data: bytes, addr: Address) -> None:
        self.received(data)  # from the robot: the socket is connected to it

    def received(self, data: bytes) -> None:
        loop = self._loop
        assert loop is not None
        calls: list[Call] = []
        with self._lock:
            now = loop.time()
            self.endpoint.receive_datagram(data, now)
            self._drain(now, calls)
        _call(calls)

    def _flush(self) -> None:
        loop = self._loop
        if loop is None:
            return
        calls: list[Call] = []
        with self._lock:
            self._drain(loop.time(), calls)
        _call(calls)

    def _drain(self, now: float, calls: list[Call]) -> None:
        """Under the lock: what the endpoint has to send sent, its events taken (the listeners to
        call, outside the lock, onto `calls`), the timer moved. Twice a period, in the same hold
        of the lock as the datagram or beat that made them."""
        endpoint = self.endpoint
        transport = self._transport
        if transport is not None and not transport.is_closing():
            tap = self.tap
            for data in endpoint.datagrams_to_send(now):
                transport.sendto(data)
                if tap is not None:
                    tap(data)
        event = endpoint.next_event()
        if event is not None:
            while event is not None:
                self._take(event, calls)
                event = endpoint.next_event()
            # Only an event changes what `read` waits for (values, occurrences, the end); most
            # events, a state every period, come with no reader waiting.
            if self._readers:
                self._changed.notify_all()
        self._set_timer(endpoint.get_timer())

    def _set_timer(self, at: float | None) -> None:
        if self._timer is not None and at != self._timer_at:
            self._timer_at = at
            self._timer.set(at)

    def _take(self, event: events.Event, calls: list[Call]) -> None:
        """Into the data buffer; the listeners to call, outside the lock, onto `calls`."""
        if type(event) is events.StateReceived:  # one a period: its type first
            device = event.device
            self._latest[device] = event.values
            self._counts[device] = self._counts.get(device, 0) + 1
        elif isinstance(event, events.OccurrenceReceived):
            device = event.device
            self.history.append(event)
            unread = self._unread.setdefault(device, deque(maxlen=MAX_UNREAD))
            unread.append(event.values)
        else:
            self._session_event(event)
            return
        listeners = self._listeners.get(device)
        if listeners:
            calls += [(listener, event.values) for listener in listeners]

    def _session_event(self, event: events.Event) -> None:
        """Any other event: into the history; a session opened, refused or closed to `open`."""
        self.history.append(event)
        if isinstance(event, events.SessionOpened) and self._opened is not None:
            if not self._opened.done():
                self._opened.set_result(event)
        elif isinstance(event, events.SessionRefused | events.SessionClosed):
            self.closed = event
            self._over.set()
            if self._opened is not None and not self._opened.done():
                self._opened.set_exception(NoSession(session_end(event)))


def _call(calls: list[Call]) -> None:
    """The listeners of what came, called outside the lock: a listener may call the Robot API,
    which takes it."""
    for listener, values in calls:
        listener(values)


def session_end(event: events.SessionRefused | events.SessionClosed) -> str:
    """Why a local system's session did not open, or is over, in words (not the event's
    repr): "no answer to HELLO ...", "the robot refused: ...", "the robot ended the session:
    shutdown", "nothing from the robot for 10 s: the session timed out (D-RSP-13)"."""
    if isinstance(event, events.SessionRefused):
        if event.reason is None:
            return "no answer to HELLO (sent 6 times, D-RSP-12)"
        return f"the robot refused: {event.reason.name.lower().replace('_', ' ')}"
    if event.reason is ByeReason.TIMEOUT and not event.by_peer:
        silence = f"{SESSION_TIMEOUT:g} s"
        return f"nothing from the robot for {silence}: the session timed out (D-RSP-13)"
    who = "the robot" if event.by_peer else "the local system"
    return f"{who} ended the session: {event.reason.name.lower()}"


class _Protocol(asyncio.DatagramProtocol):
    def __init__(self, simulacrum: Simulacrum) -> None:
        self.simulacrum = simulacrum

    def connection_made(self, transport: asyncio.BaseTransport) -> None:
        # The selector loop's datagram transport does not derive from DatagramTransport.
        self.simulacrum._transport = cast(asyncio.DatagramTransport, transport)

    def datagram_received(self, data: bytes, addr: Address) -> None:
        self.simulacrum.received(data)

    def error_received(self, exc: Exception) -> None:
        pass  # ICMP unreachable: the robot is not there (yet); HELLO is repeated, D-RSP-12
