"""Coarse-graining a chain: k consecutive links lumped into one rigid link, and states mapped both
ways (docs/design.md, "Model size").

A lumped link is the group's links welded in their straight configuration (every joint inside
the group held at zero): its length is the sum of theirs, and its mass, first moment and inertia
about its joint are the sums of theirs (the parallel-axis theorem about the group's first
joint), so the coarse chain is exactly the fine chain with those joints locked. Lumping k
uniform links of a rod model gives the uniform chain of n/k links of the same rod, to
round-off: coarse-graining and a coarser discretisation of one physical rope are the same thing.
Armature (a joint's own inertia) follows the same rule: a coarse joint keeps its group's first
joint's, and the inner joints' is dropped with their motion (summing it would give the coarse
joint rotors that turn only when the inner joints do, which are locked).

States:

- :meth:`Coarsening.to_fine` is exact: the group's first joint takes the coarse joint's
  coordinates and rates, the others zero. The fine chain then moves as the coarse one does
  (same tip, energy, and qdd with the inner joints locked).
- :meth:`Coarsening.to_coarse` is a projection: each coarse link points along its group's chord
  (from the group's first joint to the next group's, or to the tip), and its angular velocity
  turns that chord as the fine motion does (the stretching of the chord, which a rigid link
  cannot follow, is dropped). It inverts ``to_fine``: ``to_coarse(to_fine(x)) == x``.
  It needs joints whose rotations can point a link anywhere they point it: universal joints,
  or revolute joints about an axis normal to the link (planar chains); the coarse joint of a
  group is its first fine joint.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property

import numpy as np

from redysim.algorithms.dynamics import check_state, tip
from redysim.algorithms.workspace import Workspace
from redysim.errors import CaseError
from redysim.model.parts import Link
from redysim.model.tree import Chain, Model

MAPPABLE = ("R", "U")  # joint types whose coordinates to_coarse can solve for from a chord


def _rot(axis: np.ndarray, angle: float) -> np.ndarray:
    """Rotation by ``angle`` about the unit vector ``axis`` (Rodrigues)."""
    x, y, z = axis
    K = np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])
    return np.eye(3) + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


@dataclass(frozen=True, eq=False)
class Coarsening:
    """A fine chain, its coarse-grained chain, and the groups that map one to the other.

    ``starts``: (n_coarse + 1,) the first fine link of each group, then the fine link count.
    """

    fine: Model  # a Chain, or a Model laid out as one (chain_of)
    coarse: Chain
    starts: np.ndarray

    @property
    def factor(self) -> int | None:
        """k when every group has k links, else None."""
        sizes = np.diff(self.starts)
        return int(sizes[0]) if np.all(sizes == sizes[0]) else None

    @cached_property
    def _fine_first_dofs(self) -> np.ndarray:
        """Indices, in the fine q, of the DOFs of each group's first joint (coarse DOF order)."""
        off = self.fine.joint_qoff
        return np.concatenate([np.arange(off[s], off[s + 1]) for s in self.starts[:-1]])

    # ------------------------------------------------------------------- coarse -> fine (exact)
    def to_fine(self, q, v):
        """The fine state that moves as the coarse state ``(q, v)`` does (exact)."""
        q = check_state(self.coarse, "q", q)
        v = check_state(self.coarse, "v", v)
        qf = np.zeros(self.fine.n_dof)
        qdf = np.zeros(self.fine.n_dof)
        qf[self._fine_first_dofs] = q
        qdf[self._fine_first_dofs] = v
        return qf, qdf

    # ------------------------------------------------------------------- fine -> coarse (chords)
    def to_coarse(self, q, v):
        """The coarse state whose links follow the fine state's group chords (a projection;
        the inverse of :meth:`to_fine`)."""
        fine, coarse = self.fine, self.coarse
        q = check_state(fine, "q", q)
        v = check_state(fine, "v", v)
        ws = Workspace(fine)
        end = tip(fine, q, v, ws=ws)  # runs the kinematics: ws.oO, ws.t are the fine frames'
        points = np.vstack([ws.oO, end.position])  # O_1..O_nl and the tip
        vel = np.vstack([ws.t[:, 3:], end.velocity])
        qc = np.zeros(coarse.n_dof)
        qdc = np.zeros(coarse.n_dof)
        R = np.eye(3)  # the coarse parent's world rotation
        w = np.zeros(3)  # and its angular velocity
        for g in range(coarse.n_links):
            s, e = self.starts[g], self.starts[g + 1]
            chord = points[e] - points[s]
            size = float(np.linalg.norm(chord))
            if not size > 0.0:
                raise CaseError(f"{coarse.name}.to_coarse", f"group {g}", [int(s), int(e)],
                                "the group folds onto itself (its chord has zero length): no "
                                "direction for the coarse link")
            d = chord / size
            dot = vel[e] - vel[s]
            d_rate = (dot - d * (d @ dot)) / size  # the chord's turning; its stretch is dropped
            local = R.T @ d
            lo, hi = coarse.joint_qoff[g], coarse.joint_qoff[g + 1]
            units = coarse.dof_u[lo:hi]
            if hi - lo == 2:  # U: Ry(a) Rz(b) e_x = (cos a cos b, sin b, -sin a cos b)
                a = float(np.arctan2(-local[2], local[0]))
                b = float(np.arcsin(np.clip(local[1], -1.0, 1.0)))
                angles = (a, b)
            else:  # R about an axis u normal to the link: e_x turned by a about u
                u = units[0]
                a = float(np.arctan2(np.cross([1.0, 0.0, 0.0], local) @ u, local[0]))
                angles = (a,)
            axes = []  # world axes of the joint's DOFs, and the link's rotation after them
            Rg = R
            for u, angle in zip(units, angles, strict=True):
                axes.append(Rg @ u)
                Rg = Rg @ _rot(u, angle)
            A = np.cross(np.array(axes), d).T  # columns: a_i x d, the chord's turning per rate
            rates = np.linalg.lstsq(A, d_rate - np.cross(w, d), rcond=None)[0]
            qc[lo:hi] = angles
            qdc[lo:hi] = rates
            w = w + np.array(axes).T @ rates
            R = Rg
        return qc, qdc


