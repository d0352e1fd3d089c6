"""RGE-A for many states of a chain or tree at once: SIMD lanes across states.

A tile is LANES states side by side: every array of the three passes is (rows, LANES), the
states the last, contiguous axis, and every step of the passes a branch-free loop over the
states with a constant trip count, which LLVM turns into vector instructions (4 doubles a ymm
register here). The single-state kernels (:mod:`.rge_a`, :mod:`.kinematics`) keep a body's
running values in registers and run one state at a time; here the same values live in a small
tile array (``run``, ``car``, ``mu``) between steps, and a state on one core takes a fraction of
a single call's time (measured: docs/notes/2026-11-batches-and-tiles.md).

What it takes to vectorise, each found by LLVM's remarks (``llvmlite.binding.set_option("",
"--pass-remarks-missed=loop-vectorize")``):
- indices numba cannot take for negative (``at`` is unsigned): numba wraps a negative index by a
  select that makes the address non-affine, and LLVM then gives up ("unsafe dependent memory
  operations") or gathers;
- no branch inside a loop over states: one copy of each loop per joint kind and axis code (the
  branches on them are outside the loops: :func:`_axis` called with them as constants), and cos
  and sin by Cody-Waite reduction and fdlibm's polynomials with the quadrant applied by
  arithmetic;
- the tile kernels' arrays declared not to overlap (``_jit.jit_tiles``): without it LLVM adds run-
  time overlap checks for the arrays, and the backward pass ran far slower behind them.

The steps inside the loops over states are the single-state kernels' own, called once per state:
:func:`.joints.axis_transform` and :func:`.joints.axis_rates` (the joint's column, frame and
rates), and :mod:`.articulated`'s elimination, body mass, bias and shift; only the loading and
storing of a state's values from and to the tile arrays is this module's. A joint's armature
enters through them (:func:`.joints.joint_inertia`).

The kernels take named bundles (:mod:`.bundles`): the system's :class:`.bundles.Tree` and one
thread's :class:`.bundles.Tiles`, the tile arrays, declared in the layout table beside the others
(flat, their shapes in nb, nv and LANES); each kernel reads the fields it needs into locals at its
top. :func:`forward_tiles` slices both bundles out of a workspace's packed arrays and its thread's
row of the tile buffer, in compiled code (:data:`tile_bundles`, generated from the table; a bundle
passed from Python costs numba's dispatch more than the packed arrays do). numba hands a bundle's
arrays to a compiled function as separate pointer arguments, each declared noalias as the
positional arrays were: LLVM vectorises the same loops into the same packed instructions, and a
batch runs as fast (docs/notes/2026-11-batches-and-tiles.md; ``benchmarks/ab_tiles.py``).

Scope: any spatial tree, in two sets of passes. A serial chain (``Tree.serial``) of revolute
and prismatic axes (R, P, U, S as three R axes) runs :func:`forward_tiles`, whose passes carry
each body's values on to the next in ``run``, ``car`` and ``mu``; any other tree (placed joints,
branches, free joints) runs :func:`forward_tree_tiles`, whose passes are the same lane loops with
what a tree adds, each a branch on the body outside the loops over states: a body that does not
follow its parent starts from the parent's values read back from the tile's arrays (the base's
for a root), gathers its other children's articulated bodies from its row of ``tile_gm`` and
leaves its mu in ``tile_gt`` (the rows of :class:`.bundles.Tree`'s gather, as the single
kernels' gather arrays), a placed joint turns the parent's frame, a free joint's rotation is a
ball's three axes from its quaternion (normalised, as :func:`.joints.jcalc`), and Q has n_q rows.
A chain's batch compiles neither the tree's passes nor their branches (``balls`` and ``placed``
constants). The results agree with the single calls to rounding (the operations are the single
kernels', grouped alike, but a U joint's two axes are eliminated one after the other, a body's
gathered children are added before its own mass, and LLVM fuses multiply-adds where it
vectorises): not bit for bit. :func:`redysim.forward_dynamics` runs batches here unless asked
for the rows' bits (``simd=False``).

References: as :mod:`.rge_a` (Table A.1; Featherstone's ABA for the bias terms).
"""

from __future__ import annotations

import numpy as np

from redysim._jit import inline, inline_generated, jit_borrowed, jit_tiles

from .articulated import (
    add6,
    add_body,
    articulated_bias,
    eliminate_axis,
    shift_bias,
    shift_to_parent,
    velocity_wrench,
    world_inertia,
    world_moment,
)
from .bundles import (
    ALONG_X,
    BACK_ROWS,
    GATHER_MASS,
    KIN_ROWS,
    LANES,
    SLOT,
    Tiles,
    Tree,
    slicer_source,
)
from .joints import (
    BALL,
    PRISMATIC,
    REVOLUTE,
    axis_rates,
    axis_transform,
    fdlibm_sincos,
    turned,
)

TWO_OVER_PI = 6.36619772367581382433e-01
# fdlibm's pi/2 in three parts (e_rem_pio2.c): pio2_1 (33 bits), pio2_2, pio2_2t
PIO2_1, PIO2_1T = 1.57079632673412561417e+00, 6.07710050650619224932e-11
PIO2_2, PIO2_2T = 6.07710050630396597660e-11, 2.02226624879595063154e-21

