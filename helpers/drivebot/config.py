"""``SimulatorConfiguration``: the DriveBot simulator's parameters with the coursework's defaults.

Field names are the MATLAB names in snake_case (``perturbWithNoise`` → ``perturb_with_noise``); the tick
``DT`` is ``dt`` and the wheelbase ``B`` is ``wheelbase``. Angles are radians, covariances full matrices.

| field                        | default                      | meaning                                  |
|------------------------------|------------------------------|------------------------------------------|
| dt                           | 0.1 s                        | simulator tick (one vehicle vertex each) |
| maximum_step_number          | inf                          | debugging cap on the step counter        |
| wheelbase                    | 2.5 m                        | B in ψ̇ = s·sin δ / B                     |
| perturb_with_noise           | True                         | False zeroes only the measurement noise  |
| sensor_dither_time           | 0.01 s                       | random extra delay between sensor reads  |
| max_diff_delta_rate          | 20°/s                        | steering rate limit (2° per tick)        |
| max_delta                    | 40°                          | steering angle limit                     |
| max_speed, min_speed         | 10 m/s, 1 m/s                |                                          |
| max_acceleration             | 0.5 m/s²                     | 0.05 m/s per tick                        |
| enable_odometry              | True                         |                                          |
| r_odometry                   | diag(0.2, 0.1, π/180)²       | σ speed, σ lateral slip, σ yaw rate      |
| enable_compass               | False                        |                                          |
| compass_measurement_period   | 0.1 s                        |                                          |
| r_compass                    | (5π/180)²                    | 1×1                                      |
| compass_angular_offset       | 0                            | Δψ_C                                     |
| enable_gps                   | False                        |                                          |
| gps_measurement_period       | 1 s                          |                                          |
| r_gps                        | I₂                           |                                          |
| gps_position_offset          | [10, −20] m                  | lever arm in the platform frame          |
| enable_laser                 | False                        |                                          |
| laser_measurement_period     | 0.1 s                        |                                          |
| laser_detection_range        | 10 m                         | 360° field of view                       |
| r_laser                      | diag(0.1, π/180)²            | σ range, σ bearing                       |

Bounds (``validate``, ValueError naming the field): every number positive and finite except where the table
says otherwise; ``max_delta`` ≤ π/2 (a steering angle beyond 90° is not a bicycle model); every covariance is a
symmetric positive-definite matrix whose standard deviations (square roots of its eigenvalues) lie in
[1e−6, 1e6] of their units (m, rad, m/s, rad/s) and differ by at most a factor 1e6 within one matrix
(``SIGMA_BOUNDS``, ``SIGMA_RATIO``): outside them the information matrices Ω = R⁻¹ span more than ~1e24 and
the optimiser's normal equations lose every significant digit (χ² ~1e270 or no covariance at all).

A configuration is read-only once constructed (a simulator and SLAM systems read it while they run; an edit
would apply half-way): assigning a field raises ``dataclasses.FrozenInstanceError`` and the matrix fields are
read-only arrays. ``replace(**changes)`` returns a validated changed copy.
"""
from __future__ import annotations

import dataclasses
import math
import numbers
from dataclasses import dataclass, field

import numpy as np

from ..validation import boolean, float_array

__all__ = ["SimulatorConfiguration", "SIGMA_BOUNDS", "SIGMA_RATIO"]

#: Allowed range of every standard deviation of a covariance field, in its own units (module docstring).
SIGMA_BOUNDS = (1e-6, 1e6)
#: Largest allowed ratio of two standard deviations of one covariance field (condition number of R ≤ ratio²).
SIGMA_RATIO = 1e6


def _diag(*sigmas):
    return np.diag(np.square(np.asarray(sigmas, dtype=float)))


