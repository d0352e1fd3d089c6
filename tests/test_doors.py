"""The door (redysim.model.door): every public function and method that takes a model, a state
or a vector checks it before compiled code reads it (docs/design.md, "Checked at the door").

First the families a hold-out battery found, one test each (each failed before the door):
vectors of the wrong length read past their end (the loops' methods, Model.couple), a
non-Model reaching the user as AttributeError, an unaligned vector after a big-endian one
refused with numba's own message, messages that did not say what to do, and numba internals
relied on without naming the versions known. Then the property over the public API
(Hypothesis, a fixed seed): any argument of any shape, dtype, byte order, stride, alignment,
length or value gives the documented answer (the same call's on a clean float64 copy) or a
named error raised by redysim's own code, never another exception and never a read past an
array. Budget: PROPERTY_EXAMPLES examples per test, derandomized; ~15 s in all on one core.
"""

from __future__ import annotations

import os
import pickle
import subprocess
import sys
import traceback
from pathlib import Path

import numpy as np
import pytest
from engine_chains import engine_or_skip
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import redysim
from redysim import Chain, StateError
from redysim.algorithms.linkages import four_bar
from redysim.errors import CaseError, RedysimError
from redysim.integrators.explicit import integrate

REPO = Path(__file__).resolve().parents[1]
SETTINGS = dict(deadline=None, derandomize=True, database=None,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large])
PROPERTY_EXAMPLES = 60


@pytest.fixture(scope="module")
def chain():
    return Chain.uniform(3, "R", mass=1.0)


@pytest.fixture(scope="module")
def crank_rocker():
    fb = four_bar(0.3, 0.1, 0.35, 0.3, rp=0.2, gamma=0.4, density=2.0)
    return fb.loops, fb.configuration(0.3)


def unaligned(values) -> np.ndarray:
    """A float64 view of ``values`` one byte into a buffer: not aligned."""
    values = np.asarray(values, dtype=float)
    buf = np.zeros(values.size * 8 + 1, dtype=np.uint8)
    view = buf[1:].view(np.float64)
    view[:] = values
    assert not view.flags.aligned or not values.size  # (an empty view counts as aligned)
    return view


# --------------------------------------------------------------------------- the families
def test_the_loops_methods_and_couple_refuse_a_vector_of_another_length(crank_rocker):
    loops, q0 = crank_rocker
    with pytest.raises(StateError, match=r"v has shape \(1,\).*must have shape \(3,\)"):
        loops.project(q0, np.zeros(1))
    with pytest.raises(StateError, match=r"q has shape \(1,\).*must have shape \(3,\)"):
        loops.residuals(q0[:1], np.zeros(3))  # a view: its neighbours were read
    with pytest.raises(StateError, match=r"q has shape \(2,\)"):
        loops.cut_points(q0[:2])
    five = Chain.uniform(5, "R", mass=1.0)
    with pytest.raises(StateError, match=r"q has shape \(3,\).*must have shape \(5,\)"):
        five.couple(np.zeros(3), np.zeros(5))
    with pytest.raises(StateError, match=r"v has shape \(4,\)"):
        five.couple(np.zeros(5), np.zeros(4))


class NotAModel:
    n_q = n_v = 3  # (even what looks like one)


@pytest.mark.parametrize("name, args", [
    ("forward_dynamics", 2), ("inverse_dynamics", 3), ("phi", 2), ("mass_matrix", 1),
    ("udu_factors", 1), ("energy", 2), ("momentum", 2), ("generalized_momentum", 2),
    ("joint_positions", 1), ("tip", 2), ("evaluator", 0), ("simulate", None)])
def test_a_non_model_is_a_type_error_naming_the_call(name, args):
    f = getattr(redysim, name)
    for thing in (NotAModel(), "rope", None, np.zeros(3)):
        call = ((lambda thing=thing: f(thing, 1.0)) if args is None else
                (lambda thing=thing: f(thing, *[np.zeros(3)] * args)))
        # a TypeError and a CaseError (redysim.errors.ModelTypeError) naming the call
        with pytest.raises(TypeError, match=rf"^{name}: model = .*must be a redysim.Model"):
            call()
        with pytest.raises(CaseError):
            call()
    with pytest.raises(TypeError, match="frame_motion: model = .*must be a redysim.Model"):
        redysim.frame_motion(NotAModel(), np.zeros(3), np.zeros(3), frame="tip")
    with pytest.raises(TypeError, match="ClosedLoops: model = .*must be a redysim.Model"):
        redysim.ClosedLoops(NotAModel(), [], source="ClosedLoops")


