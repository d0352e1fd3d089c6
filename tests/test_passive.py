"""Robots as their files say: a model's own passive elements (joint damping, springs with their
rest positions, gravity compensation; armature, an inertia, beside them).

What holds them and what applies them (docs/design.md, "Passive elements"): the Model keeps them
(``Model.damping``, ``stiffness``, ``spring_ref``, ``gravcomp``), ``redysim.passive_forces``
gives them, a run applies them. Checked against MuJoCo's own ``mj_forward`` on MJCF files written
here (its qacc with the passive forces it computes itself, its mass matrix with its armature),
against hand calculations, and by the compiled and the Python stepping giving the same bits.
"""

from __future__ import annotations

import pickle

import numpy as np
import pytest
from conftest import rel, stable_seed
from test_integrate import _compiled_and_python_runs
from test_trees import random_configuration

import redysim
from redysim import Chain, forward_dynamics, load_model, mass_matrix, passive_forces
from redysim.algorithms.system import System
from redysim.errors import CaseError

# an arm: classes and defaults, hinges and a slide, a body of two joints, a jointless body
# (fused), every passive element; contacts off by contype
ARM = """<mujoco model="arm"><option {option}>{flags}</option>
<default><joint damping="0.3" armature="0.02"/><geom contype="0" conaffinity="0"/>
 <default class="stiff"><joint stiffness="4" springref="20" damping="0.7"/></default>
</default>
<worldbody>
<body name="base" pos="0 0 0.5" gravcomp="0.5"><joint name="j1" axis="0 0 1"/>
 <geom type="capsule" fromto="0 0 0 0 0 0.2" size="0.04" mass="2"/>
 <body name="upper" pos="0 0 0.2" gravcomp="1"><joint name="j2" class="stiff" axis="0 1 0"/>
  <joint name="j2b" axis="1 0 0" pos="0 0 0.05" armature="0.05" damping="0.1"/>
  <geom type="capsule" fromto="0 0 0 0.4 0 0" size="0.03" mass="1.5"/>
  <body name="fore" pos="0.4 0 0" gravcomp="0.25"><joint name="j3" axis="0 1 0" stiffness="2"
    springref="-30" armature="0"/>
   <geom type="capsule" fromto="0 0 0 0.3 0 0.1" size="0.025" mass="0.8"/>
   <body name="slider" pos="0.3 0 0.1"><joint name="s" type="slide" axis="1 0 0.2"
     stiffness="30" springref="0.05" damping="2" armature="0.1"/>
    <geom type="box" size="0.03 0.02 0.02" mass="0.3"/>
    <body name="tool" pos="0.05 0 0"><geom type="sphere" size="0.02" mass="0.1"/></body>
   </body>
  </body>
 </body>
</body>
</worldbody></mujoco>"""

# a floating body (armature, damping on its free joint) carrying a damped, compensated leg
FLOATER = """<mujoco model="floater"><option {option}>{flags}</option>
<default><geom contype="0" conaffinity="0"/></default>
<worldbody>
<body name="torso" pos="0.1 -0.2 1.0" quat="0.9 0.1 0.3 -0.2" gravcomp="0.3">
 <joint name="root" type="free" damping="0.4" armature="0.05"/>
 <geom type="box" size="0.2 0.1 0.05" mass="5"/>
 <body name="leg" pos="0.1 0 -0.05" gravcomp="0.8"><joint name="hip" axis="0 1 0"
   damping="1.5" stiffness="10" springref="15" armature="0.03"/>
  <geom type="capsule" fromto="0 0 0 0 0 -0.4" size="0.03" mass="1.2"/>
 </body>
</body>
</worldbody></mujoco>"""

# the arm with its jointless tool holding another fraction of its weight than the slider it is
# fused into (Hello Robot Stretch's ArUco marker body: gravcomp 0 on an arm link of 1)
FUSED = ARM.replace('<body name="slider" pos="0.3 0 0.1">',
                    '<body name="slider" pos="0.3 0 0.1" gravcomp="0.2">').replace(
    '<body name="tool" pos="0.05 0 0">', '<body name="tool" pos="0.05 0.01 0.02" gravcomp="0.7">')

