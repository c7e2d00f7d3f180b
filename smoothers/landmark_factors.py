"""Factors for landmark positions measured in the body frame, ``p = R^T (rho - r)``.

3-D: GTSAM 4.3's Python wheel has no binary Pose3-Point3 factor whose measurement is the
point in the pose frame (``PoseToPointFactor`` is not wrapped; ``ReferenceFrameFactor``
needs the local point as a third variable). We use the native ``BearingRangeFactor3D``
(C++ speed) and give it the noise of the Cartesian measurement mapped to bearing-range
coordinates to first order: with ``u = p/|p|``, ``B`` the measured bearing's tangent basis
(``Unit3.basis()``), the factor's error is ``[B^T (u_pred - u_meas), |p|_pred - |p|_meas]``
to first order, whose Jacobian with respect to ``p`` is ``J = [B^T (I - u u^T)/|p|; u^T]``;
hence ``Sigma_br = J Sigma_p J^T``. The whitened error equals the Cartesian Mahalanobis
residual to first order (``tests/test_smoother_factors.py`` checks this, and the error
convention against ``p = R^T (rho - r)``, numerically). A Python ``CustomFactor`` with the
exact Cartesian residual is kept as an option (``landmark_factor=cartesian``) and as the
reference in that test; ``benchmarks/bench_smoother.py`` times both.

2-D: ``gtsam_unstable.DeltaFactor`` (Pose2, Point2) has error ``pose.transformTo(point) -
measured``: exactly the body-frame point, natively.

Known landmarks (anchors) are landmark variables with a tight prior (the same information
the filter gets from its anchors), so association and the map treat them like the others.
"""

from __future__ import annotations

import gtsam
import gtsam_unstable
import numpy as np

from datasets.errors import InputError

MIN_RANGE_M = 1e-3
"""A measured point nearer than this has no bearing; the 3-D factor rejects it."""


def bearing_range_covariance(point_body: np.ndarray, covariance: np.ndarray) -> np.ndarray:
    """First-order covariance of (bearing tangent [rad], range [m]) of a body-frame point.

    Args:
        point_body: measured point ``p`` [m], shape (3,).
        covariance: its Cartesian covariance [m^2], shape (3, 3).

    Returns:
        (3, 3) covariance in the error coordinates of ``BearingRangeFactor3D``.
    """
    distance = float(np.linalg.norm(point_body))
    u = point_body / distance
    basis = gtsam.Unit3(point_body).basis()
    jacobian = np.vstack([basis.T @ (np.eye(3) - np.outer(u, u)) / distance, u[None, :]])
    result = jacobian @ covariance @ jacobian.T
    return 0.5 * (result + result.T)


def body_point_factor_3d(
    pose_key: int, landmark_key: int, point_body: np.ndarray, covariance: np.ndarray
) -> gtsam.NonlinearFactor:
    """Native factor of a landmark measured at ``point_body`` (3,) with covariance (3, 3)."""
    distance = float(np.linalg.norm(point_body))
    if distance < MIN_RANGE_M:
        raise InputError(
            f"landmark measured at {distance:.2e} m from the sensor: no bearing (minimum {MIN_RANGE_M} m)"
        )
    noise = gtsam.noiseModel.Gaussian.Covariance(bearing_range_covariance(point_body, covariance))
    return gtsam.BearingRangeFactor3D(
        pose_key, landmark_key, gtsam.Unit3(point_body), distance, noise
    )


