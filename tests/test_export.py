"""Export to MJCF and URDF: a model read back has the same dynamics, MuJoCo agrees, and what a
format cannot hold is refused by name.

Read back through redysim.load_model (MuJoCo's parser), an exported model may order its bodies
differently (MuJoCo lists them depth first), splits a U or S joint into one joint per axis and a
body with several joints into massless bodies again: its coordinates are matched to the
original's by joint name. MuJoCo itself (mj_forward's qacc, mj_fullM, qpos0) checks every MJCF
file without redysim's importer in between: the truth that "MuJoCo accepts it".
"""

from __future__ import annotations

import dataclasses
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
from conftest import random_chain, random_inertia, random_state, rel, stable_seed
from scipy.spatial.transform import Rotation
from test_trees import MJCF, random_configuration, random_tree, robot_urdf

import redysim
from redysim import Chain, Link, Model, forward_dynamics, load_model, mass_matrix, passive_forces
from redysim.io.export import MJCF_MAX_DEPTH, ExportError, to_mjcf, to_urdf
from redysim.io.importers import load_urdf
from redysim.model.tree import Body, TreeJoint

mujoco = pytest.importorskip("mujoco")

CASES = Path(__file__).resolve().parents[1] / "cases"
# GIM and qdd of a model read back by redysim, relative to the original's: the files carry every
# number to 17 digits, placements as xyaxes / rpy and inertias as principal axes, which cost a
# few ulps (measured <= 1.3e-13, the Stanford arm's qdd; most are 0 or 1e-16)
TOL = 1e-12
EPS = np.finfo(float).eps


def _mujoco_tol(M: np.ndarray) -> float:
    """MuJoCo's qacc against ours: two algorithms (its LDL of the CRBA matrix, our RGE-A), each
    backward stable, so their qdd differ by up to about cond(M) eps (measured <= 0.3 cond(M) eps
    on every shipped case: 5.7e-10 on fall-R256, cond 1.2e8); never tighter than TOL."""
    return max(TOL, float(np.linalg.cond(M)) * EPS)


# --------------------------------------------------------------------------- matching coordinates
def _file_joints(model: Model) -> dict[str, tuple[list[int], list[int]]]:
    """Each joint of an exported file, by its name there: (q indices, v indices) in ``model``."""
    out = {}
    for k, jn in enumerate(model.joint_names):
        qs, vs = int(model.joint_qoff[k]), int(model.joint_voff[k])
        n = int(model.joint_voff[k + 1]) - vs
        if model.joint_types[k] == "free":
            out[jn] = (list(range(qs, qs + 7)), list(range(vs, vs + 6)))
            continue
        for i, name in enumerate([jn] if n == 1 else [f"{jn}_{i}" for i in range(n)]):
            out[name] = ([qs + i], [vs + i])
    return out


def _permutation(original: Model, back: Model) -> tuple[np.ndarray, np.ndarray]:
    """Index arrays p_q, p_v with back's coordinate i = original's p[i] (free joints, which a
    URDF reader names itself, matched in order)."""
    ours, theirs = _file_joints(original), _file_joints(back)
    free = dict(zip([n for n, t in zip(back.joint_names, back.joint_types, strict=True)
                     if t == "free"],
                    [n for n, t in zip(original.joint_names, original.joint_types, strict=True)
                     if t == "free"], strict=True))
    assert sorted(free.get(n, n) for n in theirs) == sorted(ours)
    p_q, p_v = np.empty(back.n_q, dtype=int), np.empty(back.n_v, dtype=int)
    for name, (bq, bv) in theirs.items():
        oq, ov = ours[free.get(name, name)]
        p_q[bq], p_v[bv] = oq, ov
    return p_q, p_v


def _states(model: Model, seed, n: int = 2):
    rng = np.random.default_rng(seed)
    for _ in range(n):
        yield random_configuration(rng, model), rng.normal(size=model.n_v)


def _reads_back(model: Model, text: str, fmt: str, tmp_path, seed) -> Model:
    """Load the exported text with redysim.load_model; GIM and qdd equal the original's at two
    random states (the URDF of a model with a free joint is loaded floating)."""
    path = tmp_path / ("m.xml" if fmt == "mjcf" else "m.urdf")
    path.write_text(text)
    if fmt == "urdf":  # the file says whether it is to be loaded floating (hold-out battery 6)
        assert ("floating=True" in text) == ("free" in model.joint_types)
    back = load_model(path, floating="free" in model.joint_types) if fmt == "urdf" \
        else load_model(path)
    assert (back.n_q, back.n_v) == (model.n_q, model.n_v)
    assert back.total_mass == pytest.approx(model.total_mass, rel=1e-15)
    p_q, p_v = _permutation(model, back)
    for q, v in _states(model, seed):
        M = mass_matrix(model, q)
        assert rel(mass_matrix(back, q[p_q]), M[np.ix_(p_v, p_v)]) < TOL
        assert rel(forward_dynamics(back, q[p_q], v[p_v]), forward_dynamics(model, q, v)[p_v]) \
            < TOL
    return back


