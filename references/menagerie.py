"""Real robots no one here wrote: every model of a MuJoCo Menagerie checkout, loaded by
:func:`redysim.load_model` with its default options, against MuJoCo's own compile of the same
file.

    python -m redysim.references.menagerie PATH [--stub-missing-meshes] [--out F.csv] [--only RE]

``PATH`` is a checkout of github.com/google-deepmind/mujoco_menagerie (or a fork). A model is
each ``*.xml`` of a top-level folder except ``scene*.xml``; a file MuJoCo does not compile on its
own (an include fragment, keyframes of another file) is listed as such and not counted.

What is compared, at MuJoCo's ``qpos0`` and at seeded random states (hinge and slide joints
moved by N(0, 0.3), free joints to random poses, v and tau N(0, 1), all moved onto the model's
couplings and loops by the core): the mass matrix (``mj_fullM``, armature included) and the
accelerations of the *smooth* dynamics: MuJoCo's ``qacc`` with contacts, limits, frictionloss and
actuation off and fluid forces zero (what the core announces and does not simulate), its
passive forces (damping, springs, gravity compensation) on; a joint's gravity compensation that
MuJoCo routes through its actuator (``actuatorgravcomp``, clamped by ``actuatorfrcrange``) added
whole, as the core applies it (and announces). A model whose file has equality
constraints (joint couplings, ``connect``, ``weld``) holds them softly in MuJoCo
(solref/solimp) and exactly in the core, so MuJoCo's side is then its dynamics with the
constraints made exact, by Gauss's principle on MuJoCo's own quantities: qacc = a - M^-1 J^T
(J M^-1 J^T)^+ (J a + Jdot v), a = M^-1 (tau + qfrc_passive - qfrc_bias), with J MuJoCo's
equality rows (``efc_J``) and Jdot v from them by Richardson-extrapolated central differences
along v. Errors are relative in the max-norm: max |ours - MuJoCo| / max |MuJoCo|.

A model agrees when M is within 1e-12 and qacc within 1e-9 and its notes announce only what
is not smooth dynamics (frictionloss, contacts, fluid, plugins, actuators, and what does not act).

``--stub-missing-meshes``: a snapshot whose largest files are absent (a shallow mirror) has no
mesh file to compile; a small tetrahedron is written in place of each missing ``.obj``/``.stl``
(larger for meshes MuJoCo finds too small after their ``scale``), so inertias MuJoCo would take
from those meshes come from the stub: the same stub for MuJoCo and for the core, which reads
MuJoCo's compile. Explicit ``<inertial>`` elements are untouched.
"""

from __future__ import annotations

import argparse
import csv
import re
import struct
import sys
import time
from pathlib import Path

import numpy as np

M_TOL, QACC_TOL = 1e-12, 1e-9
# what the core announces and does not simulate, by design (Model.notes' words); a note with none
# of these words is a piece of dynamics dropped
ALLOWED = ("frictionloss", "contact", "collision", "fluid", "density", "viscosity", "plugin",
           "actuator", "does not act", "do not act", "limit", "range", "sensor", "visual",
           "no effect", "not read", "solref",  # solref: MuJoCo's softness, where the core is exact
           "in-plane equations",  # a planar loop closed by its independent equations
           "independent equations",  # loop equations that repeat others, dropped (the same motion)
           "mocap")  # a mocap body: held where the file puts it, an input like an actuator


# --------------------------------------------------------------------------- stubs
def _tetrahedron(size: float) -> tuple[list, list]:
    return ([(0, 0, 0), (size, 0, 0), (0, size, 0), (0, 0, size)],
            [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)])


def _stub_bytes(suffix: str, size: float) -> bytes:
    v, f = _tetrahedron(size)
    if suffix == ".stl":  # binary STL (MuJoCo reads binary STL)
        out = bytearray(b"redysim mesh stub".ljust(80, b" ")) + struct.pack("<I", len(f))
        for face in f:
            out += struct.pack("<3f", 0.0, 0.0, 0.0)
            for i in face:
                out += struct.pack("<3f", *v[i])
            out += b"\0\0"
        return bytes(out)
    return ("# redysim mesh stub\n" + "".join(f"v {x} {y} {z}\n" for x, y, z in v)
            + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f)).encode()


