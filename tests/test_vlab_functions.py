"""vlab model folders: graphically defined functions (``func``), the view file's tropism, cpp's text macros.

The expectations are computed here without lsys3d: cpfg's ``SplineFunction`` (splinefun.cpp) and its old
tropism (interpret.c ``bend``) written out again in plain Python, one value at a time.
"""

from __future__ import annotations

import itertools
import logging
import math
import tomllib
from pathlib import Path

import numpy as np
import pytest

import lsys3d
from lsys3d.lsystem.derive import interpretation
from lsys3d.lsystem.splines import read_function, read_function_set
from lsys3d.pipeline import draw

REAL = Path(__file__).parent / "corpus" / "cpfg" / "real"


# ---------------------------------------------------------------- cpfg's splinefun.cpp, written out again
def cpfg_function(points, samples):
    """``func(id, x)`` as splinefun.cpp computes it: recursive basis, halving search, linear samples."""
    n = len(points) - 1

    def uk(j):
        return 0 if j < 4 else (n - 2 if j > n else j - 3)

    def basis(k, t, u):
        if t == 1:
            return 1.0 if uk(k) <= u < uk(k + 1) else 0.0
        total = 0.0
        div = uk(k + t - 1) - uk(k)
        if div != 0:
            total = (u - uk(k)) / div * basis(k, t - 1, u)
        div = uk(k + t) - uk(k + 1)
        if div != 0:
            total += (uk(k + t) - u) / div * basis(k + 1, t - 1, u)
        return total

    def point(d):
        u = d * (n - 2)
        x = sum(points[k][0] * basis(k, 4, u) for k in range(n + 1))
        y = sum(points[k][1] * basis(k, 4, u) for k in range(n + 1))
        return x, y

    def search(v):
        low, high = 0.0, 1.0
        while True:
            check = (low + high) / 2.0
            x, y = point(check)
            if x > v:
                high = check
            else:
                low = check
            if abs(x - v) <= 0.001:
                return y

    if samples <= 2:
        return lambda v: search(min(max(v, 0.0), 1.0))
    values = [search(i / (samples - 1)) for i in range(samples)]

    def sampled(v):
        v = min(max(v, 0.0), 1.0)
        index = v * (samples - 1)
        i = math.floor(index)
        if i == samples - 1:
            return values[i]
        return (1 - index + i) * values[i] + (index - i) * values[i + 1]

    return sampled


def test_a_function_set_evaluates_as_cpfg_does():
    functions = read_function_set((REAL / "functions.fset").read_text(), "functions.fset")
    assert [f.name for f in functions] == ["Ang_1", "Ang_2", "Ang_3", "Ang_4", "Ang_5", "y", "x_motion"]
    assert len(functions[4].points) == 5  # Ang_5's points carry a multiplicity of 1
    xs = [0.0, 0.011, 0.2, 0.37, 0.5, 0.77, 0.999, 1.0, 1.5, -0.2]
    for f in functions:
        naive = cpfg_function(f.points, f.samples)
        assert f.samples == 100
        assert np.allclose(f.evaluate(np.array(xs)), [naive(x) for x in xs], atol=1e-12, rtol=0), f.name


def test_an_old_function_file_takes_its_samples_from_the_view_file():
    text = (REAL / "internode.func").read_text()
    sampled, direct = read_function(text, "internode.func", 100), read_function(text, "internode.func")
    assert (sampled.name, sampled.samples, direct.samples) == ("internode", 100, 0)
    xs = [0.0, 0.3, 0.4264, 0.43, 0.9, 1.0]
    for f in (sampled, direct):
        naive = cpfg_function(f.points, f.samples)
        assert np.allclose(f.evaluate(np.array(xs)), [naive(x) for x in xs], atol=1e-12, rtol=0)


def test_multiplicities_repeat_a_point():
    f = read_function("fver 1 1\nname: m\nsamples: 0\nflip: off\npoints: 4\n0 0\n0.3 .5\n0.5 1 2\n1 0\n", "m.func")
    assert f.points == ((0.0, 0.0), (0.3, 0.5), (0.5, 1.0), (0.5, 1.0), (1.0, 0.0))


