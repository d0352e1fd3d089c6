"""redysim.simulate on models: the quaternion of a free joint, momentum, energy, the command.

Checks that need no reference solution: a floating tree in free fall has its centre of mass on
the parabola c0 + cdot0 t + g t^2 / 2 (only gravity acts on it), its energy conserved to the
integrator's tolerance, and its quaternion on the unit sphere after every step, whichever
integrator steps it.
"""

from __future__ import annotations

import numpy as np
import pytest
from conftest import stable_seed
from test_trees import random_configuration, random_tree, robot_urdf

from redysim.errors import SettingsError, StateError
from redysim.harness.cli import main
from redysim.simulation import simulate

SETTINGS = {"ode45": dict(rtol=1e-9, atol=1e-11), "dop853": dict(rtol=1e-10, atol=1e-12),
            "rk4": dict(h=2e-4), "scipy-RK45": dict(rtol=1e-9, atol=1e-11),
            "scipy-DOP853": dict(rtol=1e-10, atol=1e-12), "scipy-LSODA": dict(rtol=1e-9,
                                                                              atol=1e-11),
            "scipy-Radau": dict(rtol=1e-8, atol=1e-10)}


def _parabola_error(sim, gravity) -> float:
    """Largest distance of the sampled COM from its least-squares line after the gravity term
    is taken off: c(t) - g t^2 / 2 must be c0 + cdot0 t."""
    A = np.column_stack([np.ones_like(sim.t), sim.t])
    rest = sim.com - 0.5 * np.outer(sim.t ** 2, gravity)
    coef, *_ = np.linalg.lstsq(A, rest, rcond=None)
    return float(np.abs(A @ coef - rest).max())


@pytest.mark.parametrize("integrator", SETTINGS)
def test_a_floating_tree_falls_freely_with_every_integrator(integrator):
    model = random_tree(stable_seed("free-fall"), n_bodies=5)
    rng = np.random.default_rng(7)
    q0, v0 = random_configuration(rng, model), rng.normal(size=model.n_v)
    sim = simulate(model, 0.3, q0=q0, v0=v0, integrator=integrator, sample=0.03,
                   **SETTINGS[integrator])
    assert sim.status == 0, sim.message
    quats = sim.q[:, model.quaternions[0]:model.quaternions[0] + 4]
    assert np.abs(np.linalg.norm(quats, axis=1) - 1).max() < 1e-15
    # it drifted (but for DOP853 at 1e-10: 13 steps, |q| within rounding of 1), and was
    # projected back
    assert (0 <= sim.quaternion_error if integrator == "dop853" else 0 < sim.quaternion_error) \
        and sim.quaternion_error < 1e-6
    assert _parabola_error(sim, model.gravity) < 1e-8
    assert np.abs(sim.delta_M).max() < 1e-6


def test_bad_settings_and_states_are_refused():
    model = random_tree(stable_seed("sim-bad"), n_bodies=3)
    with pytest.raises(SettingsError, match="h"):
        simulate(model, 0.1, integrator="rk4")
    with pytest.raises(SettingsError, match="rtol"):
        simulate(model, 0.1, rtol=2.0)
    q0 = model.neutral()
    q0[model.quaternions[0]] = 2.0
    with pytest.raises(StateError, match="unit quaternion"):
        simulate(model, 0.1, q0=q0)
    with pytest.raises(StateError, match="shape"):
        simulate(model, 0.1, v0=np.zeros(model.n_v + 1))


