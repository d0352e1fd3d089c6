"""Prototype, measured and not adopted: RGE-A for many states with SIMD lanes across states.

Issue 21 asks for batches "computed across states (SIMD lanes across states, threads across
cores)". The library's batch (``redysim.forward_dynamics`` with (B, n) arrays) runs the
single-state kernel state by state on every core. This script measures the other half, lanes
across states, on a serial U chain: every array of a tile of LANES states is (rows, LANES),
LANES a compile-time constant, and every step of the three passes a branch-free loop over the
states that LLVM vectorises (one copy per joint kind and axis, so that no branch runs both of
its sides); cos and sin by Cody-Waite reduction and fdlibm's polynomials, vectorisable.

    .venv/bin/python benchmarks/batch_simd_prototype.py [--dof 250] [--batch 64]

What it found (docs/design.md, "Performance notes"): the loops do vectorise (4 doubles a
ymm register), the results agree with the single calls to 1e-14, and the tile runs 1.0-1.2x
the single-state kernel per state, because the recursions' running values, which the
single-state kernels keep in registers, here go through memory at every step.
"""

from __future__ import annotations

import argparse
import math
import time
import timeit

import numba
import numpy as np
from numba.core import cpu, options

from redysim._jit import BORROWED_OPTIONS, inline
from redysim._kernels.joints import C1, C2, C3, C4, C5, C6, PRISMATIC, S1, S2, S3, S4, S5, S6

# numba marks a function's array arguments noalias only inside its parallel loops; without it
# LLVM must check at run time that no two of the ~15 arrays overlap and gives up (a prototype's
# switch, not the library's: redysim compiles nothing with it)
cpu.CPUTargetOptions.noalias = options.TargetOptions.Mapping("noalias")
jit_borrowed = numba.njit(**dict(BORROWED_OPTIONS, noalias=True, cache=False))

TWO_OVER_PI = 6.36619772367581382433e-01
# fdlibm's pi/2 in three parts (e_rem_pio2.c): pio2_1 (33 bits), pio2_2, pio2_2t
PIO2_1, PIO2_1T = 1.57079632673412561417e+00, 6.07710050650619224932e-11
PIO2_2, PIO2_2T = 6.07710050630396597660e-11, 2.02226624879595063154e-21

# rows of the kinematics carry: frame r (9), origin O (3), angular velocity w (3), s (3),
# om (3), dv (3), da (3), db (3)
KR, KO, KW, KS, KOM, KDV, KDA, KDB = 0, 9, 12, 15, 18, 21, 24, 27
KIN_ROWS = 30
# rows of the backward carry: X (6), Y (9), Z (6), n (3), f (3)
BX, BY, BZ, BN, BF = 0, 6, 15, 21, 24
BACK_ROWS = 27
# states per tile: every batch array is (rows, LANES) flattened, LANES a compile-time constant,
# so that the loops over states have a constant trip count and the rows constant strides
LANES = 32


@inline
def at(row, b):
    """The flat index of (row, lane b) in a tile's array."""
    return row * LANES + b


@inline
def sincos_reduced(x):
    """(cos x, sin x), branch-free: x reduced to r in [-pi/4, pi/4] by Cody-Waite, fdlibm's
    polynomials on r, then the quadrant's signs and swap. For |x| <= pi/4 the reduction is exact
    (k = 0) and the result is :func:`.joints.sincos`'s bit for bit."""
    k = math.floor(x * TWO_OVER_PI + 0.5)
    r = (x - k * PIO2_1) - k * PIO2_1T
    # the tail of pio2_1t, as fdlibm's second round: negligible below |x| ~ 1e5
    z = r * r
    rs = S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))
    s = r + r * z * (S1 + z * rs)
    rc = z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6)))))
    hz = 0.5 * z
    w = 1.0 - hz
    c = w + (((1.0 - w) - hz) + z * rc)
    quadrant = k - 4.0 * math.floor(k * 0.25)  # 0, 1, 2, 3
    swap = quadrant == 1.0 or quadrant == 3.0
    cos_ = s if swap else c
    sin_ = c if swap else s
    if quadrant == 1.0 or quadrant == 2.0:
        cos_ = -cos_
    if quadrant >= 2.0:
        sin_ = -sin_
    return cos_, sin_


