"""Consistency statistics: NEES, NIS, and the Monte Carlo averaged NEES with chi-square bounds.

Bar-Shalom, Li, Kirubarajan, "Estimation with Applications to Tracking and Navigation",
sec. 5.4: for a consistent estimator with Gaussian errors, the NEES
``e^T P^-1 e`` of an n-dimensional error is chi-square with n degrees of freedom; the
average of M independent runs' NEES, times M, is chi-square with M n degrees of freedom,
so the two-sided 95% interval of the averaged NEES is
``chi2.ppf([0.025, 0.975], M n) / M``.

Pose errors use the interface convention (DESIGN.md): 3-D ``xi = [Log(R_est^T R_true),
R_est^T (p_true - p_est)]`` (body-frame right perturbation, rotation first, as the
interface covariance); 2-D ``[R(theta_est)^T (p_true - p_est), wrap(theta_true -
theta_est)]`` (GTSAM Pose2 order). The translation part is the first-order (retract) chart
of Pose3/Pose2, not the exact SE(3) logarithm; the two agree to second order in the error.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import chi2

from datasets.rotations import so3_log, wrap_angle
from datasets.trajectory import Trajectory

CONFIDENCE = 0.95


def per_dof_band(
    summed_dof: int | np.ndarray, confidence: float = CONFIDENCE
) -> tuple[np.ndarray, np.ndarray]:
    """Two-sided ``confidence`` band of a chi-square statistic of ``summed_dof`` degrees of
    freedom divided by them (a NEES or NIS summed over runs and components, per dof): the
    band every averaged statistic of the workbench is judged by (Bar-Shalom et al. 2001,
    sec. 5.4.2). Returns ``(lower, upper)``, each shaped as ``summed_dof``."""
    summed_dof = np.asarray(summed_dof, dtype=float)
    tail = 0.5 * (1.0 - confidence)
    return chi2.ppf(tail, summed_dof) / summed_dof, chi2.ppf(1.0 - tail, summed_dof) / summed_dof


def chi2_interval(dof: int, runs: int = 1, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Two-sided interval of the NEES averaged over ``runs`` runs, each chi-square(dof):
    ``chi2.ppf([(1-c)/2, (1+c)/2], runs * dof) / runs`` (``per_dof_band`` times ``dof``)."""
    low, high = per_dof_band(runs * dof, confidence)
    return float(low * dof), float(high * dof)


def chi2_upper(dof: int | np.ndarray, confidence: float = CONFIDENCE) -> np.ndarray:
    """One-sided bound ``chi2.ppf(confidence, dof)`` (Guerreiro et al. eq. (11)'s threshold)."""
    return np.asarray(chi2.ppf(confidence, dof), dtype=float)


def nees(errors: np.ndarray, covariances: np.ndarray) -> np.ndarray:
    """Normalised estimation error squared ``e^T P^-1 e`` per step.

    Args:
        errors: shape (N, k).
        covariances: shape (N, k, k), symmetric positive definite.

    Returns:
        shape (N,); NaN where a covariance is singular or not finite.
    """
    errors = np.asarray(errors, dtype=float)
    covariances = np.asarray(covariances, dtype=float)
    result = np.full(len(errors), np.nan)
    finite = np.all(np.isfinite(covariances), axis=(1, 2)) & np.all(np.isfinite(errors), axis=1)
    rows = np.flatnonzero(finite)
    try:
        solved = np.linalg.solve(covariances[rows], errors[rows][:, :, None])[:, :, 0]
        result[rows] = np.einsum("ni,ni->n", errors[rows], solved)
        return result
    except np.linalg.LinAlgError:
        pass
    for index in rows:
        # Step by step, so that one singular covariance spoils only its own value.
        try:
            result[index] = float(
                errors[index] @ np.linalg.solve(covariances[index], errors[index])
            )
        except np.linalg.LinAlgError:
            continue
    return result


