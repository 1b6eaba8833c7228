"""Batches: grow every job of a jobs file in parallel, record each in a manifest, resume where it stopped.

::

    jobs file --read_jobs--> [Job] --plan (skip what is done)--> runner --run_job--> files + manifest lines
                                                                                   --> library.usda

* :func:`~lsys3d.library.worker.run_job` is what a worker does with one job: grow it, write its files
  (atomically), and return its manifest line -- never the meshes, so nothing
  large crosses a process or the network.
* The runner is :func:`lsys3d.library.runners.run_local` (one process per core on this
  machine, the default) or :func:`lsys3d.library.runners.run_dask` (a Dask cluster).
* The manifest, ``OUTDIR/manifest.jsonl``, gets one JSON line per finished
  job, appended by this process alone (``manifest-I-of-N.jsonl`` for shard
  ``I/N``, so shards running at once never write the same file).  The last
  line of a job id wins.
* A job is skipped when its last line says done, every file it lists is
  there with the recorded sha256, and its recipe (grammar text, iterations,
  seed, options) and formats are what the jobs file asks for now.

A manifest line (keys sorted)::

    {"lsys3d_manifest": 1, "id": "tree3d_s7", "status": "done",
     "recipe": {...what lsys3d check regrows (lsys3d.golden.golden.Recipe)...},
     "export": {"formats": ["glb", "usdc"], "options": {...ExportOptions...}},
     "files": [{"path": "tree3d/tree3d_s7.glb", "sha256": "...", "bytes": 123}, ...],
     "counts": {...lsys3d.stats.report()...}, "crown_radius": 2.31,
     "run": {"seconds": 1.2, "peak_memory": 412000000, "predicted_memory": 120000000,
             "worker": "host:pid", "attempts": 1, "finished": "2026-01-01T12:00:00.000000Z"}}

A failed job's line has ``"status": "failed"`` and ``"error"``, its one-line
message, instead of ``files``, ``counts`` and ``crown_radius``.  Everything but
``run`` is the same whichever machine, runner or worker made it.
"""

from __future__ import annotations

import contextlib
import dataclasses
import json
import logging
import os
import re
import signal
import stat
import threading
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path

from ..errors import BatchError, LSystemError, os_reason
from ..exchange.atomic import check_target
from ..exchange.library import USD_FORMATS, LibraryVariant, write_library
from ..external import FileRefused, inside, load_json, read_lines
from ..golden.golden import recipe_for
from .jobs import Job, JobSize, predict_size, read_jobs, shard
from .runners import available_memory, run_dask, run_local
from .worker import run_job, sha256_of

__all__ = [
    "MANIFEST",
    "MANIFEST_FORMAT",
    "BatchEvent",
    "BatchResult",
    "Plan",
    "available_memory",
    "batch",
    "manifest_name",
    "parse_bytes",
    "plan",
    "read_manifests",
    "run_job",
]

log = logging.getLogger("lsys3d")

MANIFEST = "manifest.jsonl"
MANIFEST_FORMAT = 1
LIBRARY = "library.usda"
MAX_MANIFEST_BYTES = 1 << 32
"""Largest manifest read (4 GiB: 100,000 jobs resumed a hundred times at 4 kB a line); read a line at a time."""
MAX_MANIFEST_LINE = 1 << 20
"""Longest manifest line parsed (lsys3d writes a few kB); a longer one is skipped with a warning."""
_LIMIT_NAME = "lsys3d.library.batch.MAX_MANIFEST_BYTES"


def manifest_name(shard_of: tuple[int, int] | None = None) -> str:
    """``manifest.jsonl``, or ``manifest-I-of-N.jsonl`` for shard ``I/N``."""
    return MANIFEST if shard_of is None else f"manifest-{shard_of[0]}-of-{shard_of[1]}.jsonl"


# ---------------------------------------------------------------- manifests


def _recipe(job: Job, grammar, outdir: Path) -> dict:
    return recipe_for(grammar, job.iterations, job.seed, job.options, golden_path=outdir / MANIFEST).as_json()


