"""First-order covariances of the corner extractor's lines and corners (steps 5-6 of
``datasets.lidar.corners``): each point's variance across its line from its range and
bearing noise, each total-least-squares line's offset and angle covariance, and the
intersection's covariance of two such lines.
"""

from __future__ import annotations

import numpy as np

from datasets.lidar.corner_config import CornerConfig


def _flat_indices(starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Point indices of inclusive ranges ``[starts, ends]`` concatenated, and their range ids."""
    lengths = ends - starts + 1
    owners = np.arange(len(starts)).repeat(lengths)
    offsets = lengths.cumsum() - lengths
    return np.arange(len(owners)) + (starts - offsets)[owners], owners


def point_perpendicular_variance(
    xy: np.ndarray, normal: np.ndarray, config: CornerConfig
) -> np.ndarray:
    """Variance [m^2] of each point across its line, from range/bearing noise:
    ``n^T (s_r^2 u u^T + r^2 s_b^2 v v^T) n`` with u radial, v tangential unit vectors."""
    x, y = xy[:, 0], xy[:, 1]
    r = np.hypot(x, y)
    scale = np.maximum(r, 1e-12)
    u_x, u_y = x / scale, y / scale
    nu = normal[:, 0] * u_x + normal[:, 1] * u_y
    nv = normal[:, 1] * u_x - normal[:, 0] * u_y  # v = (-u_y, u_x)
    return config.range_sigma_m**2 * nu**2 + (r * config.bearing_sigma_rad) ** 2 * nv**2


def line_parameter_covariance(
    xy: np.ndarray,
    starts: np.ndarray,
    ends: np.ndarray,
    centroid: np.ndarray,
    direction: np.ndarray,
    config: CornerConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First-order covariance of an unweighted least-squares line ``d = a + b s`` in the
    line's own frame (s along ``direction`` from the centroid, d along the normal), with
    heteroscedastic perpendicular noise ``sigma_i^2`` (sandwich form):
    ``var a = sum sigma^2 / n^2``, ``var b = sum sigma^2 s^2 / (sum s^2)^2``,
    ``cov ab = sum sigma^2 s / (n sum s^2)``.

    Returns:
        var_a (m,), var_b (m,), cov_ab (m,).
    """
    index, owner = _flat_indices(starts, ends)
    points = xy.take(index, axis=0)
    # per point, its line's centroid and direction (one gather)
    c_x, c_y, d_x, d_y = np.concatenate([centroid, direction], axis=1).take(owner, axis=0).T
    s = (points[:, 0] - c_x) * d_x + (points[:, 1] - c_y) * d_y
    sigma2 = point_perpendicular_variance(points, np.column_stack([-d_y, d_x]), config)
    count = len(starts)

    def total(values: np.ndarray) -> np.ndarray:
        return np.bincount(owner, weights=values, minlength=count)

    n = (ends - starts + 1).astype(float)  # the point counts (exact)
    sum_s2 = np.maximum(total(s * s), 1e-12)
    return total(sigma2) / n**2, total(sigma2 * s * s) / sum_s2**2, total(sigma2 * s) / (n * sum_s2)


def corner_covariance(
    normal_1: np.ndarray, normal_2: np.ndarray, var_v1: np.ndarray, var_v2: np.ndarray
) -> np.ndarray:
    """Covariance (k, 2, 2) of the intersection x of two lines ``n_k^T (x - c_k) = 0``.

    Perturbing line k by offset ``da_k`` and rotation ``db_k`` moves it, at the corner, by
    ``dv_k = da_k + s_k db_k`` along ``n_k``, so ``N dx = dv`` with ``N = [n_1^T; n_2^T]`` and
    ``Cov(x) = N^-1 diag(var v_1, var v_2) N^-T``.
    """
    matrix = np.stack([normal_1, normal_2], axis=1)  # rows n1, n2
    inverse = np.linalg.inv(matrix)
    diagonal = np.zeros((len(var_v1), 2, 2))
    diagonal[:, 0, 0], diagonal[:, 1, 1] = var_v1, var_v2
    covariance = inverse @ diagonal @ np.swapaxes(inverse, 1, 2)
    return 0.5 * (covariance + np.swapaxes(covariance, 1, 2))
