"""Paper-vs-ours tables of the reduced-precision study: Tables 10, A.2 and 11, and IEEE precisions.

    python -m redysim.reports.precision_tables [--out DIR] [--max-links N] [--no-ieee] [--no-table8]

Prints each table beside the paper's values (paper/published.toml) with a verdict per value and a
count of matches, and writes them as CSV and JSON to ``results/precision/`` (atomically). Table 8
runs ode45 (``redysim.integrators.explicit``) with the rounded right-hand side (about 2 minutes,
most of it GE-N on 10 links; the 3-link and 10-link runs with other rounding details add about 30
s); ``table8.json`` also keeps delta_M(t) of its main runs (``series``: Fig. 19).

Verdicts: ``exact`` (ours, rounded half away from zero to the digits the paper prints, equals the
paper), ``truncation`` (ours truncated to those digits equals it; the paper sometimes truncates),
``sign`` (equal in magnitude; published.toml marks Table 10's signs as lost in the text
extraction and re-derived; also an infinity of the other sign than the printed Inf, which the
report calls "non-finite, sign differs" and does not count a match), ``differs`` (with the
difference). Rules and findings: see
``redysim/algorithms/precision.py`` and the notes printed with each table.
"""

from __future__ import annotations

import argparse
import csv
import io
import json
import math
import platform
import sys
import time
import tomllib
from decimal import ROUND_DOWN, ROUND_HALF_UP, Decimal
from pathlib import Path

import numpy as np

import redysim
from redysim import (
    case_from_dict,
    eliminate,
    forward_dynamics,
    load_case,
    load_published,
    mass_matrix,
    phi,
)
from redysim.algorithms.dynamics import PAPER_NAMES
from redysim.algorithms.precision import ieee_qdd, reduced_factors, reduced_qdd
from redysim.harness.store import write_text_atomic
from redysim.io.cases import CASES_DIR

DEFAULT_OUT = Path("results") / "precision"
METHOD_KEYS = {paper: name for name, paper in PAPER_NAMES.items()}  # "GE-N" -> "ge-n"
TABLE11_SIZES = (5, 10, 20, 40, 60, 80, 100)
IEEE_SIZES = (3, 5, 10, 20, 40, 60, 80, 100)


# --------------------------------------------------------------------------- states
def table9_horizontal():
    """Table 9's state in the paper's stated configuration: the 3-link study chain horizontal
    (q = 0) at rest with g = 4.905 (docs/design.md, 'The paper's numbers': same GIM, phi to
    3e-14). Rounded RGE-A sees the geometry; the STUDY-R3-TABLE9 case (q1 = 60 deg, g = 9.81)
    rotates it."""
    with open(CASES_DIR / "STUDY-R3.toml", "rb") as fh:
        doc = tomllib.load(fh)
    doc["case"] = {"name": "STUDY-R3-TABLE9-HORIZONTAL",
                   "description": "Table 9's state, horizontal form: q = 0, g = 4.905"}
    doc["chain"]["gravity"] = [0.0, -4.905, 0.0]
    return case_from_dict(doc, source="reports.precision_tables")


# --------------------------------------------------------------------------- verdicts
def _dec(x: float) -> Decimal:
    return Decimal(repr(float(x)))


def printed_decimals(x, minimum: int = 0) -> int:
    """Decimal places of a transcribed value (at least ``minimum``): 0.519 -> 3, 1.25e-05 -> 7."""
    if isinstance(x, str) or x == 0 or not math.isfinite(x):
        return minimum
    return max(minimum, -_dec(x).normalize().as_tuple().exponent)


def sig_decimals(x: float) -> int:
    """Decimal places that show a transcribed value's significant digits (2708.4 -> 1)."""
    d = _dec(x).normalize().as_tuple()
    return -d.exponent


