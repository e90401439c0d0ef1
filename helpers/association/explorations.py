"""Notebook 08's exploration: one seeded range–bearing scene, the pairings of one algorithm against the truth.

**The scene.** Trial t is ``range_bearing_scenario(seed=(seed, t), n_clutter=max_clutter, **scene)``, drawn once.
Fewer clutter points keep the first n clutter columns of Y and drop the others: the clutter points are independent
and uniform in the sensed disc, so any n of them make a scene with n clutter points, and the scenes are nested
(more clutter adds points and moves none). The landmarks, the pose and the landmarks' observations are those of
the seed (the scenario draws its clutter last).

**The heading error** e (in σ_θ, the heading σ of the scene's covariance) sets the estimated heading to
θ_true + e σ_θ; the position error stays as drawn and the covariance stays. The candidates' prediction is
recomputed through the scenario's linearised model z_k = R(θ)ᵀ(m_k − t) (``observe_points``), so the predictions
and their gates rotate rigidly about the robot by −e σ_θ while the observations stay. A heading σ knob would
widen the gates and scale the error together (what notebook 08's sweep averages over); holding the covariance and
moving the error shows one thing at a time, and shows that a gate assumes a consistent covariance.

**The outcome** of landmark k with truth t_k (its observation column or −1) and pairing i_k: *right* i_k = t_k ≥ 0;
*clutter paired* i_k is a clutter point; *wrong* any other i_k ≥ 0; *missed* t_k ≥ 0 and i_k ≠ t_k. Precision =
right / pairings, recall = right / true pairings (``helpers.association.evaluation``; "n/a" for 0/0). The joint
D² of the pairings is tested against χ²_{2a}(c) at the explorer's n_σ (module ``common``), for every algorithm.
"""
from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping

import numpy as np
from matplotlib.axes import Axes
from matplotlib.figure import Figure

from ..exercises import ExerciseNotImplemented
from ..figures import COLORS
from ..gaussian import Gaussian, chi2inv, confidence_level
from ..validation import finite_number, integer, one_of, positive_number
from .common import Association, joint_sq_mahalanobis, prepare
from .evaluation import fmt_rate
from .scenarios import Scenario, observe_points, range_bearing_scenario

__all__ = ["clutter_subset", "with_heading_error", "outcomes", "gate_outlines", "draw_pairings", "PairingExplorer",
           "OUTCOME_STYLE"]

#: line style of each outcome: right, wrong, clutter paired (pairing lines) and missed (to the true observation)
OUTCOME_STYLE = {"right": dict(color=COLORS["alt"], lw=2.0), "wrong": dict(color=COLORS["bound"], lw=2.0),
                 "clutter paired": dict(color="#ff7f0e", lw=2.0),
                 "missed": dict(color=COLORS["truth"], lw=1.3, ls=(0, (1, 1.5)))}
_SUBSCRIPT = str.maketrans("0123456789", "₀₁₂₃₄₅₆₇₈₉")


def clutter_subset(sc: Scenario, n_clutter: int) -> Scenario:
    """``sc`` with only its first ``n_clutter`` clutter columns (module docstring); truth re-indexed to the kept
    columns. ValueError naming n_clutter unless 0 ≤ n_clutter ≤ the clutter points of ``sc``."""
    n_clutter = integer(n_clutter, "n_clutter", minimum=0, below=int(np.sum(sc.is_clutter)) + 1)
    keep = ~sc.is_clutter | (np.cumsum(sc.is_clutter) <= n_clutter)
    new_col = np.cumsum(keep) - 1                                   # old column → its column among those kept
    truth = np.where(sc.truth >= 0, new_col[np.maximum(sc.truth, 0)], -1)
    return dataclasses.replace(sc, Y=sc.Y[:, keep], truth=truth, is_clutter=sc.is_clutter[keep])