# rows of the kinematics carry (Tiles.tile_run, KIN_ROWS): frame r (9), origin O (3), angular
# velocity w (3), s (3), om (3), dv (3), da (3), db (3), a ball's gathered P qd, bw (3)
KR, KO, KW, KS, KOM, KDV, KDA, KDB, KBW = 0, 9, 12, 15, 18, 21, 24, 27, 30
# rows of the backward carry (Tiles.tile_car, BACK_ROWS): X (6), Y (9), Z (6), n (3), f (3)
BX, BY, BZ, BN, BF = 0, 6, 15, 21, 24
GM = GATHER_MASS + 6  # a gathering body's row of tile_gm: the carry's rows (BX..BF), in order
assert KBW + 3 == KIN_ROWS and BF + 3 == BACK_ROWS == GM  # the layout's sizes (.bundles)
# LANES, states per tile (.bundles): every tile array is (rows, LANES) flattened, LANES a
# compile-time constant, so that the loops over states have a constant trip count and the rows
# constant strides (16: as fast per state as 32 here, and half the work lost in a batch's last,
# partial tile)
F_BASE_ACCEL = SLOT["base_accel"]  # the header slot of -g's offset in the workspace's floats

# The Tree bundle and one thread's Tiles as views of a workspace's packed arrays and of its row of
# the tile buffer, generated from the layout table (.bundles.slicer_source)
tile_bundles = inline_generated(slicer_source("tile_bundles", ("Tree", "Tiles")), "tile_bundles",
                                dict(Tree=Tree, Tiles=Tiles))


@inline
def at(row, b):
    """The flat index of (row, lane b) in a tile's array, unsigned: numba then skips the
    wraparound of negative indices, whose select made the addresses non-affine (LLVM: "unsafe
    dependent memory operations", or gathers)."""
    return np.uint64(row * LANES + b)


@inline
def sincos_reduced(x):
    """(cos x, sin x), branch-free: x reduced to r in [-pi/4, pi/4] by Cody-Waite, fdlibm's
    polynomials on r, then the quadrant's signs and swap. For |x| <= pi/4 the reduction is exact
    (k = 0) and the result is :func:`.joints.sincos`'s bit for bit."""
    k = np.floor(x * TWO_OVER_PI + 0.5)
    r = (x - k * PIO2_1) - k * PIO2_1T
    # the tail of pio2_1t, as fdlibm's second round: negligible below |x| ~ 1e5
    c, s = fdlibm_sincos(r)
    quadrant = k - 4.0 * np.floor(k * 0.25)  # 0, 1, 2, 3
    # the quadrant's swap and signs by arithmetic, not branches (a branch in the loop kept LLVM
    # from vectorising it): 1 x s + 0 x c is s exactly
    swap = quadrant - 2.0 * np.floor(quadrant * 0.5)  # 1 in quadrants 1 and 3
    hc = np.floor((quadrant + 1.0) * 0.5)
    hc = hc - 2.0 * np.floor(hc * 0.5)  # 1 in quadrants 1 and 2: cos negative
    hs = np.floor(quadrant * 0.5)  # 1 in quadrants 2 and 3: sin negative
    cos_ = (1.0 - 2.0 * hc) * (swap * s + (1.0 - swap) * c)
    sin_ = (1.0 - 2.0 * hs) * (swap * c + (1.0 - swap) * s)
    return cos_, sin_


@jit_tiles
def tile_kinematics(tree, tl):
    """The kinematics pass with ``local_rates`` (:func:`.kinematics.kinematics`) for a tile of
    a serial chain's states (L = LANES; every array flat, :func:`at`): reads ``tl``'s Q, QD (n,
    L); writes its oR (nb, 9, L), oO (nb, 3, L), oP (n, 6, L), W (nb, 3, L) (angular
    velocities) and C (nb, 6, L) (local twist-rates c_k), carrying ``run`` (KIN_ROWS, L)."""
    along = tree.along
    Q, QD, oR, oO, oP = tl.tile_Q, tl.tile_QD, tl.tile_oR, tl.tile_oO, tl.tile_oP
    W, C, run = tl.tile_W, tl.tile_C, tl.tile_run
    nb = along.shape[0]
    _kin_from(-1, oR, oO, W, run)
    for k in range(nb):
        _kin_begin(k, False, False, along[k], tree.placement_p, tree.placement_R, run)
        _kin_axes(k, 0, False, tree, Q, QD, oP, run)
        _kin_end(k, oR, oO, W, C, run)


@inline
def _kin_axes(k, qs, balls, tree, Q, QD, oP, run):
    """Joint k's axes for every state (q_j in Q's row j + qs; ``balls``: a ball's axes may
    come)."""
    joint_voff, dof_kind, dof_axis, dof_u = (tree.joint_voff, tree.dof_kind, tree.dof_axis,
                                             tree.dof_u)
    for j in range(joint_voff[k], joint_voff[k + 1]):
        kind, code = dof_kind[j], dof_axis[j]
        u0, u1, u2 = dof_u[j, 0], dof_u[j, 1], dof_u[j, 2]
        jq = j + qs
        # one copy of the lane loop per (kind, axis code), each generated from _axis with its
        # branches folded away: a branch inside a vectorised loop runs both of its sides
        if kind == PRISMATIC:
            _axis_of(j, jq, PRISMATIC, code, u0, u1, u2, Q, QD, oP, run)
        elif balls and kind == BALL:
            _axis_of(j, jq, BALL, code, u0, u1, u2, Q, QD, oP, run)
        else:
            _axis_of(j, jq, REVOLUTE, code, u0, u1, u2, Q, QD, oP, run)


@inline
def _axis_of(j, jq, kind, code, u0, u1, u2, Q, QD, oP, run):
    """:func:`_axis` with its axis code a constant too (``kind`` given as one): a branch on
    ``code`` outside the loop over states."""
    if code == 0:
        _axis(j, jq, kind, 0, u0, u1, u2, Q, QD, oP, run)
    elif code == 1:
        _axis(j, jq, kind, 1, u0, u1, u2, Q, QD, oP, run)
    elif code == 2 or kind == BALL:  # (a ball's axes are its body's x, y, z)
        _axis(j, jq, kind, 2, u0, u1, u2, Q, QD, oP, run)
    else:
        _axis(j, jq, kind, 3, u0, u1, u2, Q, QD, oP, run)


