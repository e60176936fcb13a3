"""The text of a decoded segment's addresses and endpoints, IPv4 or IPv6."""

from __future__ import annotations

import socket


def address_text(address: bytes) -> str:
    """`192.0.2.7`, or `2001:db8::7`."""
    family = socket.AF_INET if len(address) == 4 else socket.AF_INET6
    return socket.inet_ntop(family, address)


def endpoint_text(address: bytes, port: int) -> str:
    """`192.0.2.7:7330`, or `[2001:db8::7]:7330`."""
    if len(address) == 4:
        return f"{address_text(address)}:{port}"
    return f"[{address_text(address)}]:{port}"
