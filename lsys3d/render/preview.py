"""Pictures: render a shaded preview of a :class:`~lsys3d.tree.Tree` to a PNG with Blender.

The renderer is Blender, run in a child process: lsys3d writes the tree to a
temporary ``.glb`` with :func:`lsys3d.exchange.export`, and Blender's Python
runs :mod:`lsys3d.render.preview_blender` on it.  That script imports only
``bpy`` and the standard library, so any Blender works: a ``blender``
executable, or a Python that can ``import bpy`` (the ``bpy`` wheel, which needs
Python 3.11).  ``quality="draft"`` (the default) renders with Blender's
Workbench engine (rasterised, studio light, the textures' colours: about a
second for 800x800, through a software OpenGL when there is no GPU);
``quality="final"`` with Cycles on the CPU (path traced, sun and sky,
denoised: tens of seconds).  :class:`PreviewSession` starts Blender before the
tree is ready, so that Blender loads while lsys3d grows the plant (the CLI
does this).

Which Blender, in this order:

1. ``PreviewOptions.blender`` (the CLI's ``--blender PATH``);
2. the environment variable ``LSYS3D_BLENDER``;
3. the running interpreter, when it can import ``bpy``;
4. ``blender`` on ``PATH``.

A path whose file name starts with ``python`` is run as a Python interpreter
(``python preview_blender.py -- JOB``), anything else as Blender
(``blender --background --factory-startup --python preview_blender.py -- JOB``).
"""

from __future__ import annotations

import importlib.util
import json
import logging
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import OptionsError, PreviewError, clip
from ..exchange import ExportOptions, export
from ..exchange.atomic import atomic_path, check_target
from ..options import Options, option
from ..tree import Tree

__all__ = [
    "ENV_BLENDER",
    "INSTALL_HINT",
    "MATERIALS",
    "QUALITIES",
    "VIEWS",
    "PreviewOptions",
    "PreviewSession",
    "base_focus",
    "blender_command",
    "check_preview",
    "junction_focus",
    "preview",
]

log = logging.getLogger("lsys3d")

VIEWS = ("front", "side", "iso", "junction", "base")
"""Camera positions: ``front`` looks along the tree's -Z (glTF's front), ``side`` along -X, ``iso`` from
45 degrees to the side and 30 degrees above; ``junction`` is a close-up of the fork where the thickest
branch leaves its parent, seen across the plane of the fork (:func:`junction_focus`); ``base`` a close-up
of the trunk's foot, its flare and bark (:func:`base_focus`)."""

MATERIALS = ("asset", "checker")
"""``asset``: the tree's own materials; ``checker``: glossy bark with a UV checker on it (8 x 8 squares per
texture tile), to look at the mesh the way a technical director does: creases, stretch and seams show."""

QUALITIES = ("draft", "final")
"""``draft``: Blender's Workbench engine, fast; ``final``: Cycles path tracing with ``samples`` per pixel."""

ENV_BLENDER = "LSYS3D_BLENDER"
INSTALL_HINT = (
    "install Blender and put `blender` on PATH, or make a Blender Python: "
    "`python3.11 -m venv .venv-bpy && .venv-bpy/bin/pip install bpy==5.0.1`, "
    f"then set {ENV_BLENDER}=.venv-bpy/bin/python (or pass --blender PATH)"
)
SCRIPT = Path(__file__).with_name("preview_blender.py")
_PYTHON_NAME = re.compile(r"python[0-9.]*(\.exe)?$", re.IGNORECASE)
_STDERR_LINES = 6


