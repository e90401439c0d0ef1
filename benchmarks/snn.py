"""SNN timing: the lab's "Release vs Debug" comparison, done the Python way (Lab 8 task 3d).

naive      = ``snn_loop`` below: the lab's loops written literally in Python — for every landmark and every
             feature an individual-compatibility test (a 2×2 marginal QR per pair), and a joint-compatibility
             evaluation (joint marginal QR + log-density) per compatible candidate.
vectorised = ``helpers.association.snn.snn``: the gate for all m·n pairs in one expression, and the surprisal
             change of all candidates of a landmark from one conditional (one QR per landmark).

Scene: the rendered lab scene at the reference pose, pose recovered by PnP, the 39-dim demo state, the
workbook's detector capped at 10 000 features, all 9 landmarks selected.

    .venv/bin/python benchmarks/snn.py            # prints the table and the naive/vectorised ratio

Goals (issue 3): vectorised ≥ 100× faster than naive; vectorised SNN on 10 000 features × 9 landmarks ≤ 20 ms.
"""
from __future__ import annotations

import platform
import sys
import time

import numpy as np

from helpers.association.compatibility import individual_compatibility, joint_compatibility, uniform_surprisal
from helpers.association.lab_demo import DEMO_DETECTOR
from helpers.association.snn import snn
from helpers.camera import load_lab_camera
from helpers.features import detect_features
from helpers.scene import recover_pose, render_lab_scene
from helpers.state_slam import lab_demo_state


def snn_loop(density, Y, sU, n_sigma=3.0, enforce_joint_compatibility=False):
    """The lab's SNN written literally: for every landmark j, every feature i not yet taken that passes
    ``individual_compatibility`` is tried with ``joint_compatibility``; j keeps the feature that lowers the
    surprisal most, if any lowers it (the null hypothesis wins only when strictly better)."""
    n, m = density.size // 2, Y.shape[1]
    idx = [-1] * n
    s = n * sU
    taken = set()
    for j in range(n):
        best, ds_best, s_best = -1, np.inf, s
        for i in range(m):
            if i in taken or not individual_compatibility(i, j, Y, density, n_sigma):
                continue
            trial = list(idx)
            trial[j] = i
            jc, s_trial = joint_compatibility(np.array(trial), sU, Y, density, n_sigma)
            if (jc or not enforce_joint_compatibility) and s_trial - s < ds_best:
                best, ds_best, s_best = i, s_trial - s, s_trial
        if best >= 0 and ds_best <= 0.0:
            idx[j], s = best, s_best
            taken.add(best)
    return np.array(idx, dtype=np.intp), float(s)


def best_time(fn, repeats):
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        out = fn()
        times.append(time.perf_counter() - t0)
    return min(times), float(np.median(times)), out


def setup():
    camera = load_lab_camera()
    scene = render_lab_scene(camera)
    pose, _ = recover_pose(scene.image, camera)
    state = lab_demo_state(pose)
    features = detect_features(scene.image, **DEMO_DETECTOR)
    idx_landmarks = np.arange(state.number_landmarks)
    density = state.predict_feature_bundle_density(camera, idx_landmarks)
    return features.Y, density, uniform_surprisal(camera.image_size)


def run(naive_repeats=1, fast_repeats=30):
    Y, density, sU = setup()
    m, n = Y.shape[1], density.size // 2
    rows = []
    for enforce in (False, True):
        t_fast, t_fast_med, (idx_f, s_f) = best_time(
            lambda e=enforce: snn(density, Y, sU, enforce_joint_compatibility=e), fast_repeats)
        t_naive, _, (idx_n, s_n) = best_time(
            lambda e=enforce: snn_loop(density, Y, sU, enforce_joint_compatibility=e), naive_repeats)
        if not (np.array_equal(idx_f, idx_n) and abs(s_f - s_n) <= 1e-9 * abs(s_n)):
            raise RuntimeError("naive and vectorised SNN disagree")
        rows.append((enforce, t_naive, t_fast, t_fast_med, idx_f, s_f))
    return m, n, rows


def main() -> int:
    m, n, rows = run()
    print(f"SNN on the rendered lab scene: m = {m} features, n = {n} landmarks "
          f"(python {platform.python_version()}, numpy {np.__version__})")
    print(f"{'enforce JC':>10} | {'naive (s)':>10} | {'vectorised best (ms)':>20} | {'median (ms)':>11} | {'ratio':>8}")
    ok = True
    for enforce, t_naive, t_fast, t_med, _, _ in rows:
        ratio = t_naive / t_fast
        print(f"{str(enforce):>10} | {t_naive:10.3f} | {1e3 * t_fast:20.2f} | {1e3 * t_med:11.2f} | {ratio:7.0f}×")
        ok &= ratio >= 100 and t_fast <= 0.020
    print(f"association {rows[0][4].tolist()}, surprisal {rows[0][5]:.4f}")
    print(f"goals (ratio ≥ 100×, vectorised ≤ 20 ms): {'met' if ok else 'NOT met'}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
