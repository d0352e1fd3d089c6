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
