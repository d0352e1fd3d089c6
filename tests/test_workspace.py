"""The model's own workspace: a dynamics function called without ``ws=`` reuses the calling
thread's workspace of the model (:func:`redysim.algorithms.workspace.model_workspace`) instead of
building one a call.

Pinned here: the default call's results are the ``ws=`` call's bit for bit, for every public
function that takes ``ws``; the workspace is made once per thread and model, never shared between
threads (two threads hammering one model get the single-threaded results); and it stays out of
the model's data: pickles, copies, equality, hashing, fields and repr.
"""

from __future__ import annotations

import copy
import dataclasses
import inspect
import pickle
import sys
import threading

import numpy as np
import pytest
from test_trees import random_configuration, random_tree

import redysim
from redysim.algorithms import dynamics, workspace
from redysim.algorithms.workspace import Workspace, model_workspace
from redysim.errors import FieldError
from redysim.model.tree import THREAD_WORKSPACES


def rope(n_links=12, joint="U"):
    return redysim.Chain.uniform(n_links, joint, length=0.02, linear_density=61.6538,
                                 radius=0.05, inertia="rod")


SYSTEMS = {"U rope": lambda: rope(), "planar R rope": lambda: rope(9, "R"),
           "tree, free base": lambda: random_tree(3), "tree, fixed base":
           lambda: random_tree(4, free=False)}


def state(system, seed):
    rng = np.random.default_rng(seed)
    if system.is_chain and system.chain_layout is None:
        q = rng.uniform(-1.5, 1.5, system.n_q)
    else:
        q = random_configuration(rng, system)
    return q, rng.uniform(-1, 1, system.n_v), rng.uniform(-1, 1, system.n_v)


def frame_of(system):
    return "tip" if "tip" in system.frames else system.body_names[-1]


def calls(system, q, qd, x, Q, QD):
    """name -> call(**ws): every public function of redysim.algorithms.dynamics that takes ``ws``,
    in each of its modes (methods, the planar kernel, batches in tiles and row by row)."""
    f = frame_of(system)
    out = {
        "forward_dynamics": lambda **kw: redysim.forward_dynamics(system, q, qd, x, **kw),
        "forward_dynamics, ge-n": lambda **kw: redysim.forward_dynamics(system, q, qd, x,
                                                                        "ge-n", **kw),
        "forward_dynamics, rge-n": lambda **kw: redysim.forward_dynamics(system, q, qd, x,
                                                                         "rge-n", **kw),
        "forward_dynamics, batch": lambda **kw: redysim.forward_dynamics(system, Q, QD, **kw),
        "forward_dynamics, batch, rows": lambda **kw: redysim.forward_dynamics(
            system, Q, QD, simd=False, threads=2, **kw),
        "inverse_dynamics": lambda **kw: redysim.inverse_dynamics(system, q, qd, x, **kw),
        "inverse_dynamics, batch": lambda **kw: redysim.inverse_dynamics(system, Q, QD, QD,
                                                                         threads=2, **kw),
        "phi": lambda **kw: redysim.phi(system, q, qd, x, **kw),
        "mass_matrix": lambda **kw: redysim.mass_matrix(system, q, **kw),
        "udu_factors": lambda **kw: redysim.udu_factors(system, q, **kw),
        "energy": lambda **kw: redysim.energy(system, q, qd, **kw),
        "delta_M": lambda **kw: redysim.delta_M(system, q, qd, 1.5, **kw),
        "frame_motion": lambda **kw: redysim.frame_motion(system, q, qd, x, frame=f, **kw),
        "joint_positions": lambda **kw: redysim.joint_positions(system, q, **kw),
        "momentum": lambda **kw: redysim.momentum(system, q, qd, **kw),
        "generalized_momentum": lambda **kw: redysim.generalized_momentum(system, q, qd, **kw),
    }
    if "free" not in system.joint_types:  # (a quaternion's gradient is refused)
        out["generalized_momentum, gradient"] = lambda **kw: redysim.generalized_momentum(
            system, q, qd, gradient=True, **kw)
    if "tip" in system.frames:
        out["tip"] = lambda **kw: redysim.tip(system, q, qd, x, **kw)
    if system.is_planar:
        out["forward_dynamics, spatial"] = lambda **kw: redysim.forward_dynamics(
            system, q, qd, x, planar=False, **kw)
    return out


def same_bits(a, b) -> bool:
    if isinstance(a, tuple):
        return len(a) == len(b) and all(same_bits(x, y) for x, y in zip(a, b, strict=True))
    if a is None or b is None:
        return a is b
    return np.asarray(a).dtype == np.asarray(b).dtype and np.array_equal(a, b) \
        and np.asarray(a).tobytes() == np.asarray(b).tobytes()


def test_every_function_that_takes_a_workspace_is_covered():
    """A new public function with ``ws`` must join the tests below (and the default path)."""
    taking = {name for name, fn in vars(dynamics).items()
              if inspect.isfunction(fn) and not name.startswith("_")
              and fn.__module__ == dynamics.__name__ and "ws" in inspect.signature(fn).parameters}
    s = rope()
    q, qd, x = state(s, 0)
    covered = {name.split(",")[0] for name in calls(s, q, qd, x, q[None], qd[None])}
    assert taking == covered


