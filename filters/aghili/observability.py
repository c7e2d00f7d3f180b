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
from filters.aghili.transition import error_dynamics


@dataclass(frozen=True)
class ObservabilityReport:
    """rank, state size, the smallest singular values (ascending), and the Pi test."""

    rank: int
    size: int
    smallest_singular_values: np.ndarray
    pi_smallest_singular_value: float | None
    anchors_collinear: bool | None


def segment_matrices(attitude, position, omega_bar, a_bar, anchors, landmarks) -> tuple[np.ndarray, np.ndarray]:
    """F (21a) and H (10) for one segment: anchors (r, 3) and estimated landmarks (n, 3), world."""
    world = np.vstack([anchors, landmarks])
    slots = np.r_[np.full(len(anchors), -1), np.arange(len(landmarks))]
    n = len(landmarks)
    F, _ = error_dynamics(omega_bar, a_bar, attitude, n)
    H = sensitivity(attitude, predict(attitude, position, world), slots, F.shape[0])
    return F, H


def observability_matrix(F: np.ndarray, H: np.ndarray) -> np.ndarray:
    """Aghili eq. (22): ``O = [H; H F; ...; H F^(N-1)]`` with N = 15 + 3n."""
    blocks = [H]
    for _ in range(F.shape[0] - 1):
        blocks.append(blocks[-1] @ F)
    return np.vstack(blocks)


def pi_matrix(anchors_body: np.ndarray) -> np.ndarray:
    """Aghili eqs. (25), (26): ``Pi = [e1 x]^2 + [e2 x]^2`` from three anchors (body frame)."""
    e = [(anchors_body[i] - anchors_body[2]) / np.linalg.norm(anchors_body[i] - anchors_body[2]) for i in (0, 1)]
    return skew(e[0]) @ skew(e[0]) + skew(e[1]) @ skew(e[1])


def rank_report(matrix: np.ndarray, size: int, tolerance: float = 1e-9, anchors_body: np.ndarray | None = None) -> ObservabilityReport:
    """Rank (SVD, relative tolerance) and the smallest singular values; eq. (27) test if 3+ anchors."""
    values = np.linalg.svd(matrix, compute_uv=False)
    rank = int(np.sum(values > tolerance * values[0]))
    pi_value, collinear = None, None
    if anchors_body is not None and len(anchors_body) >= 3:
        pi_value = float(np.linalg.svd(pi_matrix(anchors_body[:3]), compute_uv=False)[-1])
        e1, e2 = anchors_body[0] - anchors_body[2], anchors_body[1] - anchors_body[2]
        collinear = bool(np.linalg.norm(np.cross(e1, e2)) < 1e-9 * np.linalg.norm(e1) * np.linalg.norm(e2))  # eq. (27)
    return ObservabilityReport(rank, size, np.sort(values)[:6], pi_value, collinear)


def total_observability_matrix(segments: list[tuple[np.ndarray, np.ndarray]], durations: list[float], stripped: bool = False) -> np.ndarray:
    """Aghili eq. (30) (or the stripped eq. (32) with ``stripped=True``) for segments (F_j, H_j)."""
    rows, transition = [], np.eye(segments[0][0].shape[0])
    for j, (F, H) in enumerate(segments):
        block = observability_matrix(F, H)
        rows.append(block if stripped else block @ transition)
        if j < len(durations):
            transition = expm(F * durations[j]) @ transition
    return np.vstack(rows)
