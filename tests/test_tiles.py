"""Batches in SIMD tiles (redysim.algorithms._kernels.tiles): a chain's or tree's states 16 at a
time.

The expected values are the single calls' (the single-state kernel, one state at a time through
the checked public function), which the other files test against published numbers, identities,
a 50-digit reference and the engines, and, for a few rows, a 40-digit reference of their own.
The tiles compute the same passes, but eliminate a U joint's two axes one after the other where
the single kernel takes them as one 2 x 2 block, and LLVM fuses multiply-adds differently in
vector code: the rows agree to rounding, not bit for bit. Measured: within 4e-15 of max |qdd| on
the ropes and 1.4e-13 on the random chains here (GIM condition numbers up to 5e5); against the
40-digit reference the tiles' largest error over 16 states is 1.0-1.3x the single kernel's. TOL
(1e-12) leaves 7x for other CPUs' vector widths; a wrong term in any pass moves qdd by far more.
Trees (their own passes: placements, branches, free joints' quaternions) measured within 1.2e-14
of max |qdd| on the random trees and 1.5e-15 on the robots here.
"""

from __future__ import annotations

import math

import numba
import numpy as np
import pytest
from conftest import stable_seed
from test_trees import random_configuration, random_tree, robot_urdf

import redysim
from redysim import StateError, Workspace, forward_dynamics
from redysim.algorithms._kernels import tiles
from redysim.algorithms._kernels.bundles import Tiles, numba_types, segment_sizes, sizes_of
from redysim.errors import FieldError
from redysim.harness import hiprec
from redysim.harness.random_chains import MIX_KINDS, _mix_joint, random_chain, random_link
from redysim.io.kinds import load_model

TOL = 1e-12  # of max |qdd| (module docstring)


def rope(n_links=20, joint="U"):
    return redysim.Chain.uniform(n_links, joint, length=0.02, linear_density=61.6538,
                                 radius=0.05, inertia="rod")


def mixed_chain(n_links=21, seed=5):
    """Random links (off-axis centres of mass, full inertias) on every joint a tile has a loop
    for: revolute about x, y, z, negative and general axes, prismatic ones, and U joints."""
    rng = np.random.default_rng(seed)
    kinds = [k for k in MIX_KINDS if k != "S"]
    joints = [_mix_joint(rng, kinds[k % len(kinds)]) for k in range(n_links)]
    return redysim.Chain.build([random_link(rng) for _ in joints], joints, name="mixed",
                               gravity=(0.0, -9.81, 1.5))


def states(chain, rows, seed, amplitude=2.0):
    rng = np.random.default_rng(seed)
    return (rng.uniform(-amplitude, amplitude, (rows, chain.n_q)),  # angles beyond pi/4
            rng.uniform(-1, 1, (rows, chain.n_v)), rng.uniform(-1, 1, (rows, chain.n_v)))


def singles(chain, Q, QD, TAU):
    return np.array([forward_dynamics(chain, Q[i], QD[i], None if TAU is None else
                                      (TAU if TAU.ndim == 1 else TAU[i]))
                     for i in range(len(Q))])


def close(got, want):
    return np.abs(got - want).max() <= TOL * np.abs(want).max()


CHAINS = {"U rope": rope, "spatial R rope": lambda: rope(30, "R"), "mixed R, P and U": mixed_chain,
          "general R axes": lambda: random_chain("Rgen", 17, 3),
          "negative R axes": lambda: random_chain("Rneg", 15, 4),
          "P axes": lambda: random_chain("P", 12, 6),
          "S rope (three R axes a joint)": lambda: rope(10, "S")}