@jit_borrowed
def batch_kinematics(along, joint_voff, dof_kind, dof_axis, dof_u, Q, QD, oR, oO, oP, W, C,
                     run):
    """The kinematics pass with ``local_rates`` (:func:`.kinematics.kinematics`) for B states of
    a serial chain: Q, QD (n, B); writes oR (nb, 9, B), oO (nb, 3, B), oP (n, 6, B), W (nb, 3, B)
    (angular velocities) and C (nb, 6, B) (local twist-rates c_k). ``run``: (KIN_ROWS, B)."""
    nb = along.shape[0]
    for b in range(LANES):
        for i in range(KIN_ROWS):
            run[at(i, b)] = 0.0
        run[at(KR + 0, b)] = 1.0
        run[at(KR + 4, b)] = 1.0
        run[at(KR + 8, b)] = 1.0
    for k in range(nb):
        lp = along[k]
        for b in range(LANES):
            run[at(KS + 0, b)] = lp * run[at(KR + 0, b)]
            run[at(KS + 1, b)] = lp * run[at(KR + 3, b)]
            run[at(KS + 2, b)] = lp * run[at(KR + 6, b)]
            run[at(KOM + 0, b)] = run[at(KW + 0, b)]
            run[at(KOM + 1, b)] = run[at(KW + 1, b)]
            run[at(KOM + 2, b)] = run[at(KW + 2, b)]
            for i in range(KDV, KIN_ROWS):
                run[at(i, b)] = 0.0
        for j in range(joint_voff[k], joint_voff[k + 1]):
            kind, code = dof_kind[j], dof_axis[j]
            u0, u1, u2 = dof_u[j, 0], dof_u[j, 1], dof_u[j, 2]
            # one copy of the loop per (kind, axis code), each with its branches folded away:
            # a branch inside a vectorised loop runs both of its sides
            if kind == PRISMATIC:
                if code == 0:
                    _prismatic_axis(j, 0, u0, u1, u2, Q, QD, oP, run)
                elif code == 1:
                    _prismatic_axis(j, 1, u0, u1, u2, Q, QD, oP, run)
                elif code == 2:
                    _prismatic_axis(j, 2, u0, u1, u2, Q, QD, oP, run)
                else:
                    _prismatic_axis(j, 3, u0, u1, u2, Q, QD, oP, run)
            elif code == 0:
                _revolute_axis(j, 0, u0, u1, u2, Q, QD, oP, run)
            elif code == 1:
                _revolute_axis(j, 1, u0, u1, u2, Q, QD, oP, run)
            elif code == 2:
                _revolute_axis(j, 2, u0, u1, u2, Q, QD, oP, run)
            else:
                _revolute_axis(j, 3, u0, u1, u2, Q, QD, oP, run)
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
def _revolute_axis(j, code, u0, u1, u2, Q, QD, oP, run):
    """One revolute axis for every state: :func:`.joints.jcalc` and :func:`.joints.axis_rates`
    (qdd = 0) on the carry. ``code`` is the same for every state: one branch, outside the loop."""
    for b in range(LANES):
        r00, r01, r02 = run[at(KR + 0, b)], run[at(KR + 1, b)], run[at(KR + 2, b)]
        r10, r11, r12 = run[at(KR + 3, b)], run[at(KR + 4, b)], run[at(KR + 5, b)]
        r20, r21, r22 = run[at(KR + 6, b)], run[at(KR + 7, b)], run[at(KR + 8, b)]
        if code == 0:
            e0, e1, e2 = r00, r10, r20
        elif code == 1:
            e0, e1, e2 = r01, r11, r21
        elif code == 2:
            e0, e1, e2 = r02, r12, r22
        else:
            e0 = r00 * u0 + r01 * u1 + r02 * u2
            e1 = r10 * u0 + r11 * u1 + r12 * u2
            e2 = r20 * u0 + r21 * u1 + r22 * u2
        c, s = sincos_reduced(Q[at(j, b)])
        if code == 0:  # columns y, z mix
            n01, n11, n21 = c * r01 + s * r02, c * r11 + s * r12, c * r21 + s * r22
            n02, n12, n22 = c * r02 - s * r01, c * r12 - s * r11, c * r22 - s * r21
            r01, r11, r21, r02, r12, r22 = n01, n11, n21, n02, n12, n22
        elif code == 1:  # columns z, x mix
            n02, n12, n22 = c * r02 + s * r00, c * r12 + s * r10, c * r22 + s * r20
            n00, n10, n20 = c * r00 - s * r02, c * r10 - s * r12, c * r20 - s * r22
            r02, r12, r22, r00, r10, r20 = n02, n12, n22, n00, n10, n20
        elif code == 2:  # columns x, y mix
            n00, n10, n20 = c * r00 + s * r01, c * r10 + s * r11, c * r20 + s * r21
            n01, n11, n21 = c * r01 - s * r00, c * r11 - s * r10, c * r21 - s * r20
            r00, r10, r20, r01, r11, r21 = n00, n10, n20, n01, n11, n21
        else:  # R Rot(u, q)
            t = 1.0 - c
            g00, g01, g02 = c + t * u0 * u0, t * u0 * u1 - s * u2, t * u0 * u2 + s * u1
            g10, g11, g12 = t * u1 * u0 + s * u2, c + t * u1 * u1, t * u1 * u2 - s * u0
            g20, g21, g22 = t * u2 * u0 - s * u1, t * u2 * u1 + s * u0, c + t * u2 * u2
            r00, r01, r02, r10, r11, r12, r20, r21, r22 = (
                r00 * g00 + r01 * g10 + r02 * g20, r00 * g01 + r01 * g11 + r02 * g21,
                r00 * g02 + r01 * g12 + r02 * g22,
                r10 * g00 + r11 * g10 + r12 * g20, r10 * g01 + r11 * g11 + r12 * g21,
                r10 * g02 + r11 * g12 + r12 * g22,
                r20 * g00 + r21 * g10 + r22 * g20, r20 * g01 + r21 * g11 + r22 * g21,
                r20 * g02 + r21 * g12 + r22 * g22)
        oP[at(j * 6 + 0, b)] = e0
        oP[at(j * 6 + 1, b)] = e1
        oP[at(j * 6 + 2, b)] = e2
        oP[at(j * 6 + 3, b)] = 0.0
        oP[at(j * 6 + 4, b)] = 0.0
        oP[at(j * 6 + 5, b)] = 0.0
        run[at(KR + 0, b)], run[at(KR + 1, b)], run[at(KR + 2, b)] = r00, r01, r02
        run[at(KR + 3, b)], run[at(KR + 4, b)], run[at(KR + 5, b)] = r10, r11, r12
        run[at(KR + 6, b)], run[at(KR + 7, b)], run[at(KR + 8, b)] = r20, r21, r22
        # axis_rates, revolute, qdd = 0: da += Pd x = (om x e) x;  om += e x
        x = QD[at(j, b)]
        om0, om1, om2 = run[at(KOM + 0, b)], run[at(KOM + 1, b)], run[at(KOM + 2, b)]
        run[at(KDA + 0, b)] += 0.0 + (om1 * e2 - om2 * e1) * x
        run[at(KDA + 1, b)] += 0.0 + (om2 * e0 - om0 * e2) * x
        run[at(KDA + 2, b)] += 0.0 + (om0 * e1 - om1 * e0) * x
        run[at(KOM + 0, b)] = om0 + e0 * x
        run[at(KOM + 1, b)] = om1 + e1 * x
        run[at(KOM + 2, b)] = om2 + e2 * x