def _mujoco_agrees(model: Model, text: str, seed) -> None:
    """MuJoCo compiles the MJCF text; its qpos0 is the model's initial configuration and its
    mass matrix and qacc (mj_forward, no constraints, the passive forces the file gives) equal
    ours at two random states."""
    m = mujoco.MjModel.from_xml_string(text)
    d = mujoco.MjData(m)
    ours = _file_joints(model)
    assert sorted(m.joint(j).name for j in range(m.njnt)) == sorted(ours)
    p_q, p_v = np.empty(m.nq, dtype=int), np.empty(m.nv, dtype=int)
    for j in range(m.njnt):
        oq, ov = ours[m.joint(j).name]
        a, b = m.jnt_qposadr[j], m.jnt_dofadr[j]
        p_q[a:a + len(oq)], p_v[b:b + len(ov)] = oq, ov
    assert np.allclose(m.qpos0, model.initial()[p_q], rtol=0, atol=1e-15)
    for q, v in _states(model, seed):
        d.qpos[:], d.qvel[:] = q[p_q], v[p_v]
        mujoco.mj_forward(m, d)
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M)
        ours = mass_matrix(model, q)
        assert rel(M, ours[np.ix_(p_v, p_v)]) < TOL
        # (the model's passive elements are the file's: MuJoCo applies them in mj_forward)
        qdd = forward_dynamics(model, q, v, passive_forces(model, q, v))
        assert rel(d.qacc, qdd[p_v]) < _mujoco_tol(ours)


def _round_trip(model: Model, fmt: str, tmp_path, seed) -> Model:
    text = to_mjcf(model) if fmt == "mjcf" else to_urdf(model)
    if fmt == "mjcf":
        _mujoco_agrees(model, text, seed)
    return _reads_back(model, text, fmt, tmp_path, seed)


# --------------------------------------------------------------------------- every shipped model
def _rope(name):
    return lambda: redysim.load_case(name).chain


def _file(path):
    return lambda: redysim.load_model(CASES / path)


def _linkage(path):
    return lambda: redysim.load_linkage(CASES / path).model.with_cuts(())  # the open tree


def _robot(name, floating):
    return lambda: load_urdf(robot_urdf(name), floating=floating, mimic="independent")


ROD = ("body 'link1'.inertia", r"triangle inequality Iyy \+ Izz >= Ixx .*cylinder")
THIN = ("body 'link1'.inertia", r"principal moment 0.0 kg m\^2 about the body's axis "
        r"\(1.0, 0.0, 0.0\).*mjMINVAL")
CRANK = ("body 'crank'.inertia", THIN[1])
# (id, model, what to_mjcf does: None = writes a file that round-trips, else (field, message))
SHIPPED = [
    *[(n, _rope(n), THIN) for n in ("RE-R229-L1.02-DX0.765", "RE-R229-L1.02-DX1.02")],
    *[(n, _rope(n), ROD) for n in ("RE-U125-L1", "RE-U250-L2", "RE-U375-L3")],
    *[(n, _rope(n), None) for n in ("STUDY-R3", "STUDY-R3-TABLE9", "STUDY-R5", "STUDY-R10",
                                    "STUDY-R20", "STUDY-R40", "STUDY-R60", "STUDY-R80",
                                    "STUDY-R100")],
    ("fall-R256", _file("refine/fall-R256.toml"), None),
    ("hanging-R1024", _file("refine/hanging-R1024.toml"), ROD),
    ("pulled-R128", _file("refine/pulled-R128.toml"), None),
    ("spin-U250-L1", _file("refine/spin-U250-L1.toml"), ROD),
    ("puma560", _file("robots/puma560.toml"),
     ("body 'waist'.mass", r"mass 0.0 but rotational inertia .*mjMINVAL")),
    ("stanford_arm", _file("robots/stanford_arm.toml"), None),
    ("crank_rocker", _linkage("loops/crank_rocker.toml"), CRANK),
    ("hoekens_straight_line", _linkage("loops/hoekens_straight_line.toml"), CRANK),
    ("jansen_leg", _linkage("loops/jansen_leg.toml"), CRANK),
    ("pinned_chain_100", _linkage("loops/pinned_chain_100.toml"), THIN),
    ("pinned_chain_10", _linkage("loops/pinned_chain_10.toml"), THIN),
    ("ur5-fixed", _robot("ur_description/urdf/ur5_robot.urdf", False), None),
    ("panda-fixed", _robot("panda_description/urdf/panda.urdf", False), None),
    ("solo12-floating", _robot("solo12.urdf", True), None),
    ("talos_reduced-floating", _robot("talos_reduced.urdf", True), None),
]


