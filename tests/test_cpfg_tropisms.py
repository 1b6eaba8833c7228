"""cpfg's newer tropisms (the view file's ``tropism:`` and ``torque:``, ``@Ts``, ``@Ti``, ``@Td``), ``@Tf``, ``@Tp``
and its turns, checked against cpfg's turtle written out again from its C sources (vlab 9bf820d: interpret.c's
``change_dir`` and F/f, movements.c, turtle.c ``adjust_up_and_left``, blackbox.c's ``@T``, quaternions.c), in
cpfg's own frame (H = (0, 1, 0), L = (-1, 0, 0), U = (0, 0, -1) at first), not with lsys3d's code."""

from __future__ import annotations

import math

import numpy as np
import pytest

import lsys3d
from lsys3d.lsystem.derive import interpretation
from lsys3d.turtle import interpret


# ---------------------------------------------------------------- cpfg's turtle, written out again
def _cross3(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def _mult(q1, q2):  # quaternions.c mult_quats (w first)
    return [
        q1[0] * q2[0] - (q1[1] * q2[1] + q1[2] * q2[2] + q1[3] * q2[3]),
        q1[0] * q2[1] + q2[0] * q1[1] + q1[2] * q2[3] - q1[3] * q2[2],
        q1[0] * q2[2] + q2[0] * q1[2] + q1[3] * q2[1] - q1[1] * q2[3],
        q1[0] * q2[3] + q2[0] * q1[3] + q1[1] * q2[2] - q1[2] * q2[1],
    ]


def _rot_by_quat(v, q):  # quaternions.c rot_by_quat: q^-1 v q
    size = 1.0 / sum(x * x for x in q)
    qi = [size * q[0], -size * q[1], -size * q[2], -size * q[3]]
    r = _mult(_mult(qi, [0.0, *v]), q)
    return r[1:]


def _quat(angle, axis):
    return [math.cos(angle), *(math.sin(angle) * a for a in axis)]


class CpfgTurtle:
    """cpfg's turtle for F, f, + - & ^ / \\, [ ], @Ts, @Ti, @Td, @Tf, @Tp, with movements (tropisms, twists)."""

    def __init__(self, movements):
        # movements: (kind, T as read_movement leaves it, gamma, initial elasticity, increment)
        self.movements = movements
        self.pos = [0.0, 0.0, 0.0]
        self.h, self.l, self.u = [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, -1.0]
        self.ph, self.pu = list(self.h), list(self.u)
        self.e = [m[3] for m in movements]
        self.stack = []
        self.segments = []  # (start, end, H, L, U) of each F

    def adjust_up_and_left(self):  # turtle.c
        rot = _cross3(self.h, self.ph)
        n = math.sqrt(_dot(rot, rot))
        if n > 0.000001:
            self.u = list(self.pu)
            n = min(n, 1.0)
            angle = math.asin(n) * 0.5
            if _dot(self.h, self.ph) < 0:
                angle = math.pi * 0.5 - angle
            self.u = _rot_by_quat(self.u, _quat(angle, [r / n for r in rot]))
        self.l = _cross3(self.h, self.u)

    def movement_adjust(self):  # movements.c
        if not self.movements:
            return
        des = [0.0, 0.0, 0.0]
        twist = [0.0, 0.0, 0.0]
        for (kind, t, gamma, _, _), e in zip(self.movements, self.e, strict=True):
            if kind == "twist":
                twist = [twist[k] + e * t[k] for k in range(3)]
                continue
            c, s = math.cos(math.radians(gamma)), math.sin(math.radians(gamma))
            des = [des[k] + c * e * t[k] for k in range(3)]
            if s != 0.0:
                vec = _cross3(self.h, t)
                n = math.sqrt(_dot(vec, vec))
                if n < 0.0000001:
                    vec, n = list(self.l), 1.0
                vec2 = _cross3(t, vec)
                des = [des[k] + e * s / n * vec2[k] for k in range(3)]
        rot = _cross3(self.h, des)
        n = math.sqrt(_dot(rot, rot))
        if n >= 0.000001:  # adjust_by_orthotropism
            n2 = min(n, 1.0)
            self.h = _rot_by_quat(self.h, _quat(-n2 * 0.5, [r / n for r in rot]))
            self.adjust_up_and_left()
        if any(twist):
            w = math.sqrt(_dot(twist, twist))
            v2 = [x / w for x in twist]
            vec = _cross3(self.h, v2)
            if _dot(vec, vec) > 0.00000001:
                des = [x * w for x in _cross3(vec, self.h)]
                vec = _cross3(self.u, des)  # rotate_to_vector
                n = math.sqrt(_dot(vec, vec))
                if n >= 0.0000001:
                    n2 = min(n, 1.0)
                    self.u = _rot_by_quat(self.u, _quat(n2 * 0.5, [x / n for x in vec]))
                    self.l = _cross3(self.h, self.u)
                self.ph, self.pu = list(self.h), list(self.u)

    def change_dir(self, a, b, sin, cos):  # interpret.c: a turns toward b
        va, vb = getattr(self, a), getattr(self, b)
        setattr(self, a, [cos * va[k] + sin * vb[k] for k in range(3)])
        setattr(self, b, [cos * vb[k] - sin * va[k] for k in range(3)])

    def run(self, modules):
        for symbol, p in modules:
            if symbol in "Ff":
                self.movement_adjust()
                end = [self.pos[k] + p[0] * self.h[k] for k in range(3)]
                if symbol == "F":
                    self.segments.append((self.pos, end, self.h, self.l, self.u))
                    self.ph, self.pu = list(self.h), list(self.u)
                self.pos = end
            elif symbol in "+-&^/\\":
                s, c = math.sin(math.radians(p[0])), math.cos(math.radians(p[0]))
                a, b = {"+": ("h", "l"), "-": ("h", "l"), "&": ("h", "u"), "^": ("h", "u")}.get(symbol, ("l", "u"))
                self.change_dir(a, b, -s if symbol in "-^\\" else s, c)
            elif symbol == "[":
                self.stack.append((self.pos, self.h, self.l, self.u, self.ph, self.pu, list(self.e)))
            elif symbol == "]":
                self.pos, self.h, self.l, self.u, self.ph, self.pu, self.e = self.stack.pop()
            elif symbol == "@Tf":
                self.ph, self.pu = list(self.h), list(self.u)
            elif symbol == "@Tp":
                self.adjust_up_and_left()
            elif symbol in ("@Ts", "@Ti", "@Td"):  # blackbox.c
                if not p:
                    continue
                i = int(p[0] - 1)
                if not 0 <= i < len(self.movements):
                    continue
                aux = p[1] if len(p) >= 2 else self.movements[i][4]
                if symbol == "@Td":
                    aux = -aux
                elif symbol == "@Ts":
                    aux = (p[1] if len(p) >= 2 else 0.0) - self.e[i]
                self.e[i] += aux
        return self.segments


def _parse(axiom: str):
    out = []
    i = 0
    while i < len(axiom):
        if axiom[i] == " ":
            i += 1
            continue
        name = axiom[i : i + 3] if axiom.startswith("@T", i) else axiom[i]
        i += len(name)
        params = []
        if axiom.startswith("(", i):
            close = axiom.index(")", i)
            params = [float(x) for x in axiom[i + 1 : close].split(",")]
            i = close + 1
        out.append((name, params))
    return out


VIEW = (
    "angle increment: 30\n"
    "tropism: T: 0.0 -1.0 0.0 E: 0.2 S: 0.05\n"
    "tropism: T: 1 0 0.5 A: 90 E: 0.1\n"
    "torque: T: 0 0 2 I: 0.5 E: 0.3\n"
)
# as read_movement leaves them: T made a unit vector, times I (held to [-1, 1])
MOVEMENTS = [
    ("tropism", [0.0, -1.0, 0.0], 0.0, 0.2, 0.05),
    ("tropism", [1 / math.sqrt(1.25), 0.0, 0.5 / math.sqrt(1.25)], 90.0, 0.1, 0.0),
    ("twist", [0.0, 0.0, 0.5], 0.0, 0.3, 0.0),
]

CASES = [
    "F(1) F(1) F(1)",
    "/(30) &(40) \\(20) @Tf F(1) F(1) [ @Ts(1,0.5) +(30) F(1) /(45) F(1) ] @Ti(2) F(1) @Td(3,0.1) f(0.5) F(1)",
    "&(170) F(1) F(1) /(60) @Tp F(1) ^(50) -(20) F(2) @Ts(1) @Ts(3) F(1) @Ts(9,1) @Ts F(1) @Ti(1) @Ti(1) F(1)",
    "+(90) F(1) [ &(90) F(1) F(1) ] [ ^(90) @Ts(2,0.8) F(1) F(1) ] \\(30) F(1)",
]


def _grown(tmp_path, axiom: str, view: str):
    (tmp_path / "t.l").write_text(f"Lsystem: 1\nderivation length: 0\nAxiom: {axiom}\nendlsystem\n")
    (tmp_path / "t.v").write_text(view)
    grammar = lsys3d.Grammar.from_file(tmp_path / "t.l")
    return interpret(interpretation(grammar, lsys3d.derive(grammar)), grammar)


@pytest.mark.parametrize("axiom", CASES)
@pytest.mark.parametrize("movements", [True, False], ids=["movements", "none"])
def test_the_turtle_bends_and_turns_as_cpfgs_does(tmp_path, axiom, movements):
    view = VIEW if movements else "angle increment: 30\n"
    skeleton = _grown(tmp_path, axiom, view)
    segments = CpfgTurtle(MOVEMENTS if movements else []).run(_parse(axiom))
    assert len(skeleton) == len(segments)
    start, end, h, left, up = (np.array([s[k] for s in segments]) for k in range(5))
    assert np.allclose(skeleton.start, start, atol=1e-9)
    assert np.allclose(skeleton.end, end, atol=1e-9)
    assert np.allclose(skeleton.heading, h, atol=1e-9)
    # cpfg's frame has H x L = -U: lsys3d's U is cpfg's -U, L the same
    assert np.allclose(skeleton.left, left, atol=1e-9)
    assert np.allclose(skeleton.up, -up, atol=1e-9)


def test_the_movements_bend_at_all(tmp_path):
    """The cases above are not straight lines by chance: without the movements the same string ends elsewhere."""
    axiom = CASES[1]
    with_ = _grown(tmp_path, axiom, VIEW).end[-1]
    without = _grown(tmp_path, axiom, "angle increment: 30\n").end[-1]
    assert np.linalg.norm(with_ - without) > 0.1


def test_the_view_files_movements_are_read_as_cpfg_reads_them(tmp_path):
    (tmp_path / "t.l").write_text("Lsystem: 1\nAxiom: F\nendlsystem\n")
    (tmp_path / "t.v").write_text(VIEW)
    grammar = lsys3d.Grammar.from_file(tmp_path / "t.l")
    rows = np.array(lsys3d.TurtleOptions.from_grammar(grammar).tropisms).reshape(-1, 7)
    want = [[0.0 if k != "twist" else 1.0, *t, g, e, s] for k, t, g, e, s in MOVEMENTS]
    assert np.allclose(rows, want)


@pytest.mark.parametrize(
    ("line", "what"),
    [
        ("tropism: A: 90", "expects its vector (T: x y z)"),
        ("tropism: T: 0 0 0", "T: expects three numbers not all 0"),
        ("torque: T: 0 1 0 Q: 3", "unknown or incomplete entry 'Q'"),
        ("tropism: T: 0 1 0 I: 0", "its intensity (I:) is 0"),
    ],
)
def test_a_movement_cpfg_would_leave_out_is_refused_in_one_line(tmp_path, line, what):
    (tmp_path / "t.l").write_text("Lsystem: 1\nAxiom: F\nendlsystem\n")
    (tmp_path / "t.v").write_text("angle increment: 30\n" + line + "\n")
    with pytest.raises(lsys3d.GrammarError) as info:
        lsys3d.Grammar.from_file(tmp_path / "t.l")
    assert what in str(info.value) and "t.v:2" in str(info.value) and "\n" not in str(info.value)


def test_the_tropisms_model_reads_its_view_file(tmp_path):
    """vlab's Tropisms (cpfg manual): three movements, all of strength 0 as the file stands: a straight axis."""
    from pathlib import Path

    real = Path(__file__).parent / "corpus" / "cpfg" / "real"
    grammar = lsys3d.Grammar.from_file(real / "manual-Tropisms-lsystem.l")
    assert len(lsys3d.TurtleOptions.from_grammar(grammar).tropisms) == 21
    skeleton = interpret(interpretation(grammar, lsys3d.derive(grammar)), grammar)
    text = (real / "manual-Tropisms-lsystem.l").read_text()
    bent = text.replace("#define OrthoStrength 0", "#define OrthoStrength 0.3")
    (tmp_path / "manual-Tropisms-lsystem.l").write_text(bent)
    (tmp_path / "manual-Tropisms-lsystem.v").write_text((real / "manual-Tropisms-lsystem.v").read_text())
    bent_grammar = lsys3d.Grammar.from_file(tmp_path / "manual-Tropisms-lsystem.l")
    bent_skeleton = interpret(interpretation(bent_grammar, lsys3d.derive(bent_grammar)), bent_grammar)
    assert len(bent_skeleton) == len(skeleton)
    # the orthotropism T = (0, 1, 0) of strength 0.3 turns the axis up: its tip rises above the straight one's
    assert bent_skeleton.end[:, 1].max() > skeleton.end[:, 1].max() + 0.5


def test_a_tropism_the_view_file_does_not_give_is_named(tmp_path, caplog):
    import logging

    from lsys3d.pipeline import draw

    (tmp_path / "t.l").write_text("Lsystem: 1\nAxiom: @Ts(1, 0.2) F @Ts(4, 1) @Ti(0) F\nendlsystem\n")
    (tmp_path / "t.v").write_text(VIEW)
    grammar = lsys3d.Grammar.from_file(tmp_path / "t.l")
    with caplog.at_level(logging.WARNING, logger="lsys3d"):
        draw(grammar, 0, 0)
    found = [r.getMessage() for r in caplog.records if "tropisms the view file does not give" in r.getMessage()]
    assert len(found) == 1 and "(it gives 3:" in found[0] and "@Ti(0), @Ts(4) change nothing" in found[0], found
