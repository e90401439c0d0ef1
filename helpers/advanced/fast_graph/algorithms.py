"""The named optimisation algorithms: Gauss–Newton, the coursework's Levenberg–Marquardt and GTSAM's LM schedule.

(The default of ``optimize``, a Levenberg–Marquardt that converges far from the optimum, is in ``algorithms_default``.)

Each algorithm is a small class built from a frozen parameters dataclass; ``run(state, max_iterations, record)``
works on a ``linearise.FreeState`` and returns χ² and the ``LinearSystem`` (H, b, χ²) of the state it leaves in
the vertices (None when it stopped before linearising there). All three try steps through ONE mechanism,
``Trial``: it holds the accepted state X with its χ² and (H, b); ``try_step(dx)`` moves to X ⊞ (−dx) and returns
χ² there, ``accept(chi2)`` keeps the moved state (linearised when next needed), ``reject()`` goes back to X,
``finish()`` leaves X in the vertices. ``record(k, chi2, mu, rejected)`` is called once per outer iteration.

Transactions (g2o's push/pop). ``Algorithm.run`` — shared by all (the default algorithm too) — runs an algorithm's
``iterate`` inside ``try/except BaseException``: whatever escapes (a NonFiniteError, an exception in an edge model
or a vertex's ⊞, KeyboardInterrupt) first puts the last accepted X back into the vertices, then propagates. A
non-finite χ², H or b at the initial estimates, at a tried step or at an accepted one raises NonFiniteError (from
``FreeState``) naming the edges.

Levenberg–Marquardt exactly as the coursework (Lourakis, SBA Fig. 2), τ = 1e−3, ε1 = ε2 = ε3 = 1e−12, ε4 = 0:
    R0 = χ²(X), (H, b) at X; stop if ‖b‖∞ < ε1;  μ = τ·max diag H, ν = 2
    per outer iteration, until a step is accepted (or stop):
        dX = (H + μI)⁻¹ b; stop if ‖dX‖ < ε2 (‖X‖ + ε2)
        X' = X ⊞ (−dX), R1 = χ²(X'), ρ = (R0 − R1) / (dXᵀ(μ dX + b))
        ρ > 0: stop if √R0 − √R1 < ε4 √R0; accept; (H, b) at X; stop if ‖b‖∞ < ε1; μ ← μ·max(1/3, 1 − (2ρ − 1)³), ν = 2
        else:  μ ← μ ν, ν ← 2ν
    stop if √R0 < ε3
Gauss–Newton: dX = H⁻¹ b, step X ⊞ (−α dX) with α halved while χ² rises (down to 1e−10); stop when the decrease
is below ``tolerance`` (1e−5, absolute).
GTSAM's LevenbergMarquardtOptimizer with its default parameters: λ₀ = 1e−5 (absolute), λI damping, accept when
(actual / linearised decrease) > 1e−3 then λ /= 10, else λ *= 10 (stop above 1e5); stop when the decrease is below
1e−5 relative or absolute (on GTSAM's ½χ² scale).
"""

import numbers
from dataclasses import dataclass, fields

import numpy as np

from ...graph.errors import GraphError
from ...validation import finite_number, positive_number
from .linearise import LinearSystem

__all__ = ["GaussNewtonParams", "LevenbergMarquardtParams", "GTSAMLevenbergMarquardtParams", "Algorithm",
           "GaussNewton", "LevenbergMarquardt", "GTSAMLevenbergMarquardt", "Trial", "ALGORITHMS", "make_algorithm"]


_EPS = float(np.finfo(float).eps)


def _dot(a, b):
    """aᵀb without BLAS: on a loaded machine a threaded BLAS ddot can stall for milliseconds per call."""
    return float(np.multiply(a, b).sum())


def _check_fields(params, positive=()):
    """Every field a finite number ≥ 0, and > 0 for the names in ``positive``; ValueError naming the field."""
    for f in fields(params):
        value = getattr(params, f.name)
        name = f"{type(params).__name__}.{f.name}"
        if f.name in positive:
            positive_number(value, name)
        elif isinstance(value, bool) or not isinstance(value, numbers.Real) or not np.isfinite(value) or value < 0:
            raise ValueError(f"{name} must be a finite number ≥ 0, got {value!r}")


