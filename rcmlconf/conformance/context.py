"""What a case is given to run: the `Context`.

A context holds the target and the case's transcript. It opens probes, and closes them when the
case ends. Its checks turn what the target answered into a verdict.
"""

from __future__ import annotations

import asyncio
import secrets
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Protocol, TypeVar

from rcmlconf.conformance.probes.control import ControlProbe
from rcmlconf.conformance.probes.local_probe import LocalProbe
from rcmlconf.conformance.probes.lost import Contact
from rcmlconf.conformance.probes.outstanding import Outstanding
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.run_defaults import SESSION_WAIT
from rcmlconf.conformance.targets import Target
from rcmlconf.conformance.transcript import Address, Transcript
from rcmlconf.conformance.verdicts import Failed, Inconclusive, NotApplicable
from rcmlconf.impair.channel import Counts, ImpairedChannel, derive_seed
from rcmlconf.impair.spec import Impairment, parse_impairment
from rcmlconf.rcml.model import AccessNode, AccessType, DataNode, Permission, RcmlDocument
from rcmlconf.rctp.messages import Request, Response

if TYPE_CHECKING:
    from rcmlconf.conformance.loopwatch import LoopWatch

T = TypeVar("T")
#: A hold of the harness's loop this long (seconds, times --timeout-scale) makes a failed timing
#: check inconclusive. The loop's ticks are due every 5 ms, and timing checks allow tens of ms.
LATE = 0.02
_ANY = Permission(0)


class CaseRules(Protocol):
    """What a context reads of its case (`registry.Case`).

    It names the case, gives its time, says which flows run impaired and which role it plays.
    """

    @property
    def id(self) -> str: ...

    @property
    def requirements(self) -> tuple[str, ...]: ...

    @property
    def role(self) -> Role: ...

    @property
    def timeout(self) -> float: ...

    @property
    def impairment(self) -> str | None: ...

    @property
    def waits_session(self) -> bool: ...


def outside_bounds(value: float, low: float, high: float) -> float:
    """How far `value` lies outside [low, high], or 0 within. It serves as a failed check's `by`."""
    return max(low - value, value - high, 0.0)


