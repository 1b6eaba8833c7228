"""A script run as ``python SCRIPT ARGS`` runs it, in a process forked from a server that imported the heavy
libraries once (tests/test_benchmarks.py): the function the forked process calls, in a module of its own so
that the server imports neither pytest nor a test module to find it."""

from __future__ import annotations

import atexit
import os
import runpy
import sys


def run_script(script: str, args: list[str], cwd: str, out: str, err: str) -> None:
    """In the forked process: ``script`` as ``__main__`` with ``sys.argv`` ``[script, *args]``, its folder first
    on ``sys.path``, in the folder ``cwd``, its stdout and stderr (and its children's) into the files ``out``
    and ``err``; exits with the script's status after its ``atexit`` functions, as the interpreter does."""
    for fd, path in ((1, out), (2, err)):
        handle = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
        os.dup2(handle, fd)
        os.close(handle)
    sys.stdout = open(1, "w", closefd=False)  # noqa: SIM115 - the process's own, to its end
    sys.stderr = open(2, "w", closefd=False)  # noqa: SIM115
    os.chdir(cwd)
    sys.argv = [script, *args]
    sys.path.insert(0, os.path.dirname(script))
    code: int | str | None = 0
    try:
        runpy.run_path(script, run_name="__main__")
    except SystemExit as exc:
        code = exc.code
    except BaseException:
        import traceback

        traceback.print_exc()
        code = 1
    atexit._run_exitfuncs()
    sys.stdout.flush()
    sys.stderr.flush()
    raise SystemExit(code)  # multiprocessing prints a message, as the interpreter does, and exits with 1
