"""The inspection page of ``cdpm view``: its panel (one analysis per pose),
its JSON endpoints, and a real headless Chromium driven by selenium moving
sliders, picking a named pose and looking at the scene."""

from __future__ import annotations

import json
import math
import os
import shutil
import socket
import tempfile
import time
import urllib.error
import urllib.request
from pathlib import Path

import numpy as np
import pytest

import cdpm
from cdpm.errors import InputError
from cdpm.viewer import COLORS, CableState, coordinate_ranges, coordinate_sliders, pose_state
from cdpm.viewer.panel import pose_panel, q_arguments
from tests.conftest import MODELS
from tests.output_kinds import EVERY_KIND_SPEC
from tests.processes import alive

NOMINAL = np.array([math.pi / 6, math.pi / 3])
VERTICAL_SPEC = MODELS / "two_link_vertical" / "two_link_vertical.yaml"
SPATIAL_SPEC = MODELS / "spatial_8cable" / "spatial_8cable.yaml"
#: a pose of the vertical arm where no tension within the bounds holds it
INFEASIBLE = [-0.5, -1.0]


# ---------------------------------------------------------------- panel


@pytest.mark.parametrize("q", [NOMINAL, [0.0, 0.0], [0.0, math.pi / 3], [2.5, -1.0]])
def test_panel_shows_what_analyze_pose_gives(paper_robot, q):
    report = cdpm.analyze_pose(paper_robot, q)
    panel = pose_panel(paper_robot, q)
    assert panel.report is not None and panel.reason is None
    assert panel.verdict("poc").text == str(report.poc.verdict).upper()
    assert panel.verdict("poc").detail.startswith(report.poc.method + ": ")
    assert (
        panel.verdict("positive_controllable").verdict
        == report.positive_controllability.verdict.value
    )
    oc = report.output_controllability
    assert panel.verdict("output_controllable").verdict == ("yes" if oc.controllable else "no")
    assert panel.verdict("wrench_closure").verdict == report.wrench_closure.verdict.value
    assert panel.verdict("static_feasible").verdict == "yes"
    assert panel.reach["value"] == report.reach_margin[0]
    assert panel.reach["horizon"] == report.reach.horizon
    # the scene is drawn from the same report, and agrees with analysing the pose afresh
    assert panel.state.verdict is report.poc.verdict
    fresh = pose_state(paper_robot, q)
    assert fresh.verdict is report.poc.verdict and fresh.margin == pytest.approx(
        panel.reach["value"]
    )
    assert fresh.cable_states == panel.state.cable_states


def test_panel_content_at_the_paper_pose(paper_robot):
    content = pose_panel(paper_robot, "nominal").as_dict()
    assert content["q_arguments"] == "--q 0.5236 1.0472"
    rows = {row["key"]: row for row in content["verdicts"]}
    assert (rows["poc"]["text"], rows["poc"]["color"]) == ("YES", "#2e9e44")
    assert rows["poc"]["detail"].startswith("nilpotent: ")
    assert (rows["positive_controllable"]["text"], rows["positive_controllable"]["color"]) == (
        "NO",
        "#d4453a",
    )
    assert content["reach"]["value"] == pytest.approx(0.1501, abs=1e-4)
    assert content["reach"]["horizon"] == pytest.approx(0.775)
    assert [c["name"] for c in content["cables"]] == ["c1", "c2", "c3", "c4"]
    assert {c["state"] for c in content["cables"]} == {"slack"}
    assert {c["color"] for c in content["cables"]} == {"#e377c2"}  # COLORS["slack"]
    assert content["outputs"] == [
        {
            "name": "tip_x",
            "value": pytest.approx(math.sqrt(3) / 2),
            "unit": "m",
            "kind": "position",
            "definition": "tip.x",
        }
    ]
    assert content["reach"]["unit"] == "m"
    assert content["notes"] == [] and content["reason"] is None
    json.dumps(content)  # what the endpoint sends


