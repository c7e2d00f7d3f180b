"""Are a recording's sweeps motion-compensated? Decided from its first clouds, by two seam
tests that need neither per-point times nor truth, and say how each point is timed.

A spinning lidar measures each point from where the sensor was at that point's firing time.
A sweep is cut at one encoder angle; each laser's cut lies at that angle plus its own
azimuth offset, so its first and last points are neighbours in azimuth but one sweep apart
in time. What the cut looks like depends on whether the sweep was compensated:

- **Raw** (not compensated): every point is where the sensor saw it from. On a surface whose
  range changes as the sensor moves (one facing the motion), a ring's range jumps at its
  cut by exactly the change one sweep makes at that azimuth, which the next cloud measures
  directly (same ring, same azimuth, one sweep later): with ``A`` the step from a point to
  its ring neighbour at the next larger azimuth and ``D`` the next cloud's range minus this
  one's at the same azimuth, ``A = D`` where the sweep turns clockwise (the point above the
  cut is the sweep's last) and ``A = -D`` counterclockwise (it is the first). Anywhere else neighbouring
  points are nearly simultaneous and ``A`` is a surface's own shape, unrelated to ``D``.
  The ground shows nothing (a ring on flat ground has the same radius from anywhere), so
  the test needs something to face behind or ahead of the cut. It gives the spin direction
  (the sign) and the cut's azimuth, from which the points are then timed
  (``sweep_times.azimuth_point_times``). Rings are points of one elevation (rows of
  ``ROW_DEG``), never the file's order: a KITTI file stores each ring from straight ahead
  counterclockwise, whatever the firing order was.
- **Compensated**: every point is moved to one time, so surfaces are continuous across the
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

Decision (``decide_sweep_timing``), from the first ``SweepOptions.frames`` clouds (10 by
default, one second at 10 Hz: enough for a cut to repeat in ``MIN_SEAM_FRAMES`` of them):

- clouds with per-point times keep them (nothing to decide);
- raw: at least ``MIN_SEAM_ROWS`` rings cut in one ``SEAM_BAND_DEG`` band in one direction,
  ``SEAM_DIRECTION_RATIO`` times as many as in the other, and no compensated cut on the
  ground: timed by azimuth from the cut found (direction and start stated in options win);
- compensated: a compensated cut on the ground (in ``CUT_FRACTION`` of the clouds), and
  fewer than ``MIN_SEAM_ROWS`` raw cuts in either direction;
- undecided otherwise: the sensor barely moved (no range change one sweep makes stands out
  of the noise), or nothing faced it where a cut could lie, or the tests disagree. The
  clouds are then read as the stated default (no times: as compensated), with a warning.

The thresholds are ratios to noise the clouds themselves show, or properties of any
spinning lidar (one cut per laser at a fixed azimuth, laser azimuth offsets within
``SEAM_BAND_DEG``), never fitted to one recording. On the shared KITTI clips, the synthetic
corridor (raw and compensated) and a sensor standing still: ``tests/test_sweep_timing.py``.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from datasets.lidar.sweep_times import (
    CLOCKWISE,
    COUNTERCLOCKWISE,
    AzimuthSweep,
    SweepOptions,
)
from datasets.measurements import PointCloud

ROW_DEG = 0.1
"""Elevation rows standing for rings [deg]: finer than any spinning lidar's ring spacing
(0.33 deg at the densest HDL-64E block, 2 deg on a 16-beam sensor), coarse enough that a
laser's points stay in one row over a few degrees of azimuth."""

MIN_RANGE_M = 0.5
"""Points nearer than this are the vehicle or noise, not a scene."""

SEAM_TOLERANCE = 0.25
"""A raw cut's step equals the one-sweep change ``D`` up to noise and the change over one
firing interval: within this fraction of ``|D|``; so must its neighbours' steps be small
(below this fraction of ``|D|``: a cut lies within a surface, clutter jumps everywhere)."""

SEAM_QUIET_NEIGHBOURS = 2
"""Steps either side of a cut that must be small (``SEAM_TOLERANCE``)."""

INFORMATIVE_NOISE = 4.0
"""A one-sweep range change ``|D|`` counts when above this many noise sigmas of a step."""

MIN_SEAM_FRAMES = 3
"""Clouds in which a ring must show its cut at the same azimuth (``SEAM_BIN_DEG``): a cut is
at a fixed encoder angle; clutter that mimics one does not repeat there."""