def test_every_shipped_case_is_listed():
    """A case added to cases/ must be added to SHIPPED (or to the large ones) too."""
    listed = {s[0] for s in SHIPPED} | set(LARGE) | set(SLOW)
    ropes = set(redysim.list_cases())
    others = {p.stem for d in ("robots", "loops", "refine") for p in (CASES / d).glob("*.toml")}
    assert ropes | others <= listed


@pytest.mark.parametrize("fmt", ["mjcf", "urdf"])
@pytest.mark.parametrize(("make", "refused"), [s[1:] for s in SHIPPED], ids=[s[0] for s in SHIPPED])
def test_a_shipped_model_round_trips_or_is_refused_by_name(tmp_path, make, refused, fmt):
    """Every rope, DH robot, linkage tree, refinement case and a few robots of
    example-robot-data: exported, read back by redysim (and MuJoCo for MJCF) with the same GIM
    and qdd, or refused naming the body and why (MJCF only: URDF's reader takes any inertia)."""
    model = make()
    seed = stable_seed("shipped", model.name, fmt)
    if fmt == "mjcf" and refused is not None:
        field, message = refused
        with pytest.raises(ExportError, match=message) as err:
            to_mjcf(model)
        assert err.value.field == field and err.value.source == "to_mjcf"
        return
    _round_trip(model, fmt, tmp_path, seed)


LARGE = ["RE-U750-L6", "RE-U1250-L10", "RE-U3750-L30"]
SLOW = ["RE-U5000-L100", "RE-U7500-L150", "RE-U10000-L200", "RE-U15000-L300",
        "RE-U50000-L1000"]


def _large(name):
    """MJCF: refused cleanly (the rod model, at link 1; the depth besides); URDF: written
    without a RecursionError, one joint per DOF."""
    model = _rope(name)()
    with pytest.raises(ExportError, match=ROD[1]) as err:
        to_mjcf(model)
    assert err.value.field == ROD[0]
    root = ET.fromstring(to_urdf(model))
    assert len(root.findall("joint")) == model.n_v


@pytest.mark.parametrize("name", LARGE)
def test_a_large_rope_is_exported_or_refused_without_recursion(name):
    _large(name)


@pytest.mark.slow
@pytest.mark.parametrize("name", SLOW)
def test_the_largest_ropes_are_exported_or_refused_without_recursion(name):
    _large(name)


# --------------------------------------------------------------------------- MJCF
def test_mjcf_nests_at_most_what_mujocos_reader_takes():
    """MJCF_MAX_DEPTH nested bodies load in MuJoCo; one more is refused at export by name, and
    MuJoCo's reader indeed refuses the file one level deeper."""
    link = Link.uniform(0.01, 0.01, radius=0.002, model="cylinder")
    deepest = to_mjcf(Chain.build([link] * MJCF_MAX_DEPTH, ["R"] * MJCF_MAX_DEPTH))
    mujoco.MjModel.from_xml_string(deepest)
    n = MJCF_MAX_DEPTH + 1
    with pytest.raises(ExportError, match=f"more than {MJCF_MAX_DEPTH} deep") as err:
        to_mjcf(Chain.build([link] * n, ["R"] * n))
    assert err.value.field == f"body 'link{n}'"
    wrapped = deepest.replace("<worldbody>", '<worldbody>\n<body name="extra"><joint '
                              'name="extra" /><inertial pos="0 0 0" mass="1" diaginertia="1 1 1" '
                              "/>").replace("</worldbody>", "</body></worldbody>")
    with pytest.raises(ValueError, match="nesting is too deep"):
        mujoco.MjModel.from_xml_string(wrapped)


def _tree(bodies, parents, joints, gravity=(0.3, -9.81, 0.2)) -> Model:
    return Model.build(bodies, joints, parents, gravity=gravity, name="tree")


