"""JCBB: hand-made answers, equality with an exhaustive search, the incremental D² and conditional predictions,
budget, trace, bad input."""
import itertools

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from helpers.association.common import joint_sq_mahalanobis, prepare
from helpers.association.jcbb import (
    TRACE_BEST,
    TRACE_BOUND,
    TRACE_EXPANDED,
    TRACE_JC_FAIL,
    condition_on_pairing,
    jcbb,
    level_order,
)
from helpers.association.nearest_neighbour import mahalanobis_nn
from helpers.association.scenarios import range_bearing_scenario
from helpers.gaussian import Gaussian, chi2inv, confidence_level


def shifted_row(n=4, spacing=1.0, sigma_shift=1.0, sigma=0.05):
    """n landmarks on a line, sharing one uncertain translation (a pose error): strongly correlated."""
    mu = np.column_stack([spacing * np.arange(n), np.zeros(n)]).ravel()
    J = np.tile(np.eye(2), (n, 1))
    P = sigma_shift ** 2 * J @ J.T + sigma ** 2 * np.eye(2 * n)
    return Gaussian.from_cov(mu, P)


def test_constellation_beats_stars():
    # The whole row is observed shifted by +0.6 spacing: each observation is individually nearest to
    # the wrong landmark's neighbour, but only the shifted constellation is jointly compatible.
    density = shifted_row()
    mu = density.mean.reshape(-1, 2)
    Y = (mu + [0.6, 0.0]).T                            # every landmark seen, all shifted by 0.6
    truth = np.arange(4)
    icnn = mahalanobis_nn(density, Y)
    res = jcbb(density, Y)
    assert np.array_equal(res.idx, truth)
    assert res.n_pairings == 4 and res.jointly_compatible
    assert not np.array_equal(icnn.idx, truth)


def test_clutter_is_left_out_and_d2_is_incremental_equal_scratch():
    sc = range_bearing_scenario(seed=3, n_landmarks=40, n_visible=8, n_clutter=3)
    res = jcbb(sc.density, sc.Y)
    pr = prepare(sc.density, sc.Y)
    assert res.d2 == pytest.approx(joint_sq_mahalanobis(pr, res.idx), rel=1e-10, abs=1e-12)
    assert res.jointly_compatible
    assert len(set(res.idx[res.idx >= 0].tolist())) == res.n_pairings      # one-to-one
    correct = np.sum((res.idx >= 0) & (res.idx == sc.truth))
    assert correct == np.sum(sc.truth >= 0)                                  # this seed: all found


# ---------------------------------------------------------------------------------------------------------
# exhaustive search over the same tree semantics
# ---------------------------------------------------------------------------------------------------------
def exhaustive(density, Y, n_sigma):
    """Best hypothesis by brute force: every one-to-one assignment of the levels' landmarks to IC
    observations or ∗, admissible when each prefix (in level order) is jointly compatible; best = most
    pairings, then smallest D². Returns (k, D², idx, second-best D² with the same k)."""
    pr = prepare(density, Y, n_sigma)
    comp = pr.ic_d2 <= pr.ic_threshold
    levels = level_order(comp)
    c = confidence_level(n_sigma)
    options = [[-1] + np.flatnonzero(comp[lm]).tolist() for lm in levels]
    results = []
    for choice in itertools.product(*options):
        obs = [o for o in choice if o >= 0]
        if len(obs) != len(set(obs)):
            continue
        idx = np.full(pr.n, -1)
        ok = True
        k = 0
        for lm, o in zip(levels, choice):
            if o < 0:
                continue
            idx[lm] = o
            k += 1
            if joint_sq_mahalanobis(pr, idx) > chi2inv(c, pr.d * k):
                ok = False
                break
        if ok:
            results.append((-k, joint_sq_mahalanobis(pr, idx), idx))
    results.sort(key=lambda r: (r[0], r[1]))
    best = results[0]
    second = next((r[1] for r in results[1:] if r[0] == best[0]), np.inf)
    return -best[0], best[1], best[2], second