@pytest.mark.parametrize("rows", [16, 24, 37, 64])  # a tile; a partial tile; rows after tiles
@pytest.mark.parametrize("chain", CHAINS)
def test_the_tiles_are_the_single_calls(chain, rows):
    c = CHAINS[chain]()
    # an S joint's three axes near their gimbal configurations (middle angle +-pi/2) make the GIM
    # ill-conditioned, and then both kernels' rounding (and so their difference) grows with it:
    # the S rope's states stay away from there
    Q, QD, TAU = states(c, rows, rows, amplitude=0.5 if chain.startswith("S rope") else 2.0)
    ws = Workspace(c)
    got = forward_dynamics(c, Q, QD, TAU, ws=ws, planar=False)
    assert ws._tiles is not None  # the tiles ran
    want = np.array([forward_dynamics(c, Q[i], QD[i], TAU[i], planar=False)
                     for i in range(rows)])
    assert close(got, want)


@pytest.mark.parametrize("chain", ["negative R axes", "mixed R, P and U"])
def test_the_tiles_error_is_the_single_kernels(chain):
    # the largest error over 16 states, each against the 40-digit reference: one state's errors
    # are two small numbers whose ratio is luck (up to 5x either way, measured), the largest of
    # 16 is not (the tiles' 1.0-1.3x the single kernel's under three OpenBLAS kernel types,
    # whose rounding reaches the random chains' inertias)
    c = CHAINS[chain]()
    Q, QD, TAU = states(c, 16, 16)
    got = forward_dynamics(c, Q, QD, TAU)
    single, tiled = 0.0, 0.0
    for i in range(16):
        ref = hiprec.qdd_reference(c, Q[i], QD[i], TAU[i], dps=40, output="dd")
        single = max(single, hiprec.relative_errors(forward_dynamics(c, Q[i], QD[i], TAU[i]),
                                                    ref)[1])
        tiled = max(tiled, hiprec.relative_errors(got[i], ref)[1])
    assert tiled <= 2 * single, (tiled, single)


@pytest.mark.parametrize("threads", [1, 2, 3])
def test_the_tiles_on_threads_and_one_tau_or_none(threads):
    c = rope()
    Q, QD, TAU = states(c, 53, 9)  # three full tiles and a partial one over unequal blocks
    for tau in (TAU, TAU[3], None):
        got = forward_dynamics(c, Q, QD, tau, threads=threads)
        assert close(got, singles(c, Q, QD, tau))


def test_what_does_not_run_in_tiles_runs_the_rows_bit_for_bit():
    c = rope()
    Q, QD, _ = states(c, 16, 1)
    big = Q.copy()
    big[2, 0] = 2e5  # beyond the tiles' angle reduction
    for q, qd, kwargs in ((Q, QD, {"simd": False}),  # asked for the rows
                          (Q[:7], QD[:7], {}),  # under half a tile
                          (big, QD, {})):
        ws = Workspace(c)
        got = forward_dynamics(c, q, qd, ws=ws, **kwargs)
        assert ws._tiles is None
        assert np.array_equal(got, singles(c, q, qd, None))
    long = rope(5001)  # over TILE_MAX_DOF: a thread's tile arrays would be ~35 MB
    ws = Workspace(long)
    Ql, QDl, _ = states(long, 16, 3, amplitude=0.1)
    assert np.array_equal(forward_dynamics(long, Ql, QDl, ws=ws), singles(long, Ql, QDl, None))
    assert ws._tiles is None
    planar = rope(10, "R")  # the planar kernel's rows
    ws = Workspace(planar)
    forward_dynamics(planar, *states(planar, 16, 2)[:2], ws=ws)
    assert ws._tiles is None
    assert Workspace(c).tiles_ok and not Workspace(c).tiles_tree


def test_a_state_whose_qdd_is_not_finite_is_named_by_its_row():
    c = rope(8)
    Q, QD, _ = states(c, 20, 3)
    QD[13, 4] = 1e200  # finite input, the velocity products overflow
    for threads in (1, 2):
        with pytest.raises(StateError, match=r"state 13 of the batch"):
            forward_dynamics(c, Q, QD, threads=threads)


