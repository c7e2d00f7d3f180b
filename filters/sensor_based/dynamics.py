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
from typing import Literal

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
        [
            np.stack([zero, -z, y], axis=1),
            np.stack([z, zero, -x], axis=1),
            np.stack([-y, x, zero], axis=1),
        ],
        axis=1,
    )


@dataclass(frozen=True)
class ProcessNoise:
    """Disturbance model (paper section V: ``Xi = Ts diag(sigma_v^2 I, sigma_b^2, sigma_p^2 I, ...)``).

    Attributes:
        velocity_m_s: sigma_v, velocity random-walk density [m/s/sqrt(s)] (paper 0.1): one
            value for every body axis (the paper's ``sigma_v^2 I``) or one per axis (d,).
        gyro_bias_rad_s: sigma_b, bias random-walk density [rad/s/sqrt(s)] (paper 5.7e-5 deg/s).
        landmark_m: sigma_p, landmark position disturbance [m/sqrt(s)] (paper 0.05).
        direction: disturbance of direction features [1/sqrt(s)].
        gyro_noise_density: gyro white-noise density [rad/s/sqrt(Hz)] injected through ``G``.
    """

    velocity_m_s: float | np.ndarray
    gyro_bias_rad_s: float
    landmark_m: float
    direction: float
    gyro_noise_density: float


Discretization = Literal["euler", "exact"]


