"""An evening in a real browser (issue 34): Debian's Chromium driven by Playwright opens
the URL `galileo-cnc serve` printed, uploads a board, sees its preview, starts, puts a
pen in, stops with the stop button, resumes, jogs and reads the position back, and
finishes; then a second job. On sim:// and on our firmware in simavr.

Outside CI the evenings skip, naming what is missing (Chromium, Playwright); in CI
they must run. GALILEO_SCREENSHOTS=DIR saves the page at phone and desktop width (the
README's pictures).
"""

from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import threading
from contextlib import contextmanager
from pathlib import Path

import pytest

from firmware_support import ELF, build_firmware, build_harness
from serve_support import board_zip

CHROMIUM = Path("/usr/bin/chromium")
REPO = Path(__file__).resolve().parents[2]
#: a short drawing for the second job (G-code: one pen, no pen change)
SECOND_JOB = "G21 G90\nG0 X1 Y1\nG1 X2 Y1 F300\nM2\n"
WAIT_MS = 60_000


def _playwright():
    missing = [] if CHROMIUM.exists() else [f"{CHROMIUM} (apt-get install chromium)"]
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        missing.append("playwright (pip install playwright; its browser download is not "
                       "needed)")
        sync_playwright = None
    if missing:
        message = f"the browser evening needs {' and '.join(missing)}"
        if os.environ.get("CI"):
            pytest.fail(message)
        pytest.skip(message)
    return sync_playwright


@pytest.fixture(scope="module")
def chromium():
    """One browser for the evenings (each has a fresh context: no cookie shared)."""
    sync_playwright = _playwright()
    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=str(CHROMIUM))
        yield browser
        browser.close()


@contextmanager
def served_in_a_browser(browser, port: str, home: Path):
    """`galileo-cnc serve` as a user starts it, and a page of a fresh browser context;
    yields (the page, the URL serve printed)."""
    env = {**os.environ, "GALILEO_CNC_HOME": str(home), "PYTHONPATH": str(REPO),
           "GALILEO_CNC_NO_PROBE": "1", "PYTHONFAULTHANDLER": "1"}
    process = subprocess.Popen([sys.executable, "-m", "galileo_cnc", "serve", "--port", port,
                                "--listen", "127.0.0.1:0"], env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True)
    printed: list[str] = []
    try:
        context = browser.new_context(viewport={"width": 1100, "height": 900})
        try:
            page = context.new_page()
            page.set_default_timeout(WAIT_MS)
            url = _printed_url(process, printed)
            # serve's output is read on to its end: a full pipe would stop the server
            reader = threading.Thread(target=printed.extend, args=(process.stdout,),
                                      daemon=True)
            reader.start()
            try:
                yield page, url
            except Exception as failure:
                seen = _page_text(page)
                process.send_signal(signal.SIGABRT)     # faulthandler: every thread's stack
                try:
                    process.wait(10)
                except subprocess.TimeoutExpired:
                    pass                                # the finally below ends it
                reader.join(10)
                raise AssertionError(f"{failure}\n--- the page said ---\n{seen}\n--- serve "
                                     f"printed, and its threads when the wait failed ---\n"
                                     f"{''.join(printed)}") from failure
        finally:
            context.close()
    finally:
        process.terminate()
        process.wait(10)


def _printed_url(process, printed: list[str]) -> str:
    for line in process.stdout:
        printed.append(line)
        if (found := re.search(r"http://127\.0\.0\.1:\d+/\?token=\S+", line)):
            return found.group(0)
    raise AssertionError("serve printed no URL:\n" + "".join(printed))


def _page_text(page) -> str:
    try:
        return page.inner_text("body", timeout=5_000)
    except Exception as problem:        # the page itself may be what failed
        return f"(could not be read: {problem})"


