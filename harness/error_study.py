"""The true-error study: forward-dynamics methods against a 50-digit reference, 10..100,000 links.

    python -m redysim.harness.error_study [--sizes 10 100 1000] [--out results/error_study]
    python -m redysim.harness.error_study --table     # print the table of what is done

For every chain x size x configuration it computes the exact qdd of the double-precision input
(:func:`redysim.harness.hiprec.qdd_reference`, mpmath at ``--dps`` digits, O(n)) and, beside it,
every method's qdd and its true relative error ||qdd - ref|| / ||ref|| (2-norm and max-norm), with
the conditioning of the GIM.

Chains (docs/design.md, "Chain conventions"):
    U: the RE-U steel rod, l = 0.02 m, rho_l = 7850 pi 0.05^2 kg/m, r = 0.05 m, rod inertia.
    R: the section-5 study chain, l = 1 m, rho = 7025 kg/m^3, r = 0.02 m, cylinder inertia.
Configurations:
    stretched: q = 0 and the case's v (U: joint 1's y rate 1 rad/s, as in every RE-U case;
               R: v = 0, as in STUDY-R*): the straight chain, where cond2(GIM) is largest.
    random:    seeded, q ~ U(-0.3, 0.3), v ~ U(-0.3, 0.3) rad/s.
Methods (``--methods``), float64 and, where marked, float32 (``--precisions``):
    rge-a              core RGE-A, spatial kernel (``forward_dynamics(planar=False)``) [f32]
    rge-a-planar       core RGE-A, planar kernel (R chains only) [f32]
    rge-a-phi          Table A.1 as printed: phi (Eq. 12) by Newton-Euler with the base at -g,
                       then the recursion on phi (the paper's formulation, and the core's before
                       it took gravity and the velocity terms into the passes): the core's
                       compiled spatial kernels run on phi with no motion and no gravity
    ge-n, rge-n        core GIM + (reverse) Gaussian elimination, O(n^3) [f32]
    cholesky           core ``mass_matrix`` + ``phi``, scipy.linalg cho_factor/cho_solve [f32]
    literal-6x6        the non-symmetric literal Table A.1 (``redysim.harness.nonsymmetric``) [f32]
    literal-6x6-resym  the same with Mhat_k re-symmetrised at every step (the control) [f32]
    pinocchio-aba, pinocchio-aba-ryrz, pinocchio-crba, mujoco, dart, exudyn: the reference
                       engines up to their ``limits()``, each in a child process (address space
                       capped at the 12 GiB budget of references/limits.toml).
float32: the rge-a kernels and literal-6x6 run every operation in float32 (the kernels' Python
source on float32 scalars, ``redysim.harness.hiprec.FLOAT32``); ge-n, rge-n and cholesky solve the
float64 GIM and phi rounded to float32 (the solve in float32, not the assembly). Errors are
always against the reference of the double-precision input.

Conditioning, per chain x size x configuration:
    cond2          numpy.linalg.cond of the float64 GIM (SVD), up to ``--max-svd-dof``;
    cond2_lanczos  lambda_max(I) / lambda_min(I) by Lanczos (:func:`lanczos_max`) on O(n)
                   operators: I v by inverse dynamics and I^-1 v by RGE-A, both with v = 0 and
                   gravity off (an estimate, a slight underestimate: it matches the SVD to
                   ~1e-4..1e-3 where both exist);
    cond_featherstone = 4 nl^4 (Featherstone's estimate for a uniform chain).

Output (``--out``, default results/error_study):
    error_study.parquet   one row per cell (chain, n_links, config, method, precision), written
                          atomically (temp file + os.replace) after every cell; a rerun skips the
                          cells already finished (status ok / nonfinite / refused) and retries
                          the others; a core method's cell is redone when the kernels' sources
                          changed since (its ``core_digest``);
    refs/<chain><n>-<config>-dps<d>.npz   the reference as a double-double ``qdd_dd`` (n, 2)
                          [hi, lo] (~32 digits) with its ``q`` and ``v``, and .json beside it
                          (timing, the reference's self-check against ``--check-dps`` digits, the
                          condition numbers): the slow part, computed once.
All files are written atomically through :mod:`redysim.harness.store`.

Cost: the mpmath reference is O(n), minutes at 100,000 links; at 1,000 links the engines' builds
dominate (docs/notes/2026-11-costs-in-the-code.md).
"""