def verdict(ours: float, paper, decimals: int) -> tuple[str, float | None]:
    """(verdict, ours - paper) for one printed value; see the module docstring."""
    if isinstance(paper, str):  # "NaN", "Inf", "-Inf": as printed
        if math.isnan(ours):
            return ("exact" if paper == "NaN" else "differs"), None
        if math.isinf(ours) and paper.lstrip("+-") == "Inf":
            return ("exact" if (ours < 0) == paper.startswith("-") else "sign"), None
        return "differs", None
    if not math.isfinite(ours):
        return "differs", math.inf
    q = Decimal(1).scaleb(-decimals)
    p = _dec(paper).quantize(q, rounding=ROUND_HALF_UP)
    o = _dec(ours)
    if o.quantize(q, rounding=ROUND_HALF_UP) == p:
        return "exact", ours - paper
    if o.quantize(q, rounding=ROUND_DOWN) == p:
        return "truncation", ours - paper
    if abs(o).quantize(q, rounding=ROUND_HALF_UP) == abs(p):
        return "sign", ours - paper
    return "differs", ours - paper


def count(rows, key: str = "verdict", diff: str = "diff") -> dict:
    out = {"exact": 0, "truncation": 0, "sign": 0, "differs": 0, "largest_diff": 0.0}
    for r in rows:
        out[r[key]] += 1
        if r[key] == "differs" and r.get(diff) is not None:
            out["largest_diff"] = max(out["largest_diff"], abs(r[diff]))
    return out


def _fmt(x, width=11):
    if x is None:
        return f"{'':>{width}}"
    if isinstance(x, str):
        return f"{x:>{width}}"
    if not math.isfinite(x):
        return f"{x!s:>{width}}"
    return f"{x:>{width}.6g}"


# --------------------------------------------------------------------------- Table 10
def table10(pub) -> dict:
    case = table9_horizontal()
    ch, q0, v0 = case.chain, case.q0, case.v0
    q64 = forward_dynamics(ch, q0, v0)
    rows = []
    for arithmetic in ("double", "decimal"):
        for prow in pub["table10"]["rows"]:
            k = round(-math.log10(prow["accuracy"]))
            m = prow["method"]
            x = reduced_qdd(ch, q0, v0, METHOD_KEYS[m], k, arithmetic=arithmetic)
            with np.errstate(all="ignore"):
                dq = (x - q64) / q64 * 100.0
            for i in range(3):
                vq, dfq = verdict(x[i], prow["qdd"][i], 4)
                vd, dfd = verdict(dq[i], prow["dq"][i], printed_decimals(prow["dq"][i], 4))
                rows.append({"arithmetic": arithmetic, "accuracy": prow["accuracy"],
                             "method": m, "i": i + 1,
                             "paper_qdd": prow["qdd"][i], "ours_qdd": float(x[i]),
                             "verdict_qdd": vq, "diff_qdd": dfq,
                             "paper_dq": prow["dq"][i], "ours_dq": float(dq[i]),
                             "verdict_dq": vd, "diff_dq": dfd})
    # RGE-A alternatives (same kernels, other inputs), for the record
    variants = {}
    tab9 = load_case("STUDY-R3-TABLE9")
    inside = "gravity and velocity terms inside (as the core)"
    for label, c, fused in (("horizontal, phi rounded from double (main)", case, False),
                            (f"horizontal, {inside}", case, True),
                            ("q1 = 60 deg, phi rounded from double", tab9, False),
                            (f"q1 = 60 deg, {inside}", tab9, True)):
        n_ok = 0
        for prow in (r for r in pub["table10"]["rows"] if r["method"] == "RGE-A"):
            k = round(-math.log10(prow["accuracy"]))
            x = reduced_qdd(c.chain, c.q0, c.v0, "rge-a", k, fused_phi=fused)
            n_ok += sum(verdict(x[i], prow["qdd"][i], 4)[0] == "exact"
                        and verdict(float((x[i] - q64[i]) / q64[i] * 100), prow["dq"][i],
                                    printed_decimals(prow["dq"][i], 4))[0] in ("exact", "sign")
                        for i in range(3))
        variants[label] = n_ok
    counts = {}
    for a in ("double", "decimal"):
        for m in METHOD_KEYS:
            sel = [r for r in rows if r["arithmetic"] == a and r["method"] == m]
            counts[f"{a}/{m}"] = {"qdd": count(sel, "verdict_qdd", "diff_qdd"),
                                  "dq": count(sel, "verdict_dq", "diff_dq")}
    return {"rows": rows, "counts": counts, "rge_a_variants_values_matching": variants,
            "state": case.name, "qdd_double": q64.tolist()}