def test_panel_of_a_singular_pose_says_so(paper_robot):
    panel = pose_panel(paper_robot, [0.0, 0.0])  # arm stretched along x: d(tip_x)/dq = 0
    assert panel.verdict("poc").text == "NO"
    assert panel.verdict("output_controllable").detail == "output rank 0 of p = 1"
    assert panel.notes == (
        "singular pose: the output Jacobian dy/dq has rank 0 < p = 1, so to first order "
        "the outputs cannot move in some direction",
    )
    assert "note: singular pose" in str(panel)


def test_panel_of_an_infeasible_pose_gives_the_reason():
    robot = cdpm.load_robot(VERTICAL_SPEC)
    with pytest.raises(cdpm.InfeasibleEquilibriumError):
        cdpm.analyze_pose(robot, INFEASIBLE)
    panel = pose_panel(robot, INFEASIBLE)
    assert panel.report is None and panel.reach is None
    assert panel.reason.startswith("no equilibrium at this pose with method 'min_norm'")
    for key in ("poc", "positive_controllable", "output_controllable"):
        assert panel.verdict(key).text == "unavailable"
    static = panel.verdict("static_feasible")
    assert static.text == "NO" and "least statics residual 0.347" in static.detail
    assert panel.verdict("wrench_closure").text in ("YES", "NO")  # needs only L
    assert panel.state.cable_states == (CableState.UNAVAILABLE,) * 4
    assert set(panel.cable_rgb) == {COLORS["unavailable"]}
    content = panel.as_dict()
    assert all(c["tension"] is None for c in content["cables"])
    assert str(panel).startswith(
        f"Positive output controllability (POC): unavailable ({panel.reason})"
    )


def test_pose_state_takes_a_report_of_its_pose_only(paper_robot):
    report = cdpm.analyze_pose(paper_robot, "nominal")
    with pytest.raises(InputError, match="the report is of another pose than q"):
        pose_state(paper_robot, [0.0, 0.0], report=report)
    with pytest.raises(InputError, match="a report or a reason, not both"):
        pose_state(paper_robot, "nominal", report=report, reason="no")


def test_q_arguments_round_trip_through_the_command_line(paper_robot):
    from cdpm.cli._pose import _configuration_from_q

    assert q_arguments([math.pi / 6, math.pi / 3]) == "--q 0.5236 1.0472"
    assert q_arguments([-1e-9, 2.0, -0.25]) == "--q 0 2 -0.25"
    words = q_arguments([0.1234567, -2.5]).split()[1:]
    q = _configuration_from_q(paper_robot, words)
    assert q == pytest.approx([0.1235, -2.5], abs=0)


def test_coordinate_sliders_of_a_free_flyer():
    robot = cdpm.load_robot(SPATIAL_SPEC)
    natural = robot.to_natural(robot.poses["offset"])
    sliders = coordinate_sliders(robot, natural)
    units = {s.name.rsplit(".", 1)[1]: s.unit for s in sliders}
    assert units == {"x": "m", "y": "m", "z": "m", "roll": "rad", "pitch": "rad", "yaw": "rad"}
    by_name = {s.name.rsplit(".", 1)[1]: s for s in sliders}
    assert (by_name["pitch"].low, by_name["pitch"].high) == (-math.pi / 2, math.pi / 2)
    assert (by_name["yaw"].low, by_name["yaw"].high) == (-math.pi, math.pi)
    assert by_name["z"].low <= natural[2] <= by_name["z"].high
    assert coordinate_ranges(robot, natural) == {s.name: (s.low, s.high) for s in sliders}


def test_page_files_are_package_data():
    import fnmatch
    import tomllib

    from tests.conftest import ROOT

    pyproject = tomllib.loads((ROOT / "pyproject.toml").read_text())
    globs = pyproject["tool"]["setuptools"]["package-data"]["cdpm.viewer"]
    files = sorted(p.name for p in (ROOT / "cdpm" / "viewer" / "static").iterdir())
    assert files == ["page.css", "page.html", "page.js", "scene.html"]
    for name in files:  # a wheel ships every file the page serves
        assert any(fnmatch.fnmatch(f"static/{name}", g) for g in globs), name