@inline
def _kin_begin(k, placed, balls, lp, pp, G, run):
    """Body k's start, for every state, from its parent's frame, origin and angular velocity in
    ``run``: s = O_k - O_p before any prismatic axis (lp along the parent's x, or, ``placed``,
    R_p pp[k] with the frame turned to R_p G[k]), om = w_p, the local rates zero (and a ball's
    bw, ``balls``)."""
    last = KIN_ROWS if balls else KBW
    p0, p1, p2 = (pp[k, 0], pp[k, 1], pp[k, 2]) if placed else (0.0, 0.0, 0.0)
    if placed:
        g00, g01, g02 = G[k, 0, 0], G[k, 0, 1], G[k, 0, 2]
        g10, g11, g12 = G[k, 1, 0], G[k, 1, 1], G[k, 1, 2]
        g20, g21, g22 = G[k, 2, 0], G[k, 2, 1], G[k, 2, 2]
    else:
        g00 = g01 = g02 = g10 = g11 = g12 = g20 = g21 = g22 = 0.0
    for b in range(LANES):
        if placed:
            r00, r01, r02 = run[at(KR + 0, b)], run[at(KR + 1, b)], run[at(KR + 2, b)]
            r10, r11, r12 = run[at(KR + 3, b)], run[at(KR + 4, b)], run[at(KR + 5, b)]
            r20, r21, r22 = run[at(KR + 6, b)], run[at(KR + 7, b)], run[at(KR + 8, b)]
            run[at(KS + 0, b)] = r00 * p0 + r01 * p1 + r02 * p2
            run[at(KS + 1, b)] = r10 * p0 + r11 * p1 + r12 * p2
            run[at(KS + 2, b)] = r20 * p0 + r21 * p1 + r22 * p2
            (run[at(KR + 0, b)], run[at(KR + 1, b)], run[at(KR + 2, b)],
             run[at(KR + 3, b)], run[at(KR + 4, b)], run[at(KR + 5, b)],
             run[at(KR + 6, b)], run[at(KR + 7, b)], run[at(KR + 8, b)]) = turned(
                (r00, r01, r02, r10, r11, r12, r20, r21, r22),
                (g00, g01, g02, g10, g11, g12, g20, g21, g22))
        else:
            run[at(KS + 0, b)] = lp * run[at(KR + 0, b)]
            run[at(KS + 1, b)] = lp * run[at(KR + 3, b)]
            run[at(KS + 2, b)] = lp * run[at(KR + 6, b)]
        run[at(KOM + 0, b)] = run[at(KW + 0, b)]
        run[at(KOM + 1, b)] = run[at(KW + 1, b)]
        run[at(KOM + 2, b)] = run[at(KW + 2, b)]
        for i in range(KDV, last):
            run[at(i, b)] = 0.0


@inline
def _kin_end(k, oR, oO, W, C, run):
    """A body's end, for every state: its origin, frame, angular velocity and local twist-rate
    c_k written out, and left in ``run`` for a child that follows."""
    for b in range(LANES):
            s0, s1, s2 = run[at(KS + 0, b)], run[at(KS + 1, b)], run[at(KS + 2, b)]
            w0, w1, w2 = run[at(KW + 0, b)], run[at(KW + 1, b)], run[at(KW + 2, b)]
            O0 = run[at(KO + 0, b)] + s0
            O1 = run[at(KO + 1, b)] + s1
            O2 = run[at(KO + 2, b)] + s2
            e0 = (w1 * s2 - w2 * s1) + run[at(KDV + 0, b)]
            e1 = (w2 * s0 - w0 * s2) + run[at(KDV + 1, b)]
            e2 = (w0 * s1 - w1 * s0) + run[at(KDV + 2, b)]
            C[at(k * 6 + 3, b)] = (w1 * e2 - w2 * e1) + run[at(KDB + 0, b)]
            C[at(k * 6 + 4, b)] = (w2 * e0 - w0 * e2) + run[at(KDB + 1, b)]
            C[at(k * 6 + 5, b)] = (w0 * e1 - w1 * e0) + run[at(KDB + 2, b)]
            C[at(k * 6 + 0, b)] = run[at(KDA + 0, b)]
            C[at(k * 6 + 1, b)] = run[at(KDA + 1, b)]
            C[at(k * 6 + 2, b)] = run[at(KDA + 2, b)]
            for i in range(9):
                oR[at(k * 9 + i, b)] = run[at(KR + i, b)]
            run[at(KO + 0, b)] = O0
            run[at(KO + 1, b)] = O1
            run[at(KO + 2, b)] = O2
            oO[at(k * 3 + 0, b)] = O0
            oO[at(k * 3 + 1, b)] = O1
            oO[at(k * 3 + 2, b)] = O2
            for i in range(3):
                w = run[at(KOM + i, b)]
                run[at(KW + i, b)] = w
                W[at(k * 3 + i, b)] = w


