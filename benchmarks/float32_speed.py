"""What float32 buys in speed for the core's forward dynamics (RGE-A), against float64.

    .venv/bin/python benchmarks/float32_speed.py [--sizes 125 1000 50000] [--kinds U R]
        [--rounds 7] [--ieee-max 50000] [--no-strict] [--out results/bench/float32.json]

``--sizes`` are numbers of links: uniform chains ``Chain.uniform(nl, kind, length=1/nl,
linear_density=61.65, radius=0.05)``, U joints (2 DOF a link, the spatial RGE-A path) and R
joints (planar: ``chain.is_planar``, the separate planar kernel). State: seeded random,
``rng = np.random.default_rng(1)``, q ~ 0.1 N(0, 1), qd ~ N(0, 1), tau = 0.

What is timed: one qdd call as ``redysim.forward_dynamics`` makes it for RGE-A, i.e. the entry point
of ``redysim/algorithms/_kernels/entry.py`` (``rge_a_entry``: kinematics with local rates, RGE-A's
backward and forward passes; ``planar_entry`` for the R chains) on a workspace's packed arrays,
called directly (no forward_dynamics argument handling, the same Python overhead for every variant).
The library's entries are compiled for exactly one float64 signature, so every variant here is a
fresh numba compilation of the kernels' Python source (``py_func``), the whole call tree rebuilt in
a private copy of the module globals (``fresh``), with the library's options (``_nrt=False``,
``fastmath={"contract"}``, ...) but no disk cache:

    f64         the source as is, float64 arrays (the control: built the same way as f32)
    f32         the source as is, float32 copies of the float arrays (tree, scratch, q, qd, tau,
                qdd; the int arrays stay int64). numba types the Python float literals of the
                source (0.0, 1.0, 2.0, the fdlibm sin/cos constants) as float64, so a running
                scalar initialised from a literal, and every expression with one, is float64:
                this build loads and stores float32 but computes much of its arithmetic in
                float64 (mixed precision; measured below)
    f32-strict  (not with --no-strict) the same source with every float literal rewritten to
                np.float32(literal) (an AST rewrite inside this script, no library change) and
                the compiled sin/cos polynomial with float32 constants: float32 arithmetic
                throughout, what a float32 port of the kernels would run

Timing: best of ``--rounds`` rounds of N calls (N ~ 4e6 / DOF), the variants' rounds
interleaved; reported as ns per DOF. JIT compile time (first call minus a steady call) apart.

Is the float32 build float32? (1) qdd of each variant against the float64 build, beside
``redysim.algorithms.precision.ieee_qdd(chain, q, qd, dtype=np.float32, fused_phi=True)`` (the same
source run in numpy float32 scalars: every operation rounded to float32; ``fused_phi=True`` is the
core's formulation, the one timed here; ieee_qdd's default, ``fused_phi=False``, is Table A.1 as
printed on a float64 phi, another algorithm, reported apart as ``..._table_a1``) against float64,
for chains of at most ``--ieee-max`` links (numpy scalars: ~2 s at 50,000 U links). A build much
closer to float64 than the emulation is, is not float32 arithmetic; but every array the kernels
store (frames, Psihat, Ihat, phitil, ...) is rounded to float32 in the mixed build too, so the
errors may not tell the two apart. (2) The LLVM IR of each build's compiled functions:
floating-point operations on double vs float, and fpext/fptrunc conversions (the one or two fpext of
the strict build widen and box the returned flag, once a call).

Writes ``results/bench/float32.json``: machine, versions, per size and kind ns/DOF for each
variant and the ratios f64/f32, compile times, qdd differences, IR counts. Nothing in the
library is changed; numba's disk cache is pointed at a temporary directory (unless
NUMBA_CACHE_DIR is set) so that the run writes nothing into the source tree.
"""

from __future__ import annotations

