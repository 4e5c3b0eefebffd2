"""Slider update latency of the pose inspector, and the cost of one display.

Measures, on the paper's 2-link model (or another spec):

- ``update``: slider value set -> observer -> analysis -> every meshcat
  command acknowledged by the server (the time a user waits before the
  browser gets the new scene; the browser then renders in its next frame);
- ``display`` split into ``analysis`` (equilibrium, linearisation, POC
  verdict) and ``draw`` (zmq round trips to the meshcat server);
- ``pose_state`` alone (no meshcat), and a headless picture.

Run: ``python benchmarks/bench_viewer.py [--quick] [--spec SPEC] [--browser]``.
``--browser`` keeps a headless Chromium connected during the run so the
server also forwards every command to a websocket. Numbers are wall time on
a shared machine: noisy, compare medians.
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


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="fewer steps (a few seconds)")
    parser.add_argument("--spec", default=str(PAPER_SPEC), help="cable spec (default: paper model)")
    parser.add_argument("--browser", action="store_true", help="keep headless Chromium connected")
    args = parser.parse_args(argv)
    steps = 40 if args.quick else 300

    import cdpm
    from cdpm.picture import render_pose
    from cdpm.viewer import PoseInspector, Viewer, pose_state

    robot = cdpm.load_robot(args.spec)
    rng = np.random.default_rng(0)
    print(f"model {Path(args.spec).name}: nv={robot.nv}, m={robot.n_cables}, {steps} steps")

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
            f"slider update median {1e3 * statistics.median(update):.1f} ms {verdict} "
            f"the {target:.0f} ms target"
        )
    finally:
        viewer.close()
        if browser is not None:
            browser.terminate()
            browser.wait()
    return 0


if __name__ == "__main__":
    sys.exit(main())