def random_case(seed, n, m_clutter, n_sigma, d=2):
    rng = np.random.default_rng(seed)
    A = rng.normal(size=(d * n, d * n)) * 0.3
    shared = np.tile(np.eye(d), (n, 1)) * rng.uniform(0.2, 1.5)    # a common (pose-like) error
    P = A @ A.T + shared @ shared.T + 0.05 * np.eye(d * n)
    mu = rng.uniform(-3, 3, d * n)
    density = Gaussian.from_cov(mu, P)
    seen = rng.permutation(n)[: rng.integers(0, n + 1)]
    x = density.simulate(rng).reshape(n, d)
    cols = [x[k] for k in seen] + [rng.uniform(-3, 3, d) for _ in range(m_clutter)]
    Y = np.array(cols).T if cols else np.zeros((d, 0))
    if Y.shape[1]:
        Y = Y[:, rng.permutation(Y.shape[1])]
    return density, Y


@settings(max_examples=60, deadline=None, derandomize=True)
@given(seed=st.integers(0, 2 ** 32 - 1), n=st.integers(1, 5), m_clutter=st.integers(0, 2),
       n_sigma=st.sampled_from([1.5, 2.0, 3.0]))
def test_jcbb_equals_exhaustive_search(seed, n, m_clutter, n_sigma):
    density, Y = random_case(seed, n, m_clutter, n_sigma)
    res = jcbb(density, Y, n_sigma=n_sigma)
    if Y.shape[1] == 0:
        assert res.n_pairings == 0
        return
    k, d2, idx, second = exhaustive(density, Y, n_sigma)
    assert res.n_pairings == k
    assert res.d2 == pytest.approx(d2, rel=1e-9, abs=1e-12)
    if second - d2 > 1e-9 * max(1.0, d2):          # unique optimum → same idx
        assert np.array_equal(res.idx, idx)


@pytest.mark.parametrize("d", [1, 3])
@pytest.mark.parametrize("seed", range(6))
def test_other_observation_dimensions_equal_exhaustive_search(d, seed):
    density, Y = random_case(seed, 4, 1, 2.0, d=d)
    res = jcbb(density, Y, n_sigma=2.0)
    k, d2, idx, second = exhaustive(density, Y, 2.0)
    assert res.n_pairings == k and res.d2 == pytest.approx(d2, rel=1e-9, abs=1e-12)
    if second - d2 > 1e-9 * max(1.0, d2):
        assert np.array_equal(res.idx, idx)


# ---------------------------------------------------------------------------------------------------------
# budget, trace, determinism, bad input
# ---------------------------------------------------------------------------------------------------------
def test_budget_returns_best_so_far_and_says_so():
    sc = range_bearing_scenario(seed=1)
    full = jcbb(sc.density, sc.Y)
    assert not full.budget_exhausted and full.stats["nodes"] > 40
    cut = jcbb(sc.density, sc.Y, max_nodes=40)
    assert cut.budget_exhausted and cut.stats["nodes"] == 40
    assert 0 < cut.n_pairings <= full.n_pairings and cut.jointly_compatible
    pr = prepare(sc.density, sc.Y)
    assert cut.d2 == pytest.approx(joint_sq_mahalanobis(pr, cut.idx), rel=1e-10)
    same = jcbb(sc.density, sc.Y, max_nodes=full.stats["nodes"])      # exactly enough
    assert not same.budget_exhausted and np.array_equal(same.idx, full.idx)
    root_only = jcbb(sc.density, sc.Y, max_nodes=1)
    assert root_only.budget_exhausted and root_only.n_pairings == 0


def test_trace_records_the_tree():
    density = shifted_row(n=3)
    mu = density.mean.reshape(-1, 2)
    Y = np.column_stack([mu[0] + [0.6, 0], mu[1] + [0.6, 0], mu[2] + [0.6, 0], [0.3, 0.05]])
    res = jcbb(density, Y, trace=True)
    tr = res.stats["trace"]
    assert np.array_equal(jcbb(density, Y).idx, res.idx) and jcbb(density, Y).stats["nodes"] == res.stats["nodes"]
    assert tr.parent[0] == -1 and tr.level[0] == -1
    expanded = np.isin(tr.status, [TRACE_EXPANDED, TRACE_BEST])
    assert np.count_nonzero(expanded) == res.stats["nodes"]
    assert np.all(tr.parent[1:] < np.arange(1, tr.parent.size))            # parents come first
    assert np.all(tr.landmark[1:] == res.stats["level_order"][tr.level[1:]])
    assert np.any(tr.status == TRACE_JC_FAIL) and np.any(tr.status == TRACE_BOUND)
    assert tr.status[0] in (TRACE_EXPANDED, TRACE_BEST)


