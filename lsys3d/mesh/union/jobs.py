"""The union's boolean work as independent jobs, run one after another or on every core.

A union (:mod:`lsys3d.mesh.union.union`) is planned as a forest of jobs on plain arrays:

* a *leaf* job unions a few layers, each one mesh of pairwise-disjoint closed
  parts (what may touch goes into different layers), with one
  ``Manifold.batch_boolean``;
* a *merge* job unions the results of two jobs (two halves of one crowded
  cluster, split in space so that both can run at once); the merges of a
  small enough subtree are *inner*: the subtree is one job, its halves
  merged in the same process on manifold3d's own objects (a half exported
  as a mesh and rebuilt costs more than the boolean that merges it);
* the *roots* of the forest are pairwise disjoint: their meshes are simply put
  side by side.

Every job is a function of its input arrays alone (:func:`lsys3d.mesh.union.booleans.run_job`),
so the result does not depend on which process ran it or when: the same bytes
with one worker or many.  manifold3d holds the GIL while it computes, so
threads cannot run two booleans at once; worker processes can.  Each worker is
``python -P lsys3d/mesh/union/booleans.py`` fed through pipes (numpy and manifold3d only:
it starts in a fraction of a second and runs nothing of the caller's
``__main__``), and workers are used only when the work is big enough to pay for
them (:data:`POOL_MIN_TRIANGLES`).  Ctrl-C or an error ends them at once.
"""

from __future__ import annotations

import contextlib
import os
import pickle
import queue
import subprocess
import sys
import tempfile
import threading
from collections.abc import Callable
from typing import NamedTuple

import numpy as np

from ...arrays import components
from ...errors import GeometryError
from . import booleans
from .booleans import BooleanError, Part, run_job

__all__ = ["POOL_MIN_TRIANGLES", "Part", "Plan", "default_workers", "plan", "run"]

POOL_MIN_TRIANGLES = 300_000
"""Boolean input (triangles) from which a union runs its jobs in worker processes (when it may use several)."""


class Plan(NamedTuple):
    """Jobs of one union: ``leaves[i]`` (item indices), ``merges[k]`` (two node ids), ``roots`` (node ids).

    Nodes ``0..len(leaves)-1`` are the leaves; node ``len(leaves) + k`` is merge ``k``.
    """

    leaves: list[np.ndarray]
    merges: list[tuple[int, int]]
    roots: list[int]
    weight: np.ndarray  # (nodes,) triangles each job handles, for progress
    inner: np.ndarray | None = None  # (merges,) bool: merge k runs in the job of its children (None: none does)


