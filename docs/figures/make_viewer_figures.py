"""Write the README's viewer pictures: ``viewer_playground.png`` and ``viewer_replay.png``.

Run from the repository's root (needs the ``[viz]`` extra and a Chromium, see
:mod:`wbc.viz.browser`)::

    python docs/figures/make_viewer_figures.py [--dir DIR] [--out docs/figures]

* the playground (``wbc play mecanum_gen3``): the gizmo moved 0.35 m and the closed loop given
  2.5 s to follow it;
* a study replay (``wbc view DIR``): Xing et al.'s ``circle_r025/amp_qp`` run at two thirds of
  its duration, read from ``DIR`` (a ``wbc study xing --out DIR`` or ``wbc reproduce``
  folder); without ``--dir`` the quick study is run into a temporary folder first (≈ 1 min).

The same browser code (:class:`wbc.viz.browser.Browser`) takes the browser tests' screenshots.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
RUN = "petric/sine_large/whole_body"


def playground_figure(path: Path, browser) -> None:
    import numpy as np

    import wbc.robots
    from wbc.viz.playground import Playground

    robot = wbc.robots.load("mecanum_gen3")
    with Playground(robot, "daqp", port=0, verbose=False) as play:
        page = browser.open(play.viewer.url)
        goal = play.target.copy()
        goal[:3, 3] += np.array([0.15, 0.3, -0.1])
        play.set_target(goal)
        time.sleep(2.5)
        page.wait_for_timeout(600)
        browser.screenshot(page, path)


def replay_figure(path: Path, folder: Path, browser) -> None:
    import wbc.robots
    from wbc.viz.record import load_recordings
    from wbc.viz.viewer import Viewer

    recordings = load_recordings(folder)
    recording = recordings[RUN]
    with Viewer(wbc.robots.load(recording.robot), port=0, verbose=False) as viewer:
        viewer.replay(recordings, RUN)
        viewer._slider.value = int(0.6 * len(recording))
        page = browser.open(viewer.url)
        page.wait_for_timeout(600)
        browser.screenshot(page, path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--dir", type=Path, default=None,
                        help="a study output folder holding xing/xing_replay.npz")
    parser.add_argument("--out", type=Path, default=HERE, help="where the PNGs go")
    args = parser.parse_args(argv)
    from wbc.viz.browser import Browser

    with tempfile.TemporaryDirectory() as scratch:
        folder = args.dir
        if folder is None:
            folder = Path(scratch)
            subprocess.run([sys.executable, "-m", "wbc.experiments.cli", "study", "xing",
                            "--quick", "--out", str(folder)], check=True,
                           stdout=subprocess.DEVNULL)
        with Browser(width=1000, height=620) as browser:
            playground_figure(args.out / "viewer_playground.png", browser)
            replay_figure(args.out / "viewer_replay.png", folder, browser)
    print(f"wrote {args.out / 'viewer_playground.png'} and {args.out / 'viewer_replay.png'}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
