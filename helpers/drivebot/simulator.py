"""The DriveBot simulator: truth model, waypoint controller and sensors.

One ``step()`` moves tick k−1 → k:

1. truth (Euler, wheelbase B) with the control u_{k−1} = (s, δ) chosen at the previous tick:
       x ← x + s·DT·cos ψ,  y ← y + s·DT·sin ψ,  ψ ← wrap(ψ + s·DT·sin δ / B),  t ← t + DT;
2. sensors for the new truth, each only if due (t ≥ its next time; then next += period + rand·dither):
       GPS      z = [x, y] + R(ψ)·lever_arm + L_G n                    (L L^T = R_GPS)
       laser    every landmark with ‖m − p‖ ≤ range (360°):  r = ‖m − p‖ + σ_r n₁,
                β = wrap(atan2(m_y − y, m_x − x) − ψ + σ_β n₂)          (one event, 2×n data, 1-based ids;
                a reading with r ≤ 0 is not reported: a laser returns no non-positive distance)
       compass  z = wrap(ψ + Δψ_C + σ_C n)
3. the waypoint controller computes u_k: dX = wp − p, d = ‖dX‖; if d < 1 m the waypoint index advances (past the
   last one the run stops) and, the coursework's one-tick **quirk**, dX = p − wp_new; then
       s ← clamp(s + clamp(0.1·d − s, ±a_max·DT), [s_min, s_max]),
       δ ← clamp(δ + clamp(wrap(atan2(dX_y, dX_x) − ψ − δ), ±δ̇_max·DT), ±δ_max);
4. odometry  z = [s, 0, s·sin δ / B] + L_O n, stamped t_k (only while running).

Insertion order GPS, laser, compass, odometry, so the queue delivers odometry, compass, laser, GPS.
Randomness: one ``numpy.random.Generator`` draws the three first-sensor offsets (GPS, laser, compass:
rand·period) at ``start()``, then per tick each due, enabled sensor's noise and dither and the odometry noise.
The noise is drawn even when ``perturb_with_noise`` is False (scale 0), so a noise-free run has the event timing
of the noisy run with the same seed.
"""
from __future__ import annotations

import math

import numpy as np

from ..graph.angles import wrap_angle_mod
from ..validation import rng_seed
from .config import SimulatorConfiguration
from .events import Event, EventQueue, EventType
from .scenarios import Scenario

__all__ = ["DriveBotSimulator"]