@dataclass
class Context:
    case: CaseRules
    target: Target
    #: Multiplies every wait (--timeout-scale).
    scale: float = 1.0
    #: --seed, for impairments and anything random a case does.
    seed: int = 0
    #: The run's free RSP robots (`Target.rsp`), shared by its cases.
    robots: asyncio.Queue[Address] | None = None
    #: --impair: the impairment of the UDP flows of each case that declares none of its own.
    impair: Impairment | None = None
    transcript: Transcript = field(default_factory=Transcript)
    _closers: list[Callable[[], None]] = field(default_factory=list)
    #: The requests of the case's control connections waiting for answers (`answers_in_place`).
    _outstanding: list[Outstanding] = field(default_factory=list)
    #: Whether closing the case stops the client started for it (`client`).
    _finishing: bool = False
    #: The impairment channels of the case's probes (`watch`), for `excuse`.
    _channels: list[ImpairedChannel] = field(default_factory=list)
    #: How late the harness's loop ran, for `expect(..., timing=True)`. One for the whole run.
    loop_watch: LoopWatch | None = None
    #: --session-wait: the longest session timeout the case waits out (D-RCTP-11).
    session_wait: float = SESSION_WAIT
    #: The RSP robot that the runner took for the case before the case started (`rsp`).
    taken: Address | None = None
    #: Parts of the case's requirement it could not check on this target (`cannot_check`).
    unchecked: list[str] = field(default_factory=list)
    #: When the case started, in loop time.
    started: float = field(default_factory=lambda: asyncio.get_running_loop().time())
    #: The case's control connections to the server, or its datagrams to the robot, and how
    #: they went. The runner reads it to decide whether to give up on the target.
    contact: Contact = field(default_factory=Contact)

    @property
    def timeout(self) -> float:
        """The case's time, scaled by --timeout-scale.

        A case that waits out the server's session timeout also gets what --session-wait adds.
        """
        extra = self.session_wait - SESSION_WAIT if self.case.waits_session else 0.0
        return (self.case.timeout + max(extra, 0.0)) * self.scale

    @property
    def wait(self) -> float:
        """How long to wait for one answer: a third of the case's time."""
        return self.timeout / 3

    @property
    def left(self) -> float:
        """Seconds left of the case's time. Its waits may take no more."""
        return self.started + self.timeout - asyncio.get_running_loop().time()

    def cannot_check(self, part: str) -> None:
        """Record that this part of the case cannot be checked on this target.

        For example, its robot has no node that could show it, or its client refused what would.
        A pass then says so; it never passes silently.
        """
        if part not in self.unchecked:
            self.unchecked.append(part)

    def waited_session(self, announced: int) -> int:
        """`announced`, the session timeout of a CONNECT answer (D-RCTP-11).

        The run must wait that long. If it waits less, the case is inconclusive, and the message
        says how to wait for it.
        """
        if announced > self.session_wait:
            raise Inconclusive(
                f"the session timeout is {announced} s and the run waits out"
                f" {self.session_wait:g} s at most: --session-wait {announced} waits for it"
            )
        return announced

    @property
    def impairment(self) -> Impairment:
        """The impairment the case's UDP flows go through.

        It is the case's own if it declares one: the case needs that loss or reordering to check
        what it checks. Otherwise it is --impair's, or none.
        """
        if self.case.impairment:
            return parse_impairment(self.case.impairment)
        return self.impair or parse_impairment("none")

    def impairment_seed(self, *path: int | str) -> int:
        """A seed for one flow of the case, from --seed. The same seed gives the same run."""
        return derive_seed(self.seed, self.case.id, *path)

    def watch(self, *channels: ImpairedChannel | None) -> None:
        """Count what these impairment channels of a probe of the case do (`excuse`)."""
        self._channels.extend(c for c in channels if c is not None)

    def excuse(self) -> str:
        """Why a failure may be the run's impairment and not the target's fault.

        It says what --impair did to the flows of a case written for a clean path. It is ""
        when --impair did nothing to them.

        Such a failure is inconclusive. Loss, reordering or duplication that the case did not
        plan for can explain it.

        A case that declares an impairment runs under its own. It was written to tell the
        impairment's effects from the target's faults, so its failure stands.
        """
        if self.impair is None or self.case.impairment:
            return ""
        counts = Counts()
        for channel in self._channels:
            counts += channel.counts
        done = [
            f"{number} {what}"
            for number, what in (
                (counts.lost, "lost"),
                (counts.corrupted, "corrupted"),
                (counts.duplicated, "duplicated"),
                (counts.reordered, "held back"),
            )
            if number
        ]
        if self.impair.jitter and counts.sent:  # the gaps between datagrams are not the peer's
            done.append(f"delayed with {self.impair.jitter * 1000:g} ms of jitter")
        return f"--impair {self.impair}: datagrams {', '.join(done)}" if done else ""

    # -- the target ----------------------------------------------------------------------------

    @property
    def robot(self) -> RcmlDocument:
        """The RCTP target's robot.

        For a client case, it is the robot that the harness plays to the client (D-RCTP-31).
        Not applicable when there is none.
        """
        if self.case.role is Role.CLIENT and self.target.clients is not None:
            return self.target.clients.robot
        if self.target.robot is None:
            raise NotApplicable("the target's RCML is not known (give --rcml)")
        return self.target.robot

    def need(self, feature: str) -> None:
        if feature not in self.target.features:
            raise NotApplicable(f"the ICS does not declare {feature!r}")

    def access(
        self,
        kind: AccessType | None = None,
        permission: Permission = _ANY,
        where: Callable[[AccessNode], bool] = lambda _: True,
    ) -> AccessNode:
        """The robot's first access of `kind` that has `permission` and for which `where` holds.

        Not applicable when the robot has none.
        """
        for access in self.robot.access_nodes():
            of_kind = kind is None or access.type is kind
            if of_kind and permission in access.permission and where(access):
                return access
        wanted = f"{kind.value if kind else 'any'} access with {permission.to_text() or '-'}"
        raise NotApplicable(f"the robot has no {wanted}")

    def data(self, kind: AccessType, permission: Permission) -> DataNode:
        """A data node of an access of `kind` that has `permission` itself."""
        access = self.access(kind, where=lambda a: any(permission in d.permission for d in a.data))
        return next(d for d in access.data if permission in d.permission)

    # -- probes --------------------------------------------------------------------------------

    async def control(self) -> ControlProbe:
        """A new control connection to the RCTP server under test."""
        if self.target.server is None:
            raise NotApplicable("no RCTP server under test (--target)")
        probe = await ControlProbe.open(
            self.target.server, self.transcript, self.wait, self.contact
        )
        self._closers.append(probe.close)
        self._outstanding.append(probe.outstanding)
        return probe

    async def session(self) -> ControlProbe:
        """A control connection with a session open.

        Inconclusive if CONNECT fails. The rctp/session cases check CONNECT itself.
        """
        probe = await self.control()
        answer = await probe.connect(self.target.site_path)
        if answer.status != 200 or probe.session is None:
            missing = " without a Session" if answer.status == 200 else ""  # D-RCTP-11
            raise Inconclusive(f"CONNECT was answered {answer.status} {answer.reason}{missing}")
        return probe

    async def client(self) -> ControlProbe:
        """The next connection of the RCTP client under test. The harness is its server."""
        listener = self.target.clients
        if listener is None:
            raise NotApplicable("no RCTP client under test (--role client)")
        probe = await listener.accept(self.case.id, self.transcript, self.wait)
        self._closers.append(probe.close)
        self._outstanding.append(probe.outstanding)
        if not self._finishing:  # on close, stop the case's client and note how it ran
            self._finishing = True
            self._closers.insert(0, lambda: self.transcript.notes(listener.finish(self.case.id)))
        return probe

    async def client_session(self, timeout: int = 60) -> tuple[ControlProbe, Request]:
        """A client's connection, and its CONNECT request.

        The CONNECT was answered 200 with a new session (D-RCTP-11).
        """
        probe = await self.client()
        connect = await probe.next_request(requirement="R-RCTP-17")
        if connect.method != "CONNECT":
            raise Failed("R-RCTP-17", "CONNECT first", f"{connect.method} {connect.target}")
        probe.session = secrets.token_hex(8)
        await probe.answer(connect, fields=[("Session", f"{probe.session};timeout={timeout}")])
        return probe, connect

    async def local(self, *, again: bool = False) -> LocalProbe:
        """The next session of the RSP local system under test. The harness is its robot.

        The session starts with the next HELLO of a new session (D-RSP-24).

        With `again`, it is the session that the local system opens itself after the case sent
        REFUSED. No other local system is summoned for it.
        """
        listener = self.target.locals
        if listener is None:
            raise NotApplicable("no RSP local system under test (--role local)")
        probe = await listener.accept(
            self.transcript,
            self.wait,
            summon=not again,
            # Other cases' local systems may run beside this one. Their first HELLOs ask for no
            # encryption. The HELLO that follows this case's REFUSED 2 asks for encryption
            # (D-RSP-24 step 1), and that tells it apart. It may come from another socket of
            # the same local system.
            sealed=again and listener.side_by_side,
            impairment=self.impairment,
            seed=self.impairment_seed("local", "forward"),
        )
        self.watch(probe.channel)
        probe.quiet *= self.scale
        self._closers.append(probe.close)
        if not self._finishing:  # on close, stop the case's local system and note how it ran
            self._finishing = True
            self._closers.insert(0, lambda: self.transcript.notes(listener.finish()))
        return probe

    async def rsp(self) -> Address:
        """An RSP robot under test, for this case alone until the case ends.

        A robot serves one session at a time (D-RSP-12).
        """
        if self.taken is not None:  # the runner gives it back when the case ends
            address, self.taken = self.taken, None
        else:
            robots = self.robots
            if robots is None or not self.target.rsp:
                raise NotApplicable("no RSP robot under test (--rsp-target)")
            address = await robots.get()
            self._closers.append(lambda: robots.put_nowait(address))
        self._closers.append(
            lambda: self.contact.datagrams(*self.transcript.crossed("udp", address[1]))
        )
        return address

    def on_close(self, closer: Callable[[], None]) -> None:
        self._closers.append(closer)

    def close(self) -> None:
        while self._closers:
            self._closers.pop()()

    def answers_in_place(self, doubts: bool = True) -> None:
        """Raise the first answer out of place that a control connection of the case read.

        Such an answer breaks R-RCTP-3, R-RCTP-5 or D-RCTP-10 (`Outstanding`). It fails the case,
        whatever the case made of it. A case that took it for silence, or went on, was misled.

        With `doubts`, it then raises the first answer without CSeq that said a request could
        not be framed (`Outstanding.doubt`). Pass `doubts` when the case did not fail on its own.
        """
        for outstanding in self._outstanding:
            if outstanding.failure is not None:
                raise outstanding.failure
        for outstanding in self._outstanding if doubts else ():
            if outstanding.doubt is not None:
                raise outstanding.doubt

    # -- checks --------------------------------------------------------------------------------

    def requirement(self, requirement: str | None) -> str:
        return requirement or self.case.requirements[0]

    def expect(
        self,
        holds: bool,
        expected: str | tuple[str, ...],
        actual: str,
        requirement: str | None = None,
        *,
        timing: bool = False,
        by: float | None = None,
    ) -> None:
        """Fail the case unless `holds`.

        A `timing` check reads times off the harness's clock. If it fails while the harness's
        event loop was held during the case, it may be inconclusive instead. The datagrams were
        read late, so the gaps measured are the harness's, not the target's. The holds must
        explain the failure:

        - `by`, where the check can say it, is how far past its bound the thing seen lies, in
          seconds of the harness's clock. The holds must add up to that much, and to LATE at
          least (D-RSP-26, D-RCTP-33). Each hold delays what the harness reads by its length at
          most, and several by their sum: a process short of CPU is held many times a little.
          So a target that sends for half a second after it should stop is not excused by a
          250 ms hold.
        - Without `by`, one hold of LATE or longer excuses the failure.
        """
        if holds:
            return
        watch = self.loop_watch if timing else None
        if watch is not None:
            held = watch.held(self.started) if by is None else watch.total(self.started)
            if held >= max(by or 0.0, LATE * self.scale):
                wanted = " or ".join((expected,) if isinstance(expected, str) else expected)
                raise Inconclusive(
                    f"expected {wanted}; got {actual}; but the harness's event loop was held"
                    f" {held * 1000:.0f} ms during the case: its clock cannot judge the target's"
                    " timing"
                )
        raise Failed(self.requirement(requirement), expected, actual)

    def expect_status(
        self,
        answer: Response,
        statuses: int | Iterable[int],
        requirement: str | None = None,
        *,
        what: str = "",
    ) -> None:
        """Fail unless the answer's status is one of `statuses`. `what` names the request."""
        allowed = (statuses,) if isinstance(statuses, int) else tuple(statuses)
        prefix = f"{what}: " if what else ""
        self.expect(
            answer.status in allowed,
            tuple(f"{prefix}{s}" for s in allowed),
            f"{answer.status} {answer.reason}",
            requirement,
        )


def expect_answer(
    ctx: Context,
    answer: Response,
    statuses: int | Iterable[int],
    what: str,
    requirement: str | None = None,
) -> None:
    """`ctx.expect_status`, saying which request the answer was to."""
    ctx.expect_status(answer, statuses, requirement, what=what)