from __future__ import annotations

import argparse
import dataclasses
import datetime as _dt
import math
import multiprocessing as mp
import platform
import sys
import time
import traceback
from pathlib import Path

import numpy as np

from redysim import references
from redysim.algorithms.dynamics import METHODS as CORE

EPS = {"float64": float(np.finfo(np.float64).eps), "float32": float(np.finfo(np.float32).eps)}

CHAINS = {
    "U": dict(joint="U", length=0.02, linear_density=7850 * math.pi * 0.05**2, radius=0.05,
              inertia="rod", what="RE-U steel rod, l = 0.02 m, r = 0.05 m, rod inertia"),
    "R": dict(joint="R", length=1.0, linear_density=7025 * math.pi * 0.02**2, radius=0.02,
              inertia="cylinder", what="study chain, l = 1 m, r = 0.02 m, cylinder inertia"),
}
CONFIGS = ("stretched", "random")
# the core's methods (redysim.algorithms.dynamics.METHODS) and this study's variants of them
CORE_METHODS = (*CORE, "rge-a-planar", "rge-a-phi", "cholesky", "literal-6x6",
                "literal-6x6-resym")
ENGINE_METHODS = tuple(references.ENGINES)
METHODS = CORE_METHODS + ENGINE_METHODS
FLOAT32_METHODS = ("rge-a", "rge-a-planar", "ge-n", "rge-n", "cholesky", "literal-6x6",
                   "literal-6x6-resym")
DEFAULT_SIZES = (10, 30, 100, 300, 1000, 3000, 10000, 30000, 100000)
FINAL = ("ok", "nonfinite", "failed", "refused")  # statuses a rerun does not redo
KEY = ("chain", "n_links", "config", "method", "precision")
SEED = 20261122
ENGINE_MEM_GIB = 12.0  # references/limits.toml [budget] memory_gib


def log(msg: str) -> None:
    print(f"[{time.strftime('%H:%M:%S')}] {msg}", flush=True)


# --------------------------------------------------------------------------- chains and states
def make_chain(kind: str, n_links: int):
    from redysim import Chain
    p = CHAINS[kind]
    return Chain.uniform(n_links, p["joint"], length=p["length"],
                         linear_density=p["linear_density"], radius=p["radius"],
                         inertia=p["inertia"], name=f"{kind}{n_links}")


def make_state(model, kind: str, n_links: int, config: str):
    """(q, v) of a configuration (module docstring); seeded by chain kind and size."""
    n = model.n_dof
    if config == "stretched":
        q = np.zeros(n)
        v = np.zeros(n)
        if kind == "U":
            v[0] = 1.0  # w_Y0 = 1 rad/s, as in every RE-U case
        return q, v
    if config == "random":
        rng = np.random.default_rng([SEED, n_links, ord(kind)])
        return rng.uniform(-0.3, 0.3, n), rng.uniform(-0.3, 0.3, n)
    raise ValueError(f"config {config!r}: one of {CONFIGS}")


def zero_gravity(model):
    g = np.zeros(3)
    g.flags.writeable = False
    return dataclasses.replace(model, gravity=g)


# --------------------------------------------------------------------------- conditioning
def cond_svd(model, q) -> float:
    from redysim import mass_matrix
    return float(np.linalg.cond(mass_matrix(model, q)))