def with_heading_error(sc: Scenario, error: float) -> Scenario:
    """``sc`` with the estimated heading set to θ_true + ``error`` [rad] and the candidates' predicted density
    recomputed (same covariance, same position error; module docstring). ``sc`` must carry its ``state``."""
    error = finite_number(error, "error")
    if sc.state is None or sc.meas_sigma is None:
        raise ValueError("sc must be a range_bearing_scenario (with its state and meas_sigma)")
    n = sc.n
    pose_est = np.array([*sc.pose_est[:2], sc.pose_true[2] + error])
    state = Gaussian(np.concatenate([pose_est, sc.state.mean[3:]]), sc.state.sqrt_cov)
    rows = np.arange(2 * n).reshape(n, 2)

    def h(x):
        z, J_pose, J_lm = observe_points(x[:3], x[3:].reshape(n, 2))
        J = np.zeros((2 * n, 3 + 2 * n))
        J[:, :3] = J_pose.reshape(2 * n, 3)
        J[rows[:, :, None], 3 + rows[:, None, :]] = J_lm
        return z.ravel(), J

    density = state.transform(h, noise=Gaussian(np.zeros(2 * n), sc.meas_sigma * np.eye(2 * n)))
    return dataclasses.replace(sc, density=density, state=state, pose_est=pose_est)


def outcomes(idx: np.ndarray, truth: np.ndarray, is_clutter: np.ndarray) -> dict:
    """{outcome: landmark indices} for "right", "wrong", "clutter paired" and "missed" (module docstring)."""
    idx, truth = np.asarray(idx), np.asarray(truth)
    paired = idx >= 0
    to_clutter = paired & np.asarray(is_clutter)[np.maximum(idx, 0)]
    right = paired & (idx == truth)
    return {"right": np.flatnonzero(right), "wrong": np.flatnonzero(paired & ~right & ~to_clutter),
            "clutter paired": np.flatnonzero(to_clutter), "missed": np.flatnonzero((truth >= 0) & ~right)}


def gate_outlines(density: Gaussian, n_sigma: float = 3.0, n_points: int = 61) -> np.ndarray:
    """The n_σ gates μ_k + r L_k [cos t; sin t] (P_kk = L_k L_kᵀ, r² = χ²_2(c)) of a 2-D bundle ``density``, all in
    one (2, n·(n_points + 1)) polyline with NaN columns between them: one artist (``plots.draw_gates`` draws n)."""
    mu = density.mean.reshape(-1, 2)
    blocks = density.cov.reshape(len(mu), 2, len(mu), 2)[np.arange(len(mu)), :, np.arange(len(mu)), :]
    t = np.linspace(0.0, 2.0 * np.pi, n_points)
    r = np.sqrt(chi2inv(confidence_level(n_sigma), 2))
    pts = mu[:, :, None] + r * np.linalg.cholesky(blocks) @ np.vstack([np.cos(t), np.sin(t)])   # (n, 2, n_points)
    return np.concatenate([pts, np.full((len(mu), 2, 1), np.nan)], axis=2).transpose(1, 0, 2).reshape(2, -1)


def draw_pairings(ax: Axes, sc: Scenario, idx: np.ndarray, n_sigma: float = 3.0) -> dict:
    """Draw in the robot frame the candidates' n_σ gates, the observations (landmarks '●', clutter '×'), the robot,
    and each pairing of ``idx`` coloured by its outcome (missed: dotted to the true observation). Returns
    :func:`outcomes`."""
    out = outcomes(idx, sc.truth, sc.is_clutter)
    mu = sc.density.mean.reshape(-1, 2)
    gates = gate_outlines(sc.density, n_sigma)
    ax.plot(gates[0], gates[1], color=COLORS["estimate"], lw=0.9, alpha=0.8)
    ax.plot(mu[:, 0], mu[:, 1], "+", color=COLORS["estimate"], ms=7, mew=1.3, label=f"prediction, {n_sigma:g}σ gate")
    for name, ks in out.items():
        ends = sc.truth[ks] if name == "missed" else idx[ks]
        xs = np.stack([mu[ks, 0], sc.Y[0, ends], np.full(ks.size, np.nan)], axis=1).ravel()
        ys = np.stack([mu[ks, 1], sc.Y[1, ends], np.full(ks.size, np.nan)], axis=1).ravel()
        ax.plot(xs, ys, label=f"{name}: {ks.size}", **OUTCOME_STYLE[name])
    lm, cl = sc.Y[:, ~sc.is_clutter], sc.Y[:, sc.is_clutter]
    ax.plot(lm[0], lm[1], "o", color=COLORS["truth"], ms=4, label="observed landmark")
    ax.plot(cl[0], cl[1], "x", color=COLORS["truth"], ms=6, mew=1.5, label="clutter")
    ax.plot(0.0, 0.0, ">", color=COLORS["truth"], ms=9, label="robot")
    ax.set_aspect("equal")
    return out


