"""Where a batch's jobs run: worker processes on this machine, or a Dask cluster.

Both runners take the jobs to run and yield ``(job, manifest line)`` as jobs
finish, in the order they finish.  A worker runs :func:`lsys3d.library.worker.run_job`:
it writes the job's files itself and sends back only the line.

* :func:`run_local` keeps one process per core (``spawn``ed: safe with numba
  and USD, and the same on every platform).  It hands a job to a process only
  when the predicted memory of the jobs in flight stays within the budget; a
  process that dies (killed, out of memory) is replaced and its job retried,
  up to :data:`MAX_ATTEMPTS` times.  Ctrl-C and SIGTERM reach the processes as
  SIGTERM, which unwinds the job (its temporary file is removed); a process
  that does not stop within :data:`STOP_SECONDS` is killed.
* :func:`run_dask` submits every job to a Dask scheduler; the scheduler
  retries a job whose worker died (``distributed.scheduler.allowed-failures``,
  3 by default).  Each start of a job's task adds a byte to a file of its
  own in ``OUTDIR/.lsys3d-starts/`` (the workers share ``OUTDIR``): its size
  is the line's ``attempts``, as the local runner counts them, and a warning
  names each job whose worker was lost running it.  When the workers declare a ``memory`` resource
  (``dask worker --resources memory=16e9``), each job asks for its predicted
  bytes of it, so a worker runs no more jobs at once than fit.
"""

from __future__ import annotations

import contextlib
import gc
import logging
import multiprocessing
import os
import signal
import time
import traceback
import uuid
from collections import deque
from collections.abc import Callable, Iterator, Sequence
from multiprocessing.connection import wait
from pathlib import Path

from ..errors import BatchError
from ..exchange import gltf, usd  # noqa: F401 - loaded with the worker, not in its first job's time
from ..mesh.union.jobs import default_workers as cpu_count  # the cores this process may run on
from .jobs import Job, JobSize
from .worker import lost_line, run_job

__all__ = ["MAX_ATTEMPTS", "STOP_SECONDS", "cpu_count", "run_dask", "run_local"]

log = logging.getLogger("lsys3d")

MAX_ATTEMPTS = 3
"""How many times a job is started before its worker's deaths fail it (as Dask's allowed-failures)."""

STOP_SECONDS = 10.0
"""How long a worker may take to stop after SIGTERM before it is killed."""

CONNECT_TIMEOUT = "30s"
"""How long to try to reach a Dask scheduler."""


# ---------------------------------------------------------------- local processes


WORKER_BYTES = 300 << 20
"""Memory of an idle worker process (Python, numpy, numba, USD loaded): about 260 MB measured."""


def _read_int(path: str) -> int | None:
    try:
        with open(path) as f:
            text = f.read().strip()
    except OSError:
        return None
    return int(text) if text.isdigit() else None


def available_memory() -> int:
    """Bytes of memory available to new work now.

    Linux: ``MemAvailable``, or less when this process's control group (v2 or
    v1, as in a container or a farm's job slot) allows less; elsewhere all
    physical memory.
    """
    found = None
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    found = int(line.split()[1]) * 1024
                    break
    except OSError:
        pass
    if found is None:
        try:
            found = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (ValueError, OSError, AttributeError):  # pragma: no cover - no sysconf
            found = 1 << 34
    for limit, usage in (
        ("/sys/fs/cgroup/memory.max", "/sys/fs/cgroup/memory.current"),
        ("/sys/fs/cgroup/memory/memory.limit_in_bytes", "/sys/fs/cgroup/memory/memory.usage_in_bytes"),
    ):
        most, used = _read_int(limit), _read_int(usage)
        if most is not None and used is not None and most < 1 << 60:
            found = min(found, max(most - used, 0))
    return found