@dataclass(frozen=True)
class GaussNewtonParams:
    """Gauss–Newton with step halving. Stops when χ² decreases by less than ``tolerance`` (absolute)."""

    tolerance: float = 1e-5
    gradient_tolerance: float = 1e-12     # stop when ‖b‖∞ is below
    min_step_fraction: float = 1e-10      # give up when α has been halved below this

    def __post_init__(self):
        _check_fields(self, positive=("min_step_fraction",))
        if self.min_step_fraction > 1:
            raise ValueError(f"GaussNewtonParams.min_step_fraction must be ≤ 1 (the full step is α = 1), "
                             f"got {self.min_step_fraction!r}")


@dataclass(frozen=True)
class LevenbergMarquardtParams:
    """The coursework's LM (see the module docstring for ε1 … ε4)."""

    tau: float = 1e-3                     # initial μ = τ·max diag H
    gradient_tolerance: float = 1e-12     # ε1: stop when ‖b‖∞ is below
    step_tolerance: float = 1e-12         # ε2: stop when ‖dX‖ < ε2 (‖X‖ + ε2)
    chi2_tolerance: float = 1e-12         # ε3: stop when √χ² is below
    relative_decrease_tolerance: float = 0.0  # ε4: stop when √R0 − √R1 < ε4 √R0

    def __post_init__(self):
        _check_fields(self, positive=("tau",))


@dataclass(frozen=True)
class GTSAMLevenbergMarquardtParams:
    """GTSAM's LevenbergMarquardtParams defaults (λ absolute, damping λI)."""

    initial_lambda: float = 1e-5
    lambda_factor: float = 10.0
    max_lambda: float = 1e5
    min_model_fidelity: float = 1e-3      # accept when actual / linearised decrease exceeds this
    relative_tolerance: float = 1e-5      # stop when the decrease is below this × χ²
    absolute_tolerance: float = 1e-5      # … or below this on the ½χ² scale

    def __post_init__(self):
        _check_fields(self, positive=("initial_lambda", "lambda_factor", "max_lambda"))
        if self.lambda_factor <= 1:
            raise ValueError(f"GTSAMLevenbergMarquardtParams.lambda_factor must be > 1, got {self.lambda_factor!r}")
        if self.max_lambda <= self.initial_lambda:
            raise ValueError(f"GTSAMLevenbergMarquardtParams.max_lambda must be > initial_lambda "
                             f"({self.initial_lambda!r}), got {self.max_lambda!r}")


class Trial:
    """The accepted state of a run and the save / try / accept / reject mechanism all algorithms share.

    (H, b) at an accepted state is computed when first asked for (``system``): a run that stops right after
    accepting a step never linearises there (the optimiser then linearises on demand, e.g. for marginals)."""

    def __init__(self, state, start=None):
        """``start`` = (system, factored): the caller's LinearSystem at the vertices' current state (used instead
        of linearising again) and whether the solver holds its undamped factorisation (the first undamped
        ``solve`` then reuses it)."""
        self.state = state
        self.x = state.get()                  # the accepted state X
        system, factored = (None, False) if start is None else start
        if system is None:
            system = state.linearise("optimize: at the initial estimates")
        self._system = system                 # H, b at the accepted state
        self._factored = bool(factored)       # the solver holds the undamped factorisation of self._system
        self.chi2 = self._system.chi2         # χ² at the accepted state

    @property
    def system(self):
        """(H, b, χ²) at the accepted state X (the vertices must hold X; if linearising there raises, the run
        leaves X in the vertices: its χ² was finite when it was accepted)."""
        if self._system is None:
            self._system = self.state.linearise("optimize: at an accepted step")
        return self._system

    @property
    def gradient(self):
        return self.system.gradient

    def solve(self, damping=None):
        if damping is None and self._factored:
            return self.state.solve_factored(self.system)
        self._factored = damping is None
        return self.state.solve(self.system, damping)

    def try_step(self, dx):
        """Move to X ⊞ (−dx); returns χ² there (the accepted state is kept until ``accept``)."""
        _ = self.system                        # linearised at X before X is left
        self._move(dx)
        return self.state.chi2("optimize: at a trial step")

    def _move(self, dx):
        """The step itself: X ⊞ (−dx) by every vertex class's own ⊞ (subclasses may move some classes otherwise)."""
        self.state.retract(dx)

    def accept(self, chi2):
        """Keep the tried state (χ² = ``chi2``); it is linearised when (H, b) is next needed."""
        self.x, self.chi2, self._system, self._factored = self.state.get(), chi2, None, False

    def reject(self):
        """Go back to the accepted state."""
        self.state.set(self.x)

    def finish(self):
        """Leave the accepted state in the vertices; returns (χ², its LinearSystem or None if never linearised)."""
        self.state.set(self.x)
        if self._system is None:
            return self.chi2, None
        return self.chi2, LinearSystem(self._system.hessian_data, self._system.gradient, self.chi2)


