"""Thin wrappers around the real validators the export tests rely on.

* Khronos glTF-Validator: ``node tools/gltf_validate.mjs --serve`` (one process per test process, fed one
  file at a time) with the npm package pinned in ``package.json`` (install with ``npm ci``).
* usd-core's ``UsdValidation`` validators and ``UsdGeom.Mesh.ValidateTopology``
  (in process: usd-core is a dependency of lsys3d).
* usd-core's ARKit profile (``UsdUtils.ComplianceChecker(arkit=True)``, which
  usd-core 26 no longer ships): ``tools/usd_arkit_check.py`` run by the Python
  of ``.venv-usdchecker`` (usd-core 25.5; ``make validators``), or the
  interpreter named by ``LSYS3D_USDCHECK_PYTHON``.
* Blender: ``tools/blender_import.py`` run by the Python of a separate
  environment holding ``bpy`` (``.venv-bpy`` at the repository root, or the
  interpreter named by ``LSYS3D_BPY_PYTHON``), in a child process so that a
  Blender crash is a test failure, not a dead test run.

When a tool is missing, :func:`require` skips the test with the command that
installs it -- unless the environment variable ``CI`` is set, where a missing
tool fails the test: CI must run every check.
"""

from __future__ import annotations

import atexit
import json
import os
import select
import shutil
import subprocess
import tempfile
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
GLTF_SCRIPT = REPO / "tools" / "gltf_validate.mjs"
BLENDER_SCRIPT = REPO / "tools" / "blender_import.py"
BLENDER_MARK = "LSYS3D-BLENDER "
ARKIT_SCRIPT = REPO / "tools" / "usd_arkit_check.py"


def in_ci() -> bool:
    return bool(os.environ.get("CI"))


def require(available: bool, reason: str) -> None:
    """Skip (locally) or fail (under CI) when a validator is not installed."""
    if available:
        return
    if in_ci():
        pytest.fail(f"{reason} -- CI is set, so the validator must be installed")
    pytest.skip(reason)


# ---------------------------------------------------------------- glTF


def gltf_validator_available() -> tuple[bool, str]:
    if shutil.which("node") is None:
        return False, "node is not on PATH (install Node.js >= 18)"
    if not (REPO / "node_modules" / "gltf-validator").is_dir():
        return False, "gltf-validator is not installed (run `npm ci` at the repository root)"
    return True, ""


_gltf_server: subprocess.Popen | None = None


def _gltf_validator() -> subprocess.Popen:
    """This process's ``node tools/gltf_validate.mjs --serve``, started on first use (it ends with this process:
    its stdin closes).  One node per file cost 0.38 CPU s for the default tree, 0.17 of it node's start and the
    validator's first, unoptimised run; the suite validates some hundred files."""
    global _gltf_server
    if _gltf_server is None or _gltf_server.poll() is not None:
        _gltf_server = subprocess.Popen(
            ["node", str(GLTF_SCRIPT), "--serve"],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=tempfile.TemporaryFile(),  # noqa: SIM115 - the server's, to its end
            text=True,
            cwd=REPO,
        )
        atexit.register(_stop, _gltf_server)
    return _gltf_server


def _stop(server: subprocess.Popen) -> None:
    """The server ends at the end of its input (and is waited for: its CPU time counts as this process's child's)."""
    try:
        server.stdin.close()
        server.wait(timeout=30)
    except (OSError, subprocess.TimeoutExpired):
        server.kill()
        server.wait()


def validate_gltf(path: Path) -> dict:
    """The Khronos glTF-Validator's report of ``path`` (skips/fails when the validator is missing)."""
    ok, reason = gltf_validator_available()
    require(ok, reason)
    server = _gltf_validator()
    server.stdin.write(json.dumps(str(path)) + "\n")  # (relative: to the repository, the server's folder)
    server.stdin.flush()
    ready, _, _ = select.select([server.stdout], [], [], 300)
    line = server.stdout.readline() if ready else ""
    if not line:  # ended or stuck: the next call starts another
        server.kill()
        server.wait()
        server.stderr.seek(0)
        pytest.fail(f"glTF-Validator could not validate {path}: {server.stderr.read().decode(errors='replace')}")
    answer = json.loads(line)
    if "error" in answer:
        pytest.fail(f"glTF-Validator could not validate {path}: {answer['error']}")
    return answer["report"]


#: Validator infos that are not defects: an unused object (a leaf model only instanced, the lower levels
#: of detail that MSFT_lod names outside the scene), EXT_mesh_gpu_instancing and MSFT_lod, which the
#: validator knows by name but does not check, and tangents a normal map of the user's will use.
HARMLESS_INFOS = {"UNUSED_OBJECT", "UNSUPPORTED_EXTENSION", "UNUSED_MESH_TANGENT"}


def gltf_issues(report: dict, severity: int) -> list[str]:
    """``code @ pointer: message`` of the report's issues of one severity (0 error, 1 warning, 2 info, 3 hint)."""
    return [
        f"{m['code']} @ {m.get('pointer', '')}: {m['message']}"
        for m in report["issues"]["messages"]
        if m["severity"] == severity
    ]


# ---------------------------------------------------------------- USD


