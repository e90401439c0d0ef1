"""``SimulatorConfiguration``: the DriveBot simulator's parameters with the coursework's defaults.

Field names are the MATLAB names in snake_case (``perturbWithNoise`` → ``perturb_with_noise``); the tick
``DT`` is ``dt`` and the wheelbase ``B`` is ``wheelbase``. Angles are radians, covariances full matrices.

Bounds (ValueError naming the field): every number positive and finite unless its comment says otherwise;
``max_delta`` ≤ π/2; every covariance is symmetric positive definite with standard deviations (square roots of
its eigenvalues) in [1e−6, 1e6] of their units and within a factor 1e6 of each other (``SIGMA_BOUNDS``,
``SIGMA_RATIO``): outside them Ω = R⁻¹ spans more than ~1e24 and the normal equations lose every digit.

A configuration is frozen once built (a simulator and SLAM systems read it while they run): the matrix fields are
read-only copies, and ``dataclasses.replace(config, dt=0.2)`` builds a checked changed copy.
"""
from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from ..validation import (boolean, finite_number, finite_vector, float_array, integer, nonnegative_number,
                          positive_number)

__all__ = ["SimulatorConfiguration", "SIGMA_BOUNDS", "SIGMA_RATIO"]

#: Allowed range of every standard deviation of a covariance field, in its own units (module docstring).
SIGMA_BOUNDS = (1e-6, 1e6)
#: Largest allowed ratio of two standard deviations of one covariance field (condition number of R ≤ ratio²).
SIGMA_RATIO = 1e6


def _diag(*sigmas):
    return np.diag(np.square(np.asarray(sigmas, dtype=float)))


@dataclass(frozen=True)
class SimulatorConfiguration:
    """Parameters of the DriveBot simulator, with the coursework's defaults (bounds: module docstring)."""

    dt: float = 0.1                                   # simulator tick (one vehicle vertex each), s
    maximum_step_number: float = math.inf             # debugging cap on the step counter (an integer or inf)
    wheelbase: float = 2.5                            # B in ψ̇ = s·sin δ / B, m
    perturb_with_noise: bool = True                   # False zeroes only the measurement noise
    sensor_dither_time: float = 0.01                  # random extra delay between sensor reads, s (≥ 0)
    max_diff_delta_rate: float = 20.0 * math.pi / 180.0   # steering rate limit (2° per tick)
    max_delta: float = 40.0 * math.pi / 180.0         # steering angle limit
    max_speed: float = 10.0                           # m/s
    min_speed: float = 1.0                            # m/s
    max_acceleration: float = 0.5                     # m/s² (0.05 m/s per tick)
    enable_odometry: bool = True
    r_odometry: np.ndarray = field(default_factory=lambda: _diag(0.2, 0.1, math.pi / 180.0))  # σ speed, slip, ψ̇
    enable_compass: bool = False
    compass_measurement_period: float = 0.1           # s
    r_compass: np.ndarray = field(default_factory=lambda: _diag(5.0 * math.pi / 180.0))      # 1×1
    compass_angular_offset: float = 0.0               # Δψ_C (any finite angle)
    enable_gps: bool = False
    gps_measurement_period: float = 1.0               # s
    r_gps: np.ndarray = field(default_factory=lambda: np.eye(2))
    gps_position_offset: np.ndarray = field(default_factory=lambda: np.array([10.0, -20.0]))  # lever arm (body), m
    enable_laser: bool = False
    laser_measurement_period: float = 0.1             # s
    laser_detection_range: float = 10.0               # m, 360° field of view
    r_laser: np.ndarray = field(default_factory=lambda: _diag(0.1, math.pi / 180.0))          # σ range, bearing

    def __post_init__(self):
        """Check every field (bounds: module docstring) and store it normalised (floats, bools, read-only arrays)."""
        def store(name, value):
            object.__setattr__(self, name, value)

        for name in ("dt", "wheelbase", "max_diff_delta_rate", "max_delta", "max_speed", "min_speed",
                     "max_acceleration", "compass_measurement_period", "gps_measurement_period",
                     "laser_measurement_period", "laser_detection_range"):
            store(name, positive_number(getattr(self, name), name))
        if self.max_delta > 0.5 * math.pi:
            raise ValueError(f"max_delta must be at most π/2 (a steering angle beyond 90°), got {self.max_delta!r}")
        if self.min_speed > self.max_speed:
            raise ValueError(f"min_speed ({self.min_speed}) must not exceed max_speed ({self.max_speed})")
        store("sensor_dither_time", nonnegative_number(self.sensor_dither_time, "sensor_dither_time"))
        if self.maximum_step_number != math.inf:
            store("maximum_step_number", integer(self.maximum_step_number, "maximum_step_number", minimum=1))
        for name in ("perturb_with_noise", "enable_odometry", "enable_compass", "enable_gps", "enable_laser"):
            store(name, boolean(getattr(self, name), name))
        store("compass_angular_offset", finite_number(self.compass_angular_offset, "compass_angular_offset"))
        offset = finite_vector(np.ravel(self.gps_position_offset), "gps_position_offset", size=2).copy()
        offset.flags.writeable = False
        store("gps_position_offset", offset)
        for name, n in (("r_odometry", 3), ("r_compass", 1), ("r_gps", 2), ("r_laser", 2)):
            store(name, _covariance(getattr(self, name), name, n))

    @classmethod
    def field_names(cls) -> tuple[str, ...]:
        """The names of the fields, in order."""
        return tuple(f.name for f in dataclasses.fields(cls))


def _covariance(value: object, name: str, n: int) -> np.ndarray:
    """A covariance field as a read-only (n, n) float copy: symmetric, finite, positive definite, with its
    standard deviations inside SIGMA_BOUNDS and within SIGMA_RATIO of each other."""
    R = np.atleast_2d(float_array(value, name)).copy()
    if R.shape != (n, n) or not np.all(np.isfinite(R)) or not np.allclose(R, R.T):
        raise ValueError(f"{name} must be a symmetric finite {n}×{n} matrix, got {value!r}")
    eig = np.linalg.eigvalsh(R)
    if np.min(eig) <= 0:
        raise ValueError(f"{name} must be positive definite")
    sigma = np.sqrt(eig)
    if sigma[0] < SIGMA_BOUNDS[0] or sigma[-1] > SIGMA_BOUNDS[1] or sigma[-1] > SIGMA_RATIO * sigma[0]:
        raise ValueError(f"{name} must have standard deviations in [{SIGMA_BOUNDS[0]:g}, {SIGMA_BOUNDS[1]:g}] (its "
                         f"units) within a factor {SIGMA_RATIO:g} of each other, got {sigma[0]:.3g} … {sigma[-1]:.3g}")
    R.flags.writeable = False
    return R
