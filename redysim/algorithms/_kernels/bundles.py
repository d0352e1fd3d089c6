"""The kernels' data layout, declared once: the named bundles they pass and the packed arrays of
a workspace, all from one table.

numba types a NamedTuple of arrays field by field and unpacks it at no cost inside compiled code, so
a kernel's signature names what it reads (``tree.mass``, ``s.oR``) instead of two dozen positional
arrays, and adding a quantity changes one definition (docs/design.md, "Kinematic trees"). The
bundles are built once per chain or model (:mod:`redysim.algorithms.workspace`) and, on the hot
path, sliced out of a workspace's packed arrays inside compiled code (:mod:`.entry`).

:data:`LAYOUT` is the one table: each array's name, dtype, shape (in the sizes nb bodies, n_v
velocity coordinates, ng gathering bodies, nt = nb for a tree, 0 for a serial chain, and na = nv
for a model with armature, 0 without) and the
packed array that holds it (``tree_f``, ``tree_i``: the system's floats and ints; ``scratch``:
what the kernels write; ``tiles``: one thread's row of the SIMD tiles' buffer), and whether it
belongs to the :class:`Tree`, :class:`Scratch` or :class:`Tiles` bundle or is one of the
workspace's other segments. From it follow the bundles' fields (:data:`Tree`, :data:`Scratch`,
:data:`Tiles`), their numba types (:func:`numba_types`), the slot of each segment's offset in the
int array's header (:data:`SLOT`), the packing (:func:`segment_sizes`) and the compiled slicers
(:func:`bundles_source`, compiled in :mod:`.entry`; :func:`slicer_source`, the tiles' in
:mod:`.tiles`).

The tiles' arrays (:mod:`.tiles`: LANES states side by side, the states the last axis) are
``flat``: the kernels index them as one vector of their items, by unsigned indices (``tiles.at``),
so their slicer cuts 1-D views and their numba types are 1-D; their shapes count the items.

Kernels read the fields into locals at their top, once per call, and pass helpers scalars, never
arrays: an array handed to an inlined helper in a loop costs reference counting per call, ten
times a rope body's work. The kernels that take the bundles compile without numba's reference
counting altogether (``redysim._jit.jit_borrowed``). Reading the fields at the top matters for
another reason where a function makes the bundles itself (the lean entries, :mod:`.lean`) and
inlines the passes: numba's dead-code elimination (0.68) keeps a write into an array only if it
sees the array alive afterwards or drawn from an argument, and a field read inside an inlined
helper (or an array taken out of a tuple there) is neither: its writes were dropped. Written
through an array read before the pass's loop (alive in the next turn), they stay.

A serial chain is a tree (parent k - 1, each joint at the parent's ``along`` on its x axis, no
free joint): ``serial = 1`` tells the kernels so, and they then read none of the tree's tables
(``parent``, ``gather``, ``placement_code``, ``qshift``, ``placement_R``, ``placement_p``, which
a serial chain leaves empty: their shapes count nt): the rope streams no byte more than before
trees existed.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any, NamedTuple, TypeAlias

import numpy as np

ALONG_X, PLACED = 0, 1  # placement_code: a translation along the parent's x; any rotation and shift
GATHER_MASS = 21  # an articulated mass's numbers: X and Z upper triangles (6 + 6), Y (9)
# the SIMD tiles' sizes (.tiles): states per tile (a compile-time constant: the loops over states
# have a constant trip count), and the rows of the kinematics' and backward pass's carries
LANES = 16
KIN_ROWS = 33  # frame (9), origin, angular velocity, s, om, dv, da, db, a ball's bw (3 each)
BACK_ROWS = 27  # X (6), Y (9), Z (6), n (3), f (3)

# A DH robot's constants (redysim.algorithms.dh_form), one row per joint, the DH kernels'
# table (.dh): kind (0 R, 1 P); ca, sa = cos, sin alpha; c2, s2, cs = ca^2, sa^2, ca sa;
# cs2 = 2 ca sa; cms = ca^2 - sa^2; a, d, theta (q adds to theta, R, or to d, P); m; h = m c (3);
# J about O_k (xx, xy, xz, yy, yz, zz), all in the body's own frame; twist: 0 any alpha, 1, 2, 3, 4
# alpha = 0, 90, -90, 180 degrees (.dh turns y and z into each other then, without arithmetic);
# the joint's armature. Then, on the last row of a robot whose last joint is revolute (zeros
# elsewhere), that body's
# articulated inertia, which is its own and so a constant in its frame: 1 / J_zz; U / D
# (x, y angular; x, y linear); the projected inertia's A (xx, xy, yy), B (xx, xy, yx, yy) and M
# (xx, xy, yy) (its other numbers are the body's own, or zero); and A and B moved by Tz(d).
DH_COLUMNS = ("kind", "ca", "sa", "c2", "s2", "cs", "cs2", "cms", "a", "d", "theta",
              "m", "hx", "hy", "hz", "jxx", "jxy", "jxz", "jyy", "jyz", "jzz", "twist",
              "armature", "tip_inv", "tip_d0", "tip_d1", "tip_d3", "tip_d4",
              "tip_a00", "tip_a01", "tip_a11", "tip_b00", "tip_b01", "tip_b10", "tip_b11",
              "tip_m00", "tip_m01", "tip_m11",
              "tip_za00", "tip_za01", "tip_za11", "tip_zb00", "tip_zb01", "tip_zb10", "tip_zb11")
(DH_KIND, DH_CA, DH_SA, DH_C2, DH_S2, DH_CS, DH_CS2, DH_CMS, DH_A, DH_D, DH_TH, DH_M, DH_HX,
 DH_HY, DH_HZ, DH_JXX, DH_JXY, DH_JXZ, DH_JYY, DH_JYZ, DH_JZZ, DH_TW, DH_ARMATURE,
 DH_TIP_INV, DH_TIP_D0, DH_TIP_D1, DH_TIP_D3, DH_TIP_D4,
 DH_TIP_A00, DH_TIP_A01, DH_TIP_A11, DH_TIP_B00, DH_TIP_B01, DH_TIP_B10, DH_TIP_B11,
 DH_TIP_M00, DH_TIP_M01, DH_TIP_M11,
 DH_TIP_ZA00, DH_TIP_ZA01, DH_TIP_ZA11, DH_TIP_ZB00, DH_TIP_ZB01, DH_TIP_ZB10,
 DH_TIP_ZB11) = range(len(DH_COLUMNS))
DH_TIP = DH_TIP_INV  # the first of the last body's columns
DH_SCRATCH = 48  # the DH forward kernel's scratch columns per body (.dh)

# the int array's header: the sizes, the serial flag, then one offset per segment (SLOT)
HEADER_FIELDS = ("nb", "nv", "nq", "ng", "serial", "na")
H_NB, H_NV, H_NQ, H_NG, H_SERIAL, H_NA = range(len(HEADER_FIELDS))


class Field(NamedTuple):
    """One array of the layout: ``shape`` in the size names nb, nb1 (= nb + 1), nv, nt, ng and
    integers; ``array`` the packed array holding it; ``bundle`` "Tree", "Scratch", "Tiles" or
    None (a segment only the workspace and the entries read); ``planar``: present only for a
    planar chain (the planar kernel's); ``flat``: the kernels take it as a 1-D view of its items
    (the tiles'); ``dh``: present only for a robot in DH form (the DH kernels'); ``doc``: what it
    is."""

    name: str
    dtype: type
    shape: tuple
    array: str
    bundle: str | None
    doc: str
    planar: bool = False
    flat: bool = False
    dh: bool = False


F, I = np.float64, np.int64
LAYOUT: tuple[Field, ...] = (
    # the tree's ints (after the header)
    Field("parent", I, ("nt",), "tree_i", "Tree", "parent body, -1 for the base"),
    Field("gather", I, ("nt",), "tree_i", "Tree",
          "-1, or the row of the scratch's gather arrays where the children of body k that do "
          "not directly follow it (k + 1) leave their articulated masses and biases (backward "
          "passes) and where body k leaves its forward carry-over"),
    Field("placement_code", I, ("nt",), "tree_i", "Tree", "ALONG_X or PLACED"),
    Field("qshift", I, ("nt",), "tree_i", "Tree",
          "joint k's first configuration index minus its first velocity index (a free joint's "
          "quaternion has 4 numbers for 3 velocities)"),
    # the tree's floats
    Field("along", F, ("nb",), "tree_f", "Tree",
          "joint k's offset along the parent's x (the parent's length in a chain)"),
    Field("placement_R", F, ("nt", 3, 3), "tree_f", "Tree",
          "joint k's frame in the parent's (PLACED): rotation"),
    Field("placement_p", F, ("nt", 3), "tree_f", "Tree", "and translation"),
    Field("joint_voff", I, ("nb1",), "tree_i", "Tree", "first velocity coordinate of joint k"),
    Field("dof_kind", I, ("nv",), "tree_i", "Tree", "per axis: revolute, prismatic, ball"),
    Field("dof_axis", I, ("nv",), "tree_i", "Tree", "per axis: x, y, z or general (.joints)"),
    Field("dof_u", F, ("nv", 3), "tree_f", "Tree", "per axis: its unit vector"),
    Field("armature", F, ("na",), "tree_f", "Tree",
          "per axis: the joint's own inertia, added to its joint-space inertia (.joints."
          "joint_inertia); empty (na = 0) for a model without any, whose kernels then read "
          "none of it"),
    Field("mass", F, ("nb",), "tree_f", "Tree", "per body: its mass"),
    Field("inertia_O", F, ("nb", 3, 3), "tree_f", "Tree",
          "per body: inertia about its origin O_k, in its own frame"),
    Field("mass_com", F, ("nb", 3), "tree_f", "Tree", "per body: m c, in its own frame"),
    # the workspace's other float segments (the entries read them)
    Field("base_accel", F, (3,), "tree_f", None, "-g: the base's acceleration"),
    Field("gravity", F, (3,), "tree_f", None, "g"),
    Field("zeros", F, ("nv",), "tree_f", None, "zeros that no kernel writes"),
    Field("length", F, ("nb",), "tree_f", None, "a planar chain's link lengths", True),
    Field("izz_O", F, ("nb",), "tree_f", None, "its inertias about z at O_k", True),
    Field("mc_x", F, ("nb",), "tree_f", None, "its m c_x", True),
    Field("mc_y", F, ("nb",), "tree_f", None, "its m c_y", True),
    Field("dh", F, ("nb", len(DH_COLUMNS)), "tree_f", None,
          "a DH robot's constants, a row per joint (DH_COLUMNS)", dh=True),
    # the scratch (all world frame)
    Field("oR", F, ("nb", 3, 3), "scratch", "Scratch", "body rotations"),
    Field("oO", F, ("nb", 3), "scratch", "Scratch", "body origins (joint positions)"),
    Field("oP", F, ("nv", 6), "scratch", "Scratch", "motion subspace columns"),
    Field("t", F, ("nb", 6), "scratch", "Scratch", "twists"),
    Field("td", F, ("nb", 6), "scratch", "Scratch", "twist-rates"),
    Field("Ihat", F, ("nv",), "scratch", "Scratch", "RGE-A's pivots"),
    Field("Psihat", F, ("nv", 6), "scratch", "Scratch", "RGE-A's Psihat"),
    Field("phitil", F, ("nv",), "scratch", "Scratch", "RGE-A's phitil"),
    Field("phihat", F, ("nv",), "scratch", "Scratch", "RGE-A's phihat"),
    Field("W", F, ("nb", 6), "scratch", "Scratch", "resultant wrenches"),
    Field("gather_mass", F, ("ng", GATHER_MASS), "scratch", "Scratch",
          "the gathering bodies' articulated masses (Tree.gather)"),
    Field("gather_wrench", F, ("ng", 6), "scratch", "Scratch", "their biases"),
    Field("gather_twist", F, ("ng", 6), "scratch", "Scratch", "their forward carry-over"),
    Field("planar", F, ("nb", 12), "scratch", None, "the planar kernel's scratch", True),
    Field("dh_scratch", F, ("nb", DH_SCRATCH), "scratch", None, "the DH kernels' scratch",
          dh=True),
    # one thread's SIMD tiles (.tiles; flat, LANES states the last axis), in its row of the
    # workspace's tile buffer
    Field("tile_oR", F, ("nb", 9, LANES), "tiles", "Tiles", "body rotations", flat=True),
    Field("tile_oO", F, ("nb", 3, LANES), "tiles", "Tiles", "body origins", flat=True),
    Field("tile_oP", F, ("nv", 6, LANES), "tiles", "Tiles", "motion subspace columns", flat=True),
    Field("tile_W", F, ("nb", 3, LANES), "tiles", "Tiles", "angular velocities", flat=True),
    Field("tile_C", F, ("nb", 6, LANES), "tiles", "Tiles", "local twist-rates c_k", flat=True),
    Field("tile_run", F, (KIN_ROWS, LANES), "tiles", "Tiles",
          "the kinematics' values carried from body to body", flat=True),
    Field("tile_car", F, (BACK_ROWS, LANES), "tiles", "Tiles",
          "the articulated mass and bias carried from body to body", flat=True),
    Field("tile_Psihat", F, ("nv", 6, LANES), "tiles", "Tiles", "RGE-A's Psihat", flat=True),
    Field("tile_phitil", F, ("nv", LANES), "tiles", "Tiles", "RGE-A's phitil", flat=True),
    Field("tile_mu", F, (6, LANES), "tiles", "Tiles", "mu, carried from body to body",
          flat=True),
    Field("tile_gm", F, ("ng", GATHER_MASS + 6, LANES), "tiles", "Tiles",
          "a tree's gathering bodies' articulated masses and biases (Tree.gather)", flat=True),
    Field("tile_gt", F, ("ng", 6, LANES), "tiles", "Tiles",
          "and their forward carry-over mu", flat=True),
    Field("tile_bad", F, (LANES,), "tiles", "Tiles",
          "per state: 0 while its qdd are finite, else NaN", flat=True),
    Field("tile_Q", F, ("nq", LANES), "tiles", "Tiles", "the tile's q", flat=True),
    Field("tile_QD", F, ("nv", LANES), "tiles", "Tiles", "its qd", flat=True),
    Field("tile_TAU", F, ("nv", LANES), "tiles", "Tiles", "its tau", flat=True),
    Field("tile_QDD", F, ("nv", LANES), "tiles", "Tiles", "its qdd", flat=True),
)
FIELDS = {f.name: f for f in LAYOUT}
# the slot in the int array's header of each segment's offset (in its packed array)
SLOT = {f.name: len(HEADER_FIELDS) + i for i, f in enumerate(LAYOUT)}
HEADER = len(HEADER_FIELDS) + len(LAYOUT)


def _bundle(name: str, doc: str, first: tuple = ()) -> type:
    """The NamedTuple class of a bundle: ``first`` (name, type) fields, then its arrays."""
    fields = [*first, *((f.name, np.ndarray) for f in LAYOUT if f.bundle == name)]
    cls = NamedTuple(name, fields)  # type: ignore[misc]  # fields from LAYOUT, not literals
    cls.__doc__ = doc + "\n\n" + "\n".join(
        f"    {f.name} {_shape_text(f.shape)}: {f.doc}." for f in LAYOUT if f.bundle == name)
    cls.__module__ = __name__
    return cls


def _shape_text(shape: tuple) -> str:
    return "(" + ", ".join(str(x) for x in shape) + ("," if len(shape) == 1 else "") + ")"


if TYPE_CHECKING:
    # Made at run time from LAYOUT: a type checker cannot see their fields, so to mypy the
    # bundles (and annotations naming them) are Any.
    Tree: TypeAlias = Any
    Scratch: TypeAlias = Any
    Tiles: TypeAlias = Any
else:
    Tree = _bundle("Tree", "A tree's arrays (nb bodies, nv velocity coordinates; nt = nb, or 0 "
                   "for a serial chain), body k's parent before it.\n\n    serial: 1 for a "
                   "serial chain (the nt tables then empty), else 0.", first=(("serial", int),))
    Scratch = _bundle("Scratch", "What the kernels write (all world frame; nb bodies, nv DOF, "
                      "ng gathering bodies).")
    Tiles = _bundle("Tiles", "One thread's SIMD tile arrays (.tiles; world frame, nb bodies, nv "
                    "DOF, LANES states side by side, each array flat).")


def sizes_of(nb: int, nv: int, ng: int, serial: bool, nq: int | None = None,
             na: int = 0) -> dict[str, int]:
    """The size names of :data:`LAYOUT`'s shapes, for a system of these sizes (nq: its
    configuration coordinates, nv when not given; na: nv for a model with armature, else 0)."""
    return dict(nb=nb, nb1=nb + 1, nv=nv, nq=nv if nq is None else nq, ng=ng,
                nt=0 if serial else nb, na=na)


def shape_of(field: Field, sizes: dict[str, int]) -> tuple[int, ...]:
    """A field's shape for the given sizes (:func:`sizes_of`)."""
    return tuple(sizes[d] if isinstance(d, str) else d for d in field.shape)