def _massless_tree(seed) -> Model:
    """Massless bodies between joints (mass and inertia 0, one child each; two in a row) at
    random placements, under R, P, U and S joints about random axes; a branch; a massive leaf."""
    rng = np.random.default_rng(seed)

    def body(name, massless=False):
        if massless:
            return Body(name, 0.0)
        m = rng.uniform(0.3, 2.0)
        return Body(name, m, tuple(rng.normal(scale=0.1, size=3)),
                    tuple(map(tuple, random_inertia(rng, m, rng.uniform(0.2, 0.8)))))

    def joint(name, jtype):
        axis = tuple(rng.normal(size=3)) if jtype in ("R", "P") else None
        return TreeJoint(name, jtype, axis, tuple(map(tuple, Rotation.random(
            random_state=rng).as_matrix())), tuple(rng.normal(scale=0.3, size=3)))

    spec = [("a", -1, "R", False), ("m1", 0, "R", True), ("m2", 1, "P", True),
            ("b", 2, "U", False), ("m3", 0, "S", True), ("c", 4, "R", False),
            ("m4", 3, "P", True), ("d", 6, "R", False)]
    return _tree([body(n, massless) for n, _, _, massless in spec], [p for _, p, _, _ in spec],
                 [joint(f"j_{n}", t) for n, _, t, _ in spec])


@pytest.mark.parametrize("seed", range(3))
def test_massless_bodies_are_merged_into_their_child_as_mujoco_requires(seed):
    """A massless body with one child becomes joints of the child's MJCF body, each about its
    conjugated axis and anchor: MuJoCo compiles the file and its qacc and mass matrix equal
    ours. (Before: each massless body was an MJCF body of its own, which MuJoCo refused.)"""
    model = _massless_tree(stable_seed("massless", seed))
    text = to_mjcf(model)
    root = ET.fromstring(text)
    assert {b.get("name") for b in root.iter("body")} == {"a", "b", "c", "d"}
    _mujoco_agrees(model, text, seed)


@pytest.mark.parametrize("seed", range(2))
def test_merged_bodies_read_back_with_the_same_dynamics(tmp_path, seed):
    """The merged MJCF bodies (several joints with anchors) read back by redysim's importer,
    which splits them into massless bodies again."""
    model = _massless_tree(stable_seed("massless", seed))
    _reads_back(model, to_mjcf(model), "mjcf", tmp_path, seed)


SEVERAL_HINGES = """<mujoco model="several">
  <option gravity="0 0 -9.81"/>
  <worldbody>
    <body name="base" pos="0 0 0.5">
      <joint name="yaw" type="hinge" axis="0 0 1"/>
      <geom type="box" size="0.1 0.1 0.1" density="500"/>
      <body name="wrist" pos="0.3 0 0" euler="20 10 0">
        <joint name="pitch" type="hinge" axis="0 1 0" pos="{a1}"/>
        <joint name="roll" type="hinge" axis="1 0 0" pos="{a2}" ref="{ref}"/>
        <joint name="push" type="slide" axis="1 1 0"/>
        <geom type="capsule" fromto="0 0 0 0.3 0 0" size="0.04"/>
      </body>
    </body>
  </worldbody>
</mujoco>
"""


@pytest.mark.parametrize(("a1", "a2", "ref"), [("0 0 0", "0 0 0", "0"),
                                               ("0.05 0 0.02", "0.1 -0.03 0", "0.4")],
                         ids=["at-origin", "anchors-and-ref"])
def test_an_mjcf_body_with_several_joints_exports_again(tmp_path, a1, a2, ref):
    """An MJCF body with several joints, read (split into massless bodies) and exported again:
    MuJoCo runs the exported file as the original (qacc of both files at the same qpos), and
    the exported file's qpos0 is the original's. (Before: MuJoCo refused the export, "inertia
    must have positive eigenvalues", for the massless bodies' zero inertia.) The second case
    needs the importer to read joint anchors and refs."""
    path = tmp_path / "several.xml"
    path.write_text(SEVERAL_HINGES.format(a1=a1, a2=a2, ref=ref))
    model = load_model(path)
    exported = mujoco.MjModel.from_xml_string(to_mjcf(model))
    original = mujoco.MjModel.from_xml_path(str(path))
    assert [exported.joint(j).name for j in range(exported.njnt)] == \
        [original.joint(j).name for j in range(original.njnt)]
    assert np.allclose(exported.qpos0, original.qpos0, rtol=0, atol=1e-15)
    d0, d1 = mujoco.MjData(original), mujoco.MjData(exported)
    rng = np.random.default_rng(7)
    for _ in range(2):
        q, v = rng.uniform(-1.2, 1.2, original.nq), rng.normal(size=original.nv)
        for m, d in ((original, d0), (exported, d1)):
            d.qpos[:], d.qvel[:] = q, v
            mujoco.mj_forward(m, d)
        assert rel(d1.qacc, d0.qacc) < TOL


def test_initial_values_are_written_as_refs_so_that_qpos_is_q():
    """A model whose initial configuration is not zero (an MJCF file's refs, read back): each
    hinge's and slide's initial value is its ``ref`` (MuJoCo's qpos0), also in a merged body,
    and MuJoCo's qpos is still our q (qacc equal at random states)."""
    model = _massless_tree(stable_seed("massless", 0))
    q0 = np.random.default_rng(3).uniform(-1, 1, model.n_q)
    model = dataclasses.replace(model, initial_q=q0)
    _mujoco_agrees(model, to_mjcf(model), 0)