@inline
def _axis(j, jq, kind, code, u0, u1, u2, Q, QD, oP, run):
    """One axis for every state: the single-state pass's own steps, :func:`.joints.
    axis_transform` (jcalc's body, with this module's branch-free cos and sin) and
    :func:`.joints.axis_rates` at qdd = 0, on the carry ``run``, q_j in Q's row jq (a ball's
    quaternion in rows jq..jq + 3). ``kind`` and ``code`` are the same for every state: the
    caller passes them as constants, so each (kind, code) compiles to a lane loop of its own
    without branches."""
    for b in range(LANES):
        R = (run[at(KR + 0, b)], run[at(KR + 1, b)], run[at(KR + 2, b)],
             run[at(KR + 3, b)], run[at(KR + 4, b)], run[at(KR + 5, b)],
             run[at(KR + 6, b)], run[at(KR + 7, b)], run[at(KR + 8, b)])
        qj = Q[at(jq, b)]
        q1 = q2 = q3 = 0.0
        if kind == BALL and code == 0:
            q1, q2, q3 = Q[at(jq + 1, b)], Q[at(jq + 2, b)], Q[at(jq + 3, b)]
        c = s = 0.0
        if kind == REVOLUTE:
            c, s = sincos_reduced(qj)
        p0, p1, p2, p3, p4, p5, s0, s1, s2, R = axis_transform(
            kind, code, u0, u1, u2, qj, c, s, q1, q2, q3,
            run[at(KS + 0, b)], run[at(KS + 1, b)], run[at(KS + 2, b)], R)
        oP[at(j * 6 + 0, b)] = p0
        oP[at(j * 6 + 1, b)] = p1
        oP[at(j * 6 + 2, b)] = p2
        oP[at(j * 6 + 3, b)] = p3
        oP[at(j * 6 + 4, b)] = p4
        oP[at(j * 6 + 5, b)] = p5
        if kind == PRISMATIC:
            run[at(KS + 0, b)], run[at(KS + 1, b)], run[at(KS + 2, b)] = s0, s1, s2
        elif kind == REVOLUTE or code == 0:  # the frame turned (a ball's by its first axis)
            (run[at(KR + 0, b)], run[at(KR + 1, b)], run[at(KR + 2, b)],
             run[at(KR + 3, b)], run[at(KR + 4, b)], run[at(KR + 5, b)],
             run[at(KR + 6, b)], run[at(KR + 7, b)], run[at(KR + 8, b)]) = R
        (om0, om1, om2, dv0, dv1, dv2, da0, da1, da2, db0, db1, db2, bw0, bw1, bw2) = axis_rates(
            kind, code, p0, p1, p2, p3, p4, p5, QD[at(j, b)], 0.0, False,
            run[at(KOM + 0, b)], run[at(KOM + 1, b)], run[at(KOM + 2, b)],
            run[at(KDV + 0, b)], run[at(KDV + 1, b)], run[at(KDV + 2, b)],
            run[at(KDA + 0, b)], run[at(KDA + 1, b)], run[at(KDA + 2, b)],
            run[at(KDB + 0, b)], run[at(KDB + 1, b)], run[at(KDB + 2, b)],
            run[at(KBW + 0, b)], run[at(KBW + 1, b)], run[at(KBW + 2, b)])
        if kind == PRISMATIC:
            run[at(KDV + 0, b)], run[at(KDV + 1, b)], run[at(KDV + 2, b)] = dv0, dv1, dv2
            run[at(KDB + 0, b)], run[at(KDB + 1, b)], run[at(KDB + 2, b)] = db0, db1, db2
        else:
            run[at(KDA + 0, b)], run[at(KDA + 1, b)], run[at(KDA + 2, b)] = da0, da1, da2
        if kind == BALL:
            run[at(KBW + 0, b)], run[at(KBW + 1, b)], run[at(KBW + 2, b)] = bw0, bw1, bw2
        if kind == REVOLUTE or (kind == BALL and code == 2):
            run[at(KOM + 0, b)], run[at(KOM + 1, b)], run[at(KOM + 2, b)] = om0, om1, om2


@jit_tiles
def tile_tree_kinematics(tree, tl):
    """:func:`tile_kinematics` for any tree (R, P, U, S, ball and free joints, any placement):
    a body that does not follow the one before it starts from its parent's frame, origin and
    angular velocity, read back from the tile's arrays (or the base's), and Q has n_q rows (a
    joint's q in rows j + qshift)."""
    parent, placement_code, qshift, along = (tree.parent, tree.placement_code, tree.qshift,
                                             tree.along)
    placement_p, placement_R = tree.placement_p, tree.placement_R
    Q, QD, oR, oO, oP = tl.tile_Q, tl.tile_QD, tl.tile_oR, tl.tile_oO, tl.tile_oP
    W, C, run = tl.tile_W, tl.tile_C, tl.tile_run
    for k in range(along.shape[0]):
        p = parent[k]
        if k == 0 or p != k - 1:
            _kin_from(p, oR, oO, W, run)
        if placement_code[k] == ALONG_X:
            _kin_begin(k, False, True, along[k], placement_p, placement_R, run)
        else:
            _kin_begin(k, True, True, 0.0, placement_p, placement_R, run)
        _kin_axes(k, qshift[k], True, tree, Q, QD, oP, run)
        _kin_end(k, oR, oO, W, C, run)


@inline
def _kin_from(p, oR, oO, W, run):
    """The carry's frame, origin and angular velocity set to body p's (the base's, p < 0: at
    rest at the origin), for every state; :func:`_kin_begin` sets the rest of the carry."""
    if p < 0:
        for b in range(LANES):
            for i in range(KR, KW + 3):
                run[at(i, b)] = 0.0
            run[at(KR + 0, b)] = 1.0
            run[at(KR + 4, b)] = 1.0
            run[at(KR + 8, b)] = 1.0
    else:
        for b in range(LANES):
            for i in range(9):
                run[at(KR + i, b)] = oR[at(p * 9 + i, b)]
            for i in range(3):
                run[at(KO + i, b)] = oO[at(p * 3 + i, b)]
                run[at(KW + i, b)] = W[at(p * 3 + i, b)]