def _export_key(job: Job) -> dict:
    options = dataclasses.asdict(job.export_options)
    options.pop("no_clobber", None)
    return {"formats": list(job.formats), "options": dict(sorted(options.items()))}


def read_manifests(outdir: str | os.PathLike, keep: Callable[[dict], dict] | None = None) -> dict[str, dict]:
    """The last line of every job id in the folder's manifests (``manifest.jsonl``, ``manifest-I-of-N.jsonl``).

    Lines are ordered by their ``run.finished`` time, then by file and line;
    a line that does not parse (a write cut short) is skipped with a warning.
    ``keep``, when given, makes each line kept smaller (what a caller needs
    of it), so a large library's manifests are read in little memory.
    """
    outdir = Path(outdir)
    latest: dict[str, tuple[tuple, dict]] = {}
    for path in sorted(outdir.glob("manifest*.jsonl")):
        if not re.fullmatch(r"manifest(-\d+-of-\d+)?\.jsonl", path.name):
            continue
        lines = read_lines(path, MAX_MANIFEST_BYTES, MAX_MANIFEST_LINE, "manifest", _LIMIT_NAME, follow=False)
        try:
            for number, raw in lines:
                if raw is not None and not raw.strip():
                    continue
                try:
                    if raw is None:
                        raise ValueError(f"longer than {MAX_MANIFEST_LINE:,} bytes")
                    line = load_json(raw.decode("utf-8", errors="replace"))
                    if not isinstance(line, dict) or line.get("lsys3d_manifest") != MANIFEST_FORMAT:
                        raise ValueError("not a manifest line")
                except ValueError:
                    log.warning("%s:%d: not a manifest line, skipped", path, number)
                    continue
                job_id = line.get("id")
                if not isinstance(job_id, str):
                    continue
                order = (str((line.get("run") or {}).get("finished") or ""), path.name, number)
                if job_id not in latest or latest[job_id][0] <= order:
                    latest[job_id] = (order, keep(line) if keep else line)
        except FileRefused as exc:
            raise BatchError(exc.reason, str(path)) from None
    return {job_id: line for job_id, (_, line) in latest.items()}


def _for_resume(line: dict) -> dict:
    return {k: line[k] for k in ("export", "files", "recipe", "run", "status") if k in line}


def _for_library(line: dict) -> dict:
    bbox = (line.get("counts") or {}).get("bbox")
    return {"counts": {"bbox": bbox}, "crown_radius": line.get("crown_radius"), **_for_resume(line)}


def _is_done(line: dict | None, recipe: dict | None, export: dict, outdir: Path, job: Job) -> bool:
    """Whether a job's last line says its files are there, whole, and made from the same recipe.

    The line must list exactly the job's own files (``<name>/<name>_s<seed>.<format>``, inside ``outdir``
    with every symlink followed), each a regular file with the recorded size and sha256: a line that names
    any other file, however well its hash matches, never counts the job done.
    """
    if not line or line.get("status") != "done" or recipe is None:
        return False
    if line.get("recipe") != recipe or line.get("export") != export:
        return False
    files = line.get("files")
    if not isinstance(files, list) or not files:
        return False
    try:
        if sorted(entry["path"] for entry in files) != sorted(_job_files(job)):
            return False
        for entry in files:
            path = inside(outdir, entry["path"], "file")
            if path.stat().st_size != entry["bytes"] or sha256_of(path) != entry["sha256"]:
                return False
    except (OSError, LSystemError, KeyError, TypeError):
        return False
    return True


def _job_files(job: Job) -> list[str]:
    """The paths a done job's line lists: its outputs, and the ``.bin`` beside a ``.gltf``."""
    out = list(job.paths)
    out += [p[: -len(".gltf")] + ".bin" for p in job.paths if p.endswith(".gltf")]
    return out


