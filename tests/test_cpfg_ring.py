"""cpfg's ring L-systems (``ring lsystem``): the string's last module is the left neighbour of its first."""

from __future__ import annotations

from pathlib import Path

import pytest

import lsys3d

RING = Path(__file__).parent / "corpus" / "cpfg" / "real" / "manual-Ring-ring.l"


def naive_ring(string: str, rules: dict, steps: int, ring: bool) -> str:
    """Parallel rewriting with one-letter contexts, written for this test: rules are (left, pred, right) -> succ."""
    for _ in range(steps):
        out = []
        for i, c in enumerate(string):
            left = string[i - 1] if i > 0 or ring else None
            right = string[(i + 1) % len(string)] if i + 1 < len(string) or ring else None
            for (lc, pred, rc), succ in rules.items():
                if pred == c and lc in (None, left) and rc in (None, right):
                    out.append(succ)
                    break
            else:
                out.append(c)
        string = "".join(out)
    return string


@pytest.mark.parametrize("ring", [True, False])
def test_the_a_goes_round_the_ring(ring):
    """vlab's Ring with dir = 1: 'B > A --> A' moves the A left, and from the first module to the last."""
    text = RING.read_text().replace("#define dir 0", "#define dir 1").replace("derivation length: 1", "")
    grammar = lsys3d.Grammar.from_text(text, source="ring.l").replace(ring=ring)
    assert grammar.ring is ring
    start = "A" + "B" * 31  # the decomposition of X(32)
    rules = {(None, "B", "A"): "A", (None, "A", None): "B"}  # dir == 1: the first rule's condition is false
    for n in (1, 2, 5, 40):
        assert str(lsys3d.derive(grammar, n + 1)) == naive_ring(start, rules, n, ring), n
    assert str(lsys3d.derive(grammar, 2)) == ("B" * 31 + "A" if ring else "B" * 32)


def test_the_ring_is_read_and_kept():
    from lsys3d.provenance import grammar_text

    grammar = lsys3d.Grammar.from_file(RING)
    assert grammar.ring
    again = lsys3d.Grammar.from_text(grammar_text(grammar), source="ring.toml")
    assert again.ring and str(lsys3d.derive(again)) == str(lsys3d.derive(grammar))
    with pytest.raises(lsys3d.GrammarError, match="'ring' must be true or false"):
        lsys3d.Grammar(axiom="A", ring=1)
