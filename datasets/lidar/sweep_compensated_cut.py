"""The compensated-cut test of the sweep timing decision (``datasets.lidar.sweep_timing``):
do a recording's first clouds show the cut of a motion-compensated sweep on the ground, given
the sensor's motion over one sweep (``sweep_motion``)?

**Compensated**: every point is moved to one time, so surfaces are continuous across the
cut, but the rings are not: a ring on flat ground is a circle about where the sensor was
when it fired, so at the cut it jumps from one circle to the other by the distance
travelled in one sweep projected on the ray (``Delta . u``). Comparing the ground points'
horizontal ranges either side of an azimuth, the two sets of ring radii line up as they
are when the sweep is raw, and line up only after shifting one side by ``+-Delta . u``
at a compensated cut, which is isolated (the rings line up a few degrees to either side)
and repeats in most clouds. ``Delta`` is the recording's own motion: KISS-ICP over the
same clouds, as read (consecutive raw sweeps distort alike, so their registration is
not). Walls alone show nothing here (a compensated cloud is continuous), nor does a cut
at the sides of a forward motion (``Delta . u`` = 0).

The recording shows one where ``CUT_FRACTION`` of the clouds that see ground there do
(``CompensatedCutEvidence.found``).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass

import numpy as np

from datasets.lidar.sweep_raw_cut import MIN_SEAM_FRAMES
from datasets.measurements import PointCloud

GROUND_BAND_M = 0.08
"""Ground points lie within this of the ground level (the densest 2 cm height bin below the
sensor within ``GROUND_RANGE_M``) [m]."""

GROUND_RANGE_M = (2.0, 30.0)
"""Horizontal ranges searched for ground [m]."""

CUT_WINDOW_DEG = 2.0
"""Azimuth window either side of a candidate compensated cut [deg]."""

MIN_WINDOW_POINTS = 20
"""Ground points a window needs to stand for a ring set."""

CUT_NOISE = 5.0
"""A compensated cut is sought only where the motion would shift the rings by this many
times the alignment noise (the median ring misalignment between neighbouring windows)."""

CUT_RATIO = 3.0
"""At a compensated cut the rings line up this many times better shifted by the motion
than as they are."""

CUT_SHIFTS = (0.6, 0.7, 0.8, 0.9, 1.0, 1.1, 1.2, 1.3, 1.4)
"""Fractions of the predicted shift tried: KISS-ICP's first increments fall short of the
motion where little constrains it (0.07-0.12 m of 0.15 m in the synthetic corridor)."""

CUT_ASIDE_DEG = 4.0
"""Where a window no longer straddles a cut [deg] (twice ``CUT_WINDOW_DEG``)."""

CUT_ISOLATION = 3.0
"""A cut's misalignment as read is this many times that ``CUT_ASIDE_DEG`` to either side."""

CUT_FRACTION = 0.7
"""Share of the clouds seeing ground at an azimuth that must show the cut there."""


@dataclass(frozen=True)
class CompensatedCutEvidence:
    """The compensated-cut test over a few clouds (module docstring).

    Attributes:
        ratio: at the azimuth where most clouds show a cut (ties: the larger ratio), the
            median over those clouds of the ring misalignment as read over that after
            shifting by the motion; nan where no cloud shows one.
        at_deg: that azimuth [deg], or None.
        shift_m: the shift the motion predicts there [m].
        covered_deg: degrees of azimuth where the motion would show a cut on the ground.
        noise_m: the alignment noise (median misalignment of neighbouring windows) [m].
        fraction: share of the clouds seeing ground at ``at_deg`` that show a cut there.
    """

    ratio: float
    at_deg: float | None
    shift_m: float
    covered_deg: float
    noise_m: float
    fraction: float

    @property
    def found(self) -> bool:
        """Whether a compensated cut shows (in ``CUT_FRACTION`` of the clouds)."""
        return bool(self.fraction >= CUT_FRACTION)


def sweep_motion(clouds: list[np.ndarray], sweep_s: float) -> np.ndarray:
    """The sensor's motion over one sweep, (4, 4) in the lidar frame: the median of
    KISS-ICP's increments over consecutive ``clouds`` registered as read (no deskew)."""
    from datasets.lidar.kiss_icp_odometry import KissIcpOdometry, KissIcpSettings
    from datasets.rotations import so3_log

    odometry = KissIcpOdometry(KissIcpSettings(deskew=False, max_num_threads=1))
    increments = []
    for index, points in enumerate(clouds):
        odometry.register(PointCloud(t=index * sweep_s, points=np.asarray(points, dtype=float)))
        if index:
            increments.append(odometry.last_delta())
    if not increments:
        return np.eye(4)
    increments = np.array(increments)
    motion = np.eye(4)
    motion[:3, 3] = np.median(increments[:, :3, 3], axis=0)
    yaw = float(np.median([so3_log(delta[:3, :3])[2] for delta in increments]))
    motion[:2, :2] = [[np.cos(yaw), -np.sin(yaw)], [np.sin(yaw), np.cos(yaw)]]
    return motion


