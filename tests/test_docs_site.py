"""The documentation site builds with warnings as errors, and every page renders in a real
browser (Debian's Chromium, headless) with its images and no broken internal link.

The site is built from a copy of docs/ (beside links to examples/ and tests/), so that a
test run writes nothing into the repository.  Skipped, with one line, when the docs extra is
not installed, and when Chromium or its driver is not on PATH (the line says what to
install).  Where the environment sets ``SPARSEKIN_REQUIRE_BROWSER=1`` (.ci/run does, and
installs Chromium), a missing browser fails instead, so that CI always checks the site in a
real browser.
"""

from __future__ import annotations

import functools
import http.server
import os
import shutil
import subprocess
import sys
import threading
import time
from pathlib import Path
from urllib.parse import unquote, urlsplit

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS_EXTRA = 'the docs extra is not installed: pip install -e ".[docs]"'
#: Debian's names of the browser and its driver, looked up on PATH.
BROWSER_PROGRAMS = ("chromium", "chromedriver")
BROWSER_INSTALL = "apt-get install -y chromium chromium-driver (Debian)"
#: Set to 1 (CI does) to fail rather than skip where the browser is missing.
REQUIRE_BROWSER = "SPARSEKIN_REQUIRE_BROWSER"
#: The flags that run Chromium headless on this project's machines (no sandbox as root, no
#: network but loopback).
CHROMIUM_FLAGS = ("--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync")  # fmt: skip
#: Text that a page shows only when a directive or a docstring was not rendered.
UNRENDERED = (
    ".. py:",
    ".. auto",
    ":Parameters:",
    ".. rubric::",
    "```",
    "<!-- sparsekin",
    "{eval-rst}",
    "{toctree}",
)

pytest.importorskip("sphinx", reason=DOCS_EXTRA)
pytest.importorskip("myst_parser", reason=DOCS_EXTRA)
pytest.importorskip("pydata_sphinx_theme", reason=DOCS_EXTRA)
pytest.importorskip("numpydoc", reason=DOCS_EXTRA)
pytest.importorskip("selenium", reason=DOCS_EXTRA)


@pytest.fixture(scope="module")
def site(tmp_path_factory) -> Path:
    """The site, built with warnings as errors; its build time is printed (pytest -s)."""
    work = tmp_path_factory.mktemp("docs")
    shutil.copytree(ROOT / "docs", work / "docs", ignore=shutil.ignore_patterns(
        "_build", "gallery", "generated", "cli.md", "__pycache__"))  # fmt: skip
    for name in ("examples", "tests"):
        (work / name).symlink_to(ROOT / name, target_is_directory=True)
    start = time.perf_counter()
    build = subprocess.run(
        [sys.executable, "-m", "sphinx", "-W", "--keep-going", "-q", "-b", "html", str(work / "docs"),
         str(work / "site")],
        capture_output=True, text=True, timeout=900, check=False,
    )  # fmt: skip
    assert build.returncode == 0, f"the site does not build without warnings:\n{build.stderr}"
    print(f"\nsite built in {time.perf_counter() - start:.1f} s")
    return work / "site"


def find_browser() -> tuple[str, str]:
    """Chromium and chromedriver on PATH; skips (fails where `SPARSEKIN_REQUIRE_BROWSER=1`)
    with one line naming the apt line when either is missing."""
    found = {name: shutil.which(name) for name in BROWSER_PROGRAMS}
    missing = [name for name, path in found.items() if path is None]
    if missing:
        message = f"{', '.join(missing)} not on PATH: {BROWSER_INSTALL}"
        if os.environ.get(REQUIRE_BROWSER) == "1":
            pytest.fail(f"{message} ({REQUIRE_BROWSER}=1)", pytrace=False)
        pytest.skip(message)
    return found["chromium"], found["chromedriver"]


@pytest.fixture(scope="module")
def browser():
    chromium, chromedriver = find_browser()
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for flag in CHROMIUM_FLAGS:
        options.add_argument(flag)
    profile = Path(__import__("tempfile").mkdtemp(prefix="chromium-profile-"))
    options.add_argument(f"--user-data-dir={profile}")
    options.add_argument("--window-size=1280,1000")
    options.set_capability("goog:loggingPrefs", {"browser": "ALL"})
    driver = webdriver.Chrome(service=Service(executable_path=chromedriver), options=options)
    driver.set_page_load_timeout(60)
    yield driver
    driver.quit()
    shutil.rmtree(profile, ignore_errors=True)


