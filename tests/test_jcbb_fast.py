"""The compiled JCBB of the advanced part (helpers.advanced.jcbb_fast) returns what the course's jcbb returns:
the same association, joint distance and number of expanded nodes, with and without a node budget."""
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_jcbb import random_case

from helpers.advanced.jcbb_fast import jcbb as jcbb_fast
from helpers.association.jcbb import jcbb
from helpers.association.scenarios import range_bearing_scenario


def assert_same(course, fast):
    assert np.array_equal(course.idx, fast.idx)
    assert course.d2 == pytest.approx(fast.d2, rel=1e-9, abs=1e-12)
    assert course.stats["nodes"] == fast.stats["nodes"]
    assert course.stats["level_order"].tolist() == fast.stats["level_order"].tolist()
    assert course.budget_exhausted == fast.budget_exhausted and course.algorithm == fast.algorithm == "jcbb"


@settings(max_examples=200, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 6), m_clutter=st.integers(0, 3),
       n_sigma=st.sampled_from([1.5, 2.0, 3.0]), d=st.sampled_from([1, 2, 2, 3]))
def test_same_as_the_course_jcbb_on_random_scenes(seed, n, m_clutter, n_sigma, d):
    density, Y = random_case(seed, n, m_clutter, n_sigma, d=d)
    assert_same(jcbb(density, Y, n_sigma=n_sigma), jcbb_fast(density, Y, n_sigma=n_sigma))


@pytest.mark.parametrize("seed", range(12))
def test_same_as_the_course_jcbb_on_range_bearing_scenes(seed):
    sc = range_bearing_scenario(seed=(7, seed), n_landmarks=150, n_visible=20, n_clutter=2, candidate_range=None)
    assert_same(jcbb(sc.density, sc.Y), jcbb_fast(sc.density, sc.Y))
    assert_same(jcbb(sc.density, sc.Y, max_nodes=30), jcbb_fast(sc.density, sc.Y, max_nodes=30))


def test_bad_budget_is_named():
    sc = range_bearing_scenario(seed=1, n_landmarks=40, n_visible=8)
    with pytest.raises(ValueError, match="max_nodes"):
        jcbb_fast(sc.density, sc.Y, max_nodes=0)