@inline
def _prismatic_axis(j, code, u0, u1, u2, Q, QD, oP, run):
    """One prismatic axis for every state (:func:`_revolute_axis`'s counterpart)."""
    for b in range(LANES):
        if code == 0:
            e0, e1, e2 = run[at(KR + 0, b)], run[at(KR + 3, b)], run[at(KR + 6, b)]
        elif code == 1:
            e0, e1, e2 = run[at(KR + 1, b)], run[at(KR + 4, b)], run[at(KR + 7, b)]
        elif code == 2:
            e0, e1, e2 = run[at(KR + 2, b)], run[at(KR + 5, b)], run[at(KR + 8, b)]
        else:
            e0 = run[at(KR + 0, b)] * u0 + run[at(KR + 1, b)] * u1 + run[at(KR + 2, b)] * u2
            e1 = run[at(KR + 3, b)] * u0 + run[at(KR + 4, b)] * u1 + run[at(KR + 5, b)] * u2
            e2 = run[at(KR + 6, b)] * u0 + run[at(KR + 7, b)] * u1 + run[at(KR + 8, b)] * u2
        qj = Q[at(j, b)]
        run[at(KS + 0, b)] += e0 * qj
        run[at(KS + 1, b)] += e1 * qj
        run[at(KS + 2, b)] += e2 * qj
        oP[at(j * 6 + 0, b)] = 0.0
        oP[at(j * 6 + 1, b)] = 0.0
        oP[at(j * 6 + 2, b)] = 0.0
        oP[at(j * 6 + 3, b)] = e0
        oP[at(j * 6 + 4, b)] = e1
        oP[at(j * 6 + 5, b)] = e2
        x = QD[at(j, b)]
        om0, om1, om2 = run[at(KOM + 0, b)], run[at(KOM + 1, b)], run[at(KOM + 2, b)]
        run[at(KDV + 0, b)] += e0 * x
        run[at(KDV + 1, b)] += e1 * x
        run[at(KDV + 2, b)] += e2 * x
        run[at(KDB + 0, b)] += 0.0 + (om1 * e2 - om2 * e1) * x
        run[at(KDB + 1, b)] += 0.0 + (om2 * e0 - om0 * e2) * x
        run[at(KDB + 2, b)] += 0.0 + (om0 * e1 - om1 * e0) * x


