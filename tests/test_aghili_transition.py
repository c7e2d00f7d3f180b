"""Closed-form transition matrix (Aghili eq. (35), corrected) against expm(F tau)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import quad_vec
from scipy.linalg import expm

from datasets.rotations import skew, so3_exp
from filters.aghili.transition import (
    VEHICLE_DIM,
    error_dynamics,
    lambda_matrices,
    lambda_matrix,
    paper_printed_vehicle_transition,
    series_coefficient,
    vehicle_transition,
)

CASES = [
    (np.array([0.0, 0.0, 0.0]), 0.05),
    (np.array([1e-9, -2e-9, 3e-9]), 0.05),
    (np.array([0.05, -0.3, 0.2]), 0.05),
    (np.array([1.2, 0.4, -2.0]), 0.1),
    (np.array([3.0, -4.0, 2.0]), 0.5),  # |omega| tau > 2: the closed forms, not the series
]


def case_inputs(omega: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(int(1e3 * np.linalg.norm(omega)) + 7)
    a_bar = np.array([0.3, -0.4, 9.81]) + rng.normal(size=3)
    attitude = so3_exp(rng.normal(size=3))
    return a_bar, attitude


@pytest.mark.parametrize(("omega", "tau"), CASES)
def test_closed_form_transition_matches_expm(omega: np.ndarray, tau: float) -> None:
    a_bar, attitude = case_inputs(omega)
    F, _ = error_dynamics(omega, a_bar, attitude)
    np.testing.assert_allclose(
        vehicle_transition(omega, a_bar, attitude, tau), expm(F * tau), rtol=0, atol=1e-10
    )


def test_landmark_block_of_phi_is_identity() -> None:
    omega = np.array([0.1, 0.2, 0.3])
    a_bar, attitude = case_inputs(omega)
    F, G = error_dynamics(omega, a_bar, attitude, landmark_count=4)
    phi = expm(F * 0.1)
    assert F.shape == (27, 27) and G.shape == (27, 12)
    np.testing.assert_allclose(
        phi[:VEHICLE_DIM, :VEHICLE_DIM], vehicle_transition(omega, a_bar, attitude, 0.1), atol=1e-10
    )
    np.testing.assert_allclose(phi[VEHICLE_DIM:, VEHICLE_DIM:], np.eye(12), atol=0)
    np.testing.assert_allclose(phi[VEHICLE_DIM:, :VEHICLE_DIM], 0.0, atol=0)


def test_lambdas_are_successive_integrals() -> None:
    omega, tau = np.array([0.7, -0.2, 1.1]), 0.8
    lambdas = lambda_matrices(omega, tau, 5)
    np.testing.assert_allclose(lambdas[0], expm(-skew(omega) * tau), atol=1e-12)
    for n in range(1, 5):
        integral, _ = quad_vec(lambda s: lambda_matrix(n, omega, s), 0.0, tau, epsabs=1e-14)
        np.testing.assert_allclose(lambdas[n], integral, atol=1e-12)
        np.testing.assert_allclose(lambdas[n], lambda_matrix(n + 1, omega, tau), atol=1e-15)


@pytest.mark.parametrize("order", [1, 2, 3, 4, 5, 6])
def test_series_and_closed_form_coefficients_agree_at_the_switch(order: int) -> None:
    below, above = series_coefficient(order, 2.0 - 1e-12), series_coefficient(order, 2.0 + 1e-12)
    assert abs(below - above) < 1e-12


def test_printed_transition_is_wrong() -> None:
    """Eq. (35) as printed: velocity-attitude block lacks the factor 2 and the velocity-gyro
    bias block is L3/2 instead of -M L3 (so the printed matrix is not expm(F tau))."""
    omega, tau = np.array([0.1, -0.2, 0.3]), 0.05
    a_bar, attitude = case_inputs(omega)
    F, _ = error_dynamics(omega, a_bar, attitude)
    exact = expm(F * tau)
    printed = paper_printed_vehicle_transition(omega, a_bar, attitude, tau)
    np.testing.assert_allclose(
        2.0 * printed[6:9, 0:3], exact[6:9, 0:3], atol=1e-12
    )  # factor 2 missing
    assert np.abs(printed[6:9, 9:12] - exact[6:9, 9:12]).max() > 1e-4
    assert (
        np.abs(printed[3:6, 0:3] - exact[3:6, 0:3]).max() > 1e-3
    )  # position-attitude block missing