# ---------------------------------------------------------------- endpoints


def _request(url: str, body=None, host: str | None = None, token: str | None = None):
    """(status, JSON or text) of a GET (body None) or a JSON POST (with the
    page's ``token``, as the page sends it)."""
    data = None if body is None else json.dumps(body).encode()
    request = urllib.request.Request(url, data=data)
    if data is not None:
        request.add_header("Content-Type", "application/json")
    if host:
        request.add_header("Host", host)
    if token:
        request.add_header("X-Cdpm-Token", token)
    try:
        with urllib.request.urlopen(request, timeout=30) as response:
            status, raw, kind = response.status, response.read(), response.headers["Content-Type"]
    except urllib.error.HTTPError as exc:
        status, raw, kind = exc.code, exc.read(), exc.headers["Content-Type"]
    return status, json.loads(raw) if kind == "application/json" else raw.decode()


def _listening(port: int) -> list[str]:
    """Local addresses (hex, /proc/net/tcp order) listening on a TCP port."""
    found = []
    for table in ("/proc/net/tcp", "/proc/net/tcp6"):
        if os.path.exists(table):
            for line in Path(table).read_text().splitlines()[1:]:
                fields = line.split()
                address, hexport = fields[1].rsplit(":", 1)
                if fields[3] == "0A" and int(hexport, 16) == port:
                    found.append(address)
    return found


def _scene_port(page) -> int:
    return int(page.viewer.url().split(":")[2].split("/")[0])


@pytest.mark.slow
def test_page_endpoints_and_shutdown(paper_robot):
    pytest.importorskip("meshcat")
    from cdpm.viewer import InspectionPage

    with InspectionPage(paper_robot, "nominal") as page:
        assert page.url == f"http://127.0.0.1:{page.port}/"
        ports, server = [page.port, _scene_port(page)], page.viewer.server_pid
        if os.path.exists("/proc/net/tcp"):
            assert _listening(page.port) == ["0100007F"]  # 127.0.0.1 only
        status, html = _request(page.url)
        assert status == 200 and '<aside id="panel"' in html and '"static/page.js"' in html
        status, js = _request(page.url + "static/page.js")
        assert status == 200 and "performance.now()" in js
        status, model = _request(page.url + "api/model")
        assert status == 200 and model["model"] == "two_link_planar.yaml"
        assert [c["name"] for c in model["coordinates"]] == ["q1", "q2"]
        assert model["coordinates"][0]["unit"] == "rad"
        assert model["poses"] == [{"name": "nominal", "natural": pytest.approx(NOMINAL.tolist())}]
        assert model["scene"] == {"path": "scene/"}
        assert model["map"] is None and model["panel"]["pose"] == "nominal"
        assert [v["label"] for v in model["legend"]["verdicts"]] == [
            "YES",
            "MARGINAL",
            "NO",
            "unavailable",
        ]
        status, panel = _request(page.url + "api/pose", {"natural": [0.0, 0.0]}, token=page.token)
        assert status == 200 and panel["verdicts"][0]["text"] == "NO" and panel["pose"] is None
        assert page.viewer.state.verdict_key == "no"  # the scene moved too
        status, panel = _request(page.url + "api/pose", {"pose": "nominal"}, token=page.token)
        assert (
            status == 200 and panel["pose"] == "nominal" and panel["verdicts"][0]["text"] == "YES"
        )
        for body, message in [
            ({"natural": [0.0]}, "natural must be 2 finite numbers (q1, q2)"),
            ({"natural": [0.0, "x"]}, "natural must be 2 numbers"),
            ({"natural": [0.0, None]}, "natural must be 2 numbers"),  # JSON null: no number
            ({"pose": "home"}, "pose 'home' not in spec; poses: nominal"),
            ({}, "give natural coordinates or a pose name"),
        ]:
            status, answer = _request(page.url + "api/pose", body, token=page.token)
            assert status == 400 and answer["error"].startswith(message), answer
        status, answer = _request(page.url + "api/map", {"visible": True}, token=page.token)
        assert status == 400 and "start cdpm view with --map STORE" in answer["error"]
        assert _request(page.url + "api/none")[0] == 404
        status, answer = _request(page.url + "api/model", host="evil.example:80")
        assert status == 403 and "refused" in answer["error"]
    for port in ports:
        assert _listening(port) == []
    if os.path.isdir("/proc"):
        assert not alive(server)