def print_table10(t: dict, out) -> None:
    p = lambda *a: print(*a, file=out)  # noqa: E731
    p("\nTable 10: qdd(0) of the 3-link chain with every operation rounded to 1e-k "
      "(arithmetic 'double' = MATLAB's round(x/1e-k)*1e-k on IEEE doubles)")
    p(f"state: {t['state']} (q = 0, g = 4.905: Table 9's GIM and phi); dq = (qdd_F - qdd)/qdd "
      "* 100 against the double-precision qdd")
    p(f"{'acc':>6} {'method':>6} {'i':>2} {'paper qdd':>11} {'ours qdd':>11} {'verdict':>10} "
      f"{'paper dq':>11} {'ours dq':>11} {'verdict':>10}")
    for r in t["rows"]:
        if r["arithmetic"] != "double":
            continue
        p(f"{r['accuracy']:>6g} {r['method']:>6} {r['i']:>2} {_fmt(r['paper_qdd'])} "
          f"{_fmt(r['ours_qdd'])} {r['verdict_qdd']:>10} {_fmt(r['paper_dq'])} "
          f"{_fmt(r['ours_dq'])} {r['verdict_dq']:>10}")
    p("counts (18 values per method; exact / truncation / sign / differs, largest |diff|):")
    for key, c in t["counts"].items():
        p(f"  {key:16} qdd {c['qdd']['exact']:2d}/{c['qdd']['truncation']}/{c['qdd']['sign']}/"
          f"{c['qdd']['differs']:2d} ({c['qdd']['largest_diff']:.3g})   dq {c['dq']['exact']:2d}/"
          f"{c['dq']['truncation']}/{c['dq']['sign']}/{c['dq']['differs']:2d} "
          f"({c['dq']['largest_diff']:.3g})")
    for r in t["rows"]:
        if r["arithmetic"] == "decimal" and r["method"] != "RGE-A" and "differs" in (
                r["verdict_qdd"], r["verdict_dq"]):
            p(f"  decimal arithmetic differs: {r['method']} at {r['accuracy']:g}, qdd_{r['i']} = "
              f"{r['ours_qdd']:g} (paper {r['paper_qdd']}): the exact decimal tie 2.50 * 11.77 = "
              "29.425 rounds up; MATLAB's double 29.424999999999997 rounds down")
    p("RGE-A values matching (qdd and dq both), by variant of the inputs: "
      + "; ".join(f"{k}: {v}/18" for k, v in t["rge_a_variants_values_matching"].items()))


# --------------------------------------------------------------------------- Table A.2
def tableA2(pub) -> dict:
    case = table9_horizontal()
    rows, extra = [], {}
    for name, method in (("ge", "ge-n"), ("rge", "rge-n")):
        f = reduced_factors(case.chain, case.q0, case.v0, method, 3)
        entries = {"L": f.L, "U": f.U, "cond2_L": np.linalg.cond(f.L),
                   "cond2_U": np.linalg.cond(f.U), "phi_hat": f.phihat}
        for key, ours in entries.items():
            paper = pub["tableA2"][name][key]
            ours_flat = np.ravel(ours).tolist()
            paper_flat = np.ravel(np.array(paper, dtype=float)).tolist()
            for j, (o, pv) in enumerate(zip(ours_flat, paper_flat, strict=True)):
                v, d = verdict(o, pv, printed_decimals(pv))
                rows.append({"factorisation": name.upper(), "entry": key,
                             "index": j if np.ndim(ours) else None, "paper": pv, "ours": o,
                             "decimals": printed_decimals(pv), "verdict": v, "diff": d})
    f = reduced_factors(case.chain, case.q0, case.v0, "rge-a", 3)
    extra["RGE-A (spatial kernels, 1e-3; not in the paper)"] = {
        "U": f.U.tolist(), "L'=D U^T": f.L.tolist(), "cond2_U": float(np.linalg.cond(f.U)),
        "cond2_L": float(np.linalg.cond(f.L)), "qdd": f.qdd.tolist()}
    G, ph = mass_matrix(case.chain, case.q0), phi(case.chain, case.q0, case.v0)
    for name, method in (("GE", "ge-n"), ("RGE", "rge-n")):
        e = eliminate(G, ph, method)  # the float64 kernel: the exact factors to ~1e-15
        lower, upper = (e.multipliers, e.factor) if method == "ge-n" else (e.factor, e.multipliers)
        extra[f"{name} exact (double) factors"] = {
            "cond2_L": float(np.linalg.cond(lower)), "cond2_U": float(np.linalg.cond(upper)),
            "phi_hat": e.phihat.tolist()}
    return {"rows": rows, "counts": {k: count([r for r in rows if r["factorisation"] == k])
                                     for k in ("GE", "RGE")}, "extra": extra}


