"""The report and a ``redysim compare`` page, rendered in a real browser: headless Chromium (the
machine's own, driven by Playwright: redysim.reports.browser_check) loads each page from file://
and the check fails on an image that did not load, a console error or a failed request, and an
internal link that leads nowhere; the first screen (1280 x 900) of each real page is kept as a
screenshot in ``$REDYSIM_ARTIFACTS`` (else a temporary folder, named at the end of the run).

The check is shown to catch what it is for: a copy of the report with one figure's src turned to
a missing file, one with a dead ``#anchor``, one with a ``console.error`` injected, each fails
naming what broke; and a small page of every element kind it looks at (img, lazy img, object, SVG
image, #id, relative links with and without #id), good ones passing and broken ones named.

Without Chromium or Playwright the tests skip, saying which is missing; with
``REDYSIM_REQUIRE_BROWSER=1`` (.ci/run sets it) they fail instead. The report's results folder is
made here in a few seconds (a two-run sweep of RE-U125-L1 at 0.02 s with its reference, the
operation counts, the GIM study at 10 links: four figures with images, the rest "not run"), not
test_report.py's larger one; the compare page is UR5-FALL over 0.02 s with one setting per ladder
and MuJoCo as the one engine run (~5 s of CPU).
"""

from __future__ import annotations

import os
import re
import struct
import zlib
from pathlib import Path

import pytest

from redysim.reports import browser_check as bc

REQUIRED = os.environ.get(bc.REQUIRE_ENV) == "1"
FIGURE = re.compile(r"data:image/(?:png|svg\+xml);base64,")  # a figure inlined in a page


@pytest.fixture(scope="module")
def browser():
    why = bc.unavailable()
    if why:
        if REQUIRED:
            pytest.fail(f"{bc.REQUIRE_ENV}=1 (CI) and the browser check cannot run: {why}")
        pytest.skip(f"browser check: {why}")
    with bc.chromium() as started:
        yield started


@pytest.fixture(scope="module")
def report_page(tmp_path_factory) -> Path:
    """The report built from a small results folder made here (module docstring)."""
    from redysim.harness.spec import RunSpec
    from redysim.harness.sweep import run_sweep
    from redysim.reports import gim_study, opcount
    from redysim.reports.build import build_report, render_html
    from redysim.reports.results import Results

    root = tmp_path_factory.mktemp("results")
    mp = pytest.MonkeyPatch()
    mp.setenv("REDYSIM_RESULTS", str(root))  # the reference solution (inherited by the worker)
    try:
        run_sweep([RunSpec(case="RE-U125-L1", t_end=0.02, sample=0.01, integrator="rk4",
                           h=1e-3),
                   RunSpec(case="RE-U125-L1", t_end=0.02, sample=0.01, rtol=1e-6, atol=1e-8)],
                  root / "sweeps" / "tiny", name="tiny", workers=1, progress=False,
                  reference=True)
    finally:
        mp.undo()
    opcount.run(root / "opcount")
    gim_study.run(root / "gim_study", 10)
    page = tmp_path_factory.mktemp("report") / "report.html"
    page.write_text(render_html(build_report(Results(root))), encoding="utf-8")
    return page


def _png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n", f"{path} is not a PNG"
    return struct.unpack(">II", data[16:24])


def _tiny_png(path: Path) -> None:
    """A 2 x 2 RGB PNG, written by hand (signature, IHDR, IDAT, IEND)."""
    def chunk(kind: bytes, body: bytes) -> bytes:
        return (struct.pack(">I", len(body)) + kind + body
                + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF))
    rows = b"".join(b"\x00" + b"\xc8\x41\x2f" * 2 for _ in range(2))
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 2, 2, 8, 2,
                                                                       0, 0, 0))
                     + chunk(b"IDAT", zlib.compress(rows)) + chunk(b"IEND", b""))