@jit_borrowed
def batch_backward(mass, inertia_O, mass_com, joint_voff, dof_kind, oR, oO, oP, W, C, TAU,
                   Psihat, phitil, car):
    """RGE-A's backward pass (:func:`.rge_a.rge_a_backward`, serial) for B states: reads the
    batch kinematics and TAU (n, B); writes Psihat (n, 6, B) and phitil (n, B). ``car``:
    (BACK_ROWS, B), the articulated mass and bias carried from body to body."""
    nb = mass.shape[0]
    for b in range(LANES):
        for i in range(BACK_ROWS):
            car[at(i, b)] = 0.0
    for k in range(nb - 1, -1, -1):
        m = mass[k]
        j00, j01, j02 = inertia_O[k, 0, 0], inertia_O[k, 0, 1], inertia_O[k, 0, 2]
        j11, j12, j22 = inertia_O[k, 1, 1], inertia_O[k, 1, 2], inertia_O[k, 2, 2]
        mc0, mc1, mc2 = mass_com[k, 0], mass_com[k, 1], mass_com[k, 2]
        if j01 == 0.0 and j02 == 0.0 and j12 == 0.0:
            _body_mass(k, True, m, j00, j01, j02, j11, j12, j22, mc0, mc1, mc2, oR, W, car)
        else:
            _body_mass(k, False, m, j00, j01, j02, j11, j12, j22, mc0, mc1, mc2, oR, W, car)
        for j in range(joint_voff[k + 1] - 1, joint_voff[k] - 1, -1):
            if dof_kind[j] == PRISMATIC:
                _eliminate(j, PRISMATIC, oP, TAU, Psihat, phitil, car)
            else:
                _eliminate(j, 0, oP, TAU, Psihat, phitil, car)
        if k > 0:
            _bias_and_shift(k, True, oO, C, car)
        else:
            _bias_and_shift(k, False, oO, C, car)


@inline
def _body_mass(k, principal, m, j00, j01, j02, j11, j12, j22, mc0, mc1, mc2, oR, W, car):
    """Body k's own mass and velocity-product wrench added to the carried articulated body,
    for every state (``principal``: its inertia is diagonal in its frame)."""
    for b in range(LANES):
        r00, r01, r02 = oR[at(k * 9 + 0, b)], oR[at(k * 9 + 1, b)], oR[at(k * 9 + 2, b)]
        r10, r11, r12 = oR[at(k * 9 + 3, b)], oR[at(k * 9 + 4, b)], oR[at(k * 9 + 5, b)]
        r20, r21, r22 = oR[at(k * 9 + 6, b)], oR[at(k * 9 + 7, b)], oR[at(k * 9 + 8, b)]
        if principal:
            X00 = j00 * (r00 * r00) + j11 * (r01 * r01) + j22 * (r02 * r02)
            X01 = j00 * (r00 * r10) + j11 * (r01 * r11) + j22 * (r02 * r12)
            X02 = j00 * (r00 * r20) + j11 * (r01 * r21) + j22 * (r02 * r22)
            X11 = j00 * (r10 * r10) + j11 * (r11 * r11) + j22 * (r12 * r12)
            X12 = j00 * (r10 * r20) + j11 * (r11 * r21) + j22 * (r12 * r22)
            X22 = j00 * (r20 * r20) + j11 * (r21 * r21) + j22 * (r22 * r22)
        else:
            c00 = r00 * j00 + r01 * j01 + r02 * j02
            c01 = r00 * j01 + r01 * j11 + r02 * j12
            c02 = r00 * j02 + r01 * j12 + r02 * j22
            c10 = r10 * j00 + r11 * j01 + r12 * j02
            c11 = r10 * j01 + r11 * j11 + r12 * j12
            c12 = r10 * j02 + r11 * j12 + r12 * j22
            c20 = r20 * j00 + r21 * j01 + r22 * j02
            c21 = r20 * j01 + r21 * j11 + r22 * j12
            c22 = r20 * j02 + r21 * j12 + r22 * j22
            X00 = c00 * r00 + c01 * r01 + c02 * r02
            X01 = c00 * r10 + c01 * r11 + c02 * r12
            X02 = c00 * r20 + c01 * r21 + c02 * r22
            X11 = c10 * r10 + c11 * r11 + c12 * r12
            X12 = c10 * r20 + c11 * r21 + c12 * r22
            X22 = c20 * r20 + c21 * r21 + c22 * r22
        d0 = r00 * mc0 + r01 * mc1 + r02 * mc2
        d1 = r10 * mc0 + r11 * mc1 + r12 * mc2
        d2 = r20 * mc0 + r21 * mc1 + r22 * mc2
        w0, w1, w2 = W[at(k * 3 + 0, b)], W[at(k * 3 + 1, b)], W[at(k * 3 + 2, b)]
        h0 = X00 * w0 + X01 * w1 + X02 * w2
        h1 = X01 * w0 + X11 * w1 + X12 * w2
        h2 = X02 * w0 + X12 * w1 + X22 * w2
        g0 = w1 * d2 - w2 * d1
        g1 = w2 * d0 - w0 * d2
        g2 = w0 * d1 - w1 * d0
        car[at(BX + 0, b)] += X00
        car[at(BX + 1, b)] += X01
        car[at(BX + 2, b)] += X02
        car[at(BX + 3, b)] += X11
        car[at(BX + 4, b)] += X12
        car[at(BX + 5, b)] += X22
        car[at(BY + 1, b)] -= d2
        car[at(BY + 2, b)] += d1
        car[at(BY + 3, b)] += d2
        car[at(BY + 5, b)] -= d0
        car[at(BY + 6, b)] -= d1
        car[at(BY + 7, b)] += d0
        car[at(BZ + 0, b)] += m
        car[at(BZ + 3, b)] += m
        car[at(BZ + 5, b)] += m
        car[at(BN + 0, b)] += w1 * h2 - w2 * h1
        car[at(BN + 1, b)] += w2 * h0 - w0 * h2
        car[at(BN + 2, b)] += w0 * h1 - w1 * h0
        car[at(BF + 0, b)] += w1 * g2 - w2 * g1
        car[at(BF + 1, b)] += w2 * g0 - w0 * g2
        car[at(BF + 2, b)] += w0 * g1 - w1 * g0