class Algorithm:
    """Base of the three algorithms: ``run`` is the transaction around a subclass's ``iterate``."""

    name = None

    def run(self, state, max_iterations, record, start=None):
        """Iterate from the vertices' state; returns (χ², LinearSystem or None) of the accepted state left in the
        vertices (``Trial.finish``). ``start``: see ``Trial``.

        Any exception or interrupt (BaseException) restores the last accepted state before it propagates."""
        trial = None
        initial = state.get()
        try:
            trial = self.make_trial(state, start)
            self.iterate(trial, max_iterations, record)
            return trial.finish()
        except BaseException:
            state.set(initial if trial is None else trial.x)
            raise

    def make_trial(self, state, start=None):
        """The ``Trial`` over ``state`` (the default algorithm's moves SE(2) poses along arcs)."""
        return Trial(state, start)

    def iterate(self, trial, max_iterations, record):
        raise NotImplementedError


class GaussNewton(Algorithm):
    name = "gn"

    def __init__(self, params=None):
        self.params = GaussNewtonParams() if params is None else params

    def iterate(self, trial, max_iterations, record):
        p = self.params
        for k in range(1, max_iterations + 1):
            if np.max(np.abs(trial.gradient)) < p.gradient_tolerance:
                break
            dx = trial.solve()
            if not np.all(np.isfinite(dx)):
                raise GraphError("optimize (Gauss–Newton): the Hessian is singular; use algorithm='lm'")
            alpha = 1.0
            while True:
                r1 = trial.try_step(alpha * dx)
                if np.isfinite(r1) and r1 <= trial.chi2:
                    break
                trial.reject()
                alpha *= 0.5
                if alpha < p.min_step_fraction:
                    break
            if alpha < p.min_step_fraction:
                record(k, trial.chi2, 0.0, 1)
                break
            decrease = trial.chi2 - r1
            trial.accept(r1)
            record(k, trial.chi2, 0.0, 0)
            if decrease < p.tolerance:
                break


class LevenbergMarquardt(Algorithm):
    name = "lm"

    def __init__(self, params=None):
        self.params = LevenbergMarquardtParams() if params is None else params

    def iterate(self, trial, max_iterations, record):
        p = self.params
        if np.max(np.abs(trial.gradient)) < p.gradient_tolerance:
            return
        mu = p.tau * float(np.max(trial.system.hessian_data[trial.state.pattern.diag_pos]))
        nu = 2.0
        k = 1
        stop = False
        while not stop and k <= max_iterations:
            mu, nu, rejected, stop = self._iteration(trial, mu, nu)
            record(k, trial.chi2, mu, rejected)
            if np.sqrt(trial.chi2) < p.chi2_tolerance:
                stop = True
            k += 1

    def _iteration(self, trial, mu, nu):
        """Damped steps until one is accepted (or a stop test fires): returns (μ, ν, rejected steps, stop)."""
        p = self.params
        rejected = 0
        while True:
            dx = trial.solve(mu)
            if not np.all(np.isfinite(dx)):
                return mu, nu, rejected, True
            if np.sqrt(_dot(dx, dx)) < p.step_tolerance * (np.sqrt(_dot(trial.x, trial.x)) + p.step_tolerance):
                return mu, nu, rejected, True
            r0 = trial.chi2
            r1 = trial.try_step(dx)
            denom = _dot(dx, mu * dx + trial.gradient)
            rho = (r0 - r1) / denom if np.isfinite(r1) and denom > 0 else -1.0
            if rho > 0:
                stop = bool(np.sqrt(r0) - np.sqrt(r1) < p.relative_decrease_tolerance * np.sqrt(r0))
                trial.accept(r1)
                if np.max(np.abs(trial.gradient)) < p.gradient_tolerance:
                    stop = True
                mu *= max(1.0 / 3.0, 1.0 - (2.0 * rho - 1.0) ** 3)
                return mu, 2.0, rejected, stop
            trial.reject()
            rejected += 1
            mu *= nu
            nu *= 2.0
            if not np.isfinite(mu):
                return mu, nu, rejected, True


