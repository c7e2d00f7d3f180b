"""Eq. (42) sliding-window R: the posterior-residual form against the algebraic identity and
a Monte Carlo of a linear Gaussian update; the prior form as printed; ring-buffer bookkeeping."""

from __future__ import annotations

import numpy as np
import pytest

from filters.aghili.adaptive_noise import SlidingWindowNoise


def _linear_problem(seed: int):
    rng = np.random.default_rng(seed)
    L = rng.normal(size=(6, 6)) * 0.1
    P = L @ L.T + 1e-3 * np.eye(6)
    H = rng.normal(size=(3, 6))
    M = rng.normal(size=(3, 3)) * 0.2
    R = M @ M.T + 0.01 * np.eye(3)
    return rng, P, H, R


def test_posterior_residual_identity_holds_for_a_consistent_filter() -> None:
    """E[e e^T] + H P+ H^T = R exactly when S is right: R S^-1 S S^-1 R + H (P - K H P) H^T."""
    _, P, H, R = _linear_problem(0)
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    posterior_P = P - K @ H @ P
    residual_map = np.eye(3) - H @ K  # e = (I - H K) rho
    covariance_of_e = residual_map @ S @ residual_map.T
    np.testing.assert_allclose(covariance_of_e + H @ posterior_P @ H.T, R, atol=1e-12)


@pytest.mark.parametrize("residual", ["posterior", "prior"])
def test_window_recovers_r_from_simulated_updates_of_a_consistent_filter(residual: str) -> None:
    rng, P, H, R = _linear_problem(1)
    S = H @ P @ H.T + R
    K = P @ H.T @ np.linalg.inv(S)
    window = SlidingWindowNoise(4000, 1e-4, residual=residual)
    for _ in range(4000):
        error = rng.multivariate_normal(np.zeros(6), P)
        innovation = H @ error + rng.multivariate_normal(np.zeros(3), R)
        if residual == "prior":
            window.add(innovation[None], (H @ P @ H.T)[None])
        else:
            posterior_residual = innovation - H @ (K @ innovation)
            window.add(posterior_residual[None], (H @ (P - K @ H @ P) @ H.T)[None])
    np.testing.assert_allclose(window.estimate(), R, atol=0.08 * np.abs(R).max())


def test_inflated_prior_covariance_drives_the_prior_form_to_its_floor_but_not_the_posterior_form() -> (
    None
):
    """The failure the posterior form fixes: the filter believes P is 10x what it is and R is
    10x too large. The prior form W - H P- H^T goes negative (clipped to the floor); the
    posterior form stays between the truth and the filter's R (fails safe)."""
    rng, P, H, R = _linear_problem(2)
    filter_P, filter_R = 10.0 * P, 10.0 * R
    S = H @ filter_P @ H.T + filter_R
    K = filter_P @ H.T @ np.linalg.inv(S)
    floor_sigma = 1e-3
    prior = SlidingWindowNoise(3000, floor_sigma, residual="prior")
    posterior = SlidingWindowNoise(3000, floor_sigma, residual="posterior")
    for _ in range(3000):
        innovation = H @ rng.multivariate_normal(np.zeros(6), P) + rng.multivariate_normal(
            np.zeros(3), R
        )
        prior.add(innovation[None], (H @ filter_P @ H.T)[None])
        posterior.add(
            (innovation - H @ K @ innovation)[None], (H @ (filter_P - K @ H @ filter_P) @ H.T)[None]
        )
    assert np.linalg.eigvalsh(prior.estimate()).min() == pytest.approx(floor_sigma**2)
    true_trace, estimated_trace = np.trace(R), np.trace(posterior.estimate())
    assert true_trace < estimated_trace < np.trace(filter_R)


def test_ring_buffer_matches_a_plain_mean_of_the_last_w_samples() -> None:
    rng = np.random.default_rng(3)
    window = SlidingWindowNoise(7, 1e-6, min_samples=3, residual="prior")
    residuals = rng.normal(size=(40, 3))
    blocks = np.einsum("k,ij->kij", rng.uniform(0.0, 0.1, 40), np.eye(3))
    assert not window.ready
    for start in range(0, 40, 3):  # uneven batches wrap the ring
        window.add(residuals[start : start + 3], blocks[start : start + 3])
    assert window.ready and len(window) == 7
    last = residuals[-7:]
    expected = last.T @ last / 7 - blocks[-7:].mean(axis=0)
    values, vectors = np.linalg.eigh(expected)
    np.testing.assert_allclose(
        window.estimate(), (vectors * np.maximum(values, 1e-12)) @ vectors.T, atol=1e-12
    )