def tiny_board(folder: Path) -> Path:
    """A one-sided board of three features close to the origin, an aperture each (so
    three pens in centre mode): few moves for the firmware in simavr, in real time."""
    folder.mkdir()
    header = "%FSLAX46Y46*%\n%MOMM*%\n%LPD*%\n"
    (folder / "tiny-F_Cu.gbr").write_text(
        f"%TF.FileFunction,Copper,L1,Top*%\n{header}%ADD10C,0.600000*%\n"
        "%ADD11C,0.250000*%\n%ADD12R,0.800000X0.800000*%\nD10*\nX1000000Y1000000D03*\n"
        "D11*\nX1000000Y1000000D02*\nX2000000Y1000000D01*\nD12*\nX2000000Y2000000D03*\n"
        "M02*\n")
    (folder / "tiny-Edge_Cuts.gbr").write_text(
        f"%TF.FileFunction,Profile,NP*%\n{header}%ADD13C,0.100000*%\nD13*\nX0Y0D02*\n"
        "X3000000Y0D01*\nX3000000Y3000000D01*\nX0Y3000000D01*\nX0Y0D01*\nM02*\n")
    return Path(shutil.make_archive(str(folder), "zip", folder))


def _position(page) -> list[float]:
    data = page.locator("#position")
    return [float(data.get_attribute(f"data-{a}")) for a in "xyz"]


def _standing(page) -> list[float]:
    """The position once the head stands (the page hears it every quarter second)."""
    seen = _position(page)
    while True:
        page.wait_for_timeout(300)            # more than a poll (0.25 s)
        if (now := _position(page)) == seen:
            return now
        seen = now


def _answer_pen(page) -> str:
    page.wait_for_selector("#prompt[open]")
    text = page.inner_text("#prompt-text")
    page.click("#prompt-yes")
    page.wait_for_function(f"() => !document.querySelector('#prompt').open || "
                           f"document.querySelector('#prompt-text').textContent !== "
                           f"{text!r}")
    return text


def _finish(page, results: int) -> None:
    """Answer pen changes until the history has `results` rows that ended."""
    while True:
        page.wait_for_function(
            f"() => document.querySelector('#prompt').open || "
            f"[...document.querySelectorAll('#history tr td:nth-child(4)')]"
            f".filter(td => td.textContent !== 'running').length >= {results}")
        if not page.locator("#prompt[open]").count():
            return
        _answer_pen(page)


def an_evening(page, url: str, board: Path, sides: str, screenshots: Path | None = None,
               second_tab: bool = True) -> None:
    """`second_tab`: a jog held in a second tab ends when the tab is closed (once is
    enough: it is the same page on either machine)."""
    page.goto(url)
    assert "token=" not in page.url                     # kept in the cookie instead
    page.wait_for_function("() => document.querySelector('#state').textContent === 'idle'")
    page.set_input_files("#upload", str(board))
    page.wait_for_function(f"() => /board, sides {sides}$/"
                           f".test(document.querySelector('#upload-info').textContent)")
    page.select_option("#mode", "centre")
    page.click("#plan")
    page.wait_for_selector("#preview svg #head")         # the preview, the head on it
    assert page.locator("#preview svg #strokes").count() == 1
    assert "top side" in page.inner_text("#plan-lines") or sides == "top"
    page.click("#start")
    if screenshots is not None:                         # the job, its first pen asked for
        page.wait_for_selector("#prompt[open]")
        _screenshots(page, screenshots)
    first = _answer_pen(page)                           # a pen change, answered
    assert first.startswith("insert ")
    page.wait_for_selector("#prompt[open]")             # the next pen: stop here
    page.click("#stop")
    page.wait_for_function("() => !document.querySelector('#resume').disabled")
    assert "stopped" in page.inner_text("#history")
    page.click("#resume")
    _finish(page, results=2)
    rows = page.locator("#history tr").all_inner_texts()
    assert "finished" in rows[0] and "stopped" in rows[1], rows
    # a jog of a step, read back on the page and from the machine
    page.wait_for_function("() => !document.querySelector('#home').disabled")
    before = _standing(page)
    page.select_option("#step", "1")
    page.click("button.jog[data-axis='x'][data-dir='1']")
    page.wait_for_function(f"() => Math.abs(Number(document.querySelector('#position')"
                           f".dataset.x) - {before[0] + 1}) < 0.01")
    machine = page.request.get(url.split("?")[0] + "api/state").json()["position"]
    assert machine[0] == pytest.approx(before[0] + 1, abs=0.01)
    assert machine[1] == pytest.approx(before[1], abs=0.01)
    # held: Y moves while the button is down and stops when it is let go (once the
    # step has ended: the head may stand at its end while the step still waits it out)
    page.wait_for_function("() => document.querySelector('#activity').textContent === ''")
    page.select_option("#step", "")
    page.hover("button.jog[data-axis='y'][data-dir='1']")
    page.mouse.down()
    page.wait_for_function(f"() => Number(document.querySelector('#position').dataset.y)"
                           f" > {before[1] + 0.05}")
    page.mouse.up()
    page.wait_for_function("() => document.querySelector('#activity').textContent === ''")
    held = _standing(page)
    assert page.request.get(url.split("?")[0] + "api/state").json()["position"] == held
    assert held[1] > before[1] + 0.05 and held[0] == pytest.approx(before[0] + 1, abs=0.01)
    if second_tab:
        _jog_in_a_closed_tab(page, url, held)
    # the second job: another file
    second = board.parent / "second.nc"
    second.write_text(SECOND_JOB)
    page.set_input_files("#upload", str(second))
    page.wait_for_function("() => /second.nc: gcode/"
                           ".test(document.querySelector('#upload-info').textContent)")
    page.click("#plan")
    page.wait_for_function("() => /second.nc/.test(document.querySelector('#preview svg "
                           "title').textContent) || document.querySelector('#plan-lines')"
                           ".textContent.includes('commands')")
    page.wait_for_function("() => !document.querySelector('#start').disabled")
    page.click("#start")
    _finish(page, results=3)
    rows = page.locator("#history tr").all_inner_texts()
    assert rows[0].startswith("second.nc") and "finished" in rows[0], rows
    assert not page.locator("#messages li.error").count(), \
        page.locator("#messages").inner_text()
    _fits_a_phone(page)


