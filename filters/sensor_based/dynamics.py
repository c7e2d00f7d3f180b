"""Sensor-based SLAM dynamics (Guerreiro et al. 2013, eqs. (1)-(4), (10), section IV-A).

One design for 2-D and 3-D. State ``x = [v (d), b (r), f_1 (d), ..., f_F (d)]``: body-frame
velocity ``v``, rate-gyro bias ``b`` (``r = 1`` in 2-D: the z rate; ``r = 3`` in 3-D), and
*features* ``f``, each a body-frame landmark position or a landmark line direction. With
``omega_m`` the measured rate and ``S(.)`` the skew matrix (2-D: ``S(a) = a [[0,-1],[1,0]]``),

    p_dot = -S(omega_m - b) p - v,      d_dot = -S(omega_m - b) d,      v_dot = 0, b_dot = 0

(eq. (1); the 3-D form ``p_dot = -S(omega_m - b) p - v`` is the generalization the paper
names in section I). Since ``S(b) p`` is linear in ``b``, write ``S(b) q = M(q) b`` with
``M(q) = S e_z q`` = ``S q`` (d x 1) in 2-D and ``M(q) = -S(q)`` (3 x 3) in 3-D. Then

    f_dot = -S(omega_m) f + M(q) b - [f is a position] v                       (eq. (2))

which is linear in the state when ``q`` is a *known* signal: the paper's ``A(t, y(t))``
(eqs. (3)-(4)) takes ``q = y``, the measured position/direction of the visible features,
and that is what makes the error dynamics linear and the Kalman filter GAS. Non-visible
features have no measurement: they use ``q = f_hat`` (the nonlinear model, whose Jacobian
adds ``S(b_hat)`` to the ``df/df`` block), section IV-A.

Gyro noise: ``omega_m = omega + b + n`` puts ``M(f) n`` into every feature's derivative,
fully correlated across features; its covariance is added exactly (first order) through
``G = [0; M(f_1); ...; M(f_F)]``, instead of inflating a per-landmark disturbance.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PLANAR_S = np.array([[0.0, -1.0], [1.0, 0.0]])


def rate_dimension(dimension: int) -> int:
    """Dimension r of the rate/bias vector: 1 in 2-D (about z), 3 in 3-D."""
    return 1 if dimension == 2 else 3


def skew_rate(rate: np.ndarray, dimension: int) -> np.ndarray:
    """``S(rate)``, (d, d): 2-D ``rate[0] * [[0,-1],[1,0]]``, 3-D the cross-product matrix."""
    rate = np.asarray(rate, dtype=float).ravel()
    if dimension == 2:
        return float(rate[0]) * PLANAR_S
    x, y, z = rate
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def bias_coupling(points: np.ndarray) -> np.ndarray:
    """``M(q)`` with ``S(b) q = M(q) b`` for every row of ``points`` (F, d) -> (F, d, r).

    Guerreiro et al. eq. (2): the ``S p_i`` column of ``A_MV_i`` in 2-D; ``-S(p_i)`` in 3-D.
    """
    points = np.asarray(points, dtype=float)
    count, dimension = points.shape
    if dimension == 2:
        return np.stack([-points[:, 1], points[:, 0]], axis=1)[:, :, None]
    x, y, z = points[:, 0], points[:, 1], points[:, 2]
    zero = np.zeros(count)
    # -S(q)
    return -np.stack(
        [np.stack([zero, -z, y], axis=1), np.stack([z, zero, -x], axis=1), np.stack([-y, x, zero], axis=1)], axis=1
    )


@dataclass(frozen=True)
class ProcessNoise:
    """Disturbance model (paper section V: ``Xi = Ts diag(sigma_v^2 I, sigma_b^2, sigma_p^2 I, ...)``).

    Attributes:
        velocity_m_s: sigma_v, velocity random-walk density [m/s/sqrt(s)] (paper 0.1).
        gyro_bias_rad_s: sigma_b, bias random-walk density [rad/s/sqrt(s)] (paper 5.7e-5 deg/s).
        landmark_m: sigma_p, landmark position disturbance [m/sqrt(s)] (paper 0.05).
        direction: disturbance of direction features [1/sqrt(s)].
        gyro_noise_density: gyro white-noise density [rad/s/sqrt(Hz)] injected through ``G``.
    """

    velocity_m_s: float
    gyro_bias_rad_s: float
    landmark_m: float
    direction: float
    gyro_noise_density: float


def propagate(
    x: np.ndarray,
    covariance: np.ndarray,
    is_position: np.ndarray,
    visible_measurements: np.ndarray,
    visible: np.ndarray,
    rate: np.ndarray,
    dt: float,
    noise: ProcessNoise,
    dimension: int,
) -> tuple[np.ndarray, np.ndarray]:
    """One forward-Euler prediction step (Guerreiro et al. eq. (10) and section IV-A).

    ``x_{k+1} = x_k + Ts f(x_k)``, ``Sigma_{k+1} = F Sigma F^T + Xi`` with ``F = I + Ts A``.
    Visible features use ``A(t, y)`` with their measured value ``y`` (eqs. (3)-(4));
    non-visible ones the nonlinear model and its Jacobian at the estimate (IV-A).

    Args:
        x: state (n,) = [v (d), b (r), features (F*d)].
        covariance: (n, n).
        is_position: (F,) bool, True for positions (they have the ``-v`` term).
        visible_measurements: (F, d) measured value y of each visible feature (rows of
            non-visible features are ignored).
        visible: (F,) bool.
        rate: measured angular rate omega_m [rad/s], (r,).
        dt: step Ts [s].
        noise: disturbance model.
        dimension: d (2 or 3).

    Returns:
        (x_next (n,), covariance_next (n, n)), the covariance symmetrised.

    The product ``F Sigma F^T`` exploits the block structure of ``A`` (only feature rows,
    each touching the vehicle columns and its own block): O(n^2) instead of O(n^3).
    """
    d = dimension
    r = rate_dimension(d)
    nv = d + r
    n = x.size
    count = (n - nv) // d
    v, b = x[:d], x[d:nv]
    features = x[nv:].reshape(count, d)
    w = -skew_rate(rate, d)
    coupling_points = np.where(visible[:, None], visible_measurements, features)
    m = bias_coupling(coupling_points)  # (F, d, r)

    position_sign = is_position.astype(float)[:, None]
    derivative = features @ w.T + np.einsum("fdr,r->fd", m, b) - position_sign * v[None, :]
    x_next = x.copy()
    x_next[nv:] = (features + dt * derivative).ravel()

    # Rows of A for the features: vehicle columns [ -[pos] I, M(q) ], own block W (+ S(b) if
    # non-visible: derivative of M(f) b with respect to f).
    a_vehicle = np.zeros((count, d, nv))
    a_vehicle[:, :, :d] = -position_sign[:, :, None] * np.eye(d)[None]
    a_vehicle[:, :, d:] = m
    a_own = np.broadcast_to(w, (count, d, d)).copy()
    a_own[~visible] += skew_rate(b, d)

    def apply_a(matrix: np.ndarray) -> np.ndarray:
        """A @ matrix for matrix (n, k)."""
        out = np.zeros_like(matrix)
        if count:
            feature_rows = matrix[nv:].reshape(count, d, -1)
            out[nv:] = a_vehicle.reshape(count * d, nv) @ matrix[:nv] + np.matmul(a_own, feature_rows).reshape(count * d, -1)
        return out

    ap = apply_a(covariance)
    apat = apply_a(ap.T)
    predicted = ap + ap.T
    predicted *= dt
    predicted += covariance
    apat *= dt * dt
    predicted += apat
    add_process_covariance(predicted, features, is_position, noise, dt, d)
    # symmetrise in place (round-off only: every term above is symmetric)
    predicted += predicted.T
    predicted *= 0.5
    return x_next, predicted


def process_covariance(features: np.ndarray, is_position: np.ndarray, noise: ProcessNoise, dt: float, dimension: int) -> np.ndarray:
    """Disturbance covariance ``Xi_F`` for one step of length ``dt`` (paper section V, plus gyro noise).

    ``Ts diag(sigma_v^2 I_d, sigma_b^2 I_r, sigma_p^2 I_d per position, sigma_dir^2 I_d per
    direction) + Ts sigma_g^2 G G^T`` with ``G`` stacking ``M(f_i)`` (the gyro white noise
    enters every feature's derivative as ``M(f_i) n``; continuous density ``sigma_g``).
    """
    nv = dimension + rate_dimension(dimension)
    count = features.shape[0]
    q = np.zeros((nv + count * dimension, nv + count * dimension))
    add_process_covariance(q, features, is_position, noise, dt, dimension)
    return q


def add_process_covariance(
    covariance: np.ndarray, features: np.ndarray, is_position: np.ndarray, noise: ProcessNoise, dt: float, dimension: int
) -> None:
    """``covariance += Xi_F`` in place (see ``process_covariance``), without an n x n temporary
    for the diagonal part."""
    d = dimension
    r = rate_dimension(d)
    nv = d + r
    count = features.shape[0]
    diagonal = np.concatenate(
        [
            np.full(d, noise.velocity_m_s**2),
            np.full(r, noise.gyro_bias_rad_s**2),
            np.repeat(np.where(is_position, noise.landmark_m**2, noise.direction**2), d),
        ]
    )
    index = np.arange(diagonal.size)
    covariance[index, index] += dt * diagonal
    if count and noise.gyro_noise_density > 0.0:
        g = bias_coupling(features).reshape(count * d, r)
        covariance[nv:, nv:] += (dt * noise.gyro_noise_density**2) * (g @ g.T)