def test_the_tiles_keep_one_buffer_row_a_thread():
    c = rope(8)
    ws = Workspace(c)
    before = ws.nbytes
    Q, QD, _ = states(c, 64, 4)
    forward_dynamics(c, Q, QD, ws=ws, threads=2)
    buf = ws.tile_buffer(2)
    # a row a thread, laid out by the layout table's Tiles rows (each whole tiles: no padding)
    sizes = segment_sizes("tiles", sizes_of(8, 16, 0, True), False)
    assert buf.shape == (2, sum(sizes.values()))
    assert ws.nbytes == before + buf.nbytes + 64  # and up to 64 bytes to align it:
    assert buf[0].ctypes.data % 64 == 0 and buf[1].ctypes.data % 64 == 0  # each row on a line
    tree, tl = tiles.tile_bundles.py_func(ws.kernel_f, ws.kernel_i, buf[1])
    assert all(np.array_equal(a, b) for a, b in zip(tree, ws.tree, strict=True))
    row = (buf[1].ctypes.data, buf[1].ctypes.data + buf[1].nbytes)
    spans = sorted((a.ctypes.data, a.ctypes.data + a.nbytes) for a in tl)
    assert [a.size for a in tl] == [sizes[name] for name in Tiles._fields]
    assert row[0] <= spans[0][0] and spans[-1][1] <= row[1]  # in the thread's row,
    assert all(e <= s for (_, e), (s, _) in zip(spans[:-1], spans[1:], strict=True))  # apart
    with pytest.raises(FieldError, match="simd"):
        forward_dynamics(c, Q, QD, simd="yes")


@numba.njit
def _slice_tiles(fdata, idata, buf):
    tree, tl = tiles.tile_bundles(fdata, idata, buf)
    return tree.serial + tl.tile_bad.shape[0]


def test_the_tiles_slicer_gives_the_layouts_types():
    # the bundles the tile kernels are called with, as the layout declares them: C-contiguous
    # arrays, the tiles' 1-D (an array of unknown strides, "A", would keep LLVM from vectorising
    # the loops over states)
    ws = Workspace(rope(8))
    assert _slice_tiles(ws.kernel_f, ws.kernel_i, ws.tile_buffer(1)[0]) == 1 + tiles.LANES
    typemap = _slice_tiles.overloads[_slice_tiles.signatures[0]].type_annotation.typemap
    TREE, _, TILES = numba_types()
    assert all(a.layout == "C" and a.ndim == 1 for a in TILES)
    assert (typemap["tree"], typemap["tl"]) == (TREE, TILES)


@numba.njit
def _sincos_many(x, out):
    for i in range(x.shape[0]):
        out[i, 0], out[i, 1] = tiles.sincos_reduced(x[i])


def test_the_tiles_cos_and_sin_are_libms_to_an_ulp():
    rng = np.random.default_rng(11)
    quarter = math.pi / 4
    x = np.concatenate([rng.uniform(-quarter, quarter, 2000), rng.uniform(-10, 10, 2000),
                        rng.uniform(-1e5, 1e5, 2000), quarter * np.arange(-9, 10),
                        np.nextafter(quarter * np.arange(-9, 10), np.inf), [0.0, -0.0]])
    out = np.empty((x.size, 2))
    _sincos_many(x, out)
    for got, f in ((out[:, 0], np.cos), (out[:, 1], np.sin)):
        want = f(x)
        # an ulp of the result's magnitude, or of 1 where the result is near 0: the reduction
        # by pi/2 in two parts leaves ~1e-21 absolute (module docstring of tiles)
        assert np.all(np.abs(got - want) <= np.spacing(np.maximum(np.abs(want), 1.0)))


# --------------------------------------------------------------------------- trees
def tree_states(model, rows, seed):
    """Random configurations (free joints anywhere, any orientation; angles in +-1.2), with
    every third quaternion scaled off the unit sphere (the kernels normalise it, as an
    integrator's stage may leave it), velocities and torques in +-1."""
    rng = np.random.default_rng(seed)
    Q = np.array([random_configuration(rng, model) for _ in range(rows)])
    for i in model.quaternions:
        Q[::3, i:i + 4] *= 1.0 + 1e-3 * rng.uniform(-1, 1, (Q[::3].shape[0], 1))
    return Q, rng.uniform(-1, 1, (rows, model.n_v)), rng.uniform(-1, 1, (rows, model.n_v))


