"""Smooth vehicle motions with exact derivatives, the source of every simulated signal.

Each motion evaluates ``kinematics(t)``: position, world velocity and acceleration,
body-to-world attitude and body angular rate, all from closed forms or from the exact
derivatives of a cubic spline, so that an IMU synthesised from them integrates back to
the same trajectory (up to the integrator's own error). Motions are at least C2 in
position, so the accelerometer signal is continuous.

Shapes: ``t`` (N,); 3-D motions give positions (N, 3), rotations (N, 3, 3), body rates
(N, 3); planar motions give positions (N, 2), rotations (N, 2, 2), headings (N,), and body
rates (N, 1) (yaw rate about z).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.signal import lfilter

from datasets.rotations import rot2_batch


@dataclass(frozen=True)
class Kinematics:
    """True motion sampled at times ``t``.

    Attributes:
        t: times [s], shape (N,).
        position: world position [m], shape (N, d).
        velocity: world velocity [m/s], shape (N, d).
        acceleration: world acceleration [m/s^2] (gravity not included), shape (N, d).
        rotation: body-to-world rotation matrices, shape (N, d, d).
        body_rate: body angular rate [rad/s], shape (N, 3) in 3-D, (N, 1) in 2-D.
        heading: planar heading [rad] (unwrapped), shape (N,); None in 3-D.
    """

    t: np.ndarray
    position: np.ndarray
    velocity: np.ndarray
    acceleration: np.ndarray
    rotation: np.ndarray
    body_rate: np.ndarray
    heading: np.ndarray | None = None

    @property
    def dimension(self) -> int:
        return int(self.position.shape[1])

    def body_velocity(self) -> np.ndarray:
        """Velocity in the body frame, ``R^T v``, shape (N, d)."""
        return np.einsum("nji,nj->ni", self.rotation, self.velocity)


def rotation_zyx(yaw: np.ndarray, pitch: np.ndarray, roll: np.ndarray) -> np.ndarray:
    """Body-to-world ``Rz(yaw) Ry(pitch) Rx(roll)``, shape (N, 3, 3), angles [rad] shape (N,)."""
    cy, sy = np.cos(yaw), np.sin(yaw)
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    rows = [
        [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
        [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
        [-sp, cp * sr, cp * cr],
    ]
    return np.stack([np.stack(row, axis=-1) for row in rows], axis=-2)


def body_rate_zyx(
    pitch: np.ndarray,
    roll: np.ndarray,
    yaw_rate: np.ndarray,
    pitch_rate: np.ndarray,
    roll_rate: np.ndarray,
) -> np.ndarray:
    """Body angular rate [rad/s], shape (N, 3), of ``Rz(yaw) Ry(pitch) Rx(roll)`` from the
    Euler angle rates (the standard ZYX kinematic relation)."""
    cp, sp = np.cos(pitch), np.sin(pitch)
    cr, sr = np.cos(roll), np.sin(roll)
    return np.column_stack(
        [
            roll_rate - yaw_rate * sp,
            pitch_rate * cr + yaw_rate * cp * sr,
            -pitch_rate * sr + yaw_rate * cp * cr,
        ]
    )


@dataclass(frozen=True)
class Terrain:
    """Gently rolling ground ``z = h(x, y) = base + sum_i A_i sin(k_i . (x, y) + phase_i)``.

    Attributes:
        amplitudes_m: A_i [m], shape (n,).
        wave_vectors: k_i [rad/m], shape (n, 2).
        phases_rad: shape (n,).
        base_m: constant offset [m].
    """

    amplitudes_m: np.ndarray
    wave_vectors: np.ndarray
    phases_rad: np.ndarray
    base_m: float = 0.0

    def height(self, xy: np.ndarray) -> np.ndarray:
        """Ground height [m] at positions (N, 2) -> (N,)."""
        return self.evaluate(xy)[0]

    def evaluate(self, xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Height (N,), gradient (N, 2) and Hessian (N, 2, 2) at positions (N, 2)."""
        arguments = xy @ self.wave_vectors.T + self.phases_rad  # (N, n)
        height = self.base_m + np.sin(arguments) @ self.amplitudes_m
        gradient = (np.cos(arguments) * self.amplitudes_m) @ self.wave_vectors
        outer = np.einsum("ia,ib->iab", self.wave_vectors, self.wave_vectors)
        hessian = -np.einsum("ni,iab->nab", np.sin(arguments) * self.amplitudes_m, outer)
        return height, gradient, hessian