def test_the_jumping_lamp_turns_by_its_functions_at_the_time_its_blocks_give():
    """Start: t = 0, EndEach: t += dt (0.011): the homomorphism reads t = 0.011 after the one step."""
    functions = {f.name: f for f in read_function_set((REAL / "functions.fset").read_text(), "functions.fset")}
    grammar = lsys3d.Grammar.from_file(REAL / "manual-JumpingLamp-lamp.l")
    shown = interpretation(grammar, lsys3d.derive(grammar))
    angles = {n: 100 * cpfg_function(f.points, f.samples)(0.011) for n, f in functions.items()}
    modules = [shown.module(i) for i in range(len(shown))]
    got = [round(p[0], 6) for s, p in modules if s in "/&" and p and p[0] != 90.0]
    want = [angles["Ang_1"], angles["Ang_2"], angles["Ang_3"] - angles["Ang_2"], angles["Ang_4"] - angles["Ang_3"]]
    want.append(angles["Ang_5"])
    assert got == [round(w, 6) for w in want]
    moves = [p[0] for s, p in modules if s == "f" and p]
    assert moves[6:8] == pytest.approx([1.2 * angles["x_motion"] / 100, angles["y"] / 100])  # after the base plane


def test_functions_survive_the_toml_rendering():
    from lsys3d.provenance import grammar_text

    grammar = lsys3d.Grammar.from_file(REAL / "manual-TexturedSurfaces-plant.l")
    again = lsys3d.Grammar.from_text(grammar_text(grammar), source="rendered.toml")
    assert str(lsys3d.derive(again)) == str(lsys3d.derive(grammar))
    assert dict(again.turtle) == dict(grammar.turtle)


def _model(tmp_path, grammar: str, view: str, files: dict[str, str] | None = None) -> Path:
    (tmp_path / "plant.l").write_text(grammar)
    (tmp_path / "plant.v").write_text(view)
    for name, text in (files or {}).items():
        (tmp_path / name).write_text(text)
    return tmp_path / "plant.l"


LINE = "fver 1 1\nname: line\nsamples: 0\nflip: off\npoints: 4\n0 0\n0.333333 0.333333\n0.666667 0.666667\n1 1\n"


def test_func_names_a_function_of_the_view_file_by_number(tmp_path):
    path = _model(
        tmp_path,
        "Lsystem: 1\nderivation length: 1\nAxiom: A(0.25)\nA(x) --> F(4*func(1,x))\nendlsystem\n",
        "angle increment: 30\nfunction: line.func\n",
        {"line.func": LINE},
    )
    derived = lsys3d.derive(lsys3d.Grammar.from_file(path))
    assert len(derived) == 1 and derived.module(0)[1][0] == pytest.approx(1.0, abs=0.005)


def test_a_missing_function_file_and_an_unknown_function_are_refused_in_one_line(tmp_path):
    grammar = "Lsystem: 1\nderivation length: 1\nAxiom: A(0.25)\nA(x) --> F(func(2,x))\nendlsystem\n"
    path = _model(tmp_path, grammar, "angle increment: 30\nfunction: gone.func\n")
    with pytest.raises(lsys3d.GrammarError) as info:
        lsys3d.Grammar.from_file(path)
    assert str(info.value).startswith(f"{tmp_path / 'plant.v'}:2:1: function: 'gone.func': ")
    path = _model(tmp_path, grammar, "angle increment: 30\nfunction: line.func\n", {"line.func": LINE})
    with pytest.raises(lsys3d.LSystemError) as info:
        lsys3d.derive(lsys3d.Grammar.from_file(path))
    assert "func(2, ...): no such function (the view file's are 1)" in str(info.value)
    assert "\n" not in str(info.value)


def test_a_view_file_cannot_lead_out_of_the_models_folder(tmp_path):
    (tmp_path / "secret.func").write_text(LINE)
    model = tmp_path / "model"
    model.mkdir()
    path = _model(model, "Lsystem: 1\nAxiom: F\nendlsystem\n", "function: ../secret.func\n")
    with pytest.raises(lsys3d.GrammarError, match=r"function: '\.\./secret\.func'"):
        lsys3d.Grammar.from_file(path)


def test_a_macro_of_a_function_call_is_put_in_place(tmp_path):
    """JumpingLamp's '#define angle1 100*func(Ang_1,t)': text (not a constant), put where its name stands."""
    path = _model(
        tmp_path,
        "#define W 2*func(1,x)\nLsystem: 1\nderivation length: 1\nAxiom: A(0.5)\nA(x) --> F(W)\nendlsystem\n",
        "angle increment: 30\nfunction: line.func\n",
        {"line.func": LINE},
    )
    derived = lsys3d.derive(lsys3d.Grammar.from_file(path))
    assert derived.module(0)[1][0] == pytest.approx(1.0, abs=0.005)
    text = "#define W 2*w\nLsystem: 1\nderivation length: 1\nAxiom: A(3)\nA(w) --> F(W)\nendlsystem\n"
    assert str(lsys3d.derive(lsys3d.Grammar.from_text(text, source="p.l"))) == "F(6)"


