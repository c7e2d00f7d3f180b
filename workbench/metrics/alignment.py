"""Least-squares alignment of an estimated trajectory to a reference (Umeyama 1991).

``umeyama`` solves ``min_{s, R, t} sum_i || y_i - (s R x_i + t) ||^2`` over point pairs, the
same way evo's ``geometry.umeyama_alignment`` does (so SE(3)/Sim(3) results agree with
``evo_ape -a`` / ``-as``). ``align_trajectory`` applies the result to a whole trajectory.

Alignment kinds (``ALIGNMENTS``):
    ``se3``  rotation + translation (3-D points; a planar trajectory is lifted to z = 0, as
             evo does with a planar TUM file; note that a 3-D rotation may then mirror the
             plane, which is why ``se2`` exists);
    ``sim3`` rotation + translation + scale;
    ``se2``  planar rotation about z + planar translation (x, y only; z is left as is);
    ``none`` identity.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from datasets.errors import InputError
from datasets.rotations import quat_wxyz_from_matrix, rot2, wrap_angle
from datasets.trajectory import Trajectory

ALIGNMENTS = ("se3", "sim3", "se2", "none")


@dataclass(frozen=True)
class Alignment:
    """A similarity transform ``x -> scale * rotation @ x + translation``.

    Attributes:
        kind: one of ``ALIGNMENTS``.
        rotation: shape (3, 3) (an ``se2`` alignment is a rotation about z).
        translation: shape (3,) [m].
        scale: 1 unless ``sim3``.
    """

    kind: str
    rotation: np.ndarray
    translation: np.ndarray
    scale: float = 1.0

    @staticmethod
    def identity() -> Alignment:
        return Alignment("none", np.eye(3), np.zeros(3), 1.0)

    def as_dict(self) -> dict[str, object]:
        """JSON-serialisable form (lists of floats)."""
        return {
            "kind": self.kind,
            "rotation": self.rotation.tolist(),
            "translation_m": self.translation.tolist(),
            "scale": float(self.scale),
        }


def umeyama(
    source: np.ndarray, target: np.ndarray, with_scale: bool = False, allow_degenerate: bool = False
) -> tuple[np.ndarray, np.ndarray, float]:
    """Umeyama's least-squares similarity from ``source`` to ``target`` points.

    Umeyama, "Least-squares estimation of transformation parameters between two point
    patterns", IEEE PAMI 1991, eqs. (34)-(43); the order of operations follows evo's
    implementation so that results match it to rounding.

    Args:
        source: points x_i, shape (n, m), m = 2 or 3.
        target: points y_i, shape (n, m).
        with_scale: also estimate the scale (Sim(m)); otherwise scale is 1 (SE(m)).
        allow_degenerate: when the cross-covariance has rank < m - 1 (all points equal or
            collinear) the minimiser is not unique; evo refuses, and so do we unless this is
            True, in which case one of the minimisers is returned (the residual is the
            same for all of them).

    Returns:
        (rotation (m, m), translation (m,), scale).

    Raises:
        InputError: shapes disagree, fewer than one pair, or a degenerate configuration
            (unless ``allow_degenerate``).
    """
    source = np.asarray(source, dtype=float)
    target = np.asarray(target, dtype=float)
    if source.shape != target.shape or source.ndim != 2 or len(source) == 0:
        raise InputError(
            f"alignment needs two equally long point lists, got {source.shape} and {target.shape}"
        )
    count, dim = source.shape
    mean_source = source.mean(axis=0)
    mean_target = target.mean(axis=0)
    centred_source = source - mean_source
    centred_target = target - mean_target
    variance_source = np.linalg.norm(centred_source) ** 2 / count  # eq. (36)
    cross_covariance = centred_target.T @ centred_source / count  # eq. (38)
    u, d, vt = np.linalg.svd(cross_covariance)
    if np.count_nonzero(d > np.finfo(d.dtype).eps) < dim - 1 and not allow_degenerate:
        raise InputError(
            f"alignment impossible: the {count} paired positions are (nearly) identical or collinear "
            "(degenerate covariance rank); use --align none"
        )
    signs = np.eye(dim)
    if np.linalg.det(u) * np.linalg.det(vt) < 0.0:  # eq. (43): keep a proper rotation
        signs[dim - 1, dim - 1] = -1.0
    rotation = u @ signs @ vt  # eq. (40)
    scale = 1.0
    if with_scale:
        if variance_source <= 0.0:
            raise InputError("Sim(3) alignment impossible: the estimated positions do not move")
        scale = float(np.trace(np.diag(d) @ signs) / variance_source)  # eq. (42)
    translation = mean_target - scale * rotation @ mean_source  # eq. (41)
    return rotation, translation, scale


def _spatial_positions(trajectory: Trajectory) -> np.ndarray:
    if trajectory.dimension == 3:
        return trajectory.positions
    return np.column_stack([trajectory.positions, np.zeros(len(trajectory))])


def estimate_alignment(
    reference: Trajectory, estimate: Trajectory, kind: str, allow_degenerate: bool = False
) -> Alignment:
    """The alignment of ``kind`` that maps the estimate's positions onto the reference's.

    ``reference`` and ``estimate`` must already be paired pose for pose (equal length).
    """
    if kind not in ALIGNMENTS:
        raise InputError(f"unknown alignment {kind!r}; choose one of {', '.join(ALIGNMENTS)}")
    if len(reference) != len(estimate):
        raise InputError(f"alignment needs paired poses, got {len(reference)} and {len(estimate)}")
    if kind == "none":
        return Alignment.identity()
    if kind == "se2":
        rotation2, translation2, _ = umeyama(
            estimate.positions[:, :2], reference.positions[:, :2], False, allow_degenerate
        )
        rotation = np.eye(3)
        rotation[:2, :2] = rotation2
        return Alignment("se2", rotation, np.array([translation2[0], translation2[1], 0.0]), 1.0)
    rotation, translation, scale = umeyama(
        _spatial_positions(estimate),
        _spatial_positions(reference),
        kind == "sim3",
        allow_degenerate,
    )
    return Alignment(kind, rotation, translation, scale)


def apply_alignment(trajectory: Trajectory, alignment: Alignment) -> Trajectory:
    """The trajectory moved by ``alignment`` (positions and orientations). Body-frame pose
    covariances are unchanged by a rigid world transform and are kept; a scaled (``sim3``)
    trajectory loses them.

    A planar trajectory stays planar under ``se2`` and ``none``; under ``se3``/``sim3`` it is
    lifted to 3-D first (z = 0, rotation about z), as evo would read it from a TUM file.
    """
    if alignment.kind == "none":
        return trajectory
    if trajectory.dimension == 2 and alignment.kind == "se2":
        yaw = float(np.arctan2(alignment.rotation[1, 0], alignment.rotation[0, 0]))
        positions = trajectory.positions @ rot2(yaw).T + alignment.translation[:2]
        headings = np.asarray(wrap_angle(trajectory.rotations + yaw), dtype=float)
        return Trajectory(trajectory.t, positions, headings, trajectory.covariances)
    spatial = lift_to_3d(trajectory)
    positions = alignment.scale * spatial.positions @ alignment.rotation.T + alignment.translation
    matrices = np.einsum("ij,njk->nik", alignment.rotation, spatial.rotation_matrices())
    covariances = None if alignment.kind == "sim3" else spatial.covariances
    return Trajectory(
        spatial.t, positions, quat_wxyz_from_matrix(matrices).reshape(-1, 4), covariances
    )


def lift_to_3d(trajectory: Trajectory) -> Trajectory:
    """A planar trajectory as a 3-D one (z = 0, rotation about z); 3-D ones unchanged.

    Covariances of a planar trajectory are dropped (their order differs in 3-D).
    """
    if trajectory.dimension == 3:
        return trajectory
    half = 0.5 * trajectory.rotations
    quats = np.stack([np.cos(half), np.zeros_like(half), np.zeros_like(half), np.sin(half)], axis=1)
    return Trajectory(trajectory.t, _spatial_positions(trajectory), quats)
