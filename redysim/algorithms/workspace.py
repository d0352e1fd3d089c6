"""Preallocated per-model scratch arrays (Pinocchio's ``Data``): the kernels write into these.

A dynamics function called without ``ws=`` uses the model's own workspace for the calling thread
(:func:`model_workspace`): made on that thread's first call, then reused, so the default call is
as fast as one given a workspace (``benchmarks/default_path.py``).
"""

from __future__ import annotations

import functools
import threading
from functools import cached_property

import numpy as np

from redysim.algorithms._kernels import entry as E
from redysim.algorithms._kernels.bundles import (
    DH_SCRATCH,
    FIELDS,
    H_NA,
    H_NB,
    H_NG,
    H_NQ,
    H_NV,
    H_SERIAL,
    HEADER,
    SLOT,
    Scratch,
    Tree,
    segment_sizes,
    shape_of,
    sizes_of,
)
from redysim.algorithms._kernels.joints import BALL
from redysim.algorithms.dh_form import dh_constants
from redysim.model import door
from redysim.model.tree import THREAD_WORKSPACES, Model

ALIGN = 8  # every packed segment starts on a 64-byte boundary (8 doubles)


def _layout(sizes: dict[str, int], header: np.ndarray, start: int = 0) -> int:
    """Lay segments (field name -> number of items) back to back, each padded to ALIGN items:
    write each one's offset, counted from ``start``, into ``header`` at its slot; return the
    total."""
    end = start
    for name, size in sizes.items():
        header[SLOT[name]] = end
        end += -(-size // ALIGN) * ALIGN
    return end - start


def _pack(segments: dict[str, np.ndarray], dtype, header: np.ndarray, start: int = 0
          ) -> np.ndarray:
    """One array holding ``segments`` (field name -> array) as laid out by :func:`_layout`."""
    packed = np.zeros(_layout({k: a.size for k, a in segments.items()}, header, start), dtype)
    for name, a in segments.items():
        slot = SLOT[name]
        packed[header[slot] - start:header[slot] - start + a.size] = np.ravel(a)
    return packed


@functools.lru_cache(maxsize=256)
def _segments(nb: int, n: int, ng: int, serial: bool, n_q: int, na: int, planar: bool,
              dh: bool) -> tuple[dict[str, int], ...]:
    """The segments (field name -> items) of the packed tree floats, tree ints, scratch and
    tiles for a model of these sizes: the layout table walked once per set of sizes (its Python
    was a third of a small robot's Workspace: docs/notes/2026-12-08-fixed-cost.md). Sizes, not
    arrays: a few hundred bytes each. Read only (the callers iterate them)."""
    sizes = sizes_of(nb, n, ng, serial, n_q, na)
    return tuple(segment_sizes(kind, sizes, planar, dh)
                 for kind in ("tree_f", "tree_i", "scratch", "tiles"))


def tree_tables(model: Model) -> dict:
    """The :class:`~redysim.algorithms._kernels.bundles.Tree` fields of a model, as numpy arrays
    (plus ``n_q``). A serial chain (parent k - 1, every joint placed along its parent's x, no free
    or ball joint: every :class:`~redysim.model.tree.Chain`) is ``serial``, its tree tables
    empty."""
    m = model
    nb = m.n_bodies
    # (a free or ball joint's quaternion is read through the tree's qshift: not serial)
    serial = m.is_chain and not m.placement_code.any() and not (m.dof_kind == BALL).any()
    parent = np.asarray(m.parent)
    # a body gathers when a child does not follow it directly (its parent is not k - 1)
    needs = np.zeros(nb, dtype=bool)
    k = np.arange(1, nb)
    far = parent[1:] >= 0
    far &= parent[1:] != k - 1
    needs[parent[1:][far]] = True
    gather = np.where(needs, np.cumsum(needs) - 1, -1).astype(np.int64)
    nt = 0 if serial else nb
    return dict(serial=int(serial), parent=m.parent[:nt], gather=gather[:nt],
                placement_code=m.placement_code[:nt],
                qshift=(m.joint_qoff[:-1] - m.joint_voff[:-1])[:nt], along=m.placement_p[:, 0],
                placement_R=m.placement_R[:nt], placement_p=m.placement_p[:nt],
                joint_voff=m.joint_voff, dof_kind=m.dof_kind, dof_axis=m.dof_axis,
                dof_u=m.dof_u, armature=kernel_armature(m), mass=m.mass, inertia_O=m.inertia_O,
                mass_com=m.mass_com, n_q=m.n_q)


def kernel_armature(model: Model) -> np.ndarray:
    """The armature as the kernels take it: the model's (n_v,), or empty when it has none, so
    that the kernels of a model without armature read none (``joints.joint_inertia``)."""
    return model.armature if np.any(model.armature) else model.armature[:0]


def bundles_in(model: Model, convert, zeros, **arrays) -> tuple[Tree, Scratch]:
    """The two bundles with the tree's float arrays passed through ``convert`` (or given in
    ``arrays`` by field name) and the scratch made by ``zeros(shape)``: for running the kernels'
    Python source in another arithmetic (``redysim.algorithms.precision``,
    ``redysim.harness.hiprec``)."""
    t = tree_tables(model)
    tree = Tree(t["serial"], *(arrays[f] if f in arrays else convert(t[f])
                               if FIELDS[f].dtype is np.float64 else t[f]
                               for f in Tree._fields[1:]))
    sizes = sizes_of(t["mass"].shape[0], t["dof_kind"].shape[0],
                     int((t["gather"] >= 0).sum()), bool(t["serial"]), t["n_q"],
                     t["armature"].shape[0])
    return tree, Scratch(*(zeros(shape_of(FIELDS[f], sizes)) for f in Scratch._fields))


def model_workspace(model: Model) -> Workspace:
    """The calling thread's workspace of ``model``: the scratch that the dynamics functions use
    when called without ``ws=``.

    Made on the thread's first call and kept by the model (a ``threading.local`` in the model's
    ``__dict__``: one workspace per thread that calls, never shared between threads, each freed
    with its thread or the model). Calls on one thread reuse it one after another, so a result
    never aliases it (every function returns arrays of its own). Not part of the model's data:
    pickles, copies, equality and hashing leave it out (:meth:`Model.__getstate__`). Memory: one
    workspace (~380 bytes a DOF; batches add their threads' scratch and SIMD tiles) per model and
    thread that called without ``ws=``; give ``ws=`` to hold the scratch yourself.
    """
    try:
        return model._thread_workspaces.ws
    except AttributeError:  # not made yet on this thread (or for this model)
        pass
    ws = Workspace(model)  # (FieldError for something that is not a Model)
    local = model.__dict__.setdefault(THREAD_WORKSPACES, threading.local())  # (atomic)
    local.ws = ws
    return ws


class Workspace:
    """O(n) scratch for one chain or model. Not thread-safe: use one workspace per thread (the
    functions called without ``ws=`` do so by themselves: :func:`model_workspace`).

    ``tree`` and ``s``: the named bundles the kernels take
    (:mod:`redysim.algorithms._kernels.bundles`), the model's arrays (copies: the model is
    immutable) and the scratch, views of three packed arrays, ``kernel_f`` and ``kernel_i`` (the
    tree's floats and ints, with a header) and ``scratch``, which forward dynamics' entry points
    take (:mod:`redysim.algorithms._kernels.entry`: 7 arguments instead of 28). The scratch arrays
    are also attributes, all world frame (nb bodies, n DOF): ``oR`` (nb,3,3) body rotations, ``oO``
    (nb,3) joint positions, ``oP`` (n,6) motion subspaces, ``t`` and ``td`` (nb,6) twists and
    twist-rates, ``Ihat`` (n,) and ``Psihat`` (n,6) of RGE-A, ``phitil``/``phihat`` (n,), ``W``
    (nb,6) resultant wrenches, ``planar`` (nb,12) for the planar kernel. Besides: ``phi`` (n,), and
    ``zeros`` (n,), ``zeros6`` (nb,6) that no kernel writes. ``dh``: True for a robot in DH form
    (:mod:`redysim.algorithms.dh_form`), whose kernels take its constants ``dh_table`` and scratch
    ``dh_scratch`` (nb, DH_SCRATCH); None both otherwise.
    """

    def __init__(self, model: Model):
        door.require_model(model, "Workspace")
        t = tree_tables(model)
        nb, n = t["mass"].shape[0], t["dof_kind"].shape[0]
        ng = int((t["gather"] >= 0).sum())
        planar = model.is_planar
        dh_table = None if planar else dh_constants(model)
        dh = dh_table is not None
        self.model = model  # the model (a Chain is one) it was made for
        gravity = np.asarray(model.gravity, dtype=float)
        header = np.zeros(HEADER, dtype=np.int64)
        na = t["armature"].shape[0]
        header[[H_NB, H_NV, H_NQ, H_NG, H_SERIAL, H_NA]] = nb, n, t["n_q"], ng, t["serial"], na
        arrays = {**t, "base_accel": -gravity, "gravity": gravity, "zeros": np.zeros(n)}
        if planar:
            c = model
            arrays.update(length=c.length, izz_O=c.inertia_O[:, 2, 2], mc_x=c.mass_com[:, 0],
                          mc_y=c.mass_com[:, 1])
        if dh:
            arrays["dh"] = dh_table
        # the packed arrays, as the layout table lays them out (redysim.algorithms._kernels.bundles)
        tree_f, tree_i, scratch, tiles = _segments(nb, n, ng, bool(t["serial"]), int(t["n_q"]),
                                                   na, bool(planar), dh)
        self.kernel_f = _pack({f: arrays[f] for f in tree_f}, np.float64, header)
        ints_packed = _pack({f: arrays[f] for f in tree_i},
                            np.int64, header, start=HEADER)  # after the header
        scratch_items = _layout(scratch, header)
        # a thread's row of the SIMD tiles' buffer (tile_buffer), laid out as the others
        self._tile_items = _layout(tiles, header)
        self.kernel_i = np.concatenate((header, ints_packed))
        # a coupled model (not planar): the couplings' segments after the tree's, which RGE-A's
        # entries do not see (redysim.algorithms._kernels.couplings)
        self.coupled = bool(model.couplings) and not planar
        if self.coupled:
            from redysim.algorithms._kernels.couplings import COUPLING_TOL, coupling_tail

            ints, floats, items = coupling_tail(
                model, t["parent"], t["joint_voff"], bool(t["serial"]), COUPLING_TOL,
                self.kernel_f.shape[0], self.kernel_i.shape[0], scratch_items)
            self.kernel_f = np.concatenate((self.kernel_f, floats))
            self.kernel_i = np.concatenate((self.kernel_i, ints))
            scratch_items += items
        self.scratch = np.empty(scratch_items)
        bundles = getattr(E.bundles, "py_func", E.bundles)  # (a plain function without numba)
        self.tree, self.s = bundles(self.kernel_f, self.kernel_i, self.scratch)
        s = self.s
        self.oR, self.oO, self.oP, self.t, self.td = s.oR, s.oO, s.oP, s.t, s.td
        self.Ihat, self.Psihat, self.phitil, self.phihat, self.W = \
            s.Ihat, s.Psihat, s.phitil, s.phihat, s.W
        slot = SLOT["planar"]
        self.planar = (self.scratch[header[slot]:header[slot] + 12 * nb].reshape((nb, 12))
                       if planar else None)
        # a robot in DH form (redysim.algorithms.dh_form): forward and inverse dynamics run the
        # DH kernels (redysim.algorithms._kernels.dh) on these
        self.dh = dh
        self.dh_table = dh_table
        slot = SLOT["dh_scratch"]
        self.dh_scratch = (self.scratch[header[slot]:header[slot] + DH_SCRATCH * nb]
                           .reshape((nb, DH_SCRATCH)) if dh else None)
        self.phi = np.empty(n)
        # views of the packed data that the other functions take too: no kernel writes them
        f = self.kernel_f
        self.zeros = f[header[SLOT["zeros"]]:header[SLOT["zeros"]] + n]  # (n,) of zeros
        # the same, read-only: a pass that the forward-dynamics entry also calls, given it, runs
        # the entry's compiled code (read-only is another numba type: another compile)
        self.zeros_ro = self.zeros.view()
        self.zeros_ro.flags.writeable = False
        self.zeros6 = np.zeros((nb, 6))
        self.base_accel = f[header[SLOT["base_accel"]]:header[SLOT["base_accel"]] + 3]  # -g
        self.gravity = f[header[SLOT["gravity"]]:header[SLOT["gravity"]] + 3]
        self.no_accel = np.zeros(3)
        # what helper threads buy this workspace's batches, by kind of batch: measured as they
        # run (redysim.algorithms.threads.Speed), so that a batch takes helpers only while
        # they pay
        self.batch_speed: dict = {}
        self._extra_scratch: list[np.ndarray] = []  # more threads' scratch (scratches)
        self._tiles: np.ndarray | None = None  # the SIMD tiles' arrays (tile_buffer)
        self._tiles_raw: np.ndarray | None = None  # (their allocation, a little larger)
        # batches of this model can run in SIMD tiles (redysim.algorithms._kernels.tiles): a serial
        # chain of revolute and prismatic axes, or any tree (its own passes, tiles_tree)
        self.tiles_tree = not t["serial"]
        self.tiles_ok = self.tiles_tree or not (t["dof_kind"] == BALL).any()

    @cached_property
    def table_a1(self) -> Scratch:
        """The scratch with td a zero array that no kernel writes: RGE-A's backward pass run on it
        with zero twists reads c = 0 (Table A.1 as printed; the factors alone)."""
        return self.s._replace(t=self.zeros6, td=self.zeros6)

    def scratches(self, count: int) -> list[np.ndarray]:
        """``count`` scratch arrays of this workspace's layout, the first its own: one for each
        of your threads that run the kernels on this workspace's layout. Made on first use and
        kept. (A batch's helper threads keep scratch of their own:
        :mod:`redysim.algorithms.dynamics`.)"""
        extra = self._extra_scratch
        while len(extra) < count - 1:
            extra.append(np.empty_like(self.scratch))
        return [self.scratch, *extra[:count - 1]]

    def tile_buffer(self, count: int) -> np.ndarray:
        """(count, size): a row of the SIMD tiles' arrays for each of ``count`` threads (a
        batch's calling thread takes row 0), laid out as the Tiles rows of the layout table say
        (their offsets in ``kernel_i``'s header; :mod:`redysim.algorithms._kernels.tiles`). Made
        on first use and kept (grown when more threads are asked for)."""
        if self._tiles is None or self._tiles.shape[0] < count:
            # on a 64-byte boundary (each row then too: its segments are whole multiples of
            # ALIGN items): numpy's allocation is aligned to 16 bytes only, and a buffer 16, 32
            # or 48 bytes past a boundary made the tiles slower
            # (docs/notes/2026-11-batches-and-tiles.md)
            items = count * self._tile_items
            self._tiles_raw = np.zeros(items + ALIGN)
            start = (-self._tiles_raw.ctypes.data // 8) % ALIGN
            self._tiles = self._tiles_raw[start:start + items].reshape(count, self._tile_items)
        return self._tiles[:count]

    @property
    def nbytes(self) -> int:
        """Bytes held by the workspace's own arrays (O(n); views not counted twice, the
        model's arrays not counted)."""
        own = sum(v.nbytes for v in vars(self).values()
                  if isinstance(v, np.ndarray) and v.base is None)
        return own + sum(a.nbytes for a in self._extra_scratch)  # (the tile buffer's is in own)