OPTIONS = [
    ("all", "", ""),
    ("gravity-elsewhere", 'gravity="1 -2 -7"', ""),
    ("no-damper", "", '<flag damper="disable"/>'),
    ("no-spring", "", '<flag spring="disable"/>'),
    ("no-passive", "", '<flag spring="disable" damper="disable"/>'),
    ("no-gravity", "", '<flag gravity="disable"/>'),
]


def write(tmp_path, text, name):
    path = tmp_path / name
    path.write_text(text)
    return path


def mujoco_forward(path, q, v, tau):
    """MuJoCo's qacc and mass matrix at (qpos, qvel, qfrc_applied): contacts, actuation,
    friction loss and limits off by its disable flags, its passive forces kept."""
    mujoco = pytest.importorskip("mujoco")
    m = mujoco.MjModel.from_xml_path(str(path))
    off = mujoco.mjtDisableBit
    m.opt.disableflags |= off.mjDSBL_CONTACT | off.mjDSBL_ACTUATION | \
        off.mjDSBL_FRICTIONLOSS | off.mjDSBL_LIMIT
    d = mujoco.MjData(m)
    d.qpos[:], d.qvel[:], d.qfrc_applied[:] = q, v, tau
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    return d.qacc.copy(), M, d.qfrc_passive.copy()


@pytest.mark.engine
@pytest.mark.parametrize("text", [ARM, FLOATER, FUSED], ids=["arm", "floating", "fused-parts"])
@pytest.mark.parametrize("option", OPTIONS, ids=[o[0] for o in OPTIONS])
def test_a_files_passive_elements_give_mujocos_qacc(tmp_path, text, option):
    """The file's armature, damping, springs (springref in degrees, classes and defaults) and
    gravcomp, MuJoCo's flags honoured: qacc = forward_dynamics(q, v, tau + passive_forces)
    equals MuJoCo's mj_forward qacc to 1e-9 relative, M (with armature) to 1e-12, and the
    passive forces its qfrc_passive; nothing of them is announced as dropped."""
    _, opt, flags = option
    path = write(tmp_path, text.format(option=opt, flags=flags), "m.xml")
    model = load_model(path)
    assert not any(key in note for note in model.notes
                   for key in ("damping", "stiffness", "armature", "gravcomp")), model.notes
    rng = np.random.default_rng(stable_seed("passive-mujoco", text[:20], option[0]))
    for i in range(4):
        q = model.initial() if i == 0 else random_configuration(rng, model)
        v, tau = rng.normal(size=model.n_v), rng.normal(size=model.n_v)
        qacc, M, passive = mujoco_forward(path, q, v, tau)
        assert rel(mass_matrix(model, q), M) < 1e-12
        got = passive_forces(model, q, v)
        assert np.abs(got - passive).max() <= 1e-12 * max(1.0, np.abs(passive).max())
        assert rel(forward_dynamics(model, q, v, tau + got), qacc) < 1e-9


@pytest.mark.engine
def test_what_mujoco_applies_otherwise_is_announced(tmp_path):
    """A free joint's spring and actuatorgravcomp: announced by name, refused with strict=True
    (the joint's linear damping and spring kept)."""
    pytest.importorskip("mujoco")
    text = FLOATER.format(option="", flags="").replace(
        'stiffness="10"', 'stiffness="10" actuatorgravcomp="true"').replace(
        'damping="0.4"', 'damping="0.4" stiffness="3"')
    path = write(tmp_path, text, "m.xml")
    model = load_model(path)
    notes = "\n".join(model.notes)
    for fragment in ("joint 'root': stiffness = 3 dropped",
                     "joint 'hip': actuatorgravcomp = true dropped"):
        assert fragment in notes, notes
    k = model.joint_voff[model.joint_names.index("hip")]
    assert (model.damping[k], model.stiffness[k]) == (1.5, 10.0)
    assert not model.stiffness[:6].any() and np.all(model.damping[:6] == 0.4)
    with pytest.raises(redysim.ModelFileError, match="strict=True refuses"):
        load_model(path, strict=True)