@jit_tiles
def tile_backward(tree, tl):
    """RGE-A's backward pass (:func:`.rge_a.rge_a_backward`, serial, axis by axis) for a tile:
    reads ``tl``'s kinematics and TAU (n, L); writes its Psihat (n, 6, L) and phitil (n, L),
    carrying the articulated mass and bias from body to body in ``car`` (BACK_ROWS, L)."""
    mass, inertia_O, mass_com = tree.mass, tree.inertia_O, tree.mass_com
    joint_voff, dof_kind, armature = tree.joint_voff, tree.dof_kind, tree.armature
    oR, oO, oP, W, C, TAU = tl.tile_oR, tl.tile_oO, tl.tile_oP, tl.tile_W, tl.tile_C, tl.tile_TAU
    Psihat, phitil, car = tl.tile_Psihat, tl.tile_phitil, tl.tile_car
    nb = mass.shape[0]
    _zero_carry(car)
    for k in range(nb - 1, -1, -1):
        _back_body(k, mass, inertia_O, mass_com, oR, W, car)
        _back_axes(k, joint_voff, dof_kind, armature, oP, TAU, Psihat, phitil, car)
        if k > 0:
            _bias_and_shift(k, k - 1, True, oO, C, car)
        else:
            _bias_and_shift(k, 0, False, oO, C, car)


@inline
def _back_body(k, mass, inertia_O, mass_com, oR, W, car):
    """Body k's own mass and velocity-product wrench into the carry (:func:`_body_mass`, its
    inertia's kind a branch outside the loop)."""
    m = mass[k]
    j00, j01, j02 = inertia_O[k, 0, 0], inertia_O[k, 0, 1], inertia_O[k, 0, 2]
    j11, j12, j22 = inertia_O[k, 1, 1], inertia_O[k, 1, 2], inertia_O[k, 2, 2]
    mc0, mc1, mc2 = mass_com[k, 0], mass_com[k, 1], mass_com[k, 2]
    if j01 == 0.0 and j02 == 0.0 and j12 == 0.0:
        _body_mass(k, True, m, j00, j01, j02, j11, j12, j22, mc0, mc1, mc2, oR, W, car)
    else:
        _body_mass(k, False, m, j00, j01, j02, j11, j12, j22, mc0, mc1, mc2, oR, W, car)


@inline
def _back_axes(k, joint_voff, dof_kind, armature, oP, TAU, Psihat, phitil, car):
    """Joint k's axes eliminated, last first (a ball's columns are rotational: the revolute
    loop)."""
    for j in range(joint_voff[k + 1] - 1, joint_voff[k] - 1, -1):
        if dof_kind[j] == PRISMATIC:
            _eliminate(j, PRISMATIC, armature, oP, TAU, Psihat, phitil, car)
        else:
            _eliminate(j, REVOLUTE, armature, oP, TAU, Psihat, phitil, car)


@jit_tiles
def tile_tree_backward(tree, tl):
    """:func:`tile_backward` for any tree: a body whose children do not all follow it gathers
    theirs from its row of ``tile_gm`` (:class:`.bundles.Tree`'s gather), and a body that its
    parent does not precede leaves its articulated mass and bias there, the carry then zero."""
    mass, inertia_O, mass_com = tree.mass, tree.inertia_O, tree.mass_com
    joint_voff, dof_kind, armature, parent, gather = (tree.joint_voff, tree.dof_kind,
                                                      tree.armature, tree.parent, tree.gather)
    oR, oO, oP, W, C, TAU = tl.tile_oR, tl.tile_oO, tl.tile_oP, tl.tile_W, tl.tile_C, tl.tile_TAU
    Psihat, phitil, car, gm = tl.tile_Psihat, tl.tile_phitil, tl.tile_car, tl.tile_gm
    for i in range(gm.shape[0]):
        gm[i] = 0.0
    _zero_carry(car)
    for k in range(mass.shape[0] - 1, -1, -1):
        p = parent[k]
        if gather[k] >= 0:
            _gathered(gather[k], gm, car, False)
        _back_body(k, mass, inertia_O, mass_com, oR, W, car)
        _back_axes(k, joint_voff, dof_kind, armature, oP, TAU, Psihat, phitil, car)
        if p >= 0:
            _bias_and_shift(k, p, True, oO, C, car)
        else:
            _bias_and_shift(k, 0, False, oO, C, car)
        if k > 0 and p != k - 1:
            if p >= 0:
                _gathered(gather[p], gm, car, True)
            else:
                _zero_carry(car)


@inline
def _zero_carry(car):
    """The backward carry (articulated mass and bias) zero, for every state."""
    for b in range(LANES):
        for i in range(BACK_ROWS):
            car[at(i, b)] = 0.0


@inline
def _gathered(g, gm, car, leave):
    """``leave``: the carry added into gathering row g, then zero; else row g added to the carry;
    for every state."""
    for b in range(LANES):
        for i in range(BACK_ROWS):
            if leave:
                gm[at(g * GM + i, b)] += car[at(i, b)]
                car[at(i, b)] = 0.0
            else:
                car[at(i, b)] += gm[at(g * GM + i, b)]


@inline
def _body_mass(k, principal, m, j00, j01, j02, j11, j12, j22, mc0, mc1, mc2, oR, W, car):
    """Body k's own mass and velocity-product wrench added to the carried articulated body,
    for every state (``principal``: its inertia is diagonal in its frame): the single-state
    pass's steps (:mod:`.articulated`)."""
    for b in range(LANES):
        R = (oR[at(k * 9 + 0, b)], oR[at(k * 9 + 1, b)], oR[at(k * 9 + 2, b)],
             oR[at(k * 9 + 3, b)], oR[at(k * 9 + 4, b)], oR[at(k * 9 + 5, b)],
             oR[at(k * 9 + 6, b)], oR[at(k * 9 + 7, b)], oR[at(k * 9 + 8, b)])
        X = world_inertia(principal, j00, j01, j02, j11, j12, j22, R)
        d0, d1, d2 = world_moment(mc0, mc1, mc2, R)
        wrench = velocity_wrench(X, d0, d1, d2, W[at(k * 3 + 0, b)], W[at(k * 3 + 1, b)],
                                 W[at(k * 3 + 2, b)])
        M, nf = add_body(_mass(car, b), _bias(car, b), X, d0, d1, d2, m, wrench)
        _put(car, b, M, nf, True)