def print_tableA2(t: dict, out) -> None:
    p = lambda *a: print(*a, file=out)  # noqa: E731
    p("\nTable A.2: factors of the 3-link GIM from the 1e-3 rounded GE-N (I = L U) and RGE-N "
      "(I = U' L'), their cond2 and phi-hat")
    p(f"{'fact.':>5} {'entry':>8} {'idx':>3} {'paper':>11} {'ours':>11} {'verdict':>10}")
    for r in t["rows"]:
        idx = "" if r["index"] is None else r["index"]
        p(f"{r['factorisation']:>5} {r['entry']:>8} {idx!s:>3} {_fmt(r['paper'])} "
          f"{_fmt(r['ours'])} {r['verdict']:>10}")
    for k, c in t["counts"].items():
        total = sum(c[v] for v in ("exact", "truncation", "sign", "differs"))
        p(f"  {k}: {c['exact']} exact, {c['truncation']} truncation, {c['sign']} sign, "
          f"{c['differs']} differ (of {total})")
    for k, v in t["extra"].items():
        p(f"  {k}: " + json.dumps(v, default=float))


# --------------------------------------------------------------------------- Table 11
TABLE11_COLUMNS = (("ge_sweep_qdd1", "ge-n", 0), ("ge_subst_qddn", "ge-n", -1),
                   ("rge_sweep_qddn", "rge-a", -1), ("rge_subst_qdd1", "rge-a", 0))


def table11(pub, max_links: int = 100, refs: dict | None = None) -> dict:
    rows = []
    refs = {} if refs is None else refs
    for prow in pub["table11"]["rows"]:
        n = prow["links"]
        if n > max_links:
            continue
        case = load_case(f"STUDY-R{n}")
        ch, q0, v0 = case.chain, case.q0, case.v0
        G = mass_matrix(ch, q0)
        cond = float(np.linalg.cond(G))
        v, d = verdict(cond, prow["cond2"], sig_decimals(prow["cond2"]))
        q64 = np.linalg.solve(G, phi(ch, q0, v0))
        exact = refs.setdefault(("gim", n), reduced_qdd(ch, q0, v0, "rge-n", 40,
                                                        arithmetic="decimal"))
        row = {"links": n, "paper_cond2": prow["cond2"], "ours_cond2": cond, "verdict_cond2": v,
               "qdd1_double": float(q64[0]), "qddn_double": float(q64[-1]),
               "qddn_exact_of_double_system": float(exact[-1])}
        for k in (6, 7):
            runs = {m: reduced_qdd(ch, q0, v0, m, k) for m in ("ge-n", "rge-a")}
            for col, m, i in TABLE11_COLUMNS:
                # the paper's sign convention here: (qdd - qdd_F) / qdd * 100
                e = float((q64[i] - runs[m][i]) / q64[i] * 100.0)
                row[f"ours_{col}@1e-{k}"] = e
                row[f"verdict_{col}@1e-{k}"], _ = verdict(e, prow[col], sig_decimals(prow[col]))
                row[f"ratio_{col}@1e-{k}"] = e / prow[col]
                if i == 0:  # qdd_1 is well determined: the difference in units of the quantum
                    row[f"quanta_{col}@1e-{k}"] = (e - prow[col]) / 100 * abs(q64[0]) * 10**k
        for col, _, _ in TABLE11_COLUMNS:
            row[f"paper_{col}"] = prow[col]
        rows.append(row)
    counts = {}
    for k in (6, 7):
        for col, _, _ in TABLE11_COLUMNS:
            vs = [r[f"verdict_{col}@1e-{k}"] for r in rows]
            within2 = sum(0.5 <= abs(r[f"ratio_{col}@1e-{k}"]) <= 2 for r in rows)
            counts[f"{col}@1e-{k}"] = {"exact": vs.count("exact"),
                                       "truncation": vs.count("truncation"),
                                       "sign": vs.count("sign"), "differs": vs.count("differs"),
                                       "within_factor_2": within2, "of": len(rows)}
    return {"rows": rows, "counts": counts}


