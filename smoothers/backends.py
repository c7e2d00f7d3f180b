"""Incremental solvers behind the smoother: iSAM2, and GTSAM's fixed-lag smoother.

Both take (new factors, new values, key times) per keyframe and answer estimates and joint
marginal covariances. GTSAM errors during an update (an indeterminate system, a missing
variable) become ``InputError`` naming the time and carrying GTSAM's whole message
(``smoothers.gtsam_errors``), never an opaque GTSAM traceback.

Factorisation: Cholesky by default (measured at 200 landmarks in view: 15-17x faster per
keyframe than QR, the same final graph error). Cholesky fails where the information spans
many orders of magnitude (kitti-imu-gps with a keyframe every 10 IMU samples: its tiny bias
walk); then the backend rebuilds itself with QR from every factor and value it held before
the failed step, redoes that step, stays on QR for the rest of the run and says so
(``fallback``, recorded as an event and a note by the smoother). A system that is
indeterminate under QR too is an ``InputError``.

Marginals are queried in batches (``joint``, ``smoothers.joint_marginals``): one
``jointMarginalCovariance`` over the keys a step needs, never key by key in a loop.

Elimination order (iSAM2): every update puts the newest keyframe's states, the keys of its
new factors and those of the update before it in the last group (``eliminated_last``), so
that they sit in the Bayes tree's root clique, where a joint marginal is read off the root
instead of being computed through shortcuts from deep cliques. GTSAM's default puts only the
new factors' keys last: a keyframe's velocity and bias and the landmarks of the previous
scan then sank below the root, and each query of them grew with the history (60 s of
``sim:aghili-rover``: 31 ms a query on average, 98 ms in the last fifth; 38.6 s of the run's
59 s). The order changes the factorisation's fill-in, not the solution (estimates and
covariances equal to 1e-10, ``tests/test_smoother_modes.py``).

Fixed lag: ``gtsam.IncrementalFixedLagSmoother`` (the batch one offers no marginals). It
marginalises the keys whose time is strictly earlier than ``latest time - lag``
(checked in ``tests/test_smoother_modes.py``); its joint marginals come from its iSAM2.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Any

import gtsam
import numpy as np

from smoothers.gtsam_errors import explain, gtsam_message, is_indeterminate
from smoothers.joint_marginals import JointMarginals

BIAS_RELINEARIZE_THRESHOLD = 1.0
"""Relinearisation threshold of bias variables (per tangent component): the preintegrated
IMU factor is corrected to first order in the bias, so bias linearisation points may lag.