# ---------------------------------------------------------------- cpfg's old tropism, written out again
def cpfg_tropism(lengths, elasticities, tropism):
    """The end points cpfg draws for F(l)... each bent with its elasticity (interpret.c: move, then ``bend``)."""
    h, left, up = np.array([0.0, 1.0, 0.0]), np.array([-1.0, 0.0, 0.0]), np.array([0.0, 0.0, -1.0])
    t = np.asarray(tropism, float) / np.linalg.norm(tropism)
    p, ends = np.zeros(3), []
    for length, e in zip(lengths, elasticities, strict=True):
        p = p + length * h
        ends.append(p)
        s = e * t @ up
        c = math.sqrt(1 - s * s)
        h, up = c * h + s * up, c * up - s * h
        s = e * t @ left
        c = math.sqrt(1 - s * s)
        h, left = c * h + s * left, c * left - s * h
    return np.array(ends)


def test_the_view_files_tropism_is_the_grammars_and_bends_as_cpfgs(tmp_path, caplog):
    """A chain (no turns: cpfg's and lsys3d's frames differ in U's sign, which the bend does not see)."""
    path = _model(
        tmp_path,
        "Lsystem: 1\nderivation length: 0\nAxiom: F F(2) _ F F _ F _(0.9) F(1.5)\nendlsystem\n",
        "angle increment: 30\ntropism direction: 0.3,-1,0.2\ninitial elasticity: 0.1\nelasticity increment: 0.2\n",
    )
    grammar = lsys3d.Grammar.from_file(path)
    tropism = list(np.array([0.3, -1, 0.2]) / np.linalg.norm([0.3, -1, 0.2]))
    assert dict(grammar.turtle) == {"tropism": tropism, "elasticity": 0.1, "elasticity_increment": 0.2, "bend": "cpfg"}
    with caplog.at_level(logging.WARNING, logger="lsys3d"):
        _, skeleton = draw(grammar, 0, 0)
    assert not caplog.records  # '_' is drawn: no warning names it
    want = cpfg_tropism([1, 2, 1, 1, 1, 1.5], [0.1, 0.1, 0.3, 0.3, 0.5, 0.9], (0.3, -1, 0.2))
    assert np.allclose(skeleton.end, want, atol=1e-9)


# ---------------------------------------------------------------- cpfg's curveXYZ.cpp, written out again
def cpfg_curve(points, samples=100):
    """curveX/curveY(1, t) and curveGAL(1) as curveXYZ.cpp computes them (type bspline, one level of points)."""
    size = len(points)

    def b(i, k, t):  # Bi1 ... Bi4 with the knots 0, 1, 2...
        if k == 1:
            return 1.0 if i <= t < i + 1 else 0.0
        return (t - i) / (k - 1) * b(i, k - 1, t) + (i + k - t) / (k - 1) * b(i + 1, k - 1, t)

    def p_value(t):
        i = 3 + int(t * (size - 3.000001))
        t = 3.0 + t * (size - 3.000001)
        return [sum(points[i - 3 + j][c] * b(i - 3 + j, 4, t) for j in range(4)) for c in range(3)]

    pts = [p_value(i / (samples - 1)) for i in range(samples)]
    total, lengths = 0.0, [0.0]
    for q, r in itertools.pairwise(pts):
        total += math.sqrt(sum((r[c] - q[c]) ** 2 for c in range(3)))
        lengths.append(total)
    lengths = [v / total for v in lengths]

    def a_value(t):
        t = min(max(t, 0.0), 1.0)
        low, high = 0, samples - 1
        while high - low > 1:
            mid = (low + high) // 2
            if lengths[mid] > t:
                high = mid
            else:
                low = mid
        return p_value((low + (t - lengths[low]) / (lengths[high] - lengths[low])) / (samples - 1))

    return a_value, total


