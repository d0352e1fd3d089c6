"""redysim.evaluator: a model's forward (inverse) dynamics bound once, for the fastest call.

Bit for bit :func:`redysim.forward_dynamics` and :func:`redysim.inverse_dynamics` (its checked
path; its default path for contiguous float64 vectors is the evaluator's entry) on chains (the
serial kernels, and the planar one), trees, a floating robot; ``out`` honoured; what the lean
path does not take (lists, float32, strided arrays, wrong lengths, a read-only ``out``, a batch)
taken by the public function, with its conversions and its errors; a model with cut joints
refused; calls from many threads on one evaluator. No timing here: ``benchmarks/lean_call.py``.
"""

from __future__ import annotations

import inspect
import sys
import threading
import tracemalloc
import weakref

import numpy as np
import pytest
from conftest import random_chain, random_state
from test_trees import random_configuration, random_tree, robot_urdf

import redysim
from redysim import Chain, CutJoint, Link, forward_dynamics, inverse_dynamics
from redysim.errors import CaseError, FieldError, StateError
from redysim.io.kinds import load_model


def _models():
    rng = np.random.default_rng(34)
    return {
        "U chain": Chain.uniform(10, "U", length=0.02, linear_density=61.6538, radius=0.05,
                                 inertia="rod"),
        "planar R chain": Chain.uniform(5, "R", length=0.3, linear_density=2.0, radius=0.02),
        "mixed chain": random_chain(rng, 7),
        "tree": random_tree(3, free=False),
        "floating tree": random_tree(4, free=True),
    }


MODELS = _models()


def _state(rng, model):
    q = random_configuration(rng, model)
    return q, rng.normal(size=model.n_v), rng.normal(size=model.n_v)


def same_bits(a, b) -> bool:
    return a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()


def checked_forward(model, q, v, tau=None):
    """forward_dynamics by its checked path (lists are converted there, then the entry that
    releases the GIL): not the lean entry that small models' contiguous vectors take."""
    return forward_dynamics(model, q.tolist(), v.tolist(), None if tau is None else tau.tolist())


def checked_inverse(model, q, v, qdd):
    """inverse_dynamics by its checked path (lists are converted there, then the kinematics and
    the backward pass called one by one): not the lean entry that contiguous float64 vectors
    take, so that the two are compared."""
    return inverse_dynamics(model, q.tolist(), v.tolist(), qdd.tolist())


@pytest.mark.parametrize("name", MODELS)
def test_forward_and_inverse_are_the_public_functions_bit_for_bit(name):
    model = MODELS[name]
    fd = redysim.evaluator(model)
    inv = redysim.evaluator(model, "inverse_dynamics")
    rng = np.random.default_rng(7)
    for _ in range(40):
        q, v, tau = _state(rng, model)
        assert same_bits(fd(q, v), checked_forward(model, q, v))
        assert same_bits(fd(q, v, tau), checked_forward(model, q, v, tau))
        assert same_bits(forward_dynamics(model, q, v, tau), checked_forward(model, q, v, tau))
        qdd = forward_dynamics(model, q, v, tau)
        assert same_bits(inv(q, v, qdd), checked_inverse(model, q, v, qdd))
        assert same_bits(inverse_dynamics(model, q, v, qdd), checked_inverse(model, q, v, qdd))
    assert model.is_planar == (name == "planar R chain")  # the planar kernel's path is covered


@pytest.mark.parametrize("floating", [False, True], ids=["fixed", "floating"])
def test_robots_of_example_robot_data(floating):
    model = load_model(robot_urdf("ur_description/urdf/ur5_robot.urdf" if not floating
                                  else "solo12.urdf"), floating=floating)
    fd, inv = redysim.evaluator(model), redysim.evaluator(model, "inverse_dynamics")
    rng = np.random.default_rng(11)
    for _ in range(20):
        q, v, tau = _state(rng, model)
        assert same_bits(fd(q, v, tau), checked_forward(model, q, v, tau))
        assert same_bits(forward_dynamics(model, q, v, tau), checked_forward(model, q, v, tau))
        assert same_bits(inv(q, v, tau), checked_inverse(model, q, v, tau))
        assert same_bits(inverse_dynamics(model, q, v, tau), checked_inverse(model, q, v, tau))


