"""Lab 8, task 2a: individual compatibility on the lab's published cases (hidden tests).

The Lab 8 template's unit-test fixture (data/lab8_compatibility_fixture.json: a 1-landmark density with 3 features
and a 3-landmark density with 13 features, 3σ) and the demo's bundle density with the seven matches of the
handout's console output (fixture ``lab8_2a_individual_compatibility_hidden``).
"""
from __future__ import annotations

import numpy as np
import pytest
from feedback import expect_equal, fixture
from scipy.stats import norm

from helpers.association.compatibility import individual_compatibility, lab_test_fixture
from helpers.gaussian import Gaussian


@pytest.fixture(scope="module")
def lab():
    return lab_test_fixture()


def test_template_one_landmark_three_features(lab):
    """The template's 1-landmark case: only feature 1 is compatible (squared distances 26.6, 1.34, 27.1)"""
    got = [individual_compatibility(i, 0, lab["Y3"], lab["density_1"], lab["n_sigma"]) for i in range(3)]
    expect_equal(got, [False, True, False], "compatibility of features 0, 1, 2 with landmark 0",
                 given={"Y3": lab["Y3"], "mu": lab["density_1"].mean})


def test_template_three_landmarks_thirteen_features(lab):
    """The template's 3-landmark case: exactly the pairs (i, j) = (6,0), (7,1), (9,1), (10,2), (11,2), (12,2)"""
    got = sorted((i, j) for i in range(13) for j in range(3)
                 if individual_compatibility(i, j, lab["Y13"], lab["density_3"], lab["n_sigma"]))
    expect_equal(got, [(6, 0), (7, 1), (9, 1), (10, 2), (11, 2), (12, 2)], "the compatible pairs (i, j)",
                 given={"Y13": lab["Y13"], "mu": lab["density_3"].mean})


def test_template_pair_just_outside_the_gate(lab):
    """Feature 5 with landmark 0 (d² = 12.02) is just outside the 3σ gate (11.83) and inside a 99.8 % gate (12.43)"""
    expect_equal(individual_compatibility(5, 0, lab["Y13"], lab["density_3"], 3.0), False,
                 "feature 5 with landmark 0 at n_sigma = 3", given={"y_5": lab["Y13"][:, 5]})
    loose = float(norm.ppf((1 + 0.998) / 2))
    expect_equal(individual_compatibility(5, 0, lab["Y13"], lab["density_3"], loose), True,
                 "feature 5 with landmark 0 at n_sigma = %.4f (c = 0.998)" % loose, given={"y_5": lab["Y13"][:, 5]})


def test_demo_handout_matches():
    """On the demo's bundle density, each of the handout's seven matches is compatible with its own landmark only"""
    ref = fixture("lab8_2a_individual_compatibility_hidden")
    density = Gaussian.from_cov(ref["mean"], ref["cov"])
    Y = ref["Y"]
    got = np.array([[individual_compatibility(i, j, Y, density) for i in range(Y.shape[1])] for j in range(9)])
    expect_equal(got, ref["compatible"], "compatible[j, i] of landmark j (rows) with match i (columns)",
                 given={"Y (the handout's matches)": Y, "d² (rows: landmarks)": ref["d2"]})