class TerrainViaPointLoop:
    """A ground vehicle driving a closed loop through via points over a terrain.

    The horizontal path is a periodic cubic spline in time through the via points (C2,
    so acceleration is continuous), with knot times proportional to the chord lengths at
    ``speed_m_s``; the loop repeats for longer durations. Height follows the terrain; the
    heading follows the horizontal velocity; pitch and roll follow the ground slope along
    and across the heading (nose up on a rising slope, left side up when the ground rises
    to the left). All derivatives are analytic.
    """

    def __init__(self, via_points_xy: np.ndarray, speed_m_s: float, terrain: Terrain):
        points = np.asarray(via_points_xy, dtype=float)
        closed = np.vstack([points, points[:1]])
        chords = np.linalg.norm(np.diff(closed, axis=0), axis=1)
        knots = np.concatenate([[0.0], np.cumsum(chords / speed_m_s)])
        self.via_points_xy = points
        self.terrain = terrain
        self.period_s = float(knots[-1])
        self.knot_times_s = knots
        self._spline = CubicSpline(knots, closed, axis=0, bc_type="periodic")

    def kinematics(self, t: np.ndarray) -> Kinematics:
        t = np.asarray(t, dtype=float)
        tau = np.mod(t, self.period_s)
        xy, vxy, axy = self._spline(tau), self._spline(tau, 1), self._spline(tau, 2)
        height, gradient, hessian = self.terrain.evaluate(xy)
        hv = np.einsum("nab,nb->na", hessian, vxy)
        vz = np.sum(gradient * vxy, axis=1)
        az = np.sum(hv * vxy, axis=1) + np.sum(gradient * axy, axis=1)

        speed_squared = np.sum(vxy**2, axis=1)
        yaw = np.unwrap(np.arctan2(vxy[:, 1], vxy[:, 0]))
        yaw_rate = (vxy[:, 0] * axy[:, 1] - vxy[:, 1] * axy[:, 0]) / speed_squared
        forward = np.column_stack([np.cos(yaw), np.sin(yaw)])
        left = np.column_stack([-np.sin(yaw), np.cos(yaw)])
        slope_forward = np.sum(gradient * forward, axis=1)
        slope_left = np.sum(gradient * left, axis=1)
        slope_forward_rate = np.sum(hv * forward, axis=1) + slope_left * yaw_rate
        slope_left_rate = np.sum(hv * left, axis=1) - slope_forward * yaw_rate
        pitch = -np.arctan(slope_forward)
        pitch_rate = -slope_forward_rate / (1.0 + slope_forward**2)
        roll = np.arctan(slope_left)
        roll_rate = slope_left_rate / (1.0 + slope_left**2)

        return Kinematics(
            t=t,
            position=np.column_stack([xy, height]),
            velocity=np.column_stack([vxy, vz]),
            acceleration=np.column_stack([axy, az]),
            rotation=rotation_zyx(yaw, pitch, roll),
            body_rate=body_rate_zyx(pitch, roll, yaw_rate, pitch_rate, roll_rate),
        )


class CircleMotion:
    """Level constant-speed circle (counterclockwise), heading along the velocity.

    Starts at ``center + (radius, 0, 0)`` heading +y.
    """

    def __init__(self, center: np.ndarray, radius_m: float, speed_m_s: float):
        self.center = np.asarray(center, dtype=float)
        self.radius_m = float(radius_m)
        self.speed_m_s = float(speed_m_s)
        self.period_s = 2.0 * np.pi * radius_m / speed_m_s

    def kinematics(self, t: np.ndarray) -> Kinematics:
        t = np.asarray(t, dtype=float)
        omega = self.speed_m_s / self.radius_m
        angle = omega * t
        cos, sin, zero = np.cos(angle), np.sin(angle), np.zeros_like(t)
        radius = self.radius_m
        yaw = angle + 0.5 * np.pi
        return Kinematics(
            t=t,
            position=self.center + np.column_stack([radius * cos, radius * sin, zero]),
            velocity=np.column_stack([-radius * omega * sin, radius * omega * cos, zero]),
            acceleration=np.column_stack(
                [-radius * omega**2 * cos, -radius * omega**2 * sin, zero]
            ),
            rotation=rotation_zyx(yaw, zero, zero),
            body_rate=np.column_stack([zero, zero, np.full_like(t, omega)]),
        )


