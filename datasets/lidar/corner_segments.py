"""Segments of an azimuth scan (step 4 of ``datasets.lidar.corners``): split-and-merge
(Pavlidis and Horowitz's iterative end-point fit, then merges of adjacent segments whose joint
line fits), the boundary refinement of the 2-D laser front end, and the additive moments that
give every segment's total-least-squares line and residual (step 5's fits).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.lidar.corner_kernels import merge_segments_kernel, split_segments_kernel


def split_segments(
    xy: np.ndarray, starts: np.ndarray, ends: np.ndarray, threshold_m: float, max_levels: int = 64
) -> tuple[np.ndarray, np.ndarray]:
    """Iterative end-point fit (the split step of Pavlidis and Horowitz): the inclusive index
    ranges ``[starts, ends]`` of ``xy`` (m, 2) [m] split at their first point farthest from
    the chord while that distance exceeds ``threshold_m``, at most ``max_levels`` deep; the
    split point ends one segment and starts the next. Returns the final segments' starts and
    ends, ordered by start (``corner_kernels.split_segments_kernel``: compiled, as a loop
    over a scan's ten-odd levels of numpy calls cost 0.5 ms a KITTI scan)."""
    return split_segments_kernel(
        np.ascontiguousarray(xy, dtype=np.float64),
        np.asarray(starts, dtype=np.int64),
        np.asarray(ends, dtype=np.int64),
        max(float(threshold_m), 0.0),
        int(max_levels),
    )


@dataclass(frozen=True)
class _Moments:
    """Additive sums over segment points, (m, 6): n, sum x, sum y, sum xx, sum xy, sum yy."""

    sums: np.ndarray

    def line(self) -> tuple[np.ndarray, np.ndarray]:
        """Total-least-squares line: centroid (m, 2), unit direction (m, 2)."""
        mean, cxx, cxy, cyy = self._centred()
        angle = 0.5 * np.arctan2(2.0 * cxy, cxx - cyy)
        direction = np.empty((len(angle), 2))
        np.cos(angle, out=direction[:, 0])
        np.sin(angle, out=direction[:, 1])
        return mean[:, :2], direction

    def _centred(self) -> tuple[np.ndarray, ...]:
        """Means of x, y, xx, xy, yy over the points (m, 5), and the central second moments
        xx, xy, yy (m,) each."""
        mean = self.sums[:, 1:] / np.maximum(self.sums[:, :1], 1)
        cx, cy = mean[:, 0], mean[:, 1]
        return mean, mean[:, 2] - cx * cx, mean[:, 3] - cx * cy, mean[:, 4] - cy * cy


class _PrefixMoments:
    """Cumulative sums of ``1, x, y, xx, xy, yy`` over the scan, so the moments of any
    inclusive index range cost two lookups (the merge loop asks for them once per merge).

    Attributes:
        sums: (m + 1, 6), a zero row, then the running sums.
    """

    def __init__(self, xy: np.ndarray) -> None:
        x, y = xy[:, 0], xy[:, 1]
        # a zero row, then the running sums, the columns written and summed in place (the
        # same sequential sums as stacking the columns and a cumsum, without the copies)
        self.sums = np.zeros((len(xy) + 1, 6))
        columns = self.sums[1:]
        columns[:, 0], columns[:, 1], columns[:, 2] = 1.0, x, y
        np.multiply(x, x, out=columns[:, 3])
        np.multiply(x, y, out=columns[:, 4])
        np.multiply(y, y, out=columns[:, 5])
        np.cumsum(columns, axis=0, out=columns)

    def totals(self, starts, ends) -> np.ndarray:
        """(m, 6) sums of the inclusive ranges ``[starts, ends]`` (index arrays or ints)."""
        return self.sums.take(np.asarray(ends) + 1, axis=0) - self.sums.take(starts, axis=0)

    def of(self, starts: np.ndarray, ends: np.ndarray) -> _Moments:
        """Moments of the inclusive ranges ``[starts, ends]``."""
        return _Moments(self.totals(starts, ends))


def merge_segments(
    xy: np.ndarray, starts: np.ndarray, ends: np.ndarray, cluster: np.ndarray, rms_m: float
) -> tuple[np.ndarray, np.ndarray]:
    """Merge adjacent segments of one cluster whose joint line fit has RMS below ``rms_m``
    (the merge step of Pavlidis and Horowitz); greedy, best pair first (lowest joint RMS,
    then leftmost), over segments. ``cluster`` (m,) is each point's cluster number."""
    return _merge_segments(_PrefixMoments(xy), starts, ends, cluster, rms_m)


def _merge_segments(
    prefix: _PrefixMoments,
    starts: np.ndarray,
    ends: np.ndarray,
    cluster: np.ndarray,
    rms_m: float,
) -> tuple[np.ndarray, np.ndarray]:
    """``merge_segments`` with the scan's prefix moments given (``extract_corners`` fits
    its lines with the same ones): ``corner_kernels.merge_segments_kernel``, a heap of
    adjacent pairs with lazy invalidation (a merge re-scores only the two pairs next to the
    merged segment), compiled: in Python it cost 0.4 ms a KITTI scan."""
    starts = np.asarray(starts, dtype=np.int64)
    return merge_segments_kernel(
        prefix.sums, starts, np.asarray(ends, dtype=np.int64), cluster[starts], float(rms_m)
    )


def refine_boundaries(
    prefix: _PrefixMoments,
    starts: np.ndarray,
    ends: np.ndarray,
    cluster: np.ndarray,
    least: int,
) -> tuple[np.ndarray, np.ndarray]:
    """Each boundary between adjacent segments of one cluster moved to the break that fits
    the two lines best: over the points of both, the split ``[start, k] | [k + 1, end]``
    with the least sum of the two total-least-squares residual sums of squares (each
    ``n`` times the smaller eigenvalue of its scatter matrix, from the prefix moments), each
    side keeping at least ``least`` points. Boundaries are refined left to right.

    Why: the iterative end-point fit splits at the point farthest from a chord, which noise
    can put a few points away from the true break when one of the two lines has few points
    (a door jamb seen obliquely); those points of the neighbouring wall then sit in the
    short line's fit, beyond what the end trim removes, and bias its corner by centimetres
    (``tests/test_laser2d_corners.py``). After refinement adjacent segments share no point.
    """
    starts, ends = np.array(starts, dtype=np.int64), np.array(ends, dtype=np.int64)
    left_index = np.flatnonzero(
        (cluster[starts[:-1]] == cluster[ends[1:]]) & (starts[1:] - ends[:-1] <= 1)
    )
    low, high = starts[left_index], ends[left_index + 1]
    counts = np.maximum(high - low + 3 - 2 * least, 0)  # breaks k with both sides >= least
    left_index, low, high, counts = (
        left_index[counts > 0],
        low[counts > 0],
        high[counts > 0],
        counts[counts > 0],
    )
    if len(left_index) == 0:
        return starts, ends
    # every candidate break of every boundary at once: left [low, k], right [k + 1, high]
    owner = np.repeat(np.arange(len(left_index)), counts)
    offsets = np.cumsum(counts) - counts
    breaks = low[owner] + least - 1 + (np.arange(len(owner)) - offsets[owner])
    cost = _residual_sum(_Moments(prefix.totals(low[owner], breaks))) + _residual_sum(
        _Moments(prefix.totals(breaks + 1, high[owner]))
    )
    order = np.lexsort((cost, owner))
    best = breaks[order[np.concatenate([[0], np.cumsum(counts)[:-1]])]]
    for i, k in zip(left_index.tolist(), best.tolist()):
        # a break refined just before may have shortened this boundary's left segment
        k = min(max(k, int(starts[i]) + least - 1), int(ends[i + 1]) - least)
        if k >= int(starts[i]) + least - 1:
            ends[i], starts[i + 1] = k, k + 1
    return starts, ends


def _residual_sum(moments: _Moments) -> np.ndarray:
    """Total-least-squares residual sum of squares of each range (m,) [m^2]: ``n`` times the
    smaller eigenvalue of the central second-moment matrix."""
    _, cxx, cxy, cyy = moments._centred()
    half_trace = 0.5 * (cxx + cyy)
    spread = np.sqrt(np.maximum(0.25 * (cxx - cyy) ** 2 + cxy * cxy, 0.0))
    return moments.sums[:, 0] * np.maximum(half_trace - spread, 0.0)