def test_urdf_damping_is_read_and_armature_is_given_at_load(tmp_path):
    """A URDF's <dynamics damping> is the model's (its friction still announced); armature,
    which URDF has no tag for, is load_urdf's and load_model's ``armature=``: the mass matrix
    gains it on the diagonal (hand: M + diag(a)), the passive forces are -d v (hand)."""
    link = ('<link name="{n}"><inertial><origin xyz="0.2 0 0"/><mass value="1"/><inertia '
            'ixx="0.01" ixy="0" ixz="0" iyy="0.05" iyz="0" izz="0.05"/></inertial></link>')
    text = (f'<robot name="r">{link.format(n="base")}{link.format(n="a")}{link.format(n="b")}'
            '<joint name="j1" type="revolute"><parent link="base"/><child link="a"/>'
            '<axis xyz="0 0 1"/><dynamics damping="0.5" friction="0.1"/></joint>'
            '<joint name="j2" type="continuous"><parent link="a"/><child link="b"/>'
            '<origin xyz="0.4 0 0"/><axis xyz="0 1 0"/><dynamics damping="1.25"/></joint>'
            '</robot>')
    path = write(tmp_path, text, "r.urdf")
    model = load_model(path)
    assert np.array_equal(model.damping, [0.5, 1.25]) and not model.armature.any()
    assert any("friction" in n for n in model.notes)
    assert not any("<dynamics> damping" in n for n in model.notes)
    q, v = np.array([0.3, -0.7]), np.array([2.0, -1.0])
    assert np.array_equal(passive_forces(model, q, v), [-1.0, 1.25])
    geared = load_model(path, armature={"j2": 0.2})
    assert np.array_equal(geared.armature, [0.0, 0.2])
    assert np.abs(mass_matrix(geared, q) - mass_matrix(model, q) - np.diag([0, 0.2])).max() \
        < 1e-15
    assert np.array_equal(redysim.io.importers.load_urdf(path, armature=0.1).armature,
                          [0.1, 0.1])
    with pytest.raises(CaseError, match=r"armature\[0\] = -1.0: must be finite and >= 0"):
        load_model(path, armature=-1.0)


@pytest.mark.engine
def test_urdf_damping_agrees_with_pinocchio(tmp_path):
    """The URDF's damping as Pinocchio reads it (``model.damping``), and qdd with it
    (Pinocchio's aba of tau - d v) equal to the core's forward_dynamics(tau + passive)."""
    pin = pytest.importorskip("pinocchio")
    link = ('<link name="{n}"><inertial><origin xyz="0.1 0.02 0"/><mass value="1.5"/><inertia '
            'ixx="0.02" ixy="0" ixz="0" iyy="0.03" iyz="0" izz="0.04"/></inertial></link>')
    text = (f'<robot name="r">{link.format(n="base")}{link.format(n="a")}{link.format(n="b")}'
            '<joint name="j1" type="revolute"><parent link="base"/><child link="a"/>'
            '<axis xyz="0 1 0"/><dynamics damping="0.8"/><limit lower="-3" upper="3" effort="1" '
            'velocity="1"/></joint><joint name="j2" type="prismatic"><parent link="a"/>'
            '<child link="b"/><origin xyz="0.3 0 0"/><axis xyz="1 0 0"/><dynamics '
            'damping="2.5"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>'
            '</robot>')
    path = write(tmp_path, text, "r.urdf")
    model = load_model(path)
    pm = pin.buildModelFromUrdf(str(path))
    pm.gravity.linear = np.array(model.gravity)
    assert np.array_equal(pm.damping, model.damping)
    data = pm.createData()
    rng = np.random.default_rng(stable_seed("urdf-damping-pinocchio"))
    for _ in range(3):
        q, v, tau = rng.normal(size=2), rng.normal(size=2), rng.normal(size=2)
        want = pin.aba(pm, data, q, v, tau - pm.damping * v)
        got = forward_dynamics(model, q, v, tau + passive_forces(model, q, v))
        assert rel(got, want) < 1e-12