def print_table11(t: dict, out) -> None:
    p = lambda *a: print(*a, file=out)  # noqa: E731
    p("\nTable 11: % error (qdd - qdd_F)/qdd*100 of qdd_1 and qdd_nl, single-DOF study chains at "
      "q = 0, against the double-precision solution (as the paper)")
    p(f"{'nl':>4} {'cond2 paper':>12} {'ours':>12} {'':>10}")
    for r in t["rows"]:
        p(f"{r['links']:>4} {_fmt(r['paper_cond2'], 12)} {_fmt(r['ours_cond2'], 12)} "
          f"{r['verdict_cond2']:>10}")
    for col, m, i in TABLE11_COLUMNS:
        p(f"  {col} ({m.upper()}, qdd_{'1' if i == 0 else 'nl'}): paper | ours at 1e-6 (verdict) "
          "| ours at 1e-7 (verdict)")
        for r in t["rows"]:
            extra = "".join(f"  [{r[f'quanta_{col}@1e-{k}']:+.1f} quanta at 1e-{k}]"
                            for k in (6, 7) if f"quanta_{col}@1e-{k}" in r)
            p(f"  {r['links']:>4} {_fmt(r[f'paper_{col}'])} | {_fmt(r[f'ours_{col}@1e-6'])} "
              f"{r[f'verdict_{col}@1e-6']:>10} | {_fmt(r[f'ours_{col}@1e-7'])} "
              f"{r[f'verdict_{col}@1e-7']:>10}{extra}")
    p("counts (exact to the printed significant digits / within a factor 2 of the paper):")
    for k, c in t["counts"].items():
        p(f"  {k:24} exact {c['exact']}/{c['of']}, sign {c['sign']}, within x2 "
          f"{c['within_factor_2']}/{c['of']}")
    p("  qdd_nl of the double solution is rounding noise from 20 links on (true value ~0.27^nl):")
    p("  " + ", ".join(f"{r['links']}: {r['qddn_double']:.3g} (exact solution of the double "
                       f"system {r['qddn_exact_of_double_system']:.3g})" for r in t["rows"]))


# --------------------------------------------------------------------------- IEEE
def _lapack_cholesky(A, b, dtype):
    from scipy.linalg import lapack  # the report may use scipy; the core stays numpy-only

    potrf, potrs = (lapack.spotrf, lapack.spotrs) if dtype == np.float32 else \
        (lapack.dpotrf, lapack.dpotrs)
    c, info = potrf(A.astype(dtype), lower=1)
    if info != 0:  # a pivot <= 0: not positive definite in this format
        return None, f"not PD (pivot {info})"
    x, info = potrs(c, b.astype(dtype), lower=1)
    return (x, "ok") if info == 0 else (None, f"potrs info {info}")


