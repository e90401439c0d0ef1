"""Redraw time of every notebook exploration (issue 40: each redraw under about 0.3 s).

    .venv/bin/python benchmarks/explorations.py [--repeat 2]

Builds each exploration as its notebook does (the precomputation outside the timing) and moves its knobs through
a fixed list of values, each move one ``Exploration.redraw`` (the draw and the PNG the notebook shows), timed
wall and CPU. Prints per exploration the median and the largest redraw, and the median's ratio to the 0.3 s budget;
the coursework exploration's first visit of a new setting (a SLAM run) is printed apart from its cached redraws.
"""
from __future__ import annotations

import argparse
import os
import statistics
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402

from helpers.explore import choice, explore, slider, toggle  # noqa: E402

BUDGET = 0.3


def timed_moves(ex, moves, repeat):
    """(wall, cpu) seconds of each move (a dict of knob values), the fastest of ``repeat`` tries each."""
    wall, cpu = [], []
    for move in moves:
        best = (np.inf, np.inf)
        for _ in range(repeat):
            c0, w0 = time.process_time(), time.perf_counter()
            ex.redraw(**move)
            best = min(best, (time.perf_counter() - w0, time.process_time() - c0))
        wall.append(best[0])
        cpu.append(best[1])
    return wall, cpu


def lab8_rendered():
    from helpers.association.lab_demo import DEMO_DETECTOR
    from helpers.association.lab_explore import draw_snn
    from helpers.camera import load_lab_camera
    from helpers.features import detect_features
    from helpers.scene import LAB_LANDMARKS, render_lab_scene
    from helpers.state_slam import lab_demo_state

    cam = load_lab_camera()
    scene = render_lab_scene(cam, seed=0)
    features = detect_features(scene.image, **DEMO_DETECTOR)
    true_pixels = cam.world_to_pixel(LAB_LANDMARKS.T, scene.pose)
    sd_yaw = float(np.sqrt(lab_demo_state().density.cov[11, 11]))

    def draw(fig, yaw_error, gate, joint, landmark):
        state = lab_demo_state(scene.pose + np.array([0, 0, 0, 0, 0, yaw_error * sd_yaw]))
        x, y = true_pixels[:, landmark] if landmark != "all" else (0.0, 0.0)
        window = None if landmark == "all" else (x - 60, x + 60, y - 60, y + 60)
        draw_snn(fig, scene.image, cam, features, state, gate, joint, true_pixels, window=window)

    ex = explore(draw, figsize=(7.0, 6.2), yaw_error=slider(0.0, 6.0, 0.5, 0.0), gate=slider(1.0, 5.0, 0.5, 3.0),
                 joint=toggle(False), landmark=choice(["all", *range(9)], "all"))
    moves = [{"yaw_error": v} for v in np.arange(0.5, 6.01, 0.5)] + [{"gate": g} for g in (1.0, 2.0, 4.0, 5.0)] \
        + [{"joint": True}, {"landmark": 3}, {"yaw_error": 2.0}, {"landmark": "all"}]
    return "Lab 8, notebook 05 (rendered scene)", ex, moves


def lab8_photos():
    from helpers.association.lab_explore import draw_snn
    from helpers.association.photos import PhotoPrior, photo_trial, prepare_photos
    from helpers.calibration import calibrate_folder
    from helpers.paths import data_dir

    cal = calibrate_folder(data_dir() / "chessboard", (9, 6), 0.025, model="k1k2p1p2")
    photos, cam, board, prior = prepare_photos(cal), cal.camera, cal.views.board, PhotoPrior()
    index = {p.name: i for i, p in enumerate(photos)}

    def draw(fig, photo_name, error_scale, draw, gate, joint):
        i = index[photo_name]
        trial = photo_trial((39, i, draw), photos[i], cam, board, prior, error_scale=error_scale)
        (x0, y0), (x1, y1) = photos[i].corners.min(axis=1) - 40, photos[i].corners.max(axis=1) + 40
        draw_snn(fig, photos[i].image, cam, photos[i].features, prior.state(board, trial.pose_est), gate, joint,
                 photos[i].corners, noise=prior.noise, image_scale=1.0, window=(x0, x1, y0, y1), label=photo_name)

    ex = explore(draw, figsize=(7.0, 6.4), photo_name=choice(list(index), "left01.jpg"),
                 error_scale=slider(0.0, 4.0, 0.5, 1.0), draw=slider(0, 19, 1, 0), gate=slider(1.0, 5.0, 0.5, 3.0),
                 joint=toggle(False))
    moves = [{"error_scale": v} for v in (0.0, 0.5, 1.5, 2.0, 3.0, 4.0)] + [{"draw": t} for t in (1, 2, 3)] \
        + [{"photo_name": n} for n in ("left03.jpg", "left05.jpg", "left12.jpg")] + [{"gate": 2.0}, {"joint": True}]
    return "Lab 8, notebook 05b (photographs)", ex, moves