def test_page_port_in_use_is_refused(paper_robot):
    pytest.importorskip("meshcat")
    from cdpm.viewer import InspectionPage

    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        with pytest.raises(InputError, match=f"port {port} is in use; choose another port"):
            InspectionPage(paper_robot, port=port)


def test_page_map_toggle(paper_robot, tmp_path):
    pytest.importorskip("meshcat")
    pytest.importorskip("zarr")
    from cdpm.viewer import InspectionPage
    from tests.test_viewer import _server_scene

    store = tmp_path / "paper.zarr"
    cdpm.workspace_map(paper_robot, {"q1": np.linspace(-3, 3, 5)}, store=store, workers=1)
    dataset = cdpm.open_map(store)
    with InspectionPage(paper_robot, dataset=dataset, map_name=str(store)) as page:
        status, model = _request(page.url + "api/model")
        assert model["map"] == {
            "name": str(store),
            "points": 5,
            "color_by": "verdict",
            "visible": True,
        }
        assert "cdpm/map" in _server_scene(page.viewer)
        status, answer = _request(page.url + "api/map", {"visible": False}, token=page.token)
        assert (status, answer) == (200, {"visible": False, "points": 5})
        assert "cdpm/map" not in _server_scene(page.viewer)
        _request(page.url + "api/map", {"visible": True}, token=page.token)
        assert "cdpm/map" in _server_scene(page.viewer)


# ---------------------------------------------------------------- real browser

CI = os.environ.get("CI") == "true"
CHROMIUM, CHROMEDRIVER = shutil.which("chromium"), shutil.which("chromedriver")


@pytest.fixture
def browser(tmp_path):
    """A headless Chromium under chromedriver (selenium); checks on exit that
    neither chromedriver nor any Chromium process of its profile is left."""
    if not CI:  # locally without the browser, skip; in CI every piece must be there
        if CHROMIUM is None or CHROMEDRIVER is None:
            pytest.skip("needs Debian's chromium and chromium-driver (apt-get install ...)")
        pytest.importorskip("selenium", reason="needs selenium (the test extra)")
        pytest.importorskip("meshcat", reason="needs meshcat (the viz extra)")
    assert CHROMIUM and CHROMEDRIVER, "CI must install Debian's chromium and chromium-driver"
    from selenium import webdriver
    from selenium.webdriver.chrome.service import Service

    profile = tempfile.mkdtemp(prefix="cdpm-page-chromium-", dir=tmp_path)
    options = webdriver.ChromeOptions()
    options.binary_location = CHROMIUM
    for flag in [
        "--headless=new",
        "--no-sandbox",
        "--disable-gpu",
        "--use-gl=swiftshader",
        "--enable-unsafe-swiftshader",  # without it WebGL does not start: a blank scene
        "--disable-background-networking",
        "--no-first-run",
        "--disable-component-update",
        "--disable-sync",
        "--window-size=1280,900",
        f"--user-data-dir={profile}",
    ]:
        options.add_argument(flag)
    service = Service(executable_path=CHROMEDRIVER)  # no download by selenium-manager
    driver = webdriver.Chrome(service=service, options=options)
    driver.set_script_timeout(30)
    try:
        yield driver
    finally:
        driver.quit()
    assert service.process.poll() is not None, "chromedriver still runs"
    deadline = time.monotonic() + 10
    while _profile_processes(profile) and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not _profile_processes(profile), "Chromium processes left"


