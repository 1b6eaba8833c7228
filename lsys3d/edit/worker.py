"""One generation worker of ``lsys3d edit``: a child process that grows grammars sent to it, one at a time.

The server (:mod:`lsys3d.edit.pool`) starts ``python -m lsys3d.edit.worker`` and talks to it over its standard
input and output in frames (an 8-byte length, then a pickle: the two ends are the same program).  A worker is
killed when the edit it works for is superseded by a newer one; that is why the work runs in a process and
not a thread: a union cannot be interrupted, a process can.

What a job runs is the command line's own sequence: :meth:`Grammar.from_text`, :func:`lsys3d.pipeline.generate`
with :meth:`GenerateOptions.from_flat` options, and :func:`lsys3d.exchange.export` with :class:`ExportOptions`.
"""

from __future__ import annotations

import contextlib
import logging
import os
import sys
import tempfile
import time
from collections import OrderedDict
from pathlib import Path

from .. import compiling
from ..errors import GrammarError, LSystemError
from ..exchange import export
from ..exchange.common import ExportOptions
from ..external import confined_to
from ..lsystem.grammar import Grammar
from ..pipeline import GenerateOptions, generate
from ..turtle.options import GRAMMAR_KEYS, TurtleOptions
from . import frames

__all__ = ["main", "run_job"]

log = logging.getLogger("lsys3d")

WARM_UP = ("tree3d", 3)
"""The preset and iterations a new worker grows (unioned) before it says it is ready: loads or compiles the
kernels, so that the first real edit is as fast as the later ones."""

CACHED_TREES = 2
"""Trees a worker keeps, by request, so that exporting what is on screen to another format does not grow it again."""


class _Findings(logging.Handler):
    """The grammar's warnings (:mod:`lsys3d.turtle.diagnostics`) as the CLI would print them, collected."""

    def __init__(self):
        super().__init__(logging.WARNING)
        self.lines: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        text = record.getMessage()
        self.lines.append(text.removeprefix("warning: "))


def _error(exc: BaseException) -> dict:
    if isinstance(exc, GrammarError):
        return {"line": exc.line, "col": exc.col, "message": exc.reason, "where": str(exc)}
    if isinstance(exc, LSystemError):
        return {"line": None, "col": None, "message": str(exc), "where": str(exc)}
    if isinstance(exc, MemoryError):
        return {"line": None, "col": None, "message": "out of memory; lower the iterations or the limits"}
    raise exc


def run_job(job: dict, trees: OrderedDict | None = None, progress=None) -> dict:
    """Grow ``job``'s grammar and write it in the format ``job["format"]`` names; the answer as a dict.

    ``job`` holds ``text``, ``source`` (the grammar file's path, with the suffix of the text's dialect),
    ``folder`` (the only folder files named by the grammar may be read from), ``iterations``, ``seed``,
    ``options`` (flat names of :class:`GenerateOptions`), ``turtle`` (overrides of the ``[turtle]`` table),
    ``export`` (flat names of :class:`ExportOptions`), ``format`` (a suffix of :func:`lsys3d.exchange.export`)
    and ``key`` (what identifies the tree: the same key, the same tree).

    Returns ``{"ok": True, "data": bytes, "stats": ..., "diagnostics": [...]}`` or ``{"ok": False, "error":
    {"line", "col", "message"}}`` for an error the user can fix (a bad grammar, option or limit).
    """
    findings = _Findings()
    seconds: dict[str, float] = {}

    def timed(stage: str, event: str, value: float) -> None:
        if event == "done":
            seconds[stage] = round(seconds.get(stage, 0.0) + value, 6)
        if progress is not None:
            progress(stage, event, value)

    log.addHandler(findings)
    level = log.level
    if log.getEffectiveLevel() > logging.WARNING:  # the warnings are collected whatever the logging's setup
        log.setLevel(logging.WARNING)
    t0 = time.perf_counter()
    try:
        with confined_to(job["folder"]):
            tree = trees.get(job["key"]) if trees is not None else None
            cached = tree is not None
            if tree is None:
                grammar = Grammar.from_text(job["text"], source=job["source"])
                options = GenerateOptions.from_flat(**job["options"])
                if job["turtle"]:
                    options = options.replace(turtle=dict(job["turtle"]))
                tree = generate(grammar, job["iterations"], job["seed"], options=options, progress=timed)
                about = _about(grammar, options)
                if trees is not None:
                    trees[job["key"]] = (tree, findings.lines[:], dict(seconds), about)
                    while len(trees) > CACHED_TREES:
                        trees.popitem(last=False)
            else:
                trees.move_to_end(job["key"])
                tree, lines, stage_seconds, about = tree
                findings.lines[:0] = lines
                seconds.update(stage_seconds)
            export_options = ExportOptions.from_flat(**job["export"])
            with tempfile.TemporaryDirectory(prefix="lsys3d-edit-") as folder:
                path = Path(folder) / f"asset{job['format']}"
                t1 = time.perf_counter()
                export(tree, path, export_options)
                seconds["export"] = round(time.perf_counter() - t1, 6)
                data = path.read_bytes()
    except (LSystemError, MemoryError) as exc:
        return {"ok": False, "error": _error(exc), "diagnostics": findings.lines}
    finally:
        log.removeHandler(findings)
        log.setLevel(level)
    return {
        "ok": True,
        "data": data,
        "stats": {**_stats(tree, seconds, time.perf_counter() - t0), "cached": cached},
        "diagnostics": findings.lines,
        "grammar": about,
    }