def test_deterministic_and_empty_cases():
    sc = range_bearing_scenario(seed=5, n_landmarks=60, n_visible=12)
    a, b = jcbb(sc.density, sc.Y), jcbb(sc.density, sc.Y)
    assert np.array_equal(a.idx, b.idx) and a.d2 == b.d2 and a.stats["nodes"] == b.stats["nodes"]
    empty = jcbb(sc.density, np.zeros((2, 0)))
    assert empty.n_pairings == 0 and np.all(empty.idx == -1) and empty.d2 == 0.0
    far = jcbb(sc.density, np.full((2, 3), 1e4))                          # no IC candidate at all
    assert far.n_pairings == 0 and far.stats["levels"] == 0


@pytest.mark.parametrize("kwargs, match", [
    ({"max_nodes": 0}, "max_nodes"), ({"max_nodes": 2.5}, "max_nodes"), ({"trace": 1}, "trace"),
    ({"n_sigma": -1.0}, "n_sigma"),
])
def test_bad_options(kwargs, match):
    density = shifted_row(n=2)
    with pytest.raises(ValueError, match=match):
        jcbb(density, density.mean.reshape(2, 2).T, **kwargs)


@pytest.mark.parametrize("Y, match", [
    (np.zeros(4), "Y must be a 2-D"), (np.zeros((3, 2)), "multiple of the observation dimension"),
    (np.array([[0.0, np.nan], [0.0, 0.0]]), "finite"), (np.zeros((0, 2)), "Y must be a 2-D"),
])
def test_bad_observations(Y, match):
    with pytest.raises(ValueError, match=match):
        jcbb(shifted_row(n=2), Y)


def test_bad_density():
    with pytest.raises(ValueError, match="density must be"):
        jcbb(np.zeros(4), np.zeros((2, 1)))


def test_tree_and_association_figures(tmp_path, monkeypatch):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from helpers.association.plots import draw_association, draw_interpretation_tree

    density = shifted_row(n=3)
    mu = density.mean.reshape(-1, 2)
    Y = np.column_stack([mu[0] + [0.6, 0], mu[1] + [0.6, 0], mu[2] + [0.6, 0], [0.3, 0.05]])
    res = jcbb(density, Y, trace=True)
    fig, axes = plt.subplots(1, 2)
    draw_interpretation_tree(axes[0], res.stats["trace"], best_idx=res.idx)
    draw_association(axes[1], density, Y, res.idx, truth=np.arange(3), title="t")
    assert len(axes[0].lines) == res.stats["trace"].parent.size - 1 and len(axes[1].lines) > 3
    assert max(line.get_linewidth() for line in axes[0].lines) == 2.6          # the final hypothesis, thick
    with pytest.raises(ValueError, match="^trace must"):
        draw_interpretation_tree(axes[0], None)
    plt.close(fig)


def test_trace_uses_only_the_trace_codes():
    sc = range_bearing_scenario(seed=2, n_landmarks=40, n_visible=8, n_clutter=3)
    tr = jcbb(sc.density, sc.Y, trace=True).stats["trace"]
    assert set(tr.status.tolist()) <= {TRACE_EXPANDED, TRACE_JC_FAIL, TRACE_BOUND, TRACE_BEST}
    assert np.all(tr.obs[tr.status == TRACE_JC_FAIL] >= 0)                # JC failures are pairings


@pytest.mark.parametrize("seed", range(5))
def test_conditioning_on_a_pairing_is_the_gaussian_conditional(seed):
    """The incremental update (mean + Gᵀw, cov − GᵀG) against the conditional of the Gaussian, from its
    definition: the later levels given that level t's landmark is observed at y."""
    d, T, t = 2, 5, 1
    density, _ = random_case(seed, T, 0, 3.0, d=d)
    y = np.random.default_rng(seed).normal(size=d)
    mean, cov = condition_on_pairing(density.mean.reshape(T, d), density.cov, t, y)
    later = np.arange(d * (t + 1), d * T)
    cond = density.conditional(later, np.arange(d * t, d * t + d), y)
    np.testing.assert_allclose(mean.ravel()[later], cond.mean, rtol=1e-10, atol=1e-12)
    np.testing.assert_allclose(cov[np.ix_(later, later)], cond.cov, rtol=1e-9, atol=1e-12)
