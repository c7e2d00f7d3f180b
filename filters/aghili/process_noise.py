"""Discrete-time process noise ``Q_k = int_0^tau Phi(s) G Sigma G^T Phi(s)^T ds`` (Aghili
eqs. (36)-(37)).

Two implementations, tested against each other and against a brute-force quadrature in
``tests/test_aghili_process_noise.py``:

- ``process_noise_van_loan``: Van Loan's matrix exponential (exact for any F, G; one
  30 x 30 ``expm`` per step). Config ``process_noise="van-loan"``.
- ``vehicle_process_noise``: our closed form (the default). Every block of Q' reduces to
  integrals ``J_ij = int_0^tau Lambda_i(s) Lambda_j(s)^T ds`` (see ``lambda_product_integral``)
  and ``int Lambda_n = Lambda_(n+1)``; each ``J_ij`` is ``alpha 1 + beta W + gamma W^2``
  (``W = [omega_bar x]``) with scalar series in ``|omega_bar| tau`` that are summed without
  cancellation. Agrees with Van Loan to ~1e-13 relative.

Where the printed eq. (37) disagrees (read with block rows [dq_v, dr, dr_dot, db_g, db_a],
the only reading in which its diagonal ``1/3 sigma_a^2 t^3`` and ``sigma_bg^2 t`` fit):

- Q'_11 (attitude) ``(sigma_g^2/4 t + sigma_bg^2/12 t^3) 1 + sigma_bg^2/240 t^5 W^2`` is right
  to the order it keeps (the exact block is ``sigma_g^2/4 t 1 + sigma_bg^2/4 J_22``).
- the db_g-attitude block ``sigma_bg^2/4 t^2 1 + sigma_bg^2/48 t^4 W^2`` misses the first
  order term: exact is ``sigma_bg^2/2 Lambda_3^T = sigma_bg^2 (t^2/4 1 + t^3/12 W + ...)``.
- the position row is printed as ``[0, sigma_a^2 t^3/3, 0, 0, 0]``: the position-velocity
  block ``sigma_a^2 t^2/2 1`` (leading order) and the position-attitude block are missing.
- the velocity-velocity block ``Q'_33`` printed has no ``sigma_a^2 t 1`` term, which is the
  leading one; the db_a row is printed as zeros off the diagonal, but the velocity-db_a
  block is ``sigma_ba^2 Abar t^2/2``.
- two different blocks are both labelled ``Q'_43``.
So we do not use eq. (37) at all: the closed form here is derived from (36) directly.
"""

from __future__ import annotations

from functools import cache
from math import factorial

import numpy as np
from scipy.linalg import expm

from datasets.rotations import skew
from filters.aghili.transition import (
    ACCEL_BIAS,
    ATTITUDE,
    GYRO_BIAS,
    POSITION,
    VEHICLE_DIM,
    VELOCITY,
    lambda_matrices,
)

_TERMS = 24
_CLOSED_FORM_LIMIT = 3.0
"""Above this |omega| tau [rad] the series needs more terms: fall back to Van Loan."""


def noise_covariance(
    gyro_density: float, gyro_bias_walk: float, accel_density: float, accel_bias_walk: float
) -> np.ndarray:
    """Aghili section 4.1: ``Sigma_eps = diag(sg^2 1, sbg^2 1, sa^2 1, sba^2 1)`` (12, 12).

    Densities are continuous-time (``NoiseSpec``): [rad/s/sqrt(Hz)], [rad/s^2/sqrt(Hz)],
    [m/s^2/sqrt(Hz)], [m/s^3/sqrt(Hz)], in the noise order ``[eps_g, eps_bg, eps_a, eps_ba]``.
    """
    return np.diag(
        np.repeat([gyro_density**2, gyro_bias_walk**2, accel_density**2, accel_bias_walk**2], 3)
    )


def process_noise_van_loan(
    F: np.ndarray, G: np.ndarray, sigma: np.ndarray, tau: float
) -> np.ndarray:
    """Aghili eq. (36) by Van Loan (1978): ``expm([[-F, G S G^T], [0, F^T]] tau)``.

    Returns Q (N, N) for F (N, N), G (N, p), sigma (p, p), step tau [s]; symmetrised.
    """
    size = F.shape[0]
    block = np.zeros((2 * size, 2 * size))
    block[:size, :size] = -F
    block[:size, size:] = G @ sigma @ G.T
    block[size:, size:] = F.T
    exponential = expm(block * tau)
    phi = exponential[size:, size:].T
    q = phi @ exponential[:size, size:]
    return 0.5 * (q + q.T)