def test_unaligned_and_big_endian_vectors_are_converted_or_refused_by_name(chain):
    q = np.array([0.1, -0.2, 0.3])
    v = np.array([0.5, 0.0, -1.0])
    want = redysim.forward_dynamics(chain, q, v)
    # a big-endian call first, then unaligned ones (the sequence that reached numba's dispatch)
    assert np.array_equal(redysim.forward_dynamics(chain, q.astype(">f8"), v), want)
    assert np.array_equal(redysim.forward_dynamics(chain, unaligned(q), unaligned(v)), want)
    fd = redysim.evaluator(chain)
    assert np.array_equal(fd(q.astype(">f8"), v), want)
    assert np.array_equal(fd(unaligned(q), v), want)
    with pytest.raises(StateError, match=r"out \(.*aligned False.*must be a writeable, aligned"):
        redysim.forward_dynamics(chain, q, v, out=unaligned(np.zeros(3)))
    tau = redysim.inverse_dynamics(chain, q, v, want)
    assert np.array_equal(redysim.inverse_dynamics(chain, unaligned(q), v.astype(">f8"),
                                                   unaligned(want)), tau)
    batch = redysim.forward_dynamics(chain, np.tile(q, (3, 1)).astype(">f8"),
                                     np.tile(v, (3, 1)), simd=False)
    assert np.array_equal(batch, np.tile(want, (3, 1)))


def test_messages_say_what_to_do(chain):
    fd = redysim.evaluator(chain)
    with pytest.raises(TypeError, match="evaluators are per process: make one in each"):
        pickle.dumps(fd)
    with pytest.raises(StateError, match=r"delta_M: E0 = '1.0': must be a number"):
        redysim.delta_M(chain, np.zeros(3), np.zeros(3), "1.0")
    with pytest.raises(StateError, match=r"rhs\(t0, y0\) has shape \(3,\); y0 has shape \(2,\)"):
        integrate(lambda t, y: np.zeros(3), (0.0, 1.0), np.zeros(2))


@pytest.mark.engine
def test_two_hinges_on_one_axis_are_named_both(tmp_path):
    """Two hinges of one MJCF body with the same axis and anchor: the error names both (the
    second one as the field), not the massless body the importer puts between them."""
    pytest.importorskip("mujoco")
    from redysim.io.importers import ModelFileError, load_mjcf

    path = tmp_path / "twohinge.xml"
    path.write_text("""<mujoco model="twohinge"><worldbody>
      <body name="armL" pos="0 0 1">
        <joint name="l1" type="hinge" axis="0 1 0" pos="0.1 0 0"/>
        <joint name="l2" type="hinge" axis="0 -1 0" pos="0.1 0 0"/>
        <geom type="capsule" fromto="0 0 0 0.5 0 0" size="0.05"/>
      </body></worldbody></mujoco>""")
    with pytest.raises(ModelFileError, match=r"joint 'l2': moves along the same axis through "
                       r"the same point as joint 'l1'") as err:
        load_mjcf(path)
    assert "armL_l1" not in str(err.value)


ROPE = """[case]
name = "rope"
description = "a straight rope released at an angle"
[chain]
links = {links}
joint = "U"
total_length = 1.0
density = 7850.0
radius = 0.01
inertia = "rod"
[initial]
q = {q}
v = {v}
[simulation]
t_end = 0.1
"""


def test_a_straight_rope_given_as_lists_rebuilds_at_any_count(tmp_path):
    """A straight rope whose file lists its initial angles (the first joint's nonzero) rebuilt
    at a count that does not divide its own (12 -> 5; `--links 5`): the rope a file with 5
    links and the same first-joint state gives (before: "must be a list of 5 numbers, got
    shape (24,)")."""
    from redysim.io.cases import load_case, rebuilt_case

    def rope(links, name):
        q, v = [0.0] * (2 * links), [0.0] * (2 * links)
        q[0], q[1], v[1] = 0.3, -0.1, 0.5
        path = tmp_path / name
        path.write_text(ROPE.format(links=links, q=q, v=v))
        return load_case(path)

    rebuilt = rebuilt_case(rope(12, "rope12.toml"), 5)
    direct = rope(5, "rope5.toml")
    assert np.array_equal(rebuilt.q0, direct.q0) and np.array_equal(rebuilt.v0, direct.v0)
    assert np.array_equal(rebuilt.chain.length, direct.chain.length)
    assert np.array_equal(rebuilt.chain.mass, direct.chain.mass)