def l09():
    from helpers.association.explorations import PairingExplorer
    from helpers.association.jcbb import jcbb
    from helpers.association.maximum_likelihood import maximum_likelihood
    from helpers.association.nearest_neighbour import mahalanobis_nn, nearest_neighbour

    algorithms = {"NN": lambda D, Y: nearest_neighbour(D, Y, max_distance=1.0),
                  "ICNN": lambda D, Y: mahalanobis_nn(D, Y, n_sigma=3.0),
                  "ML": lambda D, Y: maximum_likelihood(D, Y, alpha=0.05),
                  "JCBB": lambda D, Y: jcbb(D, Y, n_sigma=3.0, max_nodes=10000)}
    base = dict(n_landmarks=60, size=30.0, n_visible=12, n_clutter=2, pose_sigma=(0.5, 0.5, np.deg2rad(8.0)),
                landmark_sigma=0.05, meas_sigma=0.1, candidate_range=12.0)
    view = PairingExplorer(algorithms, base, seed=81, n_sigma=3.0, max_clutter=20)
    ex = explore(view.draw, figsize=(8, 5.6), n_clutter=slider(0, 20, 1, value=2),
                 heading_error=slider(-3.0, 3.0, 0.25, value=1.0), algorithm=choice(list(algorithms), "ICNN"),
                 trial=slider(0, 199, 1, value=18))
    moves = [{"n_clutter": n} for n in (0, 5, 10, 20)] + [{"heading_error": h} for h in (-2.0, 0.0, 2.0, 3.0)] \
        + [{"algorithm": a} for a in algorithms] + [{"trial": t} for t in (3, 40, 120)]
    return "L09, notebook 08 (pairings)", ex, moves


def coursework():
    from helpers.drivebot.explorations import LoopClosureExplorer

    explorer = LoopClosureExplorer(seed=0)
    t0 = time.perf_counter()
    ex = explore(explorer.draw, figsize=(8.0, 5.6), sensors=choice(["laser", "odometry"], "laser"),
                 noise=choice([0.0, 0.5, 1.0, 2.0, 3.0], 0.0), assumed=choice([0.5, 1.0, 2.0, 3.0], 1.0),
                 closed=toggle(False))
    first = time.perf_counter() - t0
    moves = [{"closed": True}, {"closed": False}, {"assumed": 2.0}, {"assumed": 0.5}, {"closed": True},
             {"assumed": 3.0}, {"assumed": 1.0}]
    return "Coursework, notebook 18 (loop closure)", ex, moves, first


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=2, help="tries per move (the fastest counts)")
    args = parser.parse_args()
    for build in (lab8_rendered, lab8_photos, l09, coursework):
        name, ex, moves, *first = build()
        wall, cpu = timed_moves(ex, moves, args.repeat)
        med = statistics.median(wall)
        print(f"{name:<40} {len(moves):2d} moves: median {med:.3f} s (CPU {statistics.median(cpu):.3f} s), "
              f"largest {max(wall):.3f} s; median / {BUDGET} s budget = {med / BUDGET:.2f}"
              + (f"; first visit of a setting (a SLAM run) {first[0]:.1f} s" if first else ""), flush=True)


if __name__ == "__main__":
    main()