class StaticMotion:
    """No motion: a fixed pose (position [m], yaw/pitch/roll [rad])."""

    def __init__(self, position: np.ndarray, yaw_rad: float, pitch_rad: float, roll_rad: float):
        self.position = np.asarray(position, dtype=float)
        self.angles = (float(yaw_rad), float(pitch_rad), float(roll_rad))

    def kinematics(self, t: np.ndarray) -> Kinematics:
        t = np.asarray(t, dtype=float)
        count = len(t)
        yaw, pitch, roll = (np.full(count, angle) for angle in self.angles)
        zeros = np.zeros((count, 3))
        return Kinematics(
            t=t,
            position=np.tile(self.position, (count, 1)),
            velocity=zeros,
            acceleration=zeros.copy(),
            rotation=rotation_zyx(yaw, pitch, roll),
            body_rate=zeros.copy(),
        )


# Gauss-Legendre nodes for the position integral inside a rounded corner: the integrand
# (cos, sin of a smooth heading) is analytic, so 32 nodes give machine precision.
_GAUSS_NODES, _GAUSS_WEIGHTS = np.polynomial.legendre.leggauss(32)


@dataclass(frozen=True)
class _Corner:
    """A smooth turn of ``turn_rad`` over arc length ``length_m`` starting at arc length
    ``start_s``, from ``start_point`` with heading ``start_heading``."""

    start_s: float
    length_m: float
    turn_rad: float
    start_point: np.ndarray
    start_heading: float

    def heading(self, u: np.ndarray) -> np.ndarray:
        """Heading after arc length u in [0, length] into the turn."""
        length = self.length_m
        return self.start_heading + (self.turn_rad / length) * (
            u - length / (2 * np.pi) * np.sin(2 * np.pi * u / length)
        )

    def curvature(self, u: np.ndarray) -> np.ndarray:
        """Curvature [1/m]: a raised cosine, zero with zero slope at both ends (heading C2)."""
        return (self.turn_rad / self.length_m) * (1.0 - np.cos(2 * np.pi * u / self.length_m))

    def point(self, u: np.ndarray) -> np.ndarray:
        """Position after arc length u into the turn, shape (K, 2), by Gauss-Legendre."""
        u = np.asarray(u, dtype=float)
        samples = 0.5 * u[:, None] * (_GAUSS_NODES[None, :] + 1.0)  # (K, 32)
        headings = self.heading(samples)
        weights = 0.5 * u[:, None] * _GAUSS_WEIGHTS[None, :]
        return self.start_point + np.column_stack(
            [np.sum(weights * np.cos(headings), axis=1), np.sum(weights * np.sin(headings), axis=1)]
        )


def _turn_offsets(length_m: float, turn_rad: float) -> float:
    """Distance from a polyline vertex back to where a rounded turn of ``turn_rad`` over
    ``length_m`` must start (equal to the distance after the vertex where it ends)."""
    corner = _Corner(0.0, length_m, turn_rad, np.zeros(2), 0.0)
    end = corner.point(np.array([length_m]))[0]
    after = end[1] / np.sin(turn_rad)
    return float(end[0] - after * np.cos(turn_rad))