def ieee_table(max_links: int = 100, refs: dict | None = None) -> dict:
    refs = {} if refs is None else refs
    rows = []
    for n in IEEE_SIZES:
        if n > max_links:
            continue
        case = load_case(f"STUDY-R{n}")
        ch, q0, v0 = case.chain, case.q0, case.v0
        G, ph = mass_matrix(ch, q0), phi(ch, q0, v0)
        cond = float(np.linalg.cond(G))
        ref_gim = refs.setdefault(("gim", n), reduced_qdd(ch, q0, v0, "rge-n", 40,
                                                          arithmetic="decimal"))
        ref_rec = refs.setdefault(("rec", n), reduced_qdd(ch, q0, v0, "rge-a", 40,
                                                          arithmetic="decimal"))
        ref_fused = refs.setdefault(("fused", n), reduced_qdd(ch, q0, v0, "rge-a", 40,
                                                              arithmetic="decimal",
                                                              fused_phi=True))
        noise = float(np.linalg.norm(ref_gim - ref_rec) / np.linalg.norm(ref_gim))
        for dtype in (np.float32, np.float16):
            u = float(np.finfo(dtype).eps) / 2
            runs = {
                "GE-N": (ieee_qdd(ch, q0, v0, "ge-n", dtype), ref_gim),
                "RGE-N": (ieee_qdd(ch, q0, v0, "rge-n", dtype), ref_gim),
                "RGE-A": (ieee_qdd(ch, q0, v0, "rge-a", dtype), ref_rec),
                "RGE-A (as the core: gravity in the passes)": (
                    ieee_qdd(ch, q0, v0, "rge-a", dtype, fused_phi=True), ref_fused),
            }
            status = {}
            if dtype == np.float32:
                x, status["LAPACK spotrf/spotrs"] = _lapack_cholesky(G, ph, dtype)
                runs["LAPACK spotrf/spotrs"] = (x, ref_gim)
            for m, (x, ref) in runs.items():
                st = status.get(m, "ok")
                if x is not None:
                    x = np.asarray(x, dtype=float)
                    if not np.all(np.isfinite(x)):
                        big = max(np.abs(G).max(), np.abs(ph).max())
                        st = ("inputs overflow" if big > np.finfo(dtype).max
                              else "non-finite result")
                err = float(np.linalg.norm(x - ref) / np.linalg.norm(ref)) if st == "ok" \
                    else math.nan
                rows.append({"links": n, "cond2": cond, "dtype": np.dtype(dtype).name,
                             "unit_roundoff": u, "u_cond2": u * cond, "method": m,
                             "rel_error": err, "status": st, "reference_noise": noise})
    # numpy.linalg in float32 computes in float64 internally (_commonType "lite version")
    case = load_case("STUDY-R10")
    G = mass_matrix(case.chain, case.q0)
    numpy_f32_is_f64 = bool(np.array_equal(np.linalg.cholesky(G.astype(np.float32)),
                                           np.linalg.cholesky(G.astype(np.float32)
                                                              .astype(np.float64))
                                           .astype(np.float32)))
    return {"rows": rows, "numpy_linalg_float32_computes_in_float64": numpy_f32_is_f64}


def print_ieee(t: dict, out) -> None:
    p = lambda *a: print(*a, file=out)  # noqa: E731
    p("\nIEEE precisions: relative error ||qdd - qdd_ref|| / ||qdd_ref|| on the study chains at "
      "q = 0 (ref: the same inputs in 40-place decimal arithmetic)")
    methods = list(dict.fromkeys(r["method"] for r in t["rows"]))
    for dt in ("float32", "float16"):
        sel = [r for r in t["rows"] if r["dtype"] == dt]
        if not sel:
            continue
        ms = [m for m in methods if any(r["method"] == m for r in sel)]
        p(f"  {dt} (u = {sel[0]['unit_roundoff']:.3g})")
        p(f"  {'nl':>4} {'cond2':>10} {'u*cond2':>10} " + " ".join(f"{m[:20]:>20}" for m in ms))
        for n in dict.fromkeys(r["links"] for r in sel):
            rr = {r["method"]: r for r in sel if r["links"] == n}
            r0 = next(iter(rr.values()))
            cells = [f"{rr[m]['rel_error']:.3g}" if rr[m]["status"] == "ok"
                     else rr[m]["status"][:20] for m in ms]
            p(f"  {n:>4} {r0['cond2']:>10.4g} {r0['u_cond2']:>10.3g} "
              + " ".join(f"{c:>20}" for c in cells))
    p("  reference noise (exact solution of the double GIM system vs exact recursion on the double "
      "link data): " + ", ".join(f"{r['links']}: {r['reference_noise']:.2g}" for r in t["rows"]
                                 if r["dtype"] == "float32" and r["method"] == "GE-N"))
    p(f"  numpy.linalg on float32 computes in float64 internally: "
      f"{t['numpy_linalg_float32_computes_in_float64']} (so a float32 Cholesky needs LAPACK "
      "spotrf directly; numpy has no float16 linalg)")