@inline
def _eliminate(j, kind, oP, TAU, Psihat, phitil, car):
    """One axis of Table A.1 for every state: phihat, Psi, Ihat, phitil, Psihat, and the
    articulated mass and bias updated (the loop of :func:`.rge_a._rge_a_backward`)."""
    for b in range(LANES):
        p0, p1, p2 = oP[at(j * 6 + 0, b)], oP[at(j * 6 + 1, b)], oP[at(j * 6 + 2, b)]
        p3, p4, p5 = oP[at(j * 6 + 3, b)], oP[at(j * 6 + 4, b)], oP[at(j * 6 + 5, b)]
        x00, x01, x02 = car[at(BX + 0, b)], car[at(BX + 1, b)], car[at(BX + 2, b)]
        x11, x12, x22 = car[at(BX + 3, b)], car[at(BX + 4, b)], car[at(BX + 5, b)]
        y00, y01, y02 = car[at(BY + 0, b)], car[at(BY + 1, b)], car[at(BY + 2, b)]
        y10, y11, y12 = car[at(BY + 3, b)], car[at(BY + 4, b)], car[at(BY + 5, b)]
        y20, y21, y22 = car[at(BY + 6, b)], car[at(BY + 7, b)], car[at(BY + 8, b)]
        z00, z01, z02 = car[at(BZ + 0, b)], car[at(BZ + 1, b)], car[at(BZ + 2, b)]
        z11, z12, z22 = car[at(BZ + 3, b)], car[at(BZ + 4, b)], car[at(BZ + 5, b)]
        n0, n1, n2 = car[at(BN + 0, b)], car[at(BN + 1, b)], car[at(BN + 2, b)]
        f0, f1, f2 = car[at(BF + 0, b)], car[at(BF + 1, b)], car[at(BF + 2, b)]
        ph = TAU[at(j, b)] - (p0 * n0 + p1 * n1 + p2 * n2 + p3 * f0 + p4 * f1 + p5 * f2)
        e0, e1, e2 = p0 + p3, p1 + p4, p2 + p5
        if kind == PRISMATIC:
            u0 = y00 * e0 + y01 * e1 + y02 * e2
            u1 = y10 * e0 + y11 * e1 + y12 * e2
            u2 = y20 * e0 + y21 * e1 + y22 * e2
            u3 = z00 * e0 + z01 * e1 + z02 * e2
            u4 = z01 * e0 + z11 * e1 + z12 * e2
            u5 = z02 * e0 + z12 * e1 + z22 * e2
            ih = e0 * u3 + e1 * u4 + e2 * u5
        else:
            u0 = x00 * e0 + x01 * e1 + x02 * e2
            u1 = x01 * e0 + x11 * e1 + x12 * e2
            u2 = x02 * e0 + x12 * e1 + x22 * e2
            u3 = y00 * e0 + y10 * e1 + y20 * e2
            u4 = y01 * e0 + y11 * e1 + y21 * e2
            u5 = y02 * e0 + y12 * e1 + y22 * e2
            ih = e0 * u0 + e1 * u1 + e2 * u2
        inv = 1.0 / ih
        v0, v1, v2, v3, v4, v5 = u0 * inv, u1 * inv, u2 * inv, u3 * inv, u4 * inv, u5 * inv
        ptil = ph * inv
        phitil[at(j, b)] = ptil
        Psihat[at(j * 6 + 0, b)] = v0
        Psihat[at(j * 6 + 1, b)] = v1
        Psihat[at(j * 6 + 2, b)] = v2
        Psihat[at(j * 6 + 3, b)] = v3
        Psihat[at(j * 6 + 4, b)] = v4
        Psihat[at(j * 6 + 5, b)] = v5
        car[at(BN + 0, b)] = n0 + u0 * ptil
        car[at(BN + 1, b)] = n1 + u1 * ptil
        car[at(BN + 2, b)] = n2 + u2 * ptil
        car[at(BF + 0, b)] = f0 + u3 * ptil
        car[at(BF + 1, b)] = f1 + u4 * ptil
        car[at(BF + 2, b)] = f2 + u5 * ptil
        car[at(BX + 0, b)] = x00 - v0 * u0
        car[at(BX + 1, b)] = x01 - v0 * u1
        car[at(BX + 2, b)] = x02 - v0 * u2
        car[at(BX + 3, b)] = x11 - v1 * u1
        car[at(BX + 4, b)] = x12 - v1 * u2
        car[at(BX + 5, b)] = x22 - v2 * u2
        car[at(BY + 0, b)] = y00 - v0 * u3
        car[at(BY + 1, b)] = y01 - v0 * u4
        car[at(BY + 2, b)] = y02 - v0 * u5
        car[at(BY + 3, b)] = y10 - v1 * u3
        car[at(BY + 4, b)] = y11 - v1 * u4
        car[at(BY + 5, b)] = y12 - v1 * u5
        car[at(BY + 6, b)] = y20 - v2 * u3
        car[at(BY + 7, b)] = y21 - v2 * u4
        car[at(BY + 8, b)] = y22 - v2 * u5
        car[at(BZ + 0, b)] = z00 - v3 * u3
        car[at(BZ + 1, b)] = z01 - v3 * u4
        car[at(BZ + 2, b)] = z02 - v3 * u5
        car[at(BZ + 3, b)] = z11 - v4 * u4
        car[at(BZ + 4, b)] = z12 - v4 * u5
        car[at(BZ + 5, b)] = z22 - v5 * u5


