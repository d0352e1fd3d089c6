"""The one place numba is configured.

Every kernel in ``redysim.algorithms._kernels`` is decorated with :func:`jit` (a compiled function
cached on disk, so a second process loads machine code instead of recompiling) or :func:`inline` (a
small helper that numba inlines into its callers at the IR level); the entry points that the public
functions call on their hot path are :class:`EntryPoint` s.

``fastmath`` is limited to ``contract``: LLVM may fuse a multiply and an add into one FMA (one
rounding instead of two), so compiled results may differ from the kernels' Python source in the
last bits. Nothing else: no reassociation (results would depend on the compiler's choices) and
IEEE NaN and Inf (the kernels' non-finite checks rely on them). The articulated masses' symmetry
does not depend on it: only one triangle of each symmetric block is ever computed.
"""

from __future__ import annotations

import warnings
from functools import cached_property
from typing import TYPE_CHECKING, Any

import numba
from numba.core import cpu, options

if TYPE_CHECKING:  # numba's stub type of njit(**options): a kernel is a Dispatcher of its function
    from numba.core.decorators import _JITWrapper

# The numba versions whose internals redysim relies on were tested with (pyproject.toml pins
# numba to them; requirements/constraints.txt holds the exact pin): the noalias option mapped
# below, the dispatch bypass (unchecked_call), and the lean entries' unboxing and the
# evaluator's builtin (redysim.algorithms._kernels.lean, .binding), built from numba's code
# generation internals. On another numba these are off, by name, with a warning at import: the
# checked dispatch everywhere (the same answers, slower small calls), tiles without noalias.
KNOWN_NUMBA: tuple[tuple[int, int], ...] = ((0, 68),)


def _numba_version(text: str) -> tuple[int, int]:
    try:
        major, minor = text.split(".")[:2]
        return int(major), int(minor)
    except ValueError:  # (a version string of another shape: unknown)
        return (0, 0)


NUMBA_VERSION: tuple[int, int] = _numba_version(numba.__version__)
INTERNALS_OK: bool = NUMBA_VERSION in KNOWN_NUMBA
if not INTERNALS_OK:
    warnings.warn(f"redysim: numba {numba.__version__} is not a version whose internals redysim "
                  f"was tested with ({', '.join(f'{a}.{b}' for a, b in KNOWN_NUMBA)}): its "
                  "dispatch bypass, lean entries and evaluator builtin are off (the checked "
                  "calls run instead: the same answers, slower small calls); install "
                  "numba 0.68 (requirements/constraints.txt) for them", RuntimeWarning,
                  stacklevel=2)

# False under NUMBA_DISABLE_JIT: the kernels are then their Python source, and what exists in
# compiled code only (the lean entries' intrinsics, a dispatcher's compiled wrapper) is not there
JIT_ENABLED: bool = not getattr(numba.config, "DISABLE_JIT", 0)  # (numba.config: no stubs)
OPTIONS: dict[str, Any] = dict(cache=True, nogil=True, fastmath={"contract"}, error_model="numpy")
jit: _JITWrapper = numba.njit(**OPTIONS)
# IEEE arithmetic as written: no FMA fusion either, so that every result is the same on every
# x86-64 CPU (with or without FMA units, whatever its SIMD width). For what must be reproducible
# bit for bit: the integrators' stage sums, whose last bits steer the step-size control.
# fastmath is set (to False), not left unset: numba compiles a callee whose fastmath is unset
# with its caller's (numba.core.cpu's CPUTargetOptions: inherit_if_not_set("fastmath")), so that
# such a kernel compiled first inside a caller with contraction would fuse its multiply-adds,
# one compiled first on its own would not, and which one a later caller linked to would depend
# on the order of first calls (found on the DH kernels, whose qdd came out 1e-15 apart between
# a batch and forward_dynamics before their fastmath was set).
STRICT_OPTIONS: dict[str, Any] = dict(cache=True, nogil=True, error_model="numpy", fastmath=False)
jit_strict: _JITWrapper = numba.njit(**STRICT_OPTIONS)


# Kernels that allocate nothing and take the named bundles (redysim.algorithms._kernels.bundles)
# compile without numba's reference counting (NRT): every array they see is borrowed from their
# caller, which keeps it alive for the call. With it, reading a bundle's fields costs an atomic
# increment and a decrement per array per call, more than a 30-body tree's whole kinematics for
# the arrays of two bundles (docs/notes/2026-11-kernels-speed.md).
BORROWED_OPTIONS: dict[str, Any] = dict(OPTIONS, _nrt=False)
jit_borrowed: _JITWrapper = numba.njit(**BORROWED_OPTIONS)
# Borrowed and strict: for kernels whose every caller must get the same bits whether it calls
# their compiled code or LLVM inlines a copy (redysim.algorithms._kernels.dh: the public
# functions, the evaluator, batches and the compiled stepping all call them)
EXACT_BORROWED_OPTIONS: dict[str, Any] = dict(STRICT_OPTIONS, _nrt=False)
jit_exact: _JITWrapper = numba.njit(**EXACT_BORROWED_OPTIONS)

