"""Linearised error dynamics and the closed-form state transition matrix (Aghili eqs. (20),
(21a), (21b), (35)).

Error state (the order of F (21a), G (21b) and P; eq. (6) omits the velocity although every
matrix of the paper is 15+3n, so we use the full state):

    dx = [dq_v, dr, dr_dot, db_g, db_a, drho_(r+1), ..., drho_m]      (15 + 3n,)

with ``dq_v`` the vector part of the error quaternion (half-angle, body frame), ``dr`` and
``dr_dot`` world-frame position and velocity errors, biases in the paper's convention
("true = measured + bias", eqs. (13), (15)).

Continuous model (eqs. (17), (19), (20)), with ``W = [omega_bar x]`` and ``M = Abar [abar x]``:

    d/dt dq_v  = -W dq_v + 1/2 db_g + 1/2 eps_g
    d/dt dr    = dr_dot
    d/dt dr_dot = -2 M dq_v + Abar db_a + Abar eps_a
    d/dt db_g  = eps_bg,   d/dt db_a = eps_ba,   d/dt drho = 0

Closed-form transition ``Phi(tau) = expm(F tau)`` (vehicle block ``Phi'``, 15 x 15; the
landmark block is the identity):

    [ L1          0   0     1/2 L2      0        ]   rows: dq_v
    [ -2 M L3     1   tau   -M L4       Abar t^2/2]         dr
    [ -2 M L2     0   1     -M L3       Abar tau ]         dr_dot
    [ 0           0   0     1           0        ]         db_g
    [ 0           0   0     0           1        ]         db_a

with ``L1 = exp(-W tau)`` and ``L(n+1) = int_0^tau Ln``. Where the printed eq. (35) is wrong
(each checked against ``scipy.linalg.expm`` in ``tests/test_aghili_transition.py``):

- it has four block rows for a five-block state (the position row is ``[0 0 1 tau 0]``-like
  and the velocity row is missing the velocity/position structure);
- the velocity-attitude block lacks the factor 2 that F (21a) has: it is ``-2 M L2``;
- the velocity-gyro-bias block is ``-M L3``, not ``1/2 L3``;
- the position blocks need one more integral: ``-2 M L3`` and ``-M L4`` (``L4`` is not in
  the paper).
L1..L3 as printed are right (``Lambda_1..3`` of eq. (35)).
"""

from __future__ import annotations

from functools import cache
from math import factorial

import numpy as np

from datasets.rotations import skew
from filters.state_registry import StateRegistry

VEHICLE_DIM = 15
"""Size of the vehicle error state [dq_v, dr, dr_dot, db_g, db_a]."""

ATTITUDE = slice(0, 3)
POSITION = slice(3, 6)
VELOCITY = slice(6, 9)
GYRO_BIAS = slice(9, 12)
ACCEL_BIAS = slice(12, 15)

VEHICLE_BLOCKS = (
    ("attitude", ATTITUDE),
    ("position", POSITION),
    ("velocity", VELOCITY),
    ("gyro_bias", GYRO_BIAS),
    ("accel_bias", ACCEL_BIAS),
)
"""The vehicle blocks by name, in state order (the names the ``StateRegistry`` knows)."""

LANDMARK_BLOCKS = (("position", 3),)
"""An estimated landmark's blocks: its world position ``rho`` (3 entries)."""


def state_registry() -> StateRegistry:
    """The registry of an Aghili error state with no landmark yet: the vehicle blocks above,
    landmarks appended by ``augment(id, LANDMARK_BLOCKS)``."""
    return StateRegistry((name, block.stop - block.start) for name, block in VEHICLE_BLOCKS)


_SERIES_LIMIT = 2.0
_SERIES_TERMS = 20


@cache
def _inverse_factorials(order: int) -> np.ndarray:
    """``(-1)^k / (2k + order)!`` for k < _SERIES_TERMS."""
    return np.array([(-1.0) ** k / factorial(2 * k + order) for k in range(_SERIES_TERMS)])


_EVEN_POWERS = 2 * np.arange(_SERIES_TERMS)


def series_coefficient(order: int, x: float) -> float:
    """``c_j(x) = sum_k (-1)^k x^(2k) / (2k + j)!`` for ``j = order >= 1`` (dimensionless).

    ``c1 = sin x / x``, ``c2 = (1 - cos x)/x^2``, ``c3 = (x - sin x)/x^3``,
    ``c4 = (cos x - 1 + x^2/2)/x^4``, ..., i.e. ``c_(j+2) = (1/j! - c_j) / x^2``. The closed
    forms lose all precision to cancellation for small x, so the series is used below x = 2.
    """
    if x < _SERIES_LIMIT:
        return float(_inverse_factorials(order) @ x**_EVEN_POWERS)
    value = np.sin(x) / x if order % 2 == 1 else (1.0 - np.cos(x)) / x**2
    for j in range(2 - order % 2, order - 1, 2):
        value = (1.0 / factorial(j) - value) / x**2
    return float(value)


def series_coefficients(x: float, count: int) -> np.ndarray:
    """``[c_1(x), ..., c_count(x)]`` (count,) at once (see ``series_coefficient``)."""
    if x < _SERIES_LIMIT:
        return _coefficient_table(count) @ x**_EVEN_POWERS
    return np.array([series_coefficient(order, x) for order in range(1, count + 1)])


@cache
def _coefficient_table(count: int) -> np.ndarray:
    return np.array([_inverse_factorials(order) for order in range(1, count + 1)])


