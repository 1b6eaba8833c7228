"""Two processes compiling one kernel at once, from an empty cache, keep both entries of numba's cache."""

from __future__ import annotations

import json
import os
import subprocess
import sys
import textwrap

import pytest

from lsys3d import cachelock

# A kernel in a module of its own, compiled for one signature per process.
_MODULE = """
from numba import njit

@njit(cache=True)
def plus_one(x):
    return x + 1
"""

# One of the two racing processes: it widens numba's window between reading the cache's index and writing it
# back (a sleep in _save_index, after the data-file name is chosen), meets the other at a barrier, then
# compiles plus_one for its own argument, so that both read the index before either writes it unless the
# saves are locked.
_RACER = """
import os, sys, time
folder, mine, other, lock = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4] == "1"
if lock:
    import lsys3d  # installs the lock
import numba.core.caching as caching

save_index = caching.IndexDataCacheFile._save_index

def slow_save_index(self, overloads):
    time.sleep(0.3)
    save_index(self, overloads)

caching.IndexDataCacheFile._save_index = slow_save_index
sys.path.insert(0, folder)
import racing
import numba

numba.njit(lambda x: x)(1)  # numba's compiler set up before the barrier: the two compile plus_one in step
open(os.path.join(folder, "go-" + mine), "w").close()
while not os.path.exists(os.path.join(folder, "go-" + other)):
    time.sleep(0.005)
racing.plus_one(1 if mine == "int" else 1.5)
"""

# A third process: loads both signatures from the cache, and says whether it had to compile either again.
_READER = """
import json, sys
sys.path.insert(0, sys.argv[1])
import racing
out = [racing.plus_one(1), racing.plus_one(1.5)]
stats = racing.plus_one.stats
print(json.dumps([out, sum(stats.cache_hits.values()), sum(stats.cache_misses.values())]))
"""


def _race(tmp_path, lock: bool) -> list:
    folder = tmp_path / "code"
    folder.mkdir()
    (folder / "racing.py").write_text(_MODULE)
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    racers = [
        subprocess.Popen(
            [sys.executable, "-c", _RACER, str(folder), mine, other, "1" if lock else "0"],
            env=env,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        for mine, other in (("int", "float"), ("float", "int"))
    ]
    for racer in racers:
        _, err = racer.communicate(timeout=300)
        assert racer.returncode == 0, err
    read = subprocess.run(
        [sys.executable, "-c", _READER, str(folder)], env=env, capture_output=True, text=True, timeout=300
    )
    assert read.returncode == 0, read.stderr
    return json.loads(read.stdout)


@pytest.mark.slow
def test_two_processes_compiling_one_kernel_at_once_keep_both_cache_entries(tmp_path):
    (int_result, float_result), hits, misses = _race(tmp_path, lock=True)
    assert int_result == 2 and float_result == 2.5
    assert (hits, misses) == (2, 0)  # both signatures loaded from the cache: neither entry was lost


# The writer after an upgrade: plus_one's source changed, so numba's index of the old code is stale and the new
# entry reuses the old data file's name; the writer holds the data back a while after writing the index.
_WRITER = """
import os, sys, time
folder = sys.argv[1]
import lsys3d  # installs the lock
import numba.core.caching as caching

save_data = caching.IndexDataCacheFile._save_data

def slow_save_data(self, name, data):
    open(os.path.join(folder, "index-written"), "w").close()
    time.sleep(0.3)
    save_data(self, name, data)

caching.IndexDataCacheFile._save_data = slow_save_data
sys.path.insert(0, folder)
import racing
print(racing.plus_one(1))
"""

# A reader that loads plus_one while the writer is between its index and its data.
_READER_IN_BETWEEN = """
import os, sys, time
folder = sys.argv[1]
if sys.argv[2] == "1":
    import lsys3d  # installs the lock
import numba

numba.njit(lambda x: x)(1)  # numba loaded and its compiler set up before the wait: the window covers the load alone
sys.path.insert(0, folder)
while not os.path.exists(os.path.join(folder, "index-written")):
    time.sleep(0.005)
import racing
print(racing.plus_one(1))
"""


@pytest.mark.slow
def test_a_process_loading_while_another_saves_never_runs_the_old_code(tmp_path):
    folder = tmp_path / "code"
    folder.mkdir()
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path / "cache"))
    (folder / "racing.py").write_text(_MODULE)
    old = subprocess.run([sys.executable, "-c", _READER, str(folder)], env=env, capture_output=True, text=True)
    assert old.returncode == 0, old.stderr  # the old code cached: plus_one(1) == 2, for int and float
    (folder / "racing.py").write_text(_MODULE.replace("x + 1", "x + 20 "))  # an upgrade: new source, new size
    reader = subprocess.Popen(
        [sys.executable, "-c", _READER_IN_BETWEEN, str(folder), "1"],
        env=env,
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    writer = subprocess.run([sys.executable, "-c", _WRITER, str(folder)], env=env, capture_output=True, text=True)
    out, err = reader.communicate(timeout=300)
    assert writer.returncode == 0 and reader.returncode == 0, writer.stderr + err
    assert writer.stdout.split() == ["21"]
    assert out.split() == ["21"]  # the new code, loaded after the writer's data (or compiled), never the old


def test_the_lock_is_installed_by_importing_lsys3d():
    script = textwrap.dedent(
        """
        import lsys3d, sys
        assert "numba" not in sys.modules  # importing lsys3d does not import numba
        import numba.core.caching as caching
        print(getattr(caching.IndexDataCacheFile.save, "lsys3d_locked", False))
        """
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "True"


def test_the_lock_is_installed_when_numba_was_imported_first():
    script = "import numba.core.caching as c, lsys3d; print(getattr(c.IndexDataCacheFile.save, 'lsys3d_locked', 0))"
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert out.returncode == 0, out.stderr
    assert out.stdout.strip() == "True"


def test_a_folder_that_cannot_hold_the_lock_file_saves_unlocked(tmp_path):
    with cachelock.locked(str(tmp_path / "no such folder")):
        pass  # no error: numba decides whether it can save there
    with cachelock.locked(str(tmp_path)):
        assert (tmp_path / cachelock.LOCK_NAME).exists()