def _stop(signum, frame):
    """A worker's SIGTERM: SystemExit unwinds the job, so its writers remove their temporary files.

    Python prints and swallows an exception raised inside a finalizer (``__del__``: a zipfile closing after a
    ``.usdz``), which would leave a traceback on the batch's stderr and the worker running: there the stop is
    put off by 10 ms (SIGALRM), to land outside the finalizer.
    """
    inside = frame
    while inside is not None:
        if inside.f_code.co_name == "__del__":
            signal.signal(signal.SIGALRM, lambda _signum, later: _stop(signum, later))
            signal.setitimer(signal.ITIMER_REAL, 0.01)
            return
        inside = inside.f_back
    raise SystemExit(128 + signum)


def _worker_main(conn) -> None:
    """A local worker: run the jobs it is sent, one at a time, and send back their lines."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C goes to the batch, which stops the workers
    signal.signal(signal.SIGTERM, _stop)  # SystemExit unwinds the writers, which remove their temporary files
    conn.send(("ready", os.getpid()))
    while True:
        try:
            message = conn.recv()
        except (EOFError, OSError):
            return
        if message is None:
            return
        job, outdir = message
        conn.send(("done", run_job(job, outdir)))


class _Worker:
    def __init__(self, context, index: int):
        self.conn, child = context.Pipe()
        self.process = context.Process(target=_worker_main, args=(child,), name=f"lsys3d-worker-{index}", daemon=True)
        self.process.start()
        child.close()
        self.ready = False
        self.dead = False
        self.job: Job | None = None
        self.bytes = 0
        self.name = f"pid {self.process.pid}"

    def stop(self) -> None:
        """Ask the process to end: idle, by closing its queue; busy, by SIGTERM."""
        if self.dead or not self.process.is_alive():
            return
        if self.job is None:
            with contextlib.suppress(OSError, ValueError):
                self.conn.send(None)
        else:
            self.process.terminate()


def _exit_reason(code: int | None) -> str:
    if code is None:
        return "its worker stopped answering"
    if code < 0:
        try:
            name = signal.Signals(-code).name
        except ValueError:
            name = f"signal {-code}"
        why = " (out of memory?)" if -code == signal.SIGKILL else ""
        return f"its worker was killed by {name}{why}"
    return f"its worker exited with status {code}"


def run_local(
    jobs: Sequence[Job],
    outdir: str | os.PathLike,
    *,
    workers: int | None = None,
    memory: int | None = None,
    size_of: Callable[[Job], JobSize],
    on_start: Callable[[Job, str], None] | None = None,
) -> Iterator[tuple[Job, dict]]:
    """Run ``jobs`` in worker processes on this machine; yield ``(job, line)`` as each finishes.

    Parameters
    ----------
    jobs : sequence of Job
        Started in this order.
    outdir : path-like
    workers : int, optional
        Processes (default :func:`cpu_count`; never more than there are jobs).
    memory : int, optional
        Bytes the batch may use in all (default: :func:`available_memory`
        when it starts).  The workers' own memory comes off it, and a job
        starts only while the jobs in flight are predicted (``size_of``) to
        fit in the rest -- or when no other job is running.
    size_of : callable
        A job's predicted :class:`~lsys3d.library.jobs.JobSize`.
    on_start : callable, optional
        Called as ``on_start(job, worker)`` when a job is handed to a worker
        (``worker`` is ``"host:pid"``).
    """
    import socket

    jobs = list(jobs)
    count = max(1, min(workers or cpu_count(), len(jobs)))
    total = memory if memory is not None else available_memory()
    budget = total - count * WORKER_BYTES
    log.info("local runner: %d workers, %.1f GB for jobs", count, budget / 1e9)
    context = multiprocessing.get_context("spawn")
    pending = deque(jobs)
    attempts: dict[str, int] = {}
    pool: list[_Worker] = []
    host = socket.gethostname()
    outdir = str(Path(outdir).resolve())
    started_dead = 0
    warned_alone = False
    try:
        pool = [_Worker(context, i) for i in range(count)]
        while pending or any(w.job is not None for w in pool):
            in_flight = sum(w.bytes for w in pool if w.job is not None)
            busy = any(w.job is not None for w in pool)
            for w in pool:
                if not pending:
                    break
                if not w.ready or w.job is not None or w.dead:
                    continue
                job = pending[0]
                need = size_of(job).bytes
                if busy and in_flight + need > budget:
                    break  # in order: the next job waits for memory rather than be overtaken
                if not busy and need > budget and not warned_alone:
                    log.warning(
                        "%s is predicted to need %.1f GB, more than the %.1f GB the batch may use: running it alone",
                        job.id,
                        need / 1e9,
                        budget / 1e9,
                    )
                    warned_alone = True
                pending.popleft()
                w.conn.send((job, outdir))
                w.job, w.bytes = job, need
                attempts[job.id] = attempts.get(job.id, 0) + 1
                in_flight += need
                busy = True
                if on_start:
                    on_start(job, f"{host}:{w.process.pid}")
            waiting = {}
            for w in pool:
                if not w.dead:
                    waiting[w.conn] = w
                    waiting[w.process.sentinel] = w
            lost = []
            for ready in wait(list(waiting)):
                w = waiting[ready]
                if w.dead or w in lost:
                    continue
                if ready is w.process.sentinel:
                    lost.append(w)
                    continue
                try:
                    kind, payload = w.conn.recv()
                except (EOFError, OSError):
                    lost.append(w)
                    continue
                if kind == "ready":
                    w.ready = True
                elif kind == "done":
                    job, w.job, w.bytes = w.job, None, 0
                    payload.setdefault("run", {})["attempts"] = attempts.get(job.id, 1)
                    yield job, payload
            for w in lost:
                w.dead = True
                w.process.join(timeout=STOP_SECONDS)
                code = w.process.exitcode
                w.conn.close()
                if w.job is not None:
                    job = w.job
                    why = _exit_reason(code)
                    if attempts[job.id] < MAX_ATTEMPTS:
                        log.warning("%s: %s; starting it again", job.id, why)
                        pending.appendleft(job)
                    else:
                        line = lost_line(job, f"{why}, {attempts[job.id]} times")
                        line["run"]["attempts"] = attempts[job.id]
                        yield job, line
                elif not w.ready:
                    started_dead += 1
                    if started_dead >= MAX_ATTEMPTS:
                        raise BatchError(f"worker processes die while starting ({_exit_reason(code)})", "lsys3d batch")
                pool[pool.index(w)] = _Worker(context, len(pool) + started_dead)
    finally:
        _shut_down(pool)


def _shut_down(pool: list[_Worker]) -> None:
    for w in pool:
        w.stop()
    deadline = time.monotonic() + STOP_SECONDS
    for w in pool:
        w.process.join(timeout=max(0.0, deadline - time.monotonic()))
        if w.process.is_alive():
            w.process.kill()
            w.process.join()
        with contextlib.suppress(OSError):
            w.conn.close()


# ---------------------------------------------------------------- Dask


STARTS = ".lsys3d-starts"
"""The folder of ``OUTDIR`` where a Dask batch's tasks count their starts (one file per task, a byte a start)."""


