"""A user's first ``lsys3d generate``, from an empty kernel cache, run and recorded for the tests to look at.

A fresh clone (CI, ``.ci/run``) has no compiled kernels: the test run's first compiling IS a first run.  So
``pytest_sessionstart`` (tests/conftest.py) does that run once, for real, when it finds the kernel cache
empty: ``lsys3d generate`` (the default tree) in a child process whose stderr is a terminal (a pty, so the
command shows its progress line as it does to a user), with numba's events counted.  The kernels it compiles
land in the suite's own cache (as a user's land in theirs), and its record (:data:`RECORD`, a JSON file) is
what ``tests/test_compiling.py``'s first-run test asserts on.  With a warm cache there is no record and that
test does the same run itself, in a temporary cache of its own.
"""

from __future__ import annotations

import json
import os
import pty
import subprocess
import sys
import threading
from pathlib import Path

#: The environment variable naming the session's record of the first run (unset: the cache was warm).
RECORD = "LSYS3D_TESTS_FIRST_RUN"

#: What the child process runs: the command line's own ``main``, with numba's compile events counted.
SCRIPT = """
import json, sys
from numba.core import event
from lsys3d import compiling

compiled, helped = [], []

class Listener(event.Listener):
    def on_start(self, ev):
        func = ev.data["dispatcher"].py_func
        compiled.append(f"{func.__module__}.{func.__qualname__}")
        helped.append(bool(compiling._helpers))

    def on_end(self, ev):
        pass

event.register("numba:compile", Listener())
from lsys3d.cli import main
code = main(["generate", "-o", sys.argv[1]])
from lsys3d import firstrun
from lsys3d.mesh import precompile

# the kernels this process found in the cache, leaving out the cleanup's (the helper compiled those for it) and
# the spare ones (the helper's too, when it was the first to be idle)
loaded = sorted(
    f"{k.py_func.__module__}.{k.py_func.__qualname__}"
    for k in compiling.kernels()
    if sum(k._cache_hits.values())
    and not k.py_func.__module__.startswith(precompile.OWN)
    and not any(spare.covers(k) for spare in firstrun.SPARES)
)
with open(sys.argv[2], "w") as f:
    json.dump({"code": code, "compiled": compiled, "helped": any(helped), "loaded": loaded}, f)
"""


def run(folder: Path, cache: Path | None = None, timeout: float = 900) -> dict:
    """``lsys3d generate -o folder/tree.glb`` in a child process with a terminal for stderr (numba's cache in
    ``cache`` if given, else the package's own); returns its record, also left in ``folder/first-run.json``:
    ``returncode``, ``code`` (what ``main`` returned), ``compiled`` (the module and name of each kernel compiled, in
    order), ``helped`` (whether a helper process was compiling meanwhile), ``loaded`` (this process's kernels
    found in the cache: none on a first run), ``stderr`` (what the terminal got), ``stdout`` and ``output``."""
    folder.mkdir(parents=True, exist_ok=True)
    output, facts = folder / "tree.glb", folder / "facts.json"
    env = dict(os.environ)
    if cache is not None:
        env["NUMBA_CACHE_DIR"] = str(cache)
    terminal, child_side = pty.openpty()
    try:
        proc = subprocess.Popen(
            [sys.executable, "-c", SCRIPT, str(output), str(facts)],
            stdin=subprocess.DEVNULL,
            stdout=subprocess.PIPE,
            stderr=child_side,
            env=env,
        )
    finally:
        os.close(child_side)
    shown: list[bytes] = []

    def read() -> None:  # the terminal's side, drained so the child never waits on a full pty
        while True:
            try:
                chunk = os.read(terminal, 65536)
            except OSError:  # EIO: the child's side is closed
                return
            if not chunk:
                return
            shown.append(chunk)

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    try:
        stdout, _ = proc.communicate(timeout=timeout)
    except BaseException:  # a timeout or ^C: the child does not outlive the run
        proc.kill()
        proc.wait()
        raise
    finally:
        reader.join(timeout=30)
        os.close(terminal)
    record = json.loads(facts.read_text()) if facts.exists() else {}
    record.update(
        returncode=proc.returncode,
        stdout=stdout.decode(errors="replace"),
        stderr=b"".join(shown).decode(errors="replace"),
        output=str(output),
    )
    (folder / "first-run.json").write_text(json.dumps(record), encoding="utf-8")
    return record


def session_record() -> dict | None:
    """The record of the first run the session did from an empty cache, or None (the cache was warm)."""
    path = os.environ.get(RECORD)
    return json.loads(Path(path).read_text(encoding="utf-8")) if path else None


def cache_is_empty() -> bool:
    """Whether the cache holds no code of the turtle's kernel nor of the cleanup's entry kernels: a fresh
    clone's, before anything ran."""
    from lsys3d import compiling
    from lsys3d.mesh import precompile
    from lsys3d.turtle import kernel

    return not any(compiling.is_cached(k) for k in (kernel.run, *precompile.ENTRIES))
