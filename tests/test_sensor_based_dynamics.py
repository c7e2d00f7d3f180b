"""The sensor-based prediction and update against independent references."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pytest
from scipy.linalg import expm

from filters.sensor_based.dynamics import (
    ProcessNoise,
    bias_coupling,
    process_covariance,
    propagate,
    skew_rate,
)
from filters.sensor_based.update import selection_update

NOISE = ProcessNoise(
    velocity_m_s=0.1, gyro_bias_rad_s=1e-4, landmark_m=0.05, direction=0.01, gyro_noise_density=2e-3
)


def _random_state(
    rng: np.random.Generator, d: int, count: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r = 1 if d == 2 else 3
    n = d + r + count * d
    x = rng.normal(size=n)
    a = rng.normal(size=(n, n))
    cov = a @ a.T / n + 0.1 * np.eye(n)
    is_position = np.ones(count, dtype=bool)
    is_position[-1] = False  # one direction feature
    return x, cov, is_position


def _continuous_derivative(
    x: np.ndarray, rate: np.ndarray, is_position: np.ndarray, d: int
) -> np.ndarray:
    """The nonlinear model eq. (1) written independently: f_dot = -S(rate - b) f - [pos] v."""
    r = 1 if d == 2 else 3
    v, b = x[:d], x[d : d + r]
    features = x[d + r :].reshape(-1, d)
    omega = rate - b
    out = np.zeros_like(x)
    for index, f in enumerate(features):
        if d == 2:
            rotated = -omega[0] * np.array([-f[1], f[0]])
        else:
            rotated = -np.cross(omega, f)
        out[d + r + index * d : d + r + index * d + d] = rotated - (
            v if is_position[index] else 0.0
        )
    return out


@pytest.mark.parametrize("d", [2, 3])
def test_bias_coupling_is_the_derivative_of_s_of_b_times_q(d: int) -> None:
    rng = np.random.default_rng(1)
    q = rng.normal(size=(4, d))
    b = rng.normal(size=1 if d == 2 else 3)
    m = bias_coupling(q)
    for row, point in enumerate(q):
        assert np.allclose(skew_rate(b, d) @ point, m[row] @ b)


@pytest.mark.parametrize("d", [2, 3])
def test_non_visible_prediction_matches_euler_of_the_nonlinear_model_and_its_jacobian(
    d: int,
) -> None:
    rng = np.random.default_rng(2)
    x, cov, is_position = _random_state(rng, d, 4)
    rate = rng.normal(size=1 if d == 2 else 3)
    dt = 0.05
    visible = np.zeros(4, dtype=bool)
    x_next, cov_next = propagate(x, cov, is_position, np.zeros((4, d)), visible, rate, dt, NOISE, d)
    assert np.allclose(x_next, x + dt * _continuous_derivative(x, rate, is_position, d))
    # Jacobian of the Euler map by central finite differences (independent of the code's A).
    n = x.size
    jac = np.zeros((n, n))
    for column in range(n):
        step = np.zeros(n)
        step[column] = 1e-6
        plus = x + step + dt * _continuous_derivative(x + step, rate, is_position, d)
        minus = x - step + dt * _continuous_derivative(x - step, rate, is_position, d)
        jac[:, column] = (plus - minus) / 2e-6
    features = x[n - 4 * d :].reshape(4, d)
    expected = jac @ cov @ jac.T + process_covariance(features, is_position, NOISE, dt, d)
    assert np.allclose(cov_next, expected, atol=1e-8)


def _dense_ltv_matrix(
    n: int, measured: np.ndarray, is_position: np.ndarray, rate: np.ndarray, d: int
) -> np.ndarray:
    """The dense A(t, y) of eqs. (3)-(4) written out row by row (visible features only)."""
    r = 1 if d == 2 else 3
    a = np.zeros((n, n))
    m = bias_coupling(measured)
    for index in range(len(measured)):
        rows = slice(d + r + index * d, d + r + index * d + d)
        if is_position[index]:
            a[rows, :d] = -np.eye(d)
        a[rows, d : d + r] = m[index]
        a[rows, rows] = -skew_rate(rate, d)
    return a


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("discretization", ["euler", "exact"])
def test_visible_prediction_is_the_ltv_model_with_measured_positions(
    d: int, discretization: str
) -> None:
    """Euler: F = I + Ts A (eq. (10)); exact: F = expm(A Ts), with the dense A(t, y)."""
    rng = np.random.default_rng(3)
    x, cov, is_position = _random_state(rng, d, 3)
    r = 1 if d == 2 else 3
    measured = rng.normal(size=(3, d))
    rate = rng.normal(size=r)
    dt = 0.1 if discretization == "euler" else 0.3
    x_next, cov_next = propagate(
        x, cov, is_position, measured, np.ones(3, dtype=bool), rate, dt, NOISE, d, discretization
    )
    a = _dense_ltv_matrix(x.size, measured, is_position, rate, d)
    f = np.eye(x.size) + dt * a if discretization == "euler" else expm(a * dt)
    np.testing.assert_allclose(x_next, f @ x, atol=1e-12)
    q = process_covariance(x[d + r :].reshape(3, d), is_position, NOISE, dt, d)
    np.testing.assert_allclose(cov_next, f @ cov @ f.T + q, atol=1e-12)


@pytest.mark.parametrize("d", [2, 3])
def test_exact_non_visible_prediction_solves_the_nonlinear_model(d: int) -> None:
    """Non-visible features: the mean is the ODE solution of eq. (1) with v, b, omega_m held
    (scipy's solve_ivp), and the transition is its Jacobian with respect to f and v by
    central differences (the bias column is the first-order Gamma M(f), checked to O(Ts^2))."""
    from scipy.integrate import solve_ivp

    rng = np.random.default_rng(14)
    x, cov, is_position = _random_state(rng, d, 3)
    r = 1 if d == 2 else 3
    rate = rng.normal(size=r)
    dt = 0.05
    visible = np.zeros(3, dtype=bool)
    x_next, _ = propagate(
        x, cov, is_position, np.zeros((3, d)), visible, rate, dt, NOISE, d, "exact"
    )

    def flow(state: np.ndarray) -> np.ndarray:
        solution = solve_ivp(
            lambda _, y: _continuous_derivative(y, rate, is_position, d),
            (0.0, dt),
            state,
            rtol=1e-12,
            atol=1e-12,
        )
        return solution.y[:, -1]

    np.testing.assert_allclose(x_next, flow(x), atol=1e-9)
    n = x.size
    jac = np.zeros((n, n))
    for column in range(n):
        step = np.zeros(n)
        step[column] = 1e-5
        jac[:, column] = (flow(x + step) - flow(x - step)) / 2e-5
    q = process_covariance(x[d + r :].reshape(3, d), is_position, NOISE, dt, d)
    # with no bias uncertainty the bias column of F does not enter: exact up to the differences
    no_bias = cov.copy()
    no_bias[d : d + r, :] = 0.0
    no_bias[:, d : d + r] = 0.0
    _, cov_next = propagate(
        x, no_bias, is_position, np.zeros((3, d)), visible, rate, dt, NOISE, d, "exact"
    )
    np.testing.assert_allclose(cov_next, jac @ no_bias @ jac.T + q, atol=1e-8)
    # the bias column Gamma M(f_hat) is the linearised-system flow: first order in Ts
    _, cov_next = propagate(
        x, cov, is_position, np.zeros((3, d)), visible, rate, dt, NOISE, d, "exact"
    )
    np.testing.assert_allclose(cov_next, jac @ cov @ jac.T + q, atol=5 * dt**2 * np.abs(cov).max())


def test_exact_rotation_flow_has_no_euler_dilation() -> None:
    """One 0.1 s step at 0.4 rad/s: Euler dilates a 10 m landmark by (omega Ts)^2/2 * 10 m =
    8 mm; the exact flow keeps its range to round-off."""
    p = np.array([10.0, 0.0])
    x = np.concatenate([np.zeros(3), p])
    cov = np.eye(5) * 1e-4
    rate = np.array([0.4])
    hidden = np.array([False])
    euler, _ = propagate(
        x, cov, np.array([True]), np.zeros((1, 2)), hidden, rate, 0.1, NOISE, 2, "euler"
    )
    exact, _ = propagate(
        x, cov, np.array([True]), np.zeros((1, 2)), hidden, rate, 0.1, NOISE, 2, "exact"
    )
    assert np.linalg.norm(euler[3:]) - 10.0 == pytest.approx(10.0 * 0.04**2 / 2, rel=1e-3)
    assert abs(np.linalg.norm(exact[3:]) - 10.0) < 1e-12


def test_euler_converges_to_the_exact_rotation_for_small_steps() -> None:
    # A landmark under pure rotation: many small Euler steps approach expm(-S(w) T) p.
    p = np.array([2.0, 1.0])
    x = np.concatenate([np.zeros(3), p])
    cov = np.eye(5) * 1e-4
    rate = np.array([0.4])
    for _ in range(1000):
        x, cov = propagate(
            x, cov, np.array([True]), np.zeros((1, 2)), np.array([False]), rate, 1e-3, NOISE, 2
        )
    assert np.allclose(x[3:], expm(-skew_rate(rate, 2) * 1.0) @ p, atol=1e-3)


def test_gyro_noise_enters_every_landmark_fully_correlated() -> None:
    features = np.array([[1.0, 0.0], [0.0, 2.0]])
    q = process_covariance(features, np.array([True, True]), NOISE, 0.1, 2)
    block = q[3:, 3:] - np.diag(np.full(4, 0.1 * NOISE.landmark_m**2))
    g = np.array([0.0, 1.0, -2.0, 0.0])  # S p for each landmark
    assert np.allclose(block, 0.1 * NOISE.gyro_noise_density**2 * np.outer(g, g))


@dataclass(frozen=True)
class UpdateResult:
    """Per-landmark NIS and dof, as the test has always read them."""

    nis: np.ndarray
    dof: np.ndarray


def test_kalman_update_matches_textbook_joseph_form() -> None:
    rng = np.random.default_rng(4)
    n = 9
    a = rng.normal(size=(n, n))
    cov = a @ a.T + np.eye(n)
    x = rng.normal(size=n)
    indices = np.array([5, 6, 7, 8])
    h = np.zeros((4, n))
    h[np.arange(4), indices] = 1.0
    r = np.diag([0.1, 0.2, 0.3, 0.4])
    z = rng.normal(size=4)
    cov_post = cov.copy()
    x_post, outcome = selection_update(
        x, cov_post, indices, z, r, [np.array([0, 1]), np.array([2, 3])]
    )
    result = UpdateResult(outcome.innovation.group_nis, outcome.innovation.group_dof)
    s = h @ cov @ h.T + r
    k = cov @ h.T @ np.linalg.inv(s)
    joseph = (np.eye(n) - k @ h) @ cov @ (np.eye(n) - k @ h).T + k @ r @ k.T
    assert np.allclose(x_post, x + k @ (z - h @ x))
    assert np.allclose(cov_post, joseph)
    nu = z - x[indices]
    assert result.nis[0] == pytest.approx(nu[:2] @ np.linalg.solve(s[:2, :2], nu[:2]))
    assert list(result.dof) == [2, 2]


@pytest.mark.parametrize("d", [2, 3])
@pytest.mark.parametrize("scale", [0.0, 1e-7, 1e-3, 0.4, 3.0])
def test_closed_form_rotation_flow_matches_van_loan_expm(d: int, scale: float) -> None:
    from filters.sensor_based.dynamics import rotation_flow

    rng = np.random.default_rng(int(scale * 1e3) + d)
    generator = -skew_rate(rng.normal(size=1 if d == 2 else 3) * scale, d)
    dt = 0.1
    block = np.zeros((2 * d, 2 * d))
    block[:d, :d] = generator
    block[:d, d:] = np.eye(d)
    reference = expm(block * dt)
    exponential, integral = rotation_flow(generator, dt)
    np.testing.assert_allclose(exponential, reference[:d, :d], atol=1e-14)
    np.testing.assert_allclose(integral, reference[:d, d:], atol=1e-14)


@pytest.mark.parametrize("d", [2, 3])
def test_tiled_in_place_prediction_over_many_tiles_is_exact_and_exactly_symmetric(d: int) -> None:
    """150 landmarks span three tiles of ``TILE_BLOCKS`` (the last one partial): the tiled
    product equals the dense ``expm(A Ts) P expm(A Ts)^T + Q`` and is symmetric to the bit."""
    from filters.sensor_based.dynamics import TILE_BLOCKS

    count = 150
    assert count > 2 * TILE_BLOCKS and count % TILE_BLOCKS
    rng = np.random.default_rng(7)
    x, cov, is_position = _random_state(rng, d, count)
    r = 1 if d == 2 else 3
    measured = rng.normal(size=(count, d))
    rate = rng.normal(size=r)
    dt = 0.05
    x_next, cov_next = propagate(
        x, cov, is_position, measured, np.ones(count, dtype=bool), rate, dt, NOISE, d, "exact"
    )
    f = expm(_dense_ltv_matrix(x.size, measured, is_position, rate, d) * dt)
    q = process_covariance(x[d + r :].reshape(count, d), is_position, NOISE, dt, d)
    np.testing.assert_allclose(x_next, f @ x, atol=1e-12)
    np.testing.assert_allclose(cov_next, f @ cov @ f.T + q, atol=1e-11)
    assert np.array_equal(cov_next, cov_next.T)