def default_workers() -> int:
    """The cores this process may run on (its CPU affinity), at least 1."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except (AttributeError, OSError):  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def plan(
    weight: np.ndarray,
    centre: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    target: float,
    job: float = 0.0,
    leaf: float | None = None,
) -> Plan:
    """Group items into jobs of about ``target`` triangles.

    Items that touch (``a - b``) form clusters.  Small clusters are packed into
    leaf jobs in the order of their first item, each job a root; a cluster
    heavier than ``2 target`` is split in halves at the median of its items'
    ``centre`` along its longest extent, recursively, and the halves are
    merged back pairwise (siblings first), so that the pieces of one crowded
    cluster are unioned side by side and neighbours meet early; its leaves
    hold at most ``leaf`` triangles (``target`` if None).  A merge of at most
    ``job`` triangles is inner (:attr:`Plan.inner`): it runs in the job of its
    halves, and so do theirs.
    """
    leaf = target if leaf is None else leaf
    n = len(weight)
    label = components(n, a, b)
    order = np.argsort(label, kind="stable")
    cut = np.flatnonzero(np.diff(label[order])) + 1
    clusters = np.split(order, cut)  # in the order of their smallest item
    leaves: list[np.ndarray] = []
    merges: list[tuple[int, int]] = []
    roots: list[int] = []
    merge_nodes: list[int] = []  # node id of each merge, resolved below
    pack: list[np.ndarray] = []
    pack_weight = 0.0

    def flush():
        nonlocal pack, pack_weight
        if pack:
            leaves.append(np.concatenate(pack))
            roots.append(("leaf", len(leaves) - 1))
            pack, pack_weight = [], 0.0

    def split(items: np.ndarray):
        """A tree of leaves for one heavy cluster: returns its node (("leaf", i) or ("merge", k))."""
        if weight[items].sum() <= leaf or len(items) < 2:
            leaves.append(items)
            return ("leaf", len(leaves) - 1)
        c = centre[items]
        axis = int(np.argmax(c.max(axis=0) - c.min(axis=0)))
        srt = items[np.argsort(c[:, axis], kind="stable")]
        cumw = np.cumsum(weight[srt])
        half = int(np.clip(np.searchsorted(cumw, cumw[-1] / 2), 1, len(srt) - 1))
        left, right = split(np.sort(srt[:half])), split(np.sort(srt[half:]))
        merges.append((left, right))
        return ("merge", len(merges) - 1)

    for items in clusters:
        w = float(weight[items].sum())
        if w > 2 * target:
            flush()
            roots.append(split(items))
            continue
        pack.append(items)
        pack_weight += w
        if pack_weight >= target:
            flush()
    flush()
    del merge_nodes

    def node_id(node) -> int:
        kind, i = node
        return i if kind == "leaf" else len(leaves) + i

    merges_ids = [(node_id(x), node_id(y)) for x, y in merges]
    nodes = len(leaves) + len(merges)
    w = np.zeros(nodes)
    for i, items in enumerate(leaves):
        w[i] = weight[items].sum()
    for k, (x, y) in enumerate(merges_ids):  # children come before their merge
        w[len(leaves) + k] = w[x] + w[y]
    inner = w[len(leaves) :] <= job
    return Plan(leaves, merges_ids, [node_id(r) for r in roots], w, inner)


# ---------------------------------------------------------------- the scheduler


class _Worker:
    """One worker process and the thread that feeds it jobs and collects its replies."""

    def __init__(self, outbox: queue.Queue):
        self.log = tempfile.TemporaryFile()  # noqa: SIM115 - the worker's stderr, closed with the worker
        self.proc = subprocess.Popen(
            [sys.executable, "-P", booleans.__file__],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=self.log,
        )
        self.inbox: queue.Queue = queue.Queue()
        self.outbox = outbox
        self.killed = False
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        while True:
            item = self.inbox.get()
            if item is None:
                return
            node, groups, tree, where = item
            try:
                plain = [[tuple(p) for p in group] for group in groups]  # the worker knows no lsys3d class
                pickle.dump((plain, where, tree), self.proc.stdin, protocol=pickle.HIGHEST_PROTOCOL)
                self.proc.stdin.flush()
                del groups, item, plain
                reply = pickle.load(self.proc.stdout)
                if reply[0] == "ok":
                    reply = ("ok", (Part(*reply[1][0]), *reply[1][1:]))
            except (OSError, EOFError, pickle.UnpicklingError):
                if self.killed:
                    return
                reply = ("crash", self._last_words())
            self.outbox.put((node, where, reply))
            if reply[0] == "crash":
                return

    def _last_words(self) -> str:
        try:
            code = self.proc.wait(timeout=5)
        except subprocess.TimeoutExpired:
            code = None
        self.log.seek(0)
        lines = [line.strip() for line in self.log.read().decode(errors="replace").splitlines() if line.strip()]
        return f"exit status {code}" + (f", {lines[-1]}" if lines else "")

    def close(self) -> None:
        self.inbox.put(None)
        with contextlib.suppress(OSError):
            self.proc.stdin.close()
        self.thread.join(timeout=10)
        self.proc.wait()
        self.log.close()

    def kill(self) -> None:
        self.killed = True
        self.proc.kill()
        self.inbox.put(None)
        self.proc.wait()
        self.thread.join(timeout=10)
        self.log.close()


def run(
    jobs: Plan,
    leaf_parts: Callable[[int], list[Part]],
    where: Callable[[int], str],
    workers: int = 1,
    progress: Callable[[float], None] | None = None,
) -> tuple[list[Part], dict]:
    """Run a plan; returns the roots' meshes in plan order and what it measured.

    ``leaf_parts(i)`` builds the layers of leaf ``i`` when it is due (so that
    only a few leaves' arrays exist at once); ``where(node)`` names a job for
    error messages.  With ``workers > 1`` and several jobs, the jobs run in
    that many worker processes; ``progress(fraction)`` is called as jobs finish.

    Raises
    ------
    GeometryError
        A job failed (the message names it and manifold3d's status).
    """
    n_leaves = len(jobs.leaves)
    nodes = n_leaves + len(jobs.merges)
    parent = np.full(nodes, -1)
    for k, (x, y) in enumerate(jobs.merges):
        parent[x] = parent[y] = n_leaves + k
    # the job of every node: its own, or that of the inner merge it goes into (merges come after their children)
    top = np.arange(nodes)
    inner = np.zeros(len(jobs.merges), bool) if jobs.inner is None else jobs.inner
    for k in range(len(jobs.merges) - 1, -1, -1):
        if inner[k]:
            x, y = jobs.merges[k]
            top[x] = top[y] = top[n_leaves + k]
    units = np.flatnonzero(top == np.arange(nodes))
    unit_weight = np.bincount(top, jobs.weight, minlength=nodes)
    total = float(jobs.weight.sum()) or 1.0
    results: dict[int, Part] = {}
    waiting: dict[int, int] = {}  # merge node -> children done
    # the jobs that need no other job's result (leaves, inner subtrees), in the order of their first leaf
    first_leaf = np.full(nodes, nodes)
    np.minimum.at(first_leaf, top[:n_leaves], np.arange(n_leaves))
    needs = np.zeros(nodes, bool)  # the jobs that take other jobs' results: the merges that are not inner
    needs[n_leaves:] = ~inner
    free = units[~needs[units]]
    ready = free[np.argsort(first_leaf[free], kind="stable")][::-1].tolist()  # pop() takes them in order
    stats = {"jobs": len(units), "workers": 1, "worker_maxrss_kib": 0, "boolean_cpu": 0.0}
    done_weight = 0.0

    def inputs(node: int) -> tuple[list[list[Part]], list[tuple[int, int]]]:
        """The arguments of :func:`~lsys3d.mesh.union.booleans.run_job` for the job ``node``: parts, merge tree."""
        if node < n_leaves:
            return [leaf_parts(node)], []
        k = node - n_leaves
        if not inner[k]:
            x, y = jobs.merges[k]
            return [[results.pop(x), results.pop(y)]], []
        members = np.flatnonzero(top == node)
        leaves = members[members < n_leaves].tolist()
        local = {v: i for i, v in enumerate(leaves)}
        tree = []
        for m in members[members >= n_leaves].tolist():  # children before their merge, this job's root last
            x, y = jobs.merges[m - n_leaves]
            local[m] = len(leaves) + len(tree)
            tree.append((local[x], local[y]))
        return [leaf_parts(i) for i in leaves], tree

    def finished(node: int, out: Part) -> None:
        nonlocal done_weight
        results[node] = out
        done_weight += unit_weight[node]
        up = parent[node]
        if up >= 0:
            waiting[up] = waiting.get(up, 0) + 1
            if waiting[up] == 2:
                ready.append(int(up))
        if progress:
            progress(min(done_weight / total, 1.0))

    if workers <= 1 or len(units) < 2:
        while ready:
            node = ready.pop()
            try:
                groups, tree = inputs(node)
                out, _, seconds = run_job(groups, where(node), tree)
                del groups
            except BooleanError as exc:
                raise GeometryError(str(exc)) from None
            stats["boolean_cpu"] += seconds
            finished(node, out)
        return [results[r] for r in jobs.roots], stats

    outbox: queue.Queue = queue.Queue()
    pool = [_Worker(outbox) for _ in range(min(workers, len(units)))]
    stats["workers"] = len(pool)
    load = [0] * len(pool)  # jobs in flight per worker
    owner: dict[int, int] = {}
    try:
        while ready or owner:
            # keep every worker busy, with one more job queued behind the one it computes
            while ready and min(load) < 2:
                w = load.index(min(load))
                node = ready.pop()
                owner[node] = w
                load[w] += 1
                pool[w].inbox.put((node, *inputs(node), where(node)))
            node, name, reply = outbox.get()
            load[owner.pop(node)] -= 1
            if reply[0] == "error":
                raise GeometryError(reply[1])
            if reply[0] == "crash":
                raise GeometryError(f"{name}: a union worker process failed ({reply[1]})")
            out, peak, seconds = reply[1]
            stats["worker_maxrss_kib"] = max(stats["worker_maxrss_kib"], peak)
            stats["boolean_cpu"] += seconds
            finished(node, out)
    except BaseException:
        for worker in pool:  # Ctrl-C or an error: end every worker now, whatever it is computing
            worker.kill()
        raise
    for worker in pool:
        worker.close()
    return [results[r] for r in jobs.roots], stats