@inline
def _bias_and_shift(k, shift, oO, C, car):
    """Body k's articulated bias p += Mbar_k c_k, then Mbar and p shifted to the parent's origin
    (A_{k,k-1}^T Mbar A and A^T p), for every state."""
    for b in range(LANES):
        x00, x01, x02 = car[at(BX + 0, b)], car[at(BX + 1, b)], car[at(BX + 2, b)]
        x11, x12, x22 = car[at(BX + 3, b)], car[at(BX + 4, b)], car[at(BX + 5, b)]
        y00, y01, y02 = car[at(BY + 0, b)], car[at(BY + 1, b)], car[at(BY + 2, b)]
        y10, y11, y12 = car[at(BY + 3, b)], car[at(BY + 4, b)], car[at(BY + 5, b)]
        y20, y21, y22 = car[at(BY + 6, b)], car[at(BY + 7, b)], car[at(BY + 8, b)]
        z00, z01, z02 = car[at(BZ + 0, b)], car[at(BZ + 1, b)], car[at(BZ + 2, b)]
        z11, z12, z22 = car[at(BZ + 3, b)], car[at(BZ + 4, b)], car[at(BZ + 5, b)]
        ca0, ca1, ca2 = C[at(k * 6 + 0, b)], C[at(k * 6 + 1, b)], C[at(k * 6 + 2, b)]
        cb0, cb1, cb2 = C[at(k * 6 + 3, b)], C[at(k * 6 + 4, b)], C[at(k * 6 + 5, b)]
        n0 = car[at(BN + 0, b)] + ((x00 * ca0 + x01 * ca1 + x02 * ca2)
                               + (y00 * cb0 + y01 * cb1 + y02 * cb2))
        n1 = car[at(BN + 1, b)] + ((x01 * ca0 + x11 * ca1 + x12 * ca2)
                               + (y10 * cb0 + y11 * cb1 + y12 * cb2))
        n2 = car[at(BN + 2, b)] + ((x02 * ca0 + x12 * ca1 + x22 * ca2)
                               + (y20 * cb0 + y21 * cb1 + y22 * cb2))
        f0 = car[at(BF + 0, b)] + ((y00 * ca0 + y10 * ca1 + y20 * ca2)
                               + (z00 * cb0 + z01 * cb1 + z02 * cb2))
        f1 = car[at(BF + 1, b)] + ((y01 * ca0 + y11 * ca1 + y21 * ca2)
                               + (z01 * cb0 + z11 * cb1 + z12 * cb2))
        f2 = car[at(BF + 2, b)] + ((y02 * ca0 + y12 * ca1 + y22 * ca2)
                               + (z02 * cb0 + z12 * cb1 + z22 * cb2))
        if shift:
            s0 = oO[at((k - 1) * 3 + 0, b)] - oO[at(k * 3 + 0, b)]
            s1 = oO[at((k - 1) * 3 + 1, b)] - oO[at(k * 3 + 1, b)]
            s2 = oO[at((k - 1) * 3 + 2, b)] - oO[at(k * 3 + 2, b)]
            n0 -= s1 * f2 - s2 * f1
            n1 -= s2 * f0 - s0 * f2
            n2 -= s0 * f1 - s1 * f0
            S00 = y01 * s2 - y02 * s1
            S01 = y02 * s0 - y00 * s2
            S02 = y00 * s1 - y01 * s0
            S10 = y11 * s2 - y12 * s1
            S11 = y12 * s0 - y10 * s2
            S12 = y10 * s1 - y11 * s0
            S20 = y21 * s2 - y22 * s1
            S21 = y22 * s0 - y20 * s2
            S22 = y20 * s1 - y21 * s0
            q00 = s1 * z02 - s2 * z01
            q01 = s1 * z12 - s2 * z11
            q02 = s1 * z22 - s2 * z12
            q10 = s2 * z00 - s0 * z02
            q11 = s2 * z01 - s0 * z12
            q12 = s2 * z02 - s0 * z22
            q20 = s0 * z01 - s1 * z00
            q21 = s0 * z11 - s1 * z01
            q22 = s0 * z12 - s1 * z02
            car[at(BX + 0, b)] = x00 + (2.0 * S00 - (q01 * s2 - q02 * s1))
            car[at(BX + 1, b)] = x01 + (S01 + S10 - (q02 * s0 - q00 * s2))
            car[at(BX + 2, b)] = x02 + (S02 + S20 - (q00 * s1 - q01 * s0))
            car[at(BX + 3, b)] = x11 + (2.0 * S11 - (q12 * s0 - q10 * s2))
            car[at(BX + 4, b)] = x12 + (S12 + S21 - (q10 * s1 - q11 * s0))
            car[at(BX + 5, b)] = x22 + (2.0 * S22 - (q20 * s1 - q21 * s0))
            car[at(BY + 0, b)] = y00 - q00
            car[at(BY + 1, b)] = y01 - q01
            car[at(BY + 2, b)] = y02 - q02
            car[at(BY + 3, b)] = y10 - q10
            car[at(BY + 4, b)] = y11 - q11
            car[at(BY + 5, b)] = y12 - q12
            car[at(BY + 6, b)] = y20 - q20
            car[at(BY + 7, b)] = y21 - q21
            car[at(BY + 8, b)] = y22 - q22
        car[at(BN + 0, b)] = n0
        car[at(BN + 1, b)] = n1
        car[at(BN + 2, b)] = n2
        car[at(BF + 0, b)] = f0
        car[at(BF + 1, b)] = f1
        car[at(BF + 2, b)] = f2