def _profile_processes(profile: str) -> list[int]:
    """Running processes whose command line names the browser profile."""
    found = []
    for proc in Path("/proc").iterdir() if os.path.isdir("/proc") else []:
        try:
            argv = (proc / "cmdline").read_bytes().decode(errors="replace")
        except OSError:
            continue
        if proc.name.isdigit() and profile in argv and alive(int(proc.name)):
            found.append(int(proc.name))
    return found


#: JavaScript: resolve once the panel has rendered more than arguments[0] times
_WAIT_SEQ = """
const [after, done] = arguments;
const panel = document.getElementById("panel");
const check = () => Number(panel.dataset.seq) > after;
if (check()) { done(Number(panel.dataset.seq)); return; }
new MutationObserver((_, observer) => {
  if (check()) { observer.disconnect(); done(Number(panel.dataset.seq)); }
}).observe(panel, { attributes: true, attributeFilter: ["data-seq"] });
"""

#: JavaScript: set a slider's value and fire its input event, as a drag does
_MOVE_SLIDER = """
const [index, value] = arguments;
const slider = document.getElementById(`slider-${index}`);
slider.value = value;
slider.dispatchEvent(new Event("input", { bubbles: true }));
return Number(slider.value);
"""


def _seq(driver) -> int:
    return int(driver.find_element("id", "panel").get_attribute("data-seq"))


def _panel(driver) -> dict:
    """What the page shows: verdict texts, reach margin, cables, --q text, pose."""
    return driver.execute_script(
        """
        const rows = [...document.querySelectorAll("#verdict-table tr[data-verdict]")];
        const cables = [...document.querySelectorAll("#cable-table tbody tr")];
        const pressed = document.querySelector("#pose-picker button[aria-pressed=true]");
        return {
          verdicts: Object.fromEntries(
            rows.map((r) => [r.id.slice(8), r.querySelector(".badge").textContent])
          ),
          method: document.querySelector("#verdict-poc .detail").textContent.split(":")[0],
          reach: Number(document.getElementById("reach").dataset.value),
          cables: cables.map((r) => [...r.cells].slice(1).map((c) => c.textContent)),
          q: document.getElementById("q-text").textContent,
          natural: JSON.parse(document.getElementById("panel").dataset.natural),
          pose: pressed ? pressed.dataset.pose : null,
          ms: Number(document.getElementById("update-time").dataset.ms),
        };
        """
    )


def _expected(robot, natural) -> dict:
    report = cdpm.analyze_pose(robot, natural)
    lin = report.linearisation
    states = ["slack" if s > 0 else "taut" for s in lin.input_sign]
    return {
        "poc": str(report.poc.verdict).upper(),
        "brammer": str(report.positive_controllability.verdict).upper(),
        "method": report.poc.method,
        "reach": report.reach_margin[0],
        "cables": [
            [name, state, f"{f:.3f}"]
            for name, state, f in zip(lin.cable_names, states, lin.tension, strict=True)
        ],
    }


def _scene_pixels(driver) -> np.ndarray:
    """The 3-D scene's part of a screenshot, (h, w, 3) RGB."""
    from io import BytesIO

    from PIL import Image

    shot = np.asarray(Image.open(BytesIO(driver.get_screenshot_as_png())).convert("RGB"))
    rect = driver.execute_script(
        "const r = document.getElementById('scene-frame').getBoundingClientRect();"
        "return [r.left, r.top, r.right, r.bottom].map((v) => v * devicePixelRatio);"
    )
    left, top, right, bottom = (int(round(v)) for v in rect)
    return shot[top:bottom, left:right]


def _count_near(pixels: np.ndarray, rgb, tol: int = 12) -> int:
    target = np.round(np.array(rgb) * 255)
    return int(np.sum(np.all(np.abs(pixels.astype(int) - target) <= tol, axis=-1)))


