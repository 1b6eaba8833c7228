"""Every cheap shell command of README.md and docs/*.md runs, so a doc that drifts fails the suite.

The fenced ``sh`` (``bash``, ``shell``) blocks of each page are read in order; each ``lsys3d ...`` (or
``.venv/bin/lsys3d ...``) command runs through the command line's own ``main`` in a temporary folder
holding the files the docs name (``FILES``: placeholders such as ``my_plant.toml`` and ``jobs.toml``, filled
with small grammars), in this process (a subprocess per command would cost a second or two of start-up
each), with a timeout (``TIMEOUT``), one page's commands after another in one folder, since a page's later
commands use what its earlier ones wrote (``forest library/`` after ``batch jobs.toml -o library/``).

What does not run is stated here, each with its reason:

- ``SKIPPED``: commands that are not cheap or never end, by a rule (a pattern) and a reason: Blender
  previews, Dask clusters and their servers, installs, ``make`` (``make test`` is this suite), servers such
  as a future ``lsys3d edit``.
- ``SUBSTITUTIONS``: where a command's own size would cost seconds to minutes (ten variants, eight
  generations), an exact piece of the documented command and what runs instead, with the reason.  Every
  flag of the command still runs; a substitution the docs no longer hold fails the test, so this table
  cannot outlive the text it edits.

Any other command (a program this test does not know) fails, naming the page and line: a new command in
the docs is run here, or is skipped here with its reason.
"""

from __future__ import annotations

import contextlib
import glob
import os
import re
import shlex
import shutil
import signal
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

from lsys3d.cli import main

REPO = Path(__file__).resolve().parent.parent
DOCS = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
SHELLS = ("sh", "bash", "shell")
TIMEOUT = 120
"""Seconds one command may take before it fails the test (the slowest here takes a few)."""

SKIPPED = (
    (r"^make ", "make: 'make test' is this suite, 'make preview' renders with Blender; 'make demo' is "
     "'.venv/bin/lsys3d generate', which the README's next block runs"),
    (r"\blsys3d preview\b", "a Blender render (tests/test_preview.py renders previews)"),
    (r"docs/make_looks\.py", "renders the looks' pictures with Blender"),
    (r"^dask (scheduler|worker)\b", "starts a Dask scheduler or worker: a server that never ends"),
    (r"--scheduler\b", "needs the Dask cluster at that address (tests/test_batch.py runs a local cluster)"),
    (r"\bpip install\b|-m venv\b", "installs software"),
    (r"^export ", "sets a shell variable, runs nothing"),
    (r"\blsys3d edit\b", "starts a server that runs until stopped"),
)  # fmt: skip
"""(pattern, reason): a command the pattern finds (``re.search``) is not run."""