def chain_of(model: Model, where: str = "coarsen") -> Model:
    """``model`` when it is laid out as a chain of links (:attr:`Model.chain_layout`: every
    :class:`~redysim.model.tree.Chain`, and a model read from a file that has a chain's layout),
    else CaseError naming what is not a chain's (as ``where``'s argument ``chain``)."""
    if not isinstance(model, Model):
        raise CaseError(where, "chain", type(model).__name__, "must be a redysim.Model (a "
                        "Chain is one)")
    if model.chain_layout is not None:
        raise CaseError(f"{model.name}.{where}", "chain", model.name,
                        f"not a chain of links: {model.chain_layout}; coarse-graining lumps "
                        "consecutive links of a serial chain whose links lie along their x "
                        "axes (a Chain); hold joints of any tree with Model.locked instead")
    return model


def coarsen(chain: Model, k: int | None = None, *, links: int | None = None,
            name: str | None = None) -> Coarsening:
    """Lump every ``k`` consecutive links of ``chain`` into one (or give the coarse ``links``
    count, which must divide the chain's). A :class:`~redysim.model.tree.Model` is taken when it has
    a chain's layout (:func:`chain_of`): it is then the Coarsening's ``fine``, and ``coarse`` a
    :class:`~redysim.model.tree.Chain`. Returns the :class:`Coarsening` (its ``coarse`` chain and
    the state maps). Raises CaseError naming a count that does not divide, or a model that is not a
    chain."""
    chain = chain_of(chain)
    where = f"{chain.name}.coarsen"
    if chain.has_passive:  # (a lumped link has one gravcomp; a coarse joint, one damper)
        raise CaseError(where, "model", "damping/stiffness/gravcomp", "coarse-graining does not "
                        "carry joint damping, springs or gravity compensation yet: coarsen "
                        "chain.without_passive() and give the coarse chain its own "
                        "(with_passive)")
    nl = chain.n_links
    if (k is None) == (links is None):
        raise CaseError(where, "k/links", (k, links), "give exactly one of k and links")
    if links is not None:
        if isinstance(links, bool) or not isinstance(links, int | np.integer) or links < 1:
            raise CaseError(where, "links", links, "must be a whole number >= 1")
        if nl % links:
            raise CaseError(where, "links", links, f"must divide the chain's {nl} links (each "
                            "coarse link lumps the same number of fine links)")
        k = nl // links
    if isinstance(k, bool) or not isinstance(k, int | np.integer) or k < 1:
        raise CaseError(where, "k", k, "must be a whole number >= 1")
    if nl % k:
        raise CaseError(where, "k", k, f"must divide the chain's {nl} links")
    k = int(k)
    starts = np.arange(0, nl + 1, k)
    for s in starts[:-1]:
        joint = chain.joints[s]
        if joint.type not in MAPPABLE:
            raise CaseError(where, f"joints[{s}]", joint.type,
                            f"coarse joints must be one of {MAPPABLE} (the chord map solves "
                            "their angles); other joints can be locked (Model.locked)")
        if joint.type == "R":
            u = chain.dof_u[chain.joint_qoff[s]]
            if abs(u[0]) > 1e-12:
                raise CaseError(where, f"joints[{s}].axis", [float(x) for x in u],
                                "a coarse revolute joint needs an axis normal to the link (x): "
                                "it must be able to point the lumped link along a chord")
    links_out = [_lump(chain, int(s), int(e)) for s, e in zip(starts[:-1], starts[1:],
                                                              strict=True)]
    # each coarse joint keeps its group's first joint's armature; the inner joints' goes with
    # their motion (locked: no rotor of theirs turns), as Model.locked drops a locked joint's
    voff = chain.joint_voff
    armature = np.concatenate([chain.armature[voff[s]:voff[s + 1]] for s in starts[:-1]])
    coarse = Chain.build(links_out, [chain.joints[s] for s in starts[:-1]],
                         gravity=tuple(chain.gravity),
                         name=name or (f"{chain.name}/{k}" if k > 1 else chain.name),
                         source=where, armature=armature)
    return Coarsening(chain, coarse, starts)