def test_a_free_bodys_initial_pose_is_written(tmp_path):
    """MJCF gives a free body's pose as its body's pos and quat (MuJoCo's qpos0): exported
    again, the model's initial() is the file's. (Before: the pose was lost, qpos0 = neutral.)"""
    path = tmp_path / "tree.xml"
    path.write_text(MJCF)
    model = load_model(path)
    assert np.abs(model.initial()[:3]).max() > 0.5  # the file's base is at (0.1, 0.2, 1.0)
    back = _round_trip(model, "mjcf", tmp_path, 1)
    assert np.allclose(back.initial(), model.initial(), rtol=0, atol=1e-15)


def test_a_planar_lamina_is_exported_as_mujoco_checks_it():
    """A plate's principal moments satisfy Izz = Ixx + Iyy exactly, which MuJoCo's strict check
    of A + B >= C may see broken by an ulp: the exporter writes principal moments that pass,
    changed by round-off only (GIM and qdd to 1e-12)."""
    rng = np.random.default_rng(11)
    bodies, joints = [], []
    for k in range(6):
        a, b = rng.uniform(0.01, 0.1, 2)
        R = Rotation.random(random_state=rng).as_matrix()
        bodies.append(Body(f"plate{k}", 1.0, (0.1, 0, 0),
                           tuple(map(tuple, R @ np.diag([a, b, a + b]) @ R.T))))
        joints.append(TreeJoint(f"j{k}", "R", tuple(rng.normal(size=3)),
                                translation=(0.2 if k else 0.0, 0, 0)))
    model = _tree(bodies, list(range(-1, 5)), joints)
    _mujoco_agrees(model, to_mjcf(model), 2)


def _chain_with(inertia, mass=1.0):
    link = Link(0.5, mass, (0.25, 0, 0), inertia, physical=False)
    return Chain.build([link, link], ["R", "P"])


def _refusal_cases():
    massless = Body("m", 0.0)
    heavy = Body("h", 1.0, (0, 0, 0), ((0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1)))
    r = TreeJoint("r", "R", "z")
    return [
        ("massless-two-children", lambda: _tree(
            [heavy, massless, Body("c1", 1.0, inertia=heavy.inertia),
             Body("c2", 1.0, inertia=heavy.inertia)], [-1, 0, 1, 1],
            [r, TreeJoint("jm", "R", "x"), TreeJoint("j1", "R", "y"),
             TreeJoint("j2", "R", "y")]),
         "body 'm'.mass", r"massless body with 2 children \('c1', 'c2'\)"),
        ("massless-leaf", lambda: _tree([heavy, massless], [-1, 0],
                                        [r, TreeJoint("jm", "R", "x")]),
         "body 'm'.mass", "massless body with 0 children"),
        ("massless-free", lambda: _tree([massless, heavy], [-1, 0],
                                        [TreeJoint("root", "free"), r]),
         "body 'm'.mass", "massless free body"),
        ("merged-beyond-6-dofs", lambda: _tree(
            [Body("m1", 0.0), Body("m2", 0.0), heavy], [-1, 0, 1],
            [TreeJoint("s1", "S"), TreeJoint("s2", "S"), TreeJoint("r", "R", "z")]),
         "body 'h'", r"the massless bodies 'm1', 'm2' merged into it .* more than 6 DOFs"),
        ("mass-below-mjminval", lambda: _chain_with(((1e-3, 0, 0), (0, 1e-3, 0), (0, 0, 1e-3)),
                                                    mass=1e-16),
         "body 'link1'.mass", "mass 1e-16 but rotational inertia"),
        ("R-P-chain-of-bars", lambda: Chain.build([Link.uniform(0.5, 1.0)] * 2, ["R", "P"]),
         THIN[0], THIN[1]),
        ("rod-model", lambda: Chain.uniform(3, "R", length=0.01, mass=1.0, radius=0.05),
         ROD[0], ROD[1]),
    ]


@pytest.mark.parametrize(("make", "field", "message"), [c[1:] for c in _refusal_cases()],
                         ids=[c[0] for c in _refusal_cases()])
def test_mjcf_refuses_what_mujoco_refuses_naming_the_body(make, field, message):
    """What MuJoCo's compiler refuses is refused at export, naming the body and the value; the
    message says why and what to do. (Before: a file MuJoCo refused, with no word at export.)"""
    model = make()
    with pytest.raises(ExportError, match=message) as err:
        to_mjcf(model)
    assert err.value.field == field and err.value.source == "to_mjcf"
    assert "np.float64" not in str(err.value)


