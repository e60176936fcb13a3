"""`rcmlconf sniff`: RCTP and RSP captured live, one line per message as it arrives."""

from __future__ import annotations

import errno
import logging
import select
import sys
from pathlib import Path
from typing import Any

import click

from rcmlconf.cli.console import Output
from rcmlconf.wording import plural

#: Exit status when capture cannot start: not permitted, no such interface.
CANNOT_CAPTURE = 2
#: Seconds the capture waits for a frame before it looks again (and at a Ctrl-C).
POLL = 0.2


@click.command()
@click.option(
    "-i",
    "--interface",
    "interface",
    metavar="IFACE",
    help="The interface to capture on (lo for a robot on this machine). Default: scapy's "
    "default route interface.",
)
@click.option(
    "--count",
    type=click.IntRange(min=1),
    metavar="N",
    help="Stop after N messages. Default: at Ctrl-C.",
)
@click.option(
    "--model",
    "model_path",
    type=click.Path(path_type=Path),
    metavar="MODEL.rmodel",
    help="The RSP robot model: decode Device Maps and payloads (raw bytes without it).",
)
@click.option(
    "--decode-as",
    "decode_as",
    multiple=True,
    metavar="PROTO=PORT",
    help="Also decode PORT as PROTO: rctp (the TCP control connection), rctp-data (the UDP "
    "data stream) or rsp (UDP).",
)
@click.option(
    "--filter",
    "only",
    metavar="EXPR",
    help="Capture only what both sniff's own filter (RCTP's TCP ports, and UDP) and EXPR let "
    "through. EXPR is in tcpdump's syntax: 'udp port 9000', 'host 10.0.0.7'.",
)
def sniff(
    interface: str | None,
    count: int | None,
    model_path: Path | None,
    decode_as: tuple[str, ...],
    only: str | None,
) -> None:
    """Capture RCTP/2.0 and RSP traffic live and print one line per message as it arrives:
    time, endpoints, then the method and target or the status of a control message, or the
    type and sequence number of a data-stream or RSP packet.

    RCTP's control connection is read on TCP port 7330 and reassembled (messages split across
    segments, pipelined); its data stream on the UDP ports SETUP negotiates (seen in the
    Transport fields) and 7330; RSP on UDP port 7340. Capturing needs root or CAP_NET_RAW, and
    libpcap (to compile the kernel's filter).

    \b
    Exit status: 0 done (--count reached or Ctrl-C); 1 invalid model;
      2 capture not permitted, no libpcap, no such interface, or a usage error.

    \b
    Examples:
      sudo rcmlconf sniff -i lo
      sudo rcmlconf sniff -i eth0 --model cubo.rmodel --count 100
      sudo rcmlconf sniff -i lo --decode-as rsp=9000 --filter 'udp port 9000'
    """
    output = Output()
    model = None
    if model_path is not None:
        from rcmlconf.cli.models import load_or_exit
        from rcmlconf.validate.validator import load_robot_model

        model = load_or_exit(output, "sniff", model_path, load_robot_model)
    # scapy takes a moment to import: only once the options hold.
    logging.getLogger("scapy.runtime").setLevel(logging.ERROR)
    from rcmlconf.scapy_layers import capture, rsp

    try:
        ports = [capture.parse_decode_as(text) for text in decode_as]
    except ValueError as error:
        raise click.BadParameter(str(error), param_hint="--decode-as") from None
    bpf = _bpf(ports, only)
    socket = _open(output, interface, bpf, only)
    rsp.use_model(model)
    dissector = capture.Dissector(ports)
    shown = 0
    frames = 0
    try:
        output.notice(f"capturing on {socket.iface} ({bpf}); Ctrl-C to stop")
        while count is None or shown < count:
            # A bounded wait, not a blocking read: a Ctrl-C that lands just before the read
            # would otherwise wait for the next frame, which a quiet filter may never let in.
            if not select.select([socket], [], [], POLL)[0]:
                continue
            layer, data, stamp = socket.recv_raw()
            if data is None:
                continue
            frames += 1
            linktype = _linktype(layer, data)
            when = float(stamp) if stamp is not None else _now()
            for message in dissector.frame(frames, when, linktype, data):
                output.live([(capture.summary(message), "")])
                shown += 1
                if count is not None and shown >= count:
                    break
    except KeyboardInterrupt:
        pass
    finally:
        socket.close()
    output.summary(f"{plural(shown, 'message')} in {plural(frames, 'frame')}", ok=True)