def test_redysim_simulate_runs_a_urdf(capsys, tmp_path):
    """The command on a robot no one here wrote: a passive fall, the drift and the COM printed,
    the samples saved."""
    out = tmp_path / "fall.csv"
    path = robot_urdf("solo12.urdf")
    assert main(["simulate", path, "--floating", "--t-end", "0.2", "--rtol", "1e-9", "--atol",
                 "1e-11", "--out", str(out)]) == 0
    text = capsys.readouterr().out
    assert "floating base" in text and "|delta_M|" in text and "COM z [m]" in text
    import pandas as pd

    df = pd.read_csv(out)
    # a model file's own scenario samples its horizon 20 times (redysim.io.scenarios)
    assert {"t", "delta_M", "com_z", "q0", "v0"} <= set(df.columns) and len(df) == 21
    # the URDF importer's gravity, -z: in free fall (a floating file tumbles from seeded
    # velocities) the COM's height is a parabola of acceleration -g, whatever its start
    g, dt = 9.81, 0.01
    z = df["com_z"].to_numpy()
    assert np.ptp(df["v6"]) > 0  # it tumbles: its joints move
    assert (z[2:] - 2 * z[1:-1] + z[:-2]) / dt ** 2 == pytest.approx(-g, rel=1e-6)
    # and an engine runs it too (through the same harness run, redysim.harness.run)
    assert main(["simulate", path, "--floating", "--engine", "mujoco", "--t-end", "0.1"]) == 0
    assert "mujoco ode45" in capsys.readouterr().out


def test_the_talks_free_fall_of_puma_joints_2_and_3_conserves_energy(capsys):
    """The talk's 'free fall: joints 2 and 3' on the PUMA 560 of cases/robots (joints 1, 4, 5,
    6 held at zero): energy conserved to the integrator's tolerance, by the command line too."""
    from pathlib import Path

    from redysim import load_model

    path = Path(__file__).resolve().parents[1] / "cases" / "robots" / "puma560.toml"
    puma = load_model(path).locked({"joint1": 0.0, "joint4": 0.0, "joint5": 0.0,
                                    "joint6": 0.0})
    assert puma.joint_names == ("joint2", "joint3")
    sim = simulate(puma, 2.0, rtol=1e-10, atol=1e-12, sample=0.1)
    assert sim.status == 0 and np.ptp(sim.q[:, 0]) > 1.0  # it swings
    assert np.abs(sim.delta_M).max() < 1e-8
    argv = ["simulate", str(path), "--t-end", "0.5"]
    argv += [x for j in (1, 4, 5, 6) for x in ("--lock", f"joint{j}=0")]
    assert main(argv) == 0
    assert "4 joints locked" in capsys.readouterr().out
    assert main(["simulate", str(path), "--lock", "joint9=0"]) == 2
    assert "no such joint" in capsys.readouterr().err


def test_simulate_out_samples_carry_the_summarys_run_id(capsys, tmp_path):
    """`redysim simulate --out` writes the samples and the summary of one run: the samples'
    run_id is the summary's (it was the resolved spec's, an id no summary had), and a robot
    given by its name (example-robot-data:NAME) runs like its file."""
    import pandas as pd

    from redysim.io.scenarios import robot_data_file

    if robot_data_file("ur5") is None:
        pytest.skip("example-robot-data is not installed")
    out = tmp_path / "fall.csv"
    assert main(["simulate", "example-robot-data:ur5", "--t-end", "0.05", "--out",
                 str(out)]) == 0
    assert "ur5" in capsys.readouterr().out
    samples = pd.read_csv(out)
    summary = pd.read_csv(tmp_path / "fall.summary.csv")
    assert len(summary) == 1 and len(samples) == 21
    assert set(samples["run_id"]) == {summary["run_id"][0]}


def test_a_run_without_limits_reads_no_clock_per_step(monkeypatch):
    """The Simulator's fixed cost: without max_cpu_s or max_wall_s a run reads the CPU clock
    twice (its start and its cpu_s), not once per step or sample; with max_cpu_s the limit is
    still checked (a tiny one fails the run, saying so)."""
    import time

    from redysim import Chain

    chain = Chain.uniform(4, "R", length=0.25, mass=0.5)
    calls = []
    real = time.thread_time
    monkeypatch.setattr(time, "thread_time", lambda: calls.append(1) or real())
    sim = simulate(chain, 0.5, q0=np.full(4, 0.3), sample=0.01, rtol=1e-8, atol=1e-10)
    assert sim.status == 0 and sim.steps > 10 and sim.t.size == 51
    assert len(calls) == 2
    from redysim.simulation import simulator
    run = simulator(chain, 0.5, q0=np.full(4, 0.3), sample=0.01, rtol=1e-8,
                    atol=1e-10).run(max_cpu_s=1e-9)
    assert run.status == -1 and "max_cpu_s" in run.message
