"""SNN data association (helpers.association.snn) on the lab template's 13-feature fixture, and edge cases."""
import numpy as np
import pytest

from helpers.association.common import prepare
from helpers.association.compatibility import joint_compatibility
from helpers.association.snn import snn
from helpers.gaussian import Gaussian, chi2inv, confidence_level

MU_Y = np.array([1658.780527, 963.3626597, 433.112825, 731.914696, 1410.293147, 577.2375667])
S_YY = np.array([
    [-53.41061755, 9.901075665, 5.306940133, 7.303991992, -5.72141011, 6.609727066],
    [0, -37.3526274, 0.08127966678, -22.40730348, -0.2022231471, -15.87273879],
    [0, 0, 36.03250166, -22.71362239, -1.725509191, 3.766078776],
    [0, 0, 0, -41.70917897, 2.529976157, -8.843062797],
    [0, 0, 0, 0, 22.34877992, -22.53303115],
    [0, 0, 0, 0, 0, 32.74457988],
])
Y3 = np.array([[1754.156364, 1714.701131, 1921.012306], [765.1206969, 934.6000308, 849.6044461]])
Y13 = np.array([
    [549, 942, 1151, 30, 1381.755157, 1757.892465, 1637.791659, 443.3084837, 279.9869569,
     359.2704718, 1363.489534, 1387.401497, 1387.120065],
    [855, 625, 1163, 454, 986.4901225, 835.5843074, 1008.082601, 654.6662577, 862.0112818,
     747.6976779, 603.0677591, 692.7547721, 563.2515042],
])
SU = 14.832478857591873
GATE2 = 11.829158081900795


def density6():
    return Gaussian(MU_Y, S_YY)


def density2():
    return Gaussian(MU_Y[:2], S_YY[:2, :2])


def individual_sq_mahalanobis(density, Y):
    return prepare(density, Y).ic_d2                                  # (n, m)


def association_surprisal(idx, sU, Y, density):
    return joint_compatibility(np.asarray(idx), sU, Y, density, 3.0)


# ---------------------------------------------------------------------------------------------------- gate
def test_individual_gate_matches_fixture_table():
    d2 = individual_sq_mahalanobis(density6(), Y13)
    assert d2.shape == (3, 13)
    compatible = d2 <= GATE2
    expected = np.zeros((3, 13), bool)
    for i, j in [(6, 0), (7, 1), (9, 1), (10, 2), (11, 2), (12, 2)]:
        expected[j, i] = True
    np.testing.assert_array_equal(compatible, expected)
    table = {(6, 0): 1.349, (7, 1): 2.238, (9, 1): 4.437, (10, 2): 4.435, (11, 2): 7.066, (12, 2): 2.056,
             (5, 0): 12.022}
    for (i, j), v in table.items():
        assert d2[j, i] == pytest.approx(v, abs=6e-4)
    np.testing.assert_allclose(individual_sq_mahalanobis(density2(), Y3)[0], [26.556, 1.3388, 27.147], atol=6e-4)


def test_vectorised_gate_equals_per_pair_marginal():
    d = density6()
    d2 = individual_sq_mahalanobis(d, Y13)
    for j in range(3):
        mj = d.marginal([2 * j, 2 * j + 1])
        np.testing.assert_allclose(d2[j], mj.sq_mahalanobis(Y13), rtol=1e-12)


# ---------------------------------------------------------------------------------------------------- snn
def test_snn_on_13_feature_fixture():
    idx, s = snn(density6(), Y13, SU)
    np.testing.assert_array_equal(idx, [6, 7, 12])
    assert s == pytest.approx(32.05656943680852, rel=1e-9)
    jc, s2 = association_surprisal(idx, SU, Y13, density6())
    assert jc and s == s2


