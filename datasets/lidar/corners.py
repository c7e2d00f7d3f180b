"""Corner landmarks from a lidar cloud: slab, azimuth scan, clusters, split-and-merge lines,
corners where two lines meet at a sufficient angle.

Pipeline (vectorized numpy over points, except the split and merge loops of step 4, which
are compiled: ``corner_kernels``):

1. **Slab**: points within ``slab_half_thickness_m`` of ``slab_height_m`` (body z) and in
   ``[min_range_m, max_range_m]`` horizontally, projected to the x-y plane.
2. **Azimuth scan**: one point per azimuth bin (nearest the slab centre) of ``azimuth_resolution_deg``, ordered
   by azimuth: a 2-D laser scan, like the range finders the sensor-based SLAM paper
   (Guerreiro et al.) extracts its corners from.
3. **Clusters**: the scan breaks where consecutive points jump by more than
   ``break_distance_m + break_range_ratio * range`` or where ``max_gap_bins`` bins are
   empty (occlusion boundaries are never corners). The circular scan starts after a break.
4. **Split-and-merge** (Pavlidis and Horowitz 1974, "Segmentation of plane curves", the
   sensor-based paper's ref. [35]): a segment whose farthest point lies more than
   ``split_threshold_m`` from its end-point chord is split there (iterative end-point fit);
   then adjacent segments whose joint total-least-squares fit has an RMS residual below
   ``merge_rms_m`` are merged. With ``refine_boundaries`` (the 2-D laser front end,
   ``datasets.laser2d``), each boundary between adjacent segments of a cluster is then moved
   to the break where the two lines fit best (``refine_boundaries``).
5. **Lines**: total least squares per segment (``end_trim_points`` trimmed at each end, where
   the two faces of a corner mix). Guerreiro et al. (Sec. VI) fit lines with a reduced-space
   Hough transform instead; TLS is the closed-form choice here, with a first-order covariance.
   Like the paper, the slab assumes a level sensor: on a tilted platform, level the cloud with
   the attitude first (the paper projects the profile with roll and pitch).
6. **Corners**: consecutive segments of one cluster whose directions differ by at least
   ``min_corner_angle_deg`` (and at most 180 minus it) and whose line intersection lies
   within ``max_corner_gap_m`` of both segments' facing ends (with ``refine_boundaries``,
   where adjacent segments share no point: of the bridge between those ends). The corner is the
   intersection; its covariance is propagated from the range/bearing noise of the points
   (``corner_covariance``), plus an isotropic ``model_sigma_m`` floor for errors the point
   model leaves out. The floor was set where detections on the synthetic corridor bag
   scattered 1.8 cm RMS about the true corners and the point model alone predicted 1.2 cm.
   The same bag now reads 1.4 cm RMS (body x +0.6 +- 1.1 cm, y +0.1 +- 0.5 cm, horizontal
   NEES 0.34 per dof; ``benchmarks/bench_lidar_bag_consistency.py``); which later change
   of the front end made the difference was not traced. On the real KITTI clip the corners'
   re-observation NIS is 0.76 per dof with the floor, so it stays. 3-D corners take the slab
   height.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.lidar.corner_kernels import merge_segments_kernel, split_segments_kernel
from datasets.measurements import LandmarkScan


class CornerConfig(BaseModel):
    """Parameters of the corner extractor."""

    model_config = ConfigDict(extra="forbid")

    slab_height_m: float = Field(0.0, description="slab centre in the body frame (z) [m]")
    slab_half_thickness_m: float = Field(0.25, gt=0, description="half thickness of the slab [m]")
    min_range_m: float = Field(0.5, ge=0, description="nearest horizontal range used [m]")
    max_range_m: float = Field(15.0, gt=0, description="farthest horizontal range used [m]")
    azimuth_resolution_deg: float = Field(
        0.25, gt=0, description="azimuth bin of the 2-D scan [deg]"
    )
    range_sigma_m: float = Field(0.02, gt=0, description="range noise std of a point [m]")
    bearing_sigma_rad: float = Field(0.003, gt=0, description="bearing noise std of a point [rad]")
    break_distance_m: float = Field(
        0.2, gt=0, description="cluster break: fixed part of the jump [m]"
    )
    break_range_ratio: float = Field(
        0.05, ge=0, description="cluster break: part of the jump proportional to range"
    )
    max_gap_bins: int = Field(4, ge=1, description="cluster break: this many empty azimuth bins")
    split_threshold_m: float = Field(
        0.06,
        gt=0,
        description="split a segment whose farthest point is this far from its chord [m]",
    )
    merge_rms_m: float = Field(
        0.03, gt=0, description="merge adjacent segments whose joint line fit RMS is below this [m]"
    )
    min_segment_points: int = Field(6, ge=3, description="fewest points of a line segment")
    min_segment_length_m: float = Field(0.25, gt=0, description="shortest line segment [m]")
    end_trim_points: int = Field(
        1, ge=0, description="points left out of the line fit at each segment end"
    )
    refine_boundaries: bool = Field(
        False,
        description="move each boundary between adjacent segments of a cluster to where the "
        "two lines fit best (least total squared distance; refine_boundaries below)",
    )
    min_fit_points: int | None = Field(
        None,
        ge=2,
        description="fewest points a trimmed line fit keeps; a segment with fewer after the "
        "trim is fitted untrimmed (None: min_segment_points)",
    )
    min_corner_angle_deg: float = Field(
        35.0, gt=0, lt=90, description="least angle between the two lines of a corner [deg]"
    )
    max_corner_gap_m: float = Field(
        0.3, gt=0, description="farthest the intersection may be from either segment end [m]"
    )
    directions: bool = Field(
        False, description="also output the two unit line directions of every corner"
    )
    dimension: int = Field(
        3, ge=2, le=3, description="2: planar corners; 3: corners at the slab height"
    )
    slab_sigma_m: float | None = Field(
        None, description="std of a 3-D corner's z [m] (default: half thickness / sqrt(3))"
    )
    model_sigma_m: float = Field(
        0.015,
        ge=0,
        description="isotropic horizontal std added to every corner for what the point noise model leaves out (deskew and odometry error, beam width) [m]",
    )


@dataclass(frozen=True)
class Corners:
    """Corners of one cloud, in the body frame.

    Attributes:
        points: (k, d) [m].
        covariances: (k, d, d) [m^2].
        directions: (k, 2, d) unit directions along the two lines away from the corner, or None.
        segments: (m, 2, 2) end points of every fitted line segment [m] (for plots, debugging).
    """

    points: np.ndarray
    covariances: np.ndarray
    directions: np.ndarray | None
    segments: np.ndarray

    def scan(self, t: float) -> LandmarkScan:
        """As a ``LandmarkScan`` at time ``t`` (no ids: the front end does not know them)."""
        return LandmarkScan(
            t=t, points=self.points, covariances=self.covariances, directions=self.directions
        )


def azimuth_scan(points: np.ndarray, config: CornerConfig) -> tuple[np.ndarray, np.ndarray]:
    """The azimuth scan: xy (m, 2) [m] ordered by azimuth, and their bin indices (m,)."""
    indices, bins = azimuth_scan_indices(points, config)
    return points[:, :2].take(indices, axis=0), bins


def azimuth_scan_indices(points: np.ndarray, config: CornerConfig) -> tuple[np.ndarray, np.ndarray]:
    """Indices of the slab points of ``points`` (n, 3) [m] that make the azimuth scan (steps
    1-2): one point per azimuth bin (the one nearest the slab centre; among equally near
    ones, the one nearest the bin's centre azimuth), ordered by azimuth; and the bin of
    each (m,)."""
    # The slab test is the only pass over the whole cloud (120k points on KITTI, reached with
    # the cloud out of the caches, so reading its z costs most of this function): abs in
    # place rather than a second temporary, and the slab's rows gathered in one take rather
    # than two fancy-indexed columns (together 650 -> 390 us on a cold KITTI cloud).
    offset = points[:, 2] - config.slab_height_m
    np.abs(offset, out=offset)
    keep = np.flatnonzero(offset <= config.slab_half_thickness_m)  # cheap test first
    slab = points.take(keep, axis=0)
    x, y = slab[:, 0], slab[:, 1]
    squared_range = x * x + y * y
    inside = np.flatnonzero(
        (squared_range >= config.min_range_m**2) & (squared_range <= config.max_range_m**2)
    )
    keep, x, y = keep.take(inside), x.take(inside), y.take(inside)
    offset = offset.take(keep)
    resolution = np.deg2rad(config.azimuth_resolution_deg)
    azimuth = (np.arctan2(y, x) + np.pi) / resolution  # in bins
    bins = np.floor(azimuth).astype(np.int64)
    total_bins = int(np.ceil(2.0 * np.pi / resolution)) + 1
    # Per bin, the point nearest the slab centre (the most horizontal ring): unlike the
    # nearest point, it does not bias ranges short when several rings share a bin. Ties
    # are common (KITTI's z is quantised to 1 mm: a quarter of the bins) and go to the point
    # nearest the bin's centre azimuth, which keeps the scan's azimuth sampling regular
    # and does not depend on the order of the points in the file. The tie-break matters:
    # on the real KITTI clip the corner re-observation NIS/dof reads 0.68-1.22 across
    # six tie-breaks (first or last in the file, nearest or farthest, this one 0.91; an
    # unstable sort gave 0.76), so a difference of that size there is not a finding.
    # Per-bin minima and no sort of the slab: O(n), 2x faster on KITTI scans.
    nearest = np.full(total_bins, np.inf)
    np.minimum.at(nearest, bins, offset)
    winners = np.flatnonzero(offset == nearest[bins])
    winner_bins = bins[winners]
    from_centre = np.abs(azimuth[winners] - winner_bins - 0.5)
    most_central = np.full(total_bins, np.inf)
    np.minimum.at(most_central, winner_bins, from_centre)
    winners = winners[from_centre == most_central[winner_bins]]
    # exact ties left: the first in the file (winners ascend); read in bin order, the
    # per-bin minima are the scan (as np.unique's first occurrences, without its sort)
    first = np.full(total_bins, len(keep))
    np.minimum.at(first, bins[winners], winners)
    chosen = first[first < len(keep)]
    return keep[chosen], bins[chosen]


def _cluster_breaks(xy: np.ndarray, bins: np.ndarray, config: CornerConfig) -> np.ndarray:
    """``breaks[i]``: the circular scan breaks between point i and i+1 (step 3)."""
    total_bins = int(np.ceil(360.0 / config.azimuth_resolution_deg))
    jump = _norms(_rotated(xy, 1) - xy)
    ranges = np.hypot(xy[:, 0], xy[:, 1])
    rng = np.minimum(ranges, _rotated(ranges, 1))
    gap = np.mod(_rotated(bins, 1) - bins, total_bins)
    return (jump > config.break_distance_m + config.break_range_ratio * rng) | (
        gap > config.max_gap_bins
    )


def _rotated(values: np.ndarray, shift: int) -> np.ndarray:
    """``values`` (m, ...) starting at row ``shift`` (0 <= shift <= m), the rows before it
    moved to the end: ``np.roll(values, -shift, axis=0)`` without its overhead."""
    return np.concatenate([values[shift:], values[:shift]])


def _norms(vectors: np.ndarray) -> np.ndarray:
    """Euclidean norms (k,) of the rows of ``vectors`` (k, 2), bit for bit as
    ``np.linalg.norm(vectors, axis=1)`` computes them (the square root of x*x + y*y), at a
    fraction of its cost on these small arrays: a reduction along rows of two is slow."""
    x, y = vectors[:, 0], vectors[:, 1]
    return np.sqrt(x * x + y * y)


def _no_corners(config: CornerConfig) -> Corners:
    """The result without corners, shaped for ``config``."""
    d = config.dimension
    return Corners(
        np.zeros((0, d)),
        np.zeros((0, d, d)),
        np.zeros((0, 2, d)) if config.directions else None,
        np.zeros((0, 2, 2)),
    )


def _flat_indices(starts: np.ndarray, ends: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Point indices of inclusive ranges ``[starts, ends]`` concatenated, and their range ids."""
    lengths = ends - starts + 1
    owners = np.arange(len(starts)).repeat(lengths)
    offsets = lengths.cumsum() - lengths
    return np.arange(len(owners)) + (starts - offsets)[owners], owners


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


def _bridge_distance(points: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Distance (k,) [m] of each of ``points`` (k, 2) from the segment joining ``starts``
    (k, 2) to ``ends`` (k, 2)."""
    span = ends - starts
    length2 = np.maximum(np.sum(span * span, axis=1), 1e-24)
    along = np.clip(np.sum((points - starts) * span, axis=1) / length2, 0.0, 1.0)
    return _norms(points - (starts + along[:, None] * span))


def _residual_sum(moments: _Moments) -> np.ndarray:
    """Total-least-squares residual sum of squares of each range (m,) [m^2]: ``n`` times the
    smaller eigenvalue of the central second-moment matrix."""
    _, cxx, cxy, cyy = moments._centred()
    half_trace = 0.5 * (cxx + cyy)
    spread = np.sqrt(np.maximum(0.25 * (cxx - cyy) ** 2 + cxy * cxy, 0.0))
    return moments.sums[:, 0] * np.maximum(half_trace - spread, 0.0)


def point_perpendicular_variance(
    xy: np.ndarray, normal: np.ndarray, config: CornerConfig
) -> np.ndarray:
    """Variance [m^2] of each point across its line, from range/bearing noise:
    ``n^T (s_r^2 u u^T + r^2 s_b^2 v v^T) n`` with u radial, v tangential unit vectors."""
    x, y = xy[:, 0], xy[:, 1]
    r = np.hypot(x, y)
    scale = np.maximum(r, 1e-12)
    u_x, u_y = x / scale, y / scale
    nu = normal[:, 0] * u_x + normal[:, 1] * u_y
    nv = normal[:, 1] * u_x - normal[:, 0] * u_y  # v = (-u_y, u_x)
    return config.range_sigma_m**2 * nu**2 + (r * config.bearing_sigma_rad) ** 2 * nv**2


def line_parameter_covariance(
    xy: np.ndarray,
    starts: np.ndarray,
    ends: np.ndarray,
    centroid: np.ndarray,
    direction: np.ndarray,
    config: CornerConfig,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """First-order covariance of an unweighted least-squares line ``d = a + b s`` in the
    line's own frame (s along ``direction`` from the centroid, d along the normal), with
    heteroscedastic perpendicular noise ``sigma_i^2`` (sandwich form):
    ``var a = sum sigma^2 / n^2``, ``var b = sum sigma^2 s^2 / (sum s^2)^2``,
    ``cov ab = sum sigma^2 s / (n sum s^2)``.

    Returns:
        var_a (m,), var_b (m,), cov_ab (m,).
    """
    index, owner = _flat_indices(starts, ends)
    points = xy.take(index, axis=0)
    # per point, its line's centroid and direction (one gather)
    c_x, c_y, d_x, d_y = np.concatenate([centroid, direction], axis=1).take(owner, axis=0).T
    s = (points[:, 0] - c_x) * d_x + (points[:, 1] - c_y) * d_y
    sigma2 = point_perpendicular_variance(points, np.column_stack([-d_y, d_x]), config)
    count = len(starts)

    def total(values: np.ndarray) -> np.ndarray:
        return np.bincount(owner, weights=values, minlength=count)

    n = (ends - starts + 1).astype(float)  # the point counts (exact)
    sum_s2 = np.maximum(total(s * s), 1e-12)
    return total(sigma2) / n**2, total(sigma2 * s * s) / sum_s2**2, total(sigma2 * s) / (n * sum_s2)


def corner_covariance(
    normal_1: np.ndarray, normal_2: np.ndarray, var_v1: np.ndarray, var_v2: np.ndarray
) -> np.ndarray:
    """Covariance (k, 2, 2) of the intersection x of two lines ``n_k^T (x - c_k) = 0``.

    Perturbing line k by offset ``da_k`` and rotation ``db_k`` moves it, at the corner, by
    ``dv_k = da_k + s_k db_k`` along ``n_k``, so ``N dx = dv`` with ``N = [n_1^T; n_2^T]`` and
    ``Cov(x) = N^-1 diag(var v_1, var v_2) N^-T``.
    """
    matrix = np.stack([normal_1, normal_2], axis=1)  # rows n1, n2
    inverse = np.linalg.inv(matrix)
    diagonal = np.zeros((len(var_v1), 2, 2))
    diagonal[:, 0, 0], diagonal[:, 1, 1] = var_v1, var_v2
    covariance = inverse @ diagonal @ np.swapaxes(inverse, 1, 2)
    return 0.5 * (covariance + np.swapaxes(covariance, 1, 2))


def extract_corners(points: np.ndarray, config: CornerConfig) -> Corners:
    """Corners of one cloud (module docstring).

    Args:
        points: (n, 3) body-frame points [m] (finite).

    Returns:
        ``Corners`` with ``config.dimension``-D positions and covariances.
    """
    return scan_corners(*azimuth_scan(np.asarray(points, dtype=float), config), config)


def scan_corners(xy: np.ndarray, bins: np.ndarray, config: CornerConfig) -> Corners:
    """Corners of an azimuth scan (steps 3-6): ``xy`` (m, 2) [m] in azimuth order with the
    azimuth bin of each (m,), as ``azimuth_scan`` gives them.

    The order and the bins are the sensor's: a scan deskewed after its selection keeps
    them. Re-binning moved points would not give the same scan: near the seam and at
    occlusion edges two surfaces then share bins and the clusters break (on the real KITTI
    clip, re-binning after a deskew of up to 0.64 m lost 36 % of the corners, and a rigid
    0.3 m shift alone two of eight in one frame).

    Note: bearing noise displaces points along the tangent, which is not perpendicular to a
    wall seen obliquely, so the total-least-squares line is slightly rotated (errors in
    variables with correlated components). The covariance cannot describe this bias; it is
    small (about 3 mm at 7 m with 2 mrad bearing noise, ``tests/test_corners.py``).
    """
    d = config.dimension
    if len(xy) < 2 * config.min_segment_points:
        return _no_corners(config)
    breaks = _cluster_breaks(xy, bins, config)
    if breaks.any():  # start the circular scan right after a break
        shift = int(breaks.argmax()) + 1  # the first break
        xy, breaks = _rotated(xy, shift), _rotated(breaks, shift)
    cluster = np.zeros(len(xy), dtype=np.int64)  # each point's cluster number
    np.cumsum(breaks[:-1], out=cluster[1:])
    boundaries = np.flatnonzero(breaks[:-1]) + 1  # where the cluster number steps
    starts = np.concatenate([[0], boundaries])
    ends = np.concatenate([boundaries - 1, [len(xy) - 1]])
    big = ends - starts + 1 >= config.min_segment_points
    starts, ends = split_segments(xy, starts[big], ends[big], config.split_threshold_m)
    prefix = _PrefixMoments(xy)
    starts, ends = _merge_segments(prefix, starts, ends, cluster, config.merge_rms_m)
    if config.refine_boundaries:
        starts, ends = refine_boundaries(prefix, starts, ends, cluster, config.end_trim_points + 2)

    trim = config.end_trim_points
    fit_starts, fit_ends = starts + trim, ends - trim
    # a split point ends one segment and starts the next: untrimmed, each fit takes a point
    # of its neighbour (a 2-D scan's short door jambs set min_fit_points below the default)
    least = config.min_segment_points if config.min_fit_points is None else config.min_fit_points
    usable = fit_ends - fit_starts + 1 >= least
    fit_starts, fit_ends = np.where(usable, fit_starts, starts), np.where(usable, fit_ends, ends)
    centroid, direction = prefix.of(fit_starts, fit_ends).line()
    var_a, var_b, cov_ab = line_parameter_covariance(
        xy, fit_starts, fit_ends, centroid, direction, config
    )
    # each segment's first and last point projected onto its line: along (m, 2) [m] from the
    # centroid, and the segment's end points (m, 2, 2)
    along = np.sum(
        (xy.take(np.column_stack([starts, ends]), axis=0) - centroid[:, None]) * direction[:, None],
        axis=2,
    )
    segment_ends = centroid[:, None] + along[..., None] * direction[:, None]
    valid = (ends - starts + 1 >= config.min_segment_points) & (
        np.abs(along[:, 1] - along[:, 0]) >= config.min_segment_length_m
    )

    # pairs of consecutive segments: segment i (left) and i + 1 (right)
    sine = np.abs(direction[:-1, 0] * direction[1:, 1] - direction[:-1, 1] * direction[1:, 0])
    segment_cluster = cluster[starts]
    candidate = (
        valid[:-1]
        & valid[1:]
        & (segment_cluster[:-1] == segment_cluster[1:])
        & (starts[1:] - ends[:-1] <= 1)
        & (sine >= np.sin(np.deg2rad(config.min_corner_angle_deg)))
    )
    first = np.flatnonzero(candidate)
    if len(first) == 0:
        return _no_corners(config)
    # the two segments of every candidate corner, (k, 2): segment i and i + 1
    pairs = np.column_stack([first, first + 1])
    normal = np.column_stack([-direction[:, 1], direction[:, 0]])
    normals = normal[pairs]  # (k, 2, 2), rows n1 and n2
    rhs = np.sum(normals * centroid[pairs], axis=2)
    corner = np.linalg.solve(normals, rhs[..., None])[..., 0]
    facing_left, facing_right = segment_ends[pairs[:, 0], 1], segment_ends[pairs[:, 1], 0]
    if config.refine_boundaries:
        # refined segments share no point: the corner lies between their facing ends, which
        # a grazing wall can leave a beam spacing apart; measure it from that bridge
        near = _bridge_distance(corner, facing_left, facing_right) <= config.max_corner_gap_m
    else:
        gap_left = _norms(corner - facing_left)
        gap_right = _norms(corner - facing_right)
        near = (gap_left <= config.max_corner_gap_m) & (gap_right <= config.max_corner_gap_m)
    pairs, normals, corner = pairs[near], normals[near], corner[near]
    if len(pairs) == 0:
        return _no_corners(config)
    # the corner along each of its two lines, from the line's centroid (k, 2) [m]
    s = np.sum((corner[:, None] - centroid[pairs]) * direction[pairs], axis=2)
    var_v = var_a[pairs] + 2.0 * s * cov_ab[pairs] + s**2 * var_b[pairs]
    covariance_2d = corner_covariance(
        normals[:, 0], normals[:, 1], var_v[:, 0], var_v[:, 1]
    ) + config.model_sigma_m**2 * np.eye(2)

    directions = None
    if config.directions:  # (k, 2, 2): along each line, away from the corner
        towards = np.sum((centroid[pairs] - corner[:, None]) * direction[pairs], axis=2)
        directions = np.sign(towards)[..., None] * direction[pairs]
    if d == 2:
        return Corners(corner, covariance_2d, directions, segment_ends[valid])
    count = len(corner)
    points_3d = np.column_stack([corner, np.full(count, config.slab_height_m)])
    covariance = np.zeros((count, 3, 3))
    covariance[:, :2, :2] = covariance_2d
    slab_sigma = (
        config.slab_sigma_m
        if config.slab_sigma_m is not None
        else config.slab_half_thickness_m / np.sqrt(3.0)
    )
    covariance[:, 2, 2] = slab_sigma**2
    if directions is not None:
        directions = np.concatenate([directions, np.zeros((count, 2, 1))], axis=2)
    return Corners(points_3d, covariance, directions, segment_ends[valid])