# --------------------------------------------------------------------------- URDF
def test_a_rope_read_back_from_urdf_falls_the_same_way(tmp_path):
    """A rope's gravity is (0, -9.81, 0); URDF's readers assume (0, 0, -9.81): the exported
    file turns the rope's world (said in a comment) and the qdd read back is the rope's.
    (Before: qdd 100 % off, the rope fell along -z of its own frame.)"""
    model = redysim.load_case("STUDY-R5").chain
    text = to_urdf(model)
    assert "is turned to (0.0, 0.0, -9.81)" in text
    back = _reads_back(model, text, "urdf", tmp_path, 5)
    assert np.array_equal(back.gravity, [0.0, 0.0, -9.81])


@pytest.mark.parametrize("g", [(0.0, 0.0, 9.81), tuple(9.81 / 3 ** 0.5 * np.ones(3))],
                         ids=["up", "diagonal"])
def test_any_gravity_of_981_is_turned_to_minus_z(tmp_path, g):
    model = dataclasses.replace(random_tree(stable_seed("turn", g), n_bodies=6, free=False),
                                gravity=np.array(g))
    _reads_back(model, to_urdf(model), "urdf", tmp_path, 3)


@pytest.mark.parametrize(("gravity", "free", "field", "message"), [
    ((0.0, -1.62, 0.0), False, "gravity", "magnitude 1.62 m/s"),
    ((0.0, 0.0, 0.0), False, "gravity", "magnitude 0.0 m/s"),
    ((0.0, -9.81, 0.0), True, "joint 'base'", "floating model whose gravity"),
], ids=["moon", "zero", "floating-y"])
def test_urdf_refuses_a_gravity_it_cannot_hold(gravity, free, field, message):
    model = dataclasses.replace(random_tree(1, n_bodies=4, free=free), gravity=np.array(gravity))
    with pytest.raises(ExportError, match=message) as err:
        to_urdf(model)
    assert err.value.field == field and err.value.source == "to_urdf"


def test_a_body_named_world_is_refused():
    """URDF readers (MuJoCo's parser among them) take a link named 'world' as the world: a body
    of that name would be welded to it. MJCF's world body is 'world' too. (Before: URDF wrote two
    links named 'world'.)"""
    heavy = ((0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1))
    model = _tree([Body("world", 1.0, inertia=heavy), Body("arm", 1.0, inertia=heavy)], [-1, 0],
                  [TreeJoint("j1", "R", "z"), TreeJoint("j2", "R", "y", translation=(1, 0, 0))])
    for export, field in ((to_urdf, "body 'world'"), (to_mjcf, "body 'world'")):
        with pytest.raises(ExportError, match="world") as err:
            export(model)
        assert err.value.field == field


def test_repeated_names_are_refused():
    """A U joint 'j' writes joints 'j_0' and 'j_1': another joint named 'j_0' would repeat a
    name, which MuJoCo refuses and URDF readers confuse."""
    heavy = ((0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1))
    model = _tree([Body("a", 1.0, inertia=heavy), Body("b", 1.0, inertia=heavy)], [-1, 0],
                  [TreeJoint("j", "U"), TreeJoint("j_0", "R", "y", translation=(1, 0, 0))])
    for export in (to_urdf, to_mjcf):
        with pytest.raises(ExportError, match="given twice") as err:
            export(model)
        assert err.value.field == "joint 'j_0'"


# --------------------------------------------------------------------------- random trees, ropes
@pytest.mark.parametrize("fmt", ["mjcf", "urdf"])
@pytest.mark.parametrize("free", [False, True])
@pytest.mark.parametrize("seed", range(3))
def test_an_exported_tree_reads_back_with_the_same_dynamics(tmp_path, fmt, free, seed):
    """Random trees (R, P, U, S about random axes at random placements, fused fixed joints).
    URDF: a fixed base's tilted gravity of 9.81 is turned to -z; a floating one's must be -z."""
    model = random_tree(stable_seed("export", seed), n_bodies=7, free=free)
    if fmt == "urdf":
        g = np.asarray(model.gravity)
        model = dataclasses.replace(model, gravity=np.array([0.0, 0.0, -9.81]) if free
                                    else 9.81 * g / np.linalg.norm(g))
    _round_trip(model, fmt, tmp_path, seed)


@pytest.mark.parametrize("mix", [("U",), ("R", "U", "S", "P")], ids="".join)
def test_a_rope_exported_to_mjcf_is_the_same_system_in_mujoco(mix):
    """MuJoCo's own GIM and bias of the exported chain (no redysim importer in between)."""
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