def _about(grammar: Grammar, options: GenerateOptions) -> dict:
    """What the page makes controls of: the grammar's iterations, seed, angle, numeric defines and the turtle's
    settings in force (its ``[turtle]`` table under the request's overrides)."""
    turtle = TurtleOptions.from_grammar(grammar, options.turtle)
    settings = {}
    for key in sorted(GRAMMAR_KEYS):
        value = getattr(turtle, key)
        if isinstance(value, (int, float)) and not isinstance(value, bool):
            settings[key] = value
        elif isinstance(value, tuple) and all(isinstance(v, (int, float)) for v in value):
            settings[key] = list(value)
    return {
        "iterations": grammar.iterations,
        "seed": grammar.seed,
        "angle": grammar.angle,
        "dialect": grammar.dialect,
        "defines": {
            k: v for k, v in grammar.defines.items() if isinstance(v, (int, float)) and not isinstance(v, bool)
        },
        "turtle": settings,
    }


def _stats(tree, seconds: dict, total: float) -> dict:
    """Counts of what was grown and the seconds of each stage (``seconds.total``: the job in the worker; a tree
    the worker kept, ``cached``, took only the export's)."""
    leaves = tree.leaves
    leaf_triangles = len(leaves.merged.faces) if leaves.merged is not None else 0
    organ_triangles = sum(len(m.faces) for m in tree.organs.merged if m is not None)
    return {
        **tree.counts.to_json(),
        "vertices": len(tree.bark.vertices),
        "triangles": len(tree.bark.faces),
        "leaf_triangles": int(leaf_triangles),
        "organ_triangles": int(organ_triangles),
        "leaves": int(tree.skeleton.n_polygons + len(leaves.transforms)),
        "organs": len(tree.organs),
        "unioned": bool(tree.unioned),
        "watertight": bool(tree.bark.is_watertight) if tree.unioned and len(tree.bark.faces) else None,
        "lods": [{"level": lod.level, "triangles": lod.triangles} for lod in tree.lods],
        "seconds": {**seconds, "total": round(total, 6)},
    }


def _serve(read, write) -> None:
    """The worker's loop: warm up, say ``ready``, then answer each job until the input ends."""

    def send(message: dict) -> None:
        write(frames.encode(message))

    def compiling_progress(done: int, total: int, kernel: str) -> None:
        send({"kind": "compiling", "done": done, "total": total})

    trees: OrderedDict = OrderedDict()
    with compiling.watch(compiling_progress):
        name, n = WARM_UP
        with tempfile.TemporaryDirectory(prefix="lsys3d-edit-") as folder:
            export(generate(name, n), Path(folder) / "warm-up.glb")
        send({"kind": "ready", "pid": os.getpid()})
        while True:
            header = read(frames.HEADER.size)
            if len(header) < frames.HEADER.size:
                return
            job = frames.decode(read(frames.HEADER.unpack(header)[0]))
            answer = run_job(job, trees)
            answer["kind"] = "result"
            answer["id"] = job["id"]
            send(answer)


def main() -> None:
    """``python -m lsys3d.edit.worker``: frames on standard input and output; anything printed goes to stderr."""
    out = os.fdopen(os.dup(1), "wb", buffering=0)
    os.dup2(2, 1)  # a stray print (a library's) cannot corrupt the frames
    sys.stdout = sys.stderr
    stdin = sys.stdin.buffer

    def read(n: int) -> bytes:
        chunks, size = [], 0
        while size < n:
            chunk = stdin.read(n - size)
            if not chunk:
                break
            chunks.append(chunk)
            size += len(chunk)
        return b"".join(chunks)

    def write(data: bytes) -> None:
        out.write(data)

    logging.basicConfig(format="lsys3d edit worker: %(message)s", level=logging.ERROR)
    for handler in logging.getLogger().handlers:  # the grammar's warnings go to the page, not the terminal
        handler.setLevel(logging.ERROR)
    with contextlib.suppress(KeyboardInterrupt, BrokenPipeError):  # the server stopped
        _serve(read, write)


if __name__ == "__main__":
    main()
