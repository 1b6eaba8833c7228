"""The workers of ``lsys3d edit``: child processes that grow grammars, and the rule that a newer edit wins.

Each worker is ``python -m lsys3d.edit.worker`` (:mod:`lsys3d.edit.worker`), started once and kept warm (its
kernels loaded), so an edit's tube soup takes the time of the pipeline alone.  A request may name a
*channel* (the page uses ``soup``, ``full`` and ``variants``): a newer request on a channel supersedes the
older ones still waiting or running on it.  A waiting one is dropped; a running union's worker is killed (a
union cannot be interrupted, a process can) and a fresh worker started in its place; a running soup (a tenth
of a second) finishes, its answer dropped.  The superseded
request answers :class:`Superseded`, never a stale tree.

Jobs that find every worker busy wait in a queue of bounded length (:class:`Busy` past it); tube soups
(``union = false``) go first, since they are what the user waits for while typing.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import os
import sys
from dataclasses import dataclass, field

from . import frames

__all__ = ["Busy", "Pool", "Superseded", "WorkerFailed"]

log = logging.getLogger("lsys3d")


MAX_FAILED_STARTS = 3
"""Workers that may end in a row before they are ready (an install without numba, no memory) before the pool
stops starting more and fails every request with the reason."""


class Superseded(Exception):
    """A newer request on the same channel replaced this one."""


class Busy(Exception):
    """Too many requests are waiting."""


class WorkerFailed(Exception):
    """The worker died while it grew the tree (killed by the system, out of memory...)."""


@dataclass(eq=False)
class _Ticket:
    job: dict
    channel: str | None
    future: asyncio.Future
    urgent: bool
    worker: _Worker | None = None


@dataclass(eq=False)
class _Worker:
    process: asyncio.subprocess.Process
    ready: bool = False
    ticket: _Ticket | None = None
    keys: list = field(default_factory=list)
    reader: asyncio.Task | None = None
    started: bool = False  # it said ready once
    killed: bool = False  # by the pool (superseded), not by a failure


class Pool:
    """``size`` warm worker processes and a queue of at most ``queue`` waiting jobs.

    Use it from the event loop that runs the server: ``await pool.start()``, ``await pool.run(job, channel)``,
    ``await pool.close()``.  :attr:`status` says whether the workers are still compiling the kernels.
    """

    def __init__(self, size: int = 2, queue: int = 16, python: str = sys.executable):
        if size < 1:
            raise ValueError(f"Pool: size must be at least 1, not {size}")
        self.size = size
        self.queue_limit = queue
        self.python = python
        self.workers: list[_Worker] = []
        self.waiting: list[_Ticket] = []
        self.compiling: tuple[int, int] | None = None
        self.started = 0
        self.failures = 0
        self._ids = itertools.count(1)
        self._closed = False
        self.broken: str | None = None  # why no worker can start (then every request fails at once)
        self._failed_starts = 0

    # -------------------------------------------------------------- workers
    async def start(self) -> None:
        for _ in range(self.size):
            await self._spawn()

    async def _spawn(self) -> _Worker:
        process = await asyncio.create_subprocess_exec(
            self.python,
            "-m",
            "lsys3d.edit.worker",
            stdin=asyncio.subprocess.PIPE,
            stdout=asyncio.subprocess.PIPE,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
            limit=1 << 20,
        )
        worker = _Worker(process)
        self.workers.append(worker)
        self.started += 1
        worker.reader = asyncio.get_running_loop().create_task(self._read(worker))
        return worker

    async def _read(self, worker: _Worker) -> None:
        stream = worker.process.stdout
        try:
            while True:
                header = await stream.readexactly(frames.HEADER.size)
                message = frames.decode(await stream.readexactly(frames.HEADER.unpack(header)[0]))
                kind = message.get("kind")
                if kind == "compiling":
                    self.compiling = (message["done"], message["total"])
                elif kind == "ready":
                    worker.ready = worker.started = True
                    self._failed_starts = 0
                    self.compiling = None
                    self._dispatch()
                elif kind == "result":
                    ticket, worker.ticket = worker.ticket, None
                    if message["ok"]:
                        worker.keys = [*worker.keys[-1:], ticket.job["key"]]
                    if ticket is not None and not ticket.future.done():
                        ticket.future.set_result(message)
                    self._dispatch()
        except (asyncio.IncompleteReadError, ConnectionError):
            pass
        except asyncio.CancelledError:
            raise
        await self._lost(worker)

    async def _lost(self, worker: _Worker) -> None:
        """A worker ended (killed because superseded, or died): fail its job, start another in its place."""
        if worker not in self.workers:
            return
        self.workers.remove(worker)
        with contextlib.suppress(ProcessLookupError):
            worker.process.kill()
        await worker.process.wait()
        ticket, worker.ticket = worker.ticket, None
        if ticket is not None and not ticket.future.done():
            self.failures += 1
            ticket.future.set_exception(WorkerFailed(f"the worker ended (exit status {worker.process.returncode})"))
        if not worker.started and not worker.killed:
            self._failed_starts += 1
        if self._failed_starts >= MAX_FAILED_STARTS:  # it would fail again: say so instead of trying forever
            self.broken = (
                f"{self._failed_starts} workers in a row ended before they were ready (exit status "
                f"{worker.process.returncode}; their errors are on the server's terminal)"
            )
            for waiting in list(self.waiting):
                self._cancel(waiting, WorkerFailed(self.broken))
            return
        if not self._closed:
            await self._spawn()

    def _kill(self, worker: _Worker) -> None:
        worker.ready = False  # never handed another job: it is on its way out
        worker.killed = True
        with contextlib.suppress(ProcessLookupError):
            worker.process.kill()  # its reader sees the pipe close and starts another worker

    # -------------------------------------------------------------- jobs
    async def run(self, job: dict, channel: str | None = None) -> dict:
        """The worker's answer to ``job`` (:func:`lsys3d.edit.worker.run_job`).

        Raises :class:`Superseded` when a newer request on ``channel`` came before it finished,
        :class:`Busy` when the queue is full, :class:`WorkerFailed` when its worker died.
        """
        if self.broken is not None:
            raise WorkerFailed(self.broken)
        if channel is not None:
            self.supersede(channel)
        if len(self.waiting) >= self.queue_limit:
            raise Busy(f"{len(self.waiting)} requests are waiting already; try again when they are done")
        job = {**job, "id": next(self._ids)}
        urgent = job["options"].get("union") is False
        ticket = _Ticket(job, channel, asyncio.get_running_loop().create_future(), urgent)
        self.waiting.append(ticket)
        self._dispatch()
        try:
            return await ticket.future
        except asyncio.CancelledError:  # the client went away: its work is not wanted any more
            self._cancel(ticket, Superseded("the client went away"))
            raise

    def supersede(self, channel: str) -> int:
        """Cancel every request on ``channel`` still waiting or running; the number cancelled."""
        stale = [t for t in self.waiting if t.channel == channel]
        stale += [w.ticket for w in self.workers if w.ticket is not None and w.ticket.channel == channel]
        for ticket in stale:
            self._cancel(ticket, Superseded(f"superseded by a newer request on channel {channel!r}"))
        return len(stale)

    def _cancel(self, ticket: _Ticket, reason: Exception) -> None:
        if not ticket.future.done():
            ticket.future.set_exception(reason)
            ticket.future.exception()  # retrieved: no "exception never retrieved" when nobody awaits it
        if ticket in self.waiting:
            self.waiting.remove(ticket)
        worker = ticket.worker
        # A running union is killed: it may have seconds or minutes to go.  A running soup is left to finish
        # (a tenth of a second, its answer dropped): a new worker would take seconds to start in its place.
        if worker is not None and worker.ticket is ticket and not ticket.urgent:
            worker.ticket = None
            self._kill(worker)

    def _dispatch(self) -> None:
        idle = [w for w in self.workers if w.ready and w.ticket is None and w.process.returncode is None]
        while idle and self.waiting:
            self.waiting.sort(key=lambda t: not t.urgent)  # stable: soups first, each kind in order
            ticket = self.waiting.pop(0)
            # the worker that grew this tree keeps it: exporting it to another format needs no regrowing
            worker = next((w for w in idle if ticket.job["key"] in w.keys), idle[0])
            idle.remove(worker)
            worker.ticket, ticket.worker = ticket, worker
            worker.process.stdin.write(frames.encode(ticket.job))

    @property
    def status(self) -> dict:
        """``{"workers", "ready", "busy", "waiting", "compiling": {"done", "total"} or None, "started", "pids"}``:
        ``started`` counts the workers started so far (one more each time a superseded one is replaced)."""
        return {
            "workers": len(self.workers),
            "ready": sum(w.ready for w in self.workers),
            "busy": sum(w.ticket is not None for w in self.workers),
            "waiting": len(self.waiting),
            "compiling": None if self.compiling is None else dict(zip(("done", "total"), self.compiling, strict=True)),
            "started": self.started,
            "pids": [w.process.pid for w in self.workers],
            "broken": self.broken,
        }

    async def close(self) -> None:
        self._closed = True
        for ticket in list(self.waiting):
            self._cancel(ticket, Superseded("the server is stopping"))
        workers = list(self.workers)
        for worker in workers:
            if worker.ticket is not None:
                self._cancel(worker.ticket, Superseded("the server is stopping"))
            with contextlib.suppress(ProcessLookupError, ConnectionError):
                worker.process.stdin.close()
                worker.process.kill()
        for worker in workers:
            await worker.process.wait()
            if worker.reader is not None:
                worker.reader.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await worker.reader