@dataclass(frozen=True)
class PreviewOptions(Options):
    """How :func:`preview` renders a tree; every default, range and help is in its field.

    The camera of ``view`` (see :data:`VIEWS`) is fitted to the tree's
    vertices; ``quality`` picks the engine: ``draft`` Blender's Workbench,
    ``final`` Cycles, which renders ``samples`` per pixel and the denoiser
    cleans up the rest.  ``blender`` None searches (see the module's
    documentation).
    """

    size: tuple[int, int] = option((800, 800), low=1, high=16384, metavar="WxH", help="image size in pixels")
    view: str = option("front", choices=VIEWS, help="where the camera stands")
    material: str = option("asset", choices=MATERIALS, help="the tree's materials, or glossy bark with a UV checker")
    quality: str = option(
        "draft",
        choices=QUALITIES,
        help="draft: Blender's Workbench, a few seconds; final: Cycles path tracing with --samples, sun and sky",
    )
    samples: int = option(16, low=1, high=65536, help="Cycles samples per pixel with --quality final (denoised)")
    denoise: bool = option(True, help="run Blender's OpenImageDenoise on the render", cli=False)
    background: tuple[float, float, float] = option(
        (0.96, 0.96, 0.95), low=0, high=1, help="sRGB colour of the background", cli=False
    )
    margin: float = option(0.06, low=0, high=0.5, high_open=True, help="fraction of the frame left free", cli=False)
    blender: str | None = option(
        None,
        kind=str,
        metavar="PATH",
        help="a blender executable or a Python that imports bpy (default: $LSYS3D_BLENDER, this Python, PATH)",
    )
    threads: int = option(0, low=0, high=4096, help="CPU threads Cycles uses (0: every core)", cli=False)
    timeout: float | None = option(
        600.0, kind=float, optional=True, low=0, low_open=True, help="seconds before Blender is stopped", cli=False
    )
    no_clobber: bool = option(False, help="refuse to overwrite an existing file")
    scene: bool = option(
        False,
        help="also draw the scene the plant grew in ([environment], --environment), its pruning volumes left out",
    )
    pose: tuple[str, ...] = option(
        (),
        kind="strings",
        help="joints of a rigged tree to bend for the picture, as JOINT=DEGREES (about the joint's X axis)",
        cli=False,
    )

    def __post_init__(self):
        super().__post_init__()
        self.bends()  # a malformed pose is refused here, before any work

    def bends(self) -> dict[str, float]:
        """The ``pose`` as ``{joint: degrees}``.

        >>> PreviewOptions(pose=("b3_j0=30", "b5_j1=-12.5")).bends()
        {'b3_j0': 30.0, 'b5_j1': -12.5}
        """
        out = {}
        for item in self.pose:
            name, _, degrees = item.partition("=")
            try:
                value = float(degrees)
            except ValueError:
                value = math.nan
            if not name.strip() or not math.isfinite(value):
                raise OptionsError(f"PreviewOptions.pose: expected JOINT=DEGREES, not {clip(repr(item))}")
            out[name.strip()] = value
        return out


def _is_python(executable: str) -> bool:
    return bool(_PYTHON_NAME.match(Path(executable).name))


def _command(executable: str, job: str) -> list[str]:
    if _is_python(executable):
        return [executable, str(SCRIPT), "--", job]
    return [
        executable,
        "--background",
        "--factory-startup",
        "--python-exit-code",
        "1",
        "--python",
        str(SCRIPT),
        "--",
        job,
    ]


def blender_command(blender: str | None = None) -> str:
    """Find the Blender to render with: ``blender``, ``$LSYS3D_BLENDER``, this Python, ``blender`` on PATH.

    Returns
    -------
    str
        A ``blender`` executable or a Python interpreter that imports ``bpy``.

    Raises
    ------
    PreviewError
        When the named one does not exist, or none is found; the message says how to get one.
    """
    for named, where in ((blender, "--blender"), (os.environ.get(ENV_BLENDER), ENV_BLENDER)):
        if named:
            found = shutil.which(named)
            if found is None:
                raise PreviewError(f"{where} {named}: no such executable; {INSTALL_HINT}")
            return os.path.abspath(found)  # Blender runs in a temporary folder
    if importlib.util.find_spec("bpy") is not None:
        return sys.executable
    found = shutil.which("blender")
    if found is None:
        raise PreviewError(f"no Blender to render with; {INSTALL_HINT}")
    return found


def check_preview(path: str | os.PathLike, options: PreviewOptions | None = None) -> tuple[Path, str]:
    """Check, before any long work, that :func:`preview` could write ``path``; find Blender.

    Returns
    -------
    (pathlib.Path, str)
        The target and the Blender executable or Python that will render.

    Raises
    ------
    PreviewError
        A suffix other than ``.png``, or no Blender.
    ExportError
        A missing or unwritable folder, or an existing file with ``no_clobber``.
    """
    path = Path(path)
    options = PreviewOptions() if options is None else options
    if not isinstance(options, PreviewOptions):
        raise PreviewError(f"{path}: options must be a PreviewOptions, not {type(options).__name__}")
    if path.suffix.lower() != ".png":
        what = f"suffix {path.suffix!r}" if path.suffix else "no suffix"
        raise PreviewError(f"{path}: a preview is a .png image, not {what}")
    check_target(path, options.no_clobber)
    return path, blender_command(options.blender)


def _failure(path: Path, blender: str, proc: subprocess.CompletedProcess) -> PreviewError:
    """The error for a render that wrote no image, with the last lines Blender printed."""
    err = proc.stderr.decode("utf-8", "replace")
    if _is_python(blender) and "No module named 'bpy'" in err:
        return PreviewError(f"{path}: {blender} cannot import bpy; {INSTALL_HINT}")
    lines = [ln.rstrip() for ln in err.splitlines() if ln.strip() and "DeprecationWarning" not in ln]
    if not lines:  # Blender writes some errors to stdout
        lines = [ln.rstrip() for ln in proc.stdout.decode("utf-8", "replace").splitlines() if ln.strip()]
    if proc.returncode < 0:
        what = f"was killed by signal {-proc.returncode}"
    elif proc.returncode > 0:
        what = f"failed with status {proc.returncode}"
    else:
        what = "exited without writing the image"
    tail = "".join(f"\n  {ln}" for ln in lines[-_STDERR_LINES:])
    return PreviewError(f"{path}: Blender ({blender}) {what}{tail}")


