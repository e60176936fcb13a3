"""The runner gives up on a dead RCTP server or RSP robot, as the client role does when no
client ever connected (`ClientListener.arrival`). A server that resets, closes or leaves
unanswered every connection, or a robot that answers no datagram, would take each of its cases
to its own end, a few seconds or the case's timeout apiece: hundreds of verdicts that say one
thing.

Once IN_A_ROW cases in a row (as they end) found the target sent no byte on any of their
connections, or no datagram back, the cases of its role not yet started are not run:
inconclusive, with the reason. That is when the target never sent a byte in the run (to the
cases still running either), or when it refused their connections: nothing listens, it stopped
(crashed mid-run, say; it may have reset those it had taken as it stopped). A target that
answers at all is not given up on: a case it sent a byte in, or that passed, starts the count
again. A case that made no connection and sent no datagram (not applicable before it tried)
counts for neither. A case already running is not cut."""

from __future__ import annotations

from collections import Counter

from rcmlconf.conformance.probes.lost import Contact
from rcmlconf.conformance.roles import Role
from rcmlconf.conformance.verdicts import Verdict

#: The roles whose target a run gives up on: those the harness sends to first.
GIVEN_UP = frozenset({Role.SERVER, Role.ROBOT})

#: Each role's basic interconnection case (ISO/IEC 9646's): run before the rest of its role, so
#: that a target that answers nothing fails it before the run gives up on the rest.
BASIC = frozenset({"rctp/msg/connect", "rsp/session/welcome"})
#: Cases in a row, as they end, that found the target dead before the rest give up.
IN_A_ROW = 8
#: How the reason of a case given up on begins.
NOT_RUN = "not run: "
#: What the cases before found, when their connections all ended one way.
_EVERY = {
    "reset": "the target reset every connection of {cases}",
    "closed": "the target closed every connection of {cases} without a byte",
    "silent": "the target sent nothing on any connection of {cases}",
    "refused": "the target refused every connection of {cases}",
    "unreached": "no connection of {cases} reached the target",
    "unanswered": "the target answered no datagram of {cases}",
}


class GiveUp:
    """Whether the rest of a run's cases of one role are run, from the contacts of those that
    ran: one a role, since a run has one target of each (`Target`)."""

    def __init__(self) -> None:
        #: How the connections of the last cases ended that found the target dead, the latest last.
        self._row: list[Counter[str]] = []
        self._running: list[Contact] = []
        self._heard = False
        #: Why the cases not yet started are not run (from NOT_RUN on), once given up.
        self.reason: str | None = None

    def begin(self) -> Contact:
        """A case starts: its connections' contact, to give `ended` when it ends."""
        contact = Contact()
        self._running.append(contact)
        return contact

    def ended(self, contact: Contact, verdict: Verdict) -> None:
        self._running.remove(contact)
        self._heard = self._heard or contact.heard
        ends = contact.ends()
        if contact.heard or verdict is Verdict.PASS:
            self._row.clear()
        elif ends:
            self._row = [*self._row, ends][-IN_A_ROW:]
        if self.reason is None and len(self._row) == IN_A_ROW:
            self.reason = self._why()

    def _why(self) -> str | None:
        found: Counter[str] = sum(self._row, Counter())
        cases = f"the {IN_A_ROW} cases before"
        if len(found) == 1:
            why = _EVERY[next(iter(found))].format(cases=cases)
        else:
            shown = ", ".join(f"{n} {how}" for how, n in found.most_common())
            why = f"the target sent no byte on any connection of {cases} ({shown})"
        if not self._heard and not any(contact.heard for contact in self._running):
            return NOT_RUN + why
        # It answered before: given up on only once nothing listens (resets of connections it
        # had taken as it stopped aside).
        if "refused" in found and set(found) <= {"refused", "reset"}:
            return f"{NOT_RUN}{why}, having answered before: it stopped"
        return None
