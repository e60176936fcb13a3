"""What the server benches share: each server in a process of its own, pinned to one CPU.

A child runs `main(pipe, profiler)` on its own asyncio loop: the coroutine tells the parent how to
reach it (a tuple, on the pipe), then awaits `until_stopped`: the parent's "stop", or the end of
the pipe if the parent died, or `LIFETIME` at most, so that no child outlives a bench. A profiled
child sends its profile back when it stops. Processes are spawned, not forked: the parent's
loop and sockets stay its own.
"""

from __future__ import annotations

import asyncio
import contextlib
import cProfile
import io
import multiprocessing
import os
import pstats
from collections.abc import Callable, Coroutine
from dataclasses import dataclass
from multiprocessing.connection import Connection
from multiprocessing.process import BaseProcess
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parent.parent
CAMERA = ROOT / "rcmlconf" / "reference" / "robots" / "camera" / "camera.rcml"
#: A child ends by itself after this long, whatever happens to the parent.
LIFETIME = 1800.0

Main = Callable[[Connection, "cProfile.Profile | None"], Coroutine[Any, Any, None]]


async def until_stopped(pipe: Connection, profiler: cProfile.Profile | None = None) -> None:
    """Until the parent says stop (or dies, closing the pipe), LIFETIME at most; profiled
    meanwhile when asked."""
    loop = asyncio.get_running_loop()
    stop: asyncio.Future[None] = loop.create_future()

    def readable() -> None:
        if not stop.done():
            stop.set_result(None)

    loop.add_reader(pipe.fileno(), readable)
    if profiler is not None:
        profiler.enable()
    try:
        await asyncio.wait_for(stop, LIFETIME)
    except TimeoutError:
        pass
    finally:
        if profiler is not None:
            profiler.disable()
        loop.remove_reader(pipe.fileno())


async def serve_camera(pipe: Connection, profiler: cProfile.Profile | None) -> None:
    """The reference server of the camera robot; tells (RCTP port, data port, site path)."""
    from rcmlconf.reference.drivers import choose_driver
    from rcmlconf.reference.server.adapter import ReferenceServer, ServerSettings
    from rcmlconf.validate.validator import load_robot

    model = load_robot(CAMERA)
    settings = ServerSettings(port=0, http_port=None)
    server = ReferenceServer(CAMERA, model, choose_driver("auto", model), settings)
    await server.start()
    pipe.send((server.port, server.data_port, server.robot.site_path))
    try:
        await until_stopped(pipe, profiler)
    finally:
        await server.stop()


def _child(cpu: int | None, pipe: Connection, main: Main, profile: str | None) -> None:
    if cpu is not None:
        os.sched_setaffinity(0, {cpu})
    profiler = cProfile.Profile() if profile is not None else None
    with contextlib.suppress(KeyboardInterrupt):
        asyncio.run(main(pipe, profiler))
    if profiler is not None and profile is not None:
        text = io.StringIO()
        stats = pstats.Stats(profiler, stream=text)
        stats.sort_stats("tottime").print_stats(25)
        stats.sort_stats("cumulative").print_stats(profile, 30)
        with contextlib.suppress(OSError):
            pipe.send(text.getvalue())


@dataclass
class Child:
    kind: str
    process: BaseProcess
    pipe: Connection
    #: What the child said to reach it (`serve_camera`: RCTP port, data port, site path).
    ready: tuple[Any, ...]

    @property
    def pid(self) -> int:
        return self.process.pid or 0

    def stop(self) -> str | None:
        """Stop the process; its profile, if it made one."""
        report = None
        # A child that has ended by itself (its main returned) has closed its end: the send
        # fails, but what it sent before ending, its profile, is still to be read.
        with contextlib.suppress(OSError):
            self.pipe.send("stop")
        with contextlib.suppress(OSError, EOFError):
            if self.pipe.poll(60):
                report = self.pipe.recv()
        self.process.join(15)
        if self.process.is_alive():
            self.process.terminate()
            self.process.join(5)
        if self.process.is_alive():
            self.process.kill()
            self.process.join(5)
        self.pipe.close()
        return report if isinstance(report, str) else None


def start_child(kind: str, main: Main, cpu: int | None, profile: str | None = None) -> Child:
    """`main` in a new process pinned to `cpu`; `profile`: a regular expression of the
    functions whose cumulative times the profile shows (None: not profiled)."""
    context = multiprocessing.get_context("spawn")
    ours, theirs = context.Pipe()
    process = context.Process(target=_child, args=(cpu, theirs, main, profile), daemon=True)
    process.start()
    theirs.close()
    if not ours.poll(60):
        process.kill()
        raise RuntimeError(f"the {kind} process did not start")
    return Child(kind, process, ours, ours.recv())


def cpu_seconds(pid: int) -> float:
    """User + system CPU time of a process, from /proc (0.0 where there is no /proc)."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rpartition(")")[2].split()
    except OSError:
        return 0.0
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")