def test_out_is_written_and_returned():
    model = MODELS["floating tree"]
    q, v, tau = _state(np.random.default_rng(1), model)
    out = np.full(model.n_v, np.nan)
    assert redysim.evaluator(model)(q, v, tau, out=out) is out
    assert same_bits(out, checked_forward(model, q, v, tau))
    tau_out = np.empty(model.n_v)
    assert redysim.evaluator(model, "inverse_dynamics")(q, v, out, out=tau_out) is tau_out
    assert same_bits(tau_out, checked_inverse(model, q, v, out))
    # a fresh array per call without out: results never alias each other or the scratch
    fd = redysim.evaluator(model)
    a, b = fd(q, v), fd(q, 2 * v)
    assert not np.shares_memory(a, b) and not same_bits(a, b)


@pytest.mark.parametrize("kind", ["forward_dynamics", "inverse_dynamics"])
def test_other_inputs_are_converted_as_the_public_function_converts_them(kind):
    """Lists, ints, float32, strided and reversed views, read-only arrays: the same result as
    the public function's for the same input (it converts them; the lean path takes only
    contiguous float64 vectors and leaves the rest to it)."""
    model = MODELS["mixed chain"]
    public = forward_dynamics if kind == "forward_dynamics" else inverse_dynamics
    ev = redysim.evaluator(model, kind)
    q, v, x = _state(np.random.default_rng(2), model)
    wide = np.empty((3, model.n_v))
    wide[0] = q
    ro = q.copy()
    ro.flags.writeable = False
    for qq in (q.tolist(), q.astype(np.float32), wide[0, ::1], wide.T[:, 0].copy(), q[::-1][::-1],
               np.repeat(q, 2)[::2], q[::-1], ro, (q * 10).astype(np.int64)):
        assert same_bits(ev(qq, v, x), public(model, qq, v, x)), type(qq)
    strided_out = np.zeros((model.n_v, 2))[:, 0]
    with pytest.raises(StateError, match="out .*contiguous"):
        ev(q, v, x, out=strided_out)
    ro_out = np.empty(model.n_v)
    ro_out.flags.writeable = False
    with pytest.raises(StateError, match="writeable"):
        ev(q, v, x, out=ro_out)


@pytest.mark.parametrize("kind", ["forward_dynamics", "inverse_dynamics"])
def test_bad_shapes_and_dtypes_are_refused_naming_the_argument(kind):
    model = MODELS["tree"]
    ev = redysim.evaluator(model, kind)
    n = model.n_v
    q, v, x = _state(np.random.default_rng(3), model)
    third = "tau" if kind == "forward_dynamics" else "qdd"
    for args, name, length in (((q[:-1], v, x), "q", n - 1), ((q, np.zeros(n + 2), x), "v", n + 2),
                               ((q, v, x[:3]), third, 3)):
        with pytest.raises(StateError, match=rf"{name} has shape \({length},\).*must have shape"):
            ev(*args)
    with pytest.raises(StateError, match="out .*shape"):
        ev(q, v, x, out=np.empty(n + 1))
    with pytest.raises(StateError, match="out .*float64"):
        ev(q, v, x, out=np.empty(n, dtype=np.int64))
    with pytest.raises(StateError, match="v = .*not a numeric"):
        ev(q, ["a"] * n, x)
    with pytest.raises(StateError, match="not a numeric"):
        ev(q, v.astype(complex), x)
    with pytest.raises(StateError, match=r"q\[2\] = nan: not finite"):
        ev(np.where(np.arange(n) == 2, np.nan, q), v, x)
    q2 = np.tile(q, (2, 1))  # a 2-D array is the public function's batch of states
    assert same_bits(ev(q2, np.tile(v, (2, 1)), np.tile(x, (2, 1))),
                     (forward_dynamics if kind == "forward_dynamics" else inverse_dynamics)(
                         model, q2, np.tile(v, (2, 1)), np.tile(x, (2, 1))))