def _ground(points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Ground points of a cloud (n, 3) [m] as (azimuth [deg, 0..360) sorted, horizontal
    range [m]): within ``GROUND_BAND_M`` of the densest 2 cm height bin below the sensor."""
    points = np.asarray(points, dtype=float)
    horizontal = np.hypot(points[:, 0], points[:, 1])
    low, high = GROUND_RANGE_M
    below = (horizontal > low) & (horizontal < high) & (points[:, 2] < 0.0)
    if np.count_nonzero(below) < MIN_WINDOW_POINTS:
        return np.zeros(0), np.zeros(0)
    heights = points[below, 2]
    counts, edges = np.histogram(heights, bins=np.arange(heights.min(), 0.02, 0.02))
    if not len(counts):
        return np.zeros(0), np.zeros(0)
    level = edges[int(np.argmax(counts))] + 0.01
    ground = below & (np.abs(points[:, 2] - level) <= GROUND_BAND_M)
    azimuth = np.mod(np.degrees(np.arctan2(points[ground, 1], points[ground, 0])), 360.0)
    order = np.argsort(azimuth)
    return azimuth[order], horizontal[ground][order]


def _thinned(values: np.ndarray, most: int = 200) -> np.ndarray:
    """At most ``most`` of ``values``, evenly picked (a median needs no more)."""
    return values if len(values) <= most else values[:: int(np.ceil(len(values) / most))]


def _misalignment(reference: np.ndarray, values: np.ndarray) -> float:
    """Median distance [m] of ``values`` to the nearest of ``reference`` (sorted)."""
    index = np.clip(np.searchsorted(reference, values), 1, len(reference) - 1)
    return float(
        np.median(
            np.minimum(np.abs(reference[index - 1] - values), np.abs(reference[index] - values))
        )
    )


def compensated_cut_evidence(
    clouds: list[np.ndarray], motion: np.ndarray
) -> CompensatedCutEvidence:
    """The compensated-cut test (module docstring) over ``clouds`` (lidar frame) with the
    sensor's ``motion`` over one sweep (``sweep_motion``): at each whole degree, the ground's
    ring radii just below it against those just above it, as read and shifted by about
    ``+-Delta . u`` (``CUT_SHIFTS`` of it: KISS-ICP's first increments may be short of the
    motion). A cloud shows a cut there when the shift lines the rings up ``CUT_RATIO``
    times better and the misalignment as read is isolated (``CUT_ISOLATION`` times that
    ``CUT_ASIDE_DEG`` to either side, where no window straddles the cut: a curb or a slope
    misaligns a whole stretch, and nearly even ring spacing can line up a wrong shift); the
    recording shows one where most clouds that see ground there do."""
    edges = np.arange(360.0)
    directions = np.column_stack([np.cos(np.radians(edges)), np.sin(np.radians(edges))])
    shifts = np.abs(directions @ motion[:2, 3])
    as_read = np.full((len(clouds), len(edges)), np.nan)
    shifted = np.full((len(clouds), len(edges)), np.nan)
    windows = []
    for index, points in enumerate(clouds):
        azimuth, horizontal = _ground(points)
        windows.append(None)
        if len(azimuth) < 2 * MIN_WINDOW_POINTS:
            continue
        # windows by index ranges of the sorted azimuths (with the wrap at 360)
        wrapped = np.concatenate([azimuth - 360.0, azimuth, azimuth + 360.0])
        radii = np.concatenate([horizontal] * 3)
        lower = np.searchsorted(wrapped, edges - CUT_WINDOW_DEG)
        middle = np.searchsorted(wrapped, edges)
        upper = np.searchsorted(wrapped, edges + CUT_WINDOW_DEG)
        windows[index] = (radii, lower, middle, upper)
        for k in range(len(edges)):
            below, above = radii[lower[k] : middle[k]], radii[middle[k] : upper[k]]
            if len(below) >= MIN_WINDOW_POINTS and len(above) >= MIN_WINDOW_POINTS:
                as_read[index, k] = _misalignment(np.sort(below), _thinned(above))
    with np.errstate(invalid="ignore"):
        aside = np.fmax(
            np.roll(as_read, int(CUT_ASIDE_DEG), axis=1),
            np.roll(as_read, -int(CUT_ASIDE_DEG), axis=1),
        )
        isolated = as_read >= CUT_ISOLATION * aside
    # the shifts only where the misalignment as read is isolated (few places)
    for index, k in zip(*np.nonzero(isolated)):
        radii, lower, middle, upper = windows[index]
        below = np.sort(radii[lower[k] : middle[k]])
        above = _thinned(radii[middle[k] : upper[k]])
        shifted[index, k] = min(
            _misalignment(below, above - sign * factor * shifts[k])
            for sign in (1.0, -1.0)
            for factor in CUT_SHIFTS
        )
    with np.errstate(invalid="ignore", divide="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # all-nan medians: nothing measured
        measured = np.isfinite(as_read)
        noise = float(np.nanmedian(as_read)) if np.any(measured) else float("nan")
        ratio = np.where(isolated, as_read / np.maximum(shifted, 1e-12), 0.0)
        ratio[~measured] = np.nan
        shows = isolated & (ratio >= CUT_RATIO)
        seen = measured.sum(axis=0)
        # a compensated cut is at the same azimuth in every cloud: judged where at least half
        # of them (and MIN_SEAM_FRAMES) have ground either side, and where the motion would
        # shift the rings by CUT_NOISE times the alignment noise
        covered = (shifts >= CUT_NOISE * noise) & (seen >= max(MIN_SEAM_FRAMES, 0.5 * len(clouds)))
        fraction = np.where(covered, shows.sum(axis=0) / np.maximum(seen, 1), np.nan)
        typical = np.where(
            covered & np.any(shows, axis=0),
            np.nanmedian(np.where(shows, ratio, np.nan), axis=0),
            np.nan,
        )
    if not np.any(covered):
        return CompensatedCutEvidence(float("nan"), None, 0.0, 0.0, noise, 0.0)
    best = int(np.nanargmax(fraction + 1e-6 * np.nan_to_num(typical)))
    if not fraction[best] > 0:
        return CompensatedCutEvidence(float("nan"), None, 0.0, float(covered.sum()), noise, 0.0)
    return CompensatedCutEvidence(
        float(typical[best]),
        float(edges[best]),
        float(shifts[best]),
        float(covered.sum()),
        noise,
        float(fraction[best]),
    )