def test_a_chain_exports_as_a_model():
    chain = Chain.uniform(3, "U", length=0.5, mass=1.0, radius=0.05)
    assert "<freejoint" not in to_mjcf(chain) and "continuous" in to_urdf(chain)


def test_names_are_escaped():
    """A name with XML's special characters is written escaped and read back as given."""
    heavy = ((0.1, 0, 0), (0, 0.1, 0), (0, 0, 0.1))
    name = 'a<b>&"c"'
    model = _tree([Body(name, 1.0, inertia=heavy)], [-1], [TreeJoint("j&1", "R", "z")],
                  gravity=(0.0, 0.0, -9.81))
    for text in (to_mjcf(model), to_urdf(model)):
        root = ET.fromstring(text)
        assert name in {e.get("name") for e in root.iter() if e.tag in ("body", "link")}
        assert not re.search(r'name="[^"]*<', text)


@pytest.mark.parametrize("export", [to_mjcf, to_urdf])
def test_a_closed_mechanism_is_refused_by_name(export):
    """The exporters write trees: a model with cut joints would lose its loops, silently."""
    model = redysim.load_linkage(CASES / "loops" / "crank_rocker.toml").model
    with pytest.raises(ExportError, match=r"cuts = \['coupler-rocker pin'\]: a closed "
                                          r"mechanism.*model.with_cuts\(\(\)\)"):
        export(model)


@pytest.mark.engine
@pytest.mark.parametrize("mix", [("P",), ("R", "P"), ("R", "P", "U")], ids="".join)
def test_a_urdf_export_is_read_by_urdfdom_mujoco_and_redysim_with_the_same_dynamics(tmp_path,
                                                                                       mix):
    """Chains with prismatic joints (about random axes): urdfdom, Pinocchio's reader, refused
    every such file (URDF requires a <limit> on a prismatic joint). Each of the three readers'
    GIM and qdd at a random state, against the original model's: Pinocchio's CRBA and ABA,
    MuJoCo's mj_fullM and qacc (its own URDF reader), and redysim's importer."""
    pinocchio = pytest.importorskip("pinocchio")
    rng = np.random.default_rng(stable_seed("export-urdf-readers", mix))
    chain = random_chain(rng, 6, mix)
    q, qd, _ = random_state(rng, chain, "wide")
    M0, a0 = mass_matrix(chain, q), forward_dynamics(chain, q, qd)
    text = to_urdf(chain)
    assert text.count("<limit ") == text.count('type="prismatic"') > 0
    # urdfdom (Pinocchio): a continuous joint's q is (cos, sin)
    pm = pinocchio.buildModelFromXML(text)
    assert pm.nv == chain.n_dof
    qp = np.concatenate([[np.cos(x), np.sin(x)] if jm.nq == 2 else [x]
                         for jm, x in zip(list(pm.joints)[1:], q, strict=True)])
    pd = pm.createData()
    Mp = pinocchio.crba(pm, pd, qp)
    Mp = np.triu(Mp) + np.triu(Mp, 1).T
    assert rel(Mp, M0) < TOL
    assert rel(pinocchio.aba(pm, pm.createData(), qp, qd, np.zeros(pm.nv)), a0) < \
        _mujoco_tol(M0)
    # MuJoCo's URDF reader; it refuses a U joint's massless link between the two axes (to_mjcf,
    # the format for MuJoCo, merges it into the next body)
    if "U" in mix:
        with pytest.raises(ValueError, match="mass and inertia of moving bodies"):
            mujoco.MjModel.from_xml_string(text)
    else:
        m = mujoco.MjModel.from_xml_string(text)
        d = mujoco.MjData(m)
        d.qpos[:], d.qvel[:] = q, qd
        mujoco.mj_forward(m, d)
        Mm = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, Mm)
        assert rel(Mm, M0) < TOL
        assert rel(d.qacc, a0) < _mujoco_tol(M0)
    # redysim's own reader: the wide limits are announced as dropped, the dynamics the same
    path = tmp_path / "chain.urdf"
    path.write_text(text)
    back = load_model(path)
    assert any("limit" in note for note in back.notes)
    assert rel(mass_matrix(back, q), M0) < TOL
    assert rel(forward_dynamics(back, q, qd), a0) < TOL


