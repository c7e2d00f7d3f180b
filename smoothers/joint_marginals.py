"""Marginal covariances from one batched query: ``JointMarginals``.

Every covariance the smoothers report or use comes from a *joint* marginal query over all
the keys a step needs (a keyframe's states, the pose and the landmarks a scan may see, the
keys leaving the fixed-lag window, the whole map at the end), never from one
``marginalCovariance(key)`` call per key: each such call eliminates its own piece of the
Bayes tree again (measured on a 200-landmark map: 0.4 s for one landmark's marginal, 0.9 s
for the joint of all 170; a finish of 22-40 s key by key against 2.1 s batched, equal to
3e-17).

Keys are queried in increasing order, so GTSAM's full matrix of the joint is in that order
whether GTSAM keeps the order given or sorts the keys (its documentation promises neither);
blocks are then sliced from that one matrix, not fetched by one ``at(a, b)`` call per pair
(``tests/test_smoother_marginals.py`` checks both against per-key queries).
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import gtsam
import numpy as np


class JointMarginals:
    """The joint marginal covariance of a set of keys; also a
    ``smoothers.covariances.MarginalSource`` for any of those keys.

    Attributes:
        keys: the keys it covers, increasing.
    """

    def __init__(self, joint: gtsam.JointMarginal, keys: Sequence[int]) -> None:
        self.keys = sorted(set(int(key) for key in keys))
        self._full = np.asarray(joint.fullMatrix(), dtype=float)
        sizes = [np.asarray(joint.at(key, key)).shape[0] for key in self.keys]
        ends = np.cumsum(sizes)
        self._rows = {
            key: np.arange(end - size, end)
            for key, size, end in zip(self.keys, sizes, ends, strict=True)
        }
        total = int(ends[-1]) if sizes else 0
        if self._full.shape != (total, total):
            raise ValueError(f"joint marginal of shape {self._full.shape} for sizes {sizes}")

    @classmethod
    def query(cls, source, keys: Sequence[int]) -> JointMarginals:
        """One ``jointMarginalCovariance`` call of ``source`` (``ISAM2`` or ``gtsam.Marginals``)
        over ``keys`` (duplicates ignored). GTSAM's ``RuntimeError`` propagates."""
        ordered = sorted(set(int(key) for key in keys))
        return cls(source.jointMarginalCovariance(ordered), ordered)

    def covers(self, keys: Sequence[int]) -> bool:
        return all(int(key) in self._rows for key in keys)

    def marginalCovariance(self, key: int) -> np.ndarray:  # noqa: N802 - GTSAM's name
        rows = self._rows[int(key)]
        return self._full[np.ix_(rows, rows)]

    def matrix(self, keys: Sequence[int] | None = None) -> np.ndarray:
        """The joint covariance of ``keys`` (default: all), blocks in that order,
        (sum of the keys' dimensions, same)."""
        chosen = self.keys if keys is None else keys
        rows = np.concatenate([self._rows[int(key)] for key in chosen]) if len(chosen) else []
        return self._full[np.ix_(rows, rows)]


JointQuery = Callable[[Sequence[int]], JointMarginals]
"""keys -> their ``JointMarginals`` (a backend's or a batch solution's batched query)."""