class RoundedPolylinePath:
    """A planar path along a polyline with every vertex rounded by a smooth turn.

    Straight segments join turns whose curvature is a raised cosine in arc length, so the
    heading is C2 and the position C3 in arc length. ``point(s)`` etc. take arc length [m].
    """

    def __init__(self, vertices: np.ndarray, turn_length_m: float):
        vertices = np.asarray(vertices, dtype=float)
        directions = np.diff(vertices, axis=0)
        lengths = np.linalg.norm(directions, axis=1)
        headings = np.arctan2(directions[:, 1], directions[:, 0])
        self.corners: list[_Corner] = []
        s = 0.0
        point = vertices[0].copy()
        heading = float(headings[0])
        previous_exit = 0.0
        for index in range(1, len(vertices) - 1):
            turn = float(np.angle(np.exp(1j * (headings[index] - headings[index - 1]))))
            offset = _turn_offsets(turn_length_m, turn)
            straight = lengths[index - 1] - previous_exit - offset
            if straight < 0:
                raise ValueError(
                    f"polyline segment {index} too short for rounded turns of {turn_length_m} m"
                )
            point = point + straight * np.array([np.cos(heading), np.sin(heading)])
            s += straight
            corner = _Corner(s, turn_length_m, turn, point.copy(), heading)
            self.corners.append(corner)
            point = corner.point(np.array([turn_length_m]))[0]
            heading += turn
            s += turn_length_m
            previous_exit = offset
        final = lengths[-1] - previous_exit
        if final < 0:
            raise ValueError("last polyline segment too short for the rounded turn")
        self.final_start_s = s
        self.final_start_point = point
        self.final_heading = heading
        self.length_m = s + final
        self.start_heading = float(headings[0])
        self.start_point = vertices[0].copy()

    def evaluate(self, s: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Position (K, 2), heading (K,) [rad, unwrapped] and curvature (K,) at arc lengths s."""
        s = np.asarray(s, dtype=float)
        position = np.zeros((len(s), 2))
        heading = np.zeros(len(s))
        curvature = np.zeros(len(s))
        # Walk the pieces: straight before each corner, the corner, and the final straight.
        straight_start_s, straight_point, straight_heading = (
            0.0,
            self.start_point,
            self.start_heading,
        )
        pieces = []
        for corner in self.corners:
            pieces.append(
                ("straight", straight_start_s, corner.start_s, straight_point, straight_heading)
            )
            pieces.append(
                ("corner", corner.start_s, corner.start_s + corner.length_m, corner, None)
            )
            straight_start_s = corner.start_s + corner.length_m
            straight_point = corner.point(np.array([corner.length_m]))[0]
            straight_heading = corner.start_heading + corner.turn_rad
        pieces.append(("straight", straight_start_s, np.inf, straight_point, straight_heading))
        for kind, begin, end, anchor, angle in pieces:
            mask = (s >= begin) & (s < end) if np.isfinite(end) else (s >= begin)
            if not np.any(mask):
                continue
            u = s[mask] - begin
            if kind == "straight":
                position[mask] = anchor + u[:, None] * np.array([np.cos(angle), np.sin(angle)])
                heading[mask] = angle
            else:
                position[mask] = anchor.point(u)
                heading[mask] = anchor.heading(u)
                curvature[mask] = anchor.curvature(u)
        return position, heading, curvature


@dataclass(frozen=True)
class SinusoidalSpeed:
    """Speed ``v(t) = v_mean (1 + a sin(2 pi n t / T))`` over a duration T with n whole
    cycles, so the mean speed is exactly ``v_mean`` and the distance is ``v_mean T``.
    Smooth (C-infinity), never negative for ``|a| < 1``."""

    mean_m_s: float
    amplitude: float
    cycles: int
    duration_s: float

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Distance [m], speed [m/s] and its derivative [m/s^2] at times t, each (N,)."""
        w = 2 * np.pi * self.cycles / self.duration_s
        v0, a = self.mean_m_s, self.amplitude
        distance = v0 * (t + (a / w) * (1.0 - np.cos(w * t)))
        speed = v0 * (1.0 + a * np.sin(w * t))
        rate = v0 * a * w * np.cos(w * t)
        return distance, speed, rate


class RandomSpeed:
    """A seeded random speed: mean-reverting random walk (Ornstein-Uhlenbeck)
    ``dv = -(v - v_mean) / tau dt + sigma dW``, rescaled so that the distance after
    ``duration_s`` is exactly ``v_mean * duration_s`` (the path is still covered once);
    with ``tau_s=None`` a pure random walk ``dv = sigma dW``, not rescaled.

    Over times much shorter than ``tau`` the speed is a random walk of density ``sigma``
    [m/s/sqrt(s)]: the velocity model of Guerreiro et al. eq. (2) with its disturbance
    (``Xi_V = Ts sigma_v^2``). The reversion (``tau`` = 5 s by default) keeps the distance
    within about ``sigma tau sqrt(T)`` of the mean so the rescaling is a few percent.
    Drawn exactly on a 10 ms grid, linear in between: the speed is continuous, so the yaw
    rate ``curvature * speed`` is too; its derivative is piecewise constant.
    """

    GRID_S = 0.01

    def __init__(
        self,
        mean_m_s: float,
        sigma: float,
        duration_s: float,
        rng: np.random.Generator,
        tau_s: float | None = 5.0,
    ):
        self.mean_m_s = float(mean_m_s)
        self.duration_s = float(duration_s)
        count = int(np.ceil(self.duration_s / self.GRID_S)) + 2
        if tau_s is None:
            # a pure random walk (eq. (2) exactly), not rescaled: the distance is whatever
            # the walk gives
            decay, step_sigma = 1.0, sigma * np.sqrt(self.GRID_S)
        else:
            decay = np.exp(-self.GRID_S / tau_s)
            # exact OU transition over one grid step
            step_sigma = sigma * np.sqrt(tau_s / 2.0 * (1.0 - decay**2))
        shocks = rng.standard_normal(count - 1) * step_sigma
        # deviation[i] = decay * deviation[i - 1] + shocks[i - 1], from deviation[0] = 0
        deviation = np.concatenate([[0.0], lfilter([1.0], [1.0, -decay], shocks)])
        speed = self.mean_m_s + deviation
        self._times = np.arange(count) * self.GRID_S
        distance = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * self.GRID_S)])
        scale = (
            1.0
            if tau_s is None
            else self.mean_m_s
            * self.duration_s
            / float(np.interp(self.duration_s, self._times, distance))
        )
        self._speed = speed * scale
        self._distance = distance * scale
        if np.min(self._speed) <= 0.0:
            raise ValueError("random speed profile reached zero: lower its sigma")

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Distance [m], speed [m/s] and its derivative [m/s^2] at times t, each (N,)."""
        t = np.asarray(t, dtype=float)
        index = np.clip(np.searchsorted(self._times, t, side="right") - 1, 0, len(self._times) - 2)
        into = t - self._times[index]
        slope = (self._speed[index + 1] - self._speed[index]) / self.GRID_S
        speed = self._speed[index] + slope * into
        distance = self._distance[index] + self._speed[index] * into + 0.5 * slope * into**2
        return distance, speed, slope


class LateralDrift:
    """A seeded lateral body velocity ``u``: a random walk ``du = sigma dW`` from 0, drawn on
    a 10 ms grid and linear in between (as ``RandomSpeed``): a vehicle that slips sideways
    while its heading follows the path, so that its body velocity ``(v, u)`` is exactly the
    random walk per body axis the gyro-driven estimators assume."""

    GRID_S = RandomSpeed.GRID_S

    def __init__(self, sigma: float, duration_s: float, rng: np.random.Generator):
        count = int(np.ceil(float(duration_s) / self.GRID_S)) + 2
        shocks = rng.standard_normal(count - 1) * sigma * np.sqrt(self.GRID_S)
        self._times = np.arange(count) * self.GRID_S
        self._lateral = np.concatenate([[0.0], np.cumsum(shocks)])

    def evaluate(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lateral velocity [m/s] and its derivative [m/s^2] at times t, each (N,)."""
        t = np.asarray(t, dtype=float)
        index = np.clip(np.searchsorted(self._times, t, side="right") - 1, 0, len(self._times) - 2)
        slope = (self._lateral[index + 1] - self._lateral[index]) / self.GRID_S
        return self._lateral[index] + slope * (t - self._times[index]), slope

    @property
    def grid(self) -> np.ndarray:
        return self._times