def arm(**passive):
    chain = Chain.uniform(3, "R", length=0.5, mass=1.0, radius=0.02, inertia="cylinder")
    return chain.with_passive(**passive)


def test_passive_forces_by_hand():
    """-d v - k (q - ref) + the held-up weight's moment about the joint (a planar chain, so
    the moment arm is the COM's x in the world)."""
    model = arm(damping=0.5, stiffness={"joint2": 2.0}, spring_ref=[0.0, 0.3, 0.0],
                gravcomp={"link1": 1.0})
    q, v = np.array([0.1, 0.2, 0.3]), np.array([1.0, 2.0, 3.0])
    g = -model.gravity[1]
    want = np.array([-0.5 + 0.25 * np.cos(0.1) * g, -1.0 - 2.0 * (0.2 - 0.3), -1.5])
    assert np.abs(passive_forces(model, q, v) - want).max() < 1e-14
    assert not passive_forces(model.without_passive(), q, v).any()
    # the rigid-body map is unchanged by them: forward dynamics takes tau as given
    assert np.array_equal(forward_dynamics(model, q, v, np.zeros(3)),
                          forward_dynamics(model.without_passive(), q, v, np.zeros(3)))


def test_the_model_holds_them_checked_kept_and_carried():
    """Checked at the door (CaseError naming the field and value), read-only, kept through
    pickling (and a model pickled before them unpickles with zeros), carried through locking."""
    model = arm(damping=[0.1, 0.2, 0.3], stiffness=1.0, spring_ref={"joint3": -0.4},
                gravcomp=[0.5, 0.5, 1.0])
    for key in ("damping", "stiffness", "spring_ref", "gravcomp"):
        assert not getattr(model, key).flags.writeable
    back = pickle.loads(pickle.dumps(model))
    for key in ("damping", "stiffness", "spring_ref", "gravcomp"):
        assert np.array_equal(getattr(back, key), getattr(model, key))
    state = model.__getstate__()
    for key in ("damping", "stiffness", "spring_ref", "gravcomp"):
        state.pop(key)
    old = object.__new__(type(model))
    old.__setstate__(state)
    assert not old.has_passive and old.gravcomp.shape == (3,)
    locked = model.locked({"joint2": 0.3})
    assert np.array_equal(locked.damping, [0.1, 0.3])
    assert np.array_equal(locked.spring_ref, [0.0, -0.4])
    assert np.array_equal(locked.gravcomp, [0.5, 1.0])  # link2 fused into link1: both 0.5
    # link3 (gravcomp 1), fused into link2 (0.5, with mass): one fraction cannot hold both
    # link3 (gravcomp 1), fused into link2 (0.5, with mass): each part's share held at its
    # own centre of mass; the locked model's passive forces are the model's at joint3 = 0.3
    both = model.locked({"joint3": 0.3})
    assert both.gravcomp.tolist() == [0.5, 0.0]
    assert both.gravcomp_loads.shape == (2, 5)
    q, v = np.array([0.2, -0.4]), np.array([0.3, 0.7])
    want = passive_forces(model, np.array([0.2, -0.4, 0.3]), np.array([0.3, 0.7, 0.0]))
    assert np.abs(passive_forces(both, q, v) - want[:2]).max() < 1e-14
    back = pickle.loads(pickle.dumps(both))
    assert np.array_equal(back.gravcomp_loads, both.gravcomp_loads)
    assert not both.without_passive().has_passive
    with pytest.raises(CaseError, match=r"gravcomp_loads = \['link2'\]: bodies fused from parts "
                       "whose gravcomp fractions differ"):
        both.locked({"joint2": 0.1})
    for kw, match in ((dict(damping=-1.0), r"damping\[0\] = -1.0: must be finite and >= 0"),
                      (dict(stiffness=[1.0, np.nan, 1.0]), r"stiffness\[1\] = nan"),
                      (dict(spring_ref=[1.0, 2.0]), r"must be 3 numbers"),
                      (dict(gravcomp={"nope": 1.0}), r"gravcomp = 'nope': no such body"),
                      (dict(damping={"joint9": 1.0}), r"damping = 'joint9': no such joint")):
        with pytest.raises(CaseError, match=match):
            arm(**kw)
    assert arm(spring_ref=-1.0).spring_ref.tolist() == [-1.0] * 3  # a rest may be negative
    with pytest.raises(CaseError, match="coarse-graining does not carry joint damping"):
        redysim.coarsen(arm(damping=0.1), 3)  # refused, not dropped


