"""Number formatting and provenance lines shared by the report's tables and figures."""

from __future__ import annotations

import math
import textwrap
from collections.abc import Iterable, Mapping
from decimal import Decimal

import pandas as pd

from redysim.harness.provenance import provenance
from redysim.harness.spec import CORE

PROVENANCE_KEYS = ("redysim", "git_commit", "python", "numpy", "scipy", "numba", "machine", "cpu",
                   "date")
FOOTER_CHARS_PER_INCH = 19  # monospace characters per inch of a figure's footer line
SCI_TRAILING_ZEROS = 3  # printed(): 1.027e+07 rather than 10,270,000
SCI_BELOW = 1e-4        # printed(): 2.15e-06 rather than 0.00000215


def num(x, sig: int = 4) -> str:
    """A number in ``sig`` significant digits (general format); '' for None, 'NaN', 'inf'."""
    if x is None:
        return ""
    if isinstance(x, str):
        return x
    x = float(x)
    if math.isnan(x):
        return "NaN"
    if math.isinf(x):
        return "inf" if x > 0 else "-inf"
    return f"{x:.{sig}g}"


def printed(x) -> str:
    """A published value as the paper prints it: its own significant digits, scientific where
    it is very large or small (2.15e-06, 1.027e+07, 12,194, 10.2756); strings as they are."""
    if isinstance(x, str):
        return x
    d = Decimal(repr(float(x))).normalize()
    _, digits, exp = d.as_tuple()
    if exp >= SCI_TRAILING_ZEROS or (x != 0 and abs(x) < SCI_BELOW):
        return f"{float(x):.{len(digits) - 1}e}"
    if exp >= 0:
        return f"{int(d):,}"
    return format(d, "f")


def vector(xs, fmt=printed) -> str:
    """[a, b, c]; a single value without brackets."""
    if len(xs) == 1:
        return fmt(xs[0])
    return "[" + ", ".join(fmt(x) for x in xs) + "]"


def matrix(xs, n: int, fmt=printed) -> str:
    """A flat n x n matrix as [a, b, c; d, e, f; ...]."""
    rows = [", ".join(fmt(x) for x in xs[i:i + n]) for i in range(0, len(xs), n)]
    return "[" + "; ".join(rows) + "]"


def sci(x, digits: int = 2) -> str:
    """Scientific notation with ``digits`` decimals: 2.15e-06."""
    if x is None or (isinstance(x, float) and math.isnan(x)):
        return ""
    return f"{float(x):.{digits}e}"


def seconds(x) -> str:
    """A duration: 0.23 ms, 4.1 s, 3.2 min, 2.5 h."""
    if x is None or not math.isfinite(float(x)):
        return ""
    x = float(x)
    if x < 1e-3:
        return f"{x * 1e6:.3g} us"
    if x < 1:
        return f"{x * 1e3:.3g} ms"
    if x < 120:
        return f"{x:.3g} s"
    if x < 7200:
        return f"{x / 60:.3g} min"
    return f"{x / 3600:.3g} h"


def clip(text, limit: int) -> str:
    """``text`` cut to at most ``limit`` characters at a word's end, ' ...' added where it was
    cut (a single word longer than the limit is cut inside it, the only way to cut it)."""
    text = " ".join(str(text).split())
    if len(text) <= limit:
        return text
    head = text[:limit + 1].rsplit(" ", 1)[0] if " " in text[:limit + 1] else text[:limit]
    return head.rstrip(" ,;:") + " ..."


def integer(x) -> str:
    return "" if x is None or (isinstance(x, float) and math.isnan(x)) else f"{int(x):,}"


def _records(source) -> list[Mapping]:
    if source is None:
        return []
    if isinstance(source, pd.DataFrame):
        cols = [c for c in (*PROVENANCE_KEYS, "engine", "engine_version", "generated", "host")
                if c in source.columns]
        return source[cols].drop_duplicates().to_dict("records") if cols else []
    if isinstance(source, Mapping):
        return [source]
    return list(source)


def _values(records: Iterable[Mapping], key: str) -> list[str]:
    out = []
    for r in records:
        v = r.get(key)
        if v is not None and not (isinstance(v, float) and math.isnan(v)) and str(v) \
                and str(v) not in out:
            out.append(str(v))
    return out


def provenance_line(source=None, *, what: str = "") -> str:
    """One line: versions, engines, machine, commit and dates of the data in ``source`` (a
    DataFrame with provenance columns, a provenance dict, or a list of them). Keys the data does
    not carry are taken from this process (the report's build), marked "report:"."""
    recs = _records(source)
    here = provenance()
    parts = []

    def pick(key: str) -> str:
        vals = _values(recs, key)
        return ", ".join(vals) if vals else ""

    core = pick("redysim") or here["redysim"]
    commit = pick("git_commit")
    parts.append(f"redysim {core}" + (f" (git {commit})" if commit else ""))
    libs = [f"{k} {pick(k)}" for k in ("python", "numpy", "scipy", "numba") if pick(k)]
    parts.append(", ".join(libs) if libs else
                 f"report: Python {here['python']}, numpy {here['numpy']}")
    engines = []
    for r in recs:
        eng, ver = r.get("engine"), r.get("engine_version")
        if eng and eng != CORE and ver and isinstance(ver, str):
            label = ver if ver.startswith(str(eng)) else f"{eng} {ver}"
            if label not in engines:
                engines.append(label)
    if engines:
        parts.append("engines: " + ", ".join(sorted(engines)))
    machine, cpu = pick("machine") or pick("host"), pick("cpu")
    if machine and cpu:
        parts.append(f"{machine}; {cpu}")
    else:  # the data does not say it all: the report's machine beside what it says
        said = "; ".join(x for x in (machine, cpu) if x)
        parts.append(f"{said} (report: {here['machine']}; {here['cpu']})".strip())
    dates = sorted({d[:10] for d in _values(recs, "date") + _values(recs, "generated")})
    if dates:
        parts.append(dates[0] if len(dates) == 1 else f"{dates[0]}..{dates[-1]}")
    line = " | ".join(parts)
    return f"{what}: {line}" if what else line


def footer_lines(line: str, width_in: float) -> list[str]:
    """A provenance line wrapped for the footer of a figure ``width_in`` inches wide."""
    return textwrap.wrap(line, int(width_in * FOOTER_CHARS_PER_INCH)) or [""]