def usd_problems(path: Path) -> list[str]:
    """Errors and warnings of every registered ``UsdValidation`` validator, and failed mesh topology checks."""
    from pxr import Usd, UsdGeom, UsdValidation

    stage = Usd.Stage.Open(str(path))
    assert stage is not None, f"{path}: USD could not open it"
    registry = UsdValidation.ValidationRegistry()
    validators = registry.GetOrLoadAllValidators()
    assert validators, "no UsdValidation validators are registered"
    context = UsdValidation.ValidationContext(validators)
    problems = []
    for error in context.Validate(stage):
        if error.GetType() in (UsdValidation.ValidationErrorType.Error, UsdValidation.ValidationErrorType.Warn):
            problems.append(f"{error.GetType()}: {error.GetIdentifier()}: {error.GetMessage()}")
    predicate = Usd.TraverseInstanceProxies(Usd.PrimDefaultPredicate)
    for prim in Usd.PrimRange.Stage(stage, predicate):
        if prim.IsA(UsdGeom.Mesh):
            mesh = UsdGeom.Mesh(prim)
            ok, why = UsdGeom.Mesh.ValidateTopology(
                mesh.GetFaceVertexIndicesAttr().Get(),
                mesh.GetFaceVertexCountsAttr().Get(),
                len(mesh.GetPointsAttr().Get()),
            )
            if not ok:
                problems.append(f"ValidateTopology: {prim.GetPath()}: {why}")
    return problems


def arkit_problems(path: Path) -> list[str]:
    """What usd-core's ARKit compliance profile finds in ``path`` (errors and failed checks; empty: it passes).

    Run in a child process by the Python of ``.venv-usdchecker`` (usd-core 25.5, the last with
    ``UsdUtils.ComplianceChecker``). The one rule that cannot run from that wheel (shader input types, no
    shader definitions in it) is checked by usd-core 26's ``ShaderSdrCompliance`` in :func:`usd_problems`.
    """
    named = os.environ.get("LSYS3D_USDCHECK_PYTHON")
    python = Path(named) if named else REPO / ".venv-usdchecker" / "bin" / "python"
    require(
        python.exists(),
        "usd-core's ARKit checker is not installed: python3.11 -m venv .venv-usdchecker && "
        ".venv-usdchecker/bin/pip install usd-core==25.5 (make validators; or set LSYS3D_USDCHECK_PYTHON)",
    )
    proc = subprocess.run([str(python), str(ARKIT_SCRIPT), str(path)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    report = json.loads(proc.stdout.strip().splitlines()[-1])
    assert report["skipped"] in ([], ["ShaderPropertyTypeConformanceChecker"]), report
    return [*report["errors"], *report["failed_checks"]]


# ---------------------------------------------------------------- Blender


def bpy_python() -> Path | None:
    """The interpreter of the environment that holds ``bpy``, or None."""
    named = os.environ.get("LSYS3D_BPY_PYTHON")
    if named:
        return Path(named)
    candidate = REPO / ".venv-bpy" / "bin" / "python"
    return candidate if candidate.exists() else None


def bpy_lsys3d_env(python: Path) -> dict:
    """The environment for lsys3d run by ``python`` (Blender's): numba's kernel cache beside the code is
    shared only when both environments hold the same numba, whose cache files are not safe to share across
    versions (one process could read the other's code under the same file name); else a cache of its own."""
    env = dict(os.environ)
    import numba

    site = list(python.parent.parent.glob("lib/python3*/site-packages/numba-*.dist-info"))
    theirs = site[0].name[len("numba-") : -len(".dist-info")] if site else None
    if theirs != numba.__version__:
        env["NUMBA_CACHE_DIR"] = str(python.parent.parent / "numba-cache")
    return env


def blender_import(path: Path, timeout: float = 600) -> dict:
    """Import ``path`` into Blender in a child process; the report of ``tools/blender_import.py``."""
    return blender_imports([path], timeout)[0]


def blender_imports(paths: list[Path], timeout: float = 600) -> list[dict]:
    """Import each of ``paths`` into one Blender in a child process (each into an empty scene, as
    :func:`blender_import` does, for one Blender start); their reports, in order."""
    return blender_reports(BLENDER_SCRIPT, paths, timeout=timeout)


def blender_reports(script: Path, paths: list[Path], args=(), timeout: float = 600) -> list[dict]:
    """Run a Blender tool (``tools/blender_*.py``: one ``LSYS3D-BLENDER`` report line per file, in order) on
    ``paths`` and then ``args`` in one Blender in a child process; the reports, one per file."""
    python = bpy_python()
    require(
        python is not None and python.exists(),
        "Blender (bpy) is not installed: python3.11 -m venv .venv-bpy && .venv-bpy/bin/pip install bpy==5.0.1 "
        "(or set LSYS3D_BPY_PYTHON)",
    )
    names = ", ".join(str(p) for p in paths)
    proc = subprocess.run(
        [str(python), str(script), *map(str, paths), *map(str, args)],
        capture_output=True,
        text=True,
        timeout=timeout,
        cwd=REPO,
    )
    if proc.returncode < 0:
        crashed = f"Blender crashed (signal {-proc.returncode}) in {script.name} with {names}"
        pytest.fail(f"{crashed}:\n{proc.stderr[-2000:]}")
    if proc.returncode != 0:
        pytest.fail(f"Blender ({script.name}) with {names} exited {proc.returncode}:\n{proc.stderr[-2000:]}")
    lines = [ln for ln in proc.stdout.splitlines() if ln.startswith(BLENDER_MARK)]
    if len(lines) != len(paths):
        pytest.fail(
            f"Blender ({script.name}) with {names} printed {len(lines)} reports, not {len(paths)}:\n"
            f"{proc.stdout[-2000:]}\n{proc.stderr[-2000:]}"
        )
    return [json.loads(line[len(BLENDER_MARK) :]) for line in lines]
