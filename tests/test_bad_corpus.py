"""The bad-input corpus (tests/bad_inputs/): every malformed case file and bad state is refused at
the door with an error that names the file, the field and the value (never a traceback from
deeper down, never a silent wrong result, never a hang)."""

from __future__ import annotations

import math
import time
import tomllib
from pathlib import Path

import numpy as np
import pytest

from redysim import (
    CaseError,
    Chain,
    StateError,
    energy,
    forward_dynamics,
    inverse_dynamics,
    load_case,
    mass_matrix,
    phi,
    tip,
)
from redysim.harness.run import execute
from redysim.harness.spec import RunSpec

CORPUS = Path(__file__).with_name("bad_inputs")
CASE_FILES = sorted((CORPUS / "cases").glob("*.toml"))
STATES = tomllib.loads((CORPUS / "states.toml").read_text())
EXPECT_PREFIX = "# expect:"
EXPECT_SEPARATOR = " | "
NO_VALUE = "-"
MIN_CASE_FILES = 30
DOOR_SECONDS = 5.0  # refusing a file takes milliseconds; seconds would mean work past the door

# The public functions and the arguments each takes (the others are zeros).
FUNCTIONS = {
    forward_dynamics: ("q", "v", "tau"),
    inverse_dynamics: ("q", "v", "qdd"),
    phi: ("q", "v", "tau"),
    energy: ("q", "v"),
    tip: ("q", "v", "qdd"),
    mass_matrix: ("q",),
}


def expectation(path: Path) -> tuple[str, str | None, str]:
    """(field, value text or None, message fragment) from the file's first line."""
    first = path.read_bytes().split(b"\n", 1)[0].decode("ascii")
    assert first.startswith(EXPECT_PREFIX), f"{path.name}: first line must be '{EXPECT_PREFIX} ...'"
    field, value, fragment = (x.strip() for x in
                              first[len(EXPECT_PREFIX):].split(EXPECT_SEPARATOR))
    return field, None if value == NO_VALUE else value, fragment


def test_the_corpus_is_large_enough():
    assert len(CASE_FILES) >= MIN_CASE_FILES
    assert len(STATES["state"]) >= 10


@pytest.mark.parametrize("path", CASE_FILES, ids=lambda p: p.stem)
def test_bad_case_file_is_refused_with_a_named_error(path):
    field, value, fragment = expectation(path)
    t0 = time.perf_counter()
    with pytest.raises(CaseError) as err:
        load_case(path)
    assert time.perf_counter() - t0 < DOOR_SECONDS
    msg = str(err.value)
    assert err.value.field == field, msg
    assert msg.startswith(f"{path}: {field}"), msg  # the file, then the field
    if value is not None:
        assert value in msg, msg
    assert fragment in msg, msg


@pytest.mark.parametrize("path", CASE_FILES[::7], ids=lambda p: p.stem)
def test_a_run_of_a_bad_case_file_fails_with_the_message(path):
    """execute() does not raise: the run is failed and its reason is the loader's message."""
    field, _, fragment = expectation(path)
    res = execute(RunSpec(case=str(path)), reference=False)
    assert res.summary["status"] == "failed"
    assert res.summary["reason"].startswith(f"CaseError: {path}: {field}")
    assert fragment in res.summary["reason"]


# --------------------------------------------------------------------------- bad states
@pytest.fixture(scope="module")
def chain():
    c = STATES["chain"]
    return Chain.uniform(c["links"], c["joint"], mass=1.0, radius=0.05)


def _call(func, chain, arg, value):
    args = {name: np.zeros(chain.n_dof) for name in FUNCTIONS[func]}
    args[arg] = value
    return func(chain, *(args[name] for name in FUNCTIONS[func]))


def _state_params():
    extra = [{"name": "q None", "arg": "q", "value": None, "expect": ["q is required"]},
             {"name": "v None entries", "arg": "v", "value": [None] * 6,
              "expect": ["v = [None, None", "not a numeric vector", "object"]},
             {"name": "q complex", "arg": "q", "value": np.full(6, 1j),
              "expect": ["q = array(", "not a numeric vector", "complex"]},
             {"name": "q object array", "arg": "q", "value": np.zeros(6, dtype=object),
              "expect": ["not a numeric vector", "object"]}]
    for s in STATES["state"] + extra:
        for func, takes in FUNCTIONS.items():
            if s["arg"] in takes:
                yield pytest.param(s, func, id=f"{s['name']}-{func.__name__}")


@pytest.mark.parametrize("state, func", list(_state_params()))
def test_bad_state_is_refused_naming_the_argument(chain, state, func):
    with pytest.raises(StateError) as err:
        _call(func, chain, state["arg"], state["value"])
    msg = str(err.value)
    for fragment in state["expect"]:
        assert fragment in msg, msg


def test_valid_state_forms_are_still_accepted(chain):
    """The door is not too strict: lists of ints and floats, float32, read-only and strided
    arrays are states."""
    n = chain.n_dof
    ref = forward_dynamics(chain, np.zeros(n), np.zeros(n))
    wide = np.zeros(2 * n)
    readonly = np.zeros(n)
    readonly.flags.writeable = False
    for q in ([0] * n, [0.0] * n, np.zeros(n, np.float32), np.zeros(n, np.int64), wide[::2],
              readonly):
        assert np.array_equal(forward_dynamics(chain, q, np.zeros(n)), ref)


def test_overflowing_state_is_named_not_returned(chain):
    """Finite but absurd rates overflow inside the recursions: every function says so instead of
    returning NaN or inf."""
    n = chain.n_dof
    q, qd = np.zeros(n), np.full(n, 1e200)
    with pytest.raises(StateError, match=r"qdd is not finite for finite q, v \(max \|q\| = 0, "
                                         r"max \|v\| = 1e\+200\): overflow\?"):
        forward_dynamics(chain, q, qd)
    with pytest.raises(StateError, match=r"tau is not finite for finite q, v, qdd \("):
        inverse_dynamics(chain, q, qd, np.zeros(n))
    with pytest.raises(StateError, match=r"phi is not finite for finite q, v \("):
        phi(chain, q, qd)
    with pytest.raises(StateError, match=r"the energy is not finite for finite q, v \("):
        energy(chain, q, qd)
    with pytest.raises(StateError, match=r"tip's motion is not finite for finite q, v, qdd \("):
        tip(chain, q, qd, np.zeros(n))  # the centripetal acceleration w x (w x r) overflows
    assert math.isfinite(energy(chain, q, np.ones(n))[0])