def test_an_unknown_numba_is_named_at_import_and_its_internals_left_alone(tmp_path):
    """A numba of another minor version: a warning naming it, no dispatch bypass, no lean
    entries (so no evaluator builtin), tiles without the noalias option; nothing compiled."""
    code = ("import warnings, numba\nnumba.__version__ = '0.99.0'\n"
            "with warnings.catch_warnings(record=True) as w:\n"
            "    warnings.simplefilter('always')\n"
            "    from redysim import _jit\n"
            "    from redysim.algorithms._kernels import lean, binding\n"
            "print([str(x.message) for x in w if 'numba 0.99.0' in str(x.message)][0])\n"
            "assert not _jit.INTERNALS_OK and not _jit.NOALIAS\n"
            "assert 'noalias' not in _jit.TILE_OPTIONS\n"
            "assert not lean.NUMPY_LAYOUT_OK and not binding.BINDING_OK\n"
            "assert _jit.unchecked_call(numba.njit('f8(f8)')(lambda x: x)) is None\n")
    # the redysim this process imported, from anywhere (not the checkout the cwd would give)
    env = {**os.environ, "PYTHONPATH": str(Path(redysim.__file__).resolve().parents[1])}
    run = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         cwd=tmp_path, env=env, timeout=300)
    assert run.returncode == 0, run.stderr
    assert "0.68" in run.stdout and "internals" in run.stdout


# --------------------------------------------------------------------------- the property
def _vector_like(draw, n: int):
    """An argument where a vector of n values is taken: of any length, dtype, byte order,
    stride, alignment and values, or not a vector at all."""
    kind = draw(st.sampled_from(["contiguous", "float32", "int", ">f8", "strided", "unaligned",
                                 "readonly", "2d", "list", "subclass", "other"]))
    if kind == "other":
        return draw(st.sampled_from([None, "1.0", 1.0, object(), NotAModel(), [[1.0], [2.0, 3.0]],
                                     np.array(["a"] * n), np.zeros(n, dtype=complex),
                                     np.zeros(n, dtype=bool)]))
    length = draw(st.sampled_from([n, n, n, n - 1, n + 1, 0]))
    value = st.one_of(st.floats(-2.0, 2.0), st.sampled_from([0.0, np.nan, np.inf, -np.inf,
                                                             1e300, -1e300, 5e-324]))
    values = np.array(draw(st.lists(value, min_size=length, max_size=length)), dtype=float)
    if kind == "float32":
        with np.errstate(over="ignore"):  # (1e300 becomes inf)
            return values.astype(np.float32)
    if kind == "int":
        return np.nan_to_num(values, posinf=3.0, neginf=-3.0).clip(-3, 3).astype(np.int64)
    if kind == ">f8":
        return values.astype(">f8")
    if kind == "strided":
        wide = np.full(2 * length, 7.0)
        wide[::2] = values
        return wide[::2]
    if kind == "unaligned":
        return unaligned(values)
    if kind == "readonly":
        values.flags.writeable = False
        return values
    if kind == "2d":
        return values[None, :]
    if kind == "list":
        return values.tolist()
    if kind == "subclass":
        return values.view(np.ma.MaskedArray if draw(st.booleans()) else np.recarray)
    return values


def _clean(x):
    """What the call on a clean copy gets: a contiguous float64 copy of a numeric array."""
    try:
        arr = np.asarray(x)
    except (TypeError, ValueError):
        return x
    if arr.dtype.kind not in "iuf" or isinstance(x, np.matrix):
        return x
    return np.array(arr, dtype=np.float64)


PACKAGE = str(REPO / "redysim")


def _outcome(call):
    """("ok", result) or ("error", exception); any exception not raised on purpose by
    redysim's own code (a numba dispatch error, an AttributeError, a broadcast error) fails."""
    try:
        return "ok", call()
    except Exception as exc:  # noqa: BLE001 (the property: which exception)
        where = traceback.extract_tb(exc.__traceback__)[-1].filename
        ours = where.startswith(PACKAGE) and "_kernels" not in where
        named = isinstance(exc, RedysimError) or (isinstance(exc, TypeError | ValueError)
                                                  and ours)
        assert named, f"{type(exc).__name__} from {where}: {exc}"
        return "error", exc


def _same(a, b) -> bool:
    if isinstance(a, tuple):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b, strict=True))
    if isinstance(a, list):
        return all(_same(x, y) for x, y in zip(a, b, strict=True))
    return np.array_equal(np.asarray(a), np.asarray(b), equal_nan=True)


def _check(call, args):
    """The property for ``call(*args)`` against ``call(*clean args)``."""
    messy = _outcome(lambda: call(*args))
    clean = _outcome(lambda: call(*[_clean(a) for a in args]))
    if messy[0] == "ok":
        assert clean[0] == "ok", f"answered {messy[1]!r} where the clean copy raised {clean[1]}"
        assert _same(messy[1], clean[1])
    elif clean[0] == "ok":  # refused what converts: only for what is not numeric floats
        assert isinstance(messy[1], StateError | TypeError | ValueError)


