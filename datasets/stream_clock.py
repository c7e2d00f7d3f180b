"""``StreamClock``: the one check every estimator makes on its input's time stamps.

Estimators consume one time-ordered stream (``Sequence.measurements()``); a stamp that is
not finite or goes backwards is bad input, reported as an ``InputError`` that names the
estimator's context, the measurement kind and both times, before any state is touched.
"""

from __future__ import annotations

import math

from datasets.errors import InputError


class StreamClock:
    """The time of the last measurement an estimator consumed.

    Attributes:
        context: what to name in errors (the estimator and dataset).
        t: the latest time [s], None before the first measurement.
    """

    def __init__(self, context: str, start: float | None = None) -> None:
        self.context = context
        self.t: float | None = None if start is None else float(start)

    def check(self, t: float, what: str) -> float:
        """The step ``t - previous`` [s] (0 for the first stamp) without advancing;
        ``InputError`` when ``t`` is not finite or earlier than the previous time."""
        t = float(t)
        if not math.isfinite(t):
            previous = "the start" if self.t is None else f"t={self.t:.6f} s"
            raise InputError(f"{self.context}: non-finite {what} time stamp after {previous}")
        if self.t is None:
            return 0.0
        if t < self.t:
            raise InputError(
                f"{self.context}: time goes backwards at {what} t={t:.6f} s (previous {self.t:.6f} s)"
            )
        return t - self.t

    def advance(self, t: float, what: str) -> float:
        """``check``, then move the clock to ``t``; returns the step [s]."""
        step = self.check(t, what)
        self.t = float(t)
        return step
