"""The report as PDF (reportlab, pure Python): the same
:class:`~redysim.reports.content.Report` as the HTML page, on landscape A4 so the wide tables
fit. Figures are vector: reportlab lays out a frame of each figure's size, and each figure's
own one-page PDF (matplotlib's) is then drawn into its frame by pypdf. The outline (bookmarks)
lists the sections and, under each, its tables and figures."""

from __future__ import annotations

import io
import itertools
from pathlib import Path
from xml.sax.saxutils import escape

from reportlab.lib import colors
from reportlab.lib.enums import TA_LEFT
from reportlab.lib.pagesizes import A4, landscape
from reportlab.lib.styles import ParagraphStyle, getSampleStyleSheet
from reportlab.lib.units import mm
from reportlab.pdfbase.pdfmetrics import stringWidth
from reportlab.platypus import (
    CondPageBreak,
    Flowable,
    KeepTogether,
    PageBreak,
    Paragraph,
    SimpleDocTemplate,
    Spacer,
    TableStyle,
)
from reportlab.platypus import Table as RLTable

from redysim.harness.store import TEMP_PREFIX, TEMP_SUFFIX, check_kinds

from .content import DIFFER, MATCH, NOT_RUN, PARTIAL, Figure, Headline, Report, Table

PAGE = landscape(A4)
MARGIN = 12 * mm
WIDTH = PAGE[0] - 2 * MARGIN
MAX_FIGURE_H = PAGE[1] - 2 * MARGIN - 30 * mm
KIND_COLOURS = {MATCH: colors.HexColor("#e3f4e1"), DIFFER: colors.HexColor("#fbe2df"),
                PARTIAL: colors.HexColor("#fff3d6"), NOT_RUN: colors.HexColor("#eeeeee")}
HEADER_BG = colors.HexColor("#f1f3f6")
RULE = colors.HexColor("#d5d9e0")
MIN_COL_CHARS = 4     # column widths follow the longest cell, within these bounds
MAX_COL_CHARS = 60
MAX_WORD_CHARS = 14   # a column is at least as wide as its longest word, up to this
HEADER_SHARE = 0.6    # a header may wrap: it counts for this fraction of its length
CHAR_PT = 3.8         # average width of a character of the cell font [pt]
CELL_PADDING = 6.0    # left + right padding of a cell [pt]
HEADLINE_COLUMNS = 3

_base = getSampleStyleSheet()
STYLES = {
    "title": ParagraphStyle("title", parent=_base["Title"], fontSize=20, alignment=TA_LEFT,
                            spaceAfter=2),
    "subtitle": ParagraphStyle("subtitle", parent=_base["Normal"], fontSize=9.5,
                               textColor=colors.HexColor("#5b6475")),
    "h2": ParagraphStyle("h2", parent=_base["Heading2"], fontSize=14, spaceBefore=6,
                         spaceAfter=4),
    "h3": ParagraphStyle("h3", parent=_base["Heading3"], fontSize=10.5, spaceBefore=8,
                         spaceAfter=3),
    "body": ParagraphStyle("body", parent=_base["Normal"], fontSize=8.5, leading=11),
    "cell": ParagraphStyle("cell", parent=_base["Normal"], fontSize=6.8, leading=8.2),
    "head": ParagraphStyle("head", parent=_base["Normal"], fontSize=6.8, leading=8.2,
                           fontName="Helvetica-Bold"),
    "note": ParagraphStyle("note", parent=_base["Normal"], fontSize=7, leading=9,
                           textColor=colors.HexColor("#5b6475"), leftIndent=8,
                           bulletIndent=0),
    "prov": ParagraphStyle("prov", parent=_base["Normal"], fontSize=6, leading=7.5,
                           fontName="Courier", textColor=colors.HexColor("#5b6475")),
    "card_label": ParagraphStyle("card_label", parent=_base["Normal"], fontSize=6.8,
                                 textColor=colors.HexColor("#5b6475")),
    "card_value": ParagraphStyle("card_value", parent=_base["Normal"], fontSize=11,
                                 leading=13, fontName="Helvetica-Bold"),
}


def P(text: str, style: str = "body") -> Paragraph:
    return Paragraph(escape(str(text)), STYLES[style])


def _min_width(table: Table, j: int) -> float:
    """The narrowest column ``j`` may be [pt]: its longest word (header in bold, cells in the
    cell font) as the PDF draws it, so that no word is split (up to MAX_WORD_CHARS' worth)."""
    head, cell = STYLES["head"], STYLES["cell"]
    words = [stringWidth(w, head.fontName, head.fontSize) for w in table.columns[j].split()]
    words += [stringWidth(w, cell.fontName, cell.fontSize)
              for r in table.rows if j < len(r.cells) for w in r.cells[j].split()]
    cap = MAX_WORD_CHARS * CHAR_PT * 1.5
    return min(max(words, default=0.0), cap) + CELL_PADDING + 1.0