SUBSTITUTIONS = {
    "oak --seed 7 --variants 10 -o oaks.usdc": (
        "oak --seed 7 --variants 2 -o oaks.usdc",
        "2 variants show what 10 do (the variant set, the seeds) for a fifth of the time",
    ),
    "oak --seed 3 --variants 5 -o oak.glb": (
        "oak --seed 3 --variants 2 -o oak.glb",
        "2 siblings show what 5 do (the file names, the seeds)",
    ),
    "tree3d --seed 7 --variants 10 -o tree.glb": (
        "tree3d -n 4 --seed 7 --variants 2 -o tree.glb",
        "2 siblings show what 10 do; at 4 generations (see TREE3D_FLAGS)",
    ),
    "tree3d --seed 7 --variants 10 -o trees.usdc": (
        "tree3d -n 4 --seed 7 --variants 2 -o trees.usdc",
        "2 variants show what 10 do; at 4 generations (see TREE3D_FLAGS)",
    ),
    "tree3d -n 8 --workers 1 -o big.glb": (
        "tree3d -n 5 --workers 1 -o big.glb",
        "8 generations take minutes; the union on one worker is the same at 5",
    ),
    "barnsleyfern.lpy -o fern.glb --union-cover 0.25": (
        "barnsleyfern.lpy -n 7 -o fern.glb --union-cover 0.25",
        "the fern's 10 generations take minutes (it is the dense benchmark); the flags are the point at 7",
    ),
    "barnsleyfern.lpy -o fern-blobs.glb": (
        "barnsleyfern.lpy -n 7 -o fern-blobs.glb",
        "the fern's 10 generations take 5-10 s with the blobs (the default); at 7 it is a blob as well",
    ),
    "barnsleyfern.lpy -o fern-exact.glb --union-blobs 0": (
        "barnsleyfern.lpy -n 7 -o fern-exact.glb --union-blobs 0",
        "as with --union-cover: the exact union of the fern's 10 generations takes minutes; the flags are the point",
    ),
    "topiary --scene -o hedge.usdc": (
        "topiary -n 8 --scene -o hedge.usdc",
        "the hedge's 21 generations clipped to the box cost 15 CPU s; --scene writes the box beside it at 8 (4 s)",
    ),
    "ivy-wall --scene -o ivy.glb": (
        "ivy-wall -n 20 --scene -o ivy.glb",
        "the ivy's 90 generations cost 10 CPU s (30: 1.9 warm); --scene writes the wall beside it at 20 (0.6 s)",
    ),
    "batch jobs.toml -o library/": (
        "batch jobs.toml -o library/ --workers 1",
        "one worker process grows the jobs file's four small jobs as one per core does (the same files, manifest "
        "and library.usda) for 1.5 CPU s less: a second worker's start; tests/test_batch.py runs two workers",
    ),
    "generate tree -o tree.usda": (
        "generate tree -n 3 -o tree.usda",
        "the flat tree's union takes 5-6 s at its own 5 generations; the flags are the point",
    ),
}

TREE3D_FLAGS = (
    "stats tree3d --mesh",
    "tree3d --turtle width_jitter=0.2 --turtle branch_drop=0.05 --bark-displacement 0.3",
    "tree3d --turtle width_jitter=0.2 --turtle branch_roll=45",
    "tree3d --attributes compact",
    "tree3d --attributes full",
    "tree3d --rig -o rigged.glb",
    "tree3d --rig --rig-joints 64",
    "tree3d --rig --wind-animation 4",
    "tree3d --growth-animation 5 --wind-animation 2",
)
"""Commands of tree3d whose point is their flags (attributes, rig, wind, growth, turtle settings, the mesh's
stats): they run at 4 generations, where tree3d's union costs 0.09 CPU s against 0.73 at its own 6, every
flag the same."""

SUBSTITUTIONS.update(
    {
        text: (text.replace("tree3d ", "tree3d -n 4 ", 1), "at 4 generations: the flags are the point (TREE3D_FLAGS)")
        for text in TREE3D_FLAGS
    }
)
"""Documented text -> (what runs instead, why): the only edits made to the docs' commands."""

KNOWN_FAILURES: dict[str, str] = {}
"""Documented text -> why a command holding it fails today.  Strict: such a command that runs fails the
test, so the entry goes the day the command works."""

FILES = {
    "my_plant.toml": 'axiom = "A"\nangle = 30\niterations = 3\nrules = ["A -> F[+A][-A]FA"]\n',
    # two branches a node: docs/golden.md records, checks and updates it at 6 generations (64 tips, 0.08 CPU s
    # for each of the three; three branches, 729 tips: 0.75)
    "my_oak.toml": 'axiom = "A"\nangle = 25\niterations = 4\nrules = ["A -> F[&A]/[&A]"]\n',
    "jobs.toml": (
        '[defaults]\nformats = ["glb", "usdc"]\n\n'
        '[[jobs]]\ngrammar = "tree3d"\nseeds = "0-1"\noptions = { iterations = 3 }\n\n'
        '[[jobs]]\ngrammar = "bush"\nseeds = "0-1"\noptions = { iterations = 2 }\n'
    ),
}
"""Placeholders the docs name, filled with small grammars (``jobs.toml``: the species the docs' forests ask
for, tree3d and bush, two seeds each, at few generations)."""