def cartesian_point_factor_3d(
    pose_key: int, landmark_key: int, point_body: np.ndarray, covariance: np.ndarray
) -> gtsam.NonlinearFactor:
    """Python ``CustomFactor`` with the exact residual ``R^T (rho - r) - p`` (3,).

    Jacobians: with respect to the Pose3 tangent [omega, v] (right perturbation),
    ``d/d omega = [q x]`` and ``d/d v = -I`` where ``q = R^T (rho - r)``; with respect to
    the landmark, ``R^T``.
    """
    measured = np.asarray(point_body, dtype=float).copy()
    noise = gtsam.noiseModel.Gaussian.Covariance(np.asarray(covariance, dtype=float))

    def error(
        factor: gtsam.CustomFactor, values: gtsam.Values, jacobians: list | None
    ) -> np.ndarray:
        pose = values.atPose3(factor.keys()[0])
        landmark = values.atPoint3(factor.keys()[1])
        rotation = pose.rotation().matrix()
        local = rotation.T @ (landmark - pose.translation())
        if jacobians is not None:
            skew_local = np.array(
                [[0.0, -local[2], local[1]], [local[2], 0.0, -local[0]], [-local[1], local[0], 0.0]]
            )
            jacobians[0] = np.hstack([skew_local, -np.eye(3)])
            jacobians[1] = rotation.T
        return local - measured

    return gtsam.CustomFactor(noise, [pose_key, landmark_key], error)


def body_point_factor_2d(
    pose_key: int, landmark_key: int, point_body: np.ndarray, covariance: np.ndarray
) -> gtsam.NonlinearFactor:
    """Native ``DeltaFactor``: error ``pose.transformTo(point) - measured`` (2,)."""
    noise = gtsam.noiseModel.Gaussian.Covariance(np.asarray(covariance, dtype=float))
    return gtsam_unstable.DeltaFactor(
        pose_key, landmark_key, np.asarray(point_body, dtype=float), noise
    )


def landmark_prior(
    landmark_key: int, position: np.ndarray, sigma_m: float
) -> gtsam.NonlinearFactor:
    """Tight prior on a known (anchor) landmark's world position, 2-D or 3-D."""
    position = np.asarray(position, dtype=float)
    noise = gtsam.noiseModel.Isotropic.Sigma(position.size, sigma_m)
    if position.size == 3:
        return gtsam.PriorFactorPoint3(landmark_key, position, noise)
    return gtsam.PriorFactorPoint2(landmark_key, position, noise)


def landmark_marginal_prior(
    landmark_key: int, position: np.ndarray, covariance: np.ndarray
) -> gtsam.NonlinearFactor:
    """A landmark's marginal (position and full covariance) as a prior, 2-D or 3-D: how the
    fixed-lag smoother brings back a landmark that left its window."""
    position = np.asarray(position, dtype=float)
    noise = gtsam.noiseModel.Gaussian.Covariance(np.asarray(covariance, dtype=float))
    if position.size == 3:
        return gtsam.PriorFactorPoint3(landmark_key, position, noise)
    return gtsam.PriorFactorPoint2(landmark_key, position, noise)


def check_measurement_covariance(covariance: np.ndarray, t: float, index: int) -> None:
    """``InputError`` unless the per-point covariance is finite, symmetric and PD."""
    if not np.all(np.isfinite(covariance)):
        raise InputError(f"landmark scan at t={t:.6f} s: covariance of point {index} is not finite")
    try:
        np.linalg.cholesky(0.5 * (covariance + covariance.T))
    except np.linalg.LinAlgError:
        raise InputError(
            f"landmark scan at t={t:.6f} s: covariance of point {index} is not positive definite"
        ) from None


def point_factor(
    dimension: int,
    kind: str,
    pose_key: int,
    landmark_key: int,
    point_body: np.ndarray,
    covariance: np.ndarray,
) -> gtsam.NonlinearFactor:
    """The factor of one sighting: 2-D ``DeltaFactor``; 3-D by ``kind`` (the
    ``landmark_factor`` option): ``bearing-range`` (native) or ``cartesian`` (exact)."""
    if dimension == 2:
        return body_point_factor_2d(pose_key, landmark_key, point_body, covariance)
    if kind == "cartesian":
        return cartesian_point_factor_3d(pose_key, landmark_key, point_body, covariance)
    return body_point_factor_3d(pose_key, landmark_key, point_body, covariance)