@jit_borrowed
def batch_forward(joint_voff, oO, oP, Psihat, phitil, C, base_accel, QDD, mu, bad):
    """RGE-A's forward pass (:func:`.rge_a.rge_a_forward`, serial) for B states: QDD (n, B).
    ``mu``: (6, B), carried from body to body; ``bad`` (B,): 0 where every qdd of that state is
    finite, NaN where one is not."""
    nb = joint_voff.shape[0] - 1
    for b in range(LANES):
        mu[at(0, b)] = C[at(0 * 6 + 0, b)]
        mu[at(1, b)] = C[at(0 * 6 + 1, b)]
        mu[at(2, b)] = C[at(0 * 6 + 2, b)]
        mu[at(3, b)] = base_accel[0] + C[at(0 * 6 + 3, b)]
        mu[at(4, b)] = base_accel[1] + C[at(0 * 6 + 4, b)]
        mu[at(5, b)] = base_accel[2] + C[at(0 * 6 + 5, b)]
        bad[b] = 0.0
    for k in range(nb):
        jl = joint_voff[k + 1] - 1
        for j in range(joint_voff[k], jl + 1):
            if j < jl or k + 1 == nb:
                _forward_axis(j, oP, Psihat, phitil, QDD, mu, bad)
            else:
                _forward_axis_on(j, k, oO, oP, Psihat, phitil, C, QDD, mu, bad)


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