SEAM_BIN_DEG = 0.5
"""Azimuth bins in which a ring's cut must repeat [deg] (a few firing intervals)."""

SEAM_BAND_DEG = 30.0
"""Width of the band holding every ring's cut [deg]: one encoder angle plus each laser's
azimuth offset (the KITTI clips' HDL-64E rings cut at 171-195 deg)."""

MIN_SEAM_ROWS = 3
"""Rings that must show a raw cut in one band for the sweep to be read as raw."""

SEAM_DIRECTION_RATIO = 3.0
"""The direction found must show at least this many times the rings of the other one."""

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
class RawSeamEvidence:
    """The raw-cut test over a few clouds (module docstring).

    Attributes:
        rows: rings that show a raw cut, per direction (``CLOCKWISE``, ``COUNTERCLOCKWISE``):
            those in the best ``SEAM_BAND_DEG`` band.
        stray: rings with a raw cut outside that band, per direction.
        start_deg: the cut's azimuth (median of the band's rings) [deg, 0..360), per
            direction; None without rings.
        spread_deg: (first, last) cut azimuth in that band [deg], per direction.
        informative: ring neighbour pairs whose one-sweep change stands out of the noise.
        step_noise_m: noise sigma of a step between neighbours (1.4826 x median |step|).
    """

    rows: dict[int, int]
    stray: dict[int, int]
    start_deg: dict[int, float | None]
    spread_deg: dict[int, tuple[float, float] | None]
    informative: int
    step_noise_m: float


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


@dataclass(frozen=True)
class SweepTimingDecision:
    """What the clouds are read with, and why.

    Attributes:
        outcome: ``stated`` (``point_times=field``: nothing decided), ``times`` (the clouds
            carry per-point times), ``raw``, ``compensated`` or ``undecided``.
        point_times: what the loader applies: ``field`` (a cloud's own times, or none) or
            ``azimuth``.
        azimuth: the sweep timing when ``point_times == "azimuth"``, else None.
        source: ``data``, or ``options`` where the user stated point_times (or the sweep's
            direction and start).
        frames: clouds the decision read.
        evidence: the numbers behind it (JSON-serialisable).
        text: one line saying the decision and its evidence.
    """

    outcome: Literal["stated", "times", "raw", "compensated", "undecided"]
    point_times: Literal["field", "azimuth"]
    azimuth: AzimuthSweep | None
    source: Literal["data", "options"]
    frames: int
    evidence: dict[str, object] = field(default_factory=dict)
    text: str = ""
    warnings: tuple[str, ...] = ()

    @property
    def clear(self) -> bool:
        """Whether the decision is one to note rather than warn about."""
        return self.outcome != "undecided"

    def as_dict(self) -> dict[str, object]:
        """JSON-serialisable record (``Sequence.metadata["sweep_timing"]``)."""
        return {
            "outcome": self.outcome,
            "point_times": self.point_times,
            "source": self.source,
            "frames": self.frames,
            "direction": None
            if self.azimuth is None
            else ("clockwise" if self.azimuth.direction == CLOCKWISE else "counterclockwise"),
            "start_deg": None if self.azimuth is None else self.azimuth.start_deg,
            "sweep_s": None if self.azimuth is None else float(self.azimuth),
            "stamp": None if self.azimuth is None else self.azimuth.stamp,
            "evidence": self.evidence,
            "text": self.text,
        }