@pytest.mark.parametrize("kind", ["forward_dynamics", "inverse_dynamics"])
@pytest.mark.parametrize("name", MODELS)
def test_plain_vectors_take_the_lean_entry_and_never_the_checked_path(name, kind, monkeypatch):
    """The evaluator's speed is its entry: contiguous float64 vectors (and views of them, and a
    subclass's) must reach it, not fall back to the public function (which gives the same bits,
    so a broken entry would only show as a slow evaluator: an unboxing that lost the strides
    once sent every call there)."""
    from redysim.algorithms import evaluators

    model = MODELS[name]
    ev = redysim.evaluator(model, kind)
    q, v, x = _state(np.random.default_rng(5), model)
    want = (checked_forward if kind == "forward_dynamics" else checked_inverse)(model, q, v, x)

    def refuse(*args, **kwargs):
        raise AssertionError("the checked path was taken")

    monkeypatch.setattr(evaluators, "forward_dynamics", refuse)
    monkeypatch.setattr(evaluators, "inverse_dynamics", refuse)

    class Sub(np.ndarray):
        pass

    ro = q.copy()
    ro.flags.writeable = False
    wide = np.empty((2, model.n_q))
    wide[1] = q
    out = np.empty(model.n_v)
    for qq in (q, ro, wide[1], q.view(Sub)):
        assert same_bits(ev(qq, v, x), want)
    assert ev(q, v, x, out=out) is out and same_bits(out, want)
    if kind == "forward_dynamics":
        assert same_bits(ev(q, v), checked_forward(model, q, v))


def test_the_entries_unboxing_refuses_what_is_not_a_plain_float64_vector():
    """lean.CheckedVector: a TypeError from the compiled call itself for every object whose
    unboxing as a 1-D float64 vector would read the wrong memory or the wrong numbers; the
    lengths and strides are the kernel's to refuse (Refused)."""
    from redysim.algorithms._kernels import lean

    assert lean.NUMPY_LAYOUT_OK  # NumPy's structs read where the unboxing reads them
    model = MODELS["tree"]
    ws = redysim.Workspace(model)
    call = lean.FORWARD_TREE.call
    q, v, x = _state(np.random.default_rng(4), model)
    out = np.empty(model.n_v)
    args = [q, v, x, out, ws.kernel_f, ws.kernel_i, ws.scratch]
    assert call(*args) is out and same_bits(out, checked_forward(model, q, v, x))
    ro = np.empty(model.n_v)
    ro.flags.writeable = False
    unaligned = np.zeros(8 * model.n_v + 1, np.uint8)[1:].view(np.float64)
    assert not unaligned.flags.aligned
    bad_inputs = {"2-D": np.tile(q, (2, 1)), "int64": q.astype(np.int64),
                  "float32": q.astype(np.float32), "complex64": q.astype(np.complex64),
                  "big-endian": q.astype(">f8"), "0-D": np.array(1.0), "5-D": q.reshape(
                      (1, 1, 1, 1, -1)), "list": q.tolist(), "None": None, "unaligned": unaligned}
    for slot in (0, 1, 2, 3):
        for bad in bad_inputs.values():
            with pytest.raises(TypeError, match="float64"):
                call(*args[:slot], bad, *args[slot + 1:])
    with pytest.raises(TypeError, match="writeable"):
        call(q, v, x, ro, *args[4:])
    for slot in (0, 3):
        with pytest.raises(lean.Refused):  # a stride, a length: the kernel's checks
            call(*args[:slot], np.repeat(args[slot], 2)[::2], *args[slot + 1:])
        with pytest.raises(lean.Refused):
            call(*args[:slot], args[slot][:-1].copy(), *args[slot + 1:])