def _col_widths(table: Table) -> list[float]:
    """Column widths [pt]: each column's natural width (its longest cell, within bounds, and at
    least its longest word), narrow columns first; what is left is shared by the wide ones; a
    column narrower than its longest word then takes that from the widest."""
    natural, least = [], []
    for j, head in enumerate(table.columns):
        cells = [r.cells[j] for r in table.rows if j < len(r.cells)]
        longest = max([len(c) for c in cells] + [len(head) * HEADER_SHARE])
        chars = max(min(longest, MAX_COL_CHARS), MIN_COL_CHARS)
        least.append(_min_width(table, j))
        natural.append(max(chars * CHAR_PT + CELL_PADDING, least[-1]))
    widths, remaining, budget = list(natural), set(range(len(natural))), WIDTH
    while remaining:  # water-filling: a column narrower than its share keeps its width
        share = budget / len(remaining)
        narrow = {j for j in remaining if natural[j] <= share}
        if not narrow:
            for j in remaining:
                widths[j] = share
            break
        budget -= sum(natural[j] for j in narrow)
        remaining -= narrow
    short = {j: least[j] - widths[j] for j in range(len(widths)) if widths[j] < least[j]}
    if short:  # the shared columns give the words what they need, each down to its own least
        spare = {j: widths[j] - least[j] for j in range(len(widths)) if j not in short}
        room = sum(spare.values())
        take = min(sum(short.values()), room)
        for j, extra in spare.items():
            widths[j] -= take * extra / room if room > 0 else 0.0
        for j, need in short.items():
            widths[j] += need * take / sum(short.values())
    scale = WIDTH / sum(widths)
    return [w * scale for w in widths] if scale > 1 else widths


def table_flowables(t: Table) -> list:
    out = [heading(t.title, "h3", 1)]
    if t.not_run and not t.rows:
        out.append(P(t.not_run, "note"))
    else:
        data = [[P(c, "head") for c in t.columns]]
        data += [[P(c, "cell") for c in r.cells] for r in t.rows]
        style = [("GRID", (0, 0), (-1, -1), 0.25, RULE), ("BACKGROUND", (0, 0), (-1, 0), HEADER_BG),
                 ("VALIGN", (0, 0), (-1, -1), "TOP"),
                 ("LEFTPADDING", (0, 0), (-1, -1), 2.5), ("RIGHTPADDING", (0, 0), (-1, -1), 2.5),
                 ("TOPPADDING", (0, 0), (-1, -1), 1.5), ("BOTTOMPADDING", (0, 0), (-1, -1), 1.5)]
        verdict_col = len(t.columns) - 1 if t.columns[-1] == "verdict" else None
        for i, r in enumerate(t.rows, start=1):
            colour = KIND_COLOURS.get(r.kind)
            if colour is None:
                continue
            first = verdict_col if verdict_col is not None and r.kind != NOT_RUN else 0
            style.append(("BACKGROUND", (first, i), (-1, i), colour))
        rl = RLTable(data, colWidths=_col_widths(t), repeatRows=1)
        rl.setStyle(TableStyle(style))
        out.append(rl)
    out += [Paragraph(escape(n), STYLES["note"], bulletText="-") for n in t.notes]
    if t.provenance:
        out.append(P(t.provenance, "prov"))
    return out


class FigureFrame(Flowable):
    """The place of a figure: its size on the page; where it was drawn is recorded in
    ``placed`` (page, x, y, width, height, the figure), for :func:`_draw_figures`."""

    def __init__(self, figure: Figure, width: float, height: float, placed: list):
        super().__init__()
        self.figure, self.width, self.height, self.placed = figure, width, height, placed

    def wrap(self, availWidth, availHeight):  # noqa: N803 -- reportlab's names
        return self.width, self.height

    def draw(self):
        pass

    def drawOn(self, canvas, x, y, _sW=0):  # noqa: N802, N803 -- reportlab's names
        self.placed.append((canvas.getPageNumber(), x, y, self.width, self.height,
                            self.figure))


def figure_flowables(f: Figure, placed: list | None = None) -> list:
    head = [heading(f.title, "h3", 1)]
    if f.drawing is None:
        return [KeepTogether(head + [P(f"{f.not_run}. {f.caption}", "note")])]
    w, h = float(f.width_px), float(f.height_px)
    scale = min(WIDTH / w, MAX_FIGURE_H / h)
    frame = FigureFrame(f, w * scale, h * scale, placed if placed is not None else [])
    return [KeepTogether(head + [frame, P(f.caption, "note")])]


