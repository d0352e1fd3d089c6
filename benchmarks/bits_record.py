"""Trajectories of many runs in one file, to compare two revisions bit for bit.

    .venv/bin/python benchmarks/bits_record.py OUT.npz        (in each revision's checkout)
    .venv/bin/python benchmarks/bits_compare.py BASE.npz HEAD.npz

About 70 runs (the paper's rope under each integrator, damped and with a tip force; the
scenarios; the robots, coupled and not), each's t, q, v, energy, COM, counts, observers and
forces, through the APIs every revision since be08d5d has (``simulate``, ``load_case``,
``load_scenario(...).simulator()``), so that the script runs unchanged in an older checkout
(copy it there). A refactoring that keeps the arithmetic's order must give 0 differing arrays.
"""

import sys
import warnings

import numpy as np

from redysim import Chain, load_case, load_model, simulate
from redysim.io.scenarios import list_scenarios, load_scenario, robot_data_file

warnings.simplefilter("ignore")

out = {}


def keep(name, res):
    for f in ("t", "q", "v", "energy", "com"):
        out[f"{name}/{f}"] = np.asarray(getattr(res, f))
    out[f"{name}/counts"] = np.array([res.steps, res.rejected, res.nfev, res.status])
    out[f"{name}/qerr"] = np.array([res.quaternion_error, res.residual_q, res.residual_v])
    for k, v in res.observed.items():
        out[f"{name}/obs/{k}"] = np.asarray(v)
    if res.forces is not None:
        out[f"{name}/forces"] = np.asarray(res.forces)
    print(name, res.status, res.steps, res.nfev, flush=True)


# paper cases through simulate()
c = load_case("RE-U125-L1")
keep("u125-ode45", simulate(c.chain, 0.05, q0=c.q0, v0=c.v0))
keep(
    "u125-dop853",
    simulate(c.chain, 0.02, q0=c.q0, v0=c.v0, integrator="dop853", rtol=1e-8, atol=1e-10),
)
keep("u125-rk4", simulate(c.chain, 0.005, q0=c.q0, v0=c.v0, integrator="rk4", h=1e-5))
keep("u125-damped", simulate(c.chain, 0.02, q0=c.q0, v0=c.v0, damping=0.01))
keep("u125-midpoint", simulate(c.chain, 0.02, q0=c.q0, v0=c.v0, integrator="midpoint", rtol=1e-4))
keep(
    "u125-scipy",
    simulate(c.chain, 0.01, q0=c.q0, v0=c.v0, integrator="scipy-RK45", rtol=1e-6, atol=1e-8),
)
s = load_case("STUDY-R10")
keep("r10-ode45", simulate(s.chain, 1.0, q0=s.q0, v0=s.v0, rtol=1e-6, atol=1e-8))
r = load_case("RE-R229-L1.02-DX1.02")
keep("r229", simulate(r.chain, 0.2, q0=r.q0, v0=r.v0))
# a pulled case (tip force, planar) through its own simulator
p = load_case("cases/refine/pulled-R128.toml")
keep("pulled", p.simulator(0.05, sample=0.01).run())
keep("pulled-dop", p.simulator(0.05, sample=0.01, integrator="dop853", rtol=1e-9, atol=1e-11).run())
# every scenario, shortened; and the Python loop too where the steps compile
for name in list_scenarios():
    scn = load_scenario(name)
    if scn.model.n_v > 2000:
        continue
    T = min(scn.t_end, 0.05)
    try:
        keep(f"scn-{name}", scn.simulator(T, sample=T / 5).run())
        keep(f"scn-{name}-py", scn.simulator(T, sample=T / 5, compiled=False).run())
        keep(
            f"scn-{name}-dop",
            scn.simulator(T, sample=T / 5, integrator="dop853", rtol=1e-9, atol=1e-11).run(),
        )
    except Exception as exc:
        print("FAIL", name, type(exc).__name__, exc)
# loops files
for f in ("crank_rocker", "jansen_leg", "pinned_chain_10"):
    try:
        scn = load_scenario(f"cases/loops/{f}.toml")
    except Exception as exc:
        print("skip", f, exc)
        continue
    keep(f"loops-{f}", scn.simulator(0.05, sample=0.01).run())
    keep(f"loops-{f}-py", scn.simulator(0.05, sample=0.01, compiled=False).run())
# a spatial chain pulled at its tip, damped
ch = Chain.uniform(6, "U", length=0.3, linear_density=2.0, radius=0.02)
rng = np.random.default_rng(9)
q0, v0 = rng.uniform(-0.8, 0.8, ch.n_dof), rng.normal(size=ch.n_dof)
try:
    from redysim.simulation import simulator as Simulator
except ImportError:
    from redysim.simulation import Simulator
for comp in (True, False):
    keep(
        f"upull-{comp}",
        Simulator(
            ch,
            0.3,
            q0=q0,
            v0=v0,
            integrator="dop853",
            rtol=1e-9,
            atol=1e-11,
            damping=0.05,
            tip_force=np.array([1.5, -0.7, 2.0]),
            compiled=comp,
            sample=0.05,
        ).run(),
    )
# a Pinocchio qdd provider through our integrator
try:
    from redysim.references import get

    eng = get("pinocchio-aba")(c.chain)
    keep("u125-pin", Simulator(c.chain, 0.005, q0=c.q0, v0=c.v0, qdd=eng.qdd, sample=0.001).run())
except Exception as exc:
    print("engine skip", exc)

pm = load_model(robot_data_file("panda_description/urdf/panda.urdf"))
print("couplings", pm.couplings)
for comp in (True, False):
    keep(
        f"panda-coupled-{comp}",
        Simulator(
            pm, 0.05, integrator="dop853", rtol=1e-9, atol=1e-11, compiled=comp, sample=0.01
        ).run(),
    )
np.savez(sys.argv[1], **out)
print(len(out), "arrays")