def rotation_flow(generator: np.ndarray, dt: float) -> tuple[np.ndarray, np.ndarray]:
    """``(exp(K dt), int_0^dt exp(K s) ds)`` for a constant skew-symmetric ``K`` (d, d), d = 2, 3.

    Closed form (Rodrigues): with ``w`` the rate magnitude (``K^3 = -w^2 K``),
    ``exp(K t) = I + sin(w t)/w K + (1 - cos(w t))/w^2 K^2`` and its integral
    ``t I + (1 - cos(w t))/w^2 K + (w t - sin(w t))/w^3 K^2``; Taylor series below
    ``w t = 1e-4``. (Van Loan's block ``expm`` gives the same to round-off, tested, but costs
    milliseconds per call when BLAS threads contend.)
    """
    d = generator.shape[0]
    squared = generator @ generator
    rate = (
        np.sqrt(max(-0.5 * float(np.trace(squared)), 0.0))
        if d == 3
        else abs(float(generator[1, 0]))
    )
    angle = rate * dt
    if angle < 1e-4:
        a = dt * (1.0 - angle**2 / 6.0)  # sin(w t)/w
        b = dt**2 * (0.5 - angle**2 / 24.0)  # (1 - cos(w t))/w^2
        c = dt**3 * (1.0 / 6.0 - angle**2 / 120.0)  # (w t - sin(w t))/w^3
    else:
        a = np.sin(angle) / rate
        b = (1.0 - np.cos(angle)) / rate**2
        c = (angle - np.sin(angle)) / rate**3
    identity = np.eye(d)
    return identity + a * generator + b * squared, dt * identity + b * generator + c * squared


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
    discretization: Discretization = "euler",
) -> tuple[np.ndarray, np.ndarray]:
    """One prediction step (Guerreiro et al. eq. (10) and section IV-A).

    ``"euler"`` is eq. (10) as printed: ``x_{k+1} = x_k + Ts f(x_k)``,
    ``Sigma_{k+1} = F Sigma F^T + Xi`` with ``F = I + Ts A``. Visible features use
    ``A(t, y)`` with their measured value ``y`` (eqs. (3)-(4)); non-visible ones the
    nonlinear model and its Jacobian at the estimate (IV-A).

    ``"exact"`` solves the same model exactly over the step with the inputs held (zero-order
    hold on ``omega_m``, ``y`` and the vehicle state, which the model keeps constant):
    ``F = expm(A Ts)``. Each feature row block of A is ``[vehicle part, W]`` with the shared
    rotation generator ``W = -S(omega_m)`` (visible) or ``-S(omega_m - b_hat)`` (non-visible),
    so ``F`` has own blocks ``E = exp(W Ts)`` and vehicle blocks ``Gamma [-I, M(q)]`` with
    ``Gamma = int_0^Ts exp(W s) ds``. Why: forward Euler's ``I - Ts S(omega)`` is not a
    rotation; it dilates every landmark by ``(omega Ts)^2 / 2`` per step, which the filter
    explains as an approach speed. Measured on ``sim:guerreiro-loop`` (constant speed, 20
    seeds, 0.05 s steps): a common forward-velocity error of -3 mm/s after each corridor
    corner (the true scatter is 0.7 mm/s), gone with the exact flow or 0.005 s Euler steps.
    The LTV structure (A depends on measurements only) and so the GAS argument are unchanged.

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
        discretization: "euler" (eq. (10)) or "exact".

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

    # Rows of A for the features: vehicle columns [ -[pos] I, M(q) ], own block W (+ S(b) if
    # non-visible: derivative of M(f) b with respect to f).
    a_vehicle = np.zeros((count, d, nv))
    a_vehicle[:, :, :d] = -position_sign[:, :, None] * np.eye(d)[None]
    a_vehicle[:, :, d:] = m
    x_next = x.copy()
    if discretization == "euler":
        derivative = features @ w.T + np.einsum("fdr,r->fd", m, b) - position_sign * v[None, :]
        x_next[nv:] = (features + dt * derivative).ravel()
        own = np.broadcast_to(w, (count, d, d)).copy()
        own[~visible] += skew_rate(b, d)
        # F = I + dt A: feature rows [dt a_vehicle, I + dt own]
        phi_vehicle = dt * a_vehicle
        phi_own = own * dt
        phi_own += np.eye(d)[None]
    elif discretization == "exact":
        flow_visible = rotation_flow(w, dt)
        flow_hidden = rotation_flow(w + skew_rate(b, d), dt)  # -S(omega_m - b_hat)
        exp_own = np.where(visible[:, None, None], flow_visible[0][None], flow_hidden[0][None])
        integral = np.where(visible[:, None, None], flow_visible[1][None], flow_hidden[1][None])
        # held inputs: visible f' = E f + Gamma (M(y) b - v); non-visible f' = E f - Gamma v
        forcing = (
            np.where(visible[:, None], np.einsum("fdr,r->fd", m, b), 0.0)
            - position_sign * v[None, :]
        )
        x_next[nv:] = (
            np.einsum("fij,fj->fi", exp_own, features) + np.einsum("fij,fj->fi", integral, forcing)
        ).ravel()
        phi_vehicle = np.matmul(integral, a_vehicle)
        phi_own = exp_own
    else:
        raise ValueError(f"unknown discretization {discretization!r}")

    def apply_phi(matrix: np.ndarray) -> np.ndarray:
        """F @ matrix for matrix (n, k): vehicle rows unchanged, feature rows mixed."""
        out = matrix.copy()
        if count:
            feature_rows = matrix[nv:].reshape(count, d, -1)
            out[nv:] = phi_vehicle.reshape(count * d, nv) @ matrix[:nv] + np.matmul(
                phi_own, feature_rows
            ).reshape(count * d, -1)
        return out

    predicted = apply_phi(apply_phi(covariance).T)
    add_process_covariance(predicted, features, is_position, noise, dt, d)
    # symmetrise in place (round-off only: every term above is symmetric)
    predicted += predicted.T
    predicted *= 0.5
    return x_next, predicted


def process_covariance(
    features: np.ndarray, is_position: np.ndarray, noise: ProcessNoise, dt: float, dimension: int
) -> np.ndarray:
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
    covariance: np.ndarray,
    features: np.ndarray,
    is_position: np.ndarray,
    noise: ProcessNoise,
    dt: float,
    dimension: int,
) -> None:
    """``covariance += Xi_F`` in place (see ``process_covariance``), without an n x n temporary
    for the diagonal part."""
    d = dimension
    r = rate_dimension(d)
    nv = d + r
    count = features.shape[0]
    diagonal = np.concatenate(
        [
            np.broadcast_to(np.asarray(noise.velocity_m_s, dtype=float) ** 2, (d,)),
            np.full(r, noise.gyro_bias_rad_s**2),
            np.repeat(np.where(is_position, noise.landmark_m**2, noise.direction**2), d),
        ]
    )
    index = np.arange(diagonal.size)
    covariance[index, index] += dt * diagonal
    if count and noise.gyro_noise_density > 0.0:
        g = bias_coupling(features).reshape(count * d, r)
        covariance[nv:, nv:] += (dt * noise.gyro_noise_density**2) * (g @ g.T)