def junction_focus(tree: Tree) -> dict:
    """Where the ``junction`` view looks: the fork where the thickest branch leaves its parent.

    Returns
    -------
    dict
        ``target`` (the point looked at: a little past the fork, where the
        collar is), ``direction`` (unit, from the target towards the camera:
        across the plane of the fork, towards the front) and ``size`` (the
        width of the picture), in the tree's frame (metres, Y up, as glTF).

    Raises
    ------
    PreviewError
        A skeleton without a branch leaving another.
    """
    sk = tree.skeleton
    chains = sk.chains
    heads = chains.segments[chains.offsets[:-1]] if len(sk) else np.zeros(0, np.int64)
    heads = heads[sk.parent[heads] >= 0] if len(heads) else heads
    if not len(heads):
        raise PreviewError("the junction view needs a branch that leaves another, and this tree has none")
    child = int(heads[np.argmax(sk.width_start[heads])])  # the thickest; the first drawn of equals
    parent = int(sk.parent[child])
    r_parent = 0.5 * max(float(sk.width_end[parent]), float(sk.width_start[child]), 1e-6)
    a, b = sk.heading[parent], sk.heading[child]
    normal = np.cross(a, b)
    if np.linalg.norm(normal) < 1e-6:  # a straight continuation: any side will do
        normal = np.cross(a, [0.0, 0.0, 1.0] if abs(a[2]) < 0.9 else [1.0, 0.0, 0.0])
    normal = normal / np.linalg.norm(normal)
    if normal @ np.array([0.3, 0.2, 1.0]) < 0:  # look from the front (+Z), a little from the right and above
        normal = -normal
    target = sk.start[child] + 1.5 * r_parent * (a + b) / max(np.linalg.norm(a + b), 1e-9)
    return {"target": target.tolist(), "direction": normal.tolist(), "size": 9.0 * r_parent}


def base_focus(tree: Tree) -> dict:
    """Where the ``base`` view looks: the foot of the trunk, a little above the ground, from the front.

    Returns
    -------
    dict
        ``target``, ``direction`` and ``size`` as :func:`junction_focus`: the picture is four times as wide
        as the trunk at the ground, its centre one trunk diameter up, seen from the front, a little above.

    Raises
    ------
    PreviewError
        A skeleton without a segment.
    """
    sk = tree.skeleton
    if not len(sk):
        raise PreviewError("the base view needs a trunk, and this tree has no segment")
    roots = np.flatnonzero(sk.parent < 0)
    root = int(roots[np.argmax(sk.width_start[roots])])  # the thickest stem
    d = max(float(sk.width_start[root]), 1e-6)
    target = sk.start[root] + np.array([0.0, 0.9 * d, 0.0])
    direction = np.array([0.0, 0.35, 1.0]) / np.linalg.norm([0.0, 0.35, 1.0])
    return {"target": target.tolist(), "direction": direction.tolist(), "size": 4.0 * d}


def preview(
    tree: Tree, path: str | os.PathLike, options: PreviewOptions | None = None, at: float | None = None
) -> Path:
    """Render a shaded picture of ``tree`` to the PNG file ``path``.

    The tree goes to Blender as a temporary ``.glb`` (so bark and leaves keep
    their exported materials), stands upright on the ground, and is framed
    by a camera fitted to it for ``options.view``, over a light background:
    drawn by Blender's Workbench with a studio light (``quality="draft"``, the
    default), or lit by a sun and a sky and path traced by Cycles
    (``quality="final"``).

    Parameters
    ----------
    tree : Tree
        The plant to picture.
    path : str or path-like
        The ``.png`` to write (8-bit RGB).  Written atomically: an error or
        Ctrl-C never leaves a half-written image.
    options : PreviewOptions, optional
        Size, view, samples, background, which Blender...
    at : float, optional
        Seconds into the tree's growth animation (:mod:`lsys3d.look.growth`) to picture, the camera fitted
        to the grown tree (frames of one strip line up).

    Returns
    -------
    pathlib.Path
        ``path``.

    Raises
    ------
    PreviewError
        No Blender found (the message says how to install one), a tree with
        nothing to draw, or a failed render (with Blender's last lines of error output).
    ExportError
        The folder is missing or not writable, or the file exists with ``no_clobber``.

    Examples
    --------
    >>> import lsys3d
    >>> from lsys3d.render.preview import preview, PreviewOptions
    >>> tree = lsys3d.generate("tree3d", iterations=4)  # doctest: +SKIP
    >>> preview(tree, "tree.png", PreviewOptions(size=(400, 400), view="iso"))  # doctest: +SKIP
    PosixPath('tree.png')
    """
    options = PreviewOptions() if options is None else options
    check_preview(path, options)
    _check_tree(Path(path), tree, at)
    with PreviewSession(path, options) as session:
        return session.render(tree, at)