FUNCTIONS = {  # name -> (call(model, *vectors), number of vectors: each q then n_v long)
    "forward_dynamics": (lambda m, q, v, t: redysim.forward_dynamics(m, q, v, t), 3),
    "forward_dynamics(out=)": (lambda m, q, v, o: redysim.forward_dynamics(m, q, v, out=o), 3),
    "inverse_dynamics": (redysim.inverse_dynamics, 3),
    "phi": (redysim.phi, 3),
    "mass_matrix": (redysim.mass_matrix, 1),
    "udu_factors": (lambda m, q: tuple(redysim.udu_factors(m, q)), 1),
    "energy": (redysim.energy, 2),
    "delta_M": (lambda m, q, v: redysim.delta_M(m, q, v, 0.5), 2),
    "momentum": (lambda m, q, v: tuple(redysim.momentum(m, q, v)), 2),
    "generalized_momentum": (redysim.generalized_momentum, 2),
    "frame_motion": (lambda m, q, v, a: tuple(redysim.frame_motion(m, q, v, a, frame="tip")), 3),
    "joint_positions": (redysim.joint_positions, 1),
    "couple": (lambda m, q, v: m.couple(q, v), 2),
}


@settings(max_examples=PROPERTY_EXAMPLES, **SETTINGS)
@given(data=st.data(), name=st.sampled_from(sorted(FUNCTIONS)))
def test_any_argument_gets_the_answer_or_a_named_error(chain, data, name):
    call, count = FUNCTIONS[name]
    model = chain if name == "couple" or data.draw(st.integers(0, 9)) else data.draw(
        st.sampled_from([NotAModel(), None, "chain", np.zeros(3)]))  # (couple: a method)
    vectors = [_vector_like(data.draw, 3) for _ in range(count)]
    _check(lambda m, *xs: call(m, *xs), [model, *vectors])


@settings(max_examples=PROPERTY_EXAMPLES, **SETTINGS)
@given(data=st.data(), kind=st.sampled_from(["forward_dynamics", "inverse_dynamics"]))
def test_an_evaluator_takes_any_argument_as_its_public_function(chain, data, kind):
    f = redysim.evaluator(chain, kind)
    vectors = [_vector_like(data.draw, 3) for _ in range(3)]
    if data.draw(st.booleans()):  # out=, as given: only a plain vector is written into
        out = _vector_like(data.draw, 3)
        messy = _outcome(lambda: f(*vectors, out=out))
        if messy[0] == "ok":
            assert messy[1] is out
            assert _same(out, f(*[_clean(x) for x in vectors]))
        return
    _check(f, vectors)


LOOP_METHODS = {
    "forward_dynamics": (lambda lp, q, v, t: lp.forward_dynamics(q, v, t), 3),
    "residuals": (lambda lp, q, v: lp.residuals(q, v), 2),
    "project": (lambda lp, q, v: lp.project(q, v), 2),
    "evaluate": (lambda lp, q, v: lp.evaluate(q, v), 2),
    "cut_points": (lambda lp, q: lp.cut_points(q), 1),
    "check_start": (lambda lp, q: lp.check_start(q), 1),
}


@settings(max_examples=PROPERTY_EXAMPLES, **SETTINGS)
@given(data=st.data(), name=st.sampled_from(sorted(LOOP_METHODS)))
def test_the_loops_take_any_argument_to_the_answer_or_a_named_error(crank_rocker, data, name):
    loops, q0 = crank_rocker
    call, count = LOOP_METHODS[name]
    vectors = [_vector_like(data.draw, 3) for _ in range(count)]
    if data.draw(st.booleans()) and isinstance(vectors[0], np.ndarray) \
            and vectors[0].shape == (3,) and vectors[0].dtype.kind == "f":
        vectors[0] = (q0 + 1e-3 * np.nan_to_num(vectors[0].astype(float), posinf=0,
                                                neginf=0).clip(-1, 1)).astype(vectors[0].dtype)
    _check(lambda *xs: call(loops, *xs), vectors)