# --------------------------------------------------------------------------- Table 8
TABLE8_RUNS = (("three_link", "STUDY-R3"), ("ten_link", "STUDY-R10"))


def _simulate(case, method: str, decimals: int, *, arithmetic: str = "double",
              fused_phi: bool = False, cpu_limit: float = 900.0) -> dict:
    """One ode45 run (rtol 1e-4, atol 1e-6, samples every 0.05 s) with the rounded RHS, stopped
    after ``cpu_limit`` seconds of CPU time (its status then says so): CPU time, so that what
    the table records does not depend on the machine's load."""
    ch = case.chain

    def qdd(q, v, _tau):
        return reduced_qdd(ch, q, v, method, decimals, arithmetic=arithmetic,
                           fused_phi=fused_phi)

    sim = case.simulation
    res = case.simulator(integrator="ode45", rtol=sim.get("rtol", 1e-4),
                         atol=sim.get("atol", 1e-6), sample=sim.get("sample_interval", 0.05),
                         qdd=qdd, keep_states=False).run(max_cpu_s=cpu_limit, clock="process")
    dM = res.delta_M
    return {"steps": res.steps, "rejected": res.rejected, "nfev": res.nfev, "cpu_s": res.cpu_s,
            "t_reached": float(res.t[-1]), "status": res.message,
            "min_delta_M": float(min(dM)), "max_delta_M": float(max(dM)),
            "avg_abs_delta_M": float(np.mean(np.abs(dM))),
            "t": [float(t) for t in res.t], "delta_M": [float(d) for d in dM]}


def table8(pub, sensitivity: bool = True) -> dict:
    try:
        import redysim.integrators.explicit  # noqa: F401
    except ImportError:
        return {"done": False, "rows": [], "reason": "redysim.integrators.explicit (the ode45 "
                "integrator) is not in the tree; Table 8 needs whole ode45 runs with the "
                "rounded RHS"}
    rows, series = [], []
    for key, name in TABLE8_RUNS:
        entry = pub["table8"][key]
        case = load_case(name)
        k = round(-math.log10(entry["digits_accuracy"]))
        for prow in entry["rows"]:
            r = _simulate(case, METHOD_KEYS[prow["method"]], k)
            # Fig. 19: delta_M(t) of the main runs, kept apart from the table's rows
            series.append({"chain": name, "accuracy": entry["digits_accuracy"],
                           "method": prow["method"], "t": r.pop("t"),
                           "delta_M": r.pop("delta_M")})
            rows.append({"chain": name, "accuracy": entry["digits_accuracy"],
                         "t_end": entry["t_end"], "method": prow["method"],
                         "variant": "main", "paper_steps": prow["steps"],
                         "paper_cpu_s": prow["cpu_s"], **r,
                         "steps_ratio": r["steps"] / prow["steps"]})
        if sensitivity:  # how much the step count depends on rounding details
            for method, arithmetic, fused in (("RGE-N", "decimal", False),
                                              ("RGE-A", "decimal", False),
                                              ("RGE-A", "double", True)):
                prow = next(p for p in entry["rows"] if p["method"] == method)
                r = _simulate(case, METHOD_KEYS[method], k, arithmetic=arithmetic,
                              fused_phi=fused)
                del r["t"], r["delta_M"]
                rows.append({"chain": name, "accuracy": entry["digits_accuracy"],
                             "t_end": entry["t_end"], "method": method,
                             "variant": f"{arithmetic} arithmetic"
                                        + (", gravity in the passes (core)" if fused else ""),
                             "paper_steps": prow["steps"], "paper_cpu_s": prow["cpu_s"], **r,
                             "steps_ratio": r["steps"] / prow["steps"]})
    for name in dict.fromkeys(r["chain"] for r in rows):
        main = [r for r in rows if r["chain"] == name and r["variant"] == "main"]
        ge = next(r for r in main if r["method"] == "GE-N")
        for r in rows:
            if r["chain"] == name:
                r["cpu_vs_ge_n"] = r["cpu_s"] / ge["cpu_s"]
                r["paper_cpu_vs_ge_n"] = r["paper_cpu_s"] / ge["paper_cpu_s"]
    return {"done": True, "rows": rows, "series": series}


