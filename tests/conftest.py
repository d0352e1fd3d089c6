"""Shared test helpers: seeded random chains and an independent DeNOC assembly."""

from __future__ import annotations

import hashlib
import os

# Runs in tests are checks, not rankings: each is measured once (redysim.harness.cost; the
# repeats would add ~0.2 s of CPU to every short run of every sweep). Pool workers inherit it;
# tests of the repeats set it themselves.
os.environ.setdefault("REDYSIM_COST_REPEAT_S", "0")

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from redysim import Chain, Joint, Link
from redysim.model.parts import JOINT_TYPES

EPS = np.finfo(float).eps

# Nothing writes into the checkout at test time: MuJoCo appends its warnings to MUJOCO_LOG.TXT
# in the working directory unless a handler takes them (here: Python warnings), and Hypothesis
# keeps no example database (.hypothesis/).
try:
    import mujoco
except ImportError:  # a base install: no MuJoCo to silence
    pass
else:
    import warnings

    mujoco.set_mju_user_warning(lambda text: warnings.warn(f"MuJoCo: {text}", stacklevel=1))
try:
    from hypothesis import settings as _hypothesis
    from hypothesis.configuration import set_hypothesis_home_dir
except ImportError:
    pass
else:
    import tempfile

    # its other caches (constants, Unicode tables) go where its home is: not the checkout
    set_hypothesis_home_dir(tempfile.mkdtemp(prefix="redysim-hypothesis-"))
    _hypothesis.register_profile("redysim", database=None)
    _hypothesis.load_profile("redysim")


def random_inertia(rng, mass, length):
    """A physically valid inertia about the COM: a rotated box's principal moments."""
    a, b, c = length, rng.uniform(0.02, 0.3) * length, rng.uniform(0.02, 0.3) * length
    moments = mass / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    Q = Rotation.random(random_state=rng).as_matrix() if rng.random() < 0.5 else np.eye(3)
    return Q @ np.diag(moments) @ Q.T


def random_chain(rng, n_links, joint_types=("R", "U", "S", "P"), general_axes=True) -> Chain:
    """A chain of random links and a random mix of the given joint types."""
    links, joints = [], []
    for _ in range(n_links):
        length = rng.uniform(0.1, 1.0)
        mass = rng.uniform(0.1, 2.0)
        com = np.array([length / 2, 0.0, 0.0]) + rng.normal(scale=0.05 * length, size=3)
        links.append(Link(length, mass, tuple(com), tuple(map(tuple, random_inertia(rng, mass,
                                                                                    length)))))
        jt = str(rng.choice(joint_types))
        axis = None
        if jt in ("R", "P") and general_axes and rng.random() < 0.3:
            axis = tuple(rng.normal(size=3))
        elif jt in ("R", "P") and general_axes:
            axis = str(rng.choice(["x", "y", "z"]))
        joints.append(Joint(jt, axis))
    return Chain.build(links, joints, gravity=(0.0, -9.81, 0.0), name="random")


def random_state(rng, chain, spread="wide"):
    """q spread over (-pi, pi) ("wide") or near the straight chain ("straight")."""
    n = chain.n_dof
    if spread == "wide":
        q = rng.uniform(-np.pi, np.pi, n)
    else:
        q = rng.normal(scale=0.05, size=n)
    return q, rng.normal(size=n), rng.normal(size=n)


def cross_matrix(a):
    return np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])


def denoc_gim(chain: Chain, q) -> np.ndarray:
    """The GIM as N_d^T N_l^T M N_l N_d (Eq. 7-10a), assembled explicitly in numpy.

    Independent of the kernels: rotations from SciPy, inertia about O_k from the COM inertia by
    the parallel-axis theorem, every block matrix built whole.
    """
    nl, n = chain.n_links, chain.n_dof
    R = np.eye(3)
    O = np.zeros(3)
    Os, Ms, Pcols = [], [], []
    j = 0
    for k, joint in enumerate(chain.joints):
        if k > 0:
            O = O + chain.length[k - 1] * R[:, 0]
        cols = []
        for kind, u in joint.axes():
            e = R @ u
            if kind == "R":
                cols.append(np.concatenate([e, np.zeros(3)]))
                R = R @ Rotation.from_rotvec(u * q[j]).as_matrix()
            else:
                cols.append(np.concatenate([np.zeros(3), e]))
                O = O + e * q[j]
            j += 1
        Os.append(O.copy())
        Pcols.append(np.array(cols).T)
        m = chain.mass[k]
        d = R @ chain.com[k]
        I_O = R @ chain.inertia_com[k] @ R.T + m * (d @ d * np.eye(3) - np.outer(d, d))
        Mk = np.zeros((6, 6))
        Mk[:3, :3] = I_O
        Mk[:3, 3:] = m * cross_matrix(d)
        Mk[3:, :3] = -m * cross_matrix(d)
        Mk[3:, 3:] = m * np.eye(3)
        Ms.append(Mk)
    N_l = np.zeros((6 * nl, 6 * nl))
    for i in range(nl):
        for jj in range(i + 1):
            A = np.eye(6)
            A[3:, :3] = cross_matrix(Os[jj] - Os[i])  # a_{ij}: from O_i to O_j
            N_l[6 * i:6 * i + 6, 6 * jj:6 * jj + 6] = A
    N_d = np.zeros((6 * nl, n))
    M = np.zeros((6 * nl, 6 * nl))
    c = 0
    for k in range(nl):
        z = Pcols[k].shape[1]
        N_d[6 * k:6 * k + 6, c:c + z] = Pcols[k]
        M[6 * k:6 * k + 6, 6 * k:6 * k + 6] = Ms[k]
        c += z
    N = N_l @ N_d
    return N.T @ M @ N


def rel(a, b) -> float:
    """max |a - b| / max |b| (max-norm relative difference)."""
    return float(np.max(np.abs(np.asarray(a) - np.asarray(b))) / np.max(np.abs(b)))


def stable_seed(*parts) -> int:
    """A seed from ``parts`` that is the same in every process (Python's ``hash`` of a string
    is randomised per process, so a failing chain could not be built again)."""
    return int.from_bytes(hashlib.sha256(repr(parts).encode()).digest()[:8], "little")


@pytest.fixture
def rng():
    return np.random.default_rng(20261122)


ALL_JOINT_MIXES = [("R",), ("U",), ("S",), ("P",), tuple(JOINT_TYPES)]


def pytest_terminal_summary(terminalreporter):
    """Where the browser tests kept their first screens (tests/test_browser.py), when any ran."""
    import sys

    check = sys.modules.get("redysim.reports.browser_check")
    for folder in check.artefacts_used() if check else ():
        terminalreporter.write_line(f"browser check: first screens kept in {folder}")
