"""redysim: O(n) dynamics of very long serial chains and kinematic trees (DeNOC + Reverse
Gaussian Elimination).

The public surface; everything else is internal::

    from redysim import load_case, forward_dynamics
    case = load_case("RE-U125-L1")
    qdd = forward_dynamics(case.chain, case.q0, case.qd0)

    from redysim import load_model, simulate
    robot = load_model("ur5_robot.urdf")          # or an MJCF .xml
    fall = simulate(robot, 1.0, rtol=1e-8, atol=1e-10)

References:
    A. Agarwal, S. V. Shah, S. Bandyopadhyay, S. K. Saha, "Dynamics of serial kinematic chains
    with large number of degrees-of-freedom", Multibody System Dynamics (2014).
"""

from . import rbda
from .cases import Case, case_from_dict, list_cases, load_case, load_published
from .chain import JOINT_TYPES, Chain, Joint, Link
from .dynamics import (
    METHODS,
    UDU,
    Elimination,
    Tip,
    delta_M,
    eliminate,
    energy,
    forward_dynamics,
    inverse_dynamics,
    joint_positions,
    mass_matrix,
    phi,
    tip,
    udu_factors,
)
from .errors import CaseError, FieldError, RedysimError, SettingsError, StateError
from .importers import ModelFileError, load_model
from .model import Body, Model, TreeJoint
from .simulation import Simulation, simulate
from .workspace import Workspace

__version__ = "0.1.0"

__all__ = [
    "Body", "Case", "CaseError", "Chain", "Elimination", "FieldError", "JOINT_TYPES", "Joint",
    "Link", "METHODS", "Model", "ModelFileError", "RedysimError", "SettingsError", "Simulation",
    "StateError", "Tip", "TreeJoint", "UDU", "Workspace", "case_from_dict", "delta_M",
    "eliminate", "energy", "forward_dynamics", "inverse_dynamics", "joint_positions",
    "list_cases", "load_case", "load_model", "load_published", "mass_matrix", "phi", "rbda",
    "simulate", "tip", "udu_factors",
]