def _is_stub(path: Path) -> bool:
    with open(path, "rb") as fh:
        return fh.read(19).lstrip(b"# ").startswith(b"redysim mesh stub")


def stub_missing_meshes(root: Path, model_file: Path, mujoco) -> list[Path]:
    """Write a stub where a mesh ``model_file`` names is absent; enlarge the stubs MuJoCo finds
    too small (a mesh ``scale`` of 1e-3). Returns the stubs written."""
    written: list[Path] = []
    for size in (0.05, 50.0):
        try:
            spec = mujoco.MjSpec.from_file(str(model_file))
        except Exception:  # noqa: BLE001 - a fragment: MuJoCo's compile says why, later
            return written
        meshdir = Path(spec.meshdir or "")
        for mesh in spec.meshes:
            if not mesh.file:
                continue
            path = model_file.parent / meshdir / mesh.file
            if path.suffix.lower() in (".obj", ".stl") and (not path.exists() or _is_stub(path)):
                path.write_bytes(_stub_bytes(path.suffix.lower(), size))
                if path not in written:
                    written.append(path)
        if not written:
            return written
        try:
            mujoco.MjModel.from_xml_path(str(model_file))
            return written
        except Exception as exc:  # noqa: BLE001
            if "too small" not in str(exc) and "eigenvalues" not in str(exc):
                return written
    return written


# --------------------------------------------------------------------------- MuJoCo's side
def _mujoco_model(mujoco, path: Path):
    m = mujoco.MjModel.from_xml_path(str(path))
    off = mujoco.mjtDisableBit
    m.opt.disableflags |= (off.mjDSBL_CONTACT | off.mjDSBL_LIMIT | off.mjDSBL_FRICTIONLOSS
                           | off.mjDSBL_ACTUATION)
    m.opt.density, m.opt.viscosity = 0.0, 0.0
    m.opt.jacobian = mujoco.mjtJacobian.mjJAC_DENSE
    return m


def _equality_rows(mujoco, m, d, q, v) -> np.ndarray:
    d.qpos[:], d.qvel[:] = q, v
    mujoco.mj_forward(m, d)
    rows = d.efc_type[:d.nefc] == mujoco.mjtConstraint.mjCNSTR_EQUALITY
    return d.efc_J[:d.nefc * m.nv].reshape(d.nefc, m.nv)[rows].copy()


def _jdot_v(mujoco, m, d, q, v) -> np.ndarray:
    """Jdot v = d/dt (J(q(t)) v) along q' = v, by Richardson-extrapolated central differences."""
    def jv(eps):
        out = []
        for s in (eps, -eps):
            qs = q.copy()
            mujoco.mj_integratePos(m, qs, v, s)
            out.append(_equality_rows(mujoco, m, d, qs, v) @ v)
        return (out[0] - out[1]) / (2 * eps)
    h = 1e-3
    return (4 * jv(h / 2) - jv(h)) / 3


def mujoco_truth(mujoco, m, q, v, tau) -> tuple[np.ndarray, np.ndarray]:
    """(qacc of the smooth dynamics, constraints exact; M) of MuJoCo's model at (q, v, tau)."""
    d = mujoco.MjData(m)
    J = _equality_rows(mujoco, m, d, q, v) if m.neq else np.zeros((0, m.nv))
    d.qpos[:], d.qvel[:], d.qfrc_applied[:] = q, v, tau
    mujoco.mj_forward(m, d)
    M = np.zeros((m.nv, m.nv))
    mujoco.mj_fullM(m, d, M)
    f = tau + d.qfrc_passive - d.qfrc_bias
    routed = np.flatnonzero(m.jnt_actgravcomp[m.dof_jntid])  # actuatorgravcomp: the actuators'
    f[routed] += d.qfrc_gravcomp[routed]  # (off here) gravity compensation, whole, as the core's
    a = np.linalg.solve(M, f)
    if J.shape[0]:
        b = J @ a + _jdot_v(mujoco, m, d, q, v)
        Minv_Jt = np.linalg.solve(M, J.T)
        lam = np.linalg.pinv(J @ Minv_Jt, rcond=1e-10) @ b
        a = a - Minv_Jt @ lam
    return a, M