import argparse
import ast
import atexit
import inspect
import json
import math
import os
import platform
import re
import shutil
import sys
import tempfile
import textwrap
import time
import types
from pathlib import Path

if "NUMBA_CACHE_DIR" not in os.environ:  # a private cache, removed at exit
    os.environ["NUMBA_CACHE_DIR"] = tempfile.mkdtemp(prefix="redysim_f32_numba_")
    atexit.register(shutil.rmtree, os.environ["NUMBA_CACHE_DIR"], ignore_errors=True)

import llvmlite.binding as llvm  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402
from numba.core.registry import CPUDispatcher  # noqa: E402
from numba.extending import overload  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import redysim  # noqa: E402
from redysim import Chain, Workspace  # noqa: E402
from redysim.algorithms._kernels import entry as E  # noqa: E402
from redysim.algorithms._kernels import joints as J  # noqa: E402
from redysim.algorithms.precision import ieee_qdd  # noqa: E402

VARIANTS = ("f64", "f32", "f32-strict")
DTYPE = {"f64": np.float64, "f32": np.float32, "f32-strict": np.float32}


# --------------------------------------------------------------------------- fresh builds
def _sincos32(x):
    """Stand-in for ``joints.sincos`` in the strict build (its compiled overload below)."""
    return math.cos(x), math.sin(x)


_F = np.float32
_S32 = tuple(_F(v) for v in (J.S1, J.S2, J.S3, J.S4, J.S5, J.S6))
_C32 = tuple(_F(v) for v in (J.C1, J.C2, J.C3, J.C4, J.C5, J.C6))
_PI_4_32, _HALF, _ONE = _F(J.PI_4), _F(0.5), _F(1.0)


@overload(_sincos32, inline="always")
def _sincos32_compiled(x):
    """``joints._sincos_compiled`` (fdlibm's polynomials inline for |x| <= pi/4, else libm)
    with float32 constants: float32 arithmetic for a float32 x."""
    S1, S2, S3, S4, S5, S6 = _S32
    C1, C2, C3, C4, C5, C6 = _C32
    PI_4, HALF, ONE = _PI_4_32, _HALF, _ONE

    def impl(x):
        if abs(x) <= PI_4:
            z = x * x
            r = S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))
            s = x + x * z * (S1 + z * r)
            rc = z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6)))))
            hz = HALF * z
            w = ONE - hz
            return w + (((ONE - w) - hz) + z * rc), s
        return math.cos(x), math.sin(x)
    return impl


class _Float32Literals(ast.NodeTransformer):
    """Every float literal ``c`` -> ``_F32_(c)`` (numba types np.float32(c) as float32)."""

    def visit_Constant(self, node):
        if type(node.value) is float:
            return ast.copy_location(
                ast.Call(ast.Name("_F32_", ast.Load()), [node], []), node)
        return node


def _strict_function(f, env):
    """``f``'s source with float32 literals, compiled into ``env`` (a copy of its globals)."""
    tree = ast.parse(textwrap.dedent(inspect.getsource(f)))
    fdef = tree.body[0]
    fdef.decorator_list = []
    tree = ast.fix_missing_locations(_Float32Literals().visit(tree))
    env["_F32_"] = np.float32
    if "sincos" in env:
        env["sincos"] = _sincos32
    ns: dict = {}
    exec(compile(tree, inspect.getsourcefile(f) or "<kernel>", "exec"), env, ns)
    return ns[f.__name__]  # (its globals: env)


