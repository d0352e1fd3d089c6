"""Turn a pytest-benchmark JSON of benchmarks/test_bench_engines.py into a table.

    .venv/bin/python -m redysim.references.report_bench results/bench_engines.json [--markdown]

Columns: kind (qdd, batch of ``states`` states, or native step), engine, version, DOF, time per
call, ns per DOF (per DOF and state for a batch), and the ratio to the core's qdd at the same
DOF (to the core's batch for a batch). Times are each benchmark's fastest round (pytest-
benchmark's min): the calls are deterministic and a shared machine only ever adds time, far more
to a mean than to a minimum (docs/notes/2026-11-costs-in-the-code.md).
"""

from __future__ import annotations

import argparse
import json
import sys


def rows(doc: dict) -> list[dict]:
    out = []
    for b in doc["benchmarks"]:
        x = b.get("extra_info", {})
        if "engine" not in x:
            continue
        out.append({"kind": x.get("kind", "qdd"), "engine": x["engine"],
                    "robot": x.get("robot", ""), "version": x.get("version", ""),
                    "dof": int(x["dof"]), "states": int(x.get("states", 1)),
                    "mean_s": b["stats"]["mean"], "min_s": b["stats"]["min"],
                    "rounds": b["stats"]["rounds"]})
    # the core's qdd at the same size: its batch for a batch, its single call for the rest
    core = {(r["kind"] == "batch", r["robot"], r["dof"]): r["min_s"] for r in out
            if r["engine"] == "core" and r["kind"] in ("qdd", "batch")}
    for r in out:
        key = (r["kind"] == "batch", r["robot"], r["dof"])
        r["ns_per_dof"] = r["min_s"] * 1e9 / (r["dof"] * r["states"])
        r["ratio"] = r["min_s"] / core[key] if key in core else float("nan")
    out.sort(key=lambda r: (r["kind"], r["robot"], r["dof"], r["min_s"]))
    return out


def fmt_time(s: float) -> str:
    for unit, scale in (("s", 1.0), ("ms", 1e-3), ("us", 1e-6)):
        if s >= scale:
            return f"{s / scale:.3g} {unit}"
    return f"{s * 1e9:.3g} ns"


def table(rs: list[dict], markdown: bool = False) -> str:
    head = ["kind", "robot", "engine", "version", "DOF", "time/call (min)", "ns/DOF", "x core"]
    body = [[r["kind"], r["robot"] or "U chain", r["engine"], r["version"], f"{r['dof']:,}",
             fmt_time(r["min_s"]),
             f"{r['ns_per_dof']:,.0f}", f"{r['ratio']:.3g}"] for r in rs]
    if markdown:
        lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
        lines += ["| " + " | ".join(row) + " |" for row in body]
        return "\n".join(lines)
    widths = [max(len(str(x)) for x in col) for col in zip(head, *body, strict=False)]
    line = "  ".join
    return "\n".join(line(str(x).rjust(w) for x, w in zip(row, widths, strict=True))
                     for row in [head, *body])


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("json")
    ap.add_argument("--markdown", action="store_true")
    a = ap.parse_args(argv)
    with open(a.json) as fh:
        doc = json.load(fh)
    info = doc.get("machine_info", {})
    print(f"# {info.get('node', '')} {info.get('cpu', {}).get('brand_raw', '')} "
          f"python {info.get('python_version', '')}; {doc.get('datetime', '')}")
    print(table(rows(doc), a.markdown))
    return 0


if __name__ == "__main__":
    sys.exit(main())
