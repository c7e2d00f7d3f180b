"""What ``assess_truth`` found in one truth stream (``TruthQuality``): the intervals, the
thresholds used, and the masks and lines made from them."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from datasets.truth_quality.intervals import TruthInterval, excluded_mask, merged_spans
from datasets.truth_quality.settings import TruthQualitySettings


@dataclass(frozen=True)
class TruthQuality:
    """What ``assess_truth`` found in one truth stream.

    Attributes:
        intervals: the untrusted intervals, sorted by start (kinds may overlap).
        samples: number of truth samples assessed.
        start_s, end_s: the stream's time span [s].
        median_step_s: the stream's median sample step [s].
        thresholds: the thresholds and statistics actually used (names carry units).
        settings: the settings used.
    """

    intervals: tuple[TruthInterval, ...]
    samples: int
    start_s: float
    end_s: float
    median_step_s: float
    thresholds: dict[str, float] = field(default_factory=dict)
    settings: TruthQualitySettings = field(default_factory=TruthQualitySettings)

    def keep_mask(self, t: np.ndarray) -> np.ndarray:
        """(N,) bool: True for times [s] outside every interval (the samples to keep)."""
        return ~excluded_mask(t, self.intervals)

    def lines(self) -> list[str]:
        """One printable line per interval: kind, start-end [s], evidence."""
        return [interval.line() for interval in self.intervals]

    @property
    def excluded_s(self) -> float:
        """Total time [s] covered by the union of the intervals."""
        spans = merged_spans(self.intervals)
        return float(np.sum(spans[:, 1] - spans[:, 0])) if len(spans) else 0.0

    def counts(self) -> dict[str, int]:
        """Number of intervals per kind (kinds found only)."""
        found: dict[str, int] = {}
        for interval in self.intervals:
            found[interval.kind.value] = found.get(interval.kind.value, 0) + 1
        return found

    def summary(self) -> str:
        """One line: how many intervals of which kinds, and the time they cover."""
        if not self.intervals:
            return f"truth quality: nothing excluded ({self.samples} samples)"
        kinds = ", ".join(f"{count} {kind}" for kind, count in self.counts().items())
        span = self.end_s - self.start_s
        share = self.excluded_s / span if span > 0 else 0.0
        return (
            f"truth quality: {len(self.intervals)} intervals excluded ({kinds}), "
            f"{self.excluded_s:.2f} s of {span:.2f} s ({100 * share:.2f} %)"
        )