def fresh(kernel, variant, memo):
    """A new dispatcher for ``kernel`` (a numba dispatcher or a plain function) with its
    callees rebuilt the same way, in a copy of its module's globals: no specialisation or disk
    cache shared with the library's own dispatchers or with another variant's build. Options
    are the kernel's own, less ``cache``. ``variant`` "f32-strict" rewrites float literals."""
    key = (kernel, variant)
    if key in memo:
        return memo[key]
    f = getattr(kernel, "py_func", kernel)
    env = dict(f.__globals__)
    if variant == "f32-strict":
        fn = _strict_function(f, env)
    else:
        fn = types.FunctionType(f.__code__, env, f.__name__, f.__defaults__, f.__closure__)
    opts = dict(kernel.targetoptions) if isinstance(kernel, CPUDispatcher) else \
        dict(E.RGE_A.options)
    opts.pop("nopython", None)
    opts.pop("boundscheck", None)
    opts.pop("cache", None)
    disp = numba.njit(**opts)(fn)
    memo[key] = disp
    for name in f.__code__.co_names:  # after memo: a callee may be reached twice
        g = env.get(name)
        if isinstance(g, CPUDispatcher):
            env[name] = fresh(g, variant, memo)
    return disp


def dispatchers(memo, variant):
    return {k[0].__name__ if hasattr(k[0], "__name__") else str(k[0]): d
            for k, d in memo.items() if k[1] == variant}


# --------------------------------------------------------------------------- chains and packs
def make_chain(kind, nl):
    return Chain.uniform(nl, kind, length=1.0 / nl, linear_density=61.65, radius=0.05)


def make_state(model):
    rng = np.random.default_rng(1)
    n = model.n_dof
    return 0.1 * rng.standard_normal(n), rng.standard_normal(n)


def packs(ws, q, qd, dtype):
    """The entry's 7 arguments, float arrays in ``dtype`` (the layout's offsets count items)."""
    n = q.shape[0]
    return (ws.kernel_f.astype(dtype), ws.kernel_i.copy(), q.astype(dtype), qd.astype(dtype),
            np.zeros(n, dtype), np.zeros(ws.scratch.shape[0], dtype), np.zeros(n, dtype))


# --------------------------------------------------------------------------- IR inspection
_FOP = re.compile(r"= (fadd|fsub|fmul|fdiv|fneg)\b[^\n]*?(<\d+ x (?:double|float)>|double|float)")
_CONV = re.compile(r"= (fpext|fptrunc)\b")


def ir_counts(disps):
    """Floating-point ops on double and on float, and fpext/fptrunc, in the optimised LLVM IR of
    every compiled specialisation of ``disps`` (the entry and the kernels it calls)."""
    out = {"double_ops": 0, "float_ops": 0, "double_vector_ops": 0, "float_vector_ops": 0,
           "fpext": 0, "fptrunc": 0}
    for d in disps:
        for ir in d.inspect_llvm().values():
            for _op, ty in _FOP.findall(ir):
                vec = ty.startswith("<")
                base = "double" if "double" in ty else "float"
                out[f"{base}_{'vector_' if vec else ''}ops"] += 1
            for c in _CONV.findall(ir):
                out[c] += 1
    return out


# --------------------------------------------------------------------------- measurement
def rel_diff(x, ref):
    """(normwise max|x - ref| / max|ref|, elementwise max |x - ref| / |ref|) as floats."""
    x = np.asarray(x, dtype=np.float64)
    d = np.abs(x - ref)
    with np.errstate(divide="ignore", invalid="ignore"):
        elem = np.max(d / np.abs(ref))
    return float(d.max() / np.abs(ref).max()), float(elem)