#: the narrowest phone screens in use (CSS px): the page must need no sideways scroll
PHONE_WIDTH = 320


def _fits_a_phone(page) -> None:
    """At a phone's width, with the evening's preview, messages and history on it:
    nothing wider than the screen, so every control is reached by scrolling down."""
    size = page.viewport_size
    page.set_viewport_size({"width": PHONE_WIDTH, "height": 640})
    try:
        wider = page.evaluate("""() => {
            const width = document.documentElement.clientWidth;
            // inside an SVG only the SVG counts: it clips what it draws (the head
            // jogged off the preview's edge)
            return [...document.querySelectorAll('body *:not(svg *)')]
              .filter(e => e.getClientRects().length &&
                           e.getBoundingClientRect().right > width + 0.5)
              .map(e => e.tagName.toLowerCase() + (e.id ? '#' + e.id : ''));
        }""")
        assert wider == [], wider
        assert page.evaluate("() => document.documentElement.scrollWidth") <= PHONE_WIDTH
    finally:
        page.set_viewport_size(size)


def _jog_in_a_closed_tab(page, url: str, held: list[float]) -> None:
    """A second tab holds a jog (the first page sees it), and is closed: the jog ends."""
    tab = page.context.new_page()
    tab.goto(url.split("?")[0])
    tab.wait_for_function("() => !document.querySelector('#home').disabled")
    tab.hover("button.jog[data-axis='y'][data-dir='-1']")
    tab.mouse.down()
    page.wait_for_function("() => document.querySelector('#activity').textContent === "
                           "'(jog)'")
    tab.close()
    page.wait_for_function("() => document.querySelector('#activity').textContent === ''")
    assert _standing(page)[1] < held[1]


def _screenshots(page, folder: Path) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(folder / "serve-desktop.png"))
    size = page.viewport_size
    page.set_viewport_size({"width": 390, "height": 844})
    page.screenshot(path=str(folder / "serve-phone.png"))
    page.set_viewport_size(size)


def test_an_evening_in_the_browser_on_sim(chromium, tmp_path):
    shots = os.environ.get("GALILEO_SCREENSHOTS")
    board = tmp_path / "board.zip"
    board.write_bytes(board_zip(tmp_path))
    with served_in_a_browser(chromium, "sim://?speed=20", tmp_path / "home") as (page, url):
        an_evening(page, url, board, "top and bottom", Path(shots) if shots else None)


def test_an_evening_in_the_browser_on_the_firmware_in_simavr(chromium, tmp_path):
    build_firmware()
    build_harness()
    from galileo_cnc.simavr.board import SimulatedBoard

    with SimulatedBoard(ELF) as machine, \
            served_in_a_browser(chromium, machine.port, tmp_path / "home") as (page, url):
        an_evening(page, url, tiny_board(tmp_path / "tiny"), "top", second_tab=False)