def _polar(points: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """A cloud (n, 3) [m] as (row, azimuth [deg, 0..360), range [m], key) sorted by row then
    azimuth; ``key = row * 360 + azimuth`` is then increasing, so one search finds a
    point's ring neighbour in another cloud."""
    points = np.asarray(points, dtype=float)
    ranges = np.linalg.norm(points, axis=1)
    keep = np.isfinite(ranges) & (ranges > MIN_RANGE_M)
    points, ranges = points[keep], ranges[keep]
    azimuth = np.mod(np.degrees(np.arctan2(points[:, 1], points[:, 0])), 360.0)
    elevation = np.degrees(np.arcsin(np.clip(points[:, 2] / ranges, -1.0, 1.0)))
    row = np.floor(elevation / ROW_DEG).astype(np.int64)
    order = np.lexsort((azimuth, row))
    row, azimuth, ranges = row[order], azimuth[order], ranges[order]
    return row, azimuth, ranges, row * 360.0 + azimuth


def _ring_steps(
    cloud: tuple[np.ndarray, ...], later: tuple[np.ndarray, ...]
) -> tuple[np.ndarray, ...]:
    """Ring neighbour pairs of ``cloud`` (``_polar``): (row, azimuth of the pair [deg], step
    ``A`` [m], one-sweep change at the lower point ``D_lower`` and at the upper one
    ``D_upper`` [m], whether the pair's neighbours' steps are known (lower, upper side)),
    with ``D`` from ``later`` (the next cloud; nan where it has no point of the ring within
    1.5 azimuth steps)."""
    row, azimuth, ranges, key = cloud
    later_row, later_azimuth, later_ranges, later_key = later
    same_ring = row[1:] == row[:-1]
    gaps = np.diff(azimuth)
    resolution = float(np.median(gaps[same_ring & (gaps > 0)])) if np.any(same_ring) else 1.0
    index = np.clip(np.searchsorted(later_key, key), 1, max(len(later_key) - 1, 1))
    if len(later_key) < 2:
        change = np.full(len(key), np.nan)
    else:
        nearer = np.abs(later_key[index - 1] - key) < np.abs(later_key[index] - key)
        index = np.where(nearer, index - 1, index)
        found = (later_row[index] == row) & (
            np.abs(later_azimuth[index] - azimuth) <= 1.5 * resolution
        )
        change = np.where(found, later_ranges[index] - ranges, np.nan)
    pair = same_ring & (gaps < 3.0 * resolution)
    return (
        row[:-1],
        0.5 * (azimuth[1:] + azimuth[:-1]),
        np.diff(ranges),
        change[:-1],
        change[1:],
        pair,
    )


def raw_seam_evidence(clouds: list[np.ndarray]) -> RawSeamEvidence:
    """The raw-cut test (module docstring) over consecutive ``clouds`` (lidar frame, (n, 3)
    [m], one sweep apart): per ring (elevation row) and direction, the azimuth bin where a
    step matching the one-sweep change repeats in ``MIN_SEAM_FRAMES`` clouds; then the
    ``SEAM_BAND_DEG`` band holding most such rings."""
    polar = [_polar(cloud) for cloud in clouds]
    steps = [_ring_steps(polar[k], polar[k + 1]) for k in range(len(polar) - 1)]
    pooled = np.concatenate([s[2][s[5]] for s in steps]) if steps else np.zeros(0)
    noise = float(1.4826 * np.median(np.abs(pooled))) if pooled.size else float("nan")
    threshold = INFORMATIVE_NOISE * noise
    hits: dict[int, list[np.ndarray]] = {CLOCKWISE: [], COUNTERCLOCKWISE: []}
    informative = 0
    for frame, (row, azimuth, step, lower, upper, pair) in enumerate(steps):
        with np.errstate(invalid="ignore"):
            informative += int(np.sum(pair & (np.abs(lower) >= threshold)))
            for direction, change in ((CLOCKWISE, lower), (COUNTERCLOCKWISE, upper)):
                # clockwise: the pair's upper point is the later one, A = +D at the lower
                # point; counterclockwise: the lower one is, A = -D at the upper point
                expected = -direction * change
                size = np.abs(change)
                match = (
                    pair & (size >= threshold) & (np.abs(step - expected) <= SEAM_TOLERANCE * size)
                )
                quiet = pair & (np.abs(step) <= SEAM_TOLERANCE * np.nan_to_num(size))
                for shift in range(1, SEAM_QUIET_NEIGHBOURS + 1):
                    before = np.concatenate([np.zeros(shift, bool), quiet[:-shift]])
                    after = np.concatenate([quiet[shift:], np.zeros(shift, bool)])
                    match &= before & after
                chosen = np.flatnonzero(match)
                hits[direction].append(
                    np.column_stack(
                        [
                            np.full(chosen.size, frame),
                            row[chosen],
                            np.floor(azimuth[chosen] / SEAM_BIN_DEG),
                            azimuth[chosen],
                        ]
                    )
                )
    rows, stray, start, spread = {}, {}, {}, {}
    for direction, found in hits.items():
        table = np.concatenate(found) if found else np.zeros((0, 4))
        cuts = _ring_cuts(table)
        members, others = _densest_band(cuts)
        rows[direction], stray[direction] = len(members), len(others)
        start[direction] = _circular_median(members) if len(members) else None
        spread[direction] = _band_limits(members) if len(members) else None
    return RawSeamEvidence(rows, stray, start, spread, informative, noise)


def _ring_cuts(table: np.ndarray) -> np.ndarray:
    """Per ring, the azimuth [deg] of its cut: the bin where matching steps repeat in most
    clouds, kept when that is at least ``MIN_SEAM_FRAMES`` (the mean azimuth of its
    steps). ``table`` rows: (frame, row, bin, azimuth)."""
    if not len(table):
        return np.zeros(0)
    keys = np.unique(table[:, :3], axis=0)  # one per (frame, ring, bin)
    cells, counts = np.unique(keys[:, 1:], axis=0, return_counts=True)
    cuts = []
    for ring in np.unique(cells[:, 0]):
        mine = cells[:, 0] == ring
        best = int(np.argmax(np.where(mine, counts, -1)))
        if counts[best] >= MIN_SEAM_FRAMES:
            inside = (table[:, 1] == ring) & (table[:, 2] == cells[best, 1])
            cuts.append(float(np.mean(table[inside, 3])))
    return np.array(cuts)


def _densest_band(azimuths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(the azimuths [deg] in the ``SEAM_BAND_DEG`` band, wrapping at 360, that holds the
    most of them; the rest)."""
    if not len(azimuths):
        return azimuths, azimuths
    offsets = np.mod(azimuths[None, :] - azimuths[:, None], 360.0)
    inside = offsets <= SEAM_BAND_DEG
    best = int(np.argmax(inside.sum(axis=1)))
    return azimuths[inside[best]], azimuths[~inside[best]]


def _circular_median(azimuths: np.ndarray) -> float:
    """The median azimuth [deg, 0..360) of azimuths within one band (unwrapped about the
    first)."""
    reference = azimuths[0]
    unwrapped = reference + (np.mod(azimuths - reference + 180.0, 360.0) - 180.0)
    return float(np.mod(np.median(unwrapped), 360.0))


def _band_limits(azimuths: np.ndarray) -> tuple[float, float]:
    """(first, last) azimuth [deg, 0..360) of one band's azimuths."""
    centre = _circular_median(azimuths)
    offsets = np.mod(azimuths - centre + 180.0, 360.0) - 180.0
    return (
        float(np.mod(centre + offsets.min(), 360.0)),
        float(np.mod(centre + offsets.max(), 360.0)),
    )


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


def decide_sweep_timing(
    clouds: list[PointCloud],
    sweep_s: float,
    point_times: str = "auto",
    options: SweepOptions | None = None,
) -> SweepTimingDecision:
    """How a recording's clouds are timed (module docstring), from its first ``clouds``
    (lidar frame, consecutive, one sweep of ``sweep_s`` [s] apart) and the options: with
    ``point_times`` ``field`` nothing is decided; with ``azimuth`` the sweeps are raw by the
    user's word and only the spin and start are sought; with ``auto`` everything is."""
    options = options or SweepOptions()
    frames = len(clouds)
    if point_times == "field":
        return SweepTimingDecision(
            "stated",
            "field",
            None,
            "options",
            frames,
            text="sweep timing: per-point times from the clouds' time field where they have "
            "one, none otherwise (taken as motion-compensated) (point_times=field, stated)",
        )
    timed = sum(cloud.point_times is not None for cloud in clouds)
    if point_times == "auto" and frames and 2 * timed >= frames:
        return SweepTimingDecision(
            "times",
            "field",
            None,
            "data",
            frames,
            {"clouds_with_times": timed},
            f"sweep timing: {timed} of the first {frames} clouds carry per-point times: "
            "read with them (the sensor's own timing)",
        )
    points = [np.asarray(cloud.points, dtype=float) for cloud in clouds]
    stated = options.direction != "auto" and options.start_deg is not None
    seams = raw_seam_evidence(points) if len(points) >= 2 else None
    motion = sweep_motion(points, sweep_s) if len(points) >= 2 else np.eye(4)
    cut = compensated_cut_evidence(points, motion) if len(points) >= 2 else None
    travel = float(np.linalg.norm(motion[:2, 3]))
    evidence: dict[str, object] = {
        "frames": frames,
        "sweep_s": float(sweep_s),
        "travel_m_per_sweep": round(travel, 4),
        "yaw_deg_per_sweep": round(float(np.degrees(np.arctan2(motion[1, 0], motion[0, 0]))), 3),
    }
    if seams is not None:
        evidence.update(
            {
                "raw_cut_rings_clockwise": seams.rows[CLOCKWISE],
                "raw_cut_rings_counterclockwise": seams.rows[COUNTERCLOCKWISE],
                "raw_cut_rings_stray_clockwise": seams.stray[CLOCKWISE],
                "raw_cut_rings_stray_counterclockwise": seams.stray[COUNTERCLOCKWISE],
                "informative_ring_pairs": seams.informative,
                "step_noise_m": round(seams.step_noise_m, 4),
            }
        )
    if cut is not None:
        evidence.update(
            {
                "compensated_cut_ratio": None if np.isnan(cut.ratio) else round(cut.ratio, 2),
                "compensated_cut_at_deg": cut.at_deg,
                "compensated_cut_shift_m": round(cut.shift_m, 4),
                "ground_covered_deg": cut.covered_deg,
                "ground_noise_m": None if np.isnan(cut.noise_m) else round(cut.noise_m, 4),
                "compensated_cut_clouds_fraction": round(cut.fraction, 2),
            }
        )
    raw_direction = _raw_direction(seams)
    compensated = cut is not None and cut.found
    raw_rings = 0 if seams is None else max(seams.rows.values())
    found = _found_text(seams, raw_direction, cut, travel)
    if raw_direction is not None:
        evidence["start_deg_found"] = round(float(seams.start_deg[raw_direction]), 2)
        evidence["cut_spread_deg"] = [round(v, 2) for v in seams.spread_deg[raw_direction]]
    if point_times == "azimuth":
        azimuth, how = _azimuth_timing(sweep_s, options, seams, raw_direction)
        warnings = ()
        if compensated and raw_direction is None:
            warnings = (
                f"sweep timing: point_times=azimuth is stated, but the first {frames} clouds "
                f"look motion-compensated ({found}); timed by azimuth as asked",
            )
        if how == "KITTI raw's convention":
            warnings += (
                f"sweep timing: point_times=azimuth: no sweep cut found in the first {frames} "
                f"clouds ({found}); KITTI raw's convention used (clockwise from 180 deg); "
                "state --data sweep.direction=... sweep.start_deg=... if the lidar is another",
            )
        return SweepTimingDecision(
            "raw",
            "azimuth",
            azimuth,
            "options",
            frames,
            evidence,
            f"sweep timing: per-point times from azimuth, {azimuth.describe()} "
            f"(point_times=azimuth stated; direction and start {how}): {found}",
            warnings,
        )
    if raw_direction is not None and not compensated:
        azimuth, how = _azimuth_timing(sweep_s, options, seams, raw_direction)
        return SweepTimingDecision(
            "raw",
            "azimuth",
            azimuth,
            "options" if stated else "data",
            frames,
            evidence,
            f"sweep timing: raw sweeps (not motion-compensated) in the first {frames} clouds: "
            f"{found}; per-point times from azimuth, {azimuth.describe()} (direction and "
            f"start {how}; override: --data point_times=field|azimuth, sweep.direction, "
            "sweep.start_deg, sweep.stamp)",
        )
    if compensated and raw_rings < MIN_SEAM_ROWS:
        return SweepTimingDecision(
            "compensated",
            "field",
            None,
            "data",
            frames,
            evidence,
            f"sweep timing: motion-compensated sweeps in the first {frames} clouds: {found}; "
            "read without per-point times (override: --data point_times=azimuth)",
        )
    why = _undecided_reason(seams, cut, compensated, raw_direction, travel)
    text = (
        f"sweep timing undecided from the first {frames} clouds: {why} ({found}); read "
        "without per-point times, as motion-compensated; if the sweeps are raw, state "
        "--data point_times=azimuth (and sweep.direction, sweep.start_deg)"
    )
    return SweepTimingDecision("undecided", "field", None, "data", frames, evidence, text, (text,))


def _raw_direction(seams: RawSeamEvidence | None) -> int | None:
    """The spin direction whose raw cuts pass the thresholds (module docstring), or None."""
    if seams is None:
        return None
    for direction, other in ((CLOCKWISE, COUNTERCLOCKWISE), (COUNTERCLOCKWISE, CLOCKWISE)):
        rows = seams.rows[direction]
        if rows >= MIN_SEAM_ROWS and rows >= SEAM_DIRECTION_RATIO * seams.rows[other]:
            return direction
    return None


def _azimuth_timing(
    sweep_s: float, options: SweepOptions, seams: RawSeamEvidence | None, found: int | None
) -> tuple[AzimuthSweep, str]:
    """The azimuth timing: stated direction and start win, then the cut found, then KITTI
    raw's convention; and which it was."""
    direction = {"clockwise": CLOCKWISE, "counterclockwise": COUNTERCLOCKWISE}.get(
        options.direction, found
    )
    start = options.start_deg
    if start is None and found is not None and direction == found:
        start = seams.start_deg[found]
    sources = []
    if options.direction != "auto":
        sources.append("direction stated")
    if options.start_deg is not None:
        sources.append("start stated")
    if direction is None or start is None:
        if direction is None and start is None:
            return AzimuthSweep(sweep_s, CLOCKWISE, 180.0, options.stamp), "KITTI raw's convention"
        how = ", ".join(sources) + ", the rest KITTI raw's convention"
        return (
            AzimuthSweep(
                sweep_s,
                CLOCKWISE if direction is None else direction,
                180.0 if start is None else start,
                options.stamp,
            ),
            how,
        )
    how = ", ".join(sources) if sources else "found in the data"
    if sources and len(sources) < 2:
        how += ", the rest found in the data"
    return AzimuthSweep(sweep_s, direction, start, options.stamp), how


def _found_text(
    seams: RawSeamEvidence | None,
    direction: int | None,
    cut: CompensatedCutEvidence | None,
    travel: float,
) -> str:
    """The evidence in words."""
    parts = []
    if seams is not None:
        cw, ccw = seams.rows[CLOCKWISE], seams.rows[COUNTERCLOCKWISE]
        if direction is not None:
            low, high = seams.spread_deg[direction]
            spin = "clockwise" if direction == CLOCKWISE else "counterclockwise"
            parts.append(
                f"{seams.rows[direction]} rings ({ccw if direction == CLOCKWISE else cw} the "
                f"other way) step at their cut, {low:.0f}-{high:.0f} deg, by the range change "
                f"one sweep makes there: {spin}"
            )
        else:
            parts.append(
                f"raw cuts in {cw} rings clockwise, {ccw} counterclockwise (of "
                f"{seams.informative} ring pairs changing by over "
                f"{INFORMATIVE_NOISE * seams.step_noise_m:.3f} m in a sweep)"
            )
    if cut is not None:
        if cut.covered_deg == 0:
            parts.append("no ground where the motion would show a compensated cut")
        elif cut.found:
            parts.append(
                f"a compensated cut on the ground at {cut.at_deg:.0f} deg in "
                f"{100 * cut.fraction:.0f} % of the clouds (rings line up {cut.ratio:.0f}x "
                f"better shifted by the {cut.shift_m:.3f} m travel there)"
            )
        else:
            parts.append(
                f"no compensated cut on the ground (at most in {100 * cut.fraction:.0f} % of "
                f"the clouds; {cut.covered_deg:.0f} deg of azimuth could show one)"
            )
    parts.append(f"travel {travel:.3f} m per sweep")
    return "; ".join(parts)


def _undecided_reason(
    seams: RawSeamEvidence | None,
    cut: CompensatedCutEvidence | None,
    compensated: bool,
    direction: int | None,
    travel: float,
) -> str:
    """Why neither outcome holds."""
    if seams is None or cut is None:
        return "fewer than two clouds"
    if direction is not None and compensated:
        return "both a raw cut and a compensated one show: the tests disagree"
    if compensated:
        return f"a compensated cut shows, but so do raw cuts in {max(seams.rows.values())} rings"
    if np.isfinite(cut.noise_m) and travel < CUT_NOISE * cut.noise_m:
        return (
            f"the sensor barely moves (under {CUT_NOISE:g}x the ground rings' alignment noise, "
            f"{cut.noise_m:.4f} m, per sweep): no cut can stand out"
        )
    if max(seams.rows.values()) >= MIN_SEAM_ROWS:
        return "raw cuts show in both spin directions"
    return (
        "no cut shows where the motion would show one (nothing faces the sensor there, or no "
        "flat ground)"
    )
