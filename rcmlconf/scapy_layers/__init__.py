"""scapy layers for RCTP/2.0 and RSP: a second, independent dissector of their wire formats.

In a scapy session::

    >>> from rcmlconf.scapy_layers import rctp, rsp
    >>> rsp.use_model("cubo.rmodel")            # RSP Device Maps and payloads; raw without it
    >>> sniff(offline="run.pcap", session=TCPSession).show()

- `rctp`: control messages over TCP (``RCTPRequest``, ``RCTPResponse``, with ``tcp_reassemble``
  for messages split across segments and pipelined) and the UDP data stream (``RCTPStream`` and
  its DATA and FLOW payloads). Bound to port 7330; ``rctp.bind_port`` for others.
- `rsp`: the RSP header and bodies over UDP port 7340; ``rsp.bind_port`` for others. The robot
  model as they read it is `rsp_model`'s, a Device Map and its payloads `rsp_device_map`'s.
- `capture`: the messages of a capture file or a live capture, each dissected by the layers
  (`detail` for `rcmlconf dissect -V`, `Dissector` for `rcmlconf sniff`), found as `rcmlconf
  dissect` finds them (ports, `--decode-as rctp|rctp-data|rsp=PORT`, SETUP, heuristics).

Only this package and the commands that use it import scapy (`import scapy.layers.inet` alone
takes about 0.3 s).
"""

from __future__ import annotations

from rcmlconf.scapy_layers.capture import (
    Dissector,
    Message,
    detail,
    detail_of,
    messages,
    parse_decode_as,
    render,
    summary,
)

__all__ = [
    "Dissector",
    "Message",
    "detail",
    "detail_of",
    "messages",
    "parse_decode_as",
    "render",
    "summary",
]