def lanczos_max(matvec, n: int, *, steps: int = 120, seed: int = 1,
                rtol: float = 1e-10) -> tuple[float, int, float]:
    """The largest eigenvalue of a symmetric operator by Lanczos with full reorthogonalisation.

    Returns (largest Ritz value, steps taken, its relative change over the last 5 steps). The
    Ritz value is a lower bound that converges fast even inside a cluster of eigenvalues (where
    ARPACK's residual test stalls: the stretched U chain's smallest eigenvalues of I agree to
    ~5 digits). Stops when the change is below ``rtol`` or after ``steps`` steps.
    """
    rng = np.random.default_rng(seed)
    steps = min(steps, n)  # the Krylov space is all of R^n after n steps
    Q = np.empty((steps + 1, n))
    v = rng.normal(size=n)
    Q[0] = v / np.linalg.norm(v)
    alpha: list[float] = []
    beta: list[float] = []
    tops: list[float] = []
    change = float("nan")
    for j in range(steps):
        w = matvec(Q[j]).astype(float)
        alpha.append(float(Q[j] @ w))
        for _ in range(2):  # full reorthogonalisation, twice
            w -= Q[:j + 1].T @ (Q[:j + 1] @ w)
        b = float(np.linalg.norm(w))
        T = np.diag(alpha) + np.diag(beta, 1) + np.diag(beta, -1)
        tops.append(float(np.linalg.eigvalsh(T)[-1]))
        if len(tops) > 5:
            change = abs(tops[-1] - tops[-6]) / abs(tops[-1])
            if change <= rtol:
                break
        if b <= 1e-13 * max(abs(x) for x in alpha):  # invariant subspace: exact
            change = 0.0
            break
        beta.append(b)
        Q[j + 1] = w / b
    return tops[-1], len(tops), change


def cond_lanczos(model, q) -> dict:
    """lambda_max(I) and lambda_min(I) = 1 / lambda_max(I^-1) by Lanczos on O(n) operators (I v:
    inverse dynamics; I^-1 v: RGE-A; both with v = 0 and gravity off). Both Ritz values are
    lower bounds, so cond2_lanczos slightly underestimates cond2 (by < 1e-3 where the SVD is
    reliable); the relative changes over the last 5 steps are returned as lanczos_change_*."""
    from redysim import Workspace, forward_dynamics, inverse_dynamics, mass_matrix
    c0 = zero_gravity(model)
    n = c0.n_dof
    if n <= 2:
        ev = np.linalg.eigvalsh(mass_matrix(model, q))
        return dict(lambda_max=float(ev[-1]), lambda_min=float(ev[0]),
                    cond2_lanczos=float(ev[-1] / ev[0]), cond_method="eigvalsh")
    ws = Workspace(c0)
    zero = np.zeros(n)
    lmax, s1, d1 = lanczos_max(lambda v: inverse_dynamics(c0, q, zero, v, ws=ws), n)
    imax, s2, d2 = lanczos_max(
        lambda v: forward_dynamics(c0, q, zero, v, planar=False, ws=ws), n)
    return dict(lambda_max=lmax, lambda_min=1.0 / imax, cond2_lanczos=lmax * imax,
                lanczos_steps=[s1, s2], lanczos_change_max=d1, lanczos_change_min=d2,
                cond_method=COND_METHOD)


COND_METHOD = "lanczos-v3"  # bump to recompute the cached estimates


# --------------------------------------------------------------------------- references
class RefStore:
    """The mpmath references and per-state conditioning, cached under ``out/refs``."""

    def __init__(self, out: Path, dps: int, check_dps: int, check_max_links: int,
                 max_svd_dof: int):
        self.dir = out / "refs"
        self.dir.mkdir(parents=True, exist_ok=True)
        self.dps, self.check_dps, self.check_max_links = dps, check_dps, check_max_links
        self.max_svd_dof = max_svd_dof

    def _paths(self, kind, n_links, config):
        stem = self.dir / f"{kind}{n_links}-{config}-dps{self.dps}"
        return stem.with_suffix(".npz"), stem.with_suffix(".json")

    def get(self, kind, n_links, config, model, q, v) -> tuple[np.ndarray, dict]:
        from . import hiprec
        from .store import read_json, write_json_atomic, write_npz_atomic
        npz, meta_path = self._paths(kind, n_links, config)
        meta = read_json(meta_path) if meta_path.exists() else {}
        if npz.exists():
            with np.load(npz) as f:
                ref = f["qdd_dd"]
        else:
            log(f"reference {kind}{n_links} {config}: mpmath dps={self.dps} "
                f"({model.n_dof:,} DOF) ...")
            t0 = time.perf_counter()
            mp_ref = hiprec.qdd_reference(model, q, v, dps=self.dps, output="mpf")
            meta["ref_s"] = time.perf_counter() - t0
            meta["ref_s_per_link"] = meta["ref_s"] / n_links
            meta["dps"] = self.dps
            ref = hiprec.to_double_double(mp_ref)
            if n_links <= self.check_max_links and self.check_dps:
                import mpmath
                hi = hiprec.qdd_reference(model, q, v, dps=self.check_dps, output="mpf")
                with mpmath.workdps(self.check_dps):
                    diff = max(abs(a - b) for a, b in zip(mp_ref, hi, strict=True))
                    scale = max(abs(b) for b in hi)
                    meta["ref_check"] = float(diff / scale)
                meta["check_dps"] = self.check_dps
            write_npz_atomic(npz, qdd_dd=ref, q=q, v=v)
            write_json_atomic(meta, meta_path)
            log(f"reference {kind}{n_links} {config}: {meta['ref_s']:.1f} s "
                f"({1e3 * meta['ref_s_per_link']:.2f} ms/link); self-check vs dps="
                f"{self.check_dps}: {meta.get('ref_check', float('nan')):.1e}")
        if meta.get("cond_method") not in (COND_METHOD, "eigvalsh"):
            t0 = time.perf_counter()
            meta.update(cond_lanczos(model, q))
            if model.n_dof <= self.max_svd_dof and "cond2" not in meta:
                meta["cond2"] = cond_svd(model, q)
            meta["cond_s"] = time.perf_counter() - t0
            write_json_atomic(meta, meta_path)
        return ref, meta