def heading(text: str, style: str, level: int) -> Paragraph:
    """A heading that is an entry of the PDF's outline at ``level`` (0: a section)."""
    para = P(text, style)
    para.outline = (level, str(text))  # type: ignore[attr-defined]
    return para


class _Outlined(SimpleDocTemplate):
    """Adds every :func:`heading` to the outline where it is drawn."""

    _keys = itertools.count()

    def afterFlowable(self, flowable):  # noqa: N802 -- reportlab's name
        entry = getattr(flowable, "outline", None)
        if entry is None:
            return
        level, text = entry
        key = f"h{next(self._keys)}"
        self.canv.bookmarkPage(key)
        self.canv.addOutlineEntry(text, key, level=level, closed=level > 0)


def _draw_figures(path: Path, placed: list) -> None:
    """Draw each figure's own vector PDF into the frame laid out for it (pypdf)."""
    from pypdf import PdfReader, PdfWriter, Transformation

    writer = PdfWriter(clone_from=PdfReader(io.BytesIO(path.read_bytes())))
    for page, x, y, w, h, figure in placed:
        src = PdfReader(io.BytesIO(figure.pdf)).pages[0]
        sw, sh = float(src.mediabox.width), float(src.mediabox.height)
        writer.pages[page - 1].merge_transformed_page(
            src, Transformation().scale(w / sw, h / sh).translate(x, y))
    writer.page_mode = "/UseOutlines"
    with open(path, "wb") as fh:
        writer.write(fh)


def headline_flowable(items: list[Headline]) -> RLTable:
    cells = []
    for h in items:
        cells.append([P(h.label.upper(), "card_label"), P(h.value, "card_value"),
                      P(h.detail, "cell")])
    rows = [cells[i:i + HEADLINE_COLUMNS] for i in range(0, len(cells), HEADLINE_COLUMNS)]
    rows[-1] += [""] * (HEADLINE_COLUMNS - len(rows[-1]))
    t = RLTable(rows, colWidths=[WIDTH / HEADLINE_COLUMNS] * HEADLINE_COLUMNS)
    style = [("BOX", (0, 0), (-1, -1), 0.25, RULE), ("INNERGRID", (0, 0), (-1, -1), 0.25, RULE),
             ("VALIGN", (0, 0), (-1, -1), "TOP")]
    for k, h in enumerate(items):
        colour = KIND_COLOURS.get(h.kind)
        if colour is not None:
            r, c = divmod(k, HEADLINE_COLUMNS)
            style.append(("BACKGROUND", (c, r), (c, r), colour))
    t.setStyle(TableStyle(style))
    return t


def _page_footer(text: str):
    def draw(canvas, doc):
        canvas.saveState()
        canvas.setFont("Courier", 5.5)
        canvas.setFillColor(colors.HexColor("#5b6475"))
        canvas.drawString(MARGIN, 6 * mm, text[:230])
        canvas.drawRightString(PAGE[0] - MARGIN, 6 * mm, f"page {doc.page}")
        canvas.restoreState()
    return draw


def write_pdf(report: Report, path: str | Path) -> Path:
    """Render ``report`` to ``path`` (written to a temporary file, then renamed)."""
    path = Path(path)
    check_kinds(files=[path], folders=[path.parent], why="the page was not written")
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f"{TEMP_PREFIX}{path.name}{TEMP_SUFFIX}")
    story: list = [P(report.title, "title"), P(report.subtitle, "subtitle"),
                   P(f"Generated {report.generated}", "subtitle"), Spacer(1, 4 * mm)]
    placed: list = []  # the figures' frames, where reportlab put them
    if report.headline:  # (a comparison where no run met a tolerance has none)
        story += [heading("Headline", "h2", 0), headline_flowable(report.headline)]
    for s in report.sections:
        story += [PageBreak(), heading(s.title, "h2", 0)]
        story += [P(p) for p in s.intro]
        for item in s.items:
            if isinstance(item, Table):
                story += [CondPageBreak(40 * mm), *table_flowables(item)]
            else:
                story += figure_flowables(item, placed)
    doc = _Outlined(str(tmp), pagesize=PAGE, leftMargin=MARGIN, rightMargin=MARGIN,
                            topMargin=MARGIN, bottomMargin=MARGIN + 3 * mm,
                            title=report.title, author="redysim")
    footer = _page_footer(report.footer)
    try:
        doc.build(story, onFirstPage=footer, onLaterPages=footer)
        _draw_figures(tmp, placed)
        tmp.replace(path)
    finally:
        tmp.unlink(missing_ok=True)
    return path