def _copy(page: Path, folder: Path, html: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    out = folder / page.name
    out.write_text(html, encoding="utf-8")
    return out


def _clean(result: bc.PageCheck, html: str) -> None:
    """The page passed, and the check looked at every image and internal link the HTML has
    (counted here in its text)."""
    assert result.ok, result.summary()
    assert result.images == html.count("<img ") > 0
    assert result.links == len(re.findall(r'<a href="#', html)) > 0
    assert result.screenshot is not None and result.screenshot.is_file()
    assert _png_size(result.screenshot) == (1280, 900)


# ----------------------------------------------------------------------------- the real pages
def test_the_report_renders_without_a_problem(browser, report_page):
    html = report_page.read_text(encoding="utf-8")
    result = bc.check_page(report_page, browser=browser, name="report-first-screen")
    _clean(result, html)
    assert len(FIGURE.findall(html)) >= 4  # the figures the results folder has
    assert result.screenshot.parent == bc.artefacts_dir()


@pytest.mark.engine
def test_a_compare_page_renders_without_a_problem(browser, tmp_path, monkeypatch):
    pytest.importorskip("mujoco")
    from redysim.reports import compare as cmp

    monkeypatch.setenv("REDYSIM_RESULTS", str(tmp_path / "results"))  # the reference's cache
    for key, value in (("CORE_RTOLS", (1e-7,)), ("ENGINE_RTOLS", (1e-7,)),
                       ("STEP_DIVISIONS", (5,)), ("NATIVE_RTOLS", (1e-6,))):
        monkeypatch.setattr(cmp, key, value)
    page, _ = cmp.compare("UR5-FALL", tmp_path / "cmp", t_end=0.02, workers=1,
                          engines=["mujoco"], progress=False, log=lambda *a: None)
    html = page.read_text(encoding="utf-8")
    result = bc.check_page(page, browser=browser, name="compare-UR5-FALL-first-screen")
    _clean(result, html)
    assert len(FIGURE.findall(html)) == 2  # the path error and work-precision plots


# ------------------------------------------------------- the check fails on what it is for
def test_a_broken_image_fails_the_check_naming_it(browser, report_page, tmp_path):
    html = report_page.read_text(encoding="utf-8")
    broken, n = re.subn(r'src="' + FIGURE.pattern + r'[^"]*"',
                        'src="figures/missing-plot.png"', html, count=1)
    assert n == 1
    result = bc.check_page(_copy(report_page, tmp_path / "broken", broken), browser=browser,
                           artefacts=tmp_path / "shots")
    assert not result.ok
    images = [p for p in result.problems if p.startswith("image ")]
    assert len(images) == 1, result.problems
    assert "'figures/missing-plot.png'" in images[0] and "did not load" in images[0]
    assert re.search(r" in #[\w-]+ did not load", images[0])  # the figure it belongs to
    assert any(p.startswith("failed request:") and "missing-plot.png" in p
               for p in result.problems)


def test_a_dead_anchor_fails_the_check_naming_it(browser, report_page, tmp_path):
    html = report_page.read_text(encoding="utf-8")
    assert '<a href="#figures">' in html
    broken = html.replace('<a href="#figures">', '<a href="#no-such-section">', 1)
    result = bc.check_page(_copy(report_page, tmp_path / "anchor", broken), browser=browser,
                           artefacts=tmp_path / "shots")
    assert len(result.problems) == 1, result.problems
    assert result.problems[0].startswith("dead link '#no-such-section'")
    assert "no element with id 'no-such-section' in the page" in result.problems[0]


def test_a_console_error_fails_the_check_naming_it(browser, report_page, tmp_path):
    html = report_page.read_text(encoding="utf-8")
    broken = html.replace("</body>", "<script>console.error('injected: a broken widget')"
                          "</script>\n</body>", 1)
    result = bc.check_page(_copy(report_page, tmp_path / "console", broken), browser=browser,
                           artefacts=tmp_path / "shots")
    assert len(result.problems) == 1, result.problems
    assert result.problems[0].startswith("console error: injected: a broken widget")


def test_an_uncaught_exception_fails_the_check(browser, tmp_path):
    page = tmp_path / "throws.html"
    page.write_text("<!DOCTYPE html><title>t</title><script>null.f()</script>", encoding="utf-8")
    result = bc.check_page(page, browser=browser, artefacts=tmp_path / "shots")
    assert len(result.problems) == 1 and result.problems[0].startswith("uncaught exception:")


# ------------------------------------------------------------- every element kind it checks
GOOD = """<!DOCTYPE html><html><head><meta charset="utf-8"><title>kinds</title></head><body>
<nav><a href="#one">one</a> <a href="#">top</a> <a href="beside.html">beside</a>
<a href="beside.html#there">there</a> <a href="sub/other.html">other</a>
<a href="kinds.html#two">self</a> <a href="https://example.org/x">far</a>
<a href="mailto:a@b.c">mail</a> <a href="with%20space.html#in">spaced</a></nav>
<section id="one"><img src="dot.png" alt="a dot" width="20" height="20"></section>
<section id="two"><object data="dot.png" type="image/png" width="20" height="20"></object>
<object data="doc.pdf" type="application/pdf" width="20" height="20"></object>
<svg width="20" height="20"><image href="dot.png" width="20" height="20"/></svg>
<a name="old-style">old</a> <a href="#old-style">to old</a></section>
<div style="height: 3000px"></div>
<section id="below"><img src="dot.png" loading="lazy" alt="lazy" width="20" height="20">
</section></body></html>
"""


@pytest.fixture
def kinds(tmp_path) -> Path:
    _tiny_png(tmp_path / "dot.png")
    (tmp_path / "doc.pdf").write_bytes(b"%PDF-1.4\n%%EOF\n")
    (tmp_path / "beside.html").write_text('<p id="there">x</p>', encoding="utf-8")
    (tmp_path / "with space.html").write_text('<p id="in">z</p>', encoding="utf-8")
    (tmp_path / "sub").mkdir()
    (tmp_path / "sub" / "other.html").write_text("<p>y</p>", encoding="utf-8")
    page = tmp_path / "kinds.html"
    page.write_text(GOOD, encoding="utf-8")
    return page


def test_every_kind_of_element_passes_when_it_loads(browser, kinds, tmp_path):
    result = bc.check_page(kinds, browser=browser, artefacts=tmp_path / "shots")
    assert result.ok, result.summary()
    assert (result.images, result.links, result.external) == (5, 8, 2)


@pytest.mark.parametrize("good, bad, said", [
    ('<img src="dot.png" alt="a dot"', '<img src="gone.png" alt="a dot"',
     "image 'gone.png' (alt 'a dot') in #one did not load"),
    ('<img src="dot.png" loading="lazy"', '<img src="gone.png" loading="lazy"',
     "image 'gone.png' (alt 'lazy') in #below did not load"),
    ('<object data="dot.png"', '<object data="gone.png"', "object 'gone.png' in #two did not load"),
    ('<object data="doc.pdf"', '<object data="gone.pdf"', "object 'gone.pdf' in #two did not load"),
    ('<image href="dot.png"', '<image href="gone.png"', "svg image 'gone.png' in #two"),
    ('<a href="beside.html">', '<a href="gone.html">', "dead link 'gone.html' ('beside'): no file"),
    ('"beside.html#there"', '"beside.html#nowhere"',
     "dead link 'beside.html#nowhere' ('there'): no element with id 'nowhere' in "),
    ('"sub/other.html"', '"sub/gone/other.html"', "dead link 'sub/gone/other.html' ('other')"),
    ('"kinds.html#two"', '"kinds.html#three"', "no element with id 'three' in "),
    ('"with%20space.html#in"', '"with%20space.html#out"', "no element with id 'out' in "),
    ('<a href="#old-style">', '<a href="#new-style">',
     "dead link '#new-style' ('to old') in #two: no element with id 'new-style' in the page"),
])
def test_each_broken_element_is_named(browser, kinds, tmp_path, good, bad, said):
    assert GOOD.count(good) == 1
    kinds.write_text(GOOD.replace(good, bad), encoding="utf-8")
    result = bc.check_page(kinds, browser=browser, artefacts=tmp_path / "shots")
    assert any(said in p for p in result.problems), result.problems
    named = [p for p in result.problems if not p.startswith(("failed request:", "console error:"))]
    assert len(named) == 1, result.problems  # the one broken element, nothing else


def test_a_missing_page_is_said_before_any_browser(tmp_path):
    with pytest.raises(FileNotFoundError, match="browser check: no page .*nowhere.html"):
        bc.check_page(tmp_path / "nowhere.html")


def test_the_artefacts_folder_is_the_one_named(tmp_path, monkeypatch):
    monkeypatch.setenv(bc.ARTEFACTS_ENV, str(tmp_path / "made" / "here"))
    assert bc.artefacts_dir() == tmp_path / "made" / "here" and bc.artefacts_dir().is_dir()
    (tmp_path / "a-file").write_text("x")
    monkeypatch.setenv(bc.ARTEFACTS_ENV, str(tmp_path / "a-file"))
    with pytest.raises(NotADirectoryError, match="a-file' is a file where a folder goes"):
        bc.artefacts_dir()


def test_a_named_chromium_that_is_not_there_is_said(monkeypatch):
    """Why the browser tests skip (or, under CI, fail): the named executable, by name."""
    pytest.importorskip("playwright")  # else that is what is said first
    monkeypatch.setenv(bc.CHROMIUM_ENV, "/nonexistent/chromium")
    assert bc.unavailable() == "$REDYSIM_CHROMIUM = '/nonexistent/chromium': no such executable"
    with pytest.raises(RuntimeError, match="browser check: .*no such executable"):
        with bc.chromium():
            pass