def greedy_by_definition(d, Y, enforce):
    """Each greedy step of SNN with the full joint surprisal of every candidate (no incremental algebra); a
    step whose best and second-best changes are within 1e-9 of each other is ambiguous and returns None."""
    cur = np.full(d.size // 2, -1)
    for j in range(cur.size):
        s0 = association_surprisal(cur, SU, Y, d)[1]
        options = [(0.0, -1)]
        for i in np.flatnonzero(individual_sq_mahalanobis(d, Y)[j] <= GATE2):
            if i in cur:
                continue
            trial = cur.copy()
            trial[j] = i
            jc, st = association_surprisal(trial, SU, Y, d)
            if jc or not enforce:
                options.append((st - s0, i))
        options.sort()
        if len(options) > 1 and options[1][0] - options[0][0] < 1e-9:
            return None
        cur[j] = options[0][1]
    return cur


@pytest.mark.parametrize("case", ["fixture"] + [f"random {seed}" for seed in range(6)])
@pytest.mark.parametrize("enforce", [False, True])
def test_snn_choices_are_greedy_minimum_surprisal(case, enforce):
    d, Y = (density6(), Y13) if case == "fixture" else random_scene(int(case.split()[1]))
    expected = greedy_by_definition(d, Y, enforce)
    assert expected is not None                                     # the scenes have no near-tie
    idx, s = snn(d, Y, SU, enforce_joint_compatibility=enforce)
    np.testing.assert_array_equal(idx, expected)
    assert s == pytest.approx(association_surprisal(idx, SU, Y, d)[1], rel=1e-12)


def test_snn_one_landmark_three_features():
    idx, s = snn(density2(), Y3, SU)
    np.testing.assert_array_equal(idx, [1])
    assert s == pytest.approx(10.105667572052072, rel=1e-6)


def test_surprisal_agrees_with_joint_compatibility():
    for density, Y in [(density6(), Y13), (density2(), Y3)]:
        for enforce in (False, True):
            idx, s = snn(density, Y, SU, enforce_joint_compatibility=enforce)
            jc, s_ref = joint_compatibility(idx, SU, Y, density, 3.0)
            assert s == pytest.approx(s_ref, rel=1e-9)


def random_scene(seed, n=4, m=120):
    rng = np.random.default_rng(seed)
    # correlated bundle: a shared 2-D offset (pose) plus independent landmark noise
    A = np.vstack([np.tile(np.eye(2) * rng.uniform(3, 8), (n, 1)).T, np.diag(rng.uniform(2, 6, 2 * n))])
    S = np.linalg.qr(A, mode="r")
    mu = rng.uniform(100, 400, 2 * n)
    Y = np.vstack([rng.uniform(100, 400, m), rng.uniform(100, 400, m)])
    Y[:, :n] = mu.reshape(n, 2).T + rng.normal(0, 6, (2, n))         # one plausible feature per landmark
    return Gaussian(mu, S), np.round(Y)


# ---------------------------------------------------------------------------------------------------- rules
def test_a_feature_is_never_taken_twice():
    density = Gaussian(np.array([100.0, 100.0, 100.0, 100.0]), 5.0 * np.eye(4))
    Y = np.array([[101.0], [99.0]])
    idx, _ = snn(density, Y, SU)
    np.testing.assert_array_equal(idx, [0, -1])


def test_ties_go_to_the_lowest_feature_index():
    density = Gaussian(np.array([100.0, 100.0]), 5.0 * np.eye(2))
    Y = np.array([[130.0, 103.0, 97.0, 103.0], [100.0, 104.0, 96.0, 104.0]])   # 1, 2, 3 equidistant
    idx, _ = snn(density, Y, SU)
    np.testing.assert_array_equal(idx, [1])


def test_null_hypothesis_wins_when_pairing_raises_surprisal():
    # σ = 2000 px: a feature at the mean is compatible, but Δs = −sU + log 2π + log σ² > 0
    density = Gaussian(np.array([100.0, 100.0]), 2000.0 * np.eye(2))
    Y = np.array([[100.0], [100.0]])
    idx, s = snn(density, Y, SU)
    np.testing.assert_array_equal(idx, [-1])
    assert s == SU


def test_enforce_joint_compatibility_rejects_a_jointly_incompatible_pairing():
    # two independent landmarks (σ = 10 px); each feature individually at d² = 10 ≤ 11.83 but jointly
    # 20 > χ²₄(c) = 16.25
    density = Gaussian(np.array([500.0, 500.0, 800.0, 500.0]), 10.0 * np.eye(4))
    r = np.sqrt(10.0) * 10.0
    Y = np.array([[500.0 + r, 800.0 - r], [500.0, 500.0]])
    assert chi2inv(confidence_level(3.0), 4) < 20.0
    idx, _ = snn(density, Y, SU)
    np.testing.assert_array_equal(idx, [0, 1])
    idx_jc, s_jc = snn(density, Y, SU, enforce_joint_compatibility=True)
    np.testing.assert_array_equal(idx_jc, [0, -1])
    assert s_jc == pytest.approx(association_surprisal(idx_jc, SU, Y, density)[1], rel=1e-12)


def test_no_features_gives_nothing_associated():
    idx, s = snn(density6(), np.zeros((2, 0)), SU)
    np.testing.assert_array_equal(idx, [-1, -1, -1])
    assert s == 3 * SU


# ---------------------------------------------------------------------------------------------------- bad input
@pytest.mark.parametrize(
    "kwargs, word",
    [
        ({"Y": np.zeros((3, 4))}, "Y"),
        ({"Y": np.zeros(4)}, "Y"),
        ({"Y": np.array([[np.nan], [1.0]])}, "Y"),
        ({"density": np.zeros(6)}, "density"),
        ({"density": Gaussian(np.zeros(3), np.eye(3))}, "density"),
        ({"sU": np.nan}, "sU"),
        ({"sU": "14.8"}, "sU"),
        ({"n_sigma": -1.0}, "n_sigma"),
        ({"enforce_joint_compatibility": "yes"}, "enforce_joint_compatibility"),
    ],
)
def test_bad_inputs_raise_named_errors(kwargs, word):
    args = {"density": density6(), "Y": Y13, "sU": SU} | kwargs
    with pytest.raises(ValueError, match=word):
        snn(**args)




# ---------------------------------------------------------------------------------------------------- lab demo
def demo_inputs():
    from helpers.camera import load_lab_camera
    from helpers.features import Features
    from helpers.state_slam import lab_demo_state

    camera = load_lab_camera()
    state = lab_demo_state()
    h = camera.world_to_pixel(state.landmark_positions(), state.camera_pose(camera))
    # one feature 1 px from each predicted landmark, landmarks 0 and 1 missing, plus far-away clutter
    x = np.concatenate([[50.0, 1900.0], np.round(h[0, 2:]) + 1.0])
    y = np.concatenate([[50.0, 1400.0], np.round(h[1, 2:])])
    feats = Features(np.linspace(1.0, 0.5, x.size), x.astype(int), y.astype(int))
    return camera, state, feats


def test_association_demo_console_lines(capsys):
    from helpers.association.lab_demo import association_demo

    camera, state, feats = demo_inputs()
    res = association_demo(None, camera, state, image_name="GOPR9348.JPG", features=feats)
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "9 features found in GOPR9348.JPG"
    assert out[1:10] == [f"Landmark {j} is expected to be within camera FOV" for j in range(9)]
    assert out[10] == f"Surprisal = {res.surprisal:.6g}"
    assert out[11:13] == ["No feature associated with landmark 0.", "No feature associated with landmark 1."]
    for k, j in enumerate(range(2, 9)):
        i = k + 2
        assert out[13 + k] == f"Feature {i} located at [{feats.x[i]} {feats.y[i]}] in image matches landmark {j}."
    assert out[20] == "" and len(out) == 21
    np.testing.assert_array_equal(res.idx, [-1, -1, 2, 3, 4, 5, 6, 7, 8])
    jc, s = joint_compatibility(res.idx, res.sU, feats.Y, res.density)
    assert s == pytest.approx(res.surprisal, rel=1e-12)


def test_association_demo_with_no_landmark_in_view(capsys):
    from helpers.association.lab_demo import association_demo
    from helpers.state_slam import lab_demo_state

    camera, state, feats = demo_inputs()
    away = state.camera_pose(camera).copy()
    away[3] += np.pi                                          # roll by 180°: the camera looks away from the plane
    res = association_demo(None, camera, lab_demo_state(away), features=feats)
    out = capsys.readouterr().out.splitlines()
    assert all("is NOT expected" in line for line in out[1:10])
    assert res.idx.size == 0 and res.density is None and res.surprisal == 0.0
    assert "nothing to associate" in out[10]


def test_association_demo_bad_inputs():
    from helpers.association.lab_demo import association_demo

    camera, state, feats = demo_inputs()
    with pytest.raises(ValueError, match="features"):
        association_demo(None, camera, state, features=feats.Y, verbose=False)
    with pytest.raises(ValueError, match="image"):
        association_demo([[0]], camera, state, verbose=False)


def test_figure1_plot_runs_and_uses_lab_colours():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from helpers.association.lab_demo import FIGURE1_COLORS, association_demo, plot_association

    camera, state, feats = demo_inputs()
    res = association_demo(None, camera, state, features=feats, verbose=False)
    fig, ax = plot_association(np.zeros((1440, 1920), np.uint8), res)
    colours = [tuple(line.get_color()) if not isinstance(line.get_color(), str) else line.get_color()
               for line in ax.lines]
    assert FIGURE1_COLORS["unassociated"] in colours and FIGURE1_COLORS["associated"] in colours
    assert FIGURE1_COLORS["match"] in colours
    assert sorted(int(t.get_text()) for t in ax.texts) == list(range(9))            # one label per landmark
    plt.close(fig)


def test_ground_truth_check_verdicts():
    from helpers.association.lab_demo import association_demo, ground_truth_check

    camera, state, feats = demo_inputs()
    res = association_demo(None, camera, state, features=feats, verbose=False)
    rows = ground_truth_check(res, camera, state.camera_pose(camera), state.landmark_positions(), tol=2.0)
    verdicts = [r["verdict"] for r in rows]
    # landmarks 0, 1 have no feature near them (correct nulls); 2..8 have a feature 1 px away (correct)
    assert verdicts == ["correct null"] * 2 + ["correct"] * 7
    # pretend the truth is elsewhere for landmark 2: its association becomes wrong
    moved = state.landmark_positions().copy()
    moved[:, 2] += [0.0, 0.05, 0.0]
    assert ground_truth_check(res, camera, state.camera_pose(camera), moved)[2]["verdict"] == "wrong"
    with pytest.raises(ValueError, match="true_landmarks"):
        ground_truth_check(res, camera, state.camera_pose(camera), moved[:2])
    with pytest.raises(ValueError, match="tol"):
        ground_truth_check(res, camera, state.camera_pose(camera), moved, tol=0.0)


def test_figure1_zoom_window_and_bad_inputs():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from helpers.association.lab_demo import association_demo, plot_association

    camera, state, feats = demo_inputs()
    res = association_demo(None, camera, state, features=feats, verbose=False)
    img = np.zeros((1440, 1920), np.uint8)
    fig, ax = plot_association(img, res, window=(900, 1100, 600, 800))
    assert ax.get_xlim() == (900.0, 1100.0) and ax.get_ylim() == (800.0, 600.0)
    plt.close(fig)
    with pytest.raises(ValueError, match="window"):
        plot_association(img, res, window=(10, 5, 0, 10))
    with pytest.raises(ValueError, match="window"):
        plot_association(img, res, window=(3000, 3100, 0, 10))
    with pytest.raises(ValueError, match="image"):
        plot_association(img.astype(float), res)
    with pytest.raises(ValueError, match="image_scale"):
        plot_association(img, res, image_scale=0.0)
    plt.close("all")


def test_figure1_truth_overlay_marks_wrong_pairings_and_has_a_legend():
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from helpers.association.lab_demo import (
        FIGURE1_COLORS,
        association_demo,
        figure1_legend_handles,
        ground_truth_check,
        plot_association,
    )

    camera, state, feats = demo_inputs()
    res = association_demo(None, camera, state, features=feats, verbose=False)
    moved = state.landmark_positions().copy()
    moved[:, 2] += [0.0, 0.05, 0.0]                       # landmark 2's association becomes wrong
    rows = ground_truth_check(res, camera, state.camera_pose(camera), moved)
    fig, ax = plot_association(np.zeros((1440, 1920), np.uint8), res, truth=rows)
    wrong_lines = [ln for ln in ax.lines if ln.get_linestyle() == "--"]
    assert len(wrong_lines) == 1 and tuple(wrong_lines[0].get_color()) == FIGURE1_COLORS["wrong"]
    np.testing.assert_allclose(wrong_lines[0].get_xydata()[1], rows[2]["true_pixel"])
    labels = [t.get_text() for t in ax.get_legend().get_texts()]
    assert len(labels) == 6 and any("true landmark" in t for t in labels)
    # features are drawn below the landmark overlays
    feature_line = next(ln for ln in ax.lines if ln.get_marker() == ".")
    assert all(feature_line.get_zorder() < ln.get_zorder() for ln in ax.lines if ln is not feature_line)
    assert len(figure1_legend_handles()) == 4
    plt.close("all")