def _lump(chain: Model, s: int, e: int) -> Link:
    """Links s..e-1 welded straight: one link with their summed mass, first moment and inertia
    about link s's joint."""
    offset = np.concatenate(([0.0], np.cumsum(chain.length[s:e])[:-1]))  # along x
    r = chain.com[s:e].copy()
    r[:, 0] += offset  # each COM in the group's frame
    m = chain.mass[s:e]
    mass = float(m.sum())
    first = (m[:, None] * r).sum(axis=0)
    com = first / mass
    eye = np.eye(3)
    about_O = (chain.inertia_com[s:e]
               + m[:, None, None] * (np.einsum("ki,ki->k", r, r)[:, None, None] * eye
                                     - np.einsum("ki,kj->kij", r, r))).sum(axis=0)
    inertia = about_O - mass * ((com @ com) * eye - np.outer(com, com))
    inertia = 0.5 * (inertia + inertia.T)
    # the rod model breaks the triangle inequality on purpose; so may its lumps
    physical = bool(np.all([_physical(chain, j) for j in range(s, e)]))
    return Link(float(chain.length[s:e].sum()), mass, tuple(com), tuple(map(tuple, inertia)),
                physical=physical)


def _physical(chain: Model, j: int) -> bool:
    """Whether link j's inertia satisfies the triangle inequality (a rigid body's)."""
    eig = np.linalg.eigvalsh(chain.inertia_com[j])
    return bool(eig[2] <= (eig[0] + eig[1]) * (1 + 1e-12))


__all__ = ["MAPPABLE", "Coarsening", "chain_of", "coarsen"]