class PlanarPathMotion:
    """A planar vehicle following ``path`` with a speed profile, heading along the path;
    with a ``LateralDrift`` it also slips sideways (heading still along the path).

    Yaw rate is ``curvature * speed``; acceleration is ``v' t + v^2 kappa n`` (tangent t,
    left normal n), plus ``u' n - u kappa v t`` for a lateral velocity ``u``; the position
    adds ``int u n dt`` (trapezoid on the drift's 10 ms grid, linear in between).
    """

    def __init__(
        self,
        path: RoundedPolylinePath,
        speed: SinusoidalSpeed | RandomSpeed,
        drift: LateralDrift | None = None,
    ):
        self.path = path
        self.speed = speed
        self.drift = drift
        self.duration_s = speed.duration_s
        if drift is not None:
            grid = drift.grid
            lateral, _ = drift.evaluate(grid)
            distance, _, _ = speed.evaluate(grid)
            _, heading, _ = path.evaluate(distance)
            moving = lateral[:, None] * np.column_stack([-np.sin(heading), np.cos(heading)])
            steps = 0.5 * (moving[1:] + moving[:-1]) * np.diff(grid)[:, None]
            self._offset = np.vstack([np.zeros(2), np.cumsum(steps, axis=0)])

    def kinematics(self, t: np.ndarray) -> Kinematics:
        t = np.asarray(t, dtype=float)
        distance, speed, speed_rate = self.speed.evaluate(t)
        position, heading, curvature = self.path.evaluate(distance)
        tangent = np.column_stack([np.cos(heading), np.sin(heading)])
        normal = np.column_stack([-tangent[:, 1], tangent[:, 0]])
        velocity = speed[:, None] * tangent
        acceleration = speed_rate[:, None] * tangent + (speed**2 * curvature)[:, None] * normal
        if self.drift is not None:
            lateral, lateral_rate = self.drift.evaluate(t)
            grid = self.drift.grid
            position = position + np.column_stack(
                [np.interp(t, grid, self._offset[:, axis]) for axis in range(2)]
            )
            velocity = velocity + lateral[:, None] * normal
            acceleration = (
                acceleration
                + lateral_rate[:, None] * normal
                - (lateral * curvature * speed)[:, None] * tangent
            )
        return Kinematics(
            t=t,
            position=position,
            velocity=velocity,
            acceleration=acceleration,
            rotation=rot2_batch(heading),
            body_rate=(curvature * speed)[:, None],
            heading=heading,
        )
