"""Incremental solvers behind the smoother: iSAM2, and GTSAM's fixed-lag smoother.

Both take (new factors, new values, key times) per keyframe and answer estimates and
marginal covariances. GTSAM errors during an update (an indeterminate system, a missing
variable) become ``InputError`` naming the time and carrying GTSAM's whole message, never an
opaque GTSAM traceback.

Factorisation: Cholesky by default (measured at 200 landmarks in view: 15-17x faster per
keyframe than QR, the same final graph error). Cholesky fails where the information spans
many orders of magnitude (kitti-imu-gps with a keyframe every 10 IMU samples: its tiny bias
walk); then the backend rebuilds itself with QR from every factor and value it holds, redoes
what failed, stays on QR for the rest of the run and says so (``fallback``, recorded as an
event by the smoother).

Marginals are queried in batches (``joint``): one ``jointMarginalCovariance`` over the keys
a step needs (a keyframe's states, the keys leaving the fixed-lag window, the whole map),
never key by key in a loop (a single iSAM2 landmark marginal was measured at 0.4 s on a
200-landmark map; the joint of all 170 landmarks at 0.9 s).

Fixed lag: ``gtsam.IncrementalFixedLagSmoother`` (the batch one offers no marginals). It
marginalises the keys whose time is strictly earlier than ``latest time - lag``
(checked in ``tests/test_smoother_modes.py``); its joint marginals come from its iSAM2.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import gtsam
import numpy as np

from datasets.errors import InputError

BIAS_RELINEARIZE_THRESHOLD = 1.0
"""Relinearisation threshold of bias variables (per tangent component): the preintegrated
IMU factor is corrected to first order in the bias, so bias linearisation points may lag.

Measured on kitti-imu-gps (keyframe every 10 IMU samples, loaded machine): iSAM2's update
cost grows along the run (first 150 s, mean per fifth: 1.6, 6.9, 15.8, 17.7, 29.5 ms) with
the pose/velocity threshold at 0.05, 0.1 or 0.2 and with ``relinearize_skip`` 10 alike, and
stays flat (0.3 to 1.2 ms over 100 s) with relinearisation disabled: fluid relinearisation
keeps reaching far back into the history on that GTSAM-only graph. Not solved here."""


def gtsam_message(error: RuntimeError) -> str:
    """GTSAM's whole message on one line."""
    text = " ".join(line.strip() for line in str(error).strip().splitlines() if line.strip())
    return text or type(error).__name__


def _is_indeterminate(error: RuntimeError) -> bool:
    text = str(error)
    return "ndeterminant" in text or "ndeterminate" in text


def _explain(error: RuntimeError, t: float, context: str) -> InputError:
    message = gtsam_message(error)
    where = f"{context} at t={t:.6f} s" if np.isfinite(t) else context
    if _is_indeterminate(error):
        return InputError(
            f"{where}: the system is indeterminate (some state is not constrained: no prior, "
            f"anchors, GPS or enough landmarks reach it) -- GTSAM: {message}"
        )
    return InputError(f"{where} failed inside GTSAM: {message}")


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
    relinearize_threshold: float,
    relinearize_skip: int,
    dimension: int = 3,
    factorization: str = "CHOLESKY",
) -> gtsam.ISAM2Params:
    """iSAM2 parameters: the factorisation, a relinearisation threshold per variable type."""
    params = gtsam.ISAM2Params()
    thresholds = gtsam.ISAM2ThresholdMap()
    pose_dof = 6 if dimension == 3 else 3
    thresholds.insert(("x", np.full(pose_dof, relinearize_threshold)))
    thresholds.insert(("v", np.full(3, relinearize_threshold)))
    thresholds.insert(("b", np.full(6, BIAS_RELINEARIZE_THRESHOLD)))
    thresholds.insert(("l", np.full(dimension, relinearize_threshold)))
    params.setRelinearizeThreshold(thresholds)
    params.relinearizeSkip = relinearize_skip
    params.setFactorization(factorization)
    return params


