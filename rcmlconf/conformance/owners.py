"""Which client under test opened a connection of the client role (D-RCTP-31): the command the
harness started whose process, or a process of its session, holds the connection's other end.

A command the harness starts leads a session of its own (`command.Command`), whose ID is its
pid, and its children stay in it unless they leave it (setsid). On Linux the kernel says who
holds a connection's other end. Asked for the TCP socket whose local address is the
connection's peer and whose remote one is ours (sock_diag, one lookup by address, not a read of
/proc/net/tcp's every socket), it gives the socket's inode; /proc/PID/fd of the process that
holds it links `socket:[INODE]`. Only the processes of our sessions have their fds read:
/proc/PID/stat's sixth field is the session's ID. Elsewhere (no sock_diag or /proc, a client on
another host, one that left its session, one whose socket is closed already) the owner is
unknown, and the listener goes by what the connection says (`clients.ClientListener`).

A socket's inode is unique while it lives, so what was read once stays true: each socket seen
in our sessions is kept, and /proc is read only for a socket not seen yet. It is looked for first
in the processes known to be of our sessions (the command itself, mostly), those of sessions that
have had no connection yet first, then the session of the latest one; then in the processes not
read yet; then in the fds already read as sockets (one may have been closed, and its number
reused). The search stops where it finds it: a connection costs the reads of one process's fds,
and a flood from one process one read of each of its sockets, not of all of them a connection.
"""

from __future__ import annotations

import contextlib
import ipaddress
import os
import socket
import struct
from pathlib import Path

Address = tuple[str, int]
_Ip = ipaddress.IPv4Address | ipaddress.IPv6Address

PROC = Path("/proc")
#: Sockets kept, at most: the oldest are forgotten (read again should they come back).
MAX_KNOWN = 65536
#: linux/sock_diag.h and linux/inet_diag.h: a request for one socket by its addresses.
_NETLINK_SOCK_DIAG = 4
_SOCK_DIAG_BY_FAMILY = 20
_NLM_F_REQUEST = 1
_NO_COOKIE = 0xFFFFFFFF
_HEADER = struct.Struct("=IHHII")  # nlmsghdr: length, type, flags, sequence, port
_INODE_AT = _HEADER.size + 68  # inet_diag_msg's idiag_inode


