"""Recipes of the lecture L09 grading fixtures (``python tools/exercise_fixtures.py record|check NAME``).

Every L09 fixture is a hidden one (``<exercise>_hidden``): the public tests of the four association exercises use
hand-made and random scenes checked against the definitions written out in the tests. The hidden tests check the
answer key's exact results on realistic scenes:

- the range-bearing scenes of notebooks 06–08 (``helpers.association.scenarios.range_bearing_scenario``, not an
  exercise: the hidden tests draw them again from ``SCENES``) with a large pose error, so that the four algorithms
  disagree; each fixture holds the scenes' observations and predicted means (to tell a changed generator from a
  wrong answer) and the answer key's idx and D² for a few settings;
- the lab's camera scene (``lab_camera_scenario``: nine landmarks among 50 clutter features), recorded in full
  (its density comes from Lab 8 task 1c, another exercise) with its truth and the answer key's results;
- for JCBB also the number of expanded nodes, with and without a node budget.
"""
from __future__ import annotations

from exercise_fixtures import recipe

#: The range-bearing scenes of the hidden tests (the same list is in each tests/exercises/test_l09_*_hidden.py).
SCENES = [dict(seed=(7, s), n_landmarks=100, n_visible=15, n_clutter=4, candidate_range=12.0,
               pose_sigma=(0.8, 0.8, 0.25)) for s in range(6)]
CAMERA = dict(seed=3, n_clutter=50, p_detect=0.8)

# The inputs are sums of a few products (the linearised density): a few 1e-15 relative between CPUs; 1e-9 is far
# above it and far below any change of the generator. idx and node counts are integers (compared exactly); D² is
# a solve with the joint covariance of 10–15 pairings whose condition number stays below 1e4: 1e-8 relative.
RTOL, ATOL = 1e-8, 1e-10


def _scenes():
    from helpers.association.scenarios import range_bearing_scenario

    return [range_bearing_scenario(**kw) for kw in SCENES]


def _camera():
    from helpers.association.scenarios import lab_camera_scenario

    sc = lab_camera_scenario(**CAMERA)
    return {"cam_mu": sc.density.mean, "cam_P": sc.density.cov, "cam_Y": sc.Y, "cam_truth": sc.truth}


def _record(func, settings, camera_settings):
    """The answer key's idx and D² on every scene for each setting (a dict of keyword arguments, keyed by name),
    and on the camera scene; with the scenes' fingerprints and the camera scene's inputs."""
    from helpers.gaussian import Gaussian

    out = {}
    for s, sc in enumerate(_scenes()):
        out["rb%d_Y" % s], out["rb%d_mu" % s] = sc.Y, sc.density.mean
        for name, kwargs in settings.items():
            res = func(sc.density, sc.Y, **kwargs)
            out["rb%d_%s_idx" % (s, name)], out["rb%d_%s_d2" % (s, name)] = res.idx, res.d2
    cam = _camera()
    out.update(cam)
    density = Gaussian.from_cov(cam["cam_mu"], cam["cam_P"])
    for name, kwargs in camera_settings.items():
        res = func(density, cam["cam_Y"], **kwargs)
        out["cam_%s_idx" % name], out["cam_%s_d2" % name] = res.idx, res.d2
    return out


@recipe("l09_euclidean_nn_hidden", rtol=RTOL, atol=ATOL)
def euclidean_nn_hidden():
    from helpers.association.nearest_neighbour import nearest_neighbour

    return _record(nearest_neighbour, {"none": {}, "gate1": {"max_distance": 1.0}},
                   {"none": {}, "gate20": {"max_distance": 20.0}})


@recipe("l09_mahalanobis_nn_hidden", rtol=RTOL, atol=ATOL)
def mahalanobis_nn_hidden():
    from helpers.association.nearest_neighbour import mahalanobis_nn

    return _record(mahalanobis_nn, {"s3": {}, "s2": {"n_sigma": 2.0}}, {"s3": {}, "s2": {"n_sigma": 2.0}})


@recipe("l09_ml_alpha_hidden", rtol=RTOL, atol=ATOL)
def ml_alpha_hidden():
    from helpers.association.maximum_likelihood import maximum_likelihood

    return _record(maximum_likelihood, {"gate": {}, "a1e-2": {"alpha": 1e-2}, "a1": {"alpha": 1.0}},
                   {"gate": {}, "a1e-6": {"alpha": 1e-6}, "a1e-4": {"alpha": 1e-4}})


@recipe("l09_jcbb_hidden", rtol=RTOL, atol=ATOL)
def jcbb_hidden():
    from helpers.association.jcbb import jcbb

    def search(density, Y, **kwargs):
        res = jcbb(density, Y, **kwargs)
        nodes[len(nodes)] = (res.stats["nodes"], res.budget_exhausted)
        return res

    nodes = {}
    out = _record(search, {"full": {}, "budget30": {"max_nodes": 30}, "s2": {"n_sigma": 2.0}},
                  {"full": {}, "budget5": {"max_nodes": 5}})
    names = [key[:-len("_idx")] for key in out if key.endswith("_idx")]       # in the order they were run
    for j, name in enumerate(names):
        out[name + "_nodes"], out[name + "_exhausted"] = nodes[j]
    return out