def segment_sizes(array: str, sizes: dict[str, int], planar: bool,
                  dh: bool = False) -> dict[str, int]:
    """Field name -> number of items of each segment of one packed array, in layout order (the
    planar kernel's segments for a planar chain, the DH kernels' for a robot in DH form)."""
    return {f.name: math.prod(shape_of(f, sizes)) for f in LAYOUT
            if f.array == array and (planar or not f.planar) and (dh or not f.dh)}


# the argument of a generated slicer holding each packed array, and the size names' expressions
PACKED = {"tree_f": "fdata", "tree_i": "idata", "scratch": "scratch", "tiles": "buf"}
_SIZE = {"nb": "nb", "nb1": "nb + 1", "nv": "nv", "nq": "nq", "ng": "ng", "nt": "nt",
         "na": "na"}


def _view(f: Field, shaper: str | None = None) -> str:
    """The expression slicing field ``f`` out of its packed array (offset at its header slot);
    ``shaper``: the name of a function ``shaper(segment, shape)`` that gives a segment its shape
    instead of ``segment.reshape(shape)`` (:mod:`.lean`'s unchecked C-contiguous view)."""
    a, slot = PACKED[f.array], SLOT[f.name]
    factor = math.prod(d for d in f.shape if not isinstance(d, str))
    names = [_SIZE[d] for d in f.shape if isinstance(d, str)]
    count = " * ".join(([str(factor)] if factor > 1 or not names else []) + names)
    text = f"{a}[h[{slot}]:h[{slot}] + {count}]"
    if len(f.shape) > 1 and not f.flat:
        dims = ", ".join(_SIZE[d] if isinstance(d, str) else str(d) for d in f.shape)
        text = f"{shaper}({text}, ({dims}))" if shaper else text + f".reshape(({dims}))"
    return text