@pytest.mark.engine
def test_every_urdf_mujoco_refuses_is_a_model_to_mjcf_refuses_by_name():
    """A fourth hold-out battery: to_urdf's docstring said MuJoCo reads every URDF it writes
    but for U and S joints; MuJoCo refused the shipped PUMA 560's (a waist of mass 0), the
    locked PUMA's (A + B >= C) and a massless middle body's (mjMINVAL). Each shipped robot whose
    URDF MuJoCo refuses is one to_mjcf refuses by name, for MuJoCo's own reason, and urdfdom
    reads it with the same dynamics."""
    pinocchio = pytest.importorskip("pinocchio")
    refused = []
    for path in sorted((CASES / "robots").glob("*.toml")):
        model = load_model(path)
        if any(t in ("U", "S") for t in model.joint_types) or model.has_passive or \
                np.any(model.armature) or model.couplings:
            continue
        try:
            text = to_urdf(model)
        except ExportError:
            continue
        try:
            mujoco.MjModel.from_xml_string(text)
        except ValueError as exc:
            refused.append(path.stem)
            assert "mass and inertia" in str(exc) or "triangle" in str(exc) or \
                "positive eigenvalues" in str(exc), (path.stem, str(exc))
            with pytest.raises(ExportError, match="mjMINVAL|triangle inequality"):
                to_mjcf(model)
            pm = pinocchio.buildModelFromXML(text)
            assert pm.nv == model.n_v
    assert "puma560" in refused


def test_a_non_model_is_refused_by_both_exporters_as_a_model_type_error():
    """Battery 5 (F2): a Case, a str, None, a dict, the Model class or a Linkage gave a plain
    TypeError; the guide promises ModelTypeError (a TypeError) naming the call, with the way
    out for a Case and a Linkage."""
    from redysim.errors import ModelTypeError

    case = redysim.load_case("STUDY-R3")
    linkage = redysim.load_linkage(Path(__file__).resolve().parents[1] / "cases" / "loops"
                                     / "crank_rocker.toml")
    for export in (to_urdf, to_mjcf):
        name = export.__name__
        for thing in (case, "rope", None, {"a": 1}, Model, linkage):
            with pytest.raises(ModelTypeError, match=rf"^{name}: model = .*must be a "
                                                     r"redysim.Model"):
                export(thing)
        with pytest.raises(TypeError, match=r"a Case: give its \.chain"):
            export(case)
        with pytest.raises(TypeError, match=r"a Linkage: give its \.model"):
            export(linkage)


@pytest.mark.parametrize(("make", "refused"), [s[1:] for s in SHIPPED], ids=[s[0] for s in SHIPPED])
def test_a_urdf_says_what_mujoco_refuses_as_to_mjcf_does(make, refused):
    """Battery 5 (F6): the PUMA 560's URDF (a massless waist with rotational inertia) was
    written without a word, and MuJoCo refused the file; to_mjcf refuses it by name. The URDF
    keeps the model's dynamics (urdfdom and redysim read it) and says, in a comment, each body
    MuJoCo's compiler refuses with to_mjcf's reason: the same bodies, one check."""
    model = make()
    comments = re.findall(r"<!--(.*?)-->", to_urdf(model), re.S)
    said = [c for c in comments if "MuJoCo's compiler refuses this file" in c]
    if refused is None:
        assert not said
        return
    field, message = refused
    assert len(said) == 1 and field in said[0] and re.search(message, said[0])


@pytest.mark.engine
def test_the_puma_urdf_is_read_by_pinocchio_and_refused_by_mujoco_as_it_says(tmp_path):
    """The PUMA 560's URDF: Pinocchio (urdfdom) reads the model's GIM; MuJoCo's URDF reader
    refuses the body the file's comment names, and a model to_mjcf takes is read by MuJoCo's
    URDF reader with the model's GIM."""
    pinocchio = pytest.importorskip("pinocchio")
    model = redysim.load_model(CASES / "robots" / "puma560.toml")
    text = to_urdf(model)
    assert "body 'waist'.mass = 0.0" in text
    rng = np.random.default_rng(stable_seed("puma-urdf"))
    q = rng.uniform(-1, 1, model.n_q)
    pm = pinocchio.buildModelFromXML(text)
    qp = np.concatenate([[np.cos(x), np.sin(x)] if jm.nq == 2 else [x]
                         for jm, x in zip(list(pm.joints)[1:], q, strict=True)])
    Mp = pinocchio.crba(pm, pm.createData(), qp)
    assert rel(np.triu(Mp) + np.triu(Mp, 1).T, mass_matrix(model, q)) < TOL
    with pytest.raises(ValueError, match="waist"):
        mujoco.MjModel.from_xml_string(text)
    stanford = redysim.load_model(CASES / "robots" / "stanford_arm.toml")
    text = to_urdf(stanford)
    assert "MuJoCo's compiler refuses" not in text
    m = mujoco.MjModel.from_xml_string(text)
    d = mujoco.MjData(m)
    q = rng.uniform(-1, 1, stanford.n_q)
    d.qpos[:] = q
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    assert rel(M, mass_matrix(stanford, q)) < _mujoco_tol(M)