def _wait_for_scene(driver, test, timeout: float = 15.0) -> np.ndarray:
    """Screenshots of the scene until ``test(pixels)`` holds (the scene
    renders a few frames after the panel updates); returns the last one."""
    deadline = time.monotonic() + timeout
    while True:
        pixels = _scene_pixels(driver)
        if test(pixels) or time.monotonic() > deadline:
            return pixels
        time.sleep(0.2)


def test_browser_sliders_picker_and_scene(browser, paper_robot, tmp_path):
    from cdpm.viewer import InspectionPage

    driver = browser
    with InspectionPage(paper_robot, "nominal") as page:
        driver.get(page.url)
        driver.execute_async_script(_WAIT_SEQ, 0)  # the first panel
        shown = _panel(driver)
        assert shown["verdicts"]["poc"] == "YES" and shown["pose"] == "nominal"
        assert shown["q"] == "--q 0.5236 1.0472"

        # the scene at the paper's pose: four slack (pink) cables, a YES (green) marker
        def paper_pose(pixels):
            return _count_near(pixels, COLORS["slack"]) > 300 and (
                _count_near(pixels, COLORS["yes"], tol=40) > 50
            )

        pixels = _wait_for_scene(driver, paper_pose)
        Path(tmp_path / "nominal.png").write_bytes(driver.get_screenshot_as_png())
        assert _count_near(pixels, COLORS["slack"]) > 300, "slack-cable pink in the scene"
        assert _count_near(pixels, COLORS["yes"], tol=40) > 50, "YES marker green in the scene"
        assert _count_near(pixels, COLORS["no"], tol=40) < 20

        # drag q1, then q2, to the stretched arm: the panel follows each move
        for index, value in [(0, "0"), (1, "0")]:
            seq = _seq(driver)
            set_to = driver.execute_script(_MOVE_SLIDER, index, value)
            driver.execute_async_script(_WAIT_SEQ, seq)
            shown = _panel(driver)
            natural = shown["natural"]
            assert natural[index] == set_to
            expected = _expected(paper_robot, natural)
            assert shown["verdicts"]["poc"] == expected["poc"]
            assert shown["verdicts"]["positive_controllable"] == expected["brammer"]
            assert shown["method"] == expected["method"]
            assert shown["reach"] == pytest.approx(expected["reach"], rel=1e-12, abs=1e-15)
            assert shown["cables"] == expected["cables"]
            assert shown["q"] == q_arguments(natural) and shown["pose"] is None
            assert shown["ms"] > 0  # input-to-panel time, measured in the page
        assert shown["verdicts"]["poc"] == "NO" and shown["q"] == "--q 0 0"
        pixels = _wait_for_scene(driver, lambda p: _count_near(p, COLORS["no"], tol=40) > 50)
        Path(tmp_path / "stretched.png").write_bytes(driver.get_screenshot_as_png())
        assert _count_near(pixels, COLORS["no"], tol=40) > 50, "NO marker red in the scene"
        assert _count_near(pixels, COLORS["yes"], tol=40) < 20

        # pick the named pose back
        seq = _seq(driver)
        driver.find_element("css selector", "#pose-picker button[data-pose=nominal]").click()
        driver.execute_async_script(_WAIT_SEQ, seq)
        shown = _panel(driver)
        assert shown["natural"] == pytest.approx(NOMINAL.tolist(), abs=1e-15)
        assert shown["pose"] == "nominal" and shown["verdicts"]["poc"] == "YES"
        assert shown["q"] == "--q 0.5236 1.0472"
        assert driver.execute_script(
            "return Number(document.getElementById('slider-0').value)"
        ) == (
            pytest.approx(math.pi / 6, abs=0.005)  # the slider snaps to its step
        )
        pixels = _wait_for_scene(driver, paper_pose)
        assert _count_near(pixels, COLORS["yes"], tol=40) > 50

        # a fast drag: moves made while a request is in flight go out as one request
        before = driver.execute_script("return window.cdpm.timings.length")
        values = [f"{v:.3f}" for v in np.linspace(-1.0, 1.0, 30)]
        driver.execute_async_script(
            """
            const [values, done] = arguments;
            const slider = document.getElementById("slider-1");
            for (const v of values) {
              slider.value = v;
              slider.dispatchEvent(new Event("input", { bubbles: true }));
            }
            const wait = () => (window.cdpm.busy() ? setTimeout(wait, 5) : done());
            wait();
            """,
            values,
        )
        requests = driver.execute_script("return window.cdpm.timings.length") - before
        assert requests == 2  # the first move, then the other 29 coalesced into one
        shown = _panel(driver)
        assert shown["natural"] == [pytest.approx(math.pi / 6, abs=1e-15), 1.0]
        assert shown["verdicts"]["poc"] == _expected(paper_robot, shown["natural"])["poc"]

        # an emptied number field keeps the pose (no request; the field shows it again)
        before = driver.execute_script("return window.cdpm.timings.length")
        field_value = driver.execute_script(
            """
            const field = document.getElementById("value-1");
            field.value = "";
            field.dispatchEvent(new Event("change", { bubbles: true }));
            return field.value;
            """
        )
        assert driver.execute_script("return window.cdpm.timings.length") == before
        assert float(field_value) == pytest.approx(1.0)
        assert _panel(driver)["natural"][1] == 1.0

        # copy as --q: the clipboard gets the text the page shows
        driver.execute_cdp_cmd(
            "Browser.grantPermissions",
            {
                "permissions": ["clipboardReadWrite", "clipboardSanitizedWrite"],
                "origin": page.url[:-1],
            },
        )
        driver.find_element("id", "copy-q").click()
        clipboard = driver.execute_async_script(
            "navigator.clipboard.readText().then(arguments[0], (e) => arguments[0]('error: ' + e))"
        )
        assert clipboard == "--q 0.5236 1"
        note = driver.execute_async_script(
            "const done = arguments[0]; const note = document.getElementById('copy-note');"
            "const check = () => note.textContent ? done(note.textContent) : setTimeout(check, 20);"
            "check();"
        )
        assert note == "copied"
        errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
        assert not errors, errors
        ports, server = [page.port, _scene_port(page)], page.viewer.server_pid
    for port in ports:  # the page's server and the meshcat server are stopped
        assert _listening(port) == []
    if os.path.isdir("/proc"):
        assert not alive(server)