class GTSAMLevenbergMarquardt(Algorithm):
    name = "lm-gtsam"

    def __init__(self, params=None):
        self.params = GTSAMLevenbergMarquardtParams() if params is None else params

    def iterate(self, trial, max_iterations, record):
        p = self.params
        lam = p.initial_lambda
        for k in range(1, max_iterations + 1):
            r1, lam, rejected = self._damped_step(trial, lam)
            if r1 is None:
                record(k, trial.chi2, lam, rejected)
                break
            decrease = trial.chi2 - r1
            trial.accept(r1)
            lam /= p.lambda_factor
            record(k, trial.chi2, lam, rejected)
            if decrease < p.relative_tolerance * trial.chi2 or 0.5 * decrease < p.absolute_tolerance:
                break

    def _damped_step(self, trial, lam):
        """Raise λ until a step passes the fidelity test: returns (χ² after it, λ, rejected) — the state is then
        at the tried step — or (None, λ, rejected) when λ reached ``max_lambda`` or when a failed step changed χ²
        by less than ``relative_tolerance``·χ² (GTSAM's ``tryLambda``: a larger λ is not worth trying then).

        The fidelity test: the actual decrease χ²₀ − χ²₁ over the linearised one ℓ = 2bᵀdx − dxᵀH dx, which with
        (H + λI) dx = b is bᵀdx + λ‖dx‖², must exceed ``min_model_fidelity``; a step with ℓ ≤ ε·χ²₀ (ε the
        machine epsilon) never passes it, as in GTSAM."""
        p = self.params
        rejected = 0
        while lam < p.max_lambda:
            dx = trial.solve(lam)
            if np.all(np.isfinite(dx)):
                lin = _dot(trial.gradient, dx) + lam * _dot(dx, dx)
                if lin >= 0:
                    r1 = trial.try_step(dx)
                    change = trial.chi2 - r1
                    if np.isfinite(r1) and lin > _EPS * trial.chi2 and change / lin > p.min_model_fidelity:
                        return r1, lam, rejected
                    trial.reject()
                    if np.isfinite(r1) and abs(change) < p.relative_tolerance * trial.chi2:
                        return None, lam, rejected + 1
            rejected += 1
            lam *= p.lambda_factor
        return None, lam, rejected


ALGORITHMS = {"lm": (LevenbergMarquardt, LevenbergMarquardtParams),
              "gn": (GaussNewton, GaussNewtonParams),
              "lm-gtsam": (GTSAMLevenbergMarquardt, GTSAMLevenbergMarquardtParams)}


def make_algorithm(algorithm, tau=None, gn_tolerance=None):
    """The algorithm object for ``optimize``: ``algorithm`` is a name ("lm", "gn", "lm-gtsam"; ``tau`` and
    ``gn_tolerance`` then set LM's τ and Gauss–Newton's tolerance, None meaning the default) or a parameters object
    (``LevenbergMarquardtParams``, ``GaussNewtonParams``, ``GTSAMLevenbergMarquardtParams``), which sets every
    parameter. ``tau`` / ``gn_tolerance`` given where they do not apply raise ValueError (never silently ignored)."""
    name = algorithm if isinstance(algorithm, str) else None
    if tau is not None:
        tau = positive_number(tau, "tau")
        if name != "lm":
            raise ValueError(f"tau sets the initial damping of algorithm='lm' only (got algorithm={algorithm!r}); "
                             "set it in the parameters object instead")
    if gn_tolerance is not None:
        if finite_number(gn_tolerance, "gn_tolerance") < 0:
            raise ValueError(f"gn_tolerance must be a finite number ≥ 0, got {gn_tolerance!r}")
        if name != "gn":
            raise ValueError(f"gn_tolerance applies to algorithm='gn' only (got algorithm={algorithm!r}); "
                             "set it in the parameters object instead")
    for cls, params_cls in ALGORITHMS.values():
        if isinstance(algorithm, params_cls):
            return cls(algorithm)
    if name == "lm":
        return LevenbergMarquardt(LevenbergMarquardtParams(tau=LevenbergMarquardtParams.tau if tau is None else tau))
    if name == "gn":
        tolerance = GaussNewtonParams.tolerance if gn_tolerance is None else float(gn_tolerance)
        return GaussNewton(GaussNewtonParams(tolerance=tolerance))
    if name == "lm-gtsam":
        return GTSAMLevenbergMarquardt()
    raise ValueError(f"algorithm must be 'lm', 'gn' or 'lm-gtsam' or a parameters object, got {algorithm!r}")
