"""ML interpretation tree: best-first search equals exhaustive enumeration and the Hungarian optimum."""
import itertools

import numpy as np
import pytest

from helpers.association.maximum_likelihood import maximum_likelihood
from helpers.association.ml_tree import (
    assignment_ml,
    greedy_descent,
    hypothesis_cost,
    independent_ml,
    ml_costs,
    ml_tree_search,
    tree_size,
)
from helpers.association.scenarios import range_bearing_scenario
from helpers.gaussian import Gaussian


def independent(mu, sigmas):
    mu = np.asarray(mu, float)
    return Gaussian(mu.ravel(), np.diag(np.repeat(np.asarray(sigmas, float), 2)))


def exhaustive_ml(density, Y, alpha):
    """(labels, cost) of the one-to-one optimum by enumerating every leaf of the tree (small problems only)."""
    _, ell, new = ml_costs(density, Y, alpha)
    K, N = ell.shape
    assert tree_size(N, K)[0] <= 200_000
    best, best_cost = None, np.inf
    for labels in itertools.product(range(-1, N), repeat=K):
        paired = [k for k in labels if k >= 0]
        if len(paired) == len(set(paired)) and hypothesis_cost(ell, new, list(labels)) < best_cost:
            best, best_cost = labels, hypothesis_cost(ell, new, list(labels))
    return np.asarray(best, dtype=np.intp), float(best_cost)


def test_tree_size():
    assert tree_size(3, 2) == (16, 1 + 4 + 16)
    assert tree_size(0, 3) == (1, 4)
    assert tree_size(24, 12)[0] == 25 ** 12
    with pytest.raises(ValueError, match="n_observations"):
        tree_size(3, -1)


def test_two_observations_competing_for_one_landmark():
    # both observations prefer landmark 0; one-to-one forces a choice, the tree finds the cheaper one
    density = independent([[0, 0], [1, 0]], [0.4, 0.4])
    Y = np.array([[0.2, 0.0], [0.45, 0.0]]).T
    alpha = 1e-3
    own = independent_ml(density, Y, alpha)
    assert own.tolist() == [0, 0]                                     # independently, both take landmark 0
    best = ml_tree_search(density, Y, alpha)
    labels, cost = exhaustive_ml(density, Y, alpha)
    assert best.labels.tolist() == labels.tolist() and best.cost == pytest.approx(cost)
    assert sorted(best.labels.tolist()) == [0, 1]


@pytest.mark.parametrize("seed", range(6))
@pytest.mark.parametrize("alpha", [1e-4, 1e-2])
def test_best_first_equals_exhaustive_and_assignment(seed, alpha):
    sc = range_bearing_scenario(seed=seed, n_landmarks=30, n_visible=4, n_clutter=1,
                                pose_sigma=(0.3, 0.3, np.deg2rad(10.0)), candidate_range=7.0)
    if (sc.n + 1) ** sc.m > 200_000:
        pytest.skip("tree too large for the exhaustive reference")
    best = ml_tree_search(sc.density, sc.Y, alpha)
    _, ex_cost = exhaustive_ml(sc.density, sc.Y, alpha)
    _, as_cost = assignment_ml(sc.density, sc.Y, alpha)
    assert best.cost == pytest.approx(ex_cost, abs=1e-9) and best.cost == pytest.approx(as_cost, abs=1e-9)
    assert not best.budget_exhausted and best.expanded >= sc.m
    for other in (greedy_descent(sc.density, sc.Y, alpha).cost,
                  hypothesis_cost(*ml_costs(sc.density, sc.Y, alpha)[1:],
                                  maximum_likelihood(sc.density, sc.Y, alpha=alpha).observation_labels(sc.m))):
        assert best.cost <= other + 1e-9


def test_large_scene_matches_assignment_and_budget():
    sc = range_bearing_scenario(seed=0, n_landmarks=60, n_visible=10, n_clutter=2,
                                pose_sigma=(0.3, 0.3, np.deg2rad(10.0)), candidate_range=12.0)
    best = ml_tree_search(sc.density, sc.Y, 1e-3)
    assert best.cost == pytest.approx(assignment_ml(sc.density, sc.Y, 1e-3)[1], abs=1e-9)
    cut = ml_tree_search(sc.density, sc.Y, 1e-3, max_nodes=3)
    assert cut.budget_exhausted and cut.expanded == 3 and cut.labels.size == sc.m
    paired = cut.labels[cut.labels >= 0]
    assert paired.size == np.unique(paired).size                       # still one-to-one
    assert cut.cost >= best.cost - 1e-9


def test_empty_and_bad_inputs():
    density = independent([[0, 0]], [0.5])
    res = ml_tree_search(density, np.zeros((2, 0)), 0.1)
    assert res.labels.size == 0 and res.cost == 0.0
    assert assignment_ml(density, np.zeros((2, 0)), 0.1)[0].size == 0
    Y = np.array([[0.1, 0.0]]).T
    with pytest.raises(ValueError, match="alpha"):
        ml_tree_search(density, Y, 0.0)
    with pytest.raises(ValueError, match="max_nodes"):
        ml_tree_search(density, Y, 0.1, max_nodes=0)
    assert independent_ml(density, Y, 1e6).tolist() == [-1]           # α beats every landmark: "new"