def test_page_legend_says_how_each_output_is_drawn(write_spec):
    pytest.importorskip("meshcat")
    from cdpm.viewer import InspectionPage

    robot = cdpm.load_robot(write_spec(EVERY_KIND_SPEC))
    with InspectionPage(robot, "p") as page:
        model = page.model_dict()
    legend = {entry["label"]: entry["meaning"] for entry in model["legend"]["outputs"]}
    assert list(legend) == ["marker", "axes", "sleeve", "joint"]
    assert legend["axes"].endswith("the verdict marker at its origin: tip_x, tip_rz")
    assert "(c1: c1_length)" in legend["sleeve"]
    assert "(q2: elbow)" in legend["joint"]
    # a robot with point outputs only gets the marker's line alone
    paper = cdpm.load_robot(MODELS / "two_link_planar" / "two_link_planar.yaml")
    from cdpm.viewer.page import _legend

    assert [entry["label"] for entry in _legend(paper)["outputs"]] == ["marker"]


def test_browser_lists_every_output_with_its_unit_and_formula(browser, write_spec, tmp_path):
    from cdpm.viewer import InspectionPage
    from cdpm.viewer.state import AXIS_RGB

    robot = cdpm.load_robot(write_spec(EVERY_KIND_SPEC))
    driver = browser
    with InspectionPage(robot, "p", geometry="generated") as page:
        driver.get(page.url)
        driver.execute_async_script(_WAIT_SEQ, 0)
        rows = driver.execute_script(
            """
            return [...document.querySelectorAll("#output-table tbody tr")].map((r) => [
              r.dataset.output, r.dataset.kind,
              ...[...r.cells].map((c) => [...c.children].map((d) => d.textContent).join(" | ")
                                         || c.textContent),
            ]);
            """
        )
        legend = driver.execute_script(
            """
            const title = document.getElementById("legend-outputs-title");
            return [title.hidden, ...[...document.querySelectorAll("#legend-outputs .item")]
              .map((i) => i.dataset.legend)];
            """
        )
        reach = driver.find_element("id", "reach").text
        # the orientation output's triad shows in the scene: its blue z axis
        # points at the viewer here, its red x and green y axes lie in view
        pixels = _wait_for_scene(driver, lambda p: _count_near(p, AXIS_RGB[1], tol=40) > 30)
        Path(tmp_path / "every_kind.png").write_bytes(driver.get_screenshot_as_png())
        errors = [e for e in driver.get_log("browser") if e["level"] == "SEVERE"]
    y = robot.output("p")
    assert rows == [
        ["tip_x", "position", "tip_x", f"{y[0]:.4f}", "m"],
        ["tip_rz", "rotation", "tip_rz | tip.rz", "0.7000", "rad"],
        ["elbow", "joint", "elbow | joint q2", "0.4000", "rad"],
        ["c1_length", "cable", "c1_length | cable c1", f"{y[3]:.4f}", "m"],
        ["mid_x", "sum", "mid_x | 0.5 link2.x + 0.5 tip.x", f"{y[4]:.4f}", "m"],
    ]
    assert legend == [False, "marker", "axes", "sleeve", "joint"]
    # outputs in metres and radians: the reach margin counts one as the other
    horizon = reach.split("T = ")[1]
    assert reach.endswith(f"[m and rad, one to one] (exact) within T = {horizon}")
    assert _count_near(pixels, AXIS_RGB[1], tol=40) > 30, "the triad's green y axis"
    assert not errors, errors