class Owners:
    """The commands started for the cases, and which of them holds a connection's other end."""

    def __init__(self) -> None:
        #: Each started command's session ID (its pid), with the key it was started for, and
        #: the processes known to be of each.
        self._sessions: dict[int, str] = {}
        self._members: dict[int, set[str]] = {}
        #: Socket inode -> session ID, for each socket seen in our sessions' processes.
        self._known: dict[int, int] = {}
        #: Of each process of ours, the fds read: a socket's inode, or 0 for anything else.
        self._fds: dict[str, dict[str, int]] = {}
        #: The session of each process of /proc read (None: it had gone).
        self._seen: dict[str, int | None] = {}
        #: The sessions that have had a connection, the latest last.
        self._owning: dict[int, None] = {}

    def started(self, key: str, pid: int) -> None:
        """A command was started for `key` (a case's URL): `pid` leads its session."""
        self._sessions[pid] = key
        # with any process read before the harness knew of the session
        self._members[pid] = {str(pid), *(p for p, s in self._seen.items() if s == pid)}

    def ended(self, pid: int) -> None:
        """The command `pid` is over: its session owns nothing more."""
        self._sessions.pop(pid, None)
        self._owning.pop(pid, None)
        for member in self._members.pop(pid, set()):
            self._fds.pop(member, None)

    def owner(self, ours: Address, peer: Address) -> str | None:
        """The key of the command whose session holds the other end of the connection from
        `peer` to `ours`; None when it cannot be told."""
        if not self._sessions:
            return None
        inode = self._inode(_ip(peer[0]), peer[1], _ip(ours[0]), ours[1])
        if inode is None:
            return None
        session = self._known.get(inode)
        if session is None:
            session = self._search(inode)
        if session is None or session not in self._sessions:
            return None
        self._owning.pop(session, None)
        self._owning[session] = None
        return self._sessions[session]

    # -- /proc ---------------------------------------------------------------------------------

    def _search(self, inode: int) -> int | None:
        """The session of ours one of whose processes holds the socket `inode`."""
        for again in (False, True):
            if again and self._discover(inode):
                break
            idle = [s for s in self._sessions if s not in self._owning]
            for session in [*idle, *reversed(self._owning)]:
                for pid in list(self._members.get(session, ())):
                    self._read(pid, session, again)
                    if inode in self._known:
                        return self._known[inode]
        return self._known.get(inode)

    def _discover(self, inode: int) -> bool:
        """Read the processes of /proc not read yet: those of our sessions join them, their
        fds read. Whether `inode` was found."""
        try:
            pids = {name for name in os.listdir(PROC) if name.isdigit()}
        except OSError:
            return False
        for gone in self._seen.keys() - pids:
            del self._seen[gone]
        for pid in pids - self._seen.keys():
            session = self._seen[pid] = self._session_of(pid)
            if session in self._members:
                self._members[session].add(pid)
                self._read(pid, session, again=False)
        return inode in self._known

    def _read(self, pid: str, session: int, again: bool) -> None:
        """The sockets process `pid` of `session` holds: its fds not read yet, or `again` all.
        A process gone, or no more of the session, leaves it."""
        fds = PROC / pid / "fd"
        read = self._fds.setdefault(pid, {})
        try:
            if self._session_of(pid) != session:
                raise ProcessLookupError
            listed = os.listdir(fds)
        except OSError:
            self._members[session].discard(pid)
            self._fds.pop(pid, None)
            return
        for fd in listed:
            if fd in read and not again:
                continue
            try:
                link = os.readlink(fds / fd)
            except OSError:
                continue
            read[fd] = int(link[8:-1]) if link.startswith("socket:[") else 0
            if read[fd]:
                self._keep(read[fd], session)

    def _session_of(self, pid: str) -> int | None:
        """The session ID of process `pid` (None once it has gone)."""
        try:
            stat = (PROC / pid / "stat").read_bytes()
        except OSError:
            return None
        # pid (comm) state ppid pgrp session ...: comm may hold spaces and parentheses
        fields = stat[stat.rfind(b")") + 2 :].split(b" ", 4)
        with contextlib.suppress(IndexError, ValueError):
            return int(fields[3])
        return None

    def _keep(self, inode: int, session: int) -> None:
        if len(self._known) >= MAX_KNOWN:
            del self._known[next(iter(self._known))]
        self._known[inode] = session

    # -- the kernel ----------------------------------------------------------------------------

    def _inode(self, ip: _Ip, port: int, remote: _Ip, remote_port: int) -> int | None:
        """The inode of the local TCP socket from ip:port to remote:remote_port (sock_diag)."""
        if ip.version != remote.version:
            return None
        family = socket.AF_INET if ip.version == 4 else socket.AF_INET6
        request = struct.pack("=BBBBI", family, socket.IPPROTO_TCP, 0, 0, 0xFFFFFFFF)
        request += struct.pack("!HH", port, remote_port)
        request += ip.packed.ljust(16, b"\0") + remote.packed.ljust(16, b"\0")
        request += struct.pack("=III", 0, _NO_COOKIE, _NO_COOKIE)
        header = _HEADER.pack(
            _HEADER.size + len(request), _SOCK_DIAG_BY_FAMILY, _NLM_F_REQUEST, 1, 0
        )
        try:
            with socket.socket(socket.AF_NETLINK, socket.SOCK_DGRAM, _NETLINK_SOCK_DIAG) as diag:
                diag.setblocking(False)  # the kernel answers before send returns
                diag.send(header + request)
                answer = diag.recv(65536)
            kind = _HEADER.unpack_from(answer)[1]
        except (OSError, AttributeError, struct.error):  # no sock_diag here (or no answer)
            return None
        if kind != _SOCK_DIAG_BY_FAMILY or len(answer) < _INODE_AT + 4:
            return None  # an error: no such socket here
        inode: int = struct.unpack_from("=I", answer, _INODE_AT)[0]
        return inode or None  # 0: a socket no process holds any more


def _ip(text: str) -> _Ip:
    """An address's IP; an IPv4-mapped IPv6 one as IPv4 (its peer's socket is an IPv4 one)."""
    ip = ipaddress.ip_address(text.split("%")[0])
    if isinstance(ip, ipaddress.IPv6Address) and ip.ipv4_mapped is not None:
        return ip.ipv4_mapped
    return ip