@jit_borrowed
def tile_in(src, t0, count, dst):
    """dst[(j, b)] = src[t0 + b, j] for b < count; the tile's spare lanes repeat state t0."""
    n = src.shape[1]
    for j in range(n):
        for b in range(LANES):
            dst[at(j, b)] = src[t0 + (b if b < count else 0), j]


@jit_borrowed
def tile_out(src, t0, count, dst):
    """dst[t0 + b, j] = src[(j, b)] for b < count."""
    n = dst.shape[1]
    for b in range(count):
        for j in range(n):
            dst[t0 + b, j] = src[at(j, b)]


def main() -> None:
    import redysim
    from redysim.workspace import tree_tables

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--dof", type=int, default=250)
    ap.add_argument("--batch", type=int, default=64)
    a = ap.parse_args()
    L, B, n = LANES, a.batch, a.dof
    ch = redysim.Chain.uniform(n // 2, "U", length=0.02, linear_density=61.6538, radius=0.05,
                               inertia="rod")
    t = tree_tables(ch)
    nb = t["mass"].shape[0]
    rng = np.random.default_rng(0)
    Q, QD, TAU = (rng.uniform(-2, 2, (B, n)), rng.uniform(-1, 1, (B, n)),
                  rng.uniform(-1, 1, (B, n)))
    ws = redysim.Workspace(ch)
    ref = np.array([redysim.forward_dynamics(ch, Q[i], QD[i], TAU[i], ws=ws) for i in range(B)])

    def z(rows):
        return np.zeros(rows * L)

    oR, oO, oP, W, C = z(nb * 9), z(nb * 3), z(n * 6), z(nb * 3), z(nb * 6)
    run, car, Ps, pt, mu, bad = z(KIN_ROWS), z(BACK_ROWS), z(n * 6), z(n), z(6), np.zeros(L)
    Qt, QDt, Tt, QDDt = z(n), z(n), z(n), z(n)
    out = np.empty((B, n))
    ba = -np.asarray(ch.gravity, float)
    kin = (t["along"], t["joint_voff"], t["dof_kind"], t["dof_axis"], t["dof_u"], Qt, QDt, oR,
           oO, oP, W, C, run)
    back = (t["mass"], t["inertia_O"], t["mass_com"], t["joint_voff"], t["dof_kind"], oR, oO,
            oP, W, C, Tt, Ps, pt, car)
    fwd = (t["joint_voff"], oO, oP, Ps, pt, C, ba, QDDt, mu, bad)

    def batch():
        for t0 in range(0, B, L):
            count = min(L, B - t0)
            tile_in(Q, t0, count, Qt)
            tile_in(QD, t0, count, QDt)
            tile_in(TAU, t0, count, Tt)
            batch_kinematics(*kin)
            batch_backward(*back)
            batch_forward(*fwd)
            tile_out(QDDt, t0, count, out)

    t0 = time.perf_counter()
    batch()
    print(f"compile {time.perf_counter() - t0:.1f} s; LANES = {L}")
    print(f"largest difference from the single calls: "
          f"{np.abs(out - ref).max() / np.abs(ref).max():.1e} of max |qdd|")

    def best(f, number):
        return min(timeit.repeat(f, number=number, repeat=5)) / number * 1e6

    tb = best(batch, 20)
    ts = best(lambda: [redysim.forward_dynamics(ch, Q[i], QD[i], TAU[i], ws=ws)
                       for i in range(B)], 20)
    print(f"{B} states at {n} DOF: tiles {tb:.0f} us, {B} single calls {ts:.0f} us "
          f"({ts / tb:.2f}x)")
    for name, f, args in (("kinematics", batch_kinematics, kin),
                          ("backward", batch_backward, back), ("forward", batch_forward, fwd)):
        print(f"  {name:<10} {best(lambda f=f, args=args: f(*args), 50) / L:.2f} us a state")


if __name__ == "__main__":
    main()