# --------------------------------------------------------------------------- the core's side
def _state(rng, model, system, first: bool):
    from scipy.spatial.transform import Rotation

    q = np.array(model.initial(), dtype=float)
    if not first:
        for k, t in enumerate(model.joint_types):
            qs, qe = int(model.joint_qoff[k]), int(model.joint_qoff[k + 1])
            if t == "free":
                x, y, z, w = Rotation.random(random_state=rng).as_quat()
                q[qs:qs + 7] = [*(q[qs:qs + 3] + rng.normal(size=3)), w, x, y, z]
            elif t == "ball":  # (near its start on a closed mechanism, whose loops it moves)
                turn = Rotation.from_rotvec(rng.normal(scale=0.05, size=3)) if model.cuts \
                    else Rotation.random(random_state=rng)
                w0, x0, y0, z0 = q[qs:qe]
                x, y, z, w = (Rotation.from_quat([x0, y0, z0, w0]) * turn).as_quat()
                q[qs:qe] = [w, x, y, z]
            else:
                q[qs:qe] += rng.normal(scale=0.05 if model.cuts else 0.3, size=qe - qs)
    v = rng.normal(size=model.n_v)
    tau = rng.normal(size=model.n_v)
    if model.couplings:
        q, v = model.couple(q, v)
    if system.loops is not None:  # onto the loops (Newton from the moved q, a few rounds)
        for _ in range(4):
            q, v, _, _ = system.loops.project(q, v)
    y = system.initial_state(q, v, work=False) if (model.cuts or model.couplings) \
        else np.concatenate((q, v))
    return y[:model.n_q], y[model.n_q:], tau


def compare_one(path: Path, states: int = 4, seed: int = 7) -> dict:
    """One model's row of the survey (module docstring)."""
    import mujoco

    import redysim
    from redysim.algorithms.system import System

    row: dict = {"model": f"{path.parent.name}/{path.name}"}
    try:
        m = _mujoco_model(mujoco, path)
    except Exception as exc:  # noqa: BLE001 - reported, not counted
        row.update(status="mujoco-refuses", reason=str(exc).splitlines()[0][:160])
        return row
    row.update(nq=m.nq, nv=m.nv, neq=m.neq)
    t0 = time.perf_counter()
    try:
        model = redysim.load_model(path)
    except Exception as exc:  # noqa: BLE001 - a refusal, by name (or a defect: read it)
        row.update(status="refused", reason=f"{type(exc).__name__}: "
                   + str(exc).splitlines()[0][:200])
        return row
    row["load_s"] = round(time.perf_counter() - t0, 3)
    notes = [n for n in model.notes if not any(w in n.lower() for w in ALLOWED)]
    row["dropped"] = " | ".join(notes)[:300]
    rng = np.random.default_rng(seed)
    system = System(model)
    worst_m = worst_a = 0.0
    try:
        for i in range(states):
            q, v, tau = _state(rng, model, system, i == 0)
            qacc, M = mujoco_truth(mujoco, m, q, v, tau)
            ours_M = redysim.mass_matrix(model, q)
            # tau: the applied forces, as MuJoCo's qfrc_applied, on top of the system's own
            ours_a = System(model, tau=lambda t, q_, v_, tau=tau: tau,
                            loops=system.loops).qdd(0.0, q, v)
            worst_m = max(worst_m, _rel(ours_M, M))
            worst_a = max(worst_a, _rel(ours_a, qacc))
    except Exception as exc:  # noqa: BLE001 - the comparison failed: a defect to read
        row.update(status="error", reason=f"{type(exc).__name__}: "
                   + str(exc).splitlines()[0][:200])
        return row
    row.update(M_rel=f"{worst_m:.1e}", qacc_rel=f"{worst_a:.1e}")
    agrees = worst_m <= M_TOL and worst_a <= QACC_TOL and not notes
    row["status"] = "agrees" if agrees else "differs"
    return row