# --------------------------------------------------------------------------- core methods
_NJIT32 = {}


def _elimination32(name):
    """The pass ``name`` ("ge-n" or "rge-n") compiled for float32 arrays (its Python source, a
    separate, uncached dispatcher with numba's default options)."""
    if name not in _NJIT32:
        import numba

        from redysim.algorithms.precision import kernel_pass
        _NJIT32[name] = numba.njit(kernel_pass(name).py_func)
    return _NJIT32[name]


def run_core(method: str, precision: str, model, q, v) -> np.ndarray:
    """qdd of a core method (module docstring) at a precision."""
    from redysim import forward_dynamics, mass_matrix, phi

    from . import hiprec
    from .nonsymmetric import literal_rge_a
    f32 = precision == "float32"
    if method == "rge-a":
        if f32:
            return hiprec.rge_a_qdd(model, q, v, arith=hiprec.FLOAT32)
        return forward_dynamics(model, q, v, planar=False)
    if method == "rge-a-planar":
        if f32:
            return hiprec.planar_qdd(model, q, v, arith=hiprec.FLOAT32)
        return forward_dynamics(model, q, v, planar=True)
    if method in ("ge-n", "rge-n"):
        if not f32:
            return forward_dynamics(model, q, v, method=method)
        A = mass_matrix(model, q).astype(np.float32)
        b = phi(model, q, v).astype(np.float32)
        x = np.empty(model.n_dof, dtype=np.float32)
        _elimination32(method)(A, b, np.zeros_like(A), x)
        return x
    if method == "cholesky":
        import scipy.linalg
        dt = np.float32 if f32 else np.float64
        A = mass_matrix(model, q).astype(dt)
        b = phi(model, q, v).astype(dt)
        return scipy.linalg.cho_solve(scipy.linalg.cho_factor(A, check_finite=False), b,
                                      check_finite=False)
    if method == "rge-a-phi":
        return rge_a_on_phi(model, q, v)
    if method in ("literal-6x6", "literal-6x6-resym"):
        return literal_rge_a(model, q, v, dtype=np.float32 if f32 else np.float64,
                             resymmetrise=method.endswith("resym"))
    raise ValueError(method)


def rge_a_on_phi(model, q, v) -> np.ndarray:
    """Table A.1 as printed (``rge-a-phi``, module docstring), float64, O(n): the core's compiled
    passes, taken from its door to the kernels (:mod:`redysim.algorithms.precision`)."""
    from redysim import Workspace, phi
    from redysim.algorithms.precision import kernel_pass
    kinematics = kernel_pass("kinematics")
    rge_a_backward, rge_a_forward = kernel_pass("rge-a-backward"), kernel_pass("rge-a-forward")
    c, ws = model, Workspace(model)
    ph = phi(c, q, v).copy()
    kinematics(ws.tree, q, ws.zeros, ws.zeros, ws.no_accel, ws.s)
    rge_a_backward(ws.tree, ws.table_a1, ph)
    qdd = np.empty(c.n_dof)
    rge_a_forward(ws.tree, ws.table_a1, ws.no_accel, qdd)
    return qdd