class PairingExplorer:
    """The scenes, predictions and associations of the exploration, each computed once and kept.

    ``algorithms``: {name: f(density, Y) → Association}, the notebook's own; ``scene``: keyword arguments of
    ``range_bearing_scenario`` but seed (its ``pose_sigma[2]`` is σ_θ); trial t uses seed (``seed``, t);
    ``max_clutter``: the clutter drawn per scene (the knob's maximum). Algorithms that raise ExerciseNotImplemented
    on trial 0 are left out (``missing``: {name: exercise}); if none runs, the first such error propagates. The
    knobs (trial ≥ 0, 0 ≤ n_clutter ≤ max_clutter, a finite heading_error in σ_θ, an algorithm of
    ``self.algorithms``) raise ValueError naming the one that is wrong. ``draw`` is the ``draw(fig, **knobs)`` of
    ``helpers.explore.explore``.
    """

    CACHE_SIZE = 5000    #: entries kept (scenes, predictions, associations) before the cache starts again

    def __init__(self, algorithms: Mapping[str, Callable], scene: Mapping, seed: int, n_sigma: float = 3.0,
                 max_clutter: int = 20) -> None:
        if not isinstance(algorithms, Mapping) or not algorithms or not all(map(callable, algorithms.values())):
            raise ValueError(f"algorithms must be a non-empty mapping {{name: callable}}, got {algorithms!r}")
        if not isinstance(scene, Mapping) or "seed" in scene:
            raise ValueError(f"scene must be a mapping of range_bearing_scenario keyword arguments but seed, got "
                             f"{scene!r}")
        self.scene = {**scene, "n_clutter": integer(max_clutter, "max_clutter", minimum=0)}
        self.seed, self.n_sigma = integer(seed, "seed", minimum=0), positive_number(n_sigma, "n_sigma")
        self._cache, self.missing, self.algorithms, errors = {}, {}, {}, []
        sc = self.trial_scene(0)
        self.heading_sigma = float(np.sqrt(sc.pose_cov[2, 2]))
        for name, f in algorithms.items():
            try:
                f(sc.density, sc.Y)
            except ExerciseNotImplemented as err:
                self.missing[name] = err.exercise
                errors.append(err)
            else:
                self.algorithms[name] = f
        if not self.algorithms:
            raise errors[0]

    def _keep(self, key: tuple, make: Callable):
        """The value kept under ``key``, made by ``make()`` the first time; a full cache starts again."""
        if key not in self._cache:
            value = make()
            if len(self._cache) >= self.CACHE_SIZE:
                self._cache.clear()
            self._cache[key] = value
        return self._cache[key]

    def trial_scene(self, trial: int, n_clutter: int | None = None, heading_error: float | None = None) -> Scenario:
        """Trial ``trial``'s scene with ``n_clutter`` clutter points (None: all) and the heading error
        ``heading_error`` in σ_θ (None: as drawn)."""
        trial = integer(trial, "trial", minimum=0)
        heading_error = None if heading_error is None else finite_number(heading_error, "heading_error")
        if n_clutter is not None:
            n_clutter = integer(n_clutter, "n_clutter", minimum=0, below=self.scene["n_clutter"] + 1)
            return self._keep(("scene", trial, n_clutter, heading_error), lambda: clutter_subset(
                self.trial_scene(trial, None, heading_error), n_clutter))
        if heading_error is not None:
            return self._keep(("scene", trial, None, heading_error), lambda: with_heading_error(
                self.trial_scene(trial), heading_error * self.heading_sigma))
        return self._keep(("scene", trial), lambda: range_bearing_scenario((self.seed, trial), **self.scene))

    def associate(self, trial: int, n_clutter: int, heading_error: float, algorithm: str) -> Association:
        """The association of ``algorithm`` (a name of ``self.algorithms``) on that scene (kept)."""
        f = self.algorithms[one_of(algorithm, "algorithm", list(self.algorithms))]
        sc = self.trial_scene(trial, n_clutter, heading_error)
        return self._keep(("association", trial, n_clutter, heading_error, algorithm), lambda: f(sc.density, sc.Y))

    def summary(self, trial: int, n_clutter: int, heading_error: float, algorithm: str) -> dict:
        """Counts of the outcomes, ``pairings``, ``true``, ``precision``, ``recall``, ``individual`` (pairings
        inside their own gate χ²_2(c)), ``d2`` (the joint D² of the pairings) and its ``gate`` χ²_{2a}(c)."""
        sc = self.trial_scene(trial, n_clutter, heading_error)
        idx = self.associate(trial, n_clutter, heading_error, algorithm).idx
        out = {name: int(ks.size) for name, ks in outcomes(idx, sc.truth, sc.is_clutter).items()}
        k = np.flatnonzero(idx >= 0)
        made, true = int(k.size), int(np.sum(sc.truth >= 0))
        problem = prepare(sc.density, sc.Y, self.n_sigma)
        return {**out, "pairings": made, "true": true, "precision": out["right"] / made if made else np.nan,
                "recall": out["right"] / true if true else np.nan,
                "individual": int(np.sum(problem.ic_d2[k, idx[k]] <= problem.ic_threshold)),
                "d2": joint_sq_mahalanobis(problem, idx), "gate": float(problem.jc_threshold(made)) if made else 0.0}

    def draw(self, fig: Figure, n_clutter: int, heading_error: float, algorithm: str, trial: int = 0) -> dict:
        """Draw the scene and ``algorithm``'s pairings on ``fig``, titled with the knobs, the rates and the
        compatibility tests beside the axes; returns :meth:`summary`. The view (1.1 × the farthest prediction or
        observation from the robot, which a rotation keeps) is the trial's, the same for the other knobs."""
        if not isinstance(fig, Figure):
            raise ValueError(f"fig must be a matplotlib Figure, got {type(fig).__name__}")
        s = self.summary(trial, n_clutter, heading_error, algorithm)
        sc, full = self.trial_scene(trial, n_clutter, heading_error), self.trial_scene(trial)
        ax = fig.subplots()
        draw_pairings(ax, sc, self.associate(trial, n_clutter, heading_error, algorithm).idx, self.n_sigma)
        r = 1.1 * float(np.max(np.linalg.norm(np.hstack([full.density.mean.reshape(-1, 2).T, full.Y]), axis=0)))
        ax.set(xlim=(-r, r), ylim=(-r, r), xlabel="x, robot frame [m]", ylabel="y [m]")
        ax.set_title(f"{algorithm} · trial {trial} · {n_clutter} clutter points · heading error "
                     f"{heading_error:+.2f}σ ({np.rad2deg(heading_error * self.heading_sigma):+.1f}°)", fontsize=10)
        ax.legend(loc="upper left", bbox_to_anchor=(1.03, 1.0), fontsize=8)
        ok, dof = s["d2"] <= s["gate"], str(2 * s["pairings"]).translate(_SUBSCRIPT)
        fig.text(0.69, 0.6, f"precision {fmt_rate(s['precision'], 2).strip()}, recall "
                 f"{fmt_rate(s['recall'], 2).strip()}\n\nindividually compatible: {s['individual']} of "
                 f"{s['pairings']}\njoint D² {s['d2']:.1f} {'≤' if ok else '>'} χ²{dof} gate {s['gate']:.1f}\n→ "
                 f"{'' if ok else 'not '}jointly compatible", fontsize=9, va="top")
        fig.subplots_adjust(left=0.08, right=0.67, bottom=0.09, top=0.93)
        return s