@pytest.mark.parametrize("system", SYSTEMS)
def test_the_default_call_is_the_ws_call_bit_for_bit(system, monkeypatch):
    s = SYSTEMS[system]()
    q, qd, x = state(s, 1)
    rng = np.random.default_rng(2)
    Q = np.array([state(s, 10 + i)[0] for i in range(37)])  # tiles and a tail of rows
    QD = rng.uniform(-1, 1, Q.shape[:1] + (s.n_v,))
    given = Workspace(s)
    todo = calls(s, q, qd, x, Q, QD)
    want = {name: call(ws=given) for name, call in todo.items()}
    made = []  # workspaces built from here on: only the model's own, once
    monkeypatch.setattr(workspace.Workspace, "__init__", _counting(made))
    for _ in range(2):  # the first call makes the model's workspace, the second reuses it
        for name, call in todo.items():
            assert same_bits(call(), want[name]), name
    assert len(made) == 1
    assert model_workspace(s) is model_workspace(s) is not given
    assert model_workspace(s).model is s


def _counting(made):
    init = Workspace.__init__

    def counted(self, system):
        made.append(system)
        init(self, system)
    return counted


def test_a_thread_has_its_own_workspace_and_two_threads_get_their_single_results():
    """Two threads call one model without ws=, each with its own states, many times at once: each
    result is the single-threaded one (a workspace shared between the threads would mix their
    scratch: the kernels run without the GIL, and the Python parts read the scratch back)."""
    s = rope(40)
    states_of = [[state(s, 100 * t + i) for i in range(6)] for t in range(2)]

    def results(states):
        out = []
        for q, qd, x in states:
            out.append((redysim.forward_dynamics(s, q, qd, x),
                        redysim.inverse_dynamics(s, q, qd, x), redysim.energy(s, q, qd),
                        redysim.mass_matrix(s, q), redysim.tip(s, q, qd, x)))
        return out

    want = [results(st) for st in states_of]  # one thread, one after the other
    got: list[list] = [[], []]
    seen: list = [None, None]
    errors: list = []
    start = threading.Barrier(2)

    def hammer(t):
        try:
            start.wait()
            for _ in range(60):
                got[t].append(results(states_of[t]))
            seen[t] = model_workspace(s)
        except BaseException as exc:  # re-raised below, in the test's thread
            errors.append(exc)

    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads between Python bytecodes as often as may be
    try:
        threads = [threading.Thread(target=hammer, args=(t,)) for t in range(2)]
        for th in threads:
            th.start()
        for th in threads:
            th.join()
    finally:
        sys.setswitchinterval(interval)
    assert not errors, errors
    for t in range(2):
        assert len(got[t]) == 60
        for rounds in got[t]:
            assert all(same_bits(a, b) for a, b in zip(rounds, want[t], strict=True))
    assert seen[0] is not seen[1] and seen[0].model is seen[1].model is s
    assert model_workspace(s) not in seen  # the test's own thread has a third


def test_the_workspaces_stay_out_of_the_models_data():
    s = rope(8)
    q, qd, x = state(s, 3)
    h, r, fields = hash(s), repr(s), dataclasses.fields(s)
    qdd = redysim.forward_dynamics(s, q, qd, x, ws=Workspace(s))  # the derived facts it needs
    before = pickle.dumps(s)
    assert THREAD_WORKSPACES not in vars(s)
    assert same_bits(redysim.forward_dynamics(s, q, qd, x), qdd)
    assert THREAD_WORKSPACES in vars(s)  # made
    assert hash(s) == h and repr(s) == r and dataclasses.fields(s) == fields
    assert THREAD_WORKSPACES not in {f.name for f in fields}
    data = pickle.dumps(s)
    assert data == before  # the pickle is the same bytes as before the workspace was made
    for other in (pickle.loads(data), copy.copy(s), copy.deepcopy(s),
                  dataclasses.replace(s, name="other")):
        assert THREAD_WORKSPACES not in vars(other)
        assert other != s and s == s  # equality is identity, workspace or not
        assert np.array_equal(redysim.forward_dynamics(other, q, qd, x), qdd)
        assert model_workspace(other) is not model_workspace(s)
        assert model_workspace(other).model is other


def test_a_model_and_its_workspaces_are_freed_together():
    import gc
    import weakref

    s = rope(8)
    q, qd, _ = state(s, 4)
    redysim.forward_dynamics(s, q, qd)
    ref, ws_ref = weakref.ref(s), weakref.ref(model_workspace(s))
    del s
    gc.collect()
    assert ref() is None and ws_ref() is None


@pytest.mark.parametrize("system", [None, "U10", object()])
def test_something_that_is_not_a_model_is_named(system):
    """FieldError (redysim.errors.ModelTypeError, a TypeError too) naming the call and the
    argument: the public function's (the door's, redysim.model.door), or Workspace's."""
    with pytest.raises(FieldError, match=r"forward_dynamics: model = .*must be a redysim.Model"):
        redysim.forward_dynamics(system, [0.0, 0.0], [0.0, 0.0])
    with pytest.raises(FieldError, match=r"Workspace: model = .*must be a redysim.Model"):
        model_workspace(system)