@pytest.mark.parametrize("joint", ["R", "S"])  # the planar kernel, the spatial one
def test_a_singular_model_is_named_as_forward_dynamics_names_it(joint):
    """A point mass on the last joint's axis: the GIM is singular there."""
    point = Link(1.0, 1.0, (0.0, 0.0, 0.0), ((0, 0, 0), (0, 0, 0), (0, 0, 0)))
    rod = Link(1.0, 1.0, (0.5, 0.0, 0.0), ((0.01, 0, 0), (0, 0.1, 0), (0, 0, 0.1)))
    model = Chain.build([rod, rod, point], ["R", "R", joint])
    q = np.full(model.n_q, 0.1)
    with pytest.raises(StateError, match="singular at DOF") as public:
        forward_dynamics(model, q, np.zeros(model.n_v))
    with pytest.raises(StateError) as lean:
        redysim.evaluator(model)(q, np.zeros(model.n_v))
    assert str(lean.value) == str(public.value)


def test_what_is_not_a_model_or_kind_and_cut_joints_are_refused():
    with pytest.raises(FieldError, match="model"):
        redysim.evaluator("ur5_robot.urdf")
    with pytest.raises(FieldError, match="kind = 'mass_matrix'"):
        redysim.evaluator(MODELS["tree"], "mass_matrix")
    closed = MODELS["tree"].with_cuts([CutJoint("pin", 2, (0.1, 0, 0), -1, (0.5, 0, 0))])
    for kind in ("forward_dynamics", "inverse_dynamics"):
        with pytest.raises(CaseError, match="cut joints.*ClosedLoops"):
            redysim.evaluator(closed, kind)


def test_calls_from_many_threads_on_one_evaluator_are_safe():
    """Documented: the compiled call holds the GIL, so threads sharing one evaluator (and its
    one scratch) take turns; each result is its state's, bit for bit."""
    from redysim._jit import LEAN_OPTIONS

    assert LEAN_OPTIONS["nogil"] is False  # what the evaluator's thread safety rests on
    model = MODELS["floating tree"]
    fd = redysim.evaluator(model)
    rng = np.random.default_rng(5)
    states = [_state(rng, model) for _ in range(64)]
    expected = [forward_dynamics(model, q, v, tau) for q, v, tau in states]
    failures = []

    def work(offset):
        for r in range(200):
            i = (offset + 7 * r) % len(states)
            q, v, tau = states[i]
            if not same_bits(fd(q, v, tau), expected[i]):
                failures.append(i)

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert not failures


def test_the_evaluator_is_a_public_name():
    assert "evaluator" in redysim.__all__
    fd = redysim.evaluator(MODELS["U chain"])
    assert fd.__self__.model is MODELS["U chain"] and fd.__self__.kind == "forward_dynamics"
    assert fd.__name__ == "forward_dynamics" and "redysim.forward_dynamics" in fd.__doc__
    assert str(inspect.signature(fd)) == "(q, v, tau=None, out=None)"
    inv = redysim.evaluator(MODELS["U chain"], "inverse_dynamics")
    assert str(inspect.signature(inv)) == "(q, v, qdd, out=None)"
    q, v, _ = random_state(np.random.default_rng(0), MODELS["U chain"])
    assert same_bits(fd(q, v), forward_dynamics(MODELS["U chain"], q, v))


def test_the_planar_entry_loads_the_kernel_it_calls_first():
    """As ``tests/test_identities.py`` checks of .entry's: the lean planar entry declares the
    types it calls the planar kernel with (``redysim._jit.EntryPoint``'s callees)."""
    import numba

    from redysim.algorithms._kernels import lean

    point = lean.FORWARD_PLANAR
    fresh = numba.njit(point.signature, **{**point.options, "cache": False})(point.func)
    annotation = fresh.overloads[fresh.signatures[0]].type_annotation
    called = {}
    for expr, sig in annotation.calltypes.items():
        if getattr(expr, "op", None) != "call":
            continue
        ty = annotation.typemap.get(expr.func.name)
        if isinstance(ty, numba.types.Dispatcher):
            called[ty.dispatcher] = tuple(sig.args)
    assert called == {kernel: tuple(types) for kernel, types in point.callees}