def ridley_model():
    """vlab's Ridley (Algorithm 5 of Prusinkiewicz et al. 2001) from its rules: each primordium's (y, x, colour,
    sides, diameter), one decomposition at a time, the curve and the function of its model folder."""
    con = [line.split() for line in (REAL / "profile.con").read_text().splitlines()[10:] if line.strip()]
    points = [tuple(float(v) for v in p[:3]) for p in con for _ in range(int(p[3]))]
    curve, length = cpfg_curve(points)
    rho_file = read_function((REAL / "rho.func").read_text(), "rho.func")
    rho_of = cpfg_function(rho_file.points, rho_file.samples)
    s, a, ds, out = 0.0, 0.0, 0.001, []
    while s < length:  # A(s,a) : s<L
        rho = 0.1 * rho_of(s / length)
        rho_square = rho**2
        while a < rho_square and s < length:
            x = curve(s / length)[0]
            a = a + 2 * x * ds
            s = s + ds
        a = a - rho_square
        y = curve(s / length)[1]
        out.append((y, x, math.floor(1 + s / length * 32), 6 + 300 * rho, 2.1 * rho))
    return out, length


def test_ridley_places_its_primordia_as_cpfg_does():
    """Its curve (profile.con, curve: in the view file), its function (rho.func) and the while loop of its block."""
    expected = tomllib.loads((REAL.parent.parent / "expected.toml").read_text())["cpfg/real/manual-Ridley-spiral.l"][0]
    primordia, _ = ridley_model()
    assert len(primordia) == expected["organs"] == expected["counts"]["@O"]
    grammar = lsys3d.Grammar.from_file(REAL / "manual-Ridley-spiral.l")
    assert grammar.decomposition_depth == 3000 and len(primordia) < 3000  # each primordium one decomposition
    derived = lsys3d.derive(grammar)
    modules = [derived.module(i) for i in range(len(derived))]
    moves = [p[0] for s, p in modules if s == "f"]
    got = list(zip(moves[0::2], moves[1::2], strict=True))
    assert np.allclose(got, [(y, x) for y, x, *_ in primordia], atol=1e-9)
    assert np.allclose([p[0] for s, p in modules if s == "@O"], [d for *_, d in primordia], atol=1e-9)
    assert [p[0] for s, p in modules if s == ";"] == [c for _, _, c, _, _ in primordia]


def test_ridley_spheres_have_cpfgs_sides():
    """Each primordium's @!(no_poly): cpfg's blackbox.c keeps (int) no_poly, at least 3, for the sphere after it."""
    from lsys3d.look.organs import skeleton_organs
    from lsys3d.lsystem.derive import interpretation
    from lsys3d.turtle import interpret

    primordia, _ = ridley_model()
    want = [max(3, int(sides)) for _, _, _, sides, _ in primordia]
    grammar = lsys3d.Grammar.from_file(REAL / "manual-Ridley-spiral.l")
    skeleton = interpret(interpretation(grammar, lsys3d.derive(grammar)), grammar)
    assert skeleton.organ_sides.tolist() == want
    built = skeleton_organs(skeleton)
    # gluSphere(slices n, stacks n / 2 + 1): 2 n (stacks - 1) triangles each
    faces = {p.name: len(p.mesh.faces) for p in built.prototypes}
    assert sum(faces[f"sphere-{n}"] for n in want) == sum(2 * n * (n // 2) for n in want)


def test_a_while_loop_in_a_rules_block_runs_for_each_module_apart(monkeypatch):
    text = (
        "Lsystem: 1\nderivation length: 1\nAxiom: A(3) A(4) A(0)\n"
        "A(n) : {k = 0; s = 0; while (k < n) {k = k + 1; s = s + k;}} --> B(s, k)\nendlsystem\n"
    )
    assert str(lsys3d.derive(lsys3d.Grammar.from_text(text, source="p.l"))) == "B(6,3)B(10,4)B(0,0)"
    endless = text.replace("k = k + 1; ", "")
    monkeypatch.setattr("lsys3d.lsystem.derive.MAX_LOOP", 1000)  # lsys3d.lsystem.rules.MAX_LOOP: 100,000
    with pytest.raises(lsys3d.LSystemError, match="a while loop ran more than 1,000 rounds") as info:
        lsys3d.derive(lsys3d.Grammar.from_text(endless, source="p.l"))
    assert "\n" not in str(info.value)


def test_curves_of_other_types_are_refused_in_one_line(tmp_path):
    con = (REAL / "profile.con").read_text().replace("type: bspline", "type: bezier")
    path = _model(tmp_path, "Lsystem: 1\nAxiom: F\nendlsystem\n", "curve: p.con\n", {"p.con": con})
    with pytest.raises(lsys3d.GrammarError) as info:
        lsys3d.Grammar.from_file(path)
    assert "curve type 'bezier' is not supported (only 'bspline')" in str(info.value)