# --------------------------------------------------------------------------- battery 4: API doors
def test_battery4_arguments_are_refused_at_the_door_by_name(chain):
    """Each of these reached the user as a raw TypeError, ValueError or AttributeError from
    deep inside, or only at run time (hold-out battery 4, family API-DOOR)."""
    from redysim import Coupling, Simulator, System
    from redysim.errors import FieldError, ModelTypeError, SettingsError

    q = np.zeros(3)
    with pytest.raises(ModelTypeError, match="^passive_forces: model"):
        redysim.passive_forces("x", q, q)
    with pytest.raises(FieldError, match="method = 'rgea': unknown"):
        redysim.forward_dynamics(chain, q, q, method="rgea")
    with pytest.raises(FieldError, match="batches run 'rge-a' only"):
        redysim.forward_dynamics(chain, np.zeros((2, 3)), np.zeros((2, 3)), method="ge-n")
    with pytest.raises(FieldError, match="^eliminate: method = 'foo'"):
        redysim.eliminate(np.eye(2), np.ones(2), "foo")
    cases = [
        (lambda: Simulator(chain, 0.01, integrator=5), "integrator = 5"),
        (lambda: Simulator(chain, 0.01, state={"a": 1}), "state = 'dict'"),
        (lambda: Simulator(chain, 0.01, observe={"x": 5}), r"observe\['x'\] = 5"),
        (lambda: Simulator(chain, 0.01, observe=[1]), "observe = 'list'"),
        (lambda: System(chain, tau=5), "tau = 5"),
        (lambda: System(chain, qdd=3), "qdd = 3"),
        (lambda: System(chain, method="foo"), "method = 'foo'"),
        (lambda: redysim.simulate(chain, "1"), "t_end = '1'"),
        (lambda: Simulator(chain, 0.01).run(energy_bound=-1), "energy_bound = -1"),
        (lambda: Simulator(chain, 0.01).run(energy_bound=float("nan")), "energy_bound = nan"),
    ]
    for call, match in cases:
        with pytest.raises(SettingsError, match=f"^simulate: {match}"):
            call()
    with pytest.raises(StateError, match=r"provider \(qdd\) returned shape \(2,\)"):
        Simulator(System(chain, qdd=lambda q, v, tau: np.ones(2)), 0.01)
    with pytest.raises(StateError, match=r"provider \(tau\) returned shape \(\)"):
        Simulator(System(chain, tau=lambda t, q, v: 1.0), 0.01)
    with pytest.raises(CaseError, match="couplings = 'int': must be a list of Coupling"):
        chain.with_couplings(5)
    # the hang: refused up front ...
    with pytest.raises(CaseError, match=r"multiplier = 1e\+300: \|multiplier\| must be <="):
        Coupling("j2", "j1", 1e300)
    with pytest.raises(CaseError, match=r"gravcomp\[0\] \(body '.*'\) = 1e\+300: must be <="):
        chain.with_passive(gravcomp=1e300)
    with pytest.raises(SettingsError, match=r"^simulate: gravcomp = 1e\+300: must be <="):
        System(chain, gravcomp=1e300)
    # ... or, for forces of the caller's, a failure once the step falls below t_end's spacing
    res = Simulator(System(chain, tau=lambda t, q, v: np.full(3, 1e200)), 1.0).run()
    assert res.status == -1 and res.message.startswith("step size underflow: h = ")


def test_repeated_names_are_refused_by_model_build():
    from redysim import Body, Model, TreeJoint

    bodies = [Body("a", 1.0), Body("a", 1.0)]
    joints = [TreeJoint("j1", "R"), TreeJoint("j2", "R", "z", None, (1, 0, 0))]
    with pytest.raises(CaseError, match=r"body 'a' \(bodies\[1\]\)\.name = 'a': repeats the "
                                        r"name of bodies\[0\]"):
        Model.build(bodies, joints, [-1, 0])
    bodies[1], joints[1] = Body("b", 1.0), TreeJoint("j1", "R", "z", None, (1, 0, 0))
    with pytest.raises(CaseError, match=r"joint 'j1' \(joints\[1\]\)\.name = 'j1': repeats"):
        Model.build(bodies, joints, [-1, 0])


def test_a_workspace_of_an_equal_model_says_it_is_another_object(chain):
    twin = Chain.uniform(3, "R", mass=1.0)
    assert repr(twin) == repr(chain)
    with pytest.raises(redysim.errors.FieldError, match="another Model object with the same "
                                                        "description"):
        redysim.forward_dynamics(chain, np.zeros(3), np.zeros(3), ws=redysim.Workspace(twin))
    other = Chain.uniform(4, "R", mass=1.0)
    with pytest.raises(redysim.errors.FieldError, match="was made for another chain than"):
        redysim.forward_dynamics(chain, np.zeros(3), np.zeros(3), ws=redysim.Workspace(other))


ANYTHING = st.one_of(st.none(), st.integers(-3, 3), st.floats(allow_nan=True), st.text(max_size=3),
                     st.booleans(), st.lists(st.integers(0, 2), max_size=3),
                     st.dictionaries(st.text(max_size=2), st.integers(0, 2), max_size=2),
                     st.just(np.zeros(3)), st.just(lambda *a: np.zeros(3)))
SIMULATOR_ARGUMENTS = {  # name -> the valid value a drawn one replaces
    "integrator": "ode45", "state": None, "observe": None, "tau": None, "qdd": None,
    "method": "rge-a", "t_end": 0.002, "sample": None}