@inline
def _eliminate(j, kind, armature, oP, TAU, Psihat, phitil, car):
    """One axis of Table A.1 for every state (:func:`.articulated.eliminate_axis`, the step of
    :func:`.rge_a._rge_a_backward`'s loop): phitil and Psihat written, the carried articulated
    mass and bias updated."""
    for b in range(LANES):
        M, nf, _, _, ptil, v = eliminate_axis(
            kind, oP[at(j * 6 + 0, b)], oP[at(j * 6 + 1, b)], oP[at(j * 6 + 2, b)],
            oP[at(j * 6 + 3, b)], oP[at(j * 6 + 4, b)], oP[at(j * 6 + 5, b)], TAU[at(j, b)],
            armature, j, _mass(car, b), _bias(car, b))
        phitil[at(j, b)] = ptil
        Psihat[at(j * 6 + 0, b)] = v[0]
        Psihat[at(j * 6 + 1, b)] = v[1]
        Psihat[at(j * 6 + 2, b)] = v[2]
        Psihat[at(j * 6 + 3, b)] = v[3]
        Psihat[at(j * 6 + 4, b)] = v[4]
        Psihat[at(j * 6 + 5, b)] = v[5]
        _put(car, b, M, nf, True)


@inline
def _bias_and_shift(k, p, shift, oO, C, car):
    """Body k's articulated bias p += Mbar_k c_k, then (``shift``) Mbar and p shifted to its
    parent p's origin (A_{k,p}^T Mbar A and A^T p), for every state."""
    for b in range(LANES):
        M = _mass(car, b)
        nf = add6(_bias(car, b), articulated_bias(
            (C[at(k * 6 + 0, b)], C[at(k * 6 + 1, b)], C[at(k * 6 + 2, b)],
             C[at(k * 6 + 3, b)], C[at(k * 6 + 4, b)], C[at(k * 6 + 5, b)]), M))
        if shift:
            s0 = oO[at(p * 3 + 0, b)] - oO[at(k * 3 + 0, b)]
            s1 = oO[at(p * 3 + 1, b)] - oO[at(k * 3 + 1, b)]
            s2 = oO[at(p * 3 + 2, b)] - oO[at(k * 3 + 2, b)]
            nf = shift_bias(s0, s1, s2, nf)
            M = shift_to_parent(s0, s1, s2, M)
        _put(car, b, M, nf, shift)


@inline
def _mass(car, b):
    """The carried articulated mass of state b (its 21 numbers, :mod:`.articulated`'s order)."""
    return (car[at(BX + 0, b)], car[at(BX + 1, b)], car[at(BX + 2, b)], car[at(BX + 3, b)],
            car[at(BX + 4, b)], car[at(BX + 5, b)],
            car[at(BY + 0, b)], car[at(BY + 1, b)], car[at(BY + 2, b)], car[at(BY + 3, b)],
            car[at(BY + 4, b)], car[at(BY + 5, b)], car[at(BY + 6, b)], car[at(BY + 7, b)],
            car[at(BY + 8, b)],
            car[at(BZ + 0, b)], car[at(BZ + 1, b)], car[at(BZ + 2, b)], car[at(BZ + 3, b)],
            car[at(BZ + 4, b)], car[at(BZ + 5, b)])


@inline
def _bias(car, b):
    """The carried bias (n, f) of state b."""
    return (car[at(BN + 0, b)], car[at(BN + 1, b)], car[at(BN + 2, b)],
            car[at(BF + 0, b)], car[at(BF + 1, b)], car[at(BF + 2, b)])


@inline
def _put(car, b, M, nf, mass):
    """State b's carried bias, and (``mass``) articulated mass, stored back."""
    if mass:
        (car[at(BX + 0, b)], car[at(BX + 1, b)], car[at(BX + 2, b)], car[at(BX + 3, b)],
         car[at(BX + 4, b)], car[at(BX + 5, b)]) = M[0], M[1], M[2], M[3], M[4], M[5]
        (car[at(BY + 0, b)], car[at(BY + 1, b)], car[at(BY + 2, b)], car[at(BY + 3, b)],
         car[at(BY + 4, b)], car[at(BY + 5, b)], car[at(BY + 6, b)], car[at(BY + 7, b)],
         car[at(BY + 8, b)]) = M[6], M[7], M[8], M[9], M[10], M[11], M[12], M[13], M[14]
        (car[at(BZ + 0, b)], car[at(BZ + 1, b)], car[at(BZ + 2, b)], car[at(BZ + 3, b)],
         car[at(BZ + 4, b)], car[at(BZ + 5, b)]) = M[15], M[16], M[17], M[18], M[19], M[20]
    (car[at(BN + 0, b)], car[at(BN + 1, b)], car[at(BN + 2, b)],
     car[at(BF + 0, b)], car[at(BF + 1, b)], car[at(BF + 2, b)]) = nf


