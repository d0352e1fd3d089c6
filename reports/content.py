"""The report's content as plain data: sections of paragraphs, tables and figures.

One model, two renderers: the HTML page (``reports/templates/report.html.j2``) and the PDF
(``reports/pdf.py``) draw the same :class:`Report`, so the two cannot drift apart. Text is plain
(no markup); each renderer escapes it.
"""

from __future__ import annotations

from dataclasses import dataclass, field

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


@dataclass
class Figure:
    """A figure: PNG bytes (None when there is no data: ``not_run`` says how to get it)."""

    id: str
    family: str  # tip-path, tip-speed, drift, conditioning, scaling, opcount, work-precision,
    #              true-error, perf-history, perf-ladder
    title: str
    caption: str
    png: bytes | None = None
    not_run: str = ""
    width_px: int = 0
    height_px: int = 0


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
