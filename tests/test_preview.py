"""Previews: Blender renders a picture of the tree, upright, framed, in its materials' colours.

Blender is the ``bpy`` Python of ``.venv-bpy`` (or ``LSYS3D_BPY_PYTHON``), found as
``tests/validators.py`` finds it for the import tests: missing, the render tests skip
locally and fail under ``CI``.  Renders are few and small, the suite runs on 2 cores.
"""

from __future__ import annotations

import importlib.util
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import validators
from pngs import read_png

import lsys3d
from lsys3d.errors import ExportError, OptionsError, PreviewError
from lsys3d.render.preview import (
    ENV_BLENDER,
    SCRIPT,
    PreviewOptions,
    PreviewSession,
    base_focus,
    blender_command,
    check_preview,
    preview,
)

BACKGROUND = (0.96, 0.96, 0.95)


def bpy_python() -> str:
    python = validators.bpy_python()
    validators.require(
        python is not None and python.exists(),
        "Blender (bpy) is not installed: python3.11 -m venv .venv-bpy && .venv-bpy/bin/pip install bpy==5.0.1 "
        "(or set LSYS3D_BPY_PYTHON)",
    )
    return str(python)


@pytest.fixture(scope="module")
def tree():
    return lsys3d.generate("tree3d", iterations=4)


def object_mask(image: np.ndarray) -> np.ndarray:
    """Pixels that differ from the (flat) background colour, faint antialiasing aside."""
    background = np.round(np.array(BACKGROUND) * 255)
    return np.abs(image[..., :3].astype(int) - background).max(axis=2) > 4