def tree_case(name):
    if name.startswith("random"):
        seed = int(name.split()[-1])
        return random_tree(stable_seed("tiles-tree", seed), n_bodies=11, free=seed % 2 == 0)
    floating = name in ("solo12.urdf", "talos_reduced.urdf")
    return load_model(robot_urdf(name), floating=floating)


TREES = ["random 0", "random 1", "random 2", "random 3", "ur_description/urdf/ur5_robot.urdf",
         "solo12.urdf", "talos_reduced.urdf"]


@pytest.mark.parametrize("rows", [16, 37])  # a tile; two and a partial one, or rows after
@pytest.mark.parametrize("name", TREES)
def test_trees_run_in_tiles_as_their_single_calls(name, rows):
    model = tree_case(name)
    Q, QD, TAU = tree_states(model, rows, stable_seed("tiles-tree-states", name, rows))
    ws = Workspace(model)
    assert ws.tiles_ok and ws.tiles_tree
    got = forward_dynamics(model, Q, QD, TAU, ws=ws, threads=1)
    assert ws._tiles is not None  # the tiles ran
    assert close(got, singles(model, Q, QD, TAU))
    assert close(forward_dynamics(model, Q, QD, TAU[5], ws=ws), singles(model, Q, QD, TAU[5]))


def test_a_trees_tiles_on_threads_and_their_errors():
    model = tree_case("random 0")
    Q, QD, TAU = tree_states(model, 53, 8)
    for threads in (2, 3):
        assert close(forward_dynamics(model, Q, QD, TAU, threads=threads),
                     singles(model, Q, QD, TAU))
    QD[13, 4] = 1e200  # finite input, the velocity products overflow
    for threads in (1, 2):
        with pytest.raises(StateError, match=r"state 13 of the batch"):
            forward_dynamics(model, Q, QD, threads=threads)


def test_a_trees_tiles_error_is_the_single_kernels():
    # as test_the_tiles_error_is_the_single_kernels, on a tree (fixed base: the 40-digit
    # reference takes q of n_v numbers)
    model = tree_case("random 1")
    Q, QD, TAU = tree_states(model, 16, 21)
    got = forward_dynamics(model, Q, QD, TAU)
    single, tiled = 0.0, 0.0
    for i in range(16):
        ref = hiprec.qdd_reference(model, Q[i], QD[i], TAU[i], dps=40, output="dd")
        single = max(single, hiprec.relative_errors(
            forward_dynamics(model, Q[i], QD[i], TAU[i]), ref)[1])
        tiled = max(tiled, hiprec.relative_errors(got[i], ref)[1])
    assert tiled <= 2 * single, (tiled, single)


def test_a_zero_quaternion_is_named_in_a_batch_and_a_single_call():
    # a free joint's quaternion is normalised by the kernels: zero (or a norm whose square
    # underflows) is no rotation, and the error says so rather than blaming an inertia
    model = tree_case("random 0")
    Q, QD, _ = tree_states(model, 20, 5)
    i = int(model.quaternions[0])
    for bad in (0.0, 1e-170):
        Q[7, i:i + 4] = bad
        for simd in (True, False):
            with pytest.raises(StateError, match=rf"state 7 of the batch .*q\[{i}:{i + 4}\] = "
                                                 r".*quaternion .* of free joint 'base'"):
                forward_dynamics(model, Q, QD, simd=simd)
        with pytest.raises(StateError, match=r"quaternion .* of free joint 'base' is zero"):
            forward_dynamics(model, Q[7], QD[7])
        with pytest.raises(StateError, match=r"quaternion .* of free joint 'base' is zero"):
            redysim.evaluator(model)(Q[7], QD[7])
