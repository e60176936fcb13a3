"""An RCTP/2.0 client running the conformance scenario of specs/rctp-2.0.md D-RCTP-31.

python main.py --url rctp://HOST:PORT/PATH [--rcml FILE] [--fault NAME]... [-v]
python main.py --cases http://HOST:PORT+1/cases [--fault NAME]... [-v]
python main.py --list-faults | --list-bugs
(--bug NAME, repeatable, plants a robustness bug for the fuzzer's tests)
"""

from __future__ import annotations

import argparse
import asyncio
import http.client
import signal
import sys
import traceback
from html.parser import HTMLParser
from pathlib import Path
from urllib.parse import urljoin, urlsplit

import bugs
from faults import FAULTS
from rcml import MAX_DOCUMENT, Model, RcmlError, parse_rcml
from scenario import Scenario
from session import Session, Url

HTTP_TIMEOUT = 30.0  # the harness holds a request for a case not yet reached (D-RCTP-31)
MAX_INDEX = 1 << 20
MAX_LINKS = 1024


class _Links(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.hrefs: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "a" and len(self.hrefs) < MAX_LINKS:
            self.hrefs += [v for k, v in attrs if k == "href" and v]


def http_get(url: str, limit: int) -> bytes | None:
    """GET an http URL: its body when the answer is 200 and at most `limit` bytes."""
    parts = urlsplit(url)
    if parts.scheme != "http" or not parts.hostname:
        return None
    try:
        conn = http.client.HTTPConnection(parts.hostname, parts.port or 80, timeout=HTTP_TIMEOUT)
    except (ValueError, http.client.HTTPException):
        return None
    try:
        path = (parts.path or "/") + (f"?{parts.query}" if parts.query else "")
        conn.request("GET", path, headers={"User-Agent": "foreign-rctp-client/2.0"})
        resp = conn.getresponse()
        if resp.status != 200:
            return None
        data = resp.read(limit + 1)
        return data if len(data) <= limit else None
    except (OSError, http.client.HTTPException, ValueError):
        return None
    finally:
        conn.close()


def fetch_model(url: Url, faults: set[str], log: bool) -> Model | None:
    """D-RCTP-31 step 1: the index at http://HOST:PORT+1/PATH/, its one link whose path ends
    in .rcml, that document read as xml.md says (D-RCTP-29)."""
    index = url.http(url.path.rstrip("/") + "/")
    page = http_get(index, MAX_INDEX)
    if page is None:
        return _nothing(f"no index at {index}")
    links = _Links()
    try:
        links.feed(page.decode("utf-8", "replace"))
        links.close()
    except AssertionError:  # html.parser on some broken markup
        pass
    found = sorted({urljoin(index, h.strip()).split("#")[0] for h in links.hrefs})
    rcmls = [u for u in found if urlsplit(u).path.endswith(".rcml")]
    if len(rcmls) != 1:
        return _nothing(f"{index} links {len(rcmls)} .rcml files, not one")
    data = http_get(rcmls[0], MAX_DOCUMENT)
    if data is None:
        return _nothing(f"cannot fetch {rcmls[0]}")

    def load_dtd(system_id: str) -> bytes | None:  # the load-dtd fault only
        return http_get(urljoin(rcmls[0], system_id), MAX_DOCUMENT)

    try:
        model = parse_rcml(
            data,
            load_dtd if "load-dtd" in faults else None,
            foreign="read-foreign-namespace" in faults,
        )
    except RcmlError as e:
        return _nothing(f"{rcmls[0]}: {e}")
    if log:
        print(f"the robot's RCML: {rcmls[0]} (site {model.site})", file=sys.stderr)
    return model


def _nothing(why: str) -> Model | None:
    print(f"main.py: {why}", file=sys.stderr)
    return None


class Runner:
    def __init__(self, args: argparse.Namespace, model: Model | None) -> None:
        self.args = args
        self.faults = set(args.fault)
        self.model = model
        self.stop = asyncio.Event()
        self.session: Session | None = None

    def on_signal(self) -> None:
        self.stop.set()
        if self.session is not None:
            self.session.poke()

    async def case(self, text: str) -> int:
        """One run of the scenario: 0 when it ran as D-RCTP-31 says, 1 when it could not."""
        try:
            url = Url.parse(text)
        except ValueError as e:
            print(f"main.py: {e}", file=sys.stderr)
            return 1
        model = self.model
        if model is None:
            model = await asyncio.to_thread(fetch_model, url, self.faults, self.args.verbose)
            if model is None:
                return 1
        if self.stop.is_set():
            return 0
        session = Session(url, model, self.faults, self.stop, self.args.verbose)
        self.session = session
        try:
            try:
                await session.open()
            except (OSError, TimeoutError) as e:
                print(f"main.py: no connection to {url.host}:{url.port}: {e}", file=sys.stderr)
                return 1
            await Scenario(session, model).run()
            return 0
        except Exception:  # a bug of ours: report it, end this run cleanly
            traceback.print_exc()
            return 1
        finally:
            await session.finish()
            self.session = None

    async def run(self) -> int:
        loop = asyncio.get_running_loop()
        for sig in (signal.SIGINT, signal.SIGTERM):
            loop.add_signal_handler(sig, self.on_signal)
        if self.args.url:
            status = await self.case(self.args.url)
            return 0 if self.stop.is_set() else status
        body = await asyncio.to_thread(http_get, self.args.cases, 1 << 20)
        if body is None:
            print(f"main.py: cannot fetch the case list {self.args.cases}", file=sys.stderr)
            return 1
        cases = [line.strip() for line in body.decode("utf-8", "replace").splitlines()]
        for text in filter(None, cases):
            if self.stop.is_set():
                break
            status = await self.case(text)
            print(f"{text}\t{'ran' if status == 0 else 'could not run'}", file=sys.stderr)
        return 0


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description="An RCTP/2.0 client running the conformance scenario (D-RCTP-31)."
    )
    which = parser.add_mutually_exclusive_group()
    which.add_argument("--url", help="a case URL, rctp://HOST:PORT/PATH: one run")
    which.add_argument("--cases", help="http://HOST:PORT+1/cases: one run per URL it lists")
    parser.add_argument("--rcml", help="the robot's RCML file (skips step 1, the files)")
    parser.add_argument("--fault", action="append", default=[], metavar="NAME")
    parser.add_argument("--list-faults", action="store_true")
    parser.add_argument(
        "--bug",
        action="append",
        default=[],
        metavar="NAME",
        help="plant a robustness bug, for the fuzzer's tests (see --list-bugs)",
    )
    parser.add_argument("--list-bugs", action="store_true", help="print the planted bugs")
    parser.add_argument("-v", "--verbose", action="store_true")
    args = parser.parse_args(argv)
    if args.list_faults:
        for name, (rid, what) in FAULTS.items():
            print(f"{name}\t{rid}\t{what}")
        return 0
    unknown = [f for f in args.fault if f not in FAULTS]
    if unknown:
        parser.error(f"unknown fault {unknown[0]} (see --list-faults)")
    unknown = [b for b in args.bug if b not in bugs.BUGS]
    if unknown:
        parser.error(f"unknown bug {unknown[0]} (see --list-bugs)")
    if args.list_bugs:
        print(bugs.listing(), end="")
        return 0
    bugs.active = set(args.bug)
    if not args.url and not args.cases:
        parser.error("--url or --cases is required")
    model = None
    if args.rcml:
        try:
            foreign = "read-foreign-namespace" in args.fault
            model = parse_rcml(Path(args.rcml).read_bytes(), foreign=foreign)
        except (OSError, RcmlError) as e:
            print(f"main.py: {args.rcml}: {e}", file=sys.stderr)
            return 1
    try:
        return asyncio.run(Runner(args, model).run())
    except KeyboardInterrupt:
        return 0


if __name__ == "__main__":
    sys.exit(main())