def slicer_source(name: str, bundles: tuple[str, ...], shaper: str | None = None) -> str:
    """The Python source of ``name(...)``: the named bundles (one, or a tuple of them) as views
    of a workspace's packed arrays, every segment sliced out inline (a helper taking the slot, a
    literal int, was compiled once per slot, lengthening the cold compile). Its arguments are the
    packed arrays the bundles' fields are in and the int array ``idata``, whose header holds the
    sizes and offsets, in :data:`PACKED`'s order (``bundles(fdata, idata, scratch)``,
    ``tiles_of(idata, buf)``); ``shaper`` as for :func:`_view`."""
    fields = [f for b in bundles for f in LAYOUT if f.bundle == b]
    args = [a for k, a in PACKED.items() if k == "tree_i" or any(f.array == k for f in fields)]
    lines = [f"def {name}({', '.join(args)}):",
             "    h = idata",
             f"    nb, nv, nq, ng = h[{H_NB}], h[{H_NV}], h[{H_NQ}], h[{H_NG}]",
             f"    nt = 0 if h[{H_SERIAL}] else nb  # a serial chain's tree tables are empty",
             f"    na = h[{H_NA}]  # 0: no armature"]
    for b in bundles:
        first = f"h[{H_SERIAL}]," if b == "Tree" else ""
        lines += [f"    {b.lower()}_ = {b}({first}"]
        lines += [f"        {_view(f, shaper)}," for f in LAYOUT if f.bundle == b]
        lines += ["    )"]
    lines += [f"    return {', '.join(b.lower() + '_' for b in bundles)}", ""]
    return "\n".join(lines)