def core_skip_reason(method: str, precision: str, model, a) -> str:
    """Why a core cell is not run ('' to run it)."""
    n, nl = model.n_dof, model.n_links
    if method == "rge-a-planar" and not model.is_planar:
        return "n/a"  # not a cell at all
    if precision == "float32" and method not in FLOAT32_METHODS:
        return "n/a"
    if method in ("ge-n", "rge-n") and n > a.max_gen_dof:
        return f"{n:,} DOF > --max-gen-dof {a.max_gen_dof:,} (O(n^3))"
    if method == "cholesky" and n > a.max_dense_dof:
        return f"{n:,} DOF > --max-dense-dof {a.max_dense_dof:,} (O(n^2) memory, O(n^3) time)"
    slow_py = (precision == "float32" and method.startswith("rge-a")) or method.startswith(
        "literal")
    if slow_py and nl > a.max_py_links:
        return f"{nl:,} links > --max-py-links {a.max_py_links:,} (Python-speed kernel)"
    return ""


# --------------------------------------------------------------------------- engines
def _engine_child(conn, name, kind, n_links, states, mem_gib):
    """In a child process: build the engine once, qdd at each state; send a dict back."""
    out = {"ok": False, "error": "", "qdd": {}, "qdd_s": {}}
    try:
        import resource

        from redysim import references
        cls = references.get(name)
        out["version"] = cls.package_version()
        model = make_chain(kind, n_links)  # (a Chain is a Model: the adapters' input)
        cap = int(mem_gib * 2**30)
        resource.setrlimit(resource.RLIMIT_AS, (cap, cap))
        t0 = time.perf_counter()
        eng = cls(model)
        out["build_s"] = time.perf_counter() - t0
        for config, (q, v) in states.items():
            t0 = time.perf_counter()
            out["qdd"][config] = np.asarray(eng.qdd(q, v), dtype=float).copy()
            out["qdd_s"][config] = time.perf_counter() - t0
        out["ok"] = True
    except BaseException as exc:  # MemoryError, engine errors: report them, never crash
        out["error"] = f"{type(exc).__name__}: {exc}"[:400]
    conn.send(out)
    conn.close()


def run_engine_job(name, kind, n_links, states, timeout_s, mem_gib) -> dict:
    ctx = mp.get_context("spawn")
    parent, child = ctx.Pipe(duplex=False)
    proc = ctx.Process(target=_engine_child, args=(child, name, kind, n_links, states, mem_gib))
    proc.start()
    child.close()
    try:
        if parent.poll(timeout_s):
            res = parent.recv()
        else:
            res = {"ok": False, "error": f"timeout after {timeout_s:.0f} s", "qdd": {}}
    except EOFError:
        res = {"ok": False, "error": "child process died (no result)", "qdd": {}}
    proc.join(10)
    if proc.is_alive():
        proc.kill()  # our own child, by its handle
        proc.join()
    if not res["ok"] and proc.exitcode not in (0, None):
        res["error"] += f" (exit code {proc.exitcode})"
    return res


def engine_precheck(name, model) -> tuple[str, str]:
    """('refused', reason) beyond the engine's limits; ('deferred', reason) when the machine has
    not the memory now; ('', '') to run."""
    from redysim import references
    cls = references.get(name)
    if not cls.available():
        return "refused", f"{name}: package {cls.package!r} not installed"
    lim = cls.limits(model)
    if not lim.ok:
        return "refused", lim.reason
    if name.startswith("pinocchio"):
        import psutil
        need = 33 * model.n_dof**3 * 1.2 + 0.5 * 2**30  # pin.Data's nv^3 tensors (limits.toml)
        avail = psutil.virtual_memory().available
        if avail < need + 2 * 2**30:
            return "deferred", (f"memory guard: pin.Data needs ~{need / 2**30:.1f} GiB, "
                                f"{avail / 2**30:.1f} GiB available now")
    return "", ""