COPIED = {
    "sympodial.lpy": "tests/corpus/lpy/sympodial.lpy",
    "barnsleyfern.lpy": "tests/corpus/lpy/real/02-fractals_barnsleyfern.lpy",
    "plant.l": "tests/corpus/cpfg/real/05-compound-homo.l",
    "plant.v": "tests/corpus/cpfg/real/05-compound-homo.v",
    "docs/looks": "docs/looks",
    "tests/golden/koch.json": "tests/golden/koch.json",
    "my_scene.obj": "assets/presets/scenes/wall.obj",
}
"""Files of the repository the docs name, copied to the folder (never run in the repository itself);
``tests/golden/`` holds koch.json alone: checking every preset's golden file is tests/test_golden.py's work."""


@dataclass(frozen=True)
class DocCommand:
    """One shell command of a page: its continuation lines joined, its comment kept off."""

    doc: str
    line: int
    text: str

    def __str__(self) -> str:
        return f"{self.doc}:{self.line}: {self.text}"


def doc_commands(path: Path) -> list[DocCommand]:
    """The commands of a page's fenced shell blocks, in order."""
    out = []
    lines = path.read_text(encoding="utf-8").splitlines()
    fence, pending, start = None, "", 0
    for number, line in enumerate(lines, 1):
        stripped = line.strip()
        if fence is None:
            m = re.match(r"```(\w+)\s*$", stripped)
            if m and m.group(1) in SHELLS:
                fence = stripped
            continue
        if stripped == "```":
            fence = None
            continue
        if not pending:
            start = number
        if stripped.endswith("\\"):
            pending += stripped[:-1].strip() + " "
            continue
        text = _without_comment(pending + stripped)
        pending = ""
        if text:
            out.append(DocCommand(os.path.relpath(path, REPO), start, text))
    return out


def _without_comment(text: str) -> str:
    """A shell line without its comment: from a ``#`` that starts a word outside quotes."""
    quote = None
    for k, c in enumerate(text):
        if quote:
            quote = None if c == quote else quote
        elif c in "'\"":
            quote = c
        elif c == "#" and (k == 0 or text[k - 1].isspace()):
            return text[:k].strip()
    return text.strip()


def skip_reason(command: str) -> str | None:
    for pattern, reason in SKIPPED:
        if re.search(pattern, command):
            return reason
    return None


def _substituted(command: str, used: set[str]) -> str:
    for documented, (instead, _) in SUBSTITUTIONS.items():
        if documented in command:
            used.add(documented)
            command = command.replace(documented, instead)
    return command


def _argv(command: str) -> list[str] | None:
    """The arguments of an ``lsys3d`` command (globs expanded as a shell would), None for another program."""
    words = shlex.split(command)
    while words and re.fullmatch(r"[A-Z_][A-Z0-9_]*=.*", words[0]):  # NAME=value before the program
        words.pop(0)
    if not words or words[0] not in ("lsys3d", ".venv/bin/lsys3d"):
        return None
    args = []
    for word in words[1:]:
        matches = sorted(glob.glob(word)) if any(c in word for c in "*?[") else []
        args.extend(matches or [word])
    return args


def _cpu_seconds() -> float:
    """CPU time of this process and of its finished children (the union's and the batch's workers)."""
    t = os.times()
    return t.user + t.system + t.children_user + t.children_system


class _Timeout(Exception):
    pass


@contextlib.contextmanager
def _time_limit(seconds: int):
    def expire(signum, frame):
        raise _Timeout(f"took more than {seconds} s")

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def _prepare(folder: Path) -> None:
    for name, text in FILES.items():
        (folder / name).write_text(text, encoding="utf-8")
    for name, source in COPIED.items():
        target = folder / name
        target.parent.mkdir(parents=True, exist_ok=True)
        if (REPO / source).is_dir():
            shutil.copytree(REPO / source, target)
        else:
            shutil.copyfile(REPO / source, target)


PAGES = [path for path in DOCS if doc_commands(path)]


