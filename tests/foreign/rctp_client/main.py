"""An RCTP/2.0 client (an operator console's protocol side), written from specs/rctp-2.0.md.

python main.py --url rctp://HOST[:PORT]/SITE [--rcml FILE] [--loop] [-v] [--fault NAME]...
"""

from __future__ import annotations

import argparse
import asyncio
import http.client
import signal
import sys
import time
import traceback
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import urljoin, urlsplit

from faults import FAULTS
from rcml import MAX_DOCUMENT, Model, RcmlError, parse_rcml
from session import Session, Url

REFETCH_AFTER = 30.0


class _Links(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.hrefs: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "a":
            self.hrefs += [v for k, v in attrs if k == "href" and v]


def _get(host: str, port: int, path: str) -> bytes | None:
    conn = http.client.HTTPConnection(host, port, timeout=2.0)
    try:
        conn.request("GET", path, headers={"User-Agent": "foreign-rctp-client/1.0"})
        resp = conn.getresponse()
        if resp.status != 200:
            return None
        data = resp.read(MAX_DOCUMENT + 1)
        return data if len(data) <= MAX_DOCUMENT else None
    except (OSError, http.client.HTTPException):
        return None
    finally:
        conn.close()


def fetch_model(url: Url) -> Model | None:
    """D-RCTP-29: the robot's files over HTTP on the port after the RCTP port; at `/` a page
    whose links list them. The RCML whose site path is ours is the robot's."""
    if url.port >= 65535:
        return None
    host, port = url.host, url.port + 1
    page = _get(host, port, "/")
    if page is None:
        return None
    links = _Links()
    links.feed(page.decode("utf-8", "replace"))
    base = f"http://{host}:{port}/"
    found: list[Model] = []
    for href in links.hrefs[:64]:
        target = urlsplit(urljoin(base, href))
        if not target.path.lower().endswith(".rcml") or target.netloc not in ("", f"{host}:{port}"):
            continue
        data = _get(host, port, target.path)
        if data is None:
            continue
        try:
            found.append(parse_rcml(data))
        except RcmlError:
            continue
        if found[-1].site_path() == url.path:
            return found[-1]
    return found[0] if len(found) == 1 else None


async def run(args: argparse.Namespace, url: Url, faults: set[str], model: Model | None) -> int:
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    fetched_at = -REFETCH_AFTER
    while True:
        if model is None and time.monotonic() - fetched_at >= REFETCH_AFTER:
            fetched_at = time.monotonic()
            model = await asyncio.to_thread(fetch_model, url)
            if model is not None and args.verbose:
                print(f"the robot's RCML fetched: {model.site}", file=sys.stderr)
        session = Session(url, model, faults, stop, args.verbose)
        session.play_time = max(0.0, args.play)
        connected = False
        try:
            await session.open()
            connected = True
            ok = await session.run()
        except (OSError, TimeoutError) as e:
            ok = False
            session.log(f"no connection to {url.host}:{url.port}: {e}", always=not args.loop)
        except Exception:  # a bug of ours must not end a console that runs unattended
            ok = False
            traceback.print_exc()
            session.close("internal error")
        if not args.loop:
            return 0 if ok else 1
        if stop.is_set():
            return 0
        try:
            await asyncio.wait_for(stop.wait(), 0.1 if connected else 0.3)
            return 0
        except TimeoutError:
            pass


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description="An RCTP/2.0 client from specs/rctp-2.0.md.")
    parser.add_argument("--url", help="rctp://HOST[:PORT]/SITE")
    parser.add_argument("--rcml", help="the robot's RCML file (else fetched, D-RCTP-29)")
    parser.add_argument("--loop", action="store_true", help="run sessions until SIGINT/SIGTERM")
    parser.add_argument("--fault", action="append", default=[], metavar="NAME")
    parser.add_argument("--list-faults", action="store_true")
    parser.add_argument(
        "--play", type=float, default=1.0, metavar="S", help="seconds streams and events play"
    )
    parser.add_argument("-v", "--verbose", action="store_true")
    args = parser.parse_args(argv)
    if args.list_faults:
        for name, (rid, what) in FAULTS.items():
            print(f"{name}\t{rid}\t{what}")
        return 0
    unknown = [f for f in args.fault if f not in FAULTS]
    if unknown or not args.url:
        parser.error(f"unknown fault {unknown[0]}" if unknown else "--url is required")
    try:
        url = Url.parse(args.url)
    except ValueError as e:
        parser.error(str(e))
    model = None
    if args.rcml:
        try:
            model = parse_rcml(Path(args.rcml).read_bytes())
        except (OSError, RcmlError) as e:
            print(f"main.py: {args.rcml}: {e}", file=sys.stderr)
            return 2
    try:
        return asyncio.run(run(args, url, set(args.fault), model))
    except KeyboardInterrupt:
        return 0


if __name__ == "__main__":
    sys.exit(main())