Measured on kitti-imu-gps (keyframe every 10 IMU samples, loaded machine): iSAM2's update
cost grows along the run (first 150 s, mean per fifth: 1.6, 6.9, 15.8, 17.7, 29.5 ms) with
the pose/velocity threshold at 0.05, 0.1 or 0.2 and with ``relinearize_skip`` 10 alike, and
stays flat (0.3 to 1.2 ms over 100 s) with relinearisation disabled: fluid relinearisation
keeps reaching far back into the history on that GTSAM-only graph. Not solved here."""


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
    # Back-substitute every variable at every update (wildfire threshold 0). GTSAM's default
    # (0.001, in each variable's own tangent units) leaves a variable's delta stale when its
    # change is below that: a gyro bias with sigma 1.8e-4 rad/s never hears of a loop
    # closure, and ``calculateEstimate`` then returned smoothed gyro biases up to 4.3 sigma
    # from the converged batch solution on a 30 s loop (smoothed gyro-bias NEES 3.7 per dof
    # over 35 runs of the 100 s loop against the batch smoother's 0.98).
    optimisation = gtsam.ISAM2GaussNewtonParams()
    optimisation.setWildfireThreshold(0.0)
    params.setOptimizationParams(optimisation)
    params.setFactorization(factorization)
    return params


def factor_keys(graph: gtsam.NonlinearFactorGraph) -> set[int]:
    """Every key some factor of ``graph`` involves."""
    keys: set[int] = set()
    for index in range(graph.size()):
        factor = graph.at(index)
        if factor is not None:
            keys.update(int(key) for key in factor.keys())
    return keys


def eliminated_last(keys: set[int]) -> gtsam.KeyGroupMap:
    """iSAM2 ordering constraints putting ``keys`` in the last group (the root clique)."""
    groups = gtsam.KeyGroupMap()
    for key in keys:
        groups.insert2(key, 1)
    return groups


@dataclass(frozen=True)
class Fallback:
    """The moment Cholesky failed and the backend went on with QR.

    Attributes:
        t: the time of the step that failed [s] (NaN for a marginal query without one).
        reason: GTSAM's whole message.
    """

    t: float
    reason: str


def _without(held: gtsam.Values, new: gtsam.Values) -> gtsam.Values:
    """``held`` without the keys of ``new`` (a failed update may have inserted them)."""
    kept = gtsam.Values(held)
    for key in new.keys():
        if kept.exists(key):
            kept.erase(key)
    return kept


class _Incremental:
    """What both backends share: the factorisation with its QR fallback, batched marginals.

    A solver-specific subclass says how many factor slots it holds (``_held_slots``: GTSAM
    appends new factors, so the slots held before an update are the first ones) and how to
    build a fresh solver from them (``_rebuild``).
    """

    context = "update"

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

    def params(self) -> gtsam.ISAM2Params:
        return isam2_params(
            self.relinearize_threshold, self.relinearize_skip, self.dimension, self.factorization
        )

    # the solver-specific parts
    def _solver_update(
        self, graph, values, key_times, newest
    ) -> None:  # pragma: no cover - abstract
        raise NotImplementedError

    def _isam(self) -> gtsam.ISAM2:  # pragma: no cover - abstract
        raise NotImplementedError

    def _solver(self):  # pragma: no cover - abstract
        """What answers ``calculateEstimate*`` (iSAM2, or the fixed-lag smoother)."""
        raise NotImplementedError

    def _held_slots(self) -> int:  # pragma: no cover - abstract
        raise NotImplementedError

    def _rebuild(self, slots: int, new: gtsam.Values) -> None:  # pragma: no cover - abstract
        """A fresh solver (``params()``) holding the factors of the first ``slots`` slots
        at the held linearisation point without the keys of ``new``."""
        raise NotImplementedError

    def _fall_back(self, error: RuntimeError, t: float, context: str) -> None:
        """Switch to QR when Cholesky failed on an indeterminate system; otherwise raise
        the ``InputError`` for ``error``."""
        if self.factorization != "CHOLESKY" or not is_indeterminate(error):
            raise explain(error, t, context) from None
        self.factorization = "QR"
        self.fallback = Fallback(float(t), gtsam_message(error))

    def update(
        self,
        graph: gtsam.NonlinearFactorGraph,
        values: gtsam.Values,
        key_times: dict[int, float],
        t: float,
        newest: Sequence[int] = (),
    ) -> float:
        """Add factors and values (``key_times``: key -> time [s]) at time ``t`` [s];
        ``newest``: the newest keyframe's state keys (kept in the root clique where the
        solver allows it). Returns the seconds spent inside GTSAM."""
        start = time.perf_counter()
        slots = self._held_slots()
        try:
            self._solver_update(graph, values, key_times, newest)
        except RuntimeError as error:
            self._fall_back(error, t, self.context)
            try:
                self._rebuild(slots, values)
                self._solver_update(graph, values, key_times, newest)
            except RuntimeError as again:
                raise explain(again, t, f"{self.context} (QR after Cholesky failed)") from None
        elapsed = time.perf_counter() - start
        self.gtsam_seconds += elapsed
        return elapsed

    def _query(self, ask: Callable[[], Any], t: float, context: str) -> Any:
        """``ask()`` of the solver, with the QR fallback when Cholesky fails on it; any other
        GTSAM failure as the ``InputError`` of ``explain`` (``t`` [s]: for errors)."""
        try:
            return ask()
        except RuntimeError as error:
            self._fall_back(error, t, context)
        try:
            self._rebuild(self._held_slots(), gtsam.Values())
            return ask()
        except RuntimeError as again:
            raise explain(again, t, f"{context} (QR after Cholesky failed)") from None

    def joint(self, keys: Sequence[int], t: float = float("nan")) -> JointMarginals:
        """One batched joint marginal query over ``keys`` (at time ``t`` [s], for errors)."""
        return self._query(
            lambda: JointMarginals.query(self._isam(), keys), t, "joint marginal covariance"
        )

    def values(self, keys: list[int], t: float = float("nan")) -> gtsam.Values:
        """The current estimate of ``keys`` (``fetch_values``; back-substitution can meet an
        indeterminate system too: a diverged window)."""
        return self._query(
            lambda: fetch_values(self._solver(), keys, self.dimension), t, "estimate"
        )

    def estimate(self) -> gtsam.Values:
        """The current estimate of every variable."""
        return self._query(lambda: self._solver().calculateEstimate(), float("nan"), "estimate")


class Isam2Backend(_Incremental):
    """iSAM2 over the whole history."""

    context = "iSAM2 update"

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
        # every factor added so far: what a QR rebuild starts from
        self.graph = gtsam.NonlinearFactorGraph()
        # the keys of the previous update's factors, kept in the root (module docstring)
        self._previous_keys: set[int] = set()

    def _solver_update(self, graph, values, key_times, newest) -> None:
        new_keys = factor_keys(graph)
        last = new_keys | self._previous_keys | {int(key) for key in newest}
        self.isam.update(graph, values, [], eliminated_last(last))
        self._previous_keys = new_keys
        for _ in range(self.extra_iterations):
            self.isam.update()
        self.graph.push_back(graph)

    def _held_slots(self) -> int:
        return self.graph.size()

    def _rebuild(self, slots: int, new: gtsam.Values) -> None:
        held = _without(self.isam.getLinearizationPoint(), new)
        self.isam = gtsam.ISAM2(self.params())
        self.isam.update(self.graph, held)

    def _isam(self) -> gtsam.ISAM2:
        return self.isam

    def _solver(self) -> gtsam.ISAM2:
        return self.isam

    def leaving(self, t_new: float) -> list[int]:
        """Keys about to be marginalised by an update at ``t_new``: none for iSAM2."""
        return []

    def contains(self, key: int) -> bool:
        return self.isam.valueExists(key)


class FixedLagBackend(_Incremental):
    """``gtsam.IncrementalFixedLagSmoother`` with a lag in seconds."""

    context = "fixed-lag update"

    def __init__(
        self,
        lag_s: float,
        relinearize_threshold: float,
        relinearize_skip: int,
        dimension: int = 3,
        factorization: str = "CHOLESKY",
        clock: Callable[[float], float] | None = None,
    ) -> None:
        super().__init__(dimension, relinearize_threshold, relinearize_skip, factorization)
        self.lag_s = lag_s
        self.smoother = gtsam.IncrementalFixedLagSmoother(lag_s, self.params())
        # the time the lag is counted in (``smoothers.lag_clock``); key stamps are kept in it
        self.clock = clock if clock is not None else float
        self.key_times: dict[int, float] = {}

    @staticmethod
    def _stamps(key_times: dict[int, float]) -> gtsam.FixedLagSmootherKeyTimestampMap:
        stamps = gtsam.FixedLagSmootherKeyTimestampMap()
        for key, stamp in key_times.items():
            stamps.insert((key, stamp))
        return stamps

    def _solver_update(self, graph, values, key_times, newest) -> None:
        # GTSAM's fixed-lag smoother sets its own ordering constraints (what leaves first)
        stamped = {key: self.clock(stamp) for key, stamp in key_times.items()}
        self.smoother.update(graph, values, self._stamps(stamped))
        self._track(stamped)

    def _track(self, key_times: dict[int, float]) -> None:
        self.key_times.update(key_times)
        latest = max(self.key_times.values(), default=0.0)
        for key in [key for key, stamp in self.key_times.items() if stamp < latest - self.lag_s]:
            del self.key_times[key]

    def _held_slots(self) -> int:
        return self.smoother.getFactors().size()  # a reference: no copy of the window

    def _rebuild(self, slots: int, new: gtsam.Values) -> None:
        """The window's factors (with the marginal factors of what left it), linearisation
        point and stamps, as they were before the failed step, in a fresh smoother. The
        failed update had already appended its factors and values: they are left out."""
        factors = self.smoother.getFactors()
        held_factors = gtsam.NonlinearFactorGraph()
        for index in range(min(slots, factors.size())):
            factor = factors.at(index)
            if factor is not None:
                held_factors.add(factor)
        held = _without(self.smoother.getLinearizationPoint(), new)
        self.smoother = gtsam.IncrementalFixedLagSmoother(self.lag_s, self.params())
        self.smoother.update(held_factors, held, self._stamps(self.key_times))

    def _isam(self) -> gtsam.ISAM2:
        return self.smoother.getISAM2()

    def _solver(self) -> gtsam.IncrementalFixedLagSmoother:
        return self.smoother

    def leaving(self, t_new: float) -> list[int]:
        """Keys an update whose latest time is ``t_new`` [s, wall] will marginalise (clock
        time < clock(t_new) - lag)."""
        cutoff = self.clock(t_new) - self.lag_s
        return [key for key, stamp in self.key_times.items() if stamp < cutoff]

    def contains(self, key: int) -> bool:
        return key in self.key_times
