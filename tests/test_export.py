"""Export to MJCF and URDF: a model read back has the same dynamics, and MuJoCo agrees.

Read back through redysim.load_model (MuJoCo's parser), an exported model may order its bodies
differently (MuJoCo lists them depth first) and splits a U or S joint into one joint per axis:
its coordinates are matched to the original's by joint name.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from conftest import random_chain, random_state, rel, stable_seed
from test_trees import random_configuration, random_tree

from redysim import Chain, Model, forward_dynamics, load_model, mass_matrix
from redysim.export import to_mjcf, to_urdf

pytest.importorskip("mujoco")


def _v_names(model: Model) -> list[str]:
    """The name each velocity coordinate gets in an exported file."""
    names = []
    for k, jn in enumerate(model.joint_names):
        n = model.joint_voff[k + 1] - model.joint_voff[k]
        if model.joint_types[k] == "free":
            names += [f"{jn}:{i}" for i in range(n)]
        else:
            names += [jn] if n == 1 else [f"{jn}_{i}" for i in range(n)]
    return names


def _permutation(original: Model, back: Model) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays p_v, p_q with back's coordinate i = original's p[i]."""
    where = {name: i for i, name in enumerate(_v_names(original))}
    back_names = _v_names(back)
    free_back = [k for k, t in enumerate(back.joint_types) if t == "free"]
    free_orig = [k for k, t in enumerate(original.joint_types) if t == "free"]
    for kb, ko in zip(free_back, free_orig, strict=True):  # the free joint keeps its place
        for i in range(6):
            back_names[back.joint_voff[kb] + i] = f"{original.joint_names[ko]}:{i}"
    p_v = np.array([where[n] for n in back_names])
    p_q = []
    for k in range(back.n_bodies):
        if back.joint_types[k] == "free":
            ko = free_orig[free_back.index(k)]
            p_q += list(range(original.joint_qoff[ko], original.joint_qoff[ko] + 7))
        else:
            p_q += [p_v[j] + _qshift(original, p_v[j])
                    for j in range(back.joint_voff[k], back.joint_voff[k + 1])]
    return p_v, np.array(p_q)


def _qshift(model: Model, j: int) -> int:
    k = int(np.searchsorted(model.joint_voff, j, side="right") - 1)
    return int(model.joint_qoff[k] - model.joint_voff[k])


@pytest.mark.parametrize("fmt", ["mjcf", "urdf"])
@pytest.mark.parametrize("free", [False, True])
@pytest.mark.parametrize("seed", range(3))
def test_an_exported_tree_reads_back_with_the_same_dynamics(tmp_path, fmt, free, seed):
    model = random_tree(stable_seed("export", seed), n_bodies=7, free=free)
    path = tmp_path / ("m.xml" if fmt == "mjcf" else "m.urdf")
    path.write_text(to_mjcf(model) if fmt == "mjcf" else to_urdf(model))
    back = load_model(path, floating=free) if fmt == "urdf" else load_model(path)
    if fmt == "urdf":  # URDF has no gravity: the importer's is -9.81 along z
        model = dataclasses.replace(model, gravity=back.gravity)
    assert (back.n_q, back.n_v) == (model.n_q, model.n_v)
    assert back.total_mass == pytest.approx(model.total_mass, rel=1e-15)
    p_v, p_q = _permutation(model, back)
    rng = np.random.default_rng(seed)
    q, v = random_configuration(rng, model), rng.normal(size=model.n_v)
    M = mass_matrix(model, q)
    assert rel(mass_matrix(back, q[p_q]), M[np.ix_(p_v, p_v)]) < 1e-13
    assert rel(forward_dynamics(back, q[p_q], v[p_v]), forward_dynamics(model, q, v)[p_v]) \
        < 1e-12


@pytest.mark.parametrize("mix", [("U",), ("R", "U", "S", "P")], ids="".join)
def test_a_rope_exported_to_mjcf_is_the_same_system_in_mujoco(mix):
    """MuJoCo's own GIM and bias of the exported chain (no redysim importer in between)."""
    import mujoco

    rng = np.random.default_rng(stable_seed("export-mujoco", mix))
    chain = random_chain(rng, 8, mix)
    q, qd, _ = random_state(rng, chain, "gentle")
    m = mujoco.MjModel.from_xml_string(to_mjcf(chain))
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:] = q, qd
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    assert rel(M, mass_matrix(chain, q)) < 1e-12
    assert rel(d.qacc, forward_dynamics(chain, q, qd)) < 1e-10


def test_a_chain_exports_as_its_model():
    chain = Chain.uniform(3, "U", length=0.5, mass=1.0, radius=0.05)
    assert to_mjcf(chain) == to_mjcf(Model.from_chain(chain))
    assert "<freejoint" not in to_mjcf(chain) and "continuous" in to_urdf(chain)