def _started(job: Job, outdir: str, marker: Path) -> dict:
    """A Dask task: note this start of ``job`` (a byte appended to ``marker``), then run it."""
    with open(marker, "ab") as f:
        f.write(b"s")
    return run_job(job, outdir)


def _starts(marker: Path) -> int:
    """How many times a task was started (at least 1), read from its marker file, which goes."""
    try:
        found = marker.stat().st_size
        marker.unlink()
    except OSError:  # a worker that cannot write there: the job's line is right but for attempts
        return 1
    return max(found, 1)


def _connect(Client, address: str):
    """A Dask client of the scheduler at ``address``, or a BatchError that lets the process exit.

    A Client whose constructor fails is half made: its ``__del__`` closes it by waiting on its event loop, and
    when that runs at the interpreter's exit the loop is gone and the process never ends.  So the failed
    client's frames are cleared and it is collected here, while its loop still runs.
    """
    try:
        return Client(address, timeout=CONNECT_TIMEOUT, set_as_default=False)
    except Exception as exc:  # any failure to connect is the batch's one-line error
        reason = str(exc).strip().splitlines()[0] if str(exc).strip() else type(exc).__name__
        traceback.clear_frames(exc.__traceback__)
        del exc
    gc.collect()
    raise BatchError(f"cannot reach the Dask scheduler: {reason}", address)


