"""A page as a reader sees it: load an HTML page (the report, a ``redysim compare`` page) from
file:// in headless Chromium and say what is broken.

:func:`check_page` waits for the page's load, then collects

- every console error and uncaught exception the page raised, and every request that failed
  (a missing file, an HTTP status >= 400; not one the browser cancelled itself, which a PDF in
  an ``<object>`` handed to Chromium's own viewer is, at random);
- every ``<img>`` that did not load (not complete, or ``naturalWidth`` 0), every ``<object>`` /
  ``<embed>`` and every ``<image>`` inside an ``<svg>`` whose target does not load as an image
  (nor, for an object's non-image document, exist as a file);
- every internal link that leads nowhere: ``href="#id"`` without an element of that id (or an
  anchor of that name) in the page, and a relative (or file:) link to a file that does not exist
  or, with ``#id``, to an HTML file without that id. Links to other schemes (http, mailto) are
  counted, not followed: the check needs no network;

and keeps a screenshot of the first screen (1280 x 900) in the artefacts folder
(:func:`artefacts_dir`: ``$REDYSIM_ARTIFACTS``, else a temporary folder, said once). Each problem
is one line naming the element (an image by its src, a data URI shortened, and by the id of the
section it is in), so that a failing check says what to fix.

Chromium is the machine's own (``$REDYSIM_CHROMIUM``, else ``chromium`` or
``chromium-browser``, ``google-chrome`` on the PATH), driven by Playwright (the ``test`` extra)
with its ``executable_path``: no browser is downloaded.

    python -m redysim.reports.browser_check reports/out/report.html results/compare/ur5/compare.html
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from html.parser import HTMLParser
from pathlib import Path
from typing import Any
from urllib.parse import unquote, urlsplit
from urllib.request import url2pathname

ARTEFACTS_ENV = "REDYSIM_ARTIFACTS"  # where the screenshots go (outside the checkout)
CHROMIUM_ENV = "REDYSIM_CHROMIUM"  # the browser's executable, when not on the PATH
REQUIRE_ENV = "REDYSIM_REQUIRE_BROWSER"  # "1": a missing browser fails the tests (CI)
CHROMIUM_NAMES = ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable")
VIEWPORT = {"width": 1280, "height": 900}  # the first screen the screenshot keeps
LOAD_TIMEOUT_MS = 60_000  # the page's load event (a report with its figures inline: ~1 s)
RESOURCE_WAIT_MS = 10_000  # an image still loading after the page's load (lazy ones)
IMAGE_SUFFIXES = {".png", ".jpg", ".jpeg", ".gif", ".svg", ".webp", ".bmp", ".ico", ".avif"}
OTHER_SCHEMES = {"http", "https", "mailto", "tel", "ftp", "javascript", "data", "blob"}
ABORTED = "net::ERR_ABORTED"  # a request the browser cancelled (not a missing file)
BROWSER_OWN = ("chrome-extension:", "chrome:", "devtools:")  # the browser's own pages
SRC_CHARS = 80  # of a src or href in a problem's line (a data URI is megabytes)

# Run in the page after its load: wait for the images still loading (lazy ones made eager),
# probe the objects' and the SVG images' targets as images, and list every link and id.
_INSPECT = """
async (waitMs) => {
  const settle = (img) => new Promise((done) => {
    if (img.complete) { done(); return; }
    img.addEventListener('load', done, {once: true});
    img.addEventListener('error', done, {once: true});
  });
  const probe = (url) => new Promise((done) => {
    if (!url) { done(false); return; }
    const img = new Image();
    img.onload = () => done(img.naturalWidth > 0);
    img.onerror = () => done(false);
    img.src = url;
  });
  const within = (promise, fallback) => Promise.race(
    [promise, new Promise((done) => setTimeout(() => done(fallback), waitMs))]);
  const where = (el) => {
    const holder = el.parentElement ? el.parentElement.closest('[id]') : null;
    return holder ? '#' + holder.id : '';
  };
  const images = Array.from(document.images);
  for (const img of images) { if (img.loading === 'lazy') img.loading = 'eager'; }
  await within(Promise.all(images.map(settle)), null);
  const out = {images: [], embedded: [], links: [], ids: []};
  for (const img of images) {
    out.images.push({kind: 'image', src: img.getAttribute('src') || '',
                     url: img.currentSrc || img.src, alt: img.getAttribute('alt') || '',
                     where: where(img), ok: img.complete && img.naturalWidth > 0});
  }
  const embedded = [];
  for (const el of document.querySelectorAll('object, embed')) {
    const attr = el.tagName === 'OBJECT' ? 'data' : 'src';
    const src = el.getAttribute(attr) || '';
    const url = src ? new URL(src, document.baseURI).href : '';
    embedded.push({kind: el.tagName.toLowerCase(), src: src, url: url, alt: '',
                   where: where(el)});
  }
  for (const el of document.querySelectorAll('svg image')) {
    const src = el.getAttribute('href')
      || el.getAttributeNS('http://www.w3.org/1999/xlink', 'href') || '';
    const url = src ? new URL(src, document.baseURI).href : '';
    embedded.push({kind: 'svg image', src: src, url: url, alt: '', where: where(el)});
  }
  const probed = await Promise.all(embedded.map((e) => within(probe(e.url), false)));
  embedded.forEach((e, k) => { e.ok = probed[k]; out.embedded.push(e); });
  for (const a of document.querySelectorAll('a[href], area[href]')) {
    out.links.push({href: a.getAttribute('href'), url: a.href,
                    text: (a.textContent || '').trim().slice(0, 60), where: where(a)});
  }
  for (const el of document.querySelectorAll('[id]')) out.ids.push(el.id);
  for (const el of document.querySelectorAll('a[name]')) out.ids.push(el.getAttribute('name'));
  return out;
}
"""


@dataclass
class PageCheck:
    """What :func:`check_page` found on one page: ``problems`` empty is a clean page."""

    page: Path
    problems: list[str] = field(default_factory=list)
    screenshot: Path | None = None
    images: int = 0  # <img>, <object>, <embed> and SVG <image> elements checked
    links: int = 0  # internal links checked (#id, relative and file: ones)
    external: int = 0  # links to other schemes (http, mailto...): counted, not followed

    @property
    def ok(self) -> bool:
        return not self.problems

    def summary(self) -> str:
        head = (f"{self.page}: {self.images} images, {self.links} internal links "
                f"({self.external} external not followed)")
        shot = f"; first screen: {self.screenshot}" if self.screenshot else ""
        if self.ok:
            return f"{head}: ok{shot}"
        return (f"{head}: {len(self.problems)} problems{shot}\n"
                + "\n".join(f"  {p}" for p in self.problems))


def find_chromium() -> str | None:
    """The Chromium to drive: ``$REDYSIM_CHROMIUM`` (which must then exist), else the first of
    CHROMIUM_NAMES on the PATH, else None."""
    named = os.environ.get(CHROMIUM_ENV)
    if named:
        path = shutil.which(named)
        if path is None:
            raise FileNotFoundError(f"${CHROMIUM_ENV} = {named!r}: no such executable")
        return path
    for name in CHROMIUM_NAMES:
        path = shutil.which(name)
        if path:
            return path
    return None


def unavailable() -> str | None:
    """Why no page can be checked here (no Playwright, no Chromium), or None when one can."""
    try:
        import playwright.sync_api  # noqa: F401
    except ImportError:
        return ("the Python package 'playwright' is not installed (the 'test' extra: "
                "pip install -e '.[test]')")
    try:
        found = find_chromium()
    except FileNotFoundError as exc:
        return str(exc)
    if found is None:
        return (f"no Chromium on the PATH (looked for {', '.join(CHROMIUM_NAMES)}; set "
                f"${CHROMIUM_ENV} to its executable, or apt-get install chromium)")
    return None


_temporary: Path | None = None  # the default folder, made once per process
_used: list[Path] = []  # the folders screenshots went to through artefacts_dir()


def artefacts_dir(say=None) -> Path:
    """The folder the screenshots go to: ``$REDYSIM_ARTIFACTS`` (made if missing), else one
    temporary folder per process, named once through ``say`` (default: stderr)."""
    global _temporary
    named = os.environ.get(ARTEFACTS_ENV)
    if named:
        path = Path(named).expanduser().resolve()
        if path.exists() and not path.is_dir():
            raise NotADirectoryError(f"${ARTEFACTS_ENV} = {named!r} is a file where a folder "
                                     "goes (the browser check's screenshots)")
        path.mkdir(parents=True, exist_ok=True)
        return path
    if _temporary is None or not _temporary.is_dir():
        _temporary = Path(tempfile.mkdtemp(prefix="redysim-artifacts-"))
        (say or (lambda m: print(m, file=sys.stderr)))(
            f"browser check: screenshots in {_temporary} (set ${ARTEFACTS_ENV} to choose)")
    return _temporary


def artefacts_used() -> list[Path]:
    """The folders this process kept first screens in through :func:`artefacts_dir` (for a
    closing line: where to look)."""
    return list(_used)


@contextmanager
def chromium(executable: str | None = None) -> Iterator[Any]:
    """A headless Chromium (Playwright's Browser) on the machine's own executable, closed on
    exit. Raises RuntimeError saying why when there is none (:func:`unavailable`)."""
    if executable is None:
        why = unavailable()
        if why:
            raise RuntimeError(f"browser check: {why}")
        executable = find_chromium()
    from playwright.sync_api import sync_playwright

    with sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=executable, headless=True)
        try:
            yield browser
        finally:
            browser.close()


def _short(text: str) -> str:
    if text.startswith("data:"):
        return f"{text[:32]}... ({len(text)} characters)"
    if len(text) <= SRC_CHARS:
        return text
    head = SRC_CHARS // 4  # a long path or URL: its start and its end (the file's name)
    return text[:head] + "..." + text[-(SRC_CHARS - head - 3):]


class _Ids(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.ids: set[str] = set()

    def handle_starttag(self, tag, attrs) -> None:
        for key, value in attrs:
            if value and (key == "id" or (tag == "a" and key == "name")):
                self.ids.add(value)


def _ids_of(path: Path) -> set[str]:
    parser = _Ids()
    parser.feed(path.read_text(encoding="utf-8", errors="replace"))
    return parser.ids


def _link_problem(link: dict, page: Path, ids: set[str]) -> str | None:
    """Why the internal link ``link`` (href as written, url as resolved) leads nowhere."""
    href, url = link["href"], link["url"]
    said = f"link {_short(href)!r}" + (f" ({link['text']!r})" if link["text"] else "")
    if link["where"]:
        said += f" in {link['where']}"
    if href.startswith("#"):
        frag = unquote(href[1:])
        if frag in ("", "top") or frag in ids:  # '#' and '#top' are the page's top (HTML)
            return None
        return f"dead {said}: no element with id {frag!r} in the page"
    parts = urlsplit(url)
    target = Path(url2pathname(parts.path))  # (which undoes the URL's %-escapes)
    if not target.exists():
        return f"dead {said}: no file {target}"
    frag = unquote(parts.fragment)
    if not frag or frag == "top":
        return None
    if target.resolve() == page:
        there = ids
    elif target.is_file() and target.suffix.lower() in (".html", ".htm"):
        there = _ids_of(target)
    else:
        return None
    return None if frag in there else f"dead {said}: no element with id {frag!r} in {target}"


def check_page(page: Path | str, *, browser=None, name: str | None = None,
               artefacts: Path | None = None) -> PageCheck:
    """Load ``page`` from file:// in headless Chromium and check it (module docstring); its
    first screen goes to ``artefacts / (name or the page's stem).png``. ``browser``: one from
    :func:`chromium`, shared by several checks (else one is started for this page)."""
    page = Path(page).resolve()
    if not page.is_file():
        raise FileNotFoundError(f"browser check: no page {page}")
    if browser is None:
        with chromium() as started:
            return check_page(page, browser=started, name=name, artefacts=artefacts)
    result = PageCheck(page)
    said: list[str] = []  # in the order they happened
    context = browser.new_context(viewport=VIEWPORT)
    try:
        tab = context.new_page()

        def on_console(msg) -> None:
            if msg.type == "error":
                loc = msg.location or {}
                at = f" ({_short(loc['url'])}:{loc.get('lineNumber', 0) + 1})" if loc.get(
                    "url") else ""
                said.append(f"console error: {msg.text}{at}")

        def on_failed(request) -> None:
            # a request the browser cancelled itself is no missing file: an <object>'s PDF
            # handed to Chromium's own viewer (an extension's page) is aborted, at random
            if request.failure == ABORTED or request.url.startswith(BROWSER_OWN):
                return
            said.append(f"failed request: {_short(request.url)} ({request.failure})")

        def on_response(response) -> None:
            if response.status >= 400:
                said.append(f"failed request: {_short(response.url)} (HTTP {response.status})")

        tab.on("console", on_console)
        tab.on("pageerror", lambda exc: said.append(f"uncaught exception: {exc}"))
        tab.on("requestfailed", on_failed)
        tab.on("response", on_response)
        tab.goto(page.as_uri(), wait_until="load", timeout=LOAD_TIMEOUT_MS)
        found = tab.evaluate(_INSPECT, RESOURCE_WAIT_MS)
        shots = artefacts if artefacts is not None else artefacts_dir()
        shots.mkdir(parents=True, exist_ok=True)
        if artefacts is None and shots not in _used:
            _used.append(shots)
        result.screenshot = shots / f"{name or page.stem}.png"
        tab.screenshot(path=str(result.screenshot), full_page=False)
    finally:
        context.close()
    for el in found["images"] + found["embedded"]:
        result.images += 1
        if el["ok"]:
            continue
        if el["kind"] in ("object", "embed") and el["url"].startswith("file:"):
            target = Path(url2pathname(urlsplit(el["url"]).path))
            if target.is_file() and target.suffix.lower() not in IMAGE_SUFFIXES:
                continue  # a document (PDF, HTML) that is there: not an image to probe
        alt = f" (alt {_short(el['alt'])!r})" if el["alt"] else ""
        inside = f" in {el['where']}" if el["where"] else ""
        what = "image" if el["kind"] == "image" else el["kind"]
        src = _short(el["src"]) if el["src"] else "(no source)"
        result.problems.append(f"{what} {src!r}{alt}{inside} did not load")
    ids = set(found["ids"])
    for link in found["links"]:
        scheme = urlsplit(link["url"]).scheme.lower()
        if scheme in OTHER_SCHEMES and not link["href"].startswith("#"):
            result.external += 1
            continue
        result.links += 1
        problem = _link_problem(link, page, ids)
        if problem:
            result.problems.append(problem)
    result.problems.extend(said)
    return result


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("pages", nargs="+", type=Path, help="HTML files to check")
    ap.add_argument("--artefacts", type=Path, default=None,
                    help=f"where the screenshots go (default ${ARTEFACTS_ENV}, else a "
                         "temporary folder)")
    args = ap.parse_args(argv)
    why = unavailable()
    if why:
        print(f"browser check: {why}", file=sys.stderr)
        return 2
    bad = 0
    with chromium() as browser:
        for page in args.pages:
            result = check_page(page, browser=browser, artefacts=args.artefacts)
            print(result.summary())
            bad += not result.ok
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