@jit_tiles
def tile_forward(tree, tl, base_accel):
    """RGE-A's forward pass (:func:`.rge_a.rge_a_forward`, serial) for a tile: writes ``tl``'s
    QDD (n, L), carrying ``mu`` (6, L) from body to body, and ``bad`` (L,): 0 where every qdd of
    that state is finite, NaN where one is not."""
    joint_voff = tree.joint_voff
    oO, oP, Psihat, phitil, C = tl.tile_oO, tl.tile_oP, tl.tile_Psihat, tl.tile_phitil, tl.tile_C
    QDD, mu, bad = tl.tile_QDD, tl.tile_mu, tl.tile_bad
    nb = joint_voff.shape[0] - 1
    for b in range(LANES):
        bad[b] = 0.0
    _mu_base(0, C, base_accel, mu)
    for k in range(nb):
        jl = joint_voff[k + 1] - 1
        for j in range(joint_voff[k], jl + 1):
            if j < jl or k + 1 == nb:
                _forward_axis(j, oP, Psihat, phitil, QDD, mu, bad)
            else:
                _forward_axis_on(j, k, oO, oP, Psihat, phitil, C, QDD, mu, bad)


@jit_tiles
def tile_tree_forward(tree, tl, base_accel):
    """:func:`tile_forward` for any tree: a body that does not follow its parent starts from the
    parent's mu (its row of ``tile_gt``) or the base's, and a body with such children leaves its
    mu there."""
    joint_voff, parent, gather = tree.joint_voff, tree.parent, tree.gather
    oO, oP, Psihat, phitil, C = tl.tile_oO, tl.tile_oP, tl.tile_Psihat, tl.tile_phitil, tl.tile_C
    QDD, mu, bad, gt = tl.tile_QDD, tl.tile_mu, tl.tile_bad, tl.tile_gt
    nb = joint_voff.shape[0] - 1
    for b in range(LANES):
        bad[b] = 0.0
    for k in range(nb):
        p = parent[k]
        if k == 0 or p != k - 1:
            if p < 0:
                _mu_base(k, C, base_accel, mu)
            else:
                _mu_from(gather[p], p, k, oO, C, gt, mu)
        jl = joint_voff[k + 1] - 1
        onward = k + 1 < nb and parent[k + 1] == k
        g = gather[k]
        for j in range(joint_voff[k], jl + 1):
            if j < jl or not onward or g >= 0:
                _forward_axis(j, oP, Psihat, phitil, QDD, mu, bad)
            else:
                _forward_axis_on(j, k, oO, oP, Psihat, phitil, C, QDD, mu, bad)
        if g >= 0:  # mu_k kept for the children that do not follow, and on to k + 1
            for b in range(LANES):
                for i in range(6):
                    gt[at(g * 6 + i, b)] = mu[at(i, b)]
            if onward:
                _mu_from(g, k, k + 1, oO, C, gt, mu)


@inline
def _mu_base(k, C, base_accel, mu):
    """mu = [0; base_accel] + c_k: body k hangs from the base (no shift), for every state."""
    for b in range(LANES):
        mu[at(0, b)] = C[at(k * 6 + 0, b)]
        mu[at(1, b)] = C[at(k * 6 + 1, b)]
        mu[at(2, b)] = C[at(k * 6 + 2, b)]
        mu[at(3, b)] = base_accel[0] + C[at(k * 6 + 3, b)]
        mu[at(4, b)] = base_accel[1] + C[at(k * 6 + 4, b)]
        mu[at(5, b)] = base_accel[2] + C[at(k * 6 + 5, b)]


@inline
def _mu_from(g, p, k, oO, C, gt, mu):
    """mu_{k,p} = A_{k,p} mu_p + c_k, mu_p in row g of ``gt``: A [w; v] = [w; v + a x w] with a
    = O_p - O_k (:func:`.rge_a._rge_a_forward`), for every state."""
    for b in range(LANES):
        a0 = oO[at(p * 3 + 0, b)] - oO[at(k * 3 + 0, b)]
        a1 = oO[at(p * 3 + 1, b)] - oO[at(k * 3 + 1, b)]
        a2 = oO[at(p * 3 + 2, b)] - oO[at(k * 3 + 2, b)]
        u0, u1, u2 = gt[at(g * 6 + 0, b)], gt[at(g * 6 + 1, b)], gt[at(g * 6 + 2, b)]
        mu[at(3, b)] = (gt[at(g * 6 + 3, b)] + C[at(k * 6 + 3, b)]) + (a1 * u2 - a2 * u1)
        mu[at(4, b)] = (gt[at(g * 6 + 4, b)] + C[at(k * 6 + 4, b)]) + (a2 * u0 - a0 * u2)
        mu[at(5, b)] = (gt[at(g * 6 + 5, b)] + C[at(k * 6 + 5, b)]) + (a0 * u1 - a1 * u0)
        mu[at(0, b)] = u0 + C[at(k * 6 + 0, b)]
        mu[at(1, b)] = u1 + C[at(k * 6 + 1, b)]
        mu[at(2, b)] = u2 + C[at(k * 6 + 2, b)]


@inline
def _forward_axis(j, oP, Psihat, phitil, QDD, mu, bad):
    """qdd_j = phitil_j - Psihat_j^T mu, then mu += P_j qdd_j, for every state."""
    for b in range(LANES):
        m0, m1, m2 = mu[at(0, b)], mu[at(1, b)], mu[at(2, b)]
        m3, m4, m5 = mu[at(3, b)], mu[at(4, b)], mu[at(5, b)]
        x = ((phitil[at(j, b)] - (Psihat[at(j * 6 + 0, b)] * m0 + Psihat[at(j * 6 + 1, b)] * m1))
             - ((Psihat[at(j * 6 + 2, b)] * m2 + Psihat[at(j * 6 + 3, b)] * m3)
                + (Psihat[at(j * 6 + 4, b)] * m4 + Psihat[at(j * 6 + 5, b)] * m5)))
        QDD[at(j, b)] = x
        bad[b] += x * 0.0
        mu[at(0, b)] = m0 + oP[at(j * 6 + 0, b)] * x
        mu[at(1, b)] = m1 + oP[at(j * 6 + 1, b)] * x
        mu[at(2, b)] = m2 + oP[at(j * 6 + 2, b)] * x
        mu[at(3, b)] = m3 + oP[at(j * 6 + 3, b)] * x
        mu[at(4, b)] = m4 + oP[at(j * 6 + 4, b)] * x
        mu[at(5, b)] = m5 + oP[at(j * 6 + 5, b)] * x


