"""Recipes of the Lab 8 grading fixtures (``python tools/exercise_fixtures.py record|check NAME``).

Every Lab 8 fixture is a hidden one (``<exercise>_hidden``): the public tests of the lab's exercises use hand-made
inputs only. The hidden tests check the answer key's values on the lab's own case, the demo state of Lab 8 seen
through the lab camera (handout part 3c):

- lab8_1c_feature_bundle_hidden: h and J of the demo state for two selections;
- lab8_2a_individual_compatibility_hidden and lab8_2c_joint_compatibility_hidden: the demo's predicted bundle
  density (what task 1c produces, recorded so that 2a and 2c need not call it), the seven matches of the handout's
  console output, and the answer key's verdicts and surprisals on them;
- lab8_3a_detect_features_hidden: three 120 × 120 crops of the rendered lab scene (helpers.scene) around
  landmarks 5 (a board corner), 7 (a sticker on the texture) and 8 (the floating card), their true projections,
  and the answer key's features on them for three detector settings.
"""
from __future__ import annotations

import numpy as np
from exercise_fixtures import FIXTURES, recipe

#: The seven matches of the handout's console output (task 3c): landmarks 2..8 at these pixels (x, y).
HANDOUT_MATCHES = np.array([[1679, 1599, 316, 937, 1059, 826, 1018],
                            [810, 301, 254, 661, 783, 324, 170]], dtype=float)
HANDOUT_IDX = np.array([-1, -1, 0, 1, 2, 3, 4, 5, 6])

#: Crops of the rendered scene: (first row, first column) of a 120 × 120 window, and the landmark inside it.
CROPS = ((602, 876, 5), (266, 771, 7), (107, 958, 8))
CROP_SIZE = 120

#: Detector settings recorded on every crop: the workbook demo's (helpers.association.lab_demo.DEMO_DETECTOR), the
#: lab's plain detector (no smoothing, no suppression; a 20 % quality level keeps the file small) and a Harris
#: detector capped at the 25 strongest.
DETECTORS = (
    ("demo", dict(max_features=10000, method="shi-tomasi", threshold=0.01, block_size=5, nms_radius=3,
                  smoothing=1.0)),
    ("plain", dict(threshold=0.2)),
    ("harris", dict(method="harris", nms_radius=3, max_features=25)),
)


def _demo():
    from helpers.camera import load_lab_camera
    from helpers.state_slam import lab_demo_state

    return lab_demo_state(), load_lab_camera()


# h (≈ 1e3 px) and J (≤ 2e3 px/m) are sums of a few products of O(1) terms: rounding differs between BLAS and CPUs
# by a few 1e-13 relative; 1e-9 sits far above it and far below any change of the model.
@recipe("lab8_1c_feature_bundle_hidden", rtol=1e-9, atol=1e-9)
def feature_bundle_hidden():
    state, camera = _demo()
    out = {}
    for name, idx in (("sel", [5, 2, 8]), ("all", list(range(9)))):
        h, J = state.predict_feature_bundle(camera, idx)
        out["idx_" + name], out["h_" + name], out["J_" + name] = np.array(idx), h, J
    return out


def _demo_bundle():
    """The demo's bundle density of all nine landmarks as (mean, cov), and the Gaussian the tests build from it."""
    from helpers.gaussian import Gaussian

    state, camera = _demo()
    density = state.predict_feature_bundle_density(camera, list(range(9)))
    mean, cov = density.mean, density.cov
    return mean, cov, Gaussian.from_cov(mean, cov)


# The bundle covariance (σ 5–13 px, κ ≈ 1e3 at most) through a QR and back: relative rounding ~1e-13; the Mahalanobis
# distances (≤ 30) and surprisals (≈ 1e2) through a Cholesky factor of it keep ~1e-12. 1e-9 is far above both.
@recipe("lab8_2a_individual_compatibility_hidden", rtol=1e-9, atol=1e-9)
def individual_compatibility_hidden():
    from helpers.association.compatibility import individual_compatibility

    mean, cov, density = _demo_bundle()
    m = HANDOUT_MATCHES.shape[1]
    verdict = np.array([[individual_compatibility(i, j, HANDOUT_MATCHES, density) for i in range(m)]
                        for j in range(9)])
    d2 = np.array([[float(density.marginal([2 * j, 2 * j + 1]).sq_mahalanobis(HANDOUT_MATCHES[:, i]))
                    for i in range(m)] for j in range(9)])
    return {"mean": mean, "cov": cov, "Y": HANDOUT_MATCHES, "compatible": verdict, "d2": d2}


@recipe("lab8_2c_joint_compatibility_hidden", rtol=1e-9, atol=1e-9)
def joint_compatibility_hidden():
    from helpers.association.compatibility import joint_compatibility, uniform_surprisal

    mean, cov, density = _demo_bundle()
    sU = uniform_surprisal((1920, 1440))
    swapped = HANDOUT_IDX.copy()
    swapped[[5, 6]] = swapped[[6, 5]]               # landmarks 5 and 6 take each other's features
    partial = HANDOUT_IDX.copy()
    partial[[3, 7]] = -1                            # landmarks 3 and 7 left unassociated
    cases = np.vstack([HANDOUT_IDX, np.full(9, -1), swapped, partial])
    results = [joint_compatibility(idx, sU, HANDOUT_MATCHES, density) for idx in cases]
    return {"mean": mean, "cov": cov, "Y": HANDOUT_MATCHES, "sU": sU, "idx": cases,
            "compatible": np.array([r[0] for r in results]), "surprisal": np.array([r[1] for r in results])}


def _scene_crops() -> tuple[np.ndarray, np.ndarray]:
    """The three crops (3, 120, 120) uint8 and the true pixels of their landmarks in crop coordinates (2, 3).

    The render's float32 texture (cv2.remap) may round differently on another CPU, so the crops are the recorded
    INPUT: once stored, they are read back from the fixture and only the detector's outputs are recomputed."""
    path = FIXTURES / "lab8_3a_detect_features_hidden.npz"
    if path.exists():
        with np.load(path) as stored:
            return stored["images"], stored["truth"]
    from helpers.camera import load_lab_camera
    from helpers.scene import LAB_LANDMARKS, render_lab_scene

    camera = load_lab_camera()
    scene = render_lab_scene(camera)
    truth = camera.world_to_pixel(LAB_LANDMARKS.T, scene.pose)
    images = np.stack([scene.image[r:r + CROP_SIZE, c:c + CROP_SIZE] for r, c, _ in CROPS])
    local = np.array([[truth[0, j] - c, truth[1, j] - r] for r, c, j in CROPS]).T
    return images, local


# Scores are float32 responses from OpenCV (its SIMD paths may round the last bit differently): rtol 1e-5. The
# features are stored in raster order (the order of equal scores is the test's business, not the fixture's).
@recipe("lab8_3a_detect_features_hidden", rtol=1e-5, atol=1e-9)
def detect_features_hidden():
    from helpers.features import detect_features

    images, truth = _scene_crops()
    out = {"images": images, "truth": truth}
    for k, image in enumerate(images):
        for name, kwargs in DETECTORS:
            f = detect_features(image, **kwargs)
            order = np.lexsort((f.x, f.y))
            out["%s_%d_xy" % (name, k)] = np.vstack([f.x[order], f.y[order]]).astype(np.int64)
            out["%s_%d_score" % (name, k)] = f.score[order].astype(np.float64)
    return out