@settings(max_examples=PROPERTY_EXAMPLES, **SETTINGS)
@given(data=st.data(), name=st.sampled_from(sorted(SIMULATOR_ARGUMENTS)))
def test_a_run_takes_any_argument_to_a_result_or_a_named_error(chain, data, name):
    """System's, Simulator's and simulate's arguments: any value runs or is refused by
    redysim's own code, named (never an AttributeError or a TypeError from inside)."""
    from redysim import Simulator, System

    given = dict(SIMULATOR_ARGUMENTS, **{name: data.draw(ANYTHING)})
    t_end = given.pop("t_end")
    system = {k: given.pop(k) for k in ("tau", "qdd", "method")}
    kind, out = _outcome(lambda: Simulator(System(chain, **system), t_end, **given).run())
    if kind == "error":
        assert isinstance(out, RedysimError), f"{type(out).__name__}: {out}"


def test_numbers_that_pass_any_check_are_refused(chain, crank_rocker):
    """delta_M(E0=nan) answered NaN, check_start(q, nan) passed any q (battery 4)."""
    loops, q = crank_rocker
    with pytest.raises(StateError, match="^delta_M: E0 = nan: must be a finite number"):
        redysim.delta_M(chain, np.zeros(3), np.zeros(3), float("nan"))
    for tol in (float("nan"), -1e-6):
        with pytest.raises(StateError, match="^check_start: tol = .*: must be >= 0"):
            loops.check_start(q, tol)
    with pytest.raises(StateError, match="violates the cut joint"):
        loops.check_start(np.asarray(q) + 0.1, 1e-6)


def test_a_float32_state_of_a_coupled_model_is_checked_at_its_own_precision(chain):
    """Refused over 6e-9 of float32 roundoff before; the answer is the float64 copy's."""
    from redysim import Coupling

    m = Chain.uniform(3, "R", mass=1.0).with_couplings([Coupling("joint2", "joint1", 0.3)])
    q = np.array([0.7, 0.21, 0.1], dtype=np.float32)
    v = np.array([0.3, 0.09, 0.0], dtype=np.float32)
    assert abs(float(q[1]) - 0.3 * float(q[0])) > 1e-9 * 1.21  # off by float32's roundoff
    got = redysim.forward_dynamics(m, q, v)
    with pytest.raises(StateError, match="joint 'joint2', follows joint 'joint1'"):
        redysim.forward_dynamics(m, q.astype(float), v.astype(float))  # float64: its own tol
    # the same state made exact in float64 gives the same accelerations to float32's roundoff
    q64, v64 = m.couple(q.astype(float), v.astype(float))
    assert np.allclose(got, redysim.forward_dynamics(m, q64, v64), rtol=1e-5, atol=1e-5)
    with pytest.raises(StateError, match="joint 'joint2'"):  # off by more: still refused
        redysim.forward_dynamics(m, q + np.float32([0, 1e-3, 0]), v)


def test_simulate_with_too_many_links_is_bad_input_not_a_failed_run(capsys):
    """`simulate RE-U125-L1 --links 100000000` exited 1 ("run failed") after the rebuild was
    refused; it is a bad flag: exit 2, naming it, before any run."""
    from redysim.harness.cli import main

    assert main(["simulate", "RE-U125-L1", "--t-end", "0.01", "--links", "100000000"]) == 2
    err = capsys.readouterr().err
    assert "--links = 100000000: must be at most 2,000,000 links" in err and "run failed" not in err


def _small_tree():
    """A tree of R z, P x and U joints (battery 5's): q[1] is a prismatic length in metres."""
    from redysim import Body, Model, TreeJoint

    inertia = ((0.02, 0.001, 0.0), (0.001, 0.03, 0.002), (0.0, 0.002, 0.025))
    bodies = [Body("a", 1.0, (0.1, 0.02, 0.0), inertia), Body("b", 0.7, (0.2, 0.0, 0.01), inertia),
              Body("c", 0.5, (0.05, 0.03, 0.02), inertia)]
    joints = [TreeJoint("j1", "R", "z"), TreeJoint("j2", "P", "x", translation=(0.3, 0, 0)),
              TreeJoint("j3", "U", translation=(0.4, 0.0, 0.1))]
    return Model.build(bodies, joints, [-1, 0, 1], name="small")