class DriveBotSimulator:
    """Generates the coursework's event stream for a scenario: ``start()``, then while ``keep_running()``: read
    ``events()`` (this tick's batch in processing order) and ``ground_truth()`` at ``time``, and ``step()``."""

    def __init__(self, config: SimulatorConfiguration, scenario: Scenario, seed: int | np.random.Generator = 0):
        if not isinstance(config, SimulatorConfiguration):
            raise ValueError(f"config must be a SimulatorConfiguration, got {type(config).__name__}")
        if not isinstance(scenario, Scenario):
            raise ValueError(f"scenario must be a Scenario, got {type(scenario).__name__}")
        self.config = config
        self.scenario = scenario
        self._rng = seed if isinstance(seed, np.random.Generator) else np.random.default_rng(rng_seed(seed))
        self._noise_scale = 1.0 if config.perturb_with_noise else 0.0
        self._L_odo = np.linalg.cholesky(config.r_odometry)
        self._L_gps = np.linalg.cholesky(config.r_gps)
        self._L_laser = np.linalg.cholesky(config.r_laser)
        self._sigma_compass = math.sqrt(float(config.r_compass[0, 0]))
        #: laser readings not reported because their noisy range came out ≤ 0 (module docstring)
        self.dropped_laser_readings = 0

    # -- state (after start(): ``time``, the current tick's time, and ``step_number``, its index) -------------
    def ground_truth(self) -> np.ndarray:
        """The true vehicle state [x, y, ψ] at the current tick (a copy)."""
        return np.array([self._x, self._y, self._psi])

    def keep_running(self) -> bool:
        """False once the route is finished or ``maximum_step_number`` ticks have run."""
        return self._carry_on and self.step_number < self.config.maximum_step_number

    def events(self) -> list[Event]:
        """The current tick's events in processing order (the same list until the next ``step()``)."""
        return list(self._batch)

    # -- running ---------------------------------------------------------------------------------------
    def start(self) -> None:
        """Reset to [0, 0, 0] at t = 0, u = 0; queue the initial condition and a zero odometry event."""
        c = self.config
        self.time = 0.0
        self.step_number = 0
        self._x = self._y = self._psi = 0.0
        self._speed = self._steer = 0.0
        self._wp_index = 0
        self._carry_on = True
        offs = self._rng.random(3)
        self._next_gps = offs[0] * c.gps_measurement_period
        self._next_laser = offs[1] * c.laser_measurement_period
        self._next_compass = offs[2] * c.compass_measurement_period
        self.laser_fired = False           # whether the laser fired in the last step (event or not)
        q = EventQueue()
        q.insert(Event(0.0, EventType.INITIAL_CONDITION, np.zeros(3), np.zeros((3, 3))))
        q.insert(self._odometry_event())
        self._batch = q.pop_all()

    def step(self) -> None:
        """Advance one tick and generate that tick's events (RuntimeError once the route is finished)."""
        if not self._carry_on:
            raise RuntimeError("the route is finished (the vehicle passed its last waypoint, keep_running() is "
                               "False): call start() to run it again")
        c = self.config
        # 1. truth with the control chosen at the previous tick
        dist = self._speed * c.dt
        self._x += dist * math.cos(self._psi)
        self._y += dist * math.sin(self._psi)
        self._psi = wrap_angle_mod(self._psi + dist * math.sin(self._steer) / c.wheelbase)
        self.time += c.dt
        self.step_number += 1
        q = EventQueue()
        self.laser_fired = False
        # 2. sensors, insertion order GPS, laser, compass
        if c.enable_gps and self.time >= self._next_gps:
            q.insert(self._gps_event())
            self._next_gps += c.gps_measurement_period + self._rng.random() * c.sensor_dither_time
        if c.enable_laser and self.time >= self._next_laser:
            self.laser_fired = True        # also when no landmark is in range (then no LANDMARK event)
            ev = self._laser_event()
            if ev is not None:
                q.insert(ev)
            self._next_laser += c.laser_measurement_period + self._rng.random() * c.sensor_dither_time
        if c.enable_compass and self.time >= self._next_compass:
            q.insert(self._compass_event())
            self._next_compass += c.compass_measurement_period + self._rng.random() * c.sensor_dither_time
        # 3. controller; 4. odometry while running
        self._control()
        if self._carry_on and c.enable_odometry:
            q.insert(self._odometry_event())
        self._batch = q.pop_all()

    def _control(self) -> None:
        c = self.config
        wps = self.scenario.waypoints
        wx, wy = wps[0, self._wp_index], wps[1, self._wp_index]
        dx, dy = wx - self._x, wy - self._y
        d = math.hypot(dx, dy)
        if d < 1.0:
            self._wp_index += 1
            if self._wp_index >= wps.shape[1]:
                self._carry_on = False
                return
            # the coursework's quirk: for this one tick the steering target points away from the new waypoint
            dx, dy = self._x - wps[0, self._wp_index], self._y - wps[1, self._wp_index]
            d = math.hypot(dx, dy)
        dv = min(max(0.1 * d - self._speed, -c.max_acceleration * c.dt), c.max_acceleration * c.dt)
        self._speed = min(max(self._speed + dv, c.min_speed), c.max_speed)
        dd = wrap_angle_mod(math.atan2(dy, dx) - self._psi - self._steer)
        dd = min(max(dd, -c.max_diff_delta_rate * c.dt), c.max_diff_delta_rate * c.dt)
        self._steer = min(max(self._steer + dd, -c.max_delta), c.max_delta)
        self._carry_on = True

    # -- sensors ---------------------------------------------------------------------------------------
    def _odometry_event(self) -> Event:
        c = self.config
        u = np.array([self._speed, 0.0, self._speed * math.sin(self._steer) / c.wheelbase])
        z = u + self._noise_scale * (self._L_odo @ self._rng.standard_normal(3))
        return Event(self.time, EventType.VEHICLE_ODOMETRY, z, c.r_odometry)

    def _gps_event(self) -> Event:
        c = self.config
        cs, sn = math.cos(self._psi), math.sin(self._psi)
        lx, ly = c.gps_position_offset
        z = np.array([self._x + cs * lx - sn * ly, self._y + sn * lx + cs * ly])
        z = z + self._noise_scale * (self._L_gps @ self._rng.standard_normal(2))
        return Event(self.time, EventType.GPS, z, c.r_gps)

    def _compass_event(self) -> Event:
        c = self.config
        n = self._rng.standard_normal()
        z = wrap_angle_mod(self._psi + c.compass_angular_offset + self._noise_scale * self._sigma_compass * n)
        return Event(self.time, EventType.COMPASS, np.array([z]), c.r_compass)

    def _laser_event(self) -> Event | None:
        c = self.config
        lm = self.scenario.landmarks
        dx = lm[0] - self._x
        dy = lm[1] - self._y
        r = np.hypot(dx, dy)
        seen = np.flatnonzero(r <= c.laser_detection_range)
        if seen.size == 0:
            return None
        noise = self._noise_scale * (self._L_laser @ self._rng.standard_normal((2, seen.size)))
        z = np.vstack([r[seen] + noise[0], wrap_angle_mod(np.arctan2(dy[seen], dx[seen]) - self._psi + noise[1])])
        positive = z[0] > 0.0          # a laser reports no non-positive distance (module docstring)
        if not positive.all():
            self.dropped_laser_readings += int(np.count_nonzero(~positive))
            z, seen = z[:, positive], seen[positive]
            if seen.size == 0:
                return None
        return Event(self.time, EventType.LANDMARK, z, c.r_laser, landmark_ids=self.scenario.landmark_ids[seen])
