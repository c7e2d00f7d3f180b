"""Observability of the linearised Aghili SLAM (section 3): eqs. (22), (25)-(27), (30)-(32).

Numerical ranks use an SVD with a relative tolerance; the powers of F are applied with a
per-power column scaling ignored (F is built from physical units, so we report the
singular values as they are and a rank at ``tolerance * largest``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm

from datasets.rotations import skew
from filters.aghili.measurement import predict, sensitivity
from filters.aghili.transition import (
    ATTITUDE,
    LANDMARK_BLOCKS,
    POSITION,
    VEHICLE_DIM,
    VELOCITY,
    error_dynamics,
    state_registry,
)


@dataclass(frozen=True)
class ObservabilityReport:
    """rank, state size, the smallest singular values (ascending), and the Pi test."""

    rank: int
    size: int
    smallest_singular_values: np.ndarray
    pi_smallest_singular_value: float | None
    anchors_collinear: bool | None


def segment_matrices(
    attitude, position, omega_bar, a_bar, anchors, landmarks
) -> tuple[np.ndarray, np.ndarray]:
    """F (21a) and H (10) for one segment: anchors (r, 3) and estimated landmarks (n, 3), world."""
    world = np.vstack([anchors, landmarks])
    n = len(landmarks)
    registry = state_registry()  # landmarks ids 0..n-1; the anchors (-1, -2, ...) are not in it
    for landmark_id in range(n):
        registry.augment(landmark_id, LANDMARK_BLOCKS)
    ids = np.r_[-1 - np.arange(len(anchors)), np.arange(n)]
    F, _ = error_dynamics(omega_bar, a_bar, attitude, n)
    H = sensitivity(attitude, predict(attitude, position, world), registry, ids)
    return F, H


def observability_matrix(F: np.ndarray, H: np.ndarray) -> np.ndarray:
    """Aghili eq. (22): ``O = [H; H F; ...; H F^(N-1)]`` with N = 15 + 3n."""
    blocks = [H]
    for _ in range(F.shape[0] - 1):
        blocks.append(blocks[-1] @ F)
    return np.vstack(blocks)


def pi_matrix(anchors_body: np.ndarray) -> np.ndarray:
    """Aghili eqs. (25), (26): ``Pi = [e1 x]^2 + [e2 x]^2`` from three anchors (body frame)."""
    e = [
        (anchors_body[i] - anchors_body[2]) / np.linalg.norm(anchors_body[i] - anchors_body[2])
        for i in (0, 1)
    ]
    return skew(e[0]) @ skew(e[0]) + skew(e[1]) @ skew(e[1])


def rank_report(
    matrix: np.ndarray, size: int, tolerance: float = 1e-9, anchors_body: np.ndarray | None = None
) -> ObservabilityReport:
    """Rank (SVD, relative tolerance) and the smallest singular values; eq. (27) test if 3+ anchors."""
    values = np.linalg.svd(matrix, compute_uv=False)
    rank = int(np.sum(values > tolerance * values[0]))
    pi_value, collinear = None, None
    if anchors_body is not None and len(anchors_body) >= 3:
        pi_value = float(np.linalg.svd(pi_matrix(anchors_body[:3]), compute_uv=False)[-1])
        e1, e2 = anchors_body[0] - anchors_body[2], anchors_body[1] - anchors_body[2]
        collinear = bool(
            np.linalg.norm(np.cross(e1, e2)) < 1e-9 * np.linalg.norm(e1) * np.linalg.norm(e2)
        )  # eq. (27)
    return ObservabilityReport(rank, size, np.sort(values)[:6], pi_value, collinear)


def total_observability_matrix(
    segments: list[tuple[np.ndarray, np.ndarray]], durations: list[float], stripped: bool = False
) -> np.ndarray:
    """Aghili eq. (30) (or the stripped eq. (32) with ``stripped=True``) for segments (F_j, H_j)."""
    rows, transition = [], np.eye(segments[0][0].shape[0])
    for j, (F, H) in enumerate(segments):
        block = observability_matrix(F, H)
        rows.append(block if stripped else block @ transition)
        if j < len(durations):
            transition = expm(F * durations[j]) @ transition
    return np.vstack(rows)


@dataclass(frozen=True)
class TrajectoryObservability:
    """Observability at one sample of a trajectory.

    Attributes:
        t: time of the segment [s].
        segment: eq. (22) for the segment starting at t (with the eq. (27) anchor test).
        total: eq. (30) over the last ``window`` segments ending at t (None for the first ones).
        stripped: eq. (32) over the same segments.
    """

    t: float
    segment: ObservabilityReport
    total: ObservabilityReport | None
    stripped: ObservabilityReport | None


def segment_inputs(
    times: np.ndarray, rotations: np.ndarray, positions: np.ndarray, index: int
) -> tuple[np.ndarray, np.ndarray]:
    """The true mean IMU signals ``(omega_bar, a_bar)`` (body frame) of the segment starting at
    sample ``index``, by finite differences of the trajectory (gravity ``(0, 0, -9.81)``, so a
    resting accelerometer reads ``+9.81`` up, eq. (15)).

    Args:
        times (N,) [s]; rotations (N, 3, 3) body-to-world; positions (N, 3) [m].
    """
    from datasets.rotations import so3_log

    dt = times[index + 1] - times[index]
    attitude = rotations[index]
    omega = so3_log(attitude.T @ rotations[index + 1]) / dt
    accel = np.zeros(3)
    if index + 2 < len(times):
        later = times[index + 2] - times[index + 1]
        accel = (
            (positions[index + 2] - positions[index + 1]) / later
            - (positions[index + 1] - positions[index]) / dt
        ) / (0.5 * (dt + later))
    return omega, attitude.T @ (accel + np.array([0.0, 0.0, 9.81]))


def observability_along_trajectory(
    times: np.ndarray,
    rotations: np.ndarray,
    positions: np.ndarray,
    anchors: np.ndarray,
    candidates: np.ndarray,
    step_s: float,
    landmark_count: int,
    window: int = 3,
) -> list[TrajectoryObservability]:
    """Aghili eqs. (22), (27), (30), (32) every ``step_s`` along a (true) 3-D trajectory.

    Each report time starts a piecewise-constant segment (section 3): F and H from the true
    pose, the true mean IMU signals there, the anchors and the ``landmark_count``
    estimated landmarks nearest to the vehicle. The total (30) and stripped (32) matrices
    chain the last ``window`` segments (segment j lasting ``step_s``, transition
    ``expm(F_j step_s)``) with the landmark set of the latest one, so the state is the same
    in every block.

    Args:
        times (N,), rotations (N, 3, 3), positions (N, 3): the trajectory.
        anchors (r, 3): known landmarks, world [m]; candidates (L, 3): other landmarks.
    """
    if len(times) < 3:
        raise ValueError("observability along a trajectory needs at least three samples")
    indices = np.unique(np.searchsorted(times, np.arange(times[0], times[-2], step_s)))
    indices = indices[indices < len(times) - 1]
    inputs = [segment_inputs(times, rotations, positions, int(index)) for index in indices]
    reports: list[TrajectoryObservability] = []
    for k, index in enumerate(indices):
        position = positions[index]
        nearest = candidates[
            np.argsort(np.linalg.norm(candidates - position, axis=1))[:landmark_count]
        ]
        anchors_body = (anchors - position) @ rotations[index]

        def segment_at(j: int, nearest: np.ndarray = nearest) -> tuple[np.ndarray, np.ndarray]:
            return segment_matrices(
                rotations[indices[j]], positions[indices[j]], *inputs[j], anchors, nearest
            )

        F, H = segment_at(k)
        size = F.shape[0]
        segment = rank_report(observability_matrix(F, H), size, anchors_body=anchors_body)
        total = stripped = None
        if k + 1 >= window:
            chain = [segment_at(j) for j in range(k + 1 - window, k)] + [(F, H)]
            durations = [
                float(times[indices[j + 1]] - times[indices[j]]) for j in range(k + 1 - window, k)
            ]
            total = rank_report(total_observability_matrix(chain, durations), size)
            stripped = rank_report(
                total_observability_matrix(chain, durations, stripped=True), size
            )
        reports.append(TrajectoryObservability(float(times[index]), segment, total, stripped))
    return reports


def gauge_rotation_direction(
    attitude: np.ndarray,
    position: np.ndarray,
    velocity: np.ndarray,
    landmarks: np.ndarray,
    pivot: np.ndarray,
) -> np.ndarray:
    """Error-state direction (15 + 3n,) of a rotation of everything about gravity through
    ``pivot`` (world [m]), per radian: the direction a single anchor leaves unobservable.

    In the filter's coordinates (``transition`` layout): ``dq_v = Abar^T z / 2`` (half
    angle, body frame), ``dr = z x (r - pivot)``, ``dr_dot = z x v``, biases 0 (body frame,
    gravity-aligned rotation leaves them), ``drho_i = z x (rho_i - pivot)``.
    """
    z_axis = np.array([0.0, 0.0, 1.0])
    landmarks = np.asarray(landmarks, dtype=float).reshape(-1, 3)
    direction = np.zeros(VEHICLE_DIM + 3 * len(landmarks))
    direction[ATTITUDE] = 0.5 * attitude.T @ z_axis
    direction[POSITION] = np.cross(z_axis, position - pivot)
    direction[VELOCITY] = np.cross(z_axis, velocity)
    if len(landmarks):
        direction[VEHICLE_DIM:] = np.cross(z_axis, landmarks - pivot).ravel()
    return direction


def variance_along(covariance: np.ndarray, direction: np.ndarray) -> float:
    """Variance [unit of the direction's parameter^2] of the coordinate psi along
    ``x = x_hat + direction * psi`` implied by a Gaussian with ``covariance``:
    ``(u^T P^-1 u)^-1`` (the information about psi, all other directions free)."""
    factor = np.linalg.cholesky(0.5 * (covariance + covariance.T))
    whitened = np.linalg.solve(factor, direction)
    return float(1.0 / (whitened @ whitened))
