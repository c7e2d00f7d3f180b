"""The raw-cut test of the sweep timing decision (``datasets.lidar.sweep_timing``): do a
recording's first clouds show the cut of a sweep that was not motion-compensated, and where
and which way does the sensor spin?

A spinning lidar measures each point from where the sensor was at that point's firing time.
A sweep is cut at one encoder angle; each laser's cut lies at that angle plus its own
azimuth offset, so its first and last points are neighbours in azimuth but one sweep apart
in time.

**Raw** (not compensated): every point is where the sensor saw it from. On a surface whose
range changes as the sensor moves (one facing the motion), a ring's range jumps at its
cut by exactly the change one sweep makes at that azimuth, which the next cloud measures
directly (same ring, same azimuth, one sweep later): with ``A`` the step from a point to
its ring neighbour at the next larger azimuth and ``D`` the next cloud's range minus this
one's at the same azimuth, ``A = D`` where the sweep turns clockwise (the point above the
cut is the sweep's last) and ``A = -D`` counterclockwise (it is the first). Anywhere else
neighbouring points are nearly simultaneous and ``A`` is a surface's own shape, unrelated to
``D``. The ground shows nothing (a ring on flat ground has the same radius from anywhere), so
the test needs something to face behind or ahead of the cut. It gives the spin direction
(the sign) and the cut's azimuth, from which the points are then timed
(``sweep_times.azimuth_point_times``). Rings are points of one elevation (rows of
``ROW_DEG``), never the file's order: a KITTI file stores each ring from straight ahead
counterclockwise, whatever the firing order was.

The test's verdict (``_raw_direction``): at least ``MIN_SEAM_ROWS`` rings cut in one
``SEAM_BAND_DEG`` band in one direction, ``SEAM_DIRECTION_RATIO`` times as many as in the
other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.lidar.sweep_times import CLOCKWISE, COUNTERCLOCKWISE

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


def _raw_direction(seams: RawSeamEvidence | None) -> int | None:
    """The spin direction whose raw cuts pass the thresholds (module docstring), or None."""
    if seams is None:
        return None
    for direction, other in ((CLOCKWISE, COUNTERCLOCKWISE), (COUNTERCLOCKWISE, CLOCKWISE)):
        rows = seams.rows[direction]
        if rows >= MIN_SEAM_ROWS and rows >= SEAM_DIRECTION_RATIO * seams.rows[other]:
            return direction
    return None
