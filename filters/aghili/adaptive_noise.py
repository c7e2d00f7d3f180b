"""Noise-adaptive measurement covariance (Aghili section 4.4, eq. (42)).

The residual ``rho_k = z_k - h(x_k^-)`` has covariance ``W = H P^- H^T + R``, so
``R = W - H P^- H^T`` with W estimated over a sliding window of w residuals (eq. (42a),
updated recursively as in eq. (42b)).

Choices the paper leaves open (documented here):
- one 3 x 3 R is shared by all landmarks (each landmark residual is one sample), so the
  window counts landmark residuals, not scans;
- ``H P^- H^T`` is averaged over the same window as W (the paper subtracts the current one
  only; averaging both keeps the estimate unbiased when P changes within the window);
- kept positive definite: the estimate is symmetrised and its eigenvalues are clipped
  below at ``min_sigma_m^2``. W - H P H^T can be indefinite when the window is short or the
  filter is overconfident; clipping keeps the gain well-defined without pretending a
  sensor is noiseless.
- until ``min_samples`` residuals are in the window the initial R is used.
"""

from __future__ import annotations

from collections import deque

import numpy as np


class SlidingWindowNoise:
    """Eq. (42): sliding-window estimate of the 3 x 3 landmark measurement covariance [m^2].

    Args:
        window: w, number of landmark residuals averaged.
        min_sigma_m: floor on the std along any axis [m] (keeps R positive definite).
        min_samples: residuals needed before the estimate replaces the initial R.
    """

    def __init__(self, window: int, min_sigma_m: float, min_samples: int | None = None) -> None:
        if window < 1:
            raise ValueError(f"adaptive window must be >= 1, got {window}")
        self.window = int(window)
        self.min_variance = float(min_sigma_m) ** 2
        self.min_samples = self.window if min_samples is None else int(min_samples)
        self._outer: deque[np.ndarray] = deque()
        self._predicted: deque[np.ndarray] = deque()
        self._sum_outer = np.zeros((3, 3))
        self._sum_predicted = np.zeros((3, 3))
        self._pushes = 0

    def __len__(self) -> int:
        return len(self._outer)

    def add(self, residuals: np.ndarray, predicted_covariances: np.ndarray) -> None:
        """Eq. (42b): push residuals (k, 3) [m] and their ``H P^- H^T`` blocks (k, 3, 3)."""
        for residual, predicted in zip(np.asarray(residuals, float), np.asarray(predicted_covariances, float)):
            outer = np.outer(residual, residual)
            self._outer.append(outer)
            self._predicted.append(predicted)
            self._sum_outer += outer
            self._sum_predicted += predicted
            if len(self._outer) > self.window:
                self._sum_outer -= self._outer.popleft()
                self._sum_predicted -= self._predicted.popleft()
            self._pushes += 1
            if self._pushes % (16 * self.window) == 0:
                # recompute the running sums now and then: no drift from round-off
                self._sum_outer = np.sum(self._outer, axis=0)
                self._sum_predicted = np.sum(self._predicted, axis=0)

    @property
    def ready(self) -> bool:
        return len(self._outer) >= self.min_samples

    def estimate(self) -> np.ndarray:
        """Eq. (42): ``R = W - mean(H P^- H^T)`` (3, 3), symmetric with eigenvalues >= floor."""
        count = max(len(self._outer), 1)
        r = (self._sum_outer - self._sum_predicted) / count
        r = 0.5 * (r + r.T)
        values, vectors = np.linalg.eigh(r)
        values = np.maximum(values, self.min_variance)
        return (vectors * values) @ vectors.T
