"""One job in a worker: grow it, write its files (atomically) and return its manifest line.

:func:`run_job` is what a worker of either runner (:mod:`lsys3d.library.runners`) does with a job, and what
:func:`lsys3d.library.batch.batch` does itself when asked for no runner; :func:`lost_line` is the line of a job
whose worker never answered.  Only the line comes back -- never the meshes, so nothing large crosses a process
or the network.
"""

from __future__ import annotations

import contextlib
import datetime
import hashlib
import logging
import os
import socket
import time
from pathlib import Path

import numpy as np

from .. import pipeline
from ..errors import BatchError, LSystemError
from ..exchange import export
from ..external import open_regular
from ..stats import report
from .jobs import Job

__all__ = ["crown_radius", "lost_line", "run_job", "sha256_of"]

log = logging.getLogger("lsys3d")

MAX_ASSET_BYTES = 1 << 40
"""Largest asset file hashed (it is read in pieces: the bound is on time, not memory)."""


class _PeakMemory:
    """Peak resident memory of this process while one job runs.

    On Linux the kernel's high-water mark (``VmHWM``) is reset when the job
    starts (``/proc/self/clear_refs``), so it is the job's own peak (the
    worker's idle memory included).  Elsewhere it is the process's peak so far.
    """

    def __init__(self):
        with contextlib.suppress(OSError), open("/proc/self/clear_refs", "w") as f:
            f.write("5")

    @staticmethod
    def peak() -> int:
        try:
            with open("/proc/self/status") as f:
                for line in f:
                    if line.startswith("VmHWM:"):
                        return int(line.split()[1]) * 1024
        except OSError:
            pass
        try:
            import resource
            import sys

            peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
            return peak if sys.platform == "darwin" else peak * 1024
        except (ImportError, OSError):  # pragma: no cover - Windows
            return 0


def sha256_of(path: Path) -> str:
    """The sha256 of a file's bytes, as hex."""
    digest = hashlib.sha256()
    fd = open_regular(path, MAX_ASSET_BYTES, "asset", "lsys3d.library.worker.MAX_ASSET_BYTES")
    with os.fdopen(fd, "rb") as f:  # a regular file only: a pipe put in its place must not hang a resume
        while chunk := f.read(1 << 20):
            digest.update(chunk)
    return digest.hexdigest()


def _file_entry(outdir: Path, rel: str) -> dict:
    path = outdir / rel
    return {"bytes": path.stat().st_size, "path": rel, "sha256": sha256_of(path)}


def crown_radius(tree) -> float:
    """Largest horizontal distance (metres) of any bark or leaf vertex from the trunk's vertical axis."""
    points = [tree.bark.vertices]
    leaves = tree.leaves.merged if tree.leaves.merged is not None else tree.leaves.polygons
    if leaves is not None:
        points.append(leaves.vertices)
    points = np.concatenate(points)
    if not len(points):
        return 0.0
    return float(f"{float(np.hypot(points[:, 0], points[:, 2]).max()):.9g}")


def _now() -> str:
    return datetime.datetime.now(datetime.UTC).strftime("%Y-%m-%dT%H:%M:%S.%fZ")


def _worker_name() -> str:
    return f"{socket.gethostname()}:{os.getpid()}"


def _one_line(message: str) -> str:
    return " ".join(part.strip() for part in str(message).splitlines() if part.strip())


def run_job(job: Job, outdir: str | os.PathLike) -> dict:
    """Grow one job, write its files into ``outdir`` and return its manifest line.

    This is what a worker runs, in a process of the local runner or on a Dask
    worker.  It never raises for the job's own failure (a grammar that does
    not parse, a limit, an unwritable file): the line says ``"failed"`` with
    the one-line message.  The line holds what the job made (``files``,
    ``counts``, ``crown_radius``) and how it ran (``run``); the batch adds
    the job's ``recipe`` and ``export``.
    """
    meter = _PeakMemory()
    t0 = time.perf_counter()
    line: dict = {"id": job.id}
    written: list[Path] = []
    try:
        if job.grammar_error:
            raise BatchError(job.grammar_error, job.grammar_source)
        outdir = Path(outdir)
        options = job.options
        if not options.union.workers:  # the batch runs a tree per core: each union in its own process
            options = options.with_flat(workers=1)
        tree = pipeline.generate(job.grammar(), job.iterations, job.seed, options=options)
        counts = report(tree.modules, tree.skeleton, tree)
        files = []
        try:
            for rel in job.paths:
                written.append(outdir / rel)
                if rel.endswith(".gltf"):
                    written.append(outdir / (rel[: -len(".gltf")] + ".bin"))
                export(tree, outdir / rel, job.export_options)
                files.append(_file_entry(outdir, rel))
                if rel.endswith(".gltf"):
                    files.append(_file_entry(outdir, rel[: -len(".gltf")] + ".bin"))
        except BaseException:  # a job is all its files or none: a failed format takes the others with it
            for path in written:
                with contextlib.suppress(OSError):
                    path.unlink()
            raise
        line.update(status="done", files=files, counts=counts, crown_radius=crown_radius(tree))
    except BatchError as exc:
        line.update(status="failed", error=_one_line(exc.reason))
    except LSystemError as exc:
        line.update(status="failed", error=_one_line(str(exc)))
    except MemoryError:
        line.update(status="failed", error="out of memory; use fewer iterations, or lower the limits")
    except Exception as exc:  # a bug, not the job's: record it and go on with the others
        stop = _stop_inside(exc)
        if stop is not None:  # the worker's stop signal, raised inside a compiled call that wrapped it
            raise stop from None
        log.exception("job %s", job.id)
        line.update(status="failed", error=_one_line(f"internal error: {type(exc).__name__}: {exc}"))
    line["run"] = {
        "finished": _now(),
        "peak_memory": meter.peak(),
        "seconds": round(time.perf_counter() - t0, 3),
        "worker": _worker_name(),
    }
    return line


def _stop_inside(exc: BaseException) -> SystemExit | None:
    """The SystemExit (a worker's SIGTERM) that caused ``exc``, if one did.

    The signal's handler raises SystemExit wherever the worker is; inside a
    numba call (unpickling a kernel's constants) it comes out wrapped in a
    SystemError.  That is the batch being stopped, not the job failing.
    """
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, SystemExit):
            return exc
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__
    return None


def lost_line(job: Job, why: str) -> dict:
    """The manifest line of a job whose worker never answered (killed, out of memory...)."""
    return {"error": _one_line(why), "id": job.id, "run": {"finished": _now(), "worker": None}, "status": "failed"}