def lambda_matrices(omega: np.ndarray, tau: float, max_order: int) -> list[np.ndarray]:
    """``[Lambda_1, ..., Lambda_max_order]`` (each (3, 3)) of eq. (35), sharing one series
    evaluation; ``lambda_matrices(-omega, ...)`` gives the integrals of ``exp(+[omega x] s)``."""
    w = skew(omega)
    w2 = w @ w
    c = series_coefficients(float(np.linalg.norm(omega)) * tau, max_order + 1)
    eye = np.eye(3)
    return [
        tau ** (n - 1) / factorial(n - 1) * eye - tau**n * c[n - 1] * w + tau ** (n + 1) * c[n] * w2
        for n in range(1, max_order + 1)
    ]


def lambda_matrix(order: int, omega: np.ndarray, tau: float) -> np.ndarray:
    """Aghili eq. (35): ``Lambda_n(tau)`` (3, 3), the n-1 fold integral of ``exp(-[omega x] s)``.

    ``Lambda_n = tau^(n-1)/(n-1)! 1 - tau^n c_n [omega x] + tau^(n+1) c_(n+1) [omega x]^2``
    with ``x = |omega| tau`` (``series_coefficient``). ``order >= 1`` (``Lambda_4``,
    ``Lambda_5`` are the extra integrals the position blocks and Q need, absent from the
    paper).
    """
    w = skew(omega)
    x = float(np.linalg.norm(omega)) * tau
    return (
        tau ** (order - 1) / factorial(order - 1) * np.eye(3)
        - tau**order * series_coefficient(order, x) * w
        + tau ** (order + 1) * series_coefficient(order + 1, x) * (w @ w)
    )


def error_dynamics(
    omega_bar: np.ndarray, a_bar: np.ndarray, attitude: np.ndarray, landmark_count: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Aghili eqs. (21a), (21b): ``F`` (15+3n, 15+3n) and ``G`` (15+3n, 12).

    Args:
        omega_bar: bias-corrected body rate [rad/s] (3,), eq. (34a).
        a_bar: bias-corrected specific force [m/s^2] (3,), eq. (34b).
        attitude: ``Abar`` body-to-world rotation (3, 3).
        landmark_count: n, estimated landmarks in the state.

    Noise order ``[eps_g, eps_bg, eps_a, eps_ba]``. The printed G (21b) feeds ``eps_a``
    into ``b_a`` (its last row is ``[0 0 1 0]``); the bias walk is ``eps_ba``
    (``[0 0 0 1]``), which is what we use.
    """
    size = VEHICLE_DIM + 3 * landmark_count
    F = np.zeros((size, size))
    F[ATTITUDE, ATTITUDE] = -skew(omega_bar)
    F[ATTITUDE, GYRO_BIAS] = 0.5 * np.eye(3)
    F[POSITION, VELOCITY] = np.eye(3)
    F[VELOCITY, ATTITUDE] = -2.0 * attitude @ skew(a_bar)
    F[VELOCITY, ACCEL_BIAS] = attitude
    G = np.zeros((size, 12))
    G[ATTITUDE, 0:3] = 0.5 * np.eye(3)
    G[VELOCITY, 6:9] = attitude
    G[GYRO_BIAS, 3:6] = np.eye(3)
    G[ACCEL_BIAS, 9:12] = np.eye(3)
    return F, G


def vehicle_transition(
    omega_bar: np.ndarray,
    a_bar: np.ndarray,
    attitude: np.ndarray,
    tau: float,
    lambdas: list[np.ndarray] | None = None,
) -> np.ndarray:
    """Aghili eq. (35), corrected: ``Phi'(tau) = expm(F' tau)`` (15, 15) in closed form.

    Args:
        omega_bar: bias-corrected body rate [rad/s] (3,).
        a_bar: bias-corrected specific force [m/s^2] (3,).
        attitude: ``Abar`` (3, 3), held constant over the step (as in the paper).
        tau: step [s].
        lambdas: ``lambda_matrices(omega_bar, tau, >= 4)`` if already computed.
    """
    if lambdas is None:
        lambdas = lambda_matrices(omega_bar, tau, 4)
    lambdas = {n: lambdas[n - 1] for n in (1, 2, 3, 4)}
    coupling = attitude @ skew(a_bar)  # M = Abar [abar x]
    phi = np.eye(VEHICLE_DIM)
    phi[ATTITUDE, ATTITUDE] = lambdas[1]
    phi[ATTITUDE, GYRO_BIAS] = 0.5 * lambdas[2]
    phi[POSITION, ATTITUDE] = -2.0 * coupling @ lambdas[3]
    phi[POSITION, VELOCITY] = tau * np.eye(3)
    phi[POSITION, GYRO_BIAS] = -coupling @ lambdas[4]
    phi[POSITION, ACCEL_BIAS] = 0.5 * tau**2 * attitude
    phi[VELOCITY, ATTITUDE] = -2.0 * coupling @ lambdas[2]
    phi[VELOCITY, GYRO_BIAS] = -coupling @ lambdas[3]
    phi[VELOCITY, ACCEL_BIAS] = tau * attitude
    return phi


def paper_printed_vehicle_transition(
    omega_bar: np.ndarray, a_bar: np.ndarray, attitude: np.ndarray, tau: float
) -> np.ndarray:
    """Eq. (35) *as printed*, read as acting on [dq_v, dr, dr_dot, db_g] (12, 12).

    Kept only so that a test can show it disagrees with ``expm(F tau)``; never used.
    """
    lambdas = {n: lambda_matrix(n, omega_bar, tau) for n in (1, 2, 3)}
    phi = np.zeros((12, 12))
    phi[0:3, 0:3] = lambdas[1]
    phi[0:3, 9:12] = 0.5 * lambdas[2]
    phi[3:6, 6:9] = tau * np.eye(3)
    phi[6:9, 0:3] = -attitude @ skew(a_bar) @ lambdas[2]
    phi[6:9, 9:12] = 0.5 * lambdas[3]
    phi[9:12, 9:12] = np.eye(3)
    return phi