def test_a_run_applies_the_models_own_and_the_settings_add_to_them():
    """A model's own passive elements are the run's (not additions an engine stepper would
    refuse); settings add to them: a damping setting d2 on a model's d1 is d1 + d2; a second
    spring sums with the first (forces -k1 (q - r1) - k2 (q - r2))."""
    model = arm(damping=0.2, stiffness=[1.0, 0.0, 2.0], spring_ref=[0.1, 0.0, -0.2],
                gravcomp=0.5)
    own = System(model)
    assert own.additions == []
    q, v = np.array([0.4, -0.3, 0.2]), np.array([0.5, 1.0, -2.0])
    assert np.array_equal(own.forces(0.0, q, v), passive_forces(model, q, v))
    more = System(model, damping=0.3, stiffness=[0.0, 3.0, 1.0], spring_ref=[0.0, 0.5, 0.4],
                  gravcomp=0.5)
    assert more.additions == ["damping", "stiffness", "gravcomp"]
    k1, r1 = model.stiffness, model.spring_ref
    k2, r2 = np.array([0.0, 3.0, 1.0]), np.array([0.0, 0.5, 0.4])
    full = arm(gravcomp=1.0)
    want = -0.5 * v - k1 * (q - r1) - k2 * (q - r2) + passive_forces(full, q, v)
    assert np.abs(more.forces(0.0, q, v) - want).max() < 1e-13
    assert not System(model.without_passive()).forces(0.0, q, v)


def test_springs_and_gravcomp_keep_the_systems_energy():
    """Undamped, the system's energy (T + V_gravity + the springs' and the held-up weight's
    potentials) is kept by the motion to the integrator's tolerance; the model's energy (T +
    V_gravity alone) is not."""
    model = arm(stiffness=[3.0, 1.0, 2.0], spring_ref=[0.2, -0.1, 0.3], gravcomp=[0.3, 0.6, 1])
    run = redysim.simulate(model, 1.0, q0=[0.5, -0.4, 0.3], rtol=1e-11, atol=1e-13)
    assert run.status == 0
    assert np.abs(run.energy - run.energy[0]).max() < 1e-9 * np.abs(run.energy).max()
    T, V = np.array([redysim.energy(model, q, v) for q, v in zip(run.q, run.v,
                                                                  strict=True)]).T
    assert np.abs(T + V - (T + V)[0]).max() > 1e-3


@pytest.mark.parametrize("method, kw", [("ode45", {"rtol": 1e-8, "atol": 1e-10}),
                                        ("rk4", {"h": 1e-3})])
def test_a_models_own_damping_and_springs_step_alike_compiled_and_in_python(method, kw):
    """The model's own damping, springs and gravcomp: the compiled and the Python stepping take
    the same steps to the same bits, and they change the motion."""
    model = arm(damping=[0.3, 0.1, 0.2], stiffness=[2.0, 0.0, 1.0], spring_ref=0.1,
                gravcomp=[1.0, 0.0, 0.5])
    rng = np.random.default_rng(stable_seed("passive-bits", method))
    q0, v0 = random_configuration(rng, model), rng.normal(size=3)
    damped, _ = _compiled_and_python_runs(model, 0.3, q0=q0, v0=v0, integrator=method, **kw)
    rigid, _ = _compiled_and_python_runs(model.without_passive(), 0.3, q0=q0, v0=v0,
                                         integrator=method, **kw)
    assert np.abs(damped.q[-1] - rigid.q[-1]).max() > 1e-3