def _reach_text(driver) -> str:
    return driver.execute_script(
        "return document.querySelector('#reach td:nth-child(2) span:last-child').textContent"
    )


def test_browser_shows_the_reach_margin_as_a_lower_bound(browser):
    """r_T is a lower bound, the true margin in [r_T, r_T + error]: the page
    says so in the text report's words, not as r_T +- error."""
    from cdpm.viewer import InspectionPage

    robot = cdpm.load_robot(VERTICAL_SPEC)
    report = cdpm.analyze_pose(robot, "nominal")
    value, error = report.reach_margin
    assert error > 0  # a pose whose margin is not exact
    horizon = f"within T = {report.reach.horizon:.3g} s"
    driver = browser
    with InspectionPage(robot, "nominal") as page:
        driver.get(page.url)
        driver.execute_async_script(_WAIT_SEQ, 0)
        shown = _reach_text(driver)
        assert shown == f"{value:.4g} m (a lower bound: at most {error:.2g} more) {horizon}"
        assert "±" not in shown
        # the words of the text report (cdpm analyze)
        assert f"r_T = {value:.4g} m (a lower bound: at most {error:.2g} more)" in str(report)
        seq = _seq(driver)
        driver.find_element("css selector", "#pose-picker button[data-pose=horizontal]").click()
        driver.execute_async_script(_WAIT_SEQ, seq)
        exact = cdpm.analyze_pose(robot, "horizontal")
        assert exact.reach_margin == (0.0, 0.0)
        assert _reach_text(driver) == f"0 m (exact) within T = {exact.reach.horizon:.3g} s"
        ports, server = [page.port, _scene_port(page)], page.viewer.server_pid
    for port in ports:
        assert _listening(port) == []
    if os.path.isdir("/proc"):
        assert not alive(server)
