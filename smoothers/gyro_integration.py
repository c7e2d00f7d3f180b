"""The rate gyro integrated between keyframes: the measured rotation ``dtheta_m`` and the
elapsed ``dt`` of each keyframe interval, the inputs of the gyro-only motion factor
(``smoothers.gyro_motion_factor``), with the gyro's rate over each sub-interval
(``interval_rate``) and the zero-order hold's gap check (``smoothers.held_input``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.errors import InputError
from datasets.measurements import GyroSample
from datasets.model_options import IntervalRate
from smoothers.held_input import held_interval


@dataclass
class GyroAccumulator:
    """Integrates a rate gyro between keyframes: ``dtheta_m`` and ``dt``.

    With ``interval_rate="average"`` (default) samples are instantaneous values (the
    simulator's convention, and the filters' default): each sub-interval takes the straight
    line between the held sample and the next one at its midpoint, i.e. the mean of the two
    samples over a whole interval. The next sample is the one being added, or ``lookahead``
    when a keyframe is closed between two samples. ``"hold"``: zero-order hold, first order
    in the sample interval; ``"latest"``: the next sample. Measured on the 10 Hz gyro of ``sim:guerreiro-loop`` (one
    sample per keyframe; noise-free data, the truth's states): the hold's rotation residual
    alone read 0.48 per keyframe in units of the stated gyro variance, 1.39 with the noise,
    so the heading was optimistic and the smoothers' NIS read 1.016 per dof against
    ekf-slam's 0.999 on the same runs."""

    max_gap_s: float
    interval_rate: IntervalRate = "average"
    cursor: float = 0.0
    held_t: float | None = None
    held_rate: float = 0.0
    dtheta: float = 0.0
    elapsed: float = 0.0
    lookahead: tuple[float, float] | None = None

    def start(self, t: float) -> None:
        self.cursor = float(t)
        self.dtheta = 0.0
        self.elapsed = 0.0

    def _integrate_until(self, t: float, following: tuple[float, float] | None) -> None:
        dt = held_interval(self.cursor, self.held_t, t, self.max_gap_s, "gyro")
        if dt <= 0.0:
            return
        assert self.held_t is not None
        rate = self.held_rate
        later = following is not None and following[0] > self.held_t
        if self.interval_rate == "average" and later:
            next_t, next_rate = following
            weight = (0.5 * (self.cursor + t) - self.held_t) / (next_t - self.held_t)
            rate = rate + weight * (next_rate - rate)
        elif self.interval_rate == "latest" and later:
            rate = following[1]
        self.dtheta += rate * dt
        self.elapsed += dt
        self.cursor = t

    def add(self, sample: GyroSample) -> None:
        rate = float(np.asarray(sample.rate, dtype=float).ravel()[-1])
        if self.held_t is None:
            self.held_t, self.held_rate = float(sample.t), rate
        self._integrate_until(sample.t, (float(sample.t), rate))
        self.held_t, self.held_rate = float(sample.t), rate
        self.lookahead = None

    def close(self, t: float) -> tuple[float, float]:
        """(dtheta_m [rad], dt [s]) since the last keyframe, up to ``t``."""
        if self.held_t is None:
            raise InputError(f"keyframe at t={t:.6f} s: no gyro sample has arrived")
        self._integrate_until(t, self.lookahead)
        return self.dtheta, self.elapsed
