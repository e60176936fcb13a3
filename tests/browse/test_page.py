"""The example panels in a real browser (Debian's Chromium, headless) against a real `serve`:
the robot's value moves the widgets, the widgets move the robot (checked with the reference
client), two pages on one robot see each other's writes, and the privilege's refusals are shown
in words. One browser, one server and one `browse` per robot."""

from __future__ import annotations

import itertools
import re
import subprocess
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
from support.browser import browsing, chromium, serving
from support.processes import BOUND, COMMAND, Running, run_command
from support.robots import CAMERA, ROBOTS, ROVER

BUSY = "busy: another session has control"


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    with chromium() as launched:
        yield launched


@contextmanager
def robot_panel(
    factory: pytest.TempPathFactory, name: str, rcml: Path
) -> Iterator[tuple[Running, Running]]:
    """(the robot's `serve`, `browse` of its example panel)."""
    directory = factory.mktemp(name)
    rxid = str(ROBOTS / name / f"{name}.rxid")
    with (
        serving(directory / "serve", rcml) as server,
        browsing(directory / "browse", rxid, server) as panel,
    ):
        yield server, panel


@pytest.fixture(scope="module")
def camera(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Running, Running]]:
    with robot_panel(tmp_path_factory, "camera", CAMERA) as both:
        yield both


@pytest.fixture(scope="module")
def rover(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[Running, Running]]:
    with robot_panel(tmp_path_factory, "rover", ROVER) as both:
        yield both


def open_page(browser: Any, panel: Running) -> Any:
    page = browser.new_page()
    page.set_default_timeout(BOUND * 1000)
    page.goto(str(panel.ready["url"]))
    page.wait_for_selector(".state.connected[data-robot]")
    return page


def client(server: Running, rcml: Path, *args: str) -> list[str]:
    """`rcmlconf client URL ARGS`'s lines: the reference client, as a user runs it."""
    done = run_command("client", "--rcml", str(rcml), str(server.ready["rctp"]), *args)
    assert done.returncode == 0, done.stderr
    return done.stdout.splitlines()


def until(check: Callable[[], bool], what: str) -> None:
    deadline = time.monotonic() + BOUND
    while not check():
        assert time.monotonic() < deadline, what
        time.sleep(0.1)


def camera_axis(server: Running, name: str) -> int:
    """The camera's axis as its stream last sent it (a stream access has no READ, D-RCTP-17)."""
    lines = client(server, CAMERA, "stream", "/stream/control", "--duration", "0.2")
    found = re.findall(rf"\b{name}=(-?\d+)", "\n".join(lines))
    return int(found[-1])


def slide(page: Any, widget: str, value: float) -> None:
    page.fill(f"[data-rxid-id={widget}] input", str(value))


def shows(page: Any, widget: str, value: str) -> None:
    """Until the input of the widget whose RXID id is `widget` shows `value`."""
    page.wait_for_function(
        f"() => document.querySelector('[data-rxid-id={widget}] input').value == '{value}'"
    )


def note(page: Any, selector: str) -> Any:
    return page.locator(f"{selector} .note")


def noted(page: Any, selector: str, text: str) -> None:
    """Until the note next to the widget `selector` says `text` ("" for none)."""
    shown = note(page, selector).first
    until(lambda: text in shown.inner_text() if text else not shown.inner_text(), text)