@pytest.mark.engine
def test_the_exporters_write_them_or_refuse_them(tmp_path):
    """to_mjcf writes damping, stiffness with springref and gravcomp (a free joint's damping
    too), read back equal; to_urdf writes <dynamics damping>, read back equal, and refuses a
    spring or gravcomp by name (URDF has no field for them)."""
    pytest.importorskip("mujoco")
    from redysim.io.export import ExportError, to_mjcf, to_urdf

    model = load_model(write(tmp_path, ARM.format(option="", flags=""), "arm.xml"))
    floater = load_model(write(tmp_path, FLOATER.format(option="", flags=""), "f.xml"))
    for m in (model, floater):
        back = load_model(write(tmp_path, to_mjcf(m), "back.xml"))
        for key in ("armature", "damping", "stiffness", "spring_ref", "gravcomp"):
            assert np.abs(getattr(back, key) - getattr(m, key)).max() < 1e-15, key
    chain = arm(damping=[0.1, 0.0, 0.3])
    back = load_model(write(tmp_path, to_urdf(chain), "back.urdf"))
    assert np.array_equal(back.damping, chain.damping)
    with pytest.raises(ExportError, match=r"joint 'joint1'.stiffness = 2.0: URDF has no field"):
        to_urdf(arm(stiffness=2.0))
    with pytest.raises(ExportError, match=r"body 'link2'.gravcomp = 0.5: URDF has no field"):
        to_urdf(arm(gravcomp={"link2": 0.5}))


def sprung_arm():
    """A damped, sprung, compensated spatial arm (a U joint among R's, general axes)."""
    chain = Chain.build([redysim.Link.uniform(0.4, 1.0 + 0.2 * k, 0.03, "cylinder")
                         for k in range(4)], ["R", "U", redysim.Joint("R", (0, 1, 0)), "P"],
                        gravity=(0.0, 0.0, -9.81))
    return chain.with_passive(damping=[0.3, 0.2, 0.1, 0.4, 1.0],
                              stiffness=[2.0, 0.0, 1.5, 3.0, 20.0],
                              spring_ref=[0.2, 0.0, -0.3, 0.5, 0.05],
                              gravcomp=[0.0, 1.0, 0.5, 0.25])