@dataclass(frozen=True)
class Fallback:
    """The moment Cholesky failed and the backend went on with QR."""

    t: float
    reason: str


class JointMarginals:
    """The joint marginal covariance of a set of keys from one batched query; also a
    ``covariances.MarginalSource`` for any of those keys."""

    def __init__(self, joint: gtsam.JointMarginal, keys: list[int]) -> None:
        self._joint = joint
        self.keys = list(keys)

    def marginalCovariance(self, key: int) -> np.ndarray:  # noqa: N802 - GTSAM's name
        return np.asarray(self._joint.at(key, key), dtype=float)

    def matrix(self, keys: list[int] | None = None) -> np.ndarray:
        """The joint covariance of ``keys`` (default: all), blocks in that order."""
        keys = self.keys if keys is None else keys
        rows = [np.hstack([self._joint.at(a, b) for b in keys]) for a in keys]
        return np.vstack(rows)


class _Incremental:
    """What both backends share: the factorisation with its fallback, batched marginals."""

    def __init__(
        self,
        dimension: int,
        relinearize_threshold: float,
        relinearize_skip: int,
        factorization: str,
    ) -> None:
        self.dimension = dimension
        self.relinearize_threshold = relinearize_threshold
        self.relinearize_skip = relinearize_skip
        self.factorization = factorization
        self.fallback: Fallback | None = None
        self.gtsam_seconds = 0.0
        self.context = "update"

    def params(self) -> gtsam.ISAM2Params:
        return isam2_params(
            self.relinearize_threshold, self.relinearize_skip, self.dimension, self.factorization
        )

    # the solver-specific parts
    def _solver_update(self, graph, values, key_times) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _isam(self) -> gtsam.ISAM2:  # pragma: no cover - abstract
        raise NotImplementedError

    def _rebuild(self, graph, values, key_times) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _falls_back(self, error: RuntimeError, t: float) -> bool:
        """Switch to QR when Cholesky failed on an indeterminate system (rebuild pending)."""
        if self.factorization != "CHOLESKY" or not _is_indeterminate(error):
            return False
        self.factorization = "QR"
        self.fallback = Fallback(float(t), gtsam_message(error))
        return True

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
            self._solver_update(graph, values, key_times)
        except RuntimeError as error:
            if not self._falls_back(error, t):
                raise _explain(error, t, self.context) from None
            try:
                self._rebuild(graph, values, key_times)
            except RuntimeError as again:
                raise _explain(again, t, f"{self.context} (QR after Cholesky failed)") from None
        elapsed = time.perf_counter() - start
        self.gtsam_seconds += elapsed
        return elapsed

    def joint(self, keys: list[int], t: float = float("nan")) -> JointMarginals:
        """One batched joint marginal query over ``keys``."""
        try:
            return JointMarginals(self._isam().jointMarginalCovariance(list(keys)), keys)
        except RuntimeError as error:
            if not self._falls_back(error, t):
                raise _explain(error, t, "joint marginal covariance") from None
        try:
            self._rebuild(gtsam.NonlinearFactorGraph(), gtsam.Values(), {})
            return JointMarginals(self._isam().jointMarginalCovariance(list(keys)), keys)
        except RuntimeError as error:
            raise _explain(
                error, t, "joint marginal covariance (QR after Cholesky failed)"
            ) from None

    @staticmethod
    def _merged(held: gtsam.Values, new: gtsam.Values) -> gtsam.Values:
        """``held`` without the keys of ``new``, then ``new``."""
        merged = gtsam.Values(held)
        for key in new.keys():
            if merged.exists(key):
                merged.erase(key)
        merged.insert(new)
        return merged