def test_the_robot_s_value_moves_the_slider_and_a_busy_robot_says_so(
    browser: Any, camera: tuple[Running, Running]
) -> None:
    server, panel = camera
    # Another operator holds the stream and turns the camera to -90.
    other = subprocess.Popen(
        [
            *(*COMMAND, "client", "--rcml", str(CAMERA), str(server.ready["rctp"]), "stream"),
            *("/stream/control", "--mode", "both", "--set", "pan=-90", "--duration", "3"),
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        until(lambda: camera_axis(server, "pan") < 0, "the other operator never moved the camera")
        page = open_page(browser, panel)
        pan = page.locator("[data-rxid-id=pan] input")
        page.wait_for_function(
            "() => document.querySelector('[data-rxid-id=pan] input').value == '-90'"
        )
        noted(page, "[data-rxid-id=pan]", BUSY)
        assert page.inner_text("[data-rxid-id=model] output, .widget.text output") != ""
        # A page that does not hold the stream writes nothing: it says why, next to the widget.
        slide(page, "zoom", 80)
        noted(page, "[data-rxid-id=zoom]", "not acquired: take control first")
        assert pan.input_value() == "-90"
        page.close()
    finally:
        _, err = other.communicate(timeout=BOUND)
    assert other.returncode == 0, err


def test_the_slider_moves_the_robot_and_a_second_page_sees_it(
    browser: Any, camera: tuple[Running, Running]
) -> None:
    server, panel = camera
    first = open_page(browser, panel)  # the autoStart stream takes the privilege (D-RXID-8)
    second = open_page(browser, panel)
    noted(second, "[data-rxid-id=pan]", BUSY)

    slide(first, "pan", 45)
    until(lambda: camera_axis(server, "pan") == 45, "the robot never turned to 45")
    second.wait_for_function(
        "() => document.querySelector('[data-rxid-id=pan] input').value == '45'"
    )

    take, release = (
        second.locator(".actionButton", has_text=t) for t in ("Take control", "Release")
    )
    take.locator("button").click()
    noted(second, ".actionButton", BUSY)
    first.locator(".actionButton", has_text="Release").locator("button").click()
    time.sleep(0.5)  # the RELEASE's answer: nothing on the page changes when it is accepted
    noted(first, ".actionButton", "")
    take.locator("button").click()
    noted(second, ".actionButton", "")
    slide(second, "zoom", 60)
    until(lambda: camera_axis(server, "zoom") == 60, "the second page never zoomed")
    first.wait_for_function(
        "() => document.querySelector('[data-rxid-id=zoom] input').value == '60'"
    )
    release.locator("button").click()
    first.close()
    second.close()


def test_the_rover_s_event_nodes_both_ways_and_disconnect(
    browser: Any, rover: tuple[Running, Running]
) -> None:
    server, panel = rover
    page = open_page(browser, panel)
    edit = page.locator(".widget.edit input")
    # Another session's WRITE reaches the page by the server's data-change WRITE (D-RCTP-27).
    client(server, ROVER, "write", "/drive/settings", "maxSpeed=0.25")
    page.wait_for_function("() => document.querySelector('.widget.edit input').value == '0.25'")
    # The odometry's stream shows in its text widget: three numbers.
    page.wait_for_function(
        "() => document.querySelector('.widget.text output').textContent.split(',').length == 3"
    )

    edit.fill("0.75")
    edit.press("Enter")
    noted(page, ".widget.edit", "not acquired: take control first")
    page.locator(".actionButton", has_text="Take control").locator("button").click()
    edit.fill("0.5")
    edit.press("Enter")
    page.select_option(".widget.popUpMenu select", "2")
    until(
        lambda: "maxSpeed = 0.5" in client(server, ROVER, "read", "/drive/settings/maxSpeed"),
        "maxSpeed never became 0.5",
    )
    until(
        lambda: "mode = 2" in client(server, ROVER, "read", "/drive/settings/mode"),
        "mode never became 2",
    )

    # The wheels' stream writes from the start, the robot's own values until the user moves
    # a wheel: the server never STOPs it for silence (D-RCTP-23).
    assert "stopped" not in page.inner_text("#notes")

    page.locator(".actionButton", has_text="Disconnect").locator("button").click()
    page.wait_for_selector(".state.closed[data-robot]")
    assert "BYE" in page.inner_text("[data-robot]") or "closed" in page.inner_text("[data-robot]")
    page.close()


#: Before the page's script: every `values` message's focus text, in the order the page parses
#: them (each is shown in the same task, right after).
FOCUS_TEXTS = """
window.__focus = [];
const parse = JSON.parse;
JSON.parse = (data, reviver) => {
  const message = parse(data, reviver);
  if (message && message.type === "values" && "/stream/control/focus" in message.values) {
    window.__focus.push(message.values["/stream/control/focus"]);
  }
  return message;
};
"""


def test_a_value_the_page_shows_already_is_not_set_again(
    browser: Any, camera: tuple[Running, Running]
) -> None:
    """The stream's every DATA names every node, at 62.5 Hz a page: the page changes only the
    widgets whose text changed (issue 20, Speed), so the focus slider's title, set from the
    robot's value, is touched once per change of the focus, not once per message."""
    _, panel = camera
    page = browser.new_page()
    page.set_default_timeout(BOUND * 1000)
    page.add_init_script(FOCUS_TEXTS)
    page.goto(str(panel.ready["url"]))
    page.wait_for_function("() => window.__focus.length > 0")
    start = page.evaluate("""() => {
      window.__touched = 0;
      const range = document.querySelector('[data-rxid-id=focus] input');
      const count = (records) => { window.__touched += records.length; };
      window.__observer = new MutationObserver(count);
      window.__observer.observe(range, {attributes: true, attributeFilter: ["title"]});
      return window.__focus.length;
    }""")
    page.wait_for_function(f"() => window.__focus.length >= {start + 30}")
    touched, texts = page.evaluate("""() => {
      const touched = window.__touched + window.__observer.takeRecords().length;
      return [touched, window.__focus.slice()];
    }""")
    changes = sum(1 for a, b in itertools.pairwise(texts[start - 1 :]) if a != b)
    assert touched == changes, (touched, changes)
    page.close()
