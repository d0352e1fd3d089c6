"""The GIM of the paper's chains: Table 9 and the condition number against the number of links.

    python -m redysim.reports.gim_study [--out results/gim_study] [--max-links 1000]

Table 9: the 3-link study chain's GIM, cond2, phi and qdd at the state of ``STUDY-R3-TABLE9``
(docs/design.md, "Chain conventions"), in double precision, beside the published values.

Conditioning (section 5.1; Featherstone's estimate cond2 ~ 4 nl^4 for a uniform planar chain):
cond2 of the GIM at q = 0 (the straight chain, where it is largest) by SVD (numpy.linalg.cond),
for the section-5 study chain (R joints, l = 1 m) and the RE-U steel rod (U joints, l = 0.02 m),
and beside it cond2 of the unit upper factor U of RGE-A's I = U D U^T (``redysim.udu_factors``):
the paper's claim that the factors' condition numbers stay nearly invariant with nl.

Output: ``table9.json`` and ``cond.parquet`` (one row per chain x size, with provenance).
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np
import pandas as pd

from redysim import (
    Chain,
    forward_dynamics,
    load_case,
    load_published,
    mass_matrix,
    phi,
    udu_factors,
)
from redysim.harness.provenance import provenance
from redysim.harness.store import write_json_atomic, write_parquet_atomic

DEFAULT_OUT = Path("results") / "gim_study"
TABLE9_FILE = "table9.json"
COND_FILE = "cond.parquet"
TABLE9_CASE = "STUDY-R3-TABLE9"
TABLE9_DECIMALS = 4  # the paper prints Table 9 to four decimals
FEATHERSTONE_FACTOR = 4.0  # cond2 ~ 4 nl^4 (Featherstone, via the paper's introduction)
# Sizes [links]: every study chain of Tables 9 and 11 and beyond, and U chains up to ~1,000 links
# (a dense SVD of 2,000 x 2,000 takes seconds).
R_SIZES = (3, 5, 10, 20, 40, 60, 80, 100, 200, 500, 1000)
U_SIZES = (5, 10, 20, 50, 100, 200, 500, 1000)
MAX_LINKS = max(R_SIZES + U_SIZES)
CHAINS = {
    "R": ("study chain (R, l = 1 m, cylinder inertia)",
          dict(joint="R", length=1.0, linear_density=7025 * np.pi * 0.02**2, radius=0.02,
               inertia="cylinder")),
    "U": ("RE-U steel rod (U, l = 0.02 m, rod inertia)",
          dict(joint="U", length=0.02, linear_density=7850 * np.pi * 0.05**2, radius=0.05,
               inertia="rod")),
}


def table9() -> dict:
    """Our double-precision GIM, cond2, phi and qdd at Table 9's state, beside the paper's."""
    case = load_case(TABLE9_CASE)
    ch, q, qd = case.chain, case.q0, case.v0
    gim = mass_matrix(ch, q)
    pub = load_published()["table9"]
    ours = {"gim": gim.tolist(), "cond2": float(np.linalg.cond(gim)),
            "phi": phi(ch, q, qd).tolist(), "qdd": forward_dynamics(ch, q, qd).tolist()}
    paper = {k: pub[k] for k in ours}
    return {"case": TABLE9_CASE, "decimals": TABLE9_DECIMALS, "ours": ours, "paper": paper}


def conditioning(max_links: int) -> pd.DataFrame:
    """cond2 of the GIM and of RGE-A's U factor at q = 0, per chain and size."""
    rows = []
    for kind, (what, params) in CHAINS.items():
        sizes = R_SIZES if kind == "R" else U_SIZES
        for nl in (s for s in sizes if s <= max_links):
            p = dict(params)
            chain = Chain.uniform(nl, p.pop("joint"), **p)
            q = np.zeros(chain.n_dof)
            t0 = time.perf_counter()
            cond_gim = float(np.linalg.cond(mass_matrix(chain, q)))
            cond_u = float(np.linalg.cond(udu_factors(chain, q).U))
            rows.append({"chain": kind, "what": what, "n_links": nl, "n_dof": chain.n_dof,
                         "cond2_gim": cond_gim, "cond2_udu_U": cond_u,
                         "featherstone": FEATHERSTONE_FACTOR * nl**4,
                         "seconds": time.perf_counter() - t0})
    df = pd.DataFrame(rows)
    for k, v in provenance().items():
        df[k] = v
    return df


def run(out: Path, max_links: int = MAX_LINKS) -> tuple[dict, pd.DataFrame]:
    """Compute Table 9 and the conditioning study and write both into ``out``."""
    t9 = table9()
    write_json_atomic({"provenance": provenance(), **t9}, out / TABLE9_FILE)
    df = conditioning(max_links)
    write_parquet_atomic(df, out / COND_FILE)
    return t9, df


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=DEFAULT_OUT, help="output directory")
    ap.add_argument("--max-links", type=int, default=MAX_LINKS,
                    help="largest chain of the conditioning study [links]")
    args = ap.parse_args(argv)
    t9, df = run(args.out, args.max_links)
    print(f"Table 9: cond2 ours {t9['ours']['cond2']:.4f}, paper {t9['paper']['cond2']}; "
          f"qdd ours {np.round(t9['ours']['qdd'], TABLE9_DECIMALS)}, paper {t9['paper']['qdd']}")
    print(df[["chain", "n_links", "n_dof", "cond2_gim", "cond2_udu_U", "featherstone",
              "seconds"]].to_string(index=False))
    print(f"written to {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