class Isam2Backend(_Incremental):
    """iSAM2 over the whole history."""

    def __init__(
        self,
        relinearize_threshold: float,
        relinearize_skip: int,
        extra_iterations: int,
        dimension: int = 3,
        factorization: str = "CHOLESKY",
    ) -> None:
        super().__init__(dimension, relinearize_threshold, relinearize_skip, factorization)
        self.extra_iterations = extra_iterations
        self.isam = gtsam.ISAM2(self.params())
        self.graph = gtsam.NonlinearFactorGraph()  # every factor added so far (for a rebuild)
        self.context = "iSAM2 update"

    def _solver_update(self, graph, values, key_times) -> None:
        self.isam.update(graph, values)
        for _ in range(self.extra_iterations):
            self.isam.update()
        self.graph.push_back(graph)

    def _rebuild(self, graph, values, key_times) -> None:
        """A QR iSAM2 from every factor (held and new) at the held linearisation point."""
        held = self.isam.getLinearizationPoint()
        self.graph.push_back(graph)
        self.isam = gtsam.ISAM2(self.params())
        self.isam.update(self.graph, self._merged(held, values))

    def _isam(self) -> gtsam.ISAM2:
        return self.isam

    def estimate(self) -> gtsam.Values:
        return self.isam.calculateEstimate()

    def values(self, keys: list[int]) -> gtsam.Values:
        return fetch_values(self.isam, keys, self.dimension)

    def leaving(self, t_new: float) -> list[int]:
        """Keys about to be marginalised by an update at ``t_new``: none for iSAM2."""
        return []

    def contains(self, key: int) -> bool:
        return self.isam.valueExists(key)


class FixedLagBackend(_Incremental):
    """``gtsam.IncrementalFixedLagSmoother`` with a lag in seconds."""

    def __init__(
        self,
        lag_s: float,
        relinearize_threshold: float,
        relinearize_skip: int,
        dimension: int = 3,
        factorization: str = "CHOLESKY",
    ) -> None:
        super().__init__(dimension, relinearize_threshold, relinearize_skip, factorization)
        self.lag_s = lag_s
        self.smoother = gtsam.IncrementalFixedLagSmoother(lag_s, self.params())
        self.key_times: dict[int, float] = {}
        self.context = "fixed-lag update"

    @staticmethod
    def _stamps(key_times: dict[int, float]) -> gtsam.FixedLagSmootherKeyTimestampMap:
        stamps = gtsam.FixedLagSmootherKeyTimestampMap()
        for key, stamp in key_times.items():
            stamps.insert((key, stamp))
        return stamps

    def _solver_update(self, graph, values, key_times) -> None:
        self.smoother.update(graph, values, self._stamps(key_times))
        self._track(key_times)

    def _track(self, key_times: dict[int, float]) -> None:
        self.key_times.update(key_times)
        latest = max(self.key_times.values(), default=0.0)
        for key in [key for key, stamp in self.key_times.items() if stamp < latest - self.lag_s]:
            del self.key_times[key]

    def _rebuild(self, graph, values, key_times) -> None:
        """A QR smoother from the window's factors (with its marginal factors), its
        linearisation point and stamps, then the new factors."""
        held_factors = gtsam.NonlinearFactorGraph()
        for index in range(self.smoother.getFactors().size()):
            factor = self.smoother.getFactors().at(index)
            if factor is not None:
                held_factors.add(factor)
        held = self.smoother.getLinearizationPoint()
        held_times = dict(self.key_times)
        self.smoother = gtsam.IncrementalFixedLagSmoother(self.lag_s, self.params())
        self.smoother.update(held_factors, held, self._stamps(held_times))
        if graph.size() or values.size():
            self.smoother.update(graph, values, self._stamps(key_times))
            self._track(key_times)

    def _isam(self) -> gtsam.ISAM2:
        return self.smoother.getISAM2()

    def estimate(self) -> gtsam.Values:
        return self.smoother.calculateEstimate()

    def values(self, keys: list[int]) -> gtsam.Values:
        return fetch_values(self.smoother, keys, self.dimension)

    def leaving(self, t_new: float) -> list[int]:
        """Keys an update whose latest time is ``t_new`` will marginalise (time < t_new - lag)."""
        return [key for key, stamp in self.key_times.items() if stamp < t_new - self.lag_s]

    def contains(self, key: int) -> bool:
        return key in self.key_times
