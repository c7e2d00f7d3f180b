"""Corner landmarks from a lidar cloud: slab, azimuth scan, clusters, split-and-merge lines,
corners where two lines meet at a sufficient angle.

Pipeline (vectorized numpy over points, except the split and merge loops of step 4, which
are compiled: ``corner_kernels``), run by ``scan_corners`` here: steps 1-3 are in
``corner_scan``, step 4 and the line moments in ``corner_segments``, the covariances of steps
5-6 in ``corner_uncertainty``, the options in ``corner_config``.

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

from datasets.lidar.corner_config import CornerConfig
from datasets.lidar.corner_scan import _cluster_breaks, _norms, _rotated, azimuth_scan
from datasets.lidar.corner_segments import (
    _merge_segments,
    _PrefixMoments,
    refine_boundaries,
    split_segments,
)
from datasets.lidar.corner_uncertainty import corner_covariance, line_parameter_covariance
from datasets.measurements import LandmarkScan


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


def _no_corners(config: CornerConfig) -> Corners:
    """The result without corners, shaped for ``config``."""
    d = config.dimension
    return Corners(
        np.zeros((0, d)),
        np.zeros((0, d, d)),
        np.zeros((0, 2, d)) if config.directions else None,
        np.zeros((0, 2, 2)),
    )


def _bridge_distance(points: np.ndarray, starts: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Distance (k,) [m] of each of ``points`` (k, 2) from the segment joining ``starts``
    (k, 2) to ``ends`` (k, 2)."""
    span = ends - starts
    length2 = np.maximum(np.sum(span * span, axis=1), 1e-24)
    along = np.clip(np.sum((points - starts) * span, axis=1) / length2, 0.0, 1.0)
    return _norms(points - (starts + along[:, None] * span))


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