def _rel(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    if a.shape != b.shape:
        return float("inf")
    return float(np.max(np.abs(a - b)) / max(np.max(np.abs(b)), 1e-300))


def model_files(root: Path) -> list[Path]:
    return sorted(p for p in root.glob("*/*.xml") if not p.name.startswith("scene"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(prog="python -m redysim.references.menagerie",
                                 description=__doc__.split("\n\n")[0])
    ap.add_argument("root", type=Path, help="a mujoco_menagerie checkout")
    ap.add_argument("--stub-missing-meshes", action="store_true",
                    help="write a small tetrahedron where a mesh file is absent (module doc)")
    ap.add_argument("--out", type=Path, help="write the table as CSV here")
    ap.add_argument("--only", help="models whose path matches this regular expression")
    ap.add_argument("--fixtures", type=Path, metavar="DIR",
                    help="instead of the survey, write each model --only selects as a test "
                    "fixture needing no mesh file (write_fixture), with its folder's LICENSE, "
                    "under DIR/<folder>/")
    args = ap.parse_args(argv)
    if not args.root.is_dir():
        ap.error(f"{args.root}: no such folder (a mujoco_menagerie checkout)")
    import mujoco

    if args.fixtures:
        import shutil

        for path in model_files(args.root):
            if args.only and re.search(args.only, str(path.relative_to(args.root))):
                if args.stub_missing_meshes:
                    stub_missing_meshes(args.root, path, mujoco)
                target = write_fixture(path, args.fixtures / path.parent.name, mujoco)
                shutil.copy(path.parent / "LICENSE", target.parent / "LICENSE")
                print(target)
        return 0

    files = [p for p in model_files(args.root)
             if not args.only or re.search(args.only, str(p.relative_to(args.root)))]
    rows = []
    for i, path in enumerate(files):
        if args.stub_missing_meshes:
            stub_missing_meshes(args.root, path, mujoco)
        row = compare_one(path)
        rows.append(row)
        print(f"[{i + 1}/{len(files)}] {row['model']:55s} {row['status']:15s} "
              f"{row.get('M_rel', ''):>8s} {row.get('qacc_rel', ''):>8s} "
              f"{row.get('reason', row.get('dropped', ''))[:110]}", flush=True)
    counted = [r for r in rows if r["status"] != "mujoco-refuses"]
    agree = sum(r["status"] == "agrees" for r in counted)
    print(f"\n{len(counted)} models MuJoCo compiles: {agree} agree "
          f"({100 * agree / max(len(counted), 1):.1f} %), "
          + ", ".join(f"{s} {sum(r['status'] == s for r in counted)}"
                      for s in ("differs", "refused", "error")))
    if args.out:
        keys = ["model", "status", "nq", "nv", "neq", "M_rel", "qacc_rel", "load_s", "dropped",
                "reason"]
        with open(args.out, "w", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=keys, extrasaction="ignore")
            w.writeheader()
            w.writerows(rows)
    return 0



# --------------------------------------------------------------------------- test fixtures
def _exact_inertials(xml: str, m, mujoco) -> str:
    """The XML with each body's pose, <inertial> and joint axes written to 17 digits from the
    compiled model (the spec's writer rounds quaternions to 6)."""
    import xml.etree.ElementTree as ET

    root = ET.fromstring(xml)
    if root.find(".//frame") is None:  # (a <frame> would compose into the compiled poses)
        for el in root.iter("body"):
            if el.get("name"):
                b = m.body(el.get("name"))
                for key in ("euler", "axisangle", "xyaxes", "zaxis"):
                    el.attrib.pop(key, None)
                el.set("pos", " ".join(repr(float(x)) for x in b.pos))
                el.set("quat", " ".join(repr(float(x)) for x in b.quat))
        for el in root.iter("joint"):
            if el.get("name") and el.get("type", "hinge") in ("hinge", "slide"):
                j = m.joint(el.get("name"))
                el.set("axis", " ".join(repr(float(x)) for x in j.axis))
                adr = int(j.qposadr[0])  # ref and springref in radians (the writer's angle)
                el.set("ref", repr(float(m.qpos0[adr])))
                el.set("springref", repr(float(m.qpos_spring[adr])))
            if el.get("name"):
                el.set("pos", " ".join(repr(float(x)) for x in m.joint(el.get("name")).pos))
    for el in root.iter("body"):
        inertial = el.find("inertial")
        if inertial is None or not el.get("name"):
            continue
        b = m.body(el.get("name"))
        inertial.attrib.clear()
        inertial.set("pos", " ".join(repr(float(x)) for x in b.ipos))
        inertial.set("quat", " ".join(repr(float(x)) for x in b.iquat))
        inertial.set("mass", repr(float(b.mass[0])))
        inertial.set("diaginertia", " ".join(repr(float(x)) for x in b.inertia))
    return ET.tostring(root, encoding="unicode")


def write_fixture(path: Path, out: Path, mujoco) -> Path:
    """A copy of the model ``path`` that needs no mesh file, with the same dynamics: every
    body's inertia written explicitly as MuJoCo compiled it (from the meshes present), mesh
    geoms, meshes, textures and materials removed. Checked: its mass matrix and qacc equal the
    original's at random states (to 1e-13 relative), else ValueError. Returns the file written."""
    spec = mujoco.MjSpec.from_file(str(path))
    m = spec.compile()
    spec.compiler.inertiafromgeom = mujoco.mjtInertiaFromGeom.mjINERTIAFROMGEOM_FALSE
    for body in spec.bodies[1:]:
        b = m.body(body.name) if body.name else None
        if b is None:
            raise ValueError(f"{path}: an unnamed body; name it to make a fixture")
        body.explicitinertial = True
        body.mass, body.ipos = float(b.mass[0]), b.ipos.copy()
        body.iquat, body.inertia = b.iquat.copy(), b.inertia.copy()
        body.fullinertia = np.full(6, np.nan)
    meshes = {g.name for g in spec.geoms if g.type == mujoco.mjtGeom.mjGEOM_MESH}
    for g in list(spec.geoms):
        if g.type == mujoco.mjtGeom.mjGEOM_MESH:
            spec.delete(g)
        else:
            g.material = ""
    for pair in list(spec.pairs):
        if pair.geomname1 in meshes or pair.geomname2 in meshes:
            spec.delete(pair)
    for item in [*spec.meshes, *spec.materials, *spec.textures, *spec.hfields]:
        spec.delete(item)
    for s in spec.skins:
        spec.delete(s)
    out.mkdir(parents=True, exist_ok=True)
    target = out / path.name
    target.write_text(_exact_inertials(spec.to_xml(), m, mujoco))
    m1 = _mujoco_model(mujoco, path)
    m2 = _mujoco_model(mujoco, target)
    rng = np.random.default_rng(0)
    for _ in range(3):
        q = m1.qpos0 + 0.1 * rng.normal(size=m1.nq) * (m1.jnt_type[m1.dof_jntid[0]] != 0)
        d = mujoco.MjData(m1)
        d.qpos[:] = q
        mujoco.mj_normalizeQuat(m1, d.qpos)
        v, tau = rng.normal(size=m1.nv), rng.normal(size=m1.nv)
        a1, M1 = mujoco_truth(mujoco, m1, d.qpos.copy(), v, tau)
        a2, M2 = mujoco_truth(mujoco, m2, d.qpos.copy(), v, tau)
        if _rel(M2, M1) > 1e-13 or _rel(a2, a1) > 1e-12:
            raise ValueError(f"{target}: the fixture's dynamics differ from {path}'s "
                             f"(M {_rel(M2, M1):.1e}, qacc {_rel(a2, a1):.1e})")
    return target


if __name__ == "__main__":
    sys.exit(main())