def run_dask(
    jobs: Sequence[Job],
    outdir: str | os.PathLike,
    *,
    address: str,
    size_of: Callable[[Job], JobSize],
) -> Iterator[tuple[Job, dict]]:
    """Run ``jobs`` on the Dask cluster at ``address``; yield ``(job, line)`` as each finishes.

    Each job is one task, :func:`lsys3d.library.worker.run_job`, which writes the
    files on the worker (``outdir`` must be the same path there) and returns
    the line.  The workers need lsys3d installed.  A job whose worker died
    is retried by the scheduler; after its allowed failures the job fails
    with the scheduler's message.  The line's ``run.attempts`` is how many
    times the job was started (1, plus one per worker lost while running
    it), and a lost worker is logged as one warning naming the job.  When workers declare a ``memory``
    resource, each job carries its predicted bytes as a resource annotation
    (at most the largest worker's, so that every job can run somewhere).
    """
    try:
        from distributed import Client, KilledWorker, as_completed
    except ImportError:
        raise BatchError(
            "running on a Dask cluster needs Dask: pip install 'lsys3d[dask]'", "lsys3d batch --scheduler"
        ) from None
    try:  # check the address first: a Client that fails in its constructor leaves its event loop's thread running
        from distributed.comm.addressing import parse_address
        from distributed.comm.registry import get_backend

        get_backend(parse_address(address)[0])
    except (ImportError, TypeError, ValueError) as exc:
        raise BatchError(f"cannot reach the Dask scheduler: {exc}", address) from None
    client = _connect(Client, address)
    futures: dict = {}
    try:
        workers = client.scheduler_info().get("workers", {})
        declared = [w.get("resources", {}).get("memory") for w in workers.values()]
        largest = max((m for m in declared if m), default=None)
        if largest is None:
            log.info("the Dask workers declare no 'memory' resource: jobs run without a memory budget")
        token = uuid.uuid4().hex[:8]
        outdir = str(Path(outdir).resolve())
        starts = Path(outdir) / STARTS
        starts.mkdir(exist_ok=True)
        for job in jobs:
            extra = {}
            if largest:
                extra["resources"] = {"memory": min(size_of(job).bytes, largest)}
            key = f"lsys3d-{job.id}-{token}"
            future = client.submit(_started, job, outdir, starts / key, key=key, pure=False, **extra)
            futures[future] = job
        for future in as_completed(list(futures), loop=client.loop):
            job = futures.pop(future)
            lost = _starts(starts / str(future.key)) - 1
            try:
                line = future.result()
            except KilledWorker as exc:
                line = lost_line(job, f"its workers died running it ({exc})")
            except Exception as exc:  # the task could not run: name why, go on with the others
                line = lost_line(job, f"Dask could not run it: {type(exc).__name__}: {exc}")
            if lost:
                log.warning(
                    "%s: its Dask worker died running it%s; the scheduler started it again",
                    job.id,
                    "" if lost == 1 else f" ({lost} times)",
                )
            line.setdefault("run", {})["attempts"] = 1 + lost
            yield job, line
    finally:
        if futures:
            with contextlib.suppress(Exception):
                client.cancel(list(futures), force=True)
        client.close()
        with contextlib.suppress(OSError):
            (Path(outdir) / STARTS).rmdir()  # empty unless a job is still running somewhere