@pytest.mark.parametrize("q", [[0.1, 1e160, 0.2, 0.3], [1e300] * 4])
def test_mass_matrix_and_factors_of_an_overflowing_state_are_refused(q):
    """Battery 5 (F1): a prismatic joint at 1e160 m gave M[0, 0] = NaN and D[0, 0] = NaN
    silently, where energy and the dynamics refused the same finite q as an overflow."""
    m = _small_tree()
    with pytest.raises(StateError, match="^qdd is"):
        redysim.forward_dynamics(m, q, np.zeros(m.n_v))  # the other doors refuse it
    with pytest.raises(StateError, match="mass matrix is not finite .*overflow"):
        redysim.mass_matrix(m, q)
    with pytest.raises(StateError, match="not finite .*overflow"):
        redysim.udu_factors(m, q)
    assert np.isfinite(redysim.mass_matrix(m, [0.1, 1e3, 0.2, 0.3])).all()  # large but fine


def _coupled_rr():
    """Battery 5's coupled model (j4 follows j1) and a batch of 20 states on its coupling."""
    from redysim import Body, Coupling, Model, TreeJoint

    inertia = ((0.02, 0.001, 0.0), (0.001, 0.03, 0.002), (0.0, 0.002, 0.025))
    bodies = [Body(f"b{i}", 0.5 + 0.2 * i, (0.1, 0.02 * i, 0.01), inertia) for i in range(4)]
    joints = [TreeJoint("j1", "R", "z"), TreeJoint("j2", "R", "y", translation=(0.3, 0, 0)),
              TreeJoint("j3", "P", "x", translation=(0.3, 0.0, 0.1)),
              TreeJoint("j4", "R", (0.0, 0.6, 0.8), translation=(0.2, 0.1, 0))]
    m = Model.build(bodies, joints, [-1, 0, 1, 2], name="rr").with_couplings(
        [Coupling("j4", "j1", 0.5, 0.1)])
    rng = np.random.default_rng(55)
    rows = [m.couple(rng.uniform(-1, 1, 4), rng.uniform(-1, 1, 4)) for _ in range(20)]
    return m, np.array([r[0] for r in rows]), np.array([r[1] for r in rows])


def test_a_coupled_batch_refuses_a_wrong_out_as_an_uncoupled_one_does():
    """Battery 5 (F14): out of 19 rows or flat gave numpy's broadcast error for a coupled model;
    the uncoupled model's refusal by name, the same for both."""
    m, Q, V = _coupled_rr()
    for out in (np.empty((19, 4)), np.empty(80), np.empty((20, 4), dtype=np.float32),
                np.empty((4, 20)).T, [[0.0] * 4] * 20):
        for model in (m, m.tree):
            with pytest.raises(StateError, match=r"^out \(.*must be a writeable, C-contiguous "
                                                 r"float64 array of shape \(20, 4\)"):
                redysim.forward_dynamics(model, Q, V, out=out)
        with pytest.raises(StateError, match=r"shape \(20, 4\)"):  # the checked path too
            redysim.forward_dynamics(m, Q.tolist(), V, out=out)
    out = np.empty((20, 4))
    assert redysim.forward_dynamics(m, Q, V, out=out) is out
    assert np.array_equal(out[3], redysim.forward_dynamics(m, Q[3], V[3]))


@pytest.mark.parametrize("simd", [True, False])
def test_a_float32_batch_of_a_coupled_model_is_held_to_float32s_roundoff(simd):
    """Battery 5 (F13): the single float32 call was accepted, its batch refused over 2e-9 of
    float32 roundoff; a batch's row is now the single call's, bit for bit."""
    m, Q, V = _coupled_rr()
    Q32, V32 = Q.astype(np.float32), V.astype(np.float32)
    got = redysim.forward_dynamics(m, Q32, V32, simd=simd)
    for i in (0, 7, 19):
        assert np.array_equal(got[i], redysim.forward_dynamics(m, Q32[i], V32[i]))
    assert np.allclose(got, redysim.forward_dynamics(m, Q, V), rtol=1e-4, atol=1e-4)
    with pytest.raises(StateError, match="^state 0 of the batch.*joint 'j4', follows joint 'j1'"):
        redysim.forward_dynamics(m, Q32 + np.float32([0, 0, 0, 1e-3]), V32)  # off by more
    with pytest.raises(StateError, match="^state 0 of the batch.*joint 'j4'"):
        redysim.forward_dynamics(m, Q32.astype(float), V32.astype(float))  # float64's own tol


def test_battery5_arguments_are_refused_by_name(tmp_path):
    """Battery 5 (F3, F4): System's body_forces, load_model's path and a robot's name given to
    load_linkage reached the user as TypeError or FileNotFoundError from deep inside."""
    from redysim import System
    from redysim.errors import SettingsError

    m = _small_tree()
    for bad in (5, "a", {"a": 1}):
        with pytest.raises(SettingsError, match=r"body_forces = .*must be a list of \(body name"):
            System(m, body_forces=bad)
    system = System(m, body_forces=[("b", (0.0, 0.0, 1.0), (0.0, 0.0, 0.0))])  # (still taken)
    assert system.body.tolist() == [1]
    for bad in (5, None, 1.5, True):
        with pytest.raises(CaseError, match=r"^load_model: path( = .*)?: must be the path"):
            redysim.load_model(bad)
    with pytest.raises(CaseError, match="load_linkage: path = 'example-robot-data:ur5': is a "
                                        "robot's name.*redysim.load_model"):
        redysim.load_linkage("example-robot-data:ur5")