# --------------------------------------------------------------------------- results table
class Results:
    """The Parquet table: one row per cell, rewritten atomically after every cell."""

    def __init__(self, path: Path, core_digest: str = ""):
        from .store import read_parquet
        self.path = path
        self.core_digest = core_digest
        self.rows: dict[tuple, dict] = {}
        if path.exists():
            for r in read_parquet(path).to_dict("records"):
                if r["method"] in METHODS:  # a method since retired is dropped
                    self.rows[tuple(r[k] for k in KEY)] = r

    def done(self, key) -> bool:
        """Finished, and for a core method computed by the core's current kernels (their source
        digest, ``redysim.algorithms.precision.sources_digest``): a change to the kernels redoes
        the cell."""
        r = self.rows.get(key)
        if r is None or r["status"] not in FINAL:
            return False
        return key[3] not in CORE_METHODS or r.get("core_digest") == self.core_digest

    def put(self, row: dict) -> None:
        self.rows[tuple(row[k] for k in KEY)] = row
        self._write()

    def _write(self) -> None:
        """Atomically (redysim.harness.store: temp file, fsync, os.replace): a reader or a crash
        never sees a half-written table."""
        from .store import write_parquet_atomic
        write_parquet_atomic(self.frame(), self.path)

    def frame(self):
        import pandas as pd
        return pd.DataFrame(list(self.rows.values()))

    def patch(self, kind, n_links, config, precision, fields: dict) -> None:
        """Update ``fields`` (the conditioning) in the rows of one chain x size x config x
        precision, e.g. after the cached estimate was recomputed."""
        changed = False
        for key, row in self.rows.items():
            if key[:3] == (kind, n_links, config) and key[4] == precision:
                for f, v in fields.items():
                    old = row.get(f)
                    if not (old == v or (isinstance(old, float) and isinstance(v, float)
                                         and math.isnan(old) and math.isnan(v))):
                        row[f] = v
                        changed = True
        if changed:
            self._write()


def cond_fields(meta: dict, precision: str = "") -> dict:
    cond = float(meta.get("cond2", float("nan")))
    cl = float(meta.get("cond2_lanczos", float("nan")))
    out = {"cond2": cond, "cond2_lanczos": cl}
    if precision:
        out["cond2_eps"] = (cond if math.isfinite(cond) else cl) * EPS[precision]
    return out


def base_row(kind, model, config, method, precision, meta) -> dict:
    nl = model.n_links
    return {
        "chain": kind, "joint": CHAINS[kind]["joint"], "n_links": nl, "n_dof": model.n_dof,
        "config": config, "method": method, "precision": precision, "status": "", "reason": "",
        "rel2": float("nan"), "relmax": float("nan"), "n_nonfinite": 0, "time_s": float("nan"),
        **cond_fields(meta, precision), "cond_featherstone": 4.0 * nl**4,
        "ref_dps": meta.get("dps", 0), "ref_check": meta.get("ref_check", float("nan")),
        "ref_s": meta.get("ref_s", float("nan")), "engine_version": "",
        "build_s": float("nan"), "date": _dt.datetime.now().isoformat(timespec="seconds"),
        "host": platform.node(),
    }


def fill_errors(row, qdd, ref) -> dict:
    from .hiprec import relative_errors
    x = np.asarray(qdd, dtype=float)
    bad = int(np.count_nonzero(~np.isfinite(x)))
    row["n_nonfinite"] = bad
    if bad:
        row["status"] = "nonfinite"
        row["reason"] = f"{bad} of {x.size} entries NaN/Inf"
    else:
        row["rel2"], row["relmax"] = relative_errors(x, ref)
        row["status"] = "ok"
    return row


