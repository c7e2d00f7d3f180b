"""Discrete process noise (Aghili eq. (36)): closed form vs Van Loan vs brute-force quadrature,
and where the printed eq. (37) agrees and where it does not."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad_vec
from scipy.linalg import expm

from datasets.rotations import skew, so3_exp
from filters.aghili.process_noise import (
    lambda_product_integral,
    noise_covariance,
    paper_printed_blocks,
    process_noise_van_loan,
    vehicle_process_noise,
)
from filters.aghili.transition import error_dynamics, lambda_matrix

# KITTI-like continuous densities, inflated so every block is well above round-off
DENSITIES = (0.01, 0.002, 0.05, 0.01)


def inputs(seed: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    return np.array([0.2, -0.1, 9.81]) + rng.normal(size=3), so3_exp(rng.normal(size=3))


def relative_block_errors(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Max relative error per 3x3 block of ``a`` against ``b``. A block that is exactly zero in
    ``a`` (zero analytically) passes when ``b`` has only round-off there (< 1e-14 of b's
    largest entry): Van Loan and quadrature leave ~1e-21 where the closed form has 0."""
    errors = np.zeros((5, 5))
    roundoff = 1e-14 * np.abs(b).max()
    for i in range(5):
        for j in range(5):
            block_a, block_b = (
                a[3 * i : 3 * i + 3, 3 * j : 3 * j + 3],
                b[3 * i : 3 * i + 3, 3 * j : 3 * j + 3],
            )
            if not np.any(block_a):
                errors[i, j] = 0.0 if np.abs(block_b).max() < roundoff else np.inf
                continue
            errors[i, j] = np.abs(block_a - block_b).max() / np.abs(block_b).max()
    return errors


@pytest.mark.parametrize(
    ("omega", "tau"),
    [
        (np.zeros(3), 0.05),
        (np.array([1e-8, 0.0, -1e-8]), 0.05),
        (np.array([0.05, -0.3, 0.2]), 0.05),
        (np.array([1.5, -0.5, 2.0]), 0.5),
        (np.array([6.0, 0.0, 8.0]), 0.5),  # beyond the series range: Van Loan fallback
    ],
)
def test_closed_form_matches_van_loan_block_by_block(omega: np.ndarray, tau: float) -> None:
    a_bar, attitude = inputs(3)
    F, G = error_dynamics(omega, a_bar, attitude)
    reference = process_noise_van_loan(F, G, noise_covariance(*DENSITIES), tau)
    closed = vehicle_process_noise(omega, a_bar, attitude, tau, *DENSITIES)
    assert relative_block_errors(closed, reference).max() < 1e-10
    np.testing.assert_allclose(closed, closed.T, atol=0)
    assert np.linalg.eigvalsh(closed).min() > -1e-18


def test_van_loan_matches_brute_force_quadrature() -> None:
    """The independent reference: integrate expm(F s) G S G^T expm(F s)^T numerically."""
    omega, tau = np.array([0.4, -0.8, 0.3]), 0.2
    a_bar, attitude = inputs(4)
    F, G = error_dynamics(omega, a_bar, attitude, landmark_count=1)
    sigma = noise_covariance(*DENSITIES)
    integrand = lambda s: expm(F * s) @ G @ sigma @ G.T @ expm(F * s).T  # noqa: E731
    quadrature, _ = quad_vec(integrand, 0.0, tau, epsabs=1e-16, epsrel=1e-12)
    van_loan = process_noise_van_loan(F, G, sigma, tau)
    vehicle = van_loan[:15, :15]
    vehicle = np.where(
        np.abs(vehicle) < 1e-15 * np.abs(vehicle).max(), 0.0, vehicle
    )  # drop round-off
    assert relative_block_errors(vehicle, quadrature[:15, :15]).max() < 1e-8
    np.testing.assert_allclose(van_loan[15:, :], 0.0, atol=0)  # landmarks get no process noise


def test_printed_G_feeding_accel_noise_into_the_bias_is_a_different_model() -> None:
    omega, tau = np.array([0.1, 0.0, 0.0]), 0.05
    a_bar, attitude = inputs(5)
    F, G = error_dynamics(omega, a_bar, attitude)
    printed_G = G.copy()
    printed_G[12:15, 9:12] = 0.0
    printed_G[12:15, 6:9] = np.eye(3)  # eq. (21b) as printed: eps_a drives b_a
    sigma = noise_covariance(*DENSITIES)
    good = process_noise_van_loan(F, G, sigma, tau)
    bad = process_noise_van_loan(F, printed_G, sigma, tau)
    np.testing.assert_allclose(good[12:15, 12:15], DENSITIES[3] ** 2 * tau * np.eye(3), rtol=1e-9)
    assert not np.allclose(bad[12:15, 12:15], good[12:15, 12:15], rtol=0.1)


def test_lambda_product_integral_matches_quadrature() -> None:
    omega, tau = np.array([0.9, -0.4, 0.6]), 0.6
    for i, j in [(1, 1), (2, 3), (4, 2), (4, 4)]:
        integral, _ = quad_vec(
            lambda s: lambda_matrix(i, omega, s) @ lambda_matrix(j, omega, s).T,
            0.0,
            tau,
            epsabs=1e-16,
        )
        np.testing.assert_allclose(lambda_product_integral(i, j, omega, tau), integral, atol=1e-13)


def test_printed_q11_is_right_to_its_order_other_printed_blocks_are_not() -> None:
    """Eq. (37): Q'_11 agrees with the exact block up to the third-order terms it drops; the
    gyro-bias/attitude block misses its first-order W term; the position block misses the
    sigma_g and sigma_ba contributions."""
    omega, tau = np.array([0.02, -0.03, 0.01]), 0.05
    a_bar, attitude = inputs(6)
    exact = vehicle_process_noise(omega, a_bar, attitude, tau, *DENSITIES)
    printed = paper_printed_blocks(omega, tau, DENSITIES[0], DENSITIES[1], DENSITIES[2])
    assert (
        np.abs(printed["attitude"] - exact[0:3, 0:3]).max() / np.abs(exact[0:3, 0:3]).max() < 1e-9
    )
    bias_attitude = exact[9:12, 0:3]
    missing_first_order = DENSITIES[1] ** 2 * tau**3 / 12.0 * skew(omega)
    np.testing.assert_allclose(
        printed["gyro_bias_attitude"] + missing_first_order,
        bias_attitude,
        atol=1e-3 * np.abs(missing_first_order).max(),
    )
    assert (
        np.abs(printed["gyro_bias_attitude"] - bias_attitude).max()
        > 0.5 * np.abs(missing_first_order).max()
    )
    # position: sigma_a^2 t^3/3 is only the accelerometer part (gyro and accel-bias parts missing)
    assert (
        np.abs(printed["position"] - exact[3:6, 3:6]).max() > 1e-4 * np.abs(exact[3:6, 3:6]).max()
    )
    # the position-velocity block, printed as zero, is sigma_a^2 t^2/2 to leading order: a
    # correlation of sqrt(3)/2 between position and velocity noise
    correlation = exact[3, 6] / np.sqrt(exact[3, 3] * exact[6, 6])
    assert abs(correlation - np.sqrt(3) / 2) < 0.01
