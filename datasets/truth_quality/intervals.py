"""Truth intervals as data: what was found (``TruthKind``), where (``TruthInterval``, a
closed time interval on the truth's clock [s]), and the union of intervals (``merged_spans``,
``excluded_mask``) that scoring leaves out."""

from __future__ import annotations

import enum
import math
from dataclasses import dataclass

import numpy as np


class TruthKind(enum.StrEnum):
    """What made a truth interval untrustworthy (``datasets.truth_quality`` docstring: one
    paragraph each)."""

    DROPOUT = "dropout"
    RATE_CHANGE = "rate_change"
    FREEZE = "freeze"
    JUMP = "jump"
    WRONG_TRACK = "wrong_track"
    HEADING = "heading"
    MOTION = "motion"


@dataclass(frozen=True)
class TruthInterval:
    """A closed time interval of a truth stream that scoring must leave out.

    Attributes:
        start_s: first excluded time [s] (on the truth's clock).
        end_s: last excluded time [s], >= ``start_s`` (equal for a single sample).
        kind: what was found.
        evidence: the numbers that found it, one line of text.
    """

    start_s: float
    end_s: float
    kind: TruthKind
    evidence: str

    def __post_init__(self) -> None:
        if not (math.isfinite(self.start_s) and math.isfinite(self.end_s)):
            raise ValueError(f"TruthInterval needs finite times, got {self.start_s}, {self.end_s}")
        if self.end_s < self.start_s:
            raise ValueError(f"TruthInterval ends before it starts: {self.start_s} > {self.end_s}")

    @property
    def duration_s(self) -> float:
        """Length [s] (0 for a single sample)."""
        return self.end_s - self.start_s

    def line(self) -> str:
        """``kind  start-end s  evidence``, one line for printing."""
        return f"{self.kind.value:<11} {self.start_s:10.3f}-{self.end_s:10.3f} s  {self.evidence}"


def merged_spans(intervals: tuple[TruthInterval, ...] | list[TruthInterval]) -> np.ndarray:
    """The union of the intervals as sorted disjoint closed spans, shape (K, 2) [s]."""
    if not intervals:
        return np.zeros((0, 2))
    spans = np.array(sorted((i.start_s, i.end_s) for i in intervals), dtype=float)
    merged = [list(spans[0])]
    for start, end in spans[1:]:
        if start <= merged[-1][1]:
            merged[-1][1] = max(merged[-1][1], end)
        else:
            merged.append([start, end])
    return np.array(merged, dtype=float)


def excluded_mask(times: np.ndarray, intervals: tuple[TruthInterval, ...]) -> np.ndarray:
    """(N,) bool: True where a time [s] lies inside (edges included) any of the intervals."""
    times = np.asarray(times, dtype=float)
    spans = merged_spans(intervals)
    if len(spans) == 0:
        return np.zeros(times.shape, dtype=bool)
    index = np.searchsorted(spans[:, 0], times, side="right") - 1
    inside = index >= 0
    inside[inside] = times[inside] <= spans[index[inside], 1]
    return inside