# --------------------------------------------------------------------------- the study
def study(a) -> None:
    from redysim import __version__ as core_version
    out = Path(a.out)
    out.mkdir(parents=True, exist_ok=True)
    from redysim.algorithms.precision import sources_digest
    res = Results(out / "error_study.parquet", sources_digest()[:16])
    refs = RefStore(out, a.dps, a.check_dps, a.check_max_links, a.max_svd_dof)
    log(f"error study -> {res.path} ({len(res.rows)} cells on file); sizes {a.sizes}, chains "
        f"{a.chains}, configs {a.configs}, precisions {a.precisions}; core {core_version}")
    core_methods = [m for m in a.methods if m in CORE_METHODS]
    engines = [m for m in a.methods if m in ENGINE_METHODS]
    for n_links in a.sizes:
        for kind in a.chains:
            chain = make_chain(kind, n_links)
            states = {cfg: make_state(chain, kind, n_links, cfg) for cfg in a.configs}
            cells = [(m, p) for m in core_methods for p in a.precisions] + [
                (e, "float64") for e in engines]
            todo = [(cfg, m, p) for cfg in a.configs for m, p in cells
                    if not res.done((kind, n_links, cfg, m, p))
                    and core_skip_reason(m, p, chain, a) != "n/a"]
            refdata = {cfg: refs.get(kind, n_links, cfg, chain, *states[cfg])
                       for cfg in a.configs} if todo or any(
                           k[:2] == (kind, n_links) for k in res.rows) else {}
            for cfg, (_, meta) in refdata.items():  # refresh the conditioning on file
                for p in ("float64", "float32"):
                    res.patch(kind, n_links, cfg, p, cond_fields(meta, p))
            if not todo:
                continue
            # core methods, in this process
            for cfg in a.configs:
                ref, meta = refdata[cfg]
                q, v = states[cfg]
                for m in core_methods:
                    for p in a.precisions:
                        key = (kind, n_links, cfg, m, p)
                        why = core_skip_reason(m, p, chain, a)
                        if why == "n/a" or res.done(key):
                            continue
                        row = base_row(kind, chain, cfg, m, p, meta)
                        row["engine_version"] = f"redysim {core_version}"
                        row["core_digest"] = res.core_digest
                        if why:
                            row.update(status="skipped", reason=why)
                            if key not in res.rows or res.rows[key]["status"] != "skipped":
                                res.put(row)
                            continue
                        try:
                            t0 = time.perf_counter()
                            with np.errstate(all="ignore"):
                                x = run_core(m, p, chain, q, v)
                            row["time_s"] = time.perf_counter() - t0
                            fill_errors(row, x, ref)
                        except np.linalg.LinAlgError as exc:  # the method fails: a result
                            row.update(status="failed", reason=f"LinAlgError: {exc}"[:400])
                        except Exception as exc:
                            row.update(status="error", reason=f"{type(exc).__name__}: {exc}"[:400])
                            traceback.print_exc()
                        res.put(row)
                        log(f"{kind}{n_links} {cfg:9s} {m:18s} {p}: {row['status']} "
                            f"rel2 {row['rel2']:.2e} relmax {row['relmax']:.2e} "
                            f"({row['time_s']:.3g} s) {row['reason']}")
            # engines, one child process per (engine, chain, size), both configurations
            for e in engines:
                keys = {cfg: (kind, n_links, cfg, e, "float64") for cfg in a.configs}
                if all(res.done(k) for k in keys.values()):
                    continue
                status, why = engine_precheck(e, chain)
                if status:
                    for cfg in keys:
                        row = base_row(kind, chain, cfg, e, "float64", refdata[cfg][1])
                        row.update(status=status, reason=why)
                        res.put(row)
                    log(f"{kind}{n_links} {e}: {status}: {why[:120]}")
                    continue
                log(f"{kind}{n_links} {e}: building in a child process ...")
                out_e = run_engine_job(e, kind, n_links, states, a.engine_timeout,
                                       ENGINE_MEM_GIB)
                for cfg in keys:
                    ref, meta = refdata[cfg]
                    row = base_row(kind, chain, cfg, e, "float64", meta)
                    row["engine_version"] = f"{e} {out_e.get('version', '')}"
                    row["build_s"] = out_e.get("build_s", float("nan"))
                    if cfg in out_e["qdd"]:
                        row["time_s"] = out_e["qdd_s"][cfg]
                        fill_errors(row, out_e["qdd"][cfg], ref)
                    else:
                        row.update(status="error", reason=out_e["error"])
                    res.put(row)
                    log(f"{kind}{n_links} {cfg:9s} {e:18s} float64: {row['status']} "
                        f"rel2 {row['rel2']:.2e} relmax {row['relmax']:.2e} "
                        f"(build {row['build_s']:.3g} s) {row['reason'][:100]}")
    print_table(res.frame())