class _ManifestWriter:
    """Appends lines to one manifest, each in one write (a line cut short by a crash is skipped when read)."""

    def __init__(self, path: Path):
        self.path = path
        flags = os.O_RDWR | os.O_APPEND | os.O_CREAT | os.O_NONBLOCK | getattr(os, "O_NOFOLLOW", 0)
        try:  # never through a symlink, never into a pipe or device: the manifest is lsys3d's own file
            self.fd = os.open(path, flags | getattr(os, "O_CLOEXEC", 0), 0o644)
        except OSError as exc:
            if path.is_symlink():
                raise BatchError("the manifest is a symlink; lsys3d writes it only as a file", str(path)) from None
            raise BatchError(f"cannot write the manifest: {os_reason(exc)}", str(path)) from None
        try:
            info = os.fstat(self.fd)
            if not stat.S_ISREG(info.st_mode):
                raise BatchError("the manifest is not a regular file", str(path))
            if info.st_size and os.pread(self.fd, 1, info.st_size - 1) != b"\n":
                os.write(self.fd, b"\n")  # the last run died mid-line: start on a fresh one
        except OSError as exc:
            os.close(self.fd)
            raise BatchError(f"cannot write the manifest: {os_reason(exc)}", str(path)) from None
        except BatchError:
            os.close(self.fd)
            raise

    def append(self, line: dict) -> None:
        data = (json.dumps(line, sort_keys=True, allow_nan=False) + "\n").encode("utf-8")
        os.write(self.fd, data)

    def close(self) -> None:
        os.close(self.fd)


def parse_bytes(text: str) -> int:
    """``"8G"``, ``"512M"``, ``"1.5GB"``, ``"2000000"`` as bytes (powers of 1024).

    >>> parse_bytes("1.5G"), parse_bytes("512m"), parse_bytes("1000")
    (1610612736, 536870912, 1000)
    """
    m = re.fullmatch(r"\s*(\d+(?:\.\d*)?)\s*([kKmMgGtT]?)(?:i?[bB])?\s*", str(text))
    if not m:
        raise ValueError(f"expected a size such as 8G, 512M or a number of bytes, not {text!r}")
    scale = 1024 ** " KMGT".index(m.group(2).upper() or " ")
    return int(float(m.group(1)) * scale)


# ---------------------------------------------------------------- the batch


@dataclass(frozen=True)
class BatchEvent:
    """What :func:`batch` reports to its ``progress`` callback.

    ``kind`` is ``"start"`` (a job was handed to ``worker``; local runner
    only), ``"done"``, ``"failed"`` or ``"skipped"``; the counts are the
    batch's so far, ``total`` the jobs of this run (its shard).
    """

    kind: str
    job_id: str
    worker: str | None
    done: int
    failed: int
    skipped: int
    total: int
    error: str | None = None


@dataclass
class BatchResult:
    """What a batch did: the ids of the jobs done, skipped (already done) and failed, in job-list order."""

    outdir: Path
    manifest: Path
    done: list[str] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    failed: list[str] = field(default_factory=list)
    errors: dict[str, str] = field(default_factory=dict)
    library: Path | None = None
    library_variants: int = 0

    @property
    def ok(self) -> bool:
        return not self.failed