@inline
def _forward_axis_on(j, k, oO, oP, Psihat, phitil, C, QDD, mu, bad):
    """A joint's last axis, and on to body k + 1 (:func:`.rge_a._rge_a_forward`'s grouping)."""
    for b in range(LANES):
        m0, m1, m2 = mu[at(0, b)], mu[at(1, b)], mu[at(2, b)]
        m3, m4, m5 = mu[at(3, b)], mu[at(4, b)], mu[at(5, b)]
        x = ((phitil[at(j, b)] - (Psihat[at(j * 6 + 0, b)] * m0 + Psihat[at(j * 6 + 1, b)] * m1))
             - ((Psihat[at(j * 6 + 2, b)] * m2 + Psihat[at(j * 6 + 3, b)] * m3)
                + (Psihat[at(j * 6 + 4, b)] * m4 + Psihat[at(j * 6 + 5, b)] * m5)))
        QDD[at(j, b)] = x
        bad[b] += x * 0.0
        p0, p1, p2 = oP[at(j * 6 + 0, b)], oP[at(j * 6 + 1, b)], oP[at(j * 6 + 2, b)]
        p3, p4, p5 = oP[at(j * 6 + 3, b)], oP[at(j * 6 + 4, b)], oP[at(j * 6 + 5, b)]
        a0 = oO[at(k * 3 + 0, b)] - oO[at((k + 1) * 3 + 0, b)]
        a1 = oO[at(k * 3 + 1, b)] - oO[at((k + 1) * 3 + 1, b)]
        a2 = oO[at(k * 3 + 2, b)] - oO[at((k + 1) * 3 + 2, b)]
        mu[at(3, b)] = (((m3 + C[at((k + 1) * 6 + 3, b)]) + (a1 * m2 - a2 * m1))
                    + ((a1 * p2 - a2 * p1) + p3) * x)
        mu[at(4, b)] = (((m4 + C[at((k + 1) * 6 + 4, b)]) + (a2 * m0 - a0 * m2))
                    + ((a2 * p0 - a0 * p2) + p4) * x)
        mu[at(5, b)] = (((m5 + C[at((k + 1) * 6 + 5, b)]) + (a0 * m1 - a1 * m0))
                    + ((a0 * p1 - a1 * p0) + p5) * x)
        mu[at(0, b)] = (m0 + C[at((k + 1) * 6 + 0, b)]) + p0 * x
        mu[at(1, b)] = (m1 + C[at((k + 1) * 6 + 1, b)]) + p1 * x
        mu[at(2, b)] = (m2 + C[at((k + 1) * 6 + 2, b)]) + p2 * x


@inline
def tile_in(src, t0, count, dst):
    """dst[(j, b)] = src[t0 + b, j] for b < count; the tile's spare lanes repeat state t0. A
    one-row src is every state's."""
    n = src.shape[1]
    one = src.shape[0] == 1
    for b in range(LANES):
        i = 0 if one else t0 + (b if b < count else 0)
        for j in range(n):
            dst[at(j, b)] = src[i, j]


@inline
def tile_out(src, t0, count, dst):
    """dst[t0 + b, j] = src[(j, b)] for b < count."""
    n = dst.shape[1]
    for b in range(count):
        for j in range(n):
            dst[t0 + b, j] = src[at(j, b)]


@jit_borrowed
def forward_tiles(fdata, idata, Q, QD, TAU, QDD, first, last, buf):
    """QDD rows first..last - 1 by tiles of LANES states (the last one possibly partial), for
    the serial chain of a workspace's packed arrays ``fdata``, ``idata``, in the tile arrays of
    ``buf`` (a row of the workspace's tile buffer, laid out as its header says: the Tiles rows of
    :data:`.bundles.LAYOUT`). TAU has B rows or one (the same for every state). Returns -1, or
    the first row whose qdd is not finite."""
    return _run_tiles(tile_kinematics, tile_backward, tile_forward, fdata, idata, Q, QD, TAU,
                      QDD, first, last, buf)


@jit_borrowed
def forward_tree_tiles(fdata, idata, Q, QD, TAU, QDD, first, last, buf):
    """:func:`forward_tiles` for any tree (the tree passes: a compiled function of its own, so
    that a chain's first batch does not compile them)."""
    return _run_tiles(tile_tree_kinematics, tile_tree_backward, tile_tree_forward, fdata, idata,
                      Q, QD, TAU, QDD, first, last, buf)


@inline
def _run_tiles(kinematics, backward, forward, fdata, idata, Q, QD, TAU, QDD, first, last, buf):
    """The tiles of rows first..last - 1 through the three passes given."""
    tree, tl = tile_bundles(fdata, idata, buf)
    base_accel = fdata[idata[F_BASE_ACCEL]:idata[F_BASE_ACCEL] + 3]
    Qt, QDt, Tt, QDDt, bad = tl.tile_Q, tl.tile_QD, tl.tile_TAU, tl.tile_QDD, tl.tile_bad
    for t0 in range(first, last, LANES):
        count = min(LANES, last - t0)
        tile_in(Q, t0, count, Qt)
        tile_in(QD, t0, count, QDt)
        tile_in(TAU, t0, count, Tt)
        kinematics(tree, tl)
        backward(tree, tl)
        forward(tree, tl, base_accel)
        for b in range(count):
            if bad[b] != 0.0:
                return t0 + b
        tile_out(QDDt, t0, count, QDD)
    return -1