def bundles_source(shaper: str | None = None) -> str:
    """The Python source of ``bundles(fdata, idata, scratch)``: the Tree and Scratch bundles as
    views of a workspace's packed arrays (:func:`slicer_source`). Compiled in :mod:`.entry` (and,
    with ``shaper``, in :mod:`.lean`); its Python form runs in the workspace itself: one layout,
    read in one place."""
    return slicer_source("bundles", ("Tree", "Scratch"), shaper)


def numba_types():
    """(TREE, SCRATCH, TILES): the bundles' numba types, C-contiguous arrays of each field's dtype
    and dimension (1 for a flat field; imported lazily: the Python form of the layout needs no
    numba)."""
    from numba import types

    def array(f: Field):
        return types.Array(types.float64 if f.dtype is F else types.int64,
                           1 if f.flat else len(f.shape), "C")

    def named(members: tuple, cls):
        # as numba types a NamedTuple instance: fields all of one type make a NamedUniTuple
        if len(set(members)) == 1:
            return types.NamedUniTuple(members[0], len(members), cls)
        return types.NamedTuple(members, cls)

    tree = named((types.int64, *(array(f) for f in LAYOUT if f.bundle == "Tree")), Tree)
    scratch = named(tuple(array(f) for f in LAYOUT if f.bundle == "Scratch"), Scratch)
    tiles = named(tuple(array(f) for f in LAYOUT if f.bundle == "Tiles"), Tiles)
    return tree, scratch, tiles