# --------------------------------------------------------------------------- hold-out battery 6
def test_battery6_integrate_refuses_a_step_that_would_not_end_and_a_callback_not_callable():
    """integrate(..., "rk4", h=1e-12) over 2 s started 2e12 steps (simulate refused it by name);
    callback=3 was a bare TypeError from inside the run."""
    from redysim.errors import SettingsError

    def rhs(t, y):
        return np.array([y[1], -y[0]])

    with pytest.raises(SettingsError, match=r"h = 1e-12: gives 2e\+12 steps over t_span = "
                                            r"\(0, 2\); at most 100,000,000"):
        integrate(rhs, (0.0, 2.0), np.array([1.0, 0.0]), "rk4", h=1e-12)
    with pytest.raises(SettingsError, match=r"callback = 3: must be a function"):
        integrate(rhs, (0.0, 1.0), np.array([1.0, 0.0]), callback=3)


def _cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", *args], cwd=cwd, capture_output=True,
                          text=True, timeout=600, env={**os.environ,
                                                       "REDYSIM_RESULTS": str(cwd)})


def test_battery6_longrun_refuses_h_with_an_adaptive_integrator_and_a_robot_file(tmp_path):
    """longrun --h with ode45 was ignored (simulate refuses it); a URDF given to longrun was
    read as TOML ("Invalid statement")."""
    res = _cli("redysim.harness.longrun", "STUDY-R3", "--t-end", "0.2", "--h", "0.01",
               "--out", str(tmp_path / "a"), cwd=tmp_path)
    assert res.returncode == 2 and "--h = 0.01: is the step of a fixed-step integrator" \
        in res.stderr, res.stderr
    urdf = tmp_path / "arm.urdf"
    urdf.write_text("<robot name='r'/>")
    res = _cli("redysim.harness.longrun", str(urdf), "--t-end", "0.2", "--out",
               str(tmp_path / "b"), cwd=tmp_path)
    assert res.returncode == 2 and "a .urdf robot file: long runs take rope cases" \
        in res.stderr, res.stderr
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


@pytest.mark.engine
def test_battery6_simulate_out_of_a_run_that_failed_before_its_first_sample(tmp_path):
    """simulate --out of a robot run refused by its engine before any sample: an IndexError
    traceback and no file; now the failed run's record is written and the exit code says it
    failed."""
    engine_or_skip("pinocchio-aba")
    urdf = tmp_path / "mimic.urdf"
    link = ('<link name="{}"><inertial><mass value="1"/><origin xyz="0.1 0 0"/><inertia '
            'ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial></link>')
    urdf.write_text(
        "<robot name='m'>" + "".join(link.format(n) for n in ("base", "a", "b"))
        + '<joint name="ja" type="revolute"><parent link="base"/><child link="a"/>'
          '<axis xyz="0 0 1"/></joint><joint name="jb" type="revolute"><parent link="a"/>'
          '<child link="b"/><origin xyz="0.2 0 0"/><axis xyz="0 0 1"/>'
          '<mimic joint="ja" multiplier="-0.5"/></joint></robot>')
    out = tmp_path / "r.csv"
    res = subprocess.run([str(Path(sys.executable).with_name("redysim")), "simulate", str(urdf),
                          "--engine", "pinocchio-aba", "--t-end", "0.1", "--out", str(out)],
                         cwd=tmp_path, capture_output=True, text=True, timeout=600)
    assert res.returncode == 1 and "Traceback" not in res.stderr, res.stderr
    assert "refused by the engine" in res.stderr
    assert out.is_file() and out.with_suffix(".summary.csv").is_file()


@pytest.mark.parametrize("answer, says", [
    (np.array([1j, 0, 0]), r"returned array\(\[0\.\+1\.j.*; it must return 3 real numbers"),
    ("x", r"returned 'x'; it must return 3 real numbers"),
    (None, r"returned shape \(\)")])
def test_battery6_a_tau_that_is_not_real_numbers_is_named(chain, answer, says):
    """A System's tau returning complex numbers ran with their imaginary part dropped (NumPy's
    warning only); one returning a string was a bare ValueError naming nothing."""
    system = redysim.System(chain, tau=lambda t, q, v: answer)
    with pytest.raises(StateError, match=r"the joint forces' provider \(tau\) " + says):
        redysim.Simulator(system, 0.1).run()
