"""The example panels as the page is sent them, and the links each robot's session makes."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from support.robots import ROBOTS

from rcmlconf.browse.links import NORMAL_READ_EVERY, robot_links
from rcmlconf.browse.panel import Panel, build_panel
from rcmlconf.browse.sources import load_sources


def panel_of(name: str) -> Panel:
    sources = load_sources(str(ROBOTS / name / f"{name}.rxid"), 5.0)
    return build_panel(sources.rxid, {h: r.model for h, r in sources.robots.items()})


def widgets_of(panel: Panel) -> dict[str, Any]:
    described = panel.describe()
    (window,) = described["windows"]  # type: ignore[misc]
    return {w["id"] or w["caption"] or w.get("path") or w["kind"]: w for w in window["widgets"]}


def test_the_camera_s_window_and_widgets() -> None:
    described = panel_of("camera").describe()
    (window,) = described["windows"]  # type: ignore[misc]
    assert (window["title"], window["width"], window["height"]) == (
        "Pan / tilt / zoom camera",
        360,
        260,
    )
    widgets = widgets_of(panel_of("camera"))
    assert (
        widgets["pan"].items()
        >= {
            "kind": "scroll",
            "robot": "camera.rcml",
            "path": "/stream/control/pan",
            "reads": True,
            "writes": True,
            "min": -180.0,
            "max": 180.0,
            "step": 1.0,
            "orientation": "horizontal",
        }.items()
    )
    assert widgets["tilt"]["orientation"] == "vertical"
    assert widgets["zoom"]["step"] == 5.0
    moving = widgets["Moving"]
    assert (moving["reads"], moving["writes"], moving["on"], moving["off"]) == (
        True,
        False,
        "true",
        "false",
    )
    # callto: is no URL a page can load: the page shows a labelled placeholder.
    video = next(w for w in widgets.values() if w["kind"] == "netmeeting")
    assert (video["href"], video["src"]) == ("callto://127.0.0.1/camera", None)
    take = widgets["Take control"]
    assert (take["action"], take["target"]) == ("acquire", "/stream")
    assert take["robots"] == ["camera.rcml"]


def test_the_rover_s_widgets_on_event_and_stream_nodes() -> None:
    widgets = widgets_of(panel_of("rover"))
    menu = next(w for w in widgets.values() if w["kind"] == "popUpMenu")
    assert [i["value"] for i in menu["items"]] == ["0", "1", "2"]
    battery = widgets["/sensors/events/battery"]
    assert (battery["reads"], battery["writes"], battery["min"], battery["max"]) == (
        True,
        False,
        0.0,
        100.0,
    )
    # A float slider without step moves in hundredths of its range.
    assert widgets["left"]["step"] == 0.05
    disconnect = widgets["Disconnect"]
    assert (disconnect["target"], disconnect["robots"]) == (None, ["rover.rcml"])


def test_links_set_up_what_the_panel_uses() -> None:
    (camera,) = robot_links(panel_of("camera")).values()
    control, lens = camera.accesses["/stream/control"], camera.accesses["/status/lens"]
    assert (control.starts, control.mode(True), control.mode(False)) == (True, "both", "read")
    # The RXID asks no readInterval: each DATA goes to the page as it comes, not paced at the
    # RCML's 16 ms (which held and merged values, issue 20's Speed).
    assert control.pace == 0.0
    assert (lens.starts, lens.streams, lens.writes) == (True, False, False)
    assert camera.polled == ()

    (rover,) = robot_links(panel_of("rover")).values()
    odometry = rover.accesses["/sensors/odometry"]
    assert (odometry.pace, odometry.mode(True)) == (0.1, "read")  # the RXID's readInterval
    settings = rover.accesses["/drive/settings"]
    assert (settings.reads, settings.writes, settings.starts) == (True, True, True)
    assert NORMAL_READ_EVERY > 0


def test_one_panel_for_two_robots_in_two_windows(tmp_path: Path) -> None:
    """Fig. 4: one UI for several robots; each link says which session (D-RXID-2)."""
    for name in ("camera", "rover"):
        (tmp_path / f"{name}.rcml").write_bytes((ROBOTS / name / f"{name}.rcml").read_bytes())
    path = tmp_path / "both.rxid"
    path.write_text(
        '<rxid version="2.0" title="Both">'
        '<window title="Drive and look">'
        '<session name="cam" href="camera.rcml"/><session name="bot" href="rover.rcml"/>'
        '<slider session="cam" dataPath="/stream/control/zoom"/>'
        '<edit session="bot" dataPath="/drive/settings/maxSpeed"/>'
        '<actionButton caption="Leave" action="bye"/></window>'
        '<window title="Camera only"><session href="camera.rcml"/>'
        '<text dataPath="/status/lens/model"/></window></rxid>'
    )
    sources = load_sources(str(path), 5.0)
    panel = build_panel(sources.rxid, {h: r.model for h, r in sources.robots.items()})
    first, second = panel.describe()["windows"]  # type: ignore[misc]
    assert [w.get("robot") for w in first["widgets"]] == ["camera.rcml", "rover.rcml", None]
    assert first["widgets"][2]["robots"] == ["camera.rcml", "rover.rcml"]  # bye ends both
    assert second["widgets"][0]["robot"] == "camera.rcml"
    links = robot_links(panel)
    assert set(links) == {"camera.rcml", "rover.rcml"}
    assert "/status/lens" in links["camera.rcml"].accesses
    assert "/drive/settings" in links["rover.rcml"].accesses


def test_only_a_slower_rxid_read_interval_paces_the_page(tmp_path: Path) -> None:
    """D-RXID-8: an RXID readInterval no slower than the RCML's (16 ms) asks for nothing; the
    server already sends at that pace, and pacing the page at it too only delays values."""
    (tmp_path / "camera.rcml").write_bytes((ROBOTS / "camera" / "camera.rcml").read_bytes())
    paces = []
    for interval in ("16e-3", "0.05"):
        path = tmp_path / "paced.rxid"
        path.write_text(
            '<rxid version="2.0" title="Paced"><window><session href="camera.rcml"/>'
            f'<access dataPath="/stream/control" autoStart="true" readInterval="{interval}"/>'
            '<slider dataPath="/stream/control/zoom"/></window></rxid>'
        )
        sources = load_sources(str(path), 5.0)
        panel = build_panel(sources.rxid, {h: r.model for h, r in sources.robots.items()})
        paces.append(robot_links(panel)["camera.rcml"].accesses["/stream/control"].pace)
    assert paces == [0.0, 0.05]