# The SIMD tile kernels (redysim.algorithms._kernels.tiles) also declare their array arguments free
# of overlap (LLVM's noalias), without which LLVM guards each vectorised loop with run-time overlap
# checks of its arrays, behind which the backward pass ran far slower
# (docs/notes/2026-11-batches-and-tiles.md). numba sets this flag itself only for the loops it
# parallelises; its njit takes it once CPUTargetOptions maps the option name (numba 0.68:
# numba.core.compiler.Flags.noalias; tests/test_tiles.py fails if it goes). Every array a tile
# kernel is given is a distinct view of its thread's tile buffer (the Tiles bundle, its segments
# laid out by the layout table) or a chain table it only reads; a bundle's arrays reach the compiled
# function as pointer arguments of their own, so the flag covers them too.
NOALIAS: bool = INTERNALS_OK and hasattr(options.TargetOptions, "Mapping")
if NOALIAS:
    cpu.CPUTargetOptions.noalias = options.TargetOptions.Mapping("noalias")
TILE_OPTIONS: dict[str, Any] = dict(BORROWED_OPTIONS, noalias=True) if NOALIAS else dict(
    BORROWED_OPTIONS)
jit_tiles: _JITWrapper = numba.njit(**TILE_OPTIONS)


def inline(func):
    """A helper small enough to inline into every caller (numba ``inline='always'``)."""
    return numba.njit(inline="always", cache=True, nogil=True, error_model="numpy")(func)


def inline_generated(source: str, name: str, namespace: dict):
    """:func:`inline` for a helper whose source is generated (``source`` defines ``name``, with
    ``namespace`` as its globals): the layout's slicer (``redysim.algorithms._kernels.bundles``).
    numba caches nothing of its own for it (it has no file to key a cache on); it is inlined, at the
    IR level, into callers that are cached."""
    scope = {"__name__": f"{__name__}.generated", **namespace}
    exec(compile(source, f"<generated {name}>", "exec"), scope)  # noqa: S102
    return numba.njit(inline="always", nogil=True, error_model="numpy")(scope[name])


class EntryPoint:
    """A kernel compiled for exactly one signature, on first use of :attr:`compiled` (so importing
    redysim compiles nothing, and the first call pays the compile or the disk-cache load, as for
    :func:`jit`).

    Given a signature, numba compiles nothing else: a call with other argument types raises
    TypeError instead of compiling a new specialisation (a float32 or strided array, say), which
    makes the dispatcher itself the type check of the hot path.

    ``callees``: the :func:`jit` kernels the entry calls, each with the exact argument types it
    calls them with; they are compiled (or loaded from disk) first, on their own. Why: numba
    links a copy of every callee into the caller's machine code, optimised a second time with
    it, and that copy ran RGE-A slower than the callee compiled on its own
    (``benchmarks/entry_copies.py``; docs/notes/2026-11-kernels-speed.md). A caller compiled
    afresh calls the callees' own code, which numba compiled first and the JIT linker prefers to
    the copies; one loaded from numba's disk cache calls its copies unless the callees' own code
    is loaded before it. Declared types that differed from the entry's would load callee code the
    entry never calls, and the slowdown would be back: ``tests/test_identities.py`` checks that
    they do not.
    """

    def __init__(self, func, signature, callees=(), options=BORROWED_OPTIONS):
        self.func = func
        self.signature = signature
        self.callees = callees
        self.options = options

    @cached_property
    def compiled(self):
        """The compiled dispatcher (compiled, or loaded from the disk cache, on first access),
        after its callees."""
        if not numba.config.DISABLE_JIT:  # with NUMBA_DISABLE_JIT the kernels are Python
            for kernel, signature in self.callees:
                kernel.compile(signature)
        return numba.njit(self.signature, **self.options)(self.func)

    @cached_property
    def call(self):
        """:attr:`compiled`'s compiled wrapper, past numba's dispatch (:func:`unchecked_call`);
        None with ``NUMBA_DISABLE_JIT``."""
        return unchecked_call(self.compiled)


# The lean entries (redysim.algorithms._kernels.lean, behind redysim.evaluator) keep the GIL:
# releasing and taking it back costs a measurable part of a small system's call
# (docs/notes/2026-11-evaluator-and-ladder.md), and held, it serialises the calls of several
# threads on one evaluator's scratch.
LEAN_OPTIONS: dict[str, Any] = dict(BORROWED_OPTIONS, nogil=False)