@pytest.mark.engine
@pytest.mark.parametrize("name", ["pinocchio-aba", "mujoco", "drake", "dart", "exudyn"])
def test_engines_agree_with_the_core_on_a_damped_sprung_arm(name):
    """Each engine's qdd is the rigid body's map (as the core's forward_dynamics): a run through
    redysim's integrators with the engine's qdd applies the model's passive elements around it,
    and ends where the core's own run ends. MuJoCo's own RK4 holds them natively (its SPRING
    and DAMPER stages) and agrees with the core's RK4 at the same step, as Exudyn's RK44 (its
    tree's P/D control and COM loads); Drake's RK2 and DART's semi-implicit Euler (first order)
    land near it, at their orders; Drake refuses the sprung prismatic joint by name (its
    PrismaticSpring's stiffness is no Context parameter) and takes the arm without it."""
    from engine_chains import engine_or_skip

    from redysim.errors import SettingsError
    from redysim.simulation import Integrator, Simulator

    cls = engine_or_skip(name)
    model = sprung_arm()
    if not cls.limits(model).ok:
        pytest.skip(cls.limits(model).reason)
    eng = cls(model)
    rng = np.random.default_rng(stable_seed("passive-engines", name))
    q0, v0 = rng.uniform(-0.5, 0.5, model.n_q), rng.normal(size=model.n_v)
    q, v, tau = rng.uniform(-1, 1, model.n_q), rng.normal(size=model.n_v), rng.normal(
        size=model.n_v)
    assert rel(eng.qdd(q, v, tau), forward_dynamics(model, q, v, tau)) < 1e-9
    kw = dict(q0=q0, v0=v0, integrator=Integrator("rk4", h=1e-3), sample=0.1)
    core = Simulator(System(model), 0.5, **kw).run()
    theirs = Simulator(System(model, qdd=eng.qdd), 0.5, **kw).run()
    assert core.status == theirs.status == 0
    assert rel(theirs.q, core.q) < 1e-8 and rel(theirs.v, core.v) < 1e-8
    if not eng.integrators:
        return
    if name == "drake":  # (its PrismaticSpring's stiffness is no Context parameter)
        with pytest.raises(SettingsError, match="PrismaticSpring"):
            Simulator(System(model), 0.5, q0=q0, v0=v0, sample=0.1,
                      integrator=eng.stepper(h=1e-3)).run()
        stiffness = np.array(model.stiffness)
        stiffness[-1] = 0.0  # the P joint's spring off: Drake holds the rest
        model = model.with_passive(stiffness=stiffness)
        eng = cls(model)
        core = Simulator(System(model), 0.5, **kw).run()
    own, tol = {"mujoco": ("rk4", 1e-8), "exudyn": ("rk44", 1e-8), "drake": ("runge_kutta2", 3e-5),
                "dart": ("semi-implicit-euler", 1e-2)}[name]
    native = Simulator(System(model), 0.5, q0=q0, v0=v0, sample=0.1,
                       integrator=eng.stepper(own, h=1e-3)).run()
    assert rel(native.q, core.q) < tol and rel(native.v, core.v) < tol, (
        rel(native.q, core.q), rel(native.v, core.v))
    rigid = Simulator(System(model.without_passive()), 0.5, **kw).run()
    assert rel(native.v, rigid.v) > max(1e-3, 3 * tol), rel(native.v, rigid.v)  # (they act)
    # after a native run, its qdd is the rigid body's again
    assert rel(eng.qdd(q, v, tau), forward_dynamics(model, q, v, tau)) < 1e-9


@pytest.mark.engine
def test_a_fused_body_of_two_fractions_holds_each_at_its_part(tmp_path):
    """Before: refused ('one body holds one fraction'). The jointless tool (gravcomp 0.7) fused
    into the slider (0.2): the model holds the slider's and the tool's shares as loads at each
    part's centre of mass (the fused body's own fraction 0), announced nowhere as dropped;
    the passive forces are MuJoCo's (test_a_files_passive_elements_give_mujocos_qacc). The
    exporters and the engines' own stepping refuse them by name (no body of a file holds two
    fractions)."""
    from redysim.io.export import ExportError, to_mjcf

    model = load_model(write(tmp_path, FUSED.format(option="", flags=""), "m.xml"))
    k = model.body_names.index("slider")
    assert model.gravcomp[k] == 0.0
    held = sorted(model.gravcomp_loads[:, 1].tolist())
    assert held == pytest.approx([0.3 * 0.2, 0.1 * 0.7], rel=1e-12)  # slider 0.3 kg, tool 0.1
    assert set(model.gravcomp_loads[:, 0].astype(int)) == {k}
    with pytest.raises(ExportError, match="gravcomp_loads"):
        to_mjcf(model)
    from engine_chains import engine_or_skip

    from redysim.errors import SettingsError
    from redysim.simulation import Integrator, Simulator

    both = arm(gravcomp=[0.5, 0.5, 1.0]).locked({"joint3": 0.3})  # (link3 into link2)
    eng = engine_or_skip("mujoco")(both)  # its bodies' gravcomp: one fraction each
    with pytest.raises(SettingsError, match="not the model's gravcomp_loads"):
        Simulator(System(both), 0.1, integrator=eng.stepper(h=1e-3)).run()
    core = Simulator(System(both), 0.1, integrator=Integrator("rk4", h=1e-3)).run()
    assert core.status == 0