def inside_fraction(
    values: np.ndarray, dof: int | np.ndarray, confidence: float = CONFIDENCE
) -> float | None:
    """Fraction of single-run NEES/NIS values inside their two-sided chi-square interval.

    ``dof`` may be one number or one per value. NaN values count as outside. None when
    there are no values.
    """
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return None
    dofs = np.broadcast_to(np.asarray(dof, dtype=float), values.shape)
    low, high = per_dof_band(dofs, confidence)
    return float(np.mean((values >= low * dofs) & (values <= high * dofs)))


def below_fraction(
    values: np.ndarray, dof: int | np.ndarray, confidence: float = CONFIDENCE
) -> float | None:
    """Fraction of values at or below the one-sided bound ``chi2.ppf(confidence, dof)``.

    Guerreiro et al., "Globally Asymptotically Stable Sensor-Based SLAM", eq. (11): a NIS
    value is acceptable when ``nu^T S^-1 nu <= chi2_{n_m, 95%}``. (The paper prints the
    quadratic form as ``nu Sigma nu``, a typo: the transpose and the inverse innovation
    covariance are missing.)
    """
    values = np.asarray(values, dtype=float)
    if values.size == 0:
        return None
    return float(
        np.mean(values <= chi2_upper(np.broadcast_to(np.asarray(dof), values.shape), confidence))
    )


@dataclass(frozen=True)
class AveragedNees:
    """NEES averaged over Monte Carlo runs, per step.

    Attributes:
        mean: averaged NEES per step, shape (N,).
        lower, upper: two-sided bounds ``chi2.ppf([0.025, 0.975], M n) / M``.
        inside_fraction: fraction of steps with ``lower <= mean <= upper``.
        runs: M; dof: n.
    """

    mean: np.ndarray
    lower: float
    upper: float
    inside_fraction: float
    runs: int
    dof: int


def averaged_nees(nees_runs: np.ndarray, dof: int, confidence: float = CONFIDENCE) -> AveragedNees:
    """Average NEES over runs (Bar-Shalom et al. sec. 5.4.2) and test it against its bounds.

    Args:
        nees_runs: shape (M, N): NEES of run m at step n (runs share the step grid).
        dof: degrees of freedom n of each NEES value.
    """
    nees_runs = np.atleast_2d(np.asarray(nees_runs, dtype=float))
    runs = nees_runs.shape[0]
    mean = np.mean(nees_runs, axis=0)
    lower, upper = chi2_interval(dof, runs, confidence)
    fraction = float(np.mean((mean >= lower) & (mean <= upper))) if mean.size else float("nan")
    return AveragedNees(
        mean=mean, lower=lower, upper=upper, inside_fraction=fraction, runs=runs, dof=dof
    )


def pose_errors(estimate: Trajectory, truth: Trajectory) -> np.ndarray:
    """Pose errors in the interface tangent convention, pose for pose.

    Args:
        estimate, truth: trajectories of equal length and dimension (same times).

    Returns:
        3-D: shape (N, 6) ``[Log(R_est^T R_true), R_est^T (p_true - p_est)]``;
        2-D: shape (N, 3) ``[R(theta_est)^T (p_true - p_est), wrap(theta_true - theta_est)]``.
    """
    if len(estimate) != len(truth) or estimate.dimension != truth.dimension:
        raise ValueError(
            f"pose_errors needs equal trajectories: {len(estimate)}x{estimate.dimension}-D vs "
            f"{len(truth)}x{truth.dimension}-D"
        )
    rotations_est = estimate.rotation_matrices()
    difference = truth.positions - estimate.positions
    body_difference = np.einsum("nji,nj->ni", rotations_est, difference)
    if estimate.dimension == 2:
        heading = np.asarray(wrap_angle(truth.rotations - estimate.rotations), dtype=float)
        return np.column_stack([body_difference, heading])
    relative = np.einsum("nji,njk->nik", rotations_est, truth.rotation_matrices())
    return np.column_stack([so3_log(relative).reshape(-1, 3), body_difference])