# the README's commands are the most (grow, export, batch, forest, check...): slow on their own
@pytest.mark.parametrize(
    "page",
    [pytest.param(p, marks=[pytest.mark.slow] if p.name == "README.md" else []) for p in PAGES],
    ids=[str(p.relative_to(REPO)) for p in PAGES],
)
def test_the_pages_commands_run(page, tmp_path, monkeypatch, capsys):
    _prepare(tmp_path)
    monkeypatch.chdir(tmp_path)
    failures, used, timings = [], set(), []
    for command in doc_commands(page):
        if skip_reason(command.text):
            continue
        argv = _argv(_substituted(command.text, used))
        if argv is None:
            failures.append(f"{command}: not an lsys3d command; run it here or add it to SKIPPED with a reason")
            continue
        t0 = _cpu_seconds()
        try:
            with _time_limit(TIMEOUT):
                code = main(argv)
        except (_Timeout, SystemExit) as exc:
            code = f"{type(exc).__name__} {exc}"
        timings.append((_cpu_seconds() - t0, str(command)))
        out = capsys.readouterr()
        known = next((why for text, why in KNOWN_FAILURES.items() if text in command.text), None)
        if code != 0 and known is None:
            failures.append(f"{command}: exit {code}: {out.err.strip()[-500:]}")
        elif code == 0 and known is not None:
            failures.append(f"{command}: runs now; remove it from KNOWN_FAILURES ({known})")
    print("\n".join(f"{t:6.2f} s CPU  {c}" for t, c in timings))  # shown with -s: where the time goes
    assert not failures, "\n".join(failures)


def test_every_substitution_still_matches_a_documented_command():
    """A substitution whose text the docs no longer hold is stale: the command it made cheap changed."""
    texts = [c.text for path in DOCS for c in doc_commands(path)]
    stale = [documented for documented in SUBSTITUTIONS if not any(documented in text for text in texts)]
    assert not stale, f"substitutions no documented command holds any more: {stale}"


def test_every_skipped_command_is_listed_with_its_reason():
    """The commands not run, each with the rule that skips it (printed with -s; none skipped silently)."""
    skipped = [(c, skip_reason(c.text)) for path in DOCS for c in doc_commands(path) if skip_reason(c.text)]
    for command, reason in skipped:
        print(f"skipped {command}\n  because: {reason}")
    assert all(reason for _, reason in skipped)
    # the rules that skip something now; the others wait for a command (lsys3d edit, a server)
    assert {r for _, r in skipped} >= {reason for pattern, reason in SKIPPED if "edit" not in pattern}


def test_commands_are_read_from_every_kind_of_block(tmp_path):
    page = tmp_path / "page.md"
    page.write_text(
        "```sh\nlsys3d generate koch \\\n    -o k.svg   # a comment\n\n# a comment line\nmake demo\n```\n"
        "```python\nlsys3d = 1\n```\n```bash\nLSYS3D_X=1 lsys3d stats 'my plant.toml'\n```\n"
    )
    commands = doc_commands(page)
    assert [(c.line, c.text) for c in commands] == [
        (2, "lsys3d generate koch -o k.svg"),
        (6, "make demo"),
        (12, "LSYS3D_X=1 lsys3d stats 'my plant.toml'"),
    ]


@pytest.mark.skipif(shutil.which("node") is None, reason="node is not on PATH")
def test_gltf_validate_without_npm_ci_says_so_in_one_line(tmp_path):
    """``node tools/gltf_validate.mjs FILE`` (docs/export.md) before ``npm ci``: one line, not a stack trace."""
    script = tmp_path / "gltf_validate.mjs"  # a folder with no node_modules above it
    shutil.copyfile(REPO / "tools" / "gltf_validate.mjs", script)
    env = {k: v for k, v in os.environ.items() if k != "NODE_PATH"}
    done = subprocess.run(
        ["node", str(script), "tree.glb"], capture_output=True, text=True, cwd=tmp_path, env=env, timeout=60
    )
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.count("\n") == 1 and "at " not in done.stderr, done.stderr
    assert "not installed" in done.stderr and "npm ci" in done.stderr
