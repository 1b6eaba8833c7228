"""The form stage (lsys3d/turtle/form.py): pipe model, flare, curvature, irregularity, phyllotaxis, collars."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

import lsys3d
from lsys3d.errors import GrammarError, OptionsError
from lsys3d.lsystem.grammar import Grammar
from lsys3d.pipeline import GenerateOptions, draw
from lsys3d.provenance import grammar_text
from lsys3d.turtle import FormOptions, botany, form
from lsys3d.turtle.form import GOLDEN_ANGLE, pipe_widths, tip_counts
from lsys3d.turtle.skeleton import Skeleton

ROOT = Path(__file__).resolve().parent.parent
DEMO = ROOT / "docs" / "form" / "tree3d-form.toml"

BENT = FormOptions(gnarl=40, gravitropism=(5, 2), plagiotropism=3, max_substep_length=0.2)


def fork(exponent=2.0, **kw):
    """A trunk that forks into two equal children."""
    sk = Skeleton.from_segments(
        [[0, 0, 0], [0, 1, 0], [0, 1, 0]],
        [[0, 1, 0], [0.5, 2, 0], [-0.5, 2, 0]],
        0.3,
        parent=[-1, 0, 0],
        order=[0, 1, 1],
    )
    return form(sk, FormOptions(pipe_model=True, pipe_exponent=exponent, tip_width=0.02, **kw))


@pytest.fixture(scope="module")
def demo():
    g = Grammar.from_file(DEMO)
    return g, draw(g, 5, 0)[1]


@pytest.fixture(scope="module")
def plain_tree3d():
    return draw(lsys3d.load_preset("tree3d"), 5, 0)[1]


@pytest.mark.parametrize("exponent", [2.0, 2.5, 3.0])
def test_two_equal_children_keep_the_parent_area(exponent):
    sk = fork(exponent)
    parent, a, b = sk.width_end[0], sk.width_start[1], sk.width_start[2]
    assert a == b == pytest.approx(0.02)
    assert a**exponent + b**exponent == pytest.approx(parent**exponent, rel=1e-12)
    assert sk.width_start[0] == sk.width_end[0]  # a segment keeps its diameter to the fork


def test_tip_counts_and_pipe_widths():
    parent = np.array([-1, 0, 1, 1, 0, 4])
    assert tip_counts(parent).tolist() == [3, 2, 1, 1, 1, 1]
    d = pipe_widths(parent, 0.01, 2.0)
    assert d[0] ** 2 == pytest.approx(d[1] ** 2 + d[4] ** 2)


def test_widths_never_grow_along_a_chain(demo):
    _, sk = demo
    assert botany.chain_growth(sk) <= 1.0 + 1e-12
    forks, ratios, widest = botany.fork_ratios(sk)
    assert forks > 50 and widest <= 1.0 + 1e-12
    assert np.mean((ratios >= 0.8) & (ratios <= 1.25)) >= 0.9  # the pipe model, exponent 2


def test_collars_swell_into_the_parent_and_never_past_it(plain_tree3d):
    plain = form(plain_tree3d, FormOptions(pipe_model=True))
    collared = form(plain_tree3d, FormOptions(pipe_model=True, branch_collar=1.15))
    assert len(collared) > len(plain)  # each long enough lateral's first segment is split at the collar's end
    assert botany.chain_growth(collared) <= 1.0 + 1e-12
    assert botany.fork_ratios(collared)[2] <= 1.0 + 1e-12
    # the laterals' bases swell by the factor unless their parent is too thin for it
    lateral = np.flatnonzero((collared.parent >= 0) & (collared.order > collared.order[np.maximum(collared.parent, 0)]))
    base, parent_end = collared.width_start[lateral], collared.width_end[collared.parent[lateral]]
    swollen = np.isclose(base, 1.15 * collared.width_end[lateral]) | np.isclose(base, parent_end)
    assert swollen.all() and (base > collared.width_end[lateral]).any()


def test_flare_widens_the_trunk_base_and_the_bark_stays_closed():
    g = lsys3d.load_preset("tree3d")
    plain = draw(g, 4, 0, GenerateOptions.from_flat(pipe_model=True))[1]
    flared = draw(g, 4, 0, GenerateOptions.from_flat(pipe_model=True, flare=1.6, flare_height=1.0))[1]
    assert flared.width_start[0] / plain.width_start[0] >= 1.6 - 1e-12
    assert botany.trunk_flare(flared) >= 1.3
    trunk = flared.order == 0
    assert trunk.sum() > (plain.order == 0).sum()  # the base segment is split to sample the curve
    assert botany.chain_growth(flared) <= 1.0 + 1e-12  # the flare tapers smoothly, never steps up
    tree = lsys3d.generate(g, iterations=3, pipe_model=True, flare=1.6, flare_height=1.0)
    assert tree.bark.is_watertight


def test_curvature_is_deterministic_per_seed_and_differs_across_seeds(plain_tree3d):
    a, b, c = (form(plain_tree3d, BENT, seed) for seed in (1, 1, 2))
    assert np.array_equal(a.end, b.end) and np.array_equal(a.heading, b.heading)
    assert not np.allclose(a.end, c.end)
    assert botany.straight_chains(a) == 0 and len(a) > len(plain_tree3d)
    # children stay on their parent's new end, frames stay orthonormal and follow the segments
    child = np.flatnonzero(a.parent >= 0)
    attached = np.flatnonzero(
        np.linalg.norm(plain_tree3d.start[1:] - plain_tree3d.end[plain_tree3d.parent[1:]], axis=1) < 1e-12
    )
    assert len(attached) == len(plain_tree3d) - 1
    assert np.abs(a.start[child] - a.end[a.parent[child]]).max() < 1e-9
    frame = np.stack([a.heading, a.left, a.up], 1)
    assert np.abs(frame @ frame.transpose(0, 2, 1) - np.eye(3)).max() < 1e-9
    assert np.allclose(np.cross(a.heading, a.left), a.up)
    direction = (a.end - a.start) / np.linalg.norm(a.end - a.start, axis=1)[:, None]
    assert np.abs(direction - a.heading).max() < 1e-9
    # lengths are kept (the curvature turns, it does not stretch)
    assert a.lengths().sum() == pytest.approx(plain_tree3d.lengths().sum(), rel=1e-9)


def test_seeds_give_different_skeletons_through_draw(demo):
    g, _ = demo
    digests = {botany.digest(draw(g, 3, seed)[1]) for seed in range(5)}
    assert len(digests) == 5
    assert botany.digest(draw(g, 3, 7)[1]) == botany.digest(draw(g, 3, 7)[1])


def _in_frame(points, origin, sk, rows):
    """``points`` in the frame (heading, left, up) of segments ``rows`` of ``sk``, relative to ``origin``."""
    d = points - origin
    return np.stack([np.einsum("ij,ij->i", d, getattr(sk, k)[rows]) for k in ("heading", "left", "up")], 1)


def test_leaves_follow_their_twig(plain_tree3d):
    sk = plain_tree3d
    out = form(sk, BENT.replace(angle_variation=(20,), phyllotaxis="golden"), 3)
    g0, g1 = sk.leaf_segment, out.leaf_segment
    assert (g0 >= 0).all() and (out.order[g1] == sk.order[g0]).all()
    assert (out.module[g1] == sk.module[g0]).all()
    # the twig's last piece: no later piece of the same segment (same module) hangs from it
    child = np.flatnonzero(out.parent >= 0)
    same = child[out.module[child] == out.module[out.parent[child]]]
    assert not np.isin(g1, out.parent[same]).any()
    before = _in_frame(sk.leaf_position, sk.end[g0], sk, g0)
    after = _in_frame(out.leaf_position, out.end[g1], out, g1)
    assert np.abs(before - after).max() < 1e-9
    for key in ("leaf_heading", "leaf_left", "leaf_up"):
        rel0 = _in_frame(getattr(sk, key), 0.0, sk, g0)
        rel1 = _in_frame(getattr(out, key), 0.0, out, g1)
        assert np.abs(rel0 - rel1).max() < 1e-9
    assert not np.allclose(sk.leaf_position, out.leaf_position)  # they did move


AXIS = """
axiom = "F(1)A"
iterations = 8
angle = 45
rules = ["A -> F(1){laterals}/(31)A"]
"""


def _azimuths(pattern: str, laterals: str):
    g = Grammar.from_text(AXIS.format(laterals=laterals) + f'[form]\nphyllotaxis = "{pattern}"\n')
    sk = draw(g, g.iterations, 0)[1]
    lateral = np.flatnonzero((sk.parent >= 0) & (sk.order > 0))
    assert np.allclose(sk.heading[sk.order == 0], [0, 1, 0])  # a straight vertical axis: azimuth about +Y
    h = sk.heading[lateral]
    return np.degrees(np.arctan2(h[:, 2], h[:, 0])), sk.parent[lateral]


def _steps(az):
    return np.diff(az) % 360.0


def _wrapped(degrees):
    return (np.asarray(degrees) + 180.0) % 360.0 - 180.0


def test_golden_phyllotaxis_puts_successive_laterals_137_5_degrees_apart():
    az, _ = _azimuths("golden", "[&F(1)]")
    assert len(az) == 8
    steps = _steps(az)  # one way round: all 137.5, or all 360 - 137.5
    assert np.allclose(np.minimum(steps, 360.0 - steps), GOLDEN_ANGLE) and np.ptp(steps) < 1e-9
    assert pytest.approx(137.50776, abs=1e-5) == GOLDEN_ANGLE


def test_distichous_alternates_at_180_degrees():
    az, _ = _azimuths("distichous", "[&F(1)]")
    assert np.allclose(_steps(az), 180.0)


def test_decussate_pairs_turn_90_degrees_per_node():
    az, node = _azimuths("decussate", "[&F(1)][^F(1)]")
    assert len(az) == 16 and (node[0::2] == node[1::2]).all()
    assert np.allclose(_steps(az)[0::2], 180.0)  # the two of a pair
    assert np.allclose(np.abs(_wrapped(np.diff(az[0::2]))), 90.0)  # pair to pair


def test_opposite_pairs_stay_aligned():
    az, _ = _azimuths("opposite", "[&F(1)][^F(1)]")
    assert np.allclose(_steps(az)[0::2], 180.0)
    assert np.allclose(_wrapped(np.diff(az[0::2])), 0.0, atol=1e-6)


def test_whorls_spread_evenly_and_alternate():
    az, _ = _azimuths("whorl:3", "[&F(1)][/(100)&F(1)][/(200)&F(1)]")
    assert len(az) == 24
    per_whorl = az.reshape(-1, 3)
    assert np.allclose(np.abs(_wrapped(np.diff(per_whorl, axis=1))), 120.0)
    assert np.allclose(np.abs(_wrapped(np.diff(per_whorl[:, 0]))), 60.0)


def test_angle_and_length_variation_make_limbs_unlike(plain_tree3d):
    sk = plain_tree3d
    out = form(sk, FormOptions(angle_variation=(15,), length_variation=(0.2,)), 5)
    assert len(out) == len(sk)  # no curvature: no split
    lateral = np.flatnonzero((sk.parent >= 0) & (sk.order > sk.order[np.maximum(sk.parent, 0)]))

    def angles(s):
        return np.degrees(
            np.arccos(np.clip(np.einsum("ij,ij->i", s.heading[lateral], s.heading[s.parent[lateral]]), -1, 1))
        )

    change = angles(out) - angles(sk)
    assert np.abs(change).max() <= 15 + 1e-9 and np.std(change) > 3
    ratio = out.lengths() / sk.lengths()
    assert ratio.min() >= 0.8**6 - 1e-9 and ratio.max() <= 1.2**6 + 1e-9 and np.std(ratio) > 0.05
    assert np.abs(out.start[1:] - out.end[out.parent[1:]]).max() < 1e-9


def test_everything_is_off_by_default(plain_tree3d):
    assert not FormOptions().active
    assert form(plain_tree3d, FormOptions()) is plain_tree3d
    assert "form" not in GenerateOptions().plain()  # the provenance of every existing plant is unchanged
    assert GenerateOptions.from_flat(flare=1.5).plain()["form"]["flare"] == 1.5
    g = Grammar.from_file(DEMO)
    assert not FormOptions.from_grammar(g, FormOptions(enabled=False)).active  # --no-form
    assert FormOptions.from_grammar(g, FormOptions(flare=2.0)).flare == 2.0  # a flag over the table
    assert FormOptions.from_grammar(g).flare == 1.8


def test_the_form_stage_is_reported():
    seen = []
    g = Grammar.from_file(DEMO)
    draw(g, 2, 0, progress=lambda stage, event, seconds: seen.append((stage, event)))
    assert [s for s, e in seen if e == "done"] == ["derive", "interpret", "form"]
    seen.clear()
    draw(lsys3d.load_preset("tree3d"), 2, 0, progress=lambda stage, event, seconds: seen.append((stage, event)))
    assert "form" not in {s for s, _ in seen}


def test_the_form_table_survives_grammar_text():
    g = Grammar.from_file(DEMO)
    again = Grammar.from_text(grammar_text(g.replace(text=None)))
    assert dict(again.form) == dict(g.form)


@pytest.mark.parametrize(
    "changes, field",
    [
        ({"pipe_exponent": 1.5}, "pipe_exponent"),
        ({"pipe_exponent": 3.5}, "pipe_exponent"),
        ({"tip_width": 0.0}, "tip_width"),
        ({"flare": 0.5}, "flare"),
        ({"gnarl": -1.0}, "gnarl"),
        ({"substeps": 0}, "substeps"),
        ({"angle_variation": (10, 95)}, "angle_variation"),
        ({"length_variation": 1.5}, "length_variation"),
        ({"phyllotaxis": "spiral"}, "phyllotaxis"),
        ({"phyllotaxis": "whorl:1"}, "phyllotaxis"),
        ({"phototropism_light": (0, 0, 0)}, "phototropism_light"),
        ({"branch_collar": 0.9}, "branch_collar"),
    ],
)
def test_options_out_of_range_are_refused(changes, field):
    with pytest.raises(OptionsError, match=rf"FormOptions\.{field}: "):
        FormOptions(**changes)


def test_generate_refuses_a_bad_flat_option():
    with pytest.raises(OptionsError, match=r"FormOptions\.flare"):
        lsys3d.generate("koch", iterations=1, flare=0.5)


@pytest.mark.parametrize(
    "table, line, col, what",
    [
        ("[form]\npipe_model = true\n  bogus = 1\n", 6, 3, "unknown key 'bogus'"),
        ("[form]\nflare = 0.2\n", 5, 1, "flare: must be in [1, 10]"),
        ('[form]\ntip_width = 0.1\nphyllotaxis = "spiral"\n', 6, 1, "phyllotaxis"),
    ],
)
def test_a_bad_form_table_is_a_grammar_error_at_its_line(table, line, col, what):
    text = 'axiom = "F"\nrules = ["F -> F[+F]F"]\n\n' + table
    with pytest.raises(GrammarError) as info:
        lsys3d.generate(Grammar.from_text(text, source="plant.toml"), iterations=1)
    message = str(info.value)
    assert message.startswith(f"plant.toml:{line}:{col}: [form]"), message
    assert what in message


def test_a_form_table_of_the_wrong_type_is_refused():
    with pytest.raises(GrammarError, match=re.escape("'form' must be a table")):
        Grammar.from_text('axiom = "F"\nform = 3\n')


def test_curved_sub_segments_keep_their_rings_in_the_sweep():
    from lsys3d.mesh.sweep import SweepOptions, sweep

    points = np.zeros((11, 3))
    points[:, 1] = np.arange(11.0)
    sk = form(Skeleton.from_segments(points[:-1], points[1:], 0.2), FormOptions(gnarl=20, max_substep_length=0.25), 0)
    assert len(sk) == 40 and len(sk.chains) == 1
    tubes = sweep(sk, SweepOptions(sides=8))
    assert len(tubes.points) == (len(sk) + 1) * 8 + 2  # a ring at every joint: none merged back straight


def test_the_demo_grows_a_closed_bark_with_levels_of_detail():
    tree = lsys3d.generate(Grammar.from_file(DEMO), iterations=4, lod=(0, 2))
    assert tree.bark.is_watertight and len(tree.lods) == 2
    assert all(level.bark.is_watertight for level in tree.lods)
    assert tree.provenance.options == GenerateOptions.from_flat(lod=(0, 2)).plain()  # no form: not recorded


def test_the_docs_list_every_key():
    from lsys3d.turtle.form import options_markdown

    assert options_markdown() in (ROOT / "docs" / "form.md").read_text(encoding="utf-8")


def test_the_seed_matters_when_the_form_draws_on_it():
    from lsys3d.pipeline import seed_dependence

    g = Grammar.from_file(DEMO)
    assert seed_dependence(g) == ("gnarl", "angle_variation", "length_variation")
    assert seed_dependence(g, GenerateOptions.from_flat(form=False)) == ()
    assert seed_dependence(lsys3d.load_preset("tree3d"), GenerateOptions.from_flat(pipe_model=True)) == ()


def test_the_segment_limit_holds_for_the_pieces(plain_tree3d):
    from lsys3d.errors import LimitError

    limit = len(plain_tree3d) + 1
    with pytest.raises(LimitError, match=rf"form: .* more than the limit of {limit:,}"):
        form(plain_tree3d, BENT, max_segments=limit)
    with pytest.raises(LimitError, match="max-segments"):
        draw(Grammar.from_file(DEMO), 5, 0, GenerateOptions.from_flat(max_segments=1000))


@pytest.mark.parametrize(
    "options, toward, trunk_upright",
    [
        (FormOptions(gravitropism=(0, 20)), [0, 1, 0], True),  # order 0 has no gravitropism here
        (FormOptions(gravitropism=(0, -20)), [0, -1, 0], True),
        (
            FormOptions(phototropism=20, phototropism_light=(1, 0, 0)),
            [1, 0, 0],
            False,
        ),  # every order turns to the light
        (FormOptions(plagiotropism=20), [0.0, 0.0, 1.0], True),  # laterals only
    ],
)
def test_tropisms_turn_the_branch_toward_their_target(options, toward, trunk_upright):
    # a vertical trunk with a lateral rising at 45 degrees toward +z, 4 m long
    sk = Skeleton.from_segments([[0, 0, 0], [0, 1, 0]], [[0, 1, 0], [0, 1 + 2**1.5, 2**1.5]], 0.1, parent=[-1, 0])
    sk = Skeleton(**{**{k: getattr(sk, k) for k in sk.__dataclass_fields__}, "order": np.array([0, 1], np.int32)})
    out = form(sk, options)
    lateral = out.order == 1
    before = np.dot(sk.heading[1], toward)
    after = np.einsum("ij,j->i", out.heading[lateral], toward)
    assert (np.diff(after) > 0).all() and after[0] > before  # turning toward it, piece by piece
    assert (after <= 1.0 + 1e-12).all()
    assert np.allclose(out.heading[~lateral], [0, 1, 0]) == trunk_upright
