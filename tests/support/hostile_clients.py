"""Hostile RCTP clients for `run --role client --client-command`: a script the harness starts
once per case, `python hostile_clients.py {url} CASE=MODE ...`. In a case named (its URL's path
less the `/`) it does that MODE; in every other case it runs the reference client's scenario, as
a good client would. So one run shows whether one case's hostile client spills into the cases
beside it.

MODE is one of:
- `silent`: connects and sends nothing;
- `flood`: opens FLOOD connections at once, each sending CONNECT of the case's path, and
  answers nothing;
- `elsewhere`: CONNECTs a path that names no case;
- `garbage`: sends bytes that are no request;
- `forked-MODE`: MODE, in a child process (the harness started its parent).

Each stays until the harness stops it, LIFETIME seconds at most.
"""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from pathlib import Path
from urllib.parse import urlsplit

FLOOD = 500
LIFETIME = 20.0
SCRIPT = Path(sys.executable).parent / "rcmlconf"
REFERENCE = [str(SCRIPT)] if SCRIPT.exists() else [sys.executable, "-m", "rcmlconf"]
ELSEWHERE = b"CONNECT /no/such/case RCTP/2.0\r\nCSeq: 1\r\n\r\n"
GARBAGE = b"\x00\xff\x16\x03\x01 not a request \xde\xad\xbe\xef\r\n\r\n"


def main(url: str, *modes: str) -> None:
    split = urlsplit(url)
    mode = dict(m.split("=", 1) for m in modes).get(split.path[1:])
    if mode is None:
        reference = [*REFERENCE, "client", url, "scenario"]
        os.execv(reference[0], reference)
    if mode.startswith("forked-"):
        child = [sys.executable, __file__, url, f"{split.path[1:]}={mode[7:]}"]
        subprocess.run(child, timeout=LIFETIME, check=False)
        return
    address = (split.hostname or "127.0.0.1", split.port or 7330)
    held = [socket.create_connection(address, timeout=LIFETIME)]
    if mode == "flood":
        connect = f"CONNECT {split.path} RCTP/2.0\r\nCSeq: 1\r\n\r\n".encode()
        for _ in range(FLOOD - 1):
            try:
                held[-1].sendall(connect)
                held.append(socket.create_connection(address, timeout=LIFETIME))
            except OSError:  # the harness may close some: the rest stay open
                continue
    elif mode == "elsewhere":
        held[0].sendall(ELSEWHERE)
    elif mode == "garbage":
        held[0].sendall(GARBAGE)
    elif mode != "silent":
        raise SystemExit(f"unknown mode {mode!r}")
    print(f"{mode}: {len(held)} connections opened to {address[0]}:{address[1]}", flush=True)
    time.sleep(LIFETIME)


if __name__ == "__main__":
    main(*sys.argv[1:])
