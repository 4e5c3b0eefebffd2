"""Slider update latency of the pose inspector and the inspection page, and
the cost of one display.

Measures, on the paper's 2-link model (or another spec):

- ``page``: the inspection page of ``cdpm view`` in headless Chromium
  (selenium + chromedriver): input-to-panel time, measured in the page with
  ``performance.now()`` from a slider's input event to the end of the
  panel's DOM update (JSON request, one ``cdpm.analyze_pose``, the scene's
  meshcat commands, rendering the panel). Two runs: ``step`` moves the
  slider and waits for the panel each time; ``drag`` fires input events at
  60 Hz without waiting, as a dragged slider does (the page coalesces the
  moves that arrive while a request is in flight: each time is from the
  oldest move a request carries);
- ``update``: notebook slider value set -> observer -> analysis -> every
  meshcat command acknowledged by the server;
- ``display`` split into ``analysis`` (equilibrium, linearisation, POC
  verdict) and ``draw`` (zmq round trips to the meshcat server);
- ``pose_state`` alone (no meshcat), and a headless picture.

Run: ``python benchmarks/bench_viewer.py [--quick] [--spec SPEC] [--browser]
[--no-page]``. ``--browser`` keeps a headless Chromium connected during the
notebook run so the server also forwards every command to a websocket. The
page run needs Debian's ``chromium`` and ``chromium-driver`` and selenium;
without them it is left out with a note. Numbers are wall time on a shared
machine: noisy, compare medians.
"""

from __future__ import annotations

import argparse
import math
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PAPER_SPEC = ROOT / "models" / "two_link_planar" / "two_link_planar.yaml"


def _summary(name: str, seconds: list[float]) -> str:
    ms = np.array(seconds) * 1e3
    return (
        f"{name:<22} n={len(ms):4d}  median {np.median(ms):7.2f} ms  "
        f"p95 {np.percentile(ms, 95):7.2f} ms  max {ms.max():7.2f} ms"
    )


def _browser(url: str):
    chromium = shutil.which("chromium")
    if chromium is None:
        print("(no chromium: running without a connected browser)")
        return None
    profile = tempfile.mkdtemp(prefix="cdpm-bench-chromium-")
    return subprocess.Popen(
        [
            chromium,
            "--headless",
            "--no-sandbox",
            "--disable-gpu",
            "--use-gl=swiftshader",
            "--enable-unsafe-swiftshader",
            "--no-first-run",
            "--disable-background-networking",
            f"--user-data-dir={profile}",
            "--remote-debugging-port=0",
            url,
        ],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )


#: JavaScript: move slider 0 to arguments[0], resolve when the panel has rendered
_STEP = """
const [value, done] = arguments;
const panel = document.getElementById("panel");
const seq = Number(panel.dataset.seq);
new MutationObserver((_, observer) => {
  if (Number(panel.dataset.seq) > seq) { observer.disconnect(); done(window.cdpm.timings.at(-1)); }
}).observe(panel, { attributes: true, attributeFilter: ["data-seq"] });
const slider = document.getElementById("slider-0");
slider.value = value;
slider.dispatchEvent(new Event("input", { bubbles: true }));
"""

#: JavaScript: drag slider 0 across arguments[0] values at 60 Hz, resolve when idle
_DRAG = """
const [values, done] = arguments;
const slider = document.getElementById("slider-0");
const first = window.cdpm.timings.length;
let k = 0;
const timer = setInterval(() => {
  slider.value = values[k++];
  slider.dispatchEvent(new Event("input", { bubbles: true }));
  if (k < values.length) return;
  clearInterval(timer);
  const wait = () => window.cdpm.busy() ? setTimeout(wait, 5) : done({
    timings: window.cdpm.timings.slice(first), server: window.cdpm.server.slice(first),
  });
  wait();
}, 1000 / 60);
"""


def _page_driver(profile: str):
    """A headless Chromium under chromedriver with its profile in ``profile``,
    or None (with a note) when missing."""
    chromium, chromedriver = shutil.which("chromium"), shutil.which("chromedriver")
    try:
        from selenium import webdriver
        from selenium.webdriver.chrome.service import Service
    except ImportError:
        webdriver = None
    if webdriver is None or chromium is None or chromedriver is None:
        print("(page: needs chromium, chromium-driver and selenium; left out)")
        return None
    options = webdriver.ChromeOptions()
    options.binary_location = chromium
    for flag in [
        "--headless=new",
        "--no-sandbox",
        "--disable-gpu",
        "--use-gl=swiftshader",
        "--enable-unsafe-swiftshader",
        "--no-first-run",
        "--disable-background-networking",
        "--window-size=1280,900",
        f"--user-data-dir={profile}",
    ]:
        options.add_argument(flag)
    driver = webdriver.Chrome(service=Service(executable_path=chromedriver), options=options)
    driver.set_script_timeout(120)
    return driver