def test_front_view_of_tree3d(tree, tmp_path):
    options = PreviewOptions(size=(200, 200), view="front", samples=8, blender=bpy_python(), background=BACKGROUND)
    path = preview(tree, tmp_path / "tree.png", options)
    assert path == tmp_path / "tree.png"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tree.png"], "a temporary file was left behind"
    image = read_png(path)
    assert image.shape == (200, 200, 3)
    assert image[0, 0].tolist() == [245, 245, 242]  # the background colour, exactly
    mask = object_mask(image)
    assert 0.02 < mask.mean() < 0.9, f"the tree covers {mask.mean():.1%} of the picture"

    # framed: the object nearly touches the frame on its long axis, and nothing is cut off at the edges
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    height, width = rows[-1] - rows[0] + 1, cols[-1] - cols[0] + 1
    assert max(height, width) > 0.75 * 200
    assert not (mask[0].any() or mask[-1].any() or mask[:, 0].any() or mask[:, -1].any())
    # upright: taller than wide, and the trunk (a narrow band of object) at the bottom, the crown at the top
    assert height > 1.1 * width, (height, width)
    spread = mask.sum(axis=1)
    assert spread[rows[-1] - 10 : rows[-1] + 1].max() < 0.15 * width, "no trunk at the bottom: not upright"
    assert spread[rows[0] : rows[0] + height // 3].max() > 0.4 * width, "no crown at the top: not upright"

    # the colours of the exported materials: brown bark, green leaves
    pixels = image[mask].astype(int)
    r, g, b = pixels.T
    green = (g > r + 20) & (g > b + 20)
    brown = (r > g + 8) & (g > b + 4)
    assert green.mean() > 0.2, f"{green.mean():.1%} of the tree is green"
    assert brown.sum() > 20, f"{brown.sum()} brown pixels"


def test_cli_preview_iso_view_not_square(tmp_path, monkeypatch, capsys):
    """The command, through the command line's main in this process (its Blender a child as ever; the
    program's own exit statuses: the usage-error and no-Blender tests)."""
    from lsys3d.cli import main

    out = tmp_path / "bush.png"
    args = ["preview", "tree3d", "-n", "3", "--size", "160x120", "--view", "iso", "--samples", "4"]
    monkeypatch.chdir(tmp_path)
    assert main([*args, "--blender", bpy_python(), "-o", str(out)]) == 0, capsys.readouterr().err
    assert capsys.readouterr().out.startswith(f"wrote {out}: 160x120, iso view")
    image = read_png(out)
    assert image.shape == (120, 160, 3)
    mask = object_mask(image)
    assert 0.02 < mask.mean() < 0.9
    rows = np.flatnonzero(mask.any(axis=1))
    assert rows[-1] - rows[0] > 0.75 * 120, "the tree does not fill the frame's height"


def test_a_blender_executable_gets_blenders_arguments(tree, tmp_path):
    """A `blender` (here a stand-in that checks its arguments, then runs bpy) is run in background mode."""
    fake = tmp_path / "blender"
    fake.write_text(
        "#!/bin/sh\n"
        '[ "$1 $2 $3 $4 $5" = "--background --factory-startup --python-exit-code 1 --python" ] '
        '|| { echo "unexpected arguments: $*" >&2; exit 9; }\n'
        f'[ "$6" = "{SCRIPT}" ] && [ "$7" = "--" ] || exit 8\n'
        f'exec "{bpy_python()}" "$6" -- "$8"\n'
    )
    fake.chmod(0o755)
    options = PreviewOptions(size=(48, 48), samples=1, denoise=False, blender=str(fake))
    image = read_png(preview(tree, tmp_path / "tiny.png", options))
    assert image.shape == (48, 48, 3)
    assert object_mask(image).any()


# ---------------------------------------------------------------- no Blender, failed Blender


def fake_python(folder: Path, body: str) -> Path:
    """A stand-in Blender Python (its name starts with ``python``) that runs the shell ``body``."""
    path = folder / "python3.11"
    path.write_text(f"#!/bin/sh\n{body}\n")
    path.chmod(0o755)
    return path


def test_a_failed_render_reports_blenders_last_lines_and_writes_nothing(tree, tmp_path):
    target = tmp_path / "tree.png"
    target.write_bytes(b"the previous picture")
    lines = 'for i in 1 2 3 4 5 6 7 8; do echo "line $i" >&2; done; echo "boom: no GPU" >&2'
    python = fake_python(tmp_path, f"{lines}; exit 3")
    with pytest.raises(PreviewError) as info:
        preview(tree, target, PreviewOptions(blender=str(python)))
    message = str(info.value)
    assert message.startswith(f"{target}: Blender ({python}) failed with status 3")
    assert message.endswith("boom: no GPU") and "line 4" in message and "line 3" not in message
    assert target.read_bytes() == b"the previous picture"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["python3.11", "tree.png"]


def test_a_render_that_writes_no_image_is_an_error(tree, tmp_path):
    python = fake_python(tmp_path, "echo 'Saved nothing'")
    with pytest.raises(PreviewError, match="exited without writing the image\n  Saved nothing"):
        preview(tree, tmp_path / "tree.png", PreviewOptions(blender=str(python)))
    assert not (tmp_path / "tree.png").exists()


def test_a_python_without_bpy_says_how_to_get_it(tree, tmp_path):
    with pytest.raises(PreviewError, match=r"cannot import bpy; .*pip install bpy==5\.0\.1"):
        preview(tree, tmp_path / "tree.png", PreviewOptions(blender=sys.executable))


def test_blender_search_order(tmp_path, monkeypatch):
    python = fake_python(tmp_path, "exit 0")
    monkeypatch.setenv(ENV_BLENDER, str(python))
    assert blender_command() == str(python)
    assert blender_command(sys.executable) == sys.executable  # the explicit one wins
    monkeypatch.setenv(ENV_BLENDER, str(tmp_path / "missing"))
    with pytest.raises(PreviewError, match=f"^{ENV_BLENDER} .*missing: no such executable; "):
        blender_command()


@pytest.mark.skipif(importlib.util.find_spec("bpy") is not None, reason="this Python can render")
def test_cli_without_blender_is_one_line_and_exit_1(tmp_path):
    env = {k: v for k, v in os.environ.items() if k != ENV_BLENDER}
    env["PATH"] = str(tmp_path)  # no blender on it
    proc = subprocess.run(
        [sys.executable, "-m", "lsys3d", "preview", "-o", str(tmp_path / "t.png")],
        capture_output=True,
        text=True,
        env=env,
        cwd=tmp_path,
    )
    assert proc.returncode == 1
    assert proc.stdout == ""
    lines = proc.stderr.splitlines()
    assert len(lines) == 1, proc.stderr
    assert lines[0].startswith("lsys3d: error: no Blender to render with; ")
    assert "pip install bpy==5.0.1" in lines[0] and ENV_BLENDER in lines[0]
    assert list(tmp_path.iterdir()) == []


def test_bad_targets_and_options_are_refused_before_rendering(tmp_path):
    python = fake_python(tmp_path, "exit 0")
    options = PreviewOptions(blender=str(python))
    with pytest.raises(PreviewError, match=r"tree\.jpg: a preview is a \.png image, not suffix '\.jpg'"):
        check_preview(tmp_path / "tree.jpg", options)
    with pytest.raises(ExportError, match="does not exist"):
        check_preview(tmp_path / "no" / "tree.png", options)
    (tmp_path / "old.png").write_bytes(b"x")
    with pytest.raises(ExportError, match="file exists"):
        check_preview(tmp_path / "old.png", PreviewOptions(blender=str(python), no_clobber=True))
    for bad in ({"view": "top"}, {"size": (0, 10)}, {"samples": 0}, {"background": (2, 0, 0)}, {"margin": 0.5}):
        field = next(iter(bad))
        with pytest.raises(OptionsError, match=rf"^PreviewOptions\.{field}: must be "):
            PreviewOptions(**bad)


@pytest.mark.parametrize(
    ("size", "message"),
    [
        ("0x10", "must be in [1, 16,384], not 0"),
        ("10x", "expected WxH, not '10x'"),
        ("big", "expected WxH, not 'big'"),
        ("20000x10", "must be in [1, 16,384], not 20,000"),
        ("10x10x10", "must be a list of 2 whole numbers"),
    ],
)
def test_cli_size_usage_errors_exit_2(size, message, capsys):
    """The command line's parser, in this process (the program's own exit 2 for a usage error: the next test)."""
    from lsys3d.cli import main

    with pytest.raises(SystemExit) as stop:
        main(["preview", "--size", size])
    assert stop.value.code == 2
    assert f"argument --size: {message}" in capsys.readouterr().err


def test_a_pose_bends_a_rigged_tree_in_blender(tmp_path):
    """PreviewOptions.pose turns pose bones before the render: the picture changes; an unknown joint is an error."""
    rigged = lsys3d.generate("abop-1.24a", iterations=2, rig=True)
    base = {"size": (64, 64), "samples": 1, "denoise": False, "blender": bpy_python(), "background": BACKGROUND}
    rest = read_png(preview(rigged, tmp_path / "rest.png", PreviewOptions(**base)))
    joint = rigged.rig.names[2]
    bent = read_png(preview(rigged, tmp_path / "bent.png", PreviewOptions(**base, pose=(f"{joint}=60",))))
    assert (object_mask(rest) != object_mask(bent)).sum() > 50
    with pytest.raises(PreviewError, match="no joint named nowhere"):
        preview(rigged, tmp_path / "no.png", PreviewOptions(**base, pose=("nowhere=10",)))
    assert not (tmp_path / "no.png").exists()
    with pytest.raises(OptionsError, match=r"PreviewOptions.pose: expected JOINT=DEGREES, not 'b0_j1'"):
        PreviewOptions(pose=("b0_j1",))


def test_base_view_looks_at_the_foot_of_the_thickest_stem():
    tree = lsys3d.generate("tree3d", iterations=3, flare=1.6)
    focus = base_focus(tree)
    d = tree.skeleton.width_start[0]
    assert focus["size"] == pytest.approx(4 * d)
    np.testing.assert_allclose(focus["target"], tree.skeleton.start[0] + [0, 0.9 * d, 0])
    assert np.linalg.norm(focus["direction"]) == pytest.approx(1.0) and focus["direction"][2] > 0.9
    assert PreviewOptions(view="base").view == "base"  # a choice of the option


# ---------------------------------------------------------------- draft and final (issue 37)


def test_draft_is_the_default_and_final_is_the_cycles_look(tree, tmp_path):
    """Both qualities picture the tree upright in its colours; the default is the Workbench draft, and
    ``quality="final"`` still renders the Cycles look (another picture of the same tree)."""
    assert PreviewOptions().quality == "draft"
    base = {"size": (96, 96), "blender": bpy_python(), "background": BACKGROUND}
    pictures = {}
    for quality in ("draft", "final"):
        extra = {"samples": 2, "denoise": False} if quality == "final" else {}
        image = read_png(preview(tree, tmp_path / f"{quality}.png", PreviewOptions(**base, quality=quality, **extra)))
        mask = object_mask(image)
        assert 0.02 < mask.mean() < 0.9, (quality, mask.mean())
        r, g, b = image[mask].astype(int).T
        assert ((g > r + 20) & (g > b + 20)).mean() > 0.2, f"{quality}: the leaves are not green"
        lit = image[mask].max(axis=1)
        assert np.median(lit) > 50, f"{quality}: the tree is nearly black"
        pictures[quality] = image
    assert not np.array_equal(pictures["draft"], pictures["final"])
    again = preview(tree, tmp_path / "again.png", PreviewOptions(**base))  # the same picture, the same bytes
    assert again.read_bytes() == (tmp_path / "draft.png").read_bytes()


def test_a_session_starts_blender_before_the_tree_and_stops_it_unused(tree, tmp_path):
    """PreviewSession runs Blender at once (it loads while the tree grows); closed without a render it stops
    Blender and leaves nothing behind; it renders once."""
    options = PreviewOptions(size=(48, 48), blender=bpy_python(), background=BACKGROUND)
    with PreviewSession(tmp_path / "unused.png", options) as session:
        assert session._proc.poll() is None  # started, waiting for its job
    assert session._proc.returncode is not None and not (tmp_path / "unused.png").exists()
    with PreviewSession(tmp_path / "used.png", options) as session:
        assert object_mask(read_png(session.render(tree))).any()
        with pytest.raises(PreviewError, match="rendered already"):
            session.render(tree)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["used.png"]


def test_cli_preview_quality_flag(tmp_path, capsys):
    from lsys3d.cli import main

    with pytest.raises(SystemExit) as stop:
        main(["preview", "--help"])
    assert stop.value.code == 0 and "--quality {draft,final}" in capsys.readouterr().out
    proc = subprocess.run(  # the program's own exit status for a usage error
        [sys.executable, "-m", "lsys3d", "preview", "--quality", "best"], capture_output=True, text=True
    )
    assert proc.returncode == 2 and "invalid choice: 'best'" in proc.stderr


def test_scene_is_drawn_with_the_plant_and_its_volume_left_out(tmp_path):
    # vine-post, young: with --scene the 2.4 m post stands in the picture (grey), without it the vine alone (green)
    vine = lsys3d.generate("vine-post", iterations=12, union=False)
    options = PreviewOptions(size=(120, 240), samples=4, blender=bpy_python(), background=BACKGROUND)

    def shares(image):
        r, g, b = image[object_mask(image)].astype(int).T
        return ((abs(r - g) < 12) & (abs(g - b) < 12)).mean(), ((g > r + 10) & (g > b + 10)).mean()

    grey, green = shares(read_png(preview(vine, tmp_path / "plain.png", options)))
    assert green > 0.5
    grey, green = shares(read_png(preview(vine, tmp_path / "post.png", options.replace(scene=True))))
    assert grey > 0.6 and green < 0.25
    # topiary: its box is a pruning volume, left out, so the picture is the hedge's alone
    hedge = lsys3d.generate("topiary", iterations=8, union=False)
    boxed = read_png(preview(hedge, tmp_path / "boxed.png", options.replace(scene=True)))
    assert np.array_equal(boxed, read_png(preview(hedge, tmp_path / "hedge.png", options)))
