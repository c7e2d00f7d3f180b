"""Scoring corner detections against the exact corners of a synthetic world (the sidecar).

Observable corner (the recall denominator), seen from a sensor at 2-D position p:
- horizontal range within ``[min_range_m, max_range_m]`` of the extractor's slab;
- line of sight: the segment from p to the corner (stopping ``los_margin_m`` short)
  crosses no wall taller than the slab;
- both faces seen from their free side at least ``min_incidence_deg`` off the face plane,
  and each face spans at least ``min_face_bins`` azimuth bins of the extractor (so that a
  line can be fitted to it; partial occlusion of a face is not modelled).
A detection is correct (precision) when a true corner lies within ``tolerance_m`` of it
horizontally, and a true observable corner is recalled when a detection lies within
``tolerance_m`` of it.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from datasets.errors import InputError
from datasets.rotations import (
    matrix_from_quat_wxyz,
    quat_wxyz_from_rotation,
    rotation_from_quat_wxyz,
)
from datasets.trajectory import Trajectory

SIDECAR_FORMAT = "workbench-corners-1"


@dataclass(frozen=True)
class CornerTruth:
    """Exact corners of a world.

    Attributes:
        ids: (K,) int.
        positions: (K, 3) world [m] (z = the sensor's slab height).
        face_normals: (K, 2, 2) outward unit normals of the two faces.
        face_vectors: (K, 2, 2) vectors from the corner along each face to its other end [m].
        face_heights: (K,) height of the prism the corner belongs to [m].
        wall_start, wall_end: (S, 2) [m]; wall_height: (S,) [m].
    """

    ids: np.ndarray
    positions: np.ndarray
    face_normals: np.ndarray
    face_vectors: np.ndarray
    face_heights: np.ndarray
    wall_start: np.ndarray
    wall_end: np.ndarray
    wall_height: np.ndarray


def sidecar_for(bag_path: Path) -> Path:
    """``NAME.corners.json`` beside the bag file or folder ``NAME``."""
    bag_path = Path(bag_path)
    return bag_path.parent / f"{bag_path.name}.corners.json"


def read_corner_truth(path: Path) -> CornerTruth:
    """Load a sidecar; ``InputError`` naming the file when it is malformed."""
    try:
        payload = json.loads(Path(path).read_text())
        if payload.get("format") != SIDECAR_FORMAT:
            raise InputError(
                f"{path}: not a corner sidecar (format {payload.get('format')!r}, expected {SIDECAR_FORMAT})"
            )
        ids, positions, normals, vectors, heights = [], [], [], [], []
        starts, ends, wall_heights = [], [], []
        slab = float(payload["slab_height_m"])
        next_id = 0
        for polygon in payload["polygons"]:
            vertices = np.asarray(polygon["vertices"], dtype=float)
            height = float(polygon["height_m"])
            following, previous = np.roll(vertices, -1, axis=0), np.roll(vertices, 1, axis=0)
            edge = following - vertices
            edge_dir = edge / np.linalg.norm(edge, axis=1, keepdims=True)
            left = np.column_stack([-edge_dir[:, 1], edge_dir[:, 0]])
            free = left if polygon["kind"] == "boundary" else -left
            normals.append(np.stack([np.roll(free, 1, axis=0), free], axis=1))
            vectors.append(np.stack([previous - vertices, following - vertices], axis=1))
            count = len(vertices)
            ids.append(np.arange(next_id, next_id + count))
            next_id += count
            positions.append(np.column_stack([vertices, np.full(count, slab)]))
            heights.append(np.full(count, height))
            starts.append(vertices)
            ends.append(following)
            wall_heights.append(np.full(count, height))
    except InputError:
        raise
    except (OSError, ValueError, KeyError, TypeError) as error:
        raise InputError(
            f"{path}: unreadable corner sidecar ({type(error).__name__}: {error})"
        ) from None
    return CornerTruth(
        np.concatenate(ids),
        np.concatenate(positions),
        np.concatenate(normals),
        np.concatenate(vectors),
        np.concatenate(heights),
        np.concatenate(starts),
        np.concatenate(ends),
        np.concatenate(wall_heights),
    )


def interpolate_poses(trajectory: Trajectory, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Positions (M, 3) and quaternions wxyz (M, 4) at times ``t`` (linear / slerp, clamped)."""
    from scipy.spatial.transform import Slerp

    t = np.clip(np.atleast_1d(np.asarray(t, dtype=float)), trajectory.t[0], trajectory.t[-1])
    positions = np.column_stack(
        [np.interp(t, trajectory.t, trajectory.positions[:, k]) for k in range(3)]
    )
    slerp = Slerp(trajectory.t, rotation_from_quat_wxyz(trajectory.rotations))
    return positions, quat_wxyz_from_rotation(slerp(t))


def _segments_cross(p: np.ndarray, q: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(K, S): does segment p_k-q_k properly cross wall a_s-b_s (2-D)."""

    def orient(u, v, w):
        return (v[..., 0] - u[..., 0]) * (w[..., 1] - u[..., 1]) - (v[..., 1] - u[..., 1]) * (
            w[..., 0] - u[..., 0]
        )

    p, q = p[:, None], q[:, None]
    a, b = a[None], b[None]
    return (orient(p, q, a) * orient(p, q, b) < 0) & (orient(a, b, p) * orient(a, b, q) < 0)


def observable(
    truth: CornerTruth,
    sensor_xy: np.ndarray,
    sensor_z: float,
    min_range_m: float,
    max_range_m: float,
    azimuth_resolution_deg: float,
    min_face_bins: int = 8,
    min_incidence_deg: float = 15.0,
    los_margin_m: float = 0.05,
) -> np.ndarray:
    """(K,) bool: which true corners the extractor could see from ``sensor_xy`` (docstring)."""
    corner_xy = truth.positions[:, :2]
    offset = sensor_xy[None] - corner_xy
    distance = np.linalg.norm(offset, axis=1)
    view = offset / np.maximum(distance, 1e-9)[:, None]
    in_range = (
        (distance >= min_range_m) & (distance <= max_range_m) & (truth.face_heights >= sensor_z)
    )
    stop = corner_xy + los_margin_m * view
    blocking = truth.wall_height[None] >= sensor_z
    clear = ~np.any(
        _segments_cross(
            np.broadcast_to(sensor_xy, corner_xy.shape), stop, truth.wall_start, truth.wall_end
        )
        & blocking,
        axis=1,
    )
    incidence = np.einsum("kd,kfd->kf", view, truth.face_normals)
    facing = np.all(incidence >= np.sin(np.deg2rad(min_incidence_deg)), axis=1)
    far_end = corner_xy[:, None] + truth.face_vectors - sensor_xy[None, None]
    near_end = -offset[:, None]
    cosine = np.einsum("kfd,kfd->kf", far_end, np.broadcast_to(near_end, far_end.shape)) / (
        np.linalg.norm(far_end, axis=2) * distance[:, None] + 1e-12
    )
    span_deg = np.rad2deg(np.arccos(np.clip(cosine, -1.0, 1.0)))
    wide = np.all(span_deg >= min_face_bins * azimuth_resolution_deg, axis=1)
    return in_range & clear & facing & wide


@dataclass(frozen=True)
class FrameScore:
    """One frame: detections, how many are correct, observable corners, how many found."""

    detections: int
    correct: int
    observable: int
    recalled: int


def score_frame(
    truth: CornerTruth,
    detections_body: np.ndarray,
    position: np.ndarray,
    quat_wxyz: np.ndarray,
    min_range_m: float,
    max_range_m: float,
    azimuth_resolution_deg: float,
    tolerance_m: float = 0.1,
) -> FrameScore:
    """Score body-frame detections (k, 2 or 3) given the true pose (position (3,), quaternion)."""
    rotation = matrix_from_quat_wxyz(quat_wxyz)
    truth_body = (truth.positions - position) @ rotation  # R^T (rho - r), row-wise
    sensor_xy, sensor_z = position[:2], float(position[2])
    seen = observable(truth, sensor_xy, sensor_z, min_range_m, max_range_m, azimuth_resolution_deg)
    if len(detections_body) == 0:
        return FrameScore(0, 0, int(seen.sum()), 0)
    gaps = np.linalg.norm(detections_body[:, None, :2] - truth_body[None, :, :2], axis=2)
    correct = int(np.sum(gaps.min(axis=1) <= tolerance_m))
    recalled = int(np.sum(seen & (gaps.min(axis=0) <= tolerance_m)))
    return FrameScore(len(detections_body), correct, int(seen.sum()), recalled)


def score_corners(
    frames: list[tuple[float, np.ndarray]],
    truth: CornerTruth,
    trajectory: Trajectory,
    min_range_m: float,
    max_range_m: float,
    azimuth_resolution_deg: float,
    tolerance_m: float = 0.1,
) -> dict[str, float | int | None]:
    """Precision and recall over frames of ``(t, body-frame detections (k, d))``, using the
    true pose at each ``t`` (frames outside the ground truth's time span are left out).

    Returns:
        ``corner_precision``, ``corner_recall`` (None when undefined), ``detections``,
        ``correct``, ``observable``, ``recalled``, ``frames_scored``, ``tolerance_m``.
    """
    totals = np.zeros(4, dtype=int)
    scored = 0
    for t, detections in frames:
        if not trajectory.t[0] <= t <= trajectory.t[-1]:
            continue
        positions, quats = interpolate_poses(trajectory, np.array([t]))
        score = score_frame(
            truth,
            np.asarray(detections),
            positions[0],
            quats[0],
            min_range_m,
            max_range_m,
            azimuth_resolution_deg,
            tolerance_m,
        )
        totals += [score.detections, score.correct, score.observable, score.recalled]
        scored += 1
    detections, correct, seen, recalled = (int(v) for v in totals)
    return {
        "corner_precision": correct / detections if detections else None,
        "corner_recall": recalled / seen if seen else None,
        "detections": detections,
        "correct": correct,
        "observable": seen,
        "recalled": recalled,
        "frames_scored": scored,
        "tolerance_m": tolerance_m,
    }


def true_corner_ids(
    frames: list[tuple[float, np.ndarray]],
    truth: CornerTruth,
    trajectory: Trajectory,
    tolerance_m: float = 0.1,
) -> tuple[tuple[float, np.ndarray], ...]:
    """``GroundTruth.scan_ids`` for front-end corner scans: per frame ``(t, ids (k,))`` with
    the id of the true corner within ``tolerance_m`` (horizontally) of each detection, -1 for
    a detection near none (unknown to the association scoring). Frames without detections
    or outside the truth's time span are left out."""
    result = []
    for t, detections in frames:
        detections = np.asarray(detections)
        if len(detections) == 0 or not trajectory.t[0] <= t <= trajectory.t[-1]:
            continue
        positions, quats = interpolate_poses(trajectory, np.array([t]))
        truth_body = (truth.positions - positions[0]) @ matrix_from_quat_wxyz(quats[0])
        gaps = np.linalg.norm(detections[:, None, :2] - truth_body[None, :, :2], axis=2)
        nearest = np.argmin(gaps, axis=1)
        ids = np.where(
            gaps[np.arange(len(detections)), nearest] <= tolerance_m, truth.ids[nearest], -1
        )
        result.append((float(t), ids.astype(int)))
    return tuple(result)


def corner_error_statistics(
    frames: list[tuple[float, np.ndarray, np.ndarray]],
    truth: CornerTruth,
    trajectory: Trajectory,
    tolerance_m: float = 0.1,
) -> dict[str, float | int | None]:
    """Horizontal errors of the correct detections (within ``tolerance_m`` of a true corner)
    against their covariances, over frames of ``(t, points (k, d), covariances (k, d, d))``.

    Returns:
        ``corner_error_rms_m``, ``corner_predicted_rms_m`` (sqrt of the mean trace of the
        horizontal covariances), ``corner_nees_mean`` and ``corner_nees_median`` (2 dof),
        ``corner_errors`` (count); None values when there is no correct detection.
    """
    errors, covariances = [], []
    for t, points, covs in frames:
        points = np.asarray(points)
        if len(points) == 0 or not trajectory.t[0] <= t <= trajectory.t[-1]:
            continue
        positions, quats = interpolate_poses(trajectory, np.array([t]))
        truth_body = (truth.positions - positions[0]) @ matrix_from_quat_wxyz(quats[0])
        offsets = points[:, None, :2] - truth_body[None, :, :2]
        nearest = np.argmin(np.linalg.norm(offsets, axis=2), axis=1)
        error = offsets[np.arange(len(points)), nearest]
        good = np.linalg.norm(error, axis=1) <= tolerance_m
        errors.append(error[good])
        covariances.append(np.asarray(covs)[good][:, :2, :2])
    if not errors or sum(len(e) for e in errors) == 0:
        return {
            "corner_error_rms_m": None,
            "corner_predicted_rms_m": None,
            "corner_nees_mean": None,
            "corner_nees_median": None,
            "corner_errors": 0,
        }
    error, covariance = np.concatenate(errors), np.concatenate(covariances)
    nees = np.einsum("ni,nij,nj->n", error, np.linalg.inv(covariance), error)
    return {
        "corner_error_rms_m": float(np.sqrt(np.mean(np.sum(error**2, axis=1)))),
        "corner_predicted_rms_m": float(np.sqrt(np.mean(np.trace(covariance, axis1=1, axis2=2)))),
        "corner_nees_mean": float(np.mean(nees)),
        "corner_nees_median": float(np.median(nees)),
        "corner_errors": int(len(error)),
    }


def with_true_corner_ids(sequence, front_end):
    """``sequence`` with ``GroundTruth.scan_ids`` of the front end's corner scans (the true id
    of each corner from the sidecar, -1 for a false detection), running the front end over the
    stream first if it has not run (it is cached: estimators pay nothing again). Unchanged
    without a sidecar (``Sequence.corner_sidecar``), ground-truth poses or corners.

    Why at the loader: map NEES, landmark RMSE and association precision map estimator ids to
    true ids through these. Without them the mapping falls back to equal ids, which for a
    front end's anonymous corners pairs unrelated landmarks: on the synthetic corridor bag
    every estimator's map NEES read about 1e6 (a garbage number, not a failure) in
    ``workbench run`` and the suites, where only ``workbench bag`` had attached them."""
    from dataclasses import replace

    sidecar = sequence.corner_sidecar
    truth = sequence.ground_truth
    if not sidecar or truth is None or truth.pose is None or not front_end.settings.corners:
        return sequence
    if not front_end.frames:
        for _ in sequence.measurements():
            pass
    frames = [
        (frame.t, frame.corners.points)
        for frame in front_end.frames
        if frame.corners is not None and len(frame.corners.points)
    ]
    scan_ids = true_corner_ids(frames, read_corner_truth(sidecar), truth.pose)
    return replace(sequence, ground_truth=replace(truth, scan_ids=scan_ids))
