"""The report's content as plain data: sections of paragraphs, tables and figures.

One model, two renderers: the HTML page (``reports/templates/report.html.j2``) and the PDF
(``reports/pdf.py``) draw the same :class:`Report`, so the two cannot drift apart. Text is plain
(no markup); each renderer escapes it.
"""

from __future__ import annotations

import io
from dataclasses import dataclass, field
from typing import Any

# Row kinds: how a renderer colours a row's verdict.
MATCH = "match"        # ours agrees with the paper (within what the verdict says)
DIFFER = "differ"      # ours differs (the verdict says by how much and, where known, why)
PARTIAL = "partial"    # a run exists but not to the paper's horizon, or only part of the row
INFO = "info"          # no verdict: a value of ours the paper has no counterpart for
NOT_RUN = "notrun"     # no data yet: the verdict says which make target produces it
ROW_KINDS = (MATCH, DIFFER, PARTIAL, INFO, NOT_RUN)


@dataclass
class Row:
    cells: list[str]
    kind: str = INFO


@dataclass
class Table:
    """A table: ``columns`` headers, ``rows``, ``notes`` below it and a one-line ``provenance``."""

    id: str
    title: str
    columns: list[str]
    rows: list[Row] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    provenance: str = ""
    not_run: str = ""  # non-empty: the whole table has no data; says how to get it

    def counts(self) -> dict[str, int]:
        """How many rows of each kind."""
        out = dict.fromkeys(ROW_KINDS, 0)
        for r in self.rows:
            out[r.kind] += 1
        return out


DPI = 120  # a figure's raster resolution (its PNG) and the pixel size the HTML gives it


def render(fig, fmt: str) -> bytes:
    """The matplotlib figure ``fig`` as ``fmt`` bytes: svg and pdf vector (text as paths in SVG,
    so a browser without matplotlib's fonts draws the same glyphs), png at :data:`DPI`."""
    buf = io.BytesIO()
    fig.savefig(buf, format=fmt, dpi=DPI, metadata={"Date": None} if fmt == "svg" else None)
    return buf.getvalue()


@dataclass
class Figure:
    """A figure: its drawing (a matplotlib figure; None when there is no data: ``not_run`` says
    how to get it), rendered on demand as SVG (the HTML page's), PDF (the PDF's: both vector)
    or PNG (a raster, for a file a user asks for)."""

    id: str
    family: str  # tip-path, tip-speed, drift, conditioning, scaling, opcount, work-precision,
    #              true-error, perf-history, perf-ladder
    title: str
    caption: str
    drawing: Any = None
    not_run: str = ""
    width_px: int = 0   # the drawing's size at the PNG's resolution (the aspect every format
    height_px: int = 0  # keeps)
    _rendered: dict = field(default_factory=dict, repr=False, compare=False)

    def render(self, fmt: str) -> bytes | None:
        """The drawing as ``fmt`` (svg, pdf, png) bytes, rendered once; None without data."""
        if self.drawing is None:
            return None
        if fmt not in self._rendered:
            self._rendered[fmt] = render(self.drawing, fmt)
        return self._rendered[fmt]

    @property
    def svg(self) -> bytes | None:
        return self.render("svg")

    @property
    def pdf(self) -> bytes | None:
        return self.render("pdf")

    @property
    def png(self) -> bytes | None:
        return self.render("png")


@dataclass
class Section:
    id: str
    title: str
    intro: list[str] = field(default_factory=list)
    items: list[Table | Figure] = field(default_factory=list)


@dataclass
class Headline:
    """One number a reader wants first: a label, the value, and what it is compared with."""

    label: str
    value: str
    detail: str
    kind: str = INFO


@dataclass
class Report:
    title: str
    subtitle: str
    generated: str
    headline: list[Headline]
    sections: list[Section]
    footer: str

    def tables(self) -> list[Table]:
        return [i for s in self.sections for i in s.items if isinstance(i, Table)]

    def figures(self) -> list[Figure]:
        return [i for s in self.sections for i in s.items if isinstance(i, Figure)]
