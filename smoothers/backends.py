"""Incremental solvers behind the smoother: iSAM2, and GTSAM's fixed-lag smoother.

Both take (new factors, new values, key times) per keyframe and answer estimates and
marginal covariances. GTSAM errors during an update (an indeterminate system, a missing
variable) become ``InputError`` naming the time, never an opaque GTSAM traceback.

Fixed lag: gtsam 4.3's wheel exposes both ``gtsam.BatchFixedLagSmoother`` and
``gtsam.IncrementalFixedLagSmoother``; only the incremental one offers
``marginalCovariance``, which the causal covariances need, so it is the one used. It
marginalises the keys whose time is strictly earlier than ``latest time - lag``
(checked in ``tests/test_smoother_modes.py``).
"""

from __future__ import annotations

import time

import gtsam
import numpy as np

from datasets.errors import InputError


def _explain(error: RuntimeError, t: float, context: str) -> InputError:
    text = str(error).strip().splitlines()
    first = text[0] if text else type(error).__name__
    if "ndeterminant" in str(error) or "ndeterminate" in str(error):
        return InputError(
            f"{context} at t={t:.6f} s: the system is indeterminate (some state is not constrained: "
            f"no prior, anchors, GPS or enough landmarks reach it) -- GTSAM: {first}"
        )
    return InputError(f"{context} at t={t:.6f} s failed inside GTSAM: {first}")


BIAS_RELINEARIZE_THRESHOLD = 1.0
"""Relinearisation threshold of bias variables (per tangent component): the preintegrated
IMU factor is corrected to first order in the bias, so bias linearisation points may lag.

Measured on kitti-imu-gps (keyframe every 10 IMU samples, loaded machine): iSAM2's update
cost grows along the run (first 150 s, mean per fifth: 1.6, 6.9, 15.8, 17.7, 29.5 ms) with
the pose/velocity threshold at 0.05, 0.1 or 0.2 and with ``relinearize_skip`` 10 alike, and
stays flat (0.3 to 1.2 ms over 100 s) with relinearisation disabled: fluid relinearisation
keeps reaching far back into the history on that GPS-only graph. Not solved here."""


def fetch_values(source, keys: list[int], dimension: int) -> gtsam.Values:
    """The current estimate of ``keys`` only, by typed ``calculateEstimate*`` calls chosen by
    the key's symbol (x pose, v velocity/planar state, b bias, l landmark). iSAM2 still
    brings its whole delta up to date on the first call (measured: about the cost of
    ``calculateEstimate()`` on Victoria Park); the saving is the copy of every variable."""
    values = gtsam.Values()
    for key in keys:
        kind = chr(gtsam.Symbol(key).chr())
        if kind == "x":
            values.insert(
                key,
                source.calculateEstimatePose3(key)
                if dimension == 3
                else source.calculateEstimatePose2(key),
            )
        elif kind == "v":
            values.insert(key, np.asarray(source.calculateEstimateVector(key), dtype=float))
        elif kind == "b":
            values.insert(key, source.calculateEstimateConstantBias(key))
        elif kind == "l":
            point = (
                source.calculateEstimatePoint3(key)
                if dimension == 3
                else source.calculateEstimatePoint2(key)
            )
            values.insert(key, np.asarray(point, dtype=float))
        else:
            raise ValueError(f"unknown variable kind {kind!r}")
    return values


def isam2_params(
    relinearize_threshold: float, relinearize_skip: int, dimension: int = 3
) -> gtsam.ISAM2Params:
    """iSAM2 parameters: QR factorisation (Cholesky fails on the KITTI IMU's tiny bias walk,
    an information ratio of about 1e12), a threshold per variable type."""
    params = gtsam.ISAM2Params()
    thresholds = gtsam.ISAM2ThresholdMap()
    pose_dof = 6 if dimension == 3 else 3
    thresholds.insert(("x", np.full(pose_dof, relinearize_threshold)))
    thresholds.insert(("v", np.full(3 if dimension == 3 else 3, relinearize_threshold)))
    thresholds.insert(("b", np.full(6, BIAS_RELINEARIZE_THRESHOLD)))
    thresholds.insert(("l", np.full(dimension, relinearize_threshold)))
    params.setRelinearizeThreshold(thresholds)
    params.relinearizeSkip = relinearize_skip
    params.setFactorization("QR")
    return params


