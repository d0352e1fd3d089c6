"""redysim: O(n) dynamics of very long serial chains and kinematic trees (DeNOC + Reverse
Gaussian Elimination).

The public surface; everything else is internal::

    from redysim import load_case, forward_dynamics
    case = load_case("RE-U125-L1")
    qdd = forward_dynamics(case.chain, case.q0, case.v0)

    from redysim import load_model, simulate
    robot = load_model("example-robot-data:ur5")  # or a .urdf, an MJCF .xml
    fall = simulate(robot, 1.0, rtol=1e-8, atol=1e-10)

The names are imported on first use (PEP 562): ``import redysim`` itself loads neither numba nor
SciPy, so that a command's ``--help`` answers at once.

References:
    A. Agarwal, S. V. Shah, S. Bandyopadhyay, S. K. Saha, "Dynamics of serial kinematic chains
    with large number of degrees-of-freedom", Multibody System Dynamics (2014).
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

# public name -> the module that defines it (a module itself when its last part is the name)
_WHERE = {
    **dict.fromkeys(("Case", "case_from_dict", "list_cases", "load_case", "load_published"),
                    "io.cases"),
    **dict.fromkeys(("JOINT_TYPES", "Joint", "Link"), "model.parts"),
    **dict.fromkeys(("METHODS", "UDU", "Elimination", "Momentum", "Tip", "delta_M",
                     "eliminate", "energy", "forward_dynamics", "frame_motion",
                     "generalized_momentum", "inverse_dynamics", "joint_positions",
                     "mass_matrix", "momentum", "phi", "tip", "udu_factors"),
                    "algorithms.dynamics"),
    **dict.fromkeys(("CaseError", "FieldError", "ModelTypeError", "RedysimError",
                     "SettingsError", "StateError"), "errors"),
    "ModelFileError": "io.importers",
    "load_model": "io.kinds",
    **dict.fromkeys(("Body", "Chain", "Coupling", "CutJoint", "Model", "TreeJoint"), "model.tree"),
    **dict.fromkeys(("Integrator", "Simulation", "Simulator", "simulate", "simulate_batch"),
                    "simulation"),
    **dict.fromkeys(("System", "passive_forces"), "algorithms.system"),
    "ClosedLoops": "algorithms.loops",
    **dict.fromkeys(("Coarsening", "coarsen"), "algorithms.coarse"),
    **dict.fromkeys(("Linkage", "load_linkage"), "io.linkage_files"),
    "Workspace": "algorithms.workspace",
    "evaluator": "algorithms.evaluators",
    "rbda": "algorithms.rbda",
}

__all__ = sorted(_WHERE)


def __getattr__(name: str):
    module = _WHERE.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    mod = importlib.import_module(f".{module}", __name__)
    value = mod if module.rsplit(".", 1)[-1] == name else getattr(mod, name)
    globals()[name] = value  # once imported, an ordinary attribute
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *__all__})