def unchecked_call(dispatcher):
    """The compiled wrapper of ``dispatcher``'s one signature, called without numba's dispatch: no
    typing of the arguments (a cost per array that matters for small systems:
    docs/notes/2026-11-evaluator-and-ladder.md), and no check that they match the signature beyond
    each array being an ndarray of the signature's item size: the caller must pass arrays of the
    declared dtype and dimension (a 2-D array where a 1-D one is declared is unboxed past the end
    of its slot), unless the signature declares types whose unboxing checks them (the lean entries'
    vectors: ``redysim.algorithms._kernels.lean.CheckedVector``). None with ``NUMBA_DISABLE_JIT``
    (the kernel is then a plain function) or for a dispatcher without exactly one compiled
    signature, and on a numba whose internals are not known (:data:`INTERNALS_OK`)."""
    if not INTERNALS_OK:
        return None
    overloads = getattr(dispatcher, "overloads", None)
    if not overloads or len(overloads) != 1:
        return None
    return next(iter(overloads.values())).entry_point


class Pinned:
    """Calls of one :func:`jit` kernel past numba's dispatch, where the caller's arguments are of
    types fixed by construction (a solver's own bundles, a system's workspace, slices of a run's
    own float64 state): numba's dispatch types every argument at every call (~15 us for the
    bundles of a tree on a loaded VM, against ~1 us through the compiled wrapper:
    docs/notes/2026-12-08-fixed-cost.md).

    ``call(key, *args)``: ``key`` is a tuple of the objects whose identity fixes the argument
    types (the bundles); while it holds the same objects, ``args`` go to the compiled wrapper of
    the overload picked for the first call's argument types. A key with another object (a state
    reassigned from outside, say) picks again, from numba's typing of the new arguments, and an
    argument type without a compiled overload goes through numba's dispatch (which compiles it or
    converts), so a changed type re-dispatches instead of being unboxed as the old one. The
    caller keeps the arguments outside the key of the same types at every call (a Python float,
    an int, a C-contiguous float64 vector). Without the known numba internals
    (:data:`INTERNALS_OK`) or under ``NUMBA_DISABLE_JIT``: the dispatcher, every call. The same
    compiled code either way: the same bits."""

    __slots__ = ("dispatcher", "key", "entry", "omitted")

    def __init__(self, dispatcher) -> None:
        self.dispatcher = dispatcher
        self.key: tuple | None = None
        self.entry = None
        self.omitted: tuple = ()

    def call(self, key: tuple, *args):
        k = self.key
        if k is None or len(k) != len(key) or any(a is not b for a, b in zip(k, key,
                                                                            strict=True)):
            self._pin(key, args)
            if self.entry is None:  # nothing compiled for these types yet: numba's dispatch
                out = self.dispatcher(*args)  # compiles (or converts) and runs it
                self._pin(key, args)
                self.key = tuple(key)  # pinned or not, not tried again for this key
                return out
        if self.entry is None:
            return self.dispatcher(*args)
        return self.entry(*args, *self.omitted)

    def _pin(self, key: tuple, args: tuple) -> None:
        """The compiled wrapper of the overload for exactly ``args``' types (None: none yet).
        numba's typing of a bundle in Python is slow (~1 ms for a tree's two, more than a small
        robot's run): the overload found for a set of types is kept for the process, by the
        arguments' fingerprints (numba's own C-level key of a value's type, the one its
        dispatch maps to its types), so that a new run of the same types pins in microseconds."""
        self.key, self.entry, self.omitted = None, None, ()
        d = self.dispatcher
        if not (INTERNALS_OK and JIT_ENABLED) or not getattr(d, "overloads", None):
            return  # (nothing compiled yet: the dispatcher's call compiles; the next one pins)
        from numba._dispatcher import compute_fingerprint

        try:
            prints: tuple | None = (d, *(compute_fingerprint(a) for a in args))
        except Exception:  # noqa: BLE001 -- (a value without a fingerprint: typed below)
            prints = None
        found = None if prints is None else _PINNED.get(prints)
        if found is None:
            found = self._overload(args)
            if found is None:
                return
            if prints is not None:
                _PINNED[prints] = found
        self.key, (self.entry, self.omitted) = tuple(key), found

    def _overload(self, args: tuple) -> tuple | None:
        """(the compiled wrapper, the omitted defaults' values) of the overload for exactly
        ``args``' types by numba's typing, or None when there is none."""
        from numba.core import types

        d = self.dispatcher
        try:
            _, folded = d.fold_argument_types(tuple(d.typeof_pyval(a) for a in args), {})
        except Exception:  # noqa: BLE001 -- (an argument numba cannot type: its dispatch says)
            return None
        compiled = d.overloads.get(tuple(folded))
        rest = tuple(folded[len(args):])
        if compiled is None or not all(isinstance(t, types.Omitted) for t in rest):
            return None
        return compiled.entry_point, tuple(t.value for t in rest)


# (dispatcher, the fingerprints of its arguments) -> (compiled wrapper, omitted defaults): the
# overloads Pinned found, kept for the process (a handful: one per kernel and set of types)
_PINNED: dict[tuple, tuple] = {}
