"""Screenshots of the monitor as a person sees it, in Rerun's web viewer.

Records a short run with the monitor's own code (`hamnet.monitor.outputs.open_recording`,
`MonitorView`, its decoders) fed with real messages: a real sim held still (episodes of a
few steps), real perception clouds (the perception core with a random UniCORN), scripted
policy actions, safety statistics and trainer metrics of a run that learns (the trainer's
own `encode_metrics`). Also records `hamnet sim --show-scene`'s file. Each file is served
with `rerun FILE --serve-web`, opened in headless Chromium (the system's, driven by
Playwright: `pip install -e .[screenshots]`, `apt-get install chromium`) and saved as PNG
under docs/images/monitor/. First the layout as it opens, then before any trainer metrics,
then the scene file.

    .venv/bin/python scripts/monitor_screenshots.py [--out docs/images/monitor]
    .venv/bin/python scripts/monitor_screenshots.py --recording runs/ppo-easy/monitor.rrd \
        --name ppo-easy-training --out docs/images      # a real run's recording, as it is
"""

from __future__ import annotations

import argparse
import os
import signal
import subprocess
import sys
import tempfile
import time
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import numpy as np
import torch

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the real-message helpers live in tests/monitor/recorded.py

from hamnet.messages.tokens import encode as encode_tokens
from hamnet.monitor.config import OutputConfig, ViewConfig
from hamnet.monitor.decode import (
    decode_action,
    decode_event,
    decode_metrics,
    decode_scene,
    decode_state,
    decode_tokens,
    decode_transition,
)
from hamnet.monitor.outputs import add_footer, open_recording
from hamnet.monitor.view import MonitorView
from hamnet.perception.config import CloudConfig
from hamnet.perception.core import Perception
from hamnet.perception.messages import decode_scene as perception_scene
from hamnet.perception.messages import decode_state as perception_state
from hamnet.perception.unicorn import UniCORN
from hamnet.sim.scene_view import save_scene
from tests.monitor.recorded import B, action, metrics, sim_messages, statistics_event

STEPS, TIMEOUT = 60, 12
"""Sim steps recorded, and steps per episode."""
ITERATION_EVERY = 2
"""Sim steps between two trainer iterations (the learning curves spread over the steps)."""
VIEWPORT = {"width": 1600, "height": 1000}
CHROMIUM = "/usr/bin/chromium"
RENDER_WAIT_S = 25.0
"""Seconds the viewer gets to load its wasm, the data and draw."""


def record(path: Path, with_metrics: bool) -> None:
    """Write the monitor's recording of a short run to `path`."""
    rng = np.random.default_rng(0)
    torch.manual_seed(0)
    encoder = UniCORN()
    clouds = CloudConfig()
    perception: Perception | None = None
    recording, saved = open_recording(OutputConfig(save=path))
    view = MonitorView(recording, ViewConfig(env=0))
    iteration = 0
    for topic, message in sim_messages(STEPS, TIMEOUT):
        step = message.header.step
        if topic == "scene":
            view.on_scene(decode_scene(message, 0))
            scenes = perception_scene(message, None, clouds.num_points)
            if perception is None:
                perception = Perception(encoder, B, clouds)
            perception.start_episodes(scenes)
        elif topic == "state":
            view.on_state(decode_state(message, 0))
            state = perception_state(message, None)
            percepts = perception.step(torch.from_numpy(state.object_pose))
            view.on_clouds(decode_tokens(encode_tokens(percepts, step, state.episode_ids, 0), 0))
            view.on_action(decode_action(action(step, rng), 0))
            if step % 10 == 5:
                view.on_event(decode_event(statistics_event(step)))
            if with_metrics and step % ITERATION_EVERY == 1:
                iteration += 1
                view.on_metrics(decode_metrics(metrics(iteration, rng)))
        else:
            view.on_transition(decode_transition(message, 0, drawn=True))
    recording.flush()
    recording.disconnect()
    add_footer(saved)


@contextmanager
def served(path: Path, web_port: int, grpc_port: int) -> Iterator[str]:
    """`rerun FILE --serve-web`, as a person opens a file in a browser; yields the URL."""
    command = [str(Path(sys.executable).parent / "rerun"), str(path), "--serve-web", "--web-viewer-port", str(web_port),
               "--port", str(grpc_port), "--renderer", "webgl"]  # fmt: skip
    process = subprocess.Popen(command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                               start_new_session=True)  # fmt: skip
    try:
        time.sleep(3.0)
        yield f"http://localhost:{web_port}/?url=rerun%2Bhttp://localhost:{grpc_port}/proxy"
    finally:
        os.killpg(process.pid, signal.SIGTERM)  # the wrapper and the viewer binary it starts
        process.wait(timeout=10)


def screenshot(url: str, out: Path, wait_s: float = RENDER_WAIT_S) -> None:
    """Open `url` in headless Chromium and save what it shows to `out` after `wait_s`."""
    from playwright.sync_api import sync_playwright  # the optional extra `screenshots`

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(
            executable_path=CHROMIUM, headless=True,
            args=["--use-gl=angle", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
                  "--ignore-gpu-blocklist"],
        )  # fmt: skip
        page = browser.new_page(viewport=VIEWPORT)
        page.goto(url)
        page.wait_for_timeout(wait_s * 1000)
        page.screenshot(path=str(out))
        browser.close()
    print(out)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=Path("docs/images/monitor"))
    parser.add_argument("--recording", type=Path, nargs="*", default=[],
                        help="instead: screenshot these .rrd files (a real run's monitor.rrd) "
                        "as <out>/<name>.png")  # fmt: skip
    parser.add_argument("--name", nargs="*", default=[], help="the PNG names of --recording "
                        "(default: each file's parent folder)")  # fmt: skip
    parser.add_argument("--wait-s", type=float, default=RENDER_WAIT_S,
                        help="seconds the viewer loads and draws before the screenshot (a run's "
                        "file of a few MB streams in for a minute or more on a busy CPU)")  # fmt: skip
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    if args.recording:
        names = args.name or [path.resolve().parent.name for path in args.recording]
        for index, (name, path) in enumerate(zip(names, args.recording, strict=True)):
            with served(path, 9190 + index, 9977 + index) as url:
                screenshot(url, args.out / f"{name}.png", args.wait_s)
        return
    with tempfile.TemporaryDirectory() as folder:
        files = {"training": Path(folder) / "training.rrd", "no-trainer": Path(folder) / "no-trainer.rrd",
                 "show-scene": Path(folder) / "scene.rrd"}  # fmt: skip
        record(files["training"], with_metrics=True)
        record(files["no-trainer"], with_metrics=False)
        save_scene(files["show-scene"], seed=3)
        for index, (name, path) in enumerate(files.items()):
            with served(path, 9190 + index, 9977 + index) as url:
                screenshot(url, args.out / f"{name}.png")


if __name__ == "__main__":
    main()