def print_table8(t: dict, out) -> None:
    p = lambda *a: print(*a, file=out)  # noqa: E731
    if not t["done"]:
        p(f"\nTable 8: not done: {t['reason']}")
        return
    p("\nTable 8: ode45 (rtol 1e-4, atol 1e-6) with the rounded right-hand side: accepted steps "
      "and CPU, beside the paper's (CPU compared as ratios to GE-N: 2011 laptop vs here)")
    p(f"{'chain':>9} {'acc':>6} {'method':>6} {'variant':>28} {'steps':>6} {'paper':>6} "
      f"{'rej':>5} {'nfev':>6} {'CPU s':>7} {'/GE-N':>6} {'paper':>6} {'min dM':>10} "
      f"{'max dM':>10}")
    for r in t["rows"]:
        p(f"{r['chain']:>9} {r['accuracy']:>6g} {r['method']:>6} {r['variant']:>28} "
          f"{r['steps']:>6} {r['paper_steps']:>6} {r['rejected']:>5} {r['nfev']:>6} "
          f"{r['cpu_s']:>7.2f} {r['cpu_vs_ge_n']:>6.3f} {r['paper_cpu_vs_ge_n']:>6.3f} "
          f"{r['min_delta_M']:>10.3g} {r['max_delta_M']:>10.3g}"
          + ("" if r["status"] == "ok" else f"  ({r['status']} at t = {r['t_reached']:g})"))


# --------------------------------------------------------------------------- output
def _csv(rows: list[dict]) -> str:
    buf = io.StringIO()
    keys = list(dict.fromkeys(k for r in rows for k in r))
    w = csv.DictWriter(buf, fieldnames=keys, lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: r.get(k) for k in keys})
    return buf.getvalue()


def _json_default(x):
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    raise TypeError(type(x))


def _clean(x):
    """JSON has no NaN/Infinity: write them as strings."""
    if isinstance(x, float) and not math.isfinite(x):
        return str(x)
    if isinstance(x, dict):
        return {(k if isinstance(k, str) else str(k)): _clean(v) for k, v in x.items()}
    if isinstance(x, list | tuple):
        return [_clean(v) for v in x]
    return x


def write(out_dir: Path, name: str, table: dict) -> None:
    meta = {"redysim": redysim.__version__, "numpy": np.__version__,
            "python": platform.python_version(), "machine": platform.machine(),
            "generated": time.strftime("%Y-%m-%dT%H:%M:%S%z")}
    payload = _clean(json.loads(json.dumps({"meta": meta, **table}, default=_json_default)))
    write_text_atomic(json.dumps(payload, indent=1, allow_nan=False) + "\n",
                      out_dir / f"{name}.json")
    if table.get("rows"):
        write_text_atomic(_csv(table["rows"]), out_dir / f"{name}.csv")


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output directory")
    ap.add_argument("--max-links", type=int, default=100, help="largest chain of Tables 11/IEEE")
    ap.add_argument("--no-ieee", action="store_true", help="skip the IEEE precision table")
    ap.add_argument("--no-table8", action="store_true", help="skip Table 8 (ode45 runs, ~2 min)")
    ap.add_argument("--no-sensitivity", action="store_true",
                    help="Table 8 without the extra runs under other rounding details")
    args = ap.parse_args(argv)
    pub = load_published()
    out = sys.stdout
    t0 = time.perf_counter()
    refs: dict = {}
    t10 = table10(pub)
    print_table10(t10, out)
    write(args.out, "table10", t10)
    ta2 = tableA2(pub)
    print_tableA2(ta2, out)
    write(args.out, "tableA2", ta2)
    t11 = table11(pub, args.max_links, refs)
    print_table11(t11, out)
    write(args.out, "table11", t11)
    if not args.no_ieee:
        ti = ieee_table(args.max_links, refs)
        print_ieee(ti, out)
        write(args.out, "ieee", ti)
    if not args.no_table8:
        t8 = table8(pub, sensitivity=not args.no_sensitivity)
        print_table8(t8, out)
        write(args.out, "table8", t8)
    print(f"\nwritten to {args.out} in {time.perf_counter() - t0:.1f} s", file=out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