def _bench_page(robot, steps: int) -> list[float] | None:
    """Input-to-panel times [s] of the inspection page (step and drag runs)."""
    from cdpm.viewer import InspectionPage

    profile = tempfile.mkdtemp(prefix="cdpm-bench-page-")
    driver = _page_driver(profile)
    if driver is None:
        shutil.rmtree(profile, ignore_errors=True)
        return None
    try:
        with InspectionPage(robot) as page:
            driver.get(page.url)
            driver.execute_script(
                "return new Promise((done) => { const p = document.getElementById('panel');"
                "const check = () => Number(p.dataset.seq) > 0 ? done() : setTimeout(check, 20);"
                "check(); });"
            )
            low = float(driver.execute_script("return document.getElementById('slider-0').min"))
            high = float(driver.execute_script("return document.getElementById('slider-0').max"))
            values = np.linspace(low + 0.05 * (high - low), high - 0.05 * (high - low), steps)
            for v in values[:5]:  # warm up: first requests open the connection
                driver.execute_async_script(_STEP, str(v))
            step = [driver.execute_async_script(_STEP, str(v)) / 1e3 for v in values]
            print(_summary("page: step", step))
            drag = driver.execute_async_script(_DRAG, [str(v) for v in values[::-1]])
            times = [ms / 1e3 for ms in drag["timings"]]
            print(_summary("page: drag at 60 Hz", times))
            print(
                f"{'':<22} {len(values)} input events -> {len(times)} requests (coalesced); "
                f"server analysis median "
                f"{1e3 * statistics.median(s['analysis'] for s in drag['server']):.2f} ms, "
                f"scene median {1e3 * statistics.median(s['draw'] for s in drag['server']):.2f} ms"
            )
            return step + times
    finally:
        driver.quit()
        shutil.rmtree(profile, ignore_errors=True)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps (a few seconds)")
    parser.add_argument("--spec", default=str(PAPER_SPEC), help="cable spec (default: paper model)")
    parser.add_argument("--browser", action="store_true", help="keep headless Chromium connected")
    parser.add_argument("--no-page", action="store_true", help="leave out the inspection page")
    args = parser.parse_args(argv)
    steps = 40 if args.quick else 300

    import cdpm
    from cdpm.plotting.picture import render_pose
    from cdpm.viewer import PoseInspector, Viewer, pose_state

    robot = cdpm.load_robot(args.spec)
    rng = np.random.default_rng(0)
    print(f"model {Path(args.spec).name}: nv={robot.nv}, m={robot.n_cables}, {steps} steps")

    page = None if args.no_page else _bench_page(robot, steps)

    t0 = time.perf_counter()
    viewer = Viewer(robot)
    print(f"viewer start (server + scene): {1e3 * (time.perf_counter() - t0):.0f} ms")
    browser = _browser(viewer.url()) if args.browser else None
    if browser is not None:
        time.sleep(3.0)
    try:
        inspector = PoseInspector(robot, viewer=viewer)
        inspector.widget()
        name = robot.coordinate_names[0]
        lo, hi = inspector.ranges[name]
        slider = inspector.sliders[name]
        # sweep like a dragged slider: small steps along the range
        values = np.linspace(lo + 0.05 * (hi - lo), hi - 0.05 * (hi - lo), steps)
        update, analysis, draw = [], [], []
        for v in values:
            t = time.perf_counter()
            slider.value = float(v)
            update.append(time.perf_counter() - t)
            analysis.append(viewer.last_display_seconds["analysis"])
            draw.append(viewer.last_display_seconds["draw"])
        print(_summary("slider update", update))
        print(_summary("  analysis", analysis))
        print(_summary("  draw (meshcat)", draw))

        random_display = []
        for _ in range(steps):
            lo_hi = np.array(list(inspector.ranges.values()))
            natural = rng.uniform(lo_hi[:, 0], lo_hi[:, 1])
            t = time.perf_counter()
            viewer.display(natural)
            random_display.append(time.perf_counter() - t)
        print(_summary("display (random q)", random_display))

        states = []
        for _ in range(steps):
            natural = rng.uniform(-math.pi, math.pi, robot.nv)
            t = time.perf_counter()
            pose_state(robot, natural)
            states.append(time.perf_counter() - t)
        print(_summary("pose_state (no view)", states))

        pictures = []
        for _ in range(3 if args.quick else 10):
            t = time.perf_counter()
            render_pose(robot, None, Path(tempfile.gettempdir()) / "cdpm-bench.png")
            pictures.append(time.perf_counter() - t)
        print(_summary("picture (PNG)", pictures))
        target = 50.0
        verdict = "meets" if statistics.median(update) * 1e3 < target else "MISSES"
        print(
            f"notebook slider update median {1e3 * statistics.median(update):.1f} ms {verdict} "
            f"the {target:.0f} ms target"
        )
        if page:
            verdict = "meets" if statistics.median(page) * 1e3 < target else "MISSES"
            print(
                f"page input-to-panel median {1e3 * statistics.median(page):.1f} ms, worst "
                f"{1e3 * max(page):.1f} ms: {verdict} the {target:.0f} ms target"
            )
    finally:
        viewer.close()
        if browser is not None:
            browser.terminate()
            browser.wait()
    return 0


if __name__ == "__main__":
    sys.exit(main())
