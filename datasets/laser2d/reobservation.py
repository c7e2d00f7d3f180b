"""Corners re-observed in consecutive scans: confirmation, re-observation NIS, and the fit of
the corner covariance's scale.

A fixed corner seen in scan ``i`` at ``c_i`` and again in scan ``j`` at ``c_j`` (body frames)
sits, carried by the motion increment ``u = (dx, dy, dtheta)`` from ``i`` to ``j`` (in
``i``'s frame; ``Odometry.relative_pose``), at ``x_j = u_xy + R(u_theta) c_j`` in frame ``i``.
The residual ``r = x_j - c_i`` has, to first order, the covariance

    S = s (C_i + R C_j R^T) + a G Q G^T,   G = [I_2 | J R c_j],   J = [[0, -1], [1, 0]]

with ``C`` the corners' covariances as extracted (unit scale), ``Q`` the increment's stated
covariance (3, 3) and ``s`` (corner scale) and ``a`` (motion scale) 1 when both are right.
Every corner of scan ``j`` is matched to the nearest corner of scan ``i`` under ``S`` and is
*confirmed* when its squared Mahalanobis distance is within the ``confirm_probability``
chi-square gate (2 dof): only confirmed corners are emitted (``Laser2dFrontEnd``), so a
corner that slides with the viewpoint (an occlusion edge, a chair leg) never becomes a
landmark, as in the 3-D front end (``datasets.lidar.corner_tracking``).

The *re-observation NIS* is ``r^T S^-1 r`` over the confirmed pairs, per dof. Gated at
probability ``P`` its expectation is below 1: ``E[x | x < g] / 2`` for a chi-square ``x``
with 2 dof (``gated_nis_per_dof``: 0.953 at 0.99).

``fit_scales`` estimates ``(s, a)`` by maximum likelihood over all pairs, the pairs of one scan
pair stacked into one Gaussian (they share the increment's error ``G_k e``): with two or more
corners in a scan pair the shared motion error and the corners' independent errors separate,
which a per-corner NIS cannot do (``a`` is reported, not applied: the increment's covariance
is the odometry model's, calibrated on its own). The pairs the fit and the NIS read
are gated wider than the confirmation (``calibration_probability``, 0.999: the truncation then
lowers the NIS by 0.7 %, ``gated_nis_per_dof``), so the gate barely biases them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import minimize
from scipy.stats import chi2

PLANAR_GENERATOR = np.array([[0.0, -1.0], [1.0, 0.0]])


def gated_nis_per_dof(probability: float, dof: int = 2) -> float:
    """``E[x | x < g] / dof`` for ``x`` chi-square with ``dof`` degrees of freedom and ``g`` its
    ``probability`` quantile: the mean NIS per dof of consistent residuals that passed a gate
    at ``probability``."""
    gate = chi2.ppf(probability, dof)
    # E[x; x < g] = dof * P(chi2_{dof+2} < g)
    return float(dof * chi2.cdf(gate, dof + 2) / probability / dof)


@dataclass
class PairGroup:
    """The confirmed re-observations between one scan and the previous one.

    Attributes:
        frame: index of the later scan.
        residuals: (m, 2) [m], ``r`` of the module docstring (earlier scan's frame).
        corner_covariances: (m, 2, 2) [m^2], ``C_i + R C_j R^T`` at unit corner scale.
        motion_jacobians: (m, 2, 3), ``G`` of each pair.
        increment_covariance: (3, 3), ``Q``.
    """

    frame: int
    residuals: np.ndarray
    corner_covariances: np.ndarray
    motion_jacobians: np.ndarray
    increment_covariance: np.ndarray

    def stacked_covariance(self, corner_scale: float, motion_scale: float) -> np.ndarray:
        """(2m, 2m) covariance of the stacked residuals."""
        m = len(self.residuals)
        blocks = np.zeros((2 * m, 2 * m))
        for k in range(m):
            blocks[2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = corner_scale * self.corner_covariances[k]
        jacobian = self.motion_jacobians.reshape(2 * m, 3)
        return blocks + motion_scale * jacobian @ self.increment_covariance @ jacobian.T

    def pair_covariances(self, corner_scale: float, motion_scale: float) -> np.ndarray:
        """(m, 2, 2) covariance of each residual on its own."""
        motion = np.einsum(
            "kia,ab,kjb->kij",
            self.motion_jacobians,
            self.increment_covariance,
            self.motion_jacobians,
        )
        return corner_scale * self.corner_covariances + motion_scale * motion


@dataclass
class ReobservationLog:
    """Every confirmed pair so far, by scan pair, and the counts.

    Attributes:
        corners: corners extracted.
        confirmed: of them, confirmed (re-observed in place).
        groups: the confirmed pairs of each scan pair.
    """

    corners: int = 0
    confirmed: int = 0
    groups: list[PairGroup] = field(default_factory=list)

    def nis(self, corner_scale: float = 1.0, motion_scale: float = 1.0) -> np.ndarray:
        """Re-observation NIS (2 dof) of every confirmed pair, (P,)."""
        values = []
        for group in self.groups:
            covariances = group.pair_covariances(corner_scale, motion_scale)
            inverse = np.linalg.inv(covariances)
            values.append(np.einsum("ki,kij,kj->k", group.residuals, inverse, group.residuals))
        return np.concatenate(values) if values else np.zeros(0)

    def summary(self, corner_scale: float = 1.0, confirm_probability: float = 0.99) -> dict:
        """Counts and the re-observation NIS per dof (with the gated expectation to read it
        against), JSON-serialisable; ``corner_scale`` 1: the covariances as emitted."""
        values = self.nis(corner_scale)
        return {
            "corners_detected": int(self.corners),
            "corners_confirmed": int(self.confirmed),
            "reobservation_pairs": int(values.size),
            "reobservation_nis_per_dof": float(values.mean() / 2.0) if values.size else None,
            "reobservation_nis_expected_per_dof": gated_nis_per_dof(confirm_probability),
        }


def match_consecutive(
    previous_points: np.ndarray,
    previous_covariances: np.ndarray,
    points: np.ndarray,
    covariances: np.ndarray,
    increment: np.ndarray,
    increment_covariance: np.ndarray,
    gate: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Each corner of the later scan against the nearest corner of the earlier one (module
    docstring).

    Args:
        previous_points (k, 2) [m], previous_covariances (k, 2, 2) [m^2]: the earlier scan's
            corners (its body frame), covariances as emitted.
        points (m, 2), covariances (m, 2, 2): the later scan's.
        increment: (3,) ``u``; increment_covariance: (3, 3) ``Q``.
        gate: squared Mahalanobis distance accepted.

    Returns:
        confirmed (m,) bool; for the confirmed ones: residuals (c, 2) [m], corner covariance
        sums (c, 2, 2), motion Jacobians (c, 2, 3); and the index of the earlier corner
        each matched (c,).
    """
    count = len(points)
    empty = (
        np.zeros(count, dtype=bool),
        np.zeros((0, 2)),
        np.zeros((0, 2, 2)),
        np.zeros((0, 2, 3)),
        np.zeros(0, dtype=int),
    )
    if count == 0 or len(previous_points) == 0:
        return empty
    cos, sin = np.cos(increment[2]), np.sin(increment[2])
    rotation = np.array([[cos, -sin], [sin, cos]])
    moved = points @ rotation.T + increment[:2]
    moved_covariances = np.einsum("ij,kjl,ml->kim", rotation, covariances, rotation)
    jacobians = np.zeros((count, 2, 3))
    jacobians[:, :, :2] = np.eye(2)
    jacobians[:, :, 2] = (points @ rotation.T) @ PLANAR_GENERATOR.T
    motion = np.einsum("kia,ab,kjb->kij", jacobians, increment_covariance, jacobians)
    # every pair (later k, earlier l): difference and covariance
    difference = moved[:, None, :] - previous_points[None, :, :]
    corner_sum = moved_covariances[:, None] + previous_covariances[None, :]
    total = corner_sum + motion[:, None]
    sxx, sxy, syy = total[..., 0, 0], total[..., 0, 1], total[..., 1, 1]
    dx, dy = difference[..., 0], difference[..., 1]
    distance = (syy * dx * dx - 2.0 * sxy * dx * dy + sxx * dy * dy) / (sxx * syy - sxy * sxy)
    nearest = np.argmin(distance, axis=1)
    rows = np.arange(count)
    confirmed = distance[rows, nearest] <= gate
    chosen = np.flatnonzero(confirmed)
    earlier = nearest[chosen]
    return (
        confirmed,
        difference[chosen, earlier],
        corner_sum[chosen, earlier],
        jacobians[chosen],
        earlier,
    )


def fit_scales(groups: list[PairGroup], fit_motion: bool = True) -> tuple[float, float]:
    """Maximum-likelihood ``(corner scale s, motion scale a)`` over the pair groups (module
    docstring); ``fit_motion=False`` holds ``a = 1``. Groups of equal size are stacked, so an
    evaluation is a few batched determinants and solves."""
    by_size: dict[int, list[PairGroup]] = {}
    for group in groups:
        if len(group.residuals):
            by_size.setdefault(len(group.residuals), []).append(group)
    if not by_size:
        return 1.0, 1.0
    stacks = []
    for m, members in by_size.items():
        corner = np.zeros((len(members), 2 * m, 2 * m))
        for index, group in enumerate(members):
            for k in range(m):
                corner[index, 2 * k : 2 * k + 2, 2 * k : 2 * k + 2] = group.corner_covariances[k]
        jacobians = np.array([group.motion_jacobians.reshape(2 * m, 3) for group in members])
        increments = np.array([group.increment_covariance for group in members])
        motion = jacobians @ increments @ np.swapaxes(jacobians, 1, 2)
        residuals = np.array([group.residuals.reshape(-1) for group in members])
        stacks.append((corner, motion, residuals))

    def objective(log_scales: np.ndarray) -> float:
        s = float(np.exp(log_scales[0]))
        a = float(np.exp(log_scales[1])) if fit_motion else 1.0
        total = 0.0
        for corner, motion, residuals in stacks:
            covariance = s * corner + a * motion
            sign, logdet = np.linalg.slogdet(covariance)
            if np.any(sign <= 0):
                return 1e300
            solved = np.linalg.solve(covariance, residuals[..., None])[..., 0]
            total += 0.5 * float(np.sum(logdet) + np.sum(residuals * solved))
        return total

    result = minimize(
        objective, np.zeros(2), method="Nelder-Mead", options={"xatol": 1e-4, "fatol": 1e-8}
    )
    return float(np.exp(result.x[0])), float(np.exp(result.x[1])) if fit_motion else 1.0