def print_table(df) -> None:
    """The readable table: rel2 (2-norm true relative error), methods as columns."""
    import pandas as pd
    if df.empty:
        print("no results")
        return
    pd.set_option("display.width", 250)
    pd.set_option("display.max_columns", 40)
    pd.set_option("display.max_rows", 500)
    ok = df[df.status.isin(["ok", "nonfinite", "failed"])].copy()
    ok["val"] = ok.rel2.where(ok.status == "ok", np.inf)  # inf: NaN/Inf result
    ok.loc[ok.status == "failed", "val"] = -np.inf  # -inf: the method failed (LinAlgError)
    order = [m for m in METHODS if m in set(ok.method)]
    for prec in ("float64", "float32"):
        sub = ok[ok.precision == prec]
        if sub.empty:
            continue
        tab = sub.pivot_table(index=["chain", "config", "n_links"], columns="method",
                              values="val", aggfunc="first")
        tab = tab[[m for m in order if m in tab.columns]]
        cond = df.drop_duplicates(["chain", "config", "n_links"]).set_index(
            ["chain", "config", "n_links"])[["cond2", "cond2_lanczos", "cond_featherstone"]]
        tab = tab.join(cond)
        fmt = tab.map(lambda v: "" if pd.isna(v) else ("NaN" if v == np.inf else (
            "FAIL" if v == -np.inf else f"{v:.1e}")))
        print(f"\nTrue relative error ||qdd - ref||_2 / ||ref||_2, {prec} (NaN: the method "
              f"returned NaN/Inf; FAIL: it raised (Cholesky: not positive definite); blank: not "
              f"run or beyond its limit)")
        print(fmt.to_string())
    other = df[~df.status.isin(["ok", "nonfinite", "failed"])]
    if not other.empty:
        print("\nNot run (method [status]: chain n_links; the first reason):")
        for (m, st), g in other.groupby(["method", "status"], sort=False):
            where = " ".join(f"{c}:" + ",".join(str(x) for x in sorted(set(gg.n_links)))
                             for c, gg in g.groupby("chain"))
            print(f"  {m} [{st}]: {where}; {g.reason.iloc[0][:110]}")


def parse_args(argv=None):
    ap = argparse.ArgumentParser(prog="python -m redysim.harness.error_study",
                                 description=__doc__.split("\n\n")[0],
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sizes", type=int, nargs="+", default=list(DEFAULT_SIZES))
    ap.add_argument("--chains", nargs="+", default=["U", "R"], choices=list(CHAINS))
    ap.add_argument("--configs", nargs="+", default=list(CONFIGS), choices=list(CONFIGS))
    ap.add_argument("--methods", nargs="+", default=list(METHODS), choices=list(METHODS))
    ap.add_argument("--precisions", nargs="+", default=["float64", "float32"],
                    choices=["float64", "float32"])
    ap.add_argument("--no-engines", action="store_true", help="core methods only")
    ap.add_argument("--out", default="results/error_study")
    ap.add_argument("--dps", type=int, default=50, help="digits of the mpmath reference")
    ap.add_argument("--check-dps", type=int, default=70,
                    help="recompute the reference at this many digits (0: never) ...")
    ap.add_argument("--check-max-links", type=int, default=10000,
                    help="... for chains up to this many links")
    ap.add_argument("--max-gen-dof", type=int, default=2000, help="GE-N / RGE-N (O(n^3))")
    ap.add_argument("--max-dense-dof", type=int, default=10000, help="Cholesky (O(n^2) memory)")
    ap.add_argument("--max-svd-dof", type=int, default=3000, help="numpy.linalg.cond (SVD)")
    ap.add_argument("--max-py-links", type=int, default=100000,
                    help="float32 RGE-A and the literal kernels (Python speed)")
    ap.add_argument("--engine-timeout", type=float, default=900.0, help="per engine job [s]")
    ap.add_argument("--table", action="store_true", help="only print the table on file")
    a = ap.parse_args(argv)
    if a.no_engines:
        a.methods = [m for m in a.methods if m not in ENGINE_METHODS]
    a.sizes = sorted(set(a.sizes))
    return a


def main(argv=None) -> int:
    a = parse_args(argv)
    if a.table:
        print_table(Results(Path(a.out) / "error_study.parquet").frame())
        return 0
    study(a)
    return 0


if __name__ == "__main__":
    sys.exit(main())
