"""The corner extractor's compiled split and merge loops (``datasets.lidar.corner_kernels``)
against a plain-Python reference written from the algorithm's statement (Pavlidis and
Horowitz's split-and-merge, as ``datasets.lidar.corners`` describes it), segment for segment
and to the bit: on random polylines with every threshold regime, and on the azimuth scans of
the real KITTI clip (which must then give the same corners)."""

from __future__ import annotations

import heapq
import math
from pathlib import Path

import numpy as np
import pytest

from datasets.lidar.corner_config import CornerConfig
from datasets.lidar.corner_scan import azimuth_scan_indices
from datasets.lidar.corner_segments import _PrefixMoments, merge_segments, split_segments

CLIP = Path(__file__).resolve().parents[2] / "shared" / "data" / "kitti-hdl64-clip"


def reference_split(xy, starts, ends, threshold, max_levels):
    """A range splits at its first point farthest from its chord (distance > threshold), the
    split point shared, at most ``max_levels`` deep; final ranges by start."""
    done = []

    def split(first, last, level):
        a_x, a_y = float(xy[first, 0]), float(xy[first, 1])
        chord_x, chord_y = float(xy[last, 0]) - a_x, float(xy[last, 1]) - a_y
        length = max(math.sqrt(chord_x * chord_x + chord_y * chord_y), 1e-12)
        distances = [
            abs(chord_x * (float(xy[i, 1]) - a_y) - chord_y * (float(xy[i, 0]) - a_x)) / length
            for i in range(first, last + 1)
        ]
        worst = max(distances)
        if level >= max_levels or not worst > threshold:
            done.append((first, last))
            return
        at = first + distances.index(worst)
        split(first, at, level + 1)
        split(at, last, level + 1)

    for first, last in zip(starts.tolist(), ends.tolist(), strict=True):
        split(first, last, 0)
    done.sort()
    return np.array([d[0] for d in done]), np.array([d[1] for d in done])


def reference_merge(xy, starts, ends, cluster, rms_m):
    """Greedy: repeatedly merge the adjacent pair of one cluster with the lowest joint RMS
    (then the leftmost) while it is below ``rms_m``; the RMS from the range's moments."""
    sums = _PrefixMoments(xy).sums
    segments = [[s, e] for s, e in zip(starts.tolist(), ends.tolist(), strict=True)]

    def rms(first, last, first2, last2):
        n, sx, sy, sxx, sxy, syy = (
            (sums[last + 1] - sums[first]) + (sums[last2 + 1] - sums[first2])
        ).tolist()
        n = max(n, 1.0)
        cx, cy = sx / n, sy / n
        cxx, cxy, cyy = sxx / n - cx * cx, sxy / n - cx * cy, syy / n - cy * cy
        smallest = 0.5 * (cxx + cyy) - math.sqrt(0.25 * (cxx - cyy) ** 2 + cxy**2)
        return math.sqrt(max(smallest, 0.0))

    while True:
        candidates = []
        for k in range(len(segments) - 1):
            (s1, e1), (s2, e2) = segments[k], segments[k + 1]
            if cluster[s1] == cluster[s2]:
                candidates.append((rms(s1, e1, s2, e2), k))
        candidates = [c for c in candidates if c[0] < rms_m]
        if not candidates:
            break
        _, k = heapq.nsmallest(1, candidates)[0]
        segments[k][1] = segments[k + 1][1]
        del segments[k + 1]
    return np.array([s for s, _ in segments]), np.array([e for _, e in segments])


def _check(xy, starts, ends, cluster, threshold, levels, rms_m):
    ours = split_segments(xy, starts, ends, threshold, levels)
    reference = reference_split(xy, starts, ends, threshold, levels)
    np.testing.assert_array_equal(ours[0], reference[0])
    np.testing.assert_array_equal(ours[1], reference[1])
    merged = merge_segments(xy, ours[0], ours[1], cluster, rms_m)
    expected = reference_merge(xy, ours[0], ours[1], cluster, rms_m)
    np.testing.assert_array_equal(merged[0], expected[0])
    np.testing.assert_array_equal(merged[1], expected[1])


def test_split_and_merge_equal_the_reference_on_random_polylines() -> None:
    rng = np.random.default_rng(11)
    for _ in range(200):
        n = int(rng.integers(2, 300))
        xy = np.cumsum(rng.normal(size=(n, 2)) * rng.choice([0.01, 0.1, 1.0]), axis=0)
        cuts = np.sort(
            rng.choice(np.arange(1, n), size=min(n - 1, int(rng.integers(0, 6))), replace=False)
        )
        starts, ends = np.r_[0, cuts], np.r_[cuts - 1, n - 1]
        cluster = np.repeat(np.arange(len(starts)) // 2, ends - starts + 1)
        _check(
            xy,
            starts,
            ends,
            cluster,
            float(rng.choice([0.0, 0.01, 0.05, 0.3])),
            int(rng.choice([1, 2, 3, 64])),
            float(rng.choice([0.005, 0.02, 0.1, 1.0])),
        )


@pytest.mark.skipif(not CLIP.is_dir(), reason="../shared/data/kitti-hdl64-clip (real data) absent")
def test_split_and_merge_equal_the_reference_on_the_real_clip() -> None:
    """Every third scan's azimuth scan, cut into clusters at its occlusion breaks the way
    ``scan_corners`` does, with the default thresholds."""
    from datasets.lidar.corner_scan import _cluster_breaks
    from datasets.scan_folder import read_scan

    config = CornerConfig()
    for path in sorted(CLIP.glob("*.pcd"))[::3]:
        points = read_scan(path, 0.0).points
        chosen, bins = azimuth_scan_indices(points, config)
        xy = np.ascontiguousarray(points[chosen, :2])
        breaks = _cluster_breaks(xy, bins, config)
        cluster = np.zeros(len(xy), dtype=np.int64)
        np.cumsum(breaks[:-1], out=cluster[1:])
        boundaries = np.flatnonzero(breaks[:-1]) + 1
        starts, ends = np.r_[0, boundaries], np.r_[boundaries - 1, len(xy) - 1]
        big = ends - starts + 1 >= config.min_segment_points
        _check(
            xy, starts[big], ends[big], cluster, config.split_threshold_m, 64, config.merge_rms_m
        )
