"""An engine's C++ warnings are kept, not printed: DART's Inertia warns on stderr (file
descriptor 2, past Python) for a principal moment that is not > 0, a thin rod about its axis,
as every bar of a planar linkage is; `redysim compare` on Jansen's leg printed ten such lines.
The adapter keeps them (its manifest, compare's notes) and the terminal stays quiet."""

from __future__ import annotations

from pathlib import Path

import pytest

from redysim import load_linkage
from redysim.references.base import build_warnings

REPO = Path(__file__).resolve().parents[1]


@pytest.mark.engine
def test_dart_keeps_its_inertia_warnings(capfd):
    pytest.importorskip("dartpy")
    from redysim import references

    tree = load_linkage(REPO / "cases" / "loops" / "jansen_leg.toml").model.with_cuts(())
    # the fixture's premise: some body has a zero principal moment (independent of DART)
    assert (tree.inertia_com[:, 0, 0] <= 0).any() or (tree.inertia_com[:, 1, 1] <= 0).any() \
        or (tree.inertia_com[:, 2, 2] <= 0).any()
    capfd.readouterr()
    eng = references.get("dart")(tree)
    said = capfd.readouterr()
    assert "Inertia" not in said.err and "Inertia" not in said.out
    kept = build_warnings(eng)
    assert "Inertia::verifyMoment" in kept and "bodies)" in kept
    assert eng.manifest()["dart_warnings"] == kept
