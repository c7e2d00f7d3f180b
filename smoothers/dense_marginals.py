"""Joint marginals from a dense QR of the whole linearised graph: the fallback of the batch
smoother when ``gtsam.Marginals`` (Cholesky on the information matrix) fails.

GTSAM's C++ ``Marginals`` takes a ``Factorization::QR`` argument, but the Python wrapper of
GTSAM 4.3 exposes only the Cholesky constructor. QR works on the whitened Jacobian ``A``
itself (``A = Q R``, covariance ``(R^T R)^-1 = R^-1 R^-T``) instead of ``A^T A``, so it
survives the squared condition number that makes Cholesky fail (a nearly noise-free
factor beside ordinary ones). Dense, O(n^3) in the number of variables: used only after
Cholesky has failed, and said so in the run's events and notes.
"""

from __future__ import annotations

from collections.abc import Sequence

import gtsam
import numpy as np
from scipy.linalg import qr, solve_triangular


class _DenseJoint:
    """The slice of a dense covariance over some keys, with ``gtsam.JointMarginal``'s two
    accessors that ``smoothers.joint_marginals.JointMarginals`` uses."""

    def __init__(self, full: np.ndarray, rows: dict[int, np.ndarray]) -> None:
        self._full = full
        self._rows = rows

    def fullMatrix(self) -> np.ndarray:  # noqa: N802 - GTSAM's name
        return self._full

    def at(self, first: int, second: int) -> np.ndarray:
        return self._full[np.ix_(self._rows[int(first)], self._rows[int(second)])]


class DenseQrMarginals:
    """``jointMarginalCovariance`` and ``marginalCovariance`` of every key of ``values``
    from a dense QR of ``graph`` linearised at ``values``."""

    def __init__(self, graph: gtsam.NonlinearFactorGraph, values: gtsam.Values) -> None:
        keys = sorted(int(key) for key in values.keys())
        linear = graph.linearize(values)
        jacobian, _ = linear.jacobian(gtsam.Ordering(keys))
        zero = values.zeroVectors()
        sizes = [int(np.asarray(zero.at(key)).size) for key in keys]
        ends = np.cumsum(sizes)
        self._columns = {
            key: np.arange(end - size, end)
            for key, size, end in zip(keys, sizes, ends, strict=True)
        }
        n = int(ends[-1]) if sizes else 0
        if jacobian.shape[0] < n:
            raise RuntimeError(
                f"dense QR marginals: {jacobian.shape[0]} rows for {n} unknowns (under-determined)"
            )
        (triangular,) = qr(jacobian, mode="r", check_finite=False)
        triangular = triangular[:n, :n]
        if np.any(np.abs(np.diagonal(triangular)) <= 1e-300):
            raise RuntimeError("dense QR marginals: the linearised system is singular")
        inverse = solve_triangular(triangular, np.eye(n), lower=False, check_finite=False)
        self._covariance = inverse @ inverse.T

    def jointMarginalCovariance(self, keys: Sequence[int]) -> _DenseJoint:  # noqa: N802
        ordered = [int(key) for key in keys]
        rows: dict[int, np.ndarray] = {}
        columns = []
        start = 0
        for key in ordered:
            own = self._columns[key]
            rows[key] = np.arange(start, start + own.size)
            columns.append(own)
            start += own.size
        index = np.concatenate(columns) if columns else np.zeros(0, dtype=int)
        return _DenseJoint(self._covariance[np.ix_(index, index)], rows)

    def marginalCovariance(self, key: int) -> np.ndarray:  # noqa: N802 - GTSAM's name
        own = self._columns[int(key)]
        return self._covariance[np.ix_(own, own)]