@dataclass
class SimulatorConfiguration:
    """Parameters of the DriveBot simulator (see the module docstring for the table of defaults)."""

    dt: float = 0.1
    maximum_step_number: float = math.inf
    wheelbase: float = 2.5
    perturb_with_noise: bool = True
    sensor_dither_time: float = 0.01
    max_diff_delta_rate: float = 20.0 * math.pi / 180.0
    max_delta: float = 40.0 * math.pi / 180.0
    max_speed: float = 10.0
    min_speed: float = 1.0
    max_acceleration: float = 0.5
    enable_odometry: bool = True
    r_odometry: np.ndarray = field(default_factory=lambda: _diag(0.2, 0.1, math.pi / 180.0))
    enable_compass: bool = False
    compass_measurement_period: float = 0.1
    r_compass: np.ndarray = field(default_factory=lambda: _diag(5.0 * math.pi / 180.0))
    compass_angular_offset: float = 0.0
    enable_gps: bool = False
    gps_measurement_period: float = 1.0
    r_gps: np.ndarray = field(default_factory=lambda: np.eye(2))
    gps_position_offset: np.ndarray = field(default_factory=lambda: np.array([10.0, -20.0]))
    enable_laser: bool = False
    laser_measurement_period: float = 0.1
    laser_detection_range: float = 10.0
    r_laser: np.ndarray = field(default_factory=lambda: _diag(0.1, math.pi / 180.0))

    def __post_init__(self):
        self.validate()
        object.__setattr__(self, "_read_only", True)

    def __setattr__(self, name, value):
        if getattr(self, "_read_only", False):
            raise dataclasses.FrozenInstanceError(
                f"SimulatorConfiguration is read-only once constructed (cannot assign {name!r}); use "
                f"config.replace({name}=...) for a validated copy")
        object.__setattr__(self, name, value)

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        return tuple(f.name for f in dataclasses.fields(cls))

    def replace(self, **changes) -> SimulatorConfiguration:
        """A validated copy with some fields changed (unknown names raise ValueError)."""
        unknown = sorted(set(changes) - set(self.field_names()))
        if unknown:
            raise ValueError(f"unknown SimulatorConfiguration field(s) {unknown}; known: {list(self.field_names())}")
        return dataclasses.replace(self, **changes)

    def validate(self) -> None:
        """Check every field (bounds: module docstring); raise ValueError naming the field and what was expected.

        Normalises the fields in place (floats, bools, read-only float arrays); idempotent."""
        for name in ("dt", "wheelbase", "max_diff_delta_rate", "max_delta", "max_speed", "min_speed",
                     "max_acceleration", "compass_measurement_period", "gps_measurement_period",
                     "laser_measurement_period", "laser_detection_range"):
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v) or v <= 0:
                raise ValueError(f"{name} must be a positive finite number, got {v!r}")
            object.__setattr__(self, name, float(v))
        if self.max_delta > 0.5 * math.pi:
            raise ValueError(f"max_delta must be at most π/2 (a steering angle beyond 90°), got {self.max_delta!r}")
        v = self.sensor_dither_time
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v) or v < 0:
            raise ValueError(f"sensor_dither_time must be a non-negative finite number, got {v!r}")
        object.__setattr__(self, "sensor_dither_time", float(v))
        if self.min_speed > self.max_speed:
            raise ValueError(f"min_speed ({self.min_speed}) must not exceed max_speed ({self.max_speed})")
        m = self.maximum_step_number
        if isinstance(m, bool) or not isinstance(m, numbers.Real) or m <= 0 or \
                (math.isfinite(m) and m != int(m)) or math.isnan(m):
            raise ValueError(f"maximum_step_number must be a positive integer or inf, got {m!r}")
        for name in ("perturb_with_noise", "enable_odometry", "enable_compass", "enable_gps", "enable_laser"):
            object.__setattr__(self, name, boolean(getattr(self, name), name))
        v = self.compass_angular_offset
        if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v):
            raise ValueError(f"compass_angular_offset must be a finite angle in radians, got {v!r}")
        object.__setattr__(self, "compass_angular_offset", float(v))
        off = float_array(self.gps_position_offset, "gps_position_offset").reshape(-1).copy()
        if off.shape != (2,) or not np.all(np.isfinite(off)):
            raise ValueError(f"gps_position_offset must be 2 finite numbers, got {self.gps_position_offset!r}")
        off.flags.writeable = False
        object.__setattr__(self, "gps_position_offset", off)
        for name, n in (("r_odometry", 3), ("r_compass", 1), ("r_gps", 2), ("r_laser", 2)):
            object.__setattr__(self, name, _covariance(getattr(self, name), name, n))


def _covariance(value, name, n):
    """A covariance field as a read-only (n, n) float copy: symmetric, finite, positive definite, with its
    standard deviations inside SIGMA_BOUNDS and within SIGMA_RATIO of each other."""
    R = np.atleast_2d(float_array(value, name)).copy()
    if R.shape != (n, n) or not np.all(np.isfinite(R)) or not np.allclose(R, R.T):
        raise ValueError(f"{name} must be a symmetric finite {n}×{n} matrix, got {value!r}")
    eig = np.linalg.eigvalsh(R)
    if np.min(eig) <= 0:
        raise ValueError(f"{name} must be positive definite")
    lo, hi = SIGMA_BOUNDS
    sigma = np.sqrt(eig)
    if sigma[0] < lo or sigma[-1] > hi:
        raise ValueError(f"{name} must have standard deviations between {lo:g} and {hi:g} (its units), got "
                         f"σ from {sigma[0]:.3g} to {sigma[-1]:.3g}")
    if sigma[-1] > SIGMA_RATIO * sigma[0]:
        raise ValueError(f"{name} has standard deviations {sigma[0]:.3g} … {sigma[-1]:.3g} that differ by more "
                         f"than a factor {SIGMA_RATIO:g} (ill-conditioned)")
    R.flags.writeable = False
    return R