def _bpf(ports: list[tuple[str, int]], only: str | None) -> str:
    """The kernel's filter: RCTP's control connection on its TCP ports, and UDP, since the data
    stream's ports are negotiated (D-RCTP-18) and learned from the control messages; and the
    user's --filter."""
    from rcmlconf.scapy_layers.capture import DEFAULT_TCP, RCTP

    tcp = sorted({*DEFAULT_TCP, *(port for proto, port in ports if proto == RCTP)})
    ours = " or ".join([*(f"tcp port {port}" for port in tcp), "udp"])
    return ours if only is None else f"({ours}) and ({only})"


def _open(output: Output, interface: str | None, bpf: str, only: str | None) -> Any:
    """A capturing socket; the one line that says why not, and exit 2."""
    import scapy.arch  # noqa: F401  (sets conf.L2listen)
    from scapy.config import conf
    from scapy.interfaces import get_if_list

    name = interface if interface is not None else str(conf.iface)
    if name not in get_if_list():
        known = ", ".join(sorted(get_if_list()))
        output.problem("sniff", f"no interface {name!r} (this machine has {known})")
        sys.exit(CANNOT_CAPTURE)
    _compile(output, name, bpf, only)
    # Loopback shows each packet twice, going out and coming in: a socket that drops what goes
    # out sees it once, as tcpdump does. Elsewhere both directions are wanted.
    flags = conf.ifaces.dev_from_name(name).flags
    listen = conf.L2socket if flags and "LOOPBACK" in flags else conf.L2listen
    try:
        return listen(iface=name, filter=bpf)
    except PermissionError:
        pass
    except OSError as exc:
        if exc.errno not in (errno.EPERM, errno.EACCES):
            output.problem("sniff", f"cannot capture on {name}: {exc.strerror or exc}")
            sys.exit(CANNOT_CAPTURE)
    output.problem(
        "sniff",
        f"capture on {name} is not permitted: run as root, or give Python CAP_NET_RAW "
        "(sudo setcap cap_net_raw,cap_net_admin+eip $(readlink -f $(which python3)))",
    )
    sys.exit(CANNOT_CAPTURE)


def _compile(output: Output, name: str, bpf: str, only: str | None) -> None:
    """Compile the filter as the capture will (libpcap, through scapy), before capturing: a bad
    --filter is a usage error, and a machine without libpcap is told so, in one line."""
    from scapy.arch.common import compile_filter, free_filter
    from scapy.error import Scapy_Exception

    try:
        free_filter(compile_filter(bpf, iface=name))
    except ImportError:
        output.problem(
            "sniff",
            f"capture on {name} needs libpcap to compile its filter: install it (Debian:"
            " apt-get install libpcap0.8)",
        )
        sys.exit(CANNOT_CAPTURE)
    except Scapy_Exception as exc:
        # sniff's own part always compiles: what does not is the user's.
        if only is None:
            raise
        raise click.BadParameter(f"{only!r}: {exc}", param_hint="'--filter'") from None


def _linktype(layer: Any, data: bytes) -> int:
    """The link type of a captured frame, for the `FrameDecoder` that reads capture files too:
    scapy's, or guessed from the bytes when scapy does not know the interface's (Linux loopback
    gives frames with an Ethernet header of zeros)."""
    from scapy.config import conf

    from rcmlconf.pcap.frames import LINKTYPE_ETHERNET, LINKTYPE_RAW

    known = conf.l2types.layer2num.get(layer)
    if known is not None:
        return int(known)
    if data[12:14] in (b"\x08\x00", b"\x86\xdd"):
        return LINKTYPE_ETHERNET
    return LINKTYPE_RAW


def _now() -> float:
    import time

    return time.time()