@cache
def _series_by_order(i: int, j: int) -> tuple[np.ndarray, np.ndarray]:
    """Coefficients of ``lambda_product_integral`` grouped by total order ``n = k + l``.

    Returns ``(real, imag)``, shape (2 * _TERMS,) each: ``sum_{k+l=n}`` of the phase
    ``i^(l-k)`` (real or imaginary part) over ``(k+i-1)! (l+j-1)! (n+i+j-1)``.
    """
    real = np.zeros(2 * _TERMS)
    imag = np.zeros(2 * _TERMS)
    for k in range(_TERMS):
        for l in range(_TERMS):  # noqa: E741 - the equation's index
            n = k + l
            weight = 1.0 / (factorial(k + i - 1) * factorial(l + j - 1) * (n + i + j - 1))
            phase = (l - k) % 4
            if phase in (0, 2):
                real[n] += weight if phase == 0 else -weight
            else:
                imag[n] += weight if phase == 1 else -weight
    return real, imag


@cache
def _pair_tables(
    pairs: tuple[tuple[int, int], ...],
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Stacked ``_series_by_order`` tables (P, 2T), tau exponent offsets (P,), parallel factors (P,)."""
    real = np.array([_series_by_order(i, j)[0] for i, j in pairs])
    imag = np.array([_series_by_order(i, j)[1] for i, j in pairs])
    offsets = np.array([i + j - 1 for i, j in pairs], dtype=float)
    parallel = np.array(
        [1.0 / ((i + j - 1) * factorial(i - 1) * factorial(j - 1)) for i, j in pairs]
    )
    return real, imag, offsets, parallel


_ORDERS = np.arange(2 * _TERMS)
_EVEN_MASK = (_ORDERS % 2 == 0) & (_ORDERS >= 2)
_ODD_MASK = _ORDERS % 2 == 1


def _product_coefficients(
    pairs: tuple[tuple[int, int], ...], rate: float, tau: float
) -> np.ndarray:
    """``(parallel, beta, gamma)`` of ``J_ij = parallel 1 + beta W + gamma W^2`` per pair, (P, 3)."""
    real, imag, offsets, parallel = _pair_tables(pairs)
    n = _ORDERS
    rate_even = np.where(_EVEN_MASK, rate ** np.maximum(n - 2, 0), 0.0)
    rate_odd = np.where(_ODD_MASK, rate ** np.maximum(n - 1, 0), 0.0)
    tau_powers = tau ** (n[None, :] + offsets[:, None])
    out = np.empty((len(pairs), 3))
    out[:, 0] = parallel * tau**offsets
    out[:, 1] = np.sum(imag * tau_powers * rate_odd, axis=1)
    out[:, 2] = -np.sum(real * tau_powers * rate_even, axis=1)
    return out


def lambda_product_integral(i: int, j: int, omega: np.ndarray, tau: float) -> np.ndarray:
    """``J_ij = int_0^tau Lambda_i(s) Lambda_j(s)^T ds`` (3, 3) in closed (series) form.

    With ``u = omega/|omega|``, ``Lambda_n`` acts on ``u`` as ``s^(n-1)/(n-1)!`` and on the
    plane normal to u as the complex number ``z_n(s) = sum_k (-i w)^k s^(k+n-1)/(k+n-1)!``
    (the (n-1)-fold integral of ``exp(-i w s)``, w = |omega|; ``[u x]`` acts as ``i`` and the
    transpose as the conjugate). So ``J = A 1 + (Im C / w) W + ((A - Re C)/w^2) W^2`` with
    ``A = int s^(i+j-2)/((i-1)!(j-1)!)`` and ``C = int z_i conj(z_j)``; the (0, 0) term of C
    is A, so both coefficients are power series in ``w`` summed without cancellation.
    """
    w = skew(omega)
    parallel, beta, gamma = _product_coefficients(((i, j),), float(np.linalg.norm(omega)), tau)[0]
    return parallel * np.eye(3) + beta * w + gamma * (w @ w)


def vehicle_process_noise(
    omega_bar: np.ndarray,
    a_bar: np.ndarray,
    attitude: np.ndarray,
    tau: float,
    gyro_density: float,
    gyro_bias_walk: float,
    accel_density: float,
    accel_bias_walk: float,
    lambdas: list[np.ndarray] | None = None,
) -> np.ndarray:
    """Aghili eq. (36) in closed form: ``Q'`` (15, 15) for the vehicle error state.

    Same arguments as ``transition.vehicle_transition`` plus the continuous densities of
    ``noise_covariance``. Derived block by block from the columns of the corrected Phi'
    (``transition`` module) times G (21b, corrected); ``M = Abar [abar x]``. Falls back to
    Van Loan when ``|omega_bar| tau`` exceeds the series' comfortable range. ``lambdas``:
    ``lambda_matrices(omega_bar, tau, >= 5)`` if already computed.
    """
    if float(np.linalg.norm(omega_bar)) * tau > _CLOSED_FORM_LIMIT:
        from filters.aghili.transition import error_dynamics

        F, G = error_dynamics(omega_bar, a_bar, attitude)
        return process_noise_van_loan(
            F,
            G,
            noise_covariance(gyro_density, gyro_bias_walk, accel_density, accel_bias_walk),
            tau,
        )
    if lambdas is None:
        lambdas = lambda_matrices(omega_bar, tau, 5)
    sg2, sbg2, sa2, sba2 = gyro_density**2, gyro_bias_walk**2, accel_density**2, accel_bias_walk**2
    m = attitude @ skew(a_bar)
    w = skew(omega_bar)
    w2 = w @ w
    pairs = ((1, 1), (1, 2), (1, 3), (2, 2), (2, 3), (2, 4), (3, 3), (3, 4), (4, 4))
    coefficients = _product_coefficients(pairs, float(np.linalg.norm(omega_bar)), tau)
    J = {pair: c[0] * np.eye(3) + c[1] * w + c[2] * w2 for pair, c in zip(pairs, coefficients)}

    def j(a: int, b: int) -> np.ndarray:
        return J[(a, b)] if (a, b) in J else J[(b, a)].T

    eye = np.eye(3)
    q = np.zeros((VEHICLE_DIM, VEHICLE_DIM))
    # eps_g through the attitude column [L1; -2 M L3; -2 M L2; 0; 0] times 1/2
    q[ATTITUDE, ATTITUDE] = sg2 / 4.0 * j(1, 1) + sbg2 / 4.0 * j(2, 2)
    q[ATTITUDE, POSITION] = -sg2 / 2.0 * j(1, 3) @ m.T - sbg2 / 2.0 * j(2, 4) @ m.T
    q[ATTITUDE, VELOCITY] = -sg2 / 2.0 * j(1, 2) @ m.T - sbg2 / 2.0 * j(2, 3) @ m.T
    q[ATTITUDE, GYRO_BIAS] = sbg2 / 2.0 * lambdas[2]
    q[POSITION, POSITION] = (
        sg2 * m @ j(3, 3) @ m.T
        + sbg2 * m @ j(4, 4) @ m.T
        + (sa2 * tau**3 / 3.0 + sba2 * tau**5 / 20.0) * eye
    )
    q[POSITION, VELOCITY] = (
        sg2 * m @ j(3, 2) @ m.T
        + sbg2 * m @ j(4, 3) @ m.T
        + (sa2 * tau**2 / 2.0 + sba2 * tau**4 / 8.0) * eye
    )
    q[POSITION, GYRO_BIAS] = -sbg2 * m @ lambdas[4]
    q[POSITION, ACCEL_BIAS] = sba2 * tau**3 / 6.0 * attitude
    q[VELOCITY, VELOCITY] = (
        sg2 * m @ j(2, 2) @ m.T + sbg2 * m @ j(3, 3) @ m.T + (sa2 * tau + sba2 * tau**3 / 3.0) * eye
    )
    q[VELOCITY, GYRO_BIAS] = -sbg2 * m @ lambdas[3]
    q[VELOCITY, ACCEL_BIAS] = sba2 * tau**2 / 2.0 * attitude
    q[GYRO_BIAS, GYRO_BIAS] = sbg2 * tau * eye
    q[ACCEL_BIAS, ACCEL_BIAS] = sba2 * tau * eye
    # only blocks on or above the block diagonal were filled: mirror the strict upper triangle
    return np.triu(q) + np.triu(q, 1).T


def paper_printed_blocks(
    omega_bar: np.ndarray,
    tau: float,
    gyro_density: float,
    gyro_bias_walk: float,
    accel_density: float,
) -> dict[str, np.ndarray]:
    """Three blocks of eq. (37) *as printed*, for the tests that document where it is right
    and where it is not: attitude (Q'_11), gyro-bias/attitude (Q'_41), position (Q'_22)."""
    w = skew(omega_bar)
    sg2, sbg2, sa2 = gyro_density**2, gyro_bias_walk**2, accel_density**2
    return {
        "attitude": (sg2 / 4.0 * tau + sbg2 / 12.0 * tau**3) * np.eye(3)
        + sbg2 / 240.0 * tau**5 * (w @ w),
        "gyro_bias_attitude": sbg2 / 4.0 * tau**2 * np.eye(3) + sbg2 / 48.0 * tau**4 * (w @ w),
        "position": sa2 / 3.0 * tau**3 * np.eye(3),
    }
