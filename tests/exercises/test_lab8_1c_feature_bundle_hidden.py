"""Lab 8, task 1c: the feature bundle of the lab's demo state (hidden tests: the answer key's values).

The demo state (helpers.state_slam.lab_demo_state) seen through the lab camera; the expected h and J are the
answer key's, recorded in the fixture ``lab8_1c_feature_bundle_hidden`` (tools/fixture_recipes_lab8.py).
"""
from __future__ import annotations

import numpy as np
import pytest
from feedback import expect_close, expect_true, fixture
from scipy.stats import chi2, norm

from helpers.camera import load_lab_camera
from helpers.state_slam import lab_demo_state

#: The handout's console output (task 3c): landmarks 2..8 matched features at these pixels (x, y).
HANDOUT_MATCHES = {2: (1679, 810), 3: (1599, 301), 4: (316, 254), 5: (937, 661), 6: (1059, 783), 7: (826, 324),
                   8: (1018, 170)}
#: Their squared Mahalanobis distances from the predicted features of the demo state (no measurement noise).
HANDOUT_D2 = {2: 1.1615, 3: 4.7747, 4: 0.2081, 5: 0.0156, 6: 0.1101, 7: 0.8733, 8: 0.3399}


@pytest.fixture(scope="module")
def demo():
    return lab_demo_state(), load_lab_camera()


@pytest.mark.parametrize("name", ["sel", "all"])
def test_demo_bundle_equals_the_answer_key(demo, name):
    """The demo state's bundle h and J equal the answer key's (selections [5, 2, 8] and all nine landmarks)"""
    state, camera = demo
    ref = fixture("lab8_1c_feature_bundle_hidden")
    idx = ref["idx_" + name].tolist()
    h, J = state.predict_feature_bundle(camera, idx)
    # different but correct orders of the same sums round differently by ~1e-13 relative
    expect_close(h, ref["h_" + name], "h of the demo state", given={"idx_landmarks": idx}, rtol=1e-9, atol=1e-9)
    expect_close(J, ref["J_" + name], "J of the demo state", given={"idx_landmarks": idx}, rtol=1e-9, atol=1e-7)


def test_handout_matches_lie_in_the_predicted_3_sigma_ellipses(demo):
    """The handout's seven matched features lie inside the 3σ ellipses of the predicted features (P_h = J P Jᵀ)"""
    state, camera = demo
    idx = sorted(HANDOUT_MATCHES)
    h, J = state.predict_feature_bundle(camera, idx)
    P = J @ state.density.cov @ J.T
    gate = chi2.ppf(norm.cdf(3.0) - norm.cdf(-3.0), 2)
    for k, j in enumerate(idx):
        rows = slice(2 * k, 2 * k + 2)
        nu = np.asarray(HANDOUT_MATCHES[j], float) - h[rows]
        d2 = float(nu @ np.linalg.solve(P[rows, rows], nu))
        expect_close(d2, HANDOUT_D2[j], "squared Mahalanobis distance of the handout's match of landmark %d" % j,
                     given={"match": HANDOUT_MATCHES[j], "predicted pixel": h[rows]}, rtol=0, atol=5e-4)
        expect_true(d2 <= gate, "landmark %d's match is inside the 3σ gate χ²₂ = %.3f" % (j, gate), actual=d2)