@contextlib.contextmanager
def _sigterm_as_interrupt():
    """SIGTERM (a farm manager stopping the task) unwinds like Ctrl-C: in-flight jobs stop, nothing half-written."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def interrupt(signum, frame):
        raise KeyboardInterrupt

    previous = signal.signal(signal.SIGTERM, interrupt)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def remove_temporaries(jobs: Iterable[Job], outdir: Path) -> int:
    """Remove the temporary files a killed worker left beside the jobs' outputs; how many there were.

    The writers write ``.<stem>.<8 hex digits>.tmp<suffix>`` beside each file
    and rename it over the file when complete (:mod:`lsys3d.exchange.atomic`);
    a process killed before that leaves the temporary file behind.  USD
    writes through a temporary file of its own, made from that name with the
    suffix replaced by six random letters and digits: a worker killed while
    USD writes leaves that one.
    """
    wanted: dict[Path, set[str]] = {}
    for job in jobs:
        for rel in job.paths:
            path = outdir / rel
            wanted.setdefault(path.parent, set()).add(path.name)
            if path.suffix == ".gltf":
                wanted[path.parent].add(path.with_suffix(".bin").name)
    removed = 0
    pattern = re.compile(r"\.(.+)\.[0-9a-f]{8}\.tmp(\.[^.]+)")
    usd_own = re.compile(r"\.[A-Za-z0-9]{6}")
    for folder, names in wanted.items():
        stems = {Path(name).stem for name in names}
        try:
            entries = list(os.scandir(folder))
        except OSError:
            continue
        for entry in entries:
            m = pattern.fullmatch(entry.name)
            if m and (f"{m.group(1)}{m.group(2)}" in names or (usd_own.fullmatch(m.group(2)) and m.group(1) in stems)):
                with contextlib.suppress(OSError):
                    os.unlink(entry.path)
                    removed += 1
    return removed


class Plan:
    """What a batch will do: its jobs (its shard's), their recipes and predicted sizes, and which are done already.

    Made by :func:`plan`; :func:`batch` runs it.  ``to_run`` and ``skipped``
    are in job-list order.
    """

    def __init__(self, all_jobs: list[Job], jobs: list[Job], outdir: Path, shard_of: tuple[int, int] | None):
        self.all_jobs = all_jobs
        self.jobs = jobs
        self.outdir = outdir
        self.shard_of = shard_of
        self._grammars: dict[tuple[str, str], object] = {}
        self._sizes: dict[str, JobSize] = {}
        self.recipes: dict[str, dict | None] = {}
        shared: dict[tuple, dict] = {}  # the recipe of an entry's grammar, but for the seed
        for job in jobs:
            grammar = self.grammar(job)
            if grammar is None:
                self.recipes[job.id] = None
                continue
            key = (job.grammar_source, job.grammar_text, job.iterations, json.dumps(job.options.plain()))
            if key not in shared:
                shared[key] = _recipe(job, grammar, outdir)
            self.recipes[job.id] = {**shared[key], "seed": job.seed}
        previous = read_manifests(outdir, keep=_for_resume) if outdir.is_dir() else {}
        self.to_run: list[Job] = []
        self.skipped: list[str] = []
        for job in jobs:
            if _is_done(previous.get(job.id), self.recipes[job.id], _export_key(job), outdir, job):
                self.skipped.append(job.id)
            else:
                self.to_run.append(job)

    @property
    def manifest(self) -> Path:
        return self.outdir / manifest_name(self.shard_of)

    def grammar(self, job: Job):
        """The job's parsed grammar (None when it does not parse), parsed once per text."""
        key = (job.grammar_source, job.grammar_text)
        if key not in self._grammars:
            self._grammars[key] = job.grammar() if job.grammar_error is None else None
        return self._grammars[key]

    def size_of(self, job: Job) -> JobSize:
        """The job's predicted size (:func:`lsys3d.library.jobs.predict_size`), computed once."""
        if job.id not in self._sizes:
            grammar = self.grammar(job)
            self._sizes[job.id] = (
                predict_size(grammar, job.iterations, job.seed, job.options) if grammar else JobSize(0, 0, 0, 0)
            )
        return self._sizes[job.id]


def plan(
    jobs: str | os.PathLike | Sequence[Job], outdir: str | os.PathLike, shard_of: tuple[int, int] | None = None
) -> Plan:
    """Read the jobs (a jobs file or a job list), take the shard, and find which jobs are done in ``outdir``.

    Nothing is written.  See :func:`batch` for the parameters.
    """
    all_jobs = read_jobs(jobs) if isinstance(jobs, (str, os.PathLike)) else list(jobs)
    mine = shard(all_jobs, *shard_of) if shard_of else all_jobs
    return Plan(all_jobs, mine, Path(outdir), shard_of)


def batch(
    jobs: str | os.PathLike | Sequence[Job] | Plan,
    outdir: str | os.PathLike,
    *,
    scheduler: str | None = None,
    shard_of: tuple[int, int] | None = None,
    workers: int | None = None,
    memory: int | None = None,
    library: bool = True,
    progress: Callable[[BatchEvent], None] | None = None,
) -> BatchResult:
    """Grow every job of a jobs file (or job list) into ``outdir``, with a manifest; resume what is done.

    Parameters
    ----------
    jobs : path-like, sequence of Job, or Plan
        A jobs file (:func:`lsys3d.library.jobs.read_jobs`), its job list, or the
        :func:`plan` of one (then ``shard_of`` is the plan's).
    outdir : path-like
        The output folder (made if missing).  Each job writes
        ``<name>/<name>_s<seed>.<format>``; the batch writes the manifest and
        ``library.usda``.
    scheduler : str, optional
        A Dask scheduler's address (``tcp://host:8786``): run the jobs on that
        cluster (needs ``pip install 'lsys3d[dask]'``; the workers must see
        ``outdir`` at the same path).  Default: processes on this machine.
    shard_of : (int, int), optional
        ``(I, N)``: run only shard I of N (:func:`lsys3d.library.jobs.shard`), for a
        farm that runs one command per task.
    workers : int, optional
        Local worker processes (default: one per core this process may use).
    memory : int, optional
        Bytes the local runner may use in all (default: the memory available
        when the batch starts).  Jobs whose predicted sizes
        (:func:`lsys3d.library.jobs.predict_size`) would together exceed it wait.
    library : bool
        Write ``outdir/library.usda`` from the done jobs' USD files.
    progress : callable, optional
        Called with a :class:`BatchEvent` as jobs start and end.

    Returns
    -------
    BatchResult

    Raises
    ------
    BatchError
        A bad jobs file, an output folder that cannot be written, an
        unreachable scheduler.  A job's own failure is not raised: it is in
        the manifest and in ``BatchResult.failed``.
    KeyboardInterrupt
        Ctrl-C or SIGTERM: the jobs in flight are stopped and their temporary
        files removed; what finished is in the manifest, and the same call
        resumes.
    """
    outdir = Path(outdir)
    the = jobs if isinstance(jobs, Plan) else plan(jobs, outdir, shard_of)
    if the.outdir != outdir:
        raise BatchError(f"the plan was made for {str(the.outdir)!r}", str(outdir))
    _prepare(outdir, the.jobs, the.shard_of)
    result = BatchResult(outdir=outdir, manifest=the.manifest, skipped=list(the.skipped))
    total = len(the.jobs)
    counts = {"done": 0, "failed": 0, "skipped": len(result.skipped)}

    def report(kind: str, job_id: str, worker: str | None = None, error: str | None = None) -> None:
        if progress:
            done, failed, skipped = counts["done"], counts["failed"], counts["skipped"]
            progress(BatchEvent(kind, job_id, worker, done, failed, skipped, total, error))

    for job_id in result.skipped:
        report("skipped", job_id)

    to_run = the.to_run
    remove_temporaries(to_run, outdir)  # left by a run that was killed
    writer = _ManifestWriter(the.manifest)
    runnable = [job for job in to_run if job.grammar_error is None]
    results = _runner(runnable, outdir, scheduler, workers, memory, the.size_of, report)
    interrupted = False
    try:
        with _sigterm_as_interrupt():
            for job in to_run:  # jobs whose grammar does not parse fail at once, without a worker
                if job.grammar_error is not None:
                    _record(job, run_job(job, outdir), None, the.recipes, writer, result, counts, report)
            for job, line in results:
                size = the.size_of(job) if job.id in the._sizes else None
                _record(job, line, size, the.recipes, writer, result, counts, report)
    except KeyboardInterrupt:
        interrupted = True
        raise
    finally:
        results.close()
        writer.close()
        removed = remove_temporaries(to_run, outdir)
        if removed:
            log.info("removed %d temporary files of stopped jobs", removed)
        if interrupted:
            lost = len(to_run) - counts["done"] - counts["failed"]
            log.warning(
                "interrupted: %d jobs done, %d failed, %d not run; the same command resumes",
                counts["done"],
                counts["failed"],
                lost,
            )
    order = {job.id: i for i, job in enumerate(the.jobs)}
    for ids in (result.done, result.failed):
        ids.sort(key=order.__getitem__)
    if library:
        _write_library(outdir, the.all_jobs, result)
    return result


def _prepare(outdir: Path, jobs: Sequence[Job], shard_of: tuple[int, int] | None = None) -> None:
    """Make the output folder and the jobs' folders; fail now if they cannot be written."""
    names = sorted({job.name for job in jobs})
    for name in names:  # a job's folder must not take the place of the batch's own files
        if name == LIBRARY or re.fullmatch(r"manifest(-\d+-of-\d+)?\.jsonl", name):
            raise BatchError(
                f"the job name {name!r} is the name of the batch's own {'library' if name == LIBRARY else 'manifest'}; "
                'give its entry another name (name = "...")',
                str(outdir / name),
            )
    try:
        outdir.mkdir(parents=True, exist_ok=True)
        for name in names:
            (outdir / name).mkdir(exist_ok=True)
    except OSError as exc:
        raise BatchError(f"cannot make the output folder: {exc.strerror or exc}", str(outdir)) from None
    manifest = outdir / manifest_name(shard_of)
    try:
        check_target(manifest, no_clobber=False)
    except LSystemError as exc:
        raise BatchError(str(exc).split(": ", 1)[-1], str(manifest)) from None


def _record(job, line, size, recipes, writer, result, counts, report) -> None:
    """Complete a worker's line with the job's recipe and export, append it, count it."""
    line = dict(line)
    line["lsys3d_manifest"] = MANIFEST_FORMAT
    line["recipe"] = recipes.get(job.id)
    line["export"] = _export_key(job)
    run = dict(line.get("run") or {})
    run.setdefault("attempts", 1)
    if size is not None:
        run["predicted_memory"] = size.bytes
    line["run"] = dict(sorted(run.items()))
    writer.append(line)
    if line.get("status") == "done":
        counts["done"] += 1
        result.done.append(job.id)
        report("done", job.id, run.get("worker"))
    else:
        counts["failed"] += 1
        result.failed.append(job.id)
        result.errors[job.id] = line.get("error") or "failed"
        report("failed", job.id, run.get("worker"), result.errors[job.id])


def _runner(jobs, outdir, scheduler, workers, memory, size_of, report):
    """The results ``(job, line)`` of the local runner or of Dask, as they come."""
    if not jobs:
        return
    if scheduler:
        yield from run_dask(jobs, outdir, address=scheduler, size_of=size_of)
    else:
        yield from run_local(
            jobs,
            outdir,
            workers=workers,
            memory=memory,
            size_of=size_of,
            on_start=lambda job, worker: report("start", job.id, worker),
        )


def _write_library(outdir: Path, jobs: Sequence[Job], result: BatchResult) -> None:
    """``library.usda`` over every job of the list (all shards) that is done and wrote a USD file."""
    usd_jobs = [job for job in jobs if any(f in USD_FORMATS for f in job.formats)]
    if not usd_jobs:
        log.info("no job writes USD: no %s", LIBRARY)
        return
    lines = read_manifests(outdir, keep=_for_library)
    variants = []
    for job in usd_jobs:
        line = lines.get(job.id)
        if not line or line.get("status") != "done":
            continue
        files = {entry["path"]: entry for entry in line.get("files", [])}
        usd = next((p for p in job.paths if p.rsplit(".", 1)[1] in USD_FORMATS), None)
        glb = next((p for p in job.paths if p.endswith(".glb")), None)
        if usd not in files or not (outdir / usd).is_file():
            continue
        bbox = (line.get("counts") or {}).get("bbox", {})
        variants.append(
            LibraryVariant(
                species=job.name,
                seed=job.seed,
                usd=usd,
                glb=glb if glb in files and (outdir / glb).is_file() else None,
                crown_radius=float(line.get("crown_radius", 0.0)),
                bbox_min=tuple(bbox.get("min", (0.0, 0.0, 0.0))),
                bbox_max=tuple(bbox.get("max", (0.0, 0.0, 0.0))),
            )
        )
    if not variants:
        log.info("no USD file done yet: no %s", LIBRARY)
        return
    result.library = write_library(outdir / LIBRARY, variants, usd_jobs[0].export_options)
    result.library_variants = len(variants)