@pytest.fixture(scope="module")
def server(site):
    """The site over HTTP on the loopback interface, on a free port."""
    handler = functools.partial(_QuietHandler, directory=str(site))
    httpd = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=httpd.serve_forever, daemon=True)
    thread.start()
    yield f"http://127.0.0.1:{httpd.server_address[1]}"
    httpd.shutdown()
    httpd.server_close()


class _QuietHandler(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *arguments) -> None:
        pass


def site_pages(site: Path) -> list[str]:
    return sorted(path.relative_to(site).as_posix() for path in site.rglob("*.html")
                  if not path.relative_to(site).parts[0].startswith("_"))  # fmt: skip


def test_the_site_has_every_page(site):
    pages = set(site_pages(site))
    sources = {path.relative_to(ROOT / "docs").with_suffix(".html").as_posix()
               for path in (ROOT / "docs").rglob("*.md") if path.parts[-2] not in ("gallery", "generated")}  # fmt: skip
    assert sources <= pages
    examples = {f"gallery/{path.stem}.html" for path in (ROOT / "examples").glob("*.toml")}
    assert examples <= pages and {"reference/cli.html", "gallery/index.html"} <= pages


def test_every_page_renders_with_its_images_and_no_broken_link(browser, site, server):
    from selenium.webdriver.support.ui import WebDriverWait

    ids: dict[str, set[str]] = {}
    links: list[tuple[str, str]] = []
    problems: list[str] = []
    n_images = 0
    for page in site_pages(site):
        browser.get(f"{server}/{page}")
        WebDriverWait(browser, 30).until(
            lambda driver: driver.execute_script("return document.readyState") == "complete"
        )
        WebDriverWait(browser, 30).until(
            lambda driver: driver.execute_script("return Array.from(document.images).every(i => i.complete)")
        )
        state = browser.execute_script("""
            return {
                title: document.title,
                heading: (document.querySelector('main h1') || {}).textContent || '',
                text: (document.querySelector('main') || document.body).innerText,
                broken: Array.from(document.images).filter(i => i.naturalWidth === 0).map(i => i.src),
                images: document.images.length,
                links: Array.from(document.querySelectorAll('a[href]')).map(a => a.href),
                ids: Array.from(document.querySelectorAll('[id]')).map(e => e.id),
            };""")  # fmt: skip
        n_images += state["images"]
        if not state["title"] or (
            page not in ("search.html", "genindex.html") and not state["heading"].strip()
        ):
            problems.append(f"{page}: no title or no heading")
        if len(state["text"]) < 100 and page != "search.html":  # the search page waits for a query
            problems.append(f"{page}: almost no text ({len(state['text'])} characters)")
        problems += [f"{page}: unrendered {marker!r}" for marker in UNRENDERED if marker in state["text"]]
        problems += [f"{page}: image not shown: {src}" for src in state["broken"]]
        errors = [entry["message"] for entry in browser.get_log("browser")
                  if entry["level"] == "SEVERE" and "favicon.ico" not in entry["message"]]  # fmt: skip
        problems += [f"{page}: console error: {message}" for message in errors]
        ids[page] = set(state["ids"])
        links += [(page, link) for link in state["links"]]
    for page, link in links:
        parts = urlsplit(link)
        if f"{parts.scheme}://{parts.netloc}" != server:
            continue  # outside the site: not fetched (no network here)
        path = unquote(parts.path).lstrip("/") or "index.html"
        if path.endswith("/"):
            path += "index.html"
        if not (site / path).is_file():
            problems.append(f"{page}: broken link to {path}")
        elif parts.fragment and path in ids and unquote(parts.fragment) not in ids[path]:
            problems.append(f"{page}: link to a missing anchor {path}#{parts.fragment}")
    assert not problems, "\n".join(problems)
    assert n_images >= 2 * len(
        list((ROOT / "examples").glob("*.toml"))
    )  # each gallery page: drawing and frame