def calls_per_round(ndof, budget):
    return max(5, int(budget // ndof))


def run_size(kind, nl, entries, variants, a, results_compile):
    chain = make_chain(kind, nl)
    assert chain.is_planar == (kind == "R")
    n = chain.n_dof
    q, qd = make_state(chain)
    ws = Workspace(chain)
    args = {v: packs(ws, q, qd, DTYPE[v]) for v in variants}
    row = {"kind": kind, "links": nl, "dof": n, "planar": bool(chain.is_planar)}
    # the first call compiles (once per variant and kind): compile time = first - steady
    for v in variants:
        fn = entries[v]
        t0 = time.perf_counter()
        flag = fn(*args[v])
        first = time.perf_counter() - t0
        assert flag == 0.0, (v, flag)
        if (kind, v) not in results_compile:
            t0 = time.perf_counter()
            fn(*args[v])
            steady = time.perf_counter() - t0
            results_compile[(kind, v)] = first - steady
    # timing: best of rounds, variants interleaved (order rotated each round)
    N = calls_per_round(n, a.budget)
    best = {v: math.inf for v in variants}
    for r in range(a.rounds):
        order = variants[r % len(variants):] + variants[:r % len(variants)]
        for v in order:
            fn, ar = entries[v], args[v]
            t0 = time.perf_counter()
            for _ in range(N):
                fn(*ar)
            best[v] = min(best[v], (time.perf_counter() - t0) / N)
    row["calls_per_round"] = N
    row["rounds"] = a.rounds
    row["ns_per_dof"] = {v: best[v] / n * 1e9 for v in variants}
    row["us_per_call"] = {v: best[v] * 1e6 for v in variants}
    for v in variants:
        if v != "f64":
            row[f"speedup_f64_over_{v}"] = best["f64"] / best[v]
    # the library's own path (its float64 entry, through forward_dynamics' argument handling
    # too), for reference: same qdd as the fresh f64 build?
    out = np.empty(n)
    lib = redysim.forward_dynamics(chain, q, qd, ws=ws, out=out)
    N2 = calls_per_round(n, a.budget)
    tl = math.inf
    for _ in range(3):
        t0 = time.perf_counter()
        for _ in range(N2):
            redysim.forward_dynamics(chain, q, qd, ws=ws, out=out)
        tl = min(tl, (time.perf_counter() - t0) / N2)
    row["library_forward_dynamics_ns_per_dof"] = tl / n * 1e9
    qdd = {v: args[v][6].astype(np.float64) for v in variants}
    ref = qdd["f64"]
    row["f64_build_vs_library"] = rel_diff(ref, lib)[0]
    row["max_abs_qdd_f64"] = float(np.abs(ref).max())
    acc = {}
    for v in variants:
        if v != "f64":
            nw, el = rel_diff(qdd[v], ref)
            acc[v] = {"normwise": nw, "elementwise": el}
    if nl <= a.ieee_max:
        # the same source in numpy scalars, every operation rounded to the dtype. fused_phi=True
        # runs the core's formulation (gravity as the base's twist-rate, qd inside the passes),
        # the one the builds here run; ieee_qdd's default (fused_phi=False) runs Table A.1 as
        # printed on phi computed in float64 and rounded, a different algorithm whose error
        # grows ~n^2 eps (rge_a.py's notes): reported apart, not comparable with the builds
        for label, dt, fused in (("ieee_qdd_float32", np.float32, True),
                                 ("ieee_qdd_float32_table_a1", np.float32, False),
                                 ("ieee_qdd_float64", np.float64, True)):
            t0 = time.perf_counter()
            ie = ieee_qdd(chain, q, qd, dtype=dt, fused_phi=fused).astype(np.float64)
            t_ie = time.perf_counter() - t0
            nw, el = rel_diff(ie, ref)
            acc[label] = {"normwise": nw, "elementwise": el, "seconds": t_ie,
                          "fused_phi": fused}
            if label == "ieee_qdd_float32":
                ie32 = ie
        for v in variants:  # each float32 build against the per-operation float32 emulation
            if v != "f64":
                acc[v]["vs_ieee_qdd_float32_normwise"] = rel_diff(qdd[v], ie32)[0]
    row["qdd_rel_diff_vs_f64"] = acc
    return row


def machine():
    model = platform.processor()
    flags = ""
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name") and not model.startswith("Intel"):
                model = line.split(":", 1)[1].strip()
            if line.startswith("flags") and not flags:
                flags = line.split(":", 1)[1]
    except OSError:
        pass
    simd = [f for f in ("avx2", "fma", "avx512f", "avx512dq", "avx512vl", "avx512_fp16")
            if f in flags.split()]
    return {"cpu_model": model, "cpu_count": os.cpu_count(), "simd_flags": simd,
            "llvm_cpu": numba.config.CPU_NAME or llvm.get_host_cpu_name(),
            "python": platform.python_version(), "numba": numba.__version__,
            "numpy": np.__version__, "platform": platform.platform()}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", type=int, nargs="+", default=[125, 1000, 50_000],
                    help="numbers of links")
    ap.add_argument("--kinds", nargs="+", default=["U", "R"], choices=["U", "R"])
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--budget", type=float, default=4e6,
                    help="DOF x calls per round (N = budget / DOF, at least 5)")
    ap.add_argument("--ieee-max", type=int, default=50_000,
                    help="compare with precision.ieee_qdd up to this many links")
    ap.add_argument("--no-strict", action="store_true", help="skip the f32-strict build")
    ap.add_argument("--out", default=str(ROOT / "results" / "bench" / "float32.json"))
    a = ap.parse_args(argv)
    variants = tuple(v for v in VARIANTS if not (a.no_strict and v == "f32-strict"))

    info = machine()
    print(f"{info['cpu_model']} ({info['cpu_count']} CPUs, {info['llvm_cpu']}, "
          f"{' '.join(info['simd_flags'])}); numba {info['numba']}, numpy {info['numpy']}")
    rows, compile_s, ir = [], {}, {}
    for kind in a.kinds:
        src = E.rge_a_entry if kind == "U" else E.planar_entry
        memos = {v: {} for v in variants}
        entries = {v: fresh(src, v, memos[v]) for v in variants}
        for nl in a.sizes:
            row = run_size(kind, nl, entries, variants, a, compile_s)
            rows.append(row)
            ns = row["ns_per_dof"]
            acc = row["qdd_rel_diff_vs_f64"]
            print(f"{kind} {nl:>6} links {row['dof']:>7} DOF  ns/DOF "
                  + "  ".join(f"{v} {ns[v]:6.2f}" for v in variants)
                  + f"  lib {row['library_forward_dynamics_ns_per_dof']:6.2f}"
                  + "  f64/f32 " + " ".join(f"{row[f'speedup_f64_over_{v}']:.3f}"
                                            for v in variants if v != "f64")
                  + "  |dqdd|/|qdd| " + " ".join(
                      f"{k.replace('ieee_qdd_float', 'ieee')} {d['normwise']:.2e}"
                      for k, d in acc.items()), flush=True)
        for v in variants:
            ir[f"{kind} {v}"] = ir_counts(memos[v].values())
            print(f"  IR {kind} {v}: {ir[f'{kind} {v}']}")
    report = {
        "what": __doc__.split("\n\n")[0].strip(),
        "how": "best of rounds of N direct calls of a fresh numba build of the forward-dynamics "
               "entry (entry.rge_a_entry / planar_entry py_func and all callees), ns per DOF",
        "machine": info,
        "chains": "Chain.uniform(nl, kind, length=1/nl, linear_density=61.65, radius=0.05)",
        "state": "rng = np.random.default_rng(1); q = 0.1 N(0,1); qd = N(0,1); tau = 0",
        "variants": {
            "f64": "kernel source as is, float64 arrays",
            "f32": "kernel source as is, float32 arrays (float literals stay float64: mixed)",
            "f32-strict": "float literals rewritten to np.float32 in the benchmark's copy of the "
                          "source; sin/cos polynomial with float32 constants",
        },
        "compile_seconds": {f"{k} {v}": s for (k, v), s in compile_s.items()},
        "llvm_ir_fp_ops": ir,
        "sizes": rows,
    }
    out = Path(a.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    out.write_text(json.dumps(report, indent=2) + "\n")
    print("compile s: " + ", ".join(f"{k} {v:.2f}" for k, v in report["compile_seconds"].items()))
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