def test_the_evaluator_runs_with_numba_disabled():
    """NUMBA_DISABLE_JIT=1: no compiled call to bypass the dispatch of; every call takes the
    public function (the kernels' Python source)."""
    import json
    import os
    import subprocess
    import sys

    code = ("import numpy as np, redysim; c = redysim.Chain.uniform(3, 'U', length=1.0, "
            "linear_density=1.0, radius=0.1); q = np.full(6, 0.1); "
            "fd = redysim.evaluator(c); assert fd.__self__.kind == 'forward_dynamics'; "
            "print([fd(q, q).tolist(), "
            "redysim.evaluator(c, 'inverse_dynamics')(q, q, q).tolist()])")
    env = dict(os.environ, NUMBA_DISABLE_JIT="1")
    plain = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                           check=True, env=env)
    c = Chain.uniform(3, "U", length=1.0, linear_density=1.0, radius=0.1)
    q = np.full(6, 0.1)
    fd, inv = json.loads(plain.stdout)
    np.testing.assert_allclose(fd, forward_dynamics(c, q, q), rtol=1e-12)
    np.testing.assert_allclose(inv, inverse_dynamics(c, q, q, q), rtol=1e-12)


@pytest.mark.parametrize("links", [10, 260])  # 20 DOF; 520, past inverse_dynamics' lean limit
def test_the_default_calls_are_the_checked_paths_bits_at_any_size_and_on_threads(links):
    """forward_dynamics and inverse_dynamics by default (inverse_dynamics by the lean entry up
    to its limit, by the passes above), against their checked paths, bit for bit; from four
    threads at once, each thread's results its sequential ones."""
    model = Chain.uniform(links, "U", length=0.02, linear_density=61.6538, radius=0.05)
    rng = np.random.default_rng(links)
    states = [_state(rng, model) for _ in range(8)]
    want = []
    for q, v, tau in states:
        qdd = forward_dynamics(model, q, v, tau)
        assert same_bits(qdd, checked_forward(model, q, v, tau))
        back = inverse_dynamics(model, q, v, qdd)
        assert same_bits(back, checked_inverse(model, q, v, qdd))
        want.append((qdd, back))
    got: dict = {}

    def work(k):
        got[k] = [(forward_dynamics(model, q, v, tau),
                   inverse_dynamics(model, q, v, forward_dynamics(model, q, v, tau)))
                  for _ in range(20) for q, v, tau in states][-len(states):]

    threads = [threading.Thread(target=work, args=(k,)) for k in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for k in range(4):
        assert all(same_bits(a, c) and same_bits(b, d)
                   for (a, b), (c, d) in zip(got[k], want, strict=True))


def test_the_default_inverse_leaves_the_workspace_as_the_checked_path_does():
    """The implicit integrator's tension preconditioner reads the Newton-Euler wrenches and the
    link axes that inverse_dynamics leaves in the workspace: the lean entry leaves the same."""
    from redysim import Workspace

    model = MODELS["U chain"]
    q, v, qdd = _state(np.random.default_rng(9), model)
    lean, checked = Workspace(model), Workspace(model)
    inverse_dynamics(model, q, v, qdd, ws=lean)
    inverse_dynamics(model, q.tolist(), v.tolist(), qdd.tolist(), ws=checked)
    assert same_bits(lean.s.W, checked.s.W) and same_bits(lean.oR, checked.oR)


def test_the_builtins_arguments_are_taken_as_a_python_functions_would_take_them():
    """The evaluator is a builtin whose C function reads its own arguments
    (``_kernels/binding.py``): every way of passing them gives the checked path's bits, ``out``
    is returned, and what it does not take itself (other names, a name given twice, too few or
    too many) is the checked path's to refuse, with a Python function's TypeError."""
    from redysim.algorithms._kernels import binding

    assert binding.BINDING_OK
    model = MODELS["tree"]
    fd, inv = redysim.evaluator(model), redysim.evaluator(model, "inverse_dynamics")
    assert type(fd).__name__ == "builtin_function_or_method"
    q, v, tau = _state(np.random.default_rng(8), model)
    want, want0 = checked_forward(model, q, v, tau), checked_forward(model, q, v)
    out = np.empty(model.n_v)
    for call, expected in ((lambda: fd(q, v), want0), (lambda: fd(q, v, None), want0),
                           (lambda: fd(q, v, tau), want), (lambda: fd(q, v, tau=tau), want),
                           (lambda: fd(q, v, tau=None, out=None), want0),
                           (lambda: fd(q=q, v=v, tau=tau), want),
                           (lambda: fd(q, v, **{"ta" + "u": tau}), want)):  # (not interned)
        assert same_bits(call(), expected)
    for call, expected in ((lambda: fd(q, v, tau, out), want), (lambda: fd(q, v, out=out), want0),
                           (lambda: fd(q, v, out=out, tau=tau), want),
                           (lambda: fd(q, v, None, out=out), want0)):
        out[:] = np.nan
        assert call() is out and same_bits(out, expected)
    x = fd(q, v, tau)
    tau_back = checked_inverse(model, q, v, x)
    assert same_bits(inv(q, v, qdd=x), tau_back) and inv(q, v, x, out=out) is out
    assert same_bits(out, tau_back)
    for bad, message in ((lambda: fd(q), "missing 1 required positional argument: 'v'"),
                         (lambda: fd(q, v, tau, out, out), "from 2 to 4 positional"),
                         (lambda: fd(q, v, torque=tau), "unexpected keyword argument 'torque'"),
                         (lambda: fd(q, v, tau, tau=tau), "multiple values for argument 'tau'"),
                         (lambda: inv(q, v), "missing 1 required positional argument: 'qdd'"),
                         (lambda: inv(q, v, None), "qdd")):
        with pytest.raises((TypeError, StateError), match=message):
            bad()
    assert fd.__name__ == "forward_dynamics"


def test_the_builtin_keeps_no_reference_it_should_not():
    """Reference counts around the builtin's own allocation and the caller's arrays: a new
    result is the caller's alone, ``out`` and the inputs are left as they were, and calls that
    the entry refuses after allocating (a result that is not finite: the checked path then
    computes it again) or whose vectors the builtin does not take release what they made."""
    model = MODELS["floating tree"]
    fd, inv = redysim.evaluator(model), redysim.evaluator(model, "inverse_dynamics")
    q, v, tau = _state(np.random.default_rng(9), model)
    out = np.empty(model.n_v)
    result = fd(q, v)
    assert sys.getrefcount(result) == 2  # the name and getrefcount's argument
    gone = weakref.ref(result)
    del result
    assert gone() is None
    before = [sys.getrefcount(a) for a in (q, v, tau, out)]
    huge = np.full(model.n_v, 1e308)  # a torque whose qdd overflows: refused, then checked

    def overflow():
        with pytest.raises(StateError, match="not finite"):
            fd(q, v, huge)

    lists = (q.tolist(), v.tolist())
    for _ in range(100):
        fd(q, v)
        fd(q, v, tau, out)
        inv(q, v, tau)
        inv(q, v, tau, out=out)
        overflow()
        fd(*lists)
    assert [sys.getrefcount(a) for a in (q, v, tau, out)] == before
    def refused():  # (a plain try: pytest.raises keeps what it caught)
        try:
            fd(q, v, huge)
        except StateError:
            pass

    calls = (refused, lambda: fd(*lists), lambda: fd(q, v))
    for _ in range(500):
        for call in calls:
            call()
    tracemalloc.start()
    try:
        first = tracemalloc.get_traced_memory()[0]
        for _ in range(10_000):
            for call in calls:
                call()
        grown = tracemalloc.get_traced_memory()[0] - first
    finally:
        tracemalloc.stop()
    assert grown < 10_000  # a vector leaked a call would be ~100 bytes a call or more
