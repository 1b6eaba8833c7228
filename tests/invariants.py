"""Invariants the property tests check, written independently of the code under test."""

from __future__ import annotations


def balanced(symbols: str) -> bool:
    """Every ``]`` closes an earlier ``[`` and every ``[`` is closed."""
    depth = 0
    for c in symbols:
        depth += {"[": 1, "]": -1}.get(c, 0)
        if depth < 0:
            return False
    return depth == 0