def _check_tree(path: Path, tree, at: float | None = None) -> None:
    if not isinstance(tree, Tree):
        raise PreviewError(f"{path}: expected a lsys3d Tree, got {type(tree).__name__}")
    if at is not None and tree.growth is None:
        raise PreviewError(f"{path}: at={at}: the tree has no growth animation (growth_animation=SECONDS)")
    if len(tree.bark.faces) == 0 and (tree.leaves.merged is None or len(tree.leaves.merged.faces) == 0):
        raise PreviewError(f"{path}: the tree has no bark and no leaves to draw")


class PreviewSession:
    """A Blender started before the tree is ready: it loads (``import bpy``, about 2 s) while lsys3d grows it.

    ``with PreviewSession(path, options) as session: tree = ...; session.render(tree)`` is
    :func:`preview` with the Blender start-up hidden behind the growth; the CLI's ``preview`` does
    this.  The target and Blender are checked (:func:`check_preview`) when the session starts.
    Blender waits for its one job on its standard input; a session closed without a render stops it.
    """

    def __init__(self, path: str | os.PathLike, options: PreviewOptions | None = None):
        self.options = PreviewOptions() if options is None else options
        self.path, self.blender = check_preview(path, self.options)
        self._folder = tempfile.TemporaryDirectory(prefix="lsys3d-preview-")
        command = _command(self.blender, "-")
        log.info("render: %s", " ".join(command))
        try:
            self._proc = subprocess.Popen(
                command,
                stdin=subprocess.PIPE,
                stdout=subprocess.PIPE,
                stderr=subprocess.PIPE,
                cwd=self._folder.name,
            )
        except OSError as exc:
            self._folder.cleanup()
            raise PreviewError(
                f"{self.path}: cannot run {self.blender}: {exc.strerror or exc}; {INSTALL_HINT}"
            ) from None

    def __enter__(self) -> PreviewSession:
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def close(self) -> None:
        """Stop Blender if it still waits (no render was asked for), and remove the temporary folder."""
        proc = self._proc
        if proc.poll() is None:
            proc.kill()
            proc.communicate()
        self._folder.cleanup()

    def render(self, tree: Tree, at: float | None = None) -> Path:
        """Render ``tree`` to the session's PNG (once), ``at`` seconds into its growth; see :func:`preview`."""
        path, options = self.path, self.options
        _check_tree(path, tree, at)
        if self._proc.stdin.closed:
            raise PreviewError(f"{path}: this preview session has rendered already")
        width, height = options.size
        t0 = time.perf_counter()
        folder = self._folder.name
        glb = export(tree, Path(folder) / "tree.glb", ExportOptions(scene=options.scene))
        with atomic_path(path, options.no_clobber) as tmp:
            job = {
                "glb": str(glb),
                "png": str(tmp.resolve()),
                "width": width,
                "height": height,
                "view": options.view,
                "quality": options.quality,
                "samples": options.samples,
                "denoise": options.denoise,
                "background": list(options.background),
                "margin": options.margin,
                "threads": options.threads,
                "material": options.material,
                "bark_material": tree.bark_material.name,
                "pose": options.bends(),
                "time": at,
            }
            if options.view == "junction":
                job["focus"] = junction_focus(tree)
            elif options.view == "base":
                job["focus"] = base_focus(tree)
            proc = self._proc
            try:
                if proc.poll() is not None:  # Blender stopped before it was given the job: its output says why
                    raise BrokenPipeError
                stdout, stderr = proc.communicate((json.dumps(job) + "\n").encode(), timeout=options.timeout)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.communicate()
                raise PreviewError(f"{path}: Blender ({self.blender}) took more than {options.timeout:g} s") from None
            except BrokenPipeError:  # Blender stopped before it read the job: its error output says why
                stdout, stderr = proc.communicate()
            done = subprocess.CompletedProcess(proc.args, proc.returncode, stdout, stderr)
            if done.returncode != 0 or not tmp.exists() or tmp.stat().st_size == 0:
                raise _failure(path, self.blender, done)
        log.info(
            "render: %dx%d %s view, %s, in %.1f s",
            width,
            height,
            options.view,
            options.quality,
            time.perf_counter() - t0,
        )
        return path