class Isam2Backend:
    """iSAM2 over the whole history."""

    def __init__(
        self,
        relinearize_threshold: float,
        relinearize_skip: int,
        extra_iterations: int,
        dimension: int = 3,
    ) -> None:
        self.isam = gtsam.ISAM2(isam2_params(relinearize_threshold, relinearize_skip, dimension))
        self.dimension = dimension
        self.extra_iterations = extra_iterations
        self.gtsam_seconds = 0.0

    def update(
        self,
        graph: gtsam.NonlinearFactorGraph,
        values: gtsam.Values,
        key_times: dict[int, float],
        t: float,
    ) -> float:
        """Add factors and values; returns the seconds spent inside GTSAM."""
        start = time.perf_counter()
        try:
            self.isam.update(graph, values)
            for _ in range(self.extra_iterations):
                self.isam.update()
        except RuntimeError as error:
            raise _explain(error, t, "iSAM2 update") from None
        elapsed = time.perf_counter() - start
        self.gtsam_seconds += elapsed
        return elapsed

    def estimate(self) -> gtsam.Values:
        return self.isam.calculateEstimate()

    def values(self, keys: list[int]) -> gtsam.Values:
        return fetch_values(self.isam, keys, self.dimension)

    def marginal_covariance(self, key: int) -> np.ndarray:
        try:
            return self.isam.marginalCovariance(key)
        except RuntimeError as error:
            raise _explain(
                error,
                float("nan"),
                f"iSAM2 marginal covariance of {gtsam.DefaultKeyFormatter(key)}",
            ) from None

    def joint_marginal_covariance(self, keys: list[int]) -> np.ndarray:
        """Full joint marginal covariance of ``keys``, blocks in the given order."""
        try:
            joint = self.isam.jointMarginalCovariance(keys)
        except RuntimeError as error:
            raise _explain(error, float("nan"), "iSAM2 joint marginal covariance") from None
        rows = [np.hstack([joint.at(a, b) for b in keys]) for a in keys]
        return np.vstack(rows)

    def leaving(self, t_new: float) -> list[int]:
        """Keys about to be marginalised by an update at ``t_new``: none for iSAM2."""
        return []

    def contains(self, key: int) -> bool:
        return self.isam.valueExists(key)


class FixedLagBackend:
    """``gtsam.IncrementalFixedLagSmoother`` with a lag in seconds."""

    def __init__(
        self, lag_s: float, relinearize_threshold: float, relinearize_skip: int, dimension: int = 3
    ) -> None:
        self.lag_s = lag_s
        self.dimension = dimension
        self.smoother = gtsam.IncrementalFixedLagSmoother(
            lag_s, isam2_params(relinearize_threshold, relinearize_skip, dimension)
        )
        self.key_times: dict[int, float] = {}
        self.gtsam_seconds = 0.0

    def update(
        self,
        graph: gtsam.NonlinearFactorGraph,
        values: gtsam.Values,
        key_times: dict[int, float],
        t: float,
    ) -> float:
        stamps = gtsam.FixedLagSmootherKeyTimestampMap()
        for key, stamp in key_times.items():
            stamps.insert((key, stamp))
        start = time.perf_counter()
        try:
            self.smoother.update(graph, values, stamps)
        except RuntimeError as error:
            raise _explain(error, t, "fixed-lag update") from None
        elapsed = time.perf_counter() - start
        self.gtsam_seconds += elapsed
        self.key_times.update(key_times)
        latest = max(self.key_times.values(), default=t)
        for key in [key for key, stamp in self.key_times.items() if stamp < latest - self.lag_s]:
            del self.key_times[key]
        return elapsed

    def estimate(self) -> gtsam.Values:
        return self.smoother.calculateEstimate()

    def values(self, keys: list[int]) -> gtsam.Values:
        return fetch_values(self.smoother, keys, self.dimension)

    def marginal_covariance(self, key: int) -> np.ndarray:
        try:
            return self.smoother.marginalCovariance(key)
        except RuntimeError as error:
            raise _explain(
                error,
                float("nan"),
                f"fixed-lag marginal covariance of {gtsam.DefaultKeyFormatter(key)}",
            ) from None

    def leaving(self, t_new: float) -> list[int]:
        """Keys an update whose latest time is ``t_new`` will marginalise (time < t_new - lag)."""
        return [key for key, stamp in self.key_times.items() if stamp < t_new - self.lag_s]

    def contains(self, key: int) -> bool:
        return key in self.key_times
