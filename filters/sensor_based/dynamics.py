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

from datasets.rotations import PLANAR_GENERATOR


def rate_dimension(dimension: int) -> int:
    """Dimension r of the rate/bias vector: 1 in 2-D (about z), 3 in 3-D."""
    return 1 if dimension == 2 else 3


def skew_rate(rate: np.ndarray, dimension: int) -> np.ndarray:
    """``S(rate)``, (d, d): 2-D ``rate[0] * [[0,-1],[1,0]]``, 3-D the cross-product matrix."""
    rate = np.asarray(rate, dtype=float).ravel()
    if dimension == 2:
        return float(rate[0]) * PLANAR_GENERATOR
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


def propagate_in_place(
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
    undisturbed: np.ndarray | None = None,
) -> np.ndarray:
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
        undisturbed: (F,) bool, features that take no disturbance (the Earth frame's,
            ``earth_state``); None: none.

    Returns:
        x_next (n,); ``covariance`` is replaced by ``F Sigma F^T + Xi`` in place.

    ``F Sigma F^T`` is evaluated block by block (``_transform_in_place``): the vehicle rows of
    F are the identity and each feature row block touches only the vehicle columns and its
    own block, so the product costs O(n^2) with a few n x n temporaries and no copy of the
    whole matrix per factor.
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

    diagonal, gyro_factor = process_noise_factors(features, is_position, noise, dt, d, undisturbed)
    if count:
        _transform_in_place(
            covariance, nv, phi_vehicle.reshape(count * d, nv), phi_own, gyro_factor
        )
    index = np.arange(diagonal.size)
    covariance[index, index] += diagonal
    # the feature and cross blocks are written exactly symmetric; the vehicle block is
    # only added to on its diagonal, so symmetrising it keeps the whole of P symmetric
    vehicle_block = covariance[:nv, :nv]
    vehicle_block[...] = 0.5 * (vehicle_block + vehicle_block.T)
    return x_next


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
    undisturbed: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``propagate_in_place`` on a copy: (x_next (n,), covariance_next (n, n))."""
    predicted = np.array(covariance, dtype=float, copy=True)
    x_next = propagate_in_place(
        x,
        predicted,
        is_position,
        visible_measurements,
        visible,
        rate,
        dt,
        noise,
        dimension,
        discretization,
        undisturbed,
    )
    return x_next, predicted


TILE_BLOCKS = 64
"""Feature blocks per tile of the in-place prediction (128 x 128 doubles in 2-D: 128 KiB,
held in cache while it is read, transformed and written twice)."""


def _transform_in_place(
    covariance: np.ndarray,
    nv: int,
    vehicle: np.ndarray,
    own: np.ndarray,
    noise_factor: np.ndarray,
) -> None:
    """``P <- F P F^T + [0; N] [0; N]^T`` for ``F = [[I, 0], [V, E]]``, ``E = blockdiag(own)``.

    With ``P = [[A, B], [B^T, C]]`` and ``G = B E^T``: the vehicle block A is unchanged,
    ``B' = A V^T + G`` and ``C' = E C E^T + V B' + (V G)^T + N N^T``; the three low-rank
    terms are one product ``[V, G^T, N] [B'; V^T; N^T]``.

    ``C'`` is computed tile by tile over the upper triangle only (``TILE_BLOCKS`` feature
    blocks a side): tile ``(I, J)``, ``I <= J``, is ``E_I C_IJ E_J^T`` plus its low-rank
    part, written to ``(I, J)`` and, transposed, to ``(J, I)``. Only upper tiles are read,
    so the update is in place; the result is exactly symmetric (no separate
    symmetrisation pass over P), and each tile stays in cache while it is read and written.
    Measured at 400 landmarks in 2-D (N = 803, ``OPENBLAS_NUM_THREADS=1``): one prediction
    5.7 -> 1.9 ms against the whole-matrix products and ``P += P.T`` it replaces (equal to
    round-off, ``tests/test_sensor_based_dynamics.py``).

    Args:
        covariance: P (n, n), updated in place.
        nv: size of the vehicle block.
        vehicle: V (L, nv), the feature rows' vehicle columns of F.
        own: E's diagonal blocks (F, d, d), L = F d.
        noise_factor: N (L, k), the feature block's low-rank process noise (k may be 0).
    """
    count, d, _ = own.shape
    size = count * d
    block_b = covariance[:nv, nv:]
    features = covariance[nv:, nv:]
    # G = B E^T, column block by column block: (count, nv, d) -> (nv, L)
    g = np.matmul(block_b.reshape(nv, count, d).transpose(1, 0, 2), own.transpose(0, 2, 1))
    g = g.transpose(1, 0, 2).reshape(nv, size)
    new_b = covariance[:nv, :nv] @ vehicle.T + g
    left = np.hstack([vehicle, g.T, noise_factor])  # (L, k)
    right = np.vstack([new_b, vehicle.T, noise_factor.T])  # (k, L)
    own_transposed = own.transpose(0, 2, 1)
    for first in range(0, count, TILE_BLOCKS):
        last = min(first + TILE_BLOCKS, count)
        rows = slice(first * d, last * d)
        for second in range(first, count, TILE_BLOCKS):
            end = min(second + TILE_BLOCKS, count)
            columns = slice(second * d, end * d)
            tile = features[rows, columns]
            # E_I C_IJ (row blocks), then (.) E_J^T (column blocks)
            rotated = np.matmul(own[first:last], tile.reshape(last - first, d, -1))
            rotated = rotated.reshape((last - first) * d, end - second, d).transpose(1, 0, 2)
            rotated = np.matmul(rotated, own_transposed[second:end])
            result = rotated.transpose(1, 0, 2).reshape((last - first) * d, (end - second) * d)
            result += left[rows] @ right[:, columns]
            if first == second:
                result += result.T.copy()
                result *= 0.5
            tile[...] = result
            if first != second:
                features[columns, rows] = result.T
    block_b[...] = new_b
    covariance[nv:, :nv] = new_b.T


def process_noise_factors(
    features: np.ndarray,
    is_position: np.ndarray,
    noise: ProcessNoise,
    dt: float,
    dimension: int,
    undisturbed: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """``Xi_F`` of one step of length ``dt`` as ``diag(diagonal) + [0; N] [0; N]^T``
    (see ``process_covariance``): returns (diagonal (n,), N (L, r)) with
    ``N = sqrt(Ts) sigma_g G``. ``undisturbed`` (F,) bool: features without disturbance
    (the Earth frame's); the gyro noise still reaches them through ``G``.
    """
    d = dimension
    r = rate_dimension(d)
    count = features.shape[0]
    disturbance = np.where(is_position, noise.landmark_m**2, noise.direction**2)
    if undisturbed is not None:
        disturbance = np.where(undisturbed, 0.0, disturbance)
    diagonal = dt * np.concatenate(
        [
            np.broadcast_to(np.asarray(noise.velocity_m_s, dtype=float) ** 2, (d,)),
            np.full(r, noise.gyro_bias_rad_s**2),
            np.repeat(disturbance, d),
        ]
    )
    if count == 0 or noise.gyro_noise_density <= 0.0:
        return diagonal, np.zeros((count * d, 0))
    factor = np.sqrt(dt) * noise.gyro_noise_density * bias_coupling(features).reshape(count * d, r)
    return diagonal, factor


def process_covariance(
    features: np.ndarray, is_position: np.ndarray, noise: ProcessNoise, dt: float, dimension: int
) -> np.ndarray:
    """Disturbance covariance ``Xi_F`` for one step of length ``dt`` (paper section V, plus gyro noise).

    ``Ts diag(sigma_v^2 I_d, sigma_b^2 I_r, sigma_p^2 I_d per position, sigma_dir^2 I_d per
    direction) + Ts sigma_g^2 G G^T`` with ``G`` stacking ``M(f_i)`` (the gyro white noise
    enters every feature's derivative as ``M(f_i) n``; continuous density ``sigma_g``).
    """
    nv = dimension + rate_dimension(dimension)
    diagonal, factor = process_noise_factors(features, is_position, noise, dt, dimension)
    q = np.diag(diagonal)
    q[nv:, nv:] += factor @ factor.T
    return q
