"""The relations metric: the error of an estimate's relative poses against given ones.

Source: R. Kümmerle, B. Steder, C. Dornhege, M. Ruhnke, G. Grisetti, C. Stachniss and
A. Kleiner, "On measuring the accuracy of SLAM algorithms", Autonomous Robots 27(4),
387-407, 2009. A *relation* is a pair of times (t1, t2) with the relative pose of the robot
at t2 in the frame of its pose at t1, obtained without the estimator (for the classic
indoor laser logs, by hand-checked scan matching). The paper's metric is

    epsilon(delta) = 1/N sum_ij trans(delta_ij (-) delta*_ij)^2 + rot(delta_ij (-) delta*_ij)^2

with delta_ij = x_j (-) x_i the estimated relative pose, delta*_ij the given one and (-)
the inverse pose composition (a (-) b = b^-1 a). Translation and rotation have different
units, so the paper reports them apart: mean and standard deviation over all relations of
the absolute translational error [m] and absolute rotational error [deg], and of their
squares [m^2], [deg^2]. Here, per relation (poses as homogeneous transforms):

    delta = G^-1 (T_1^-1 T_2)          G: the given relative pose, T_k: the estimate at t_k
    trans error = ||trans(delta)|| = ||trans(T_1^-1 T_2) - trans(G)||   [m]
    rot error   = |angle(rot(delta))| in [0, 180]                        [deg]

The second form of the translational error holds because rot(G)^T preserves the norm: it
does not depend on the relative rotation (Cartographer's ``compute_relations_metrics``,
which implements the paper's statistics, uses (T_1^-1 T_2) G^-1, whose translation does;
the rotational errors agree). The standard deviations are sample ones (ddof 1, as
Cartographer's): None with fewer than two relations.

Stamps: each relation's t1 and t2 take the estimate's *nearest* pose within ``max_diff_s``
(evo's nearest-stamp rule, ``timestamps.matching_time_indices``); nothing is interpolated,
so a gap in the estimate never produces a pose it did not report. The default,
``DEFAULT_MAX_DIFF_S`` = 0.01 s, is evo's: the relations of the field are stamped with the
laser scans' own times and an estimate keeps a pose at every scan, so the right pose is
found to within rounding, while 0.01 s is far below half of any scan interval of those
logs (about 0.1 s at 5 Hz), so a neighbouring scan's pose is never taken instead. A
relation that cannot be scored is skipped and counted with its reason (``SKIP_REASONS``),
never dropped silently.

Planar and spatial trajectories and relations mix freely: every pose is lifted to SE(3)
(z = 0, rotation about z), so a planar estimate scored against spatial relations counts
their z, roll and pitch as error.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from datasets.errors import InputError
from datasets.state import Relations
from datasets.text_files import text_lines
from datasets.trajectory import Trajectory
from workbench.metrics.alignment import lift_to_3d
from workbench.metrics.rpe import rotation_angles
from workbench.metrics.timestamps import DEFAULT_MAX_DIFF_S, matching_time_indices

__all__ = [
    "DEFAULT_MAX_DIFF_S",
    "SKIP_REASONS",
    "Relations",
    "RelationsResult",
    "read_relations",
    "relation_errors",
    "relations_from_trajectory",
]

COLUMNS = "t1 t2 x y z roll pitch yaw"

SKIP_REASONS = {
    "outside_span": "t1 or t2 farther than max_diff_s outside the estimate's first..last pose",
    "no_pose_near_t1": "no estimate pose within max_diff_s of t1",
    "no_pose_near_t2": "no estimate pose within max_diff_s of t2",
    "same_pose": "t1 and t2 matched the same estimate pose",
    "non_finite_pose": "the estimate's pose at t1 or t2 is not finite",
}
"""Why a relation is not scored, in the order they are checked (the first that applies)."""


def read_relations(path: str | Path, max_diff_s: float | None = None) -> Relations:
    """Read a relations file: one relation a line, ``t1 t2 x y z roll pitch yaw``.

    Times [s] (the log's own stamps); the pose at t2 in the frame of the pose at t1:
    translation [m], rotation Rz(yaw) Ry(pitch) Rx(roll) [rad] (Cartographer's reading of
    these files). Blank lines and everything after a ``#`` are ignored; commas count as
    spaces. t2 may come before t1 (a relative pose is defined either way); t1 == t2 is an
    error, as it relates a pose to itself and measures nothing of the estimate.

    Args:
        path: the file.
        max_diff_s: stamp tolerance [s] to store with the relations (None: the default).

    Returns:
        ``Relations`` with times (R, 2) and poses (R, 3) [x, y, yaw] when every line has
        z = roll = pitch = 0 (a planar log), else (R, 6) [x, y, z, roll, pitch, yaw].

    Raises:
        InputError: naming the file (and line) for a missing or non-text file, a line
            without 8 columns, a non-number, a non-finite value, t1 == t2, or no relation.
    """
    path = Path(path)
    rows: list[list[float]] = []
    for number, line in text_lines(path, "relations file"):
        content = line.split("#", 1)[0].replace(",", " ").split()
        if not content:
            continue
        if len(content) != 8:
            raise InputError(f"{path}:{number}: expected 8 columns ({COLUMNS}), got {len(content)}")
        values = []
        for column, text in zip(COLUMNS.split(), content):
            try:
                values.append(float(text))
            except ValueError:
                raise InputError(f"{path}:{number}: {column} is not a number: {text!r}") from None
        bad = [column for column, value in zip(COLUMNS.split(), values) if not math.isfinite(value)]
        if bad:
            raise InputError(f"{path}:{number}: {', '.join(bad)} not finite")
        if values[0] == values[1]:
            raise InputError(
                f"{path}:{number}: t1 and t2 are the same time ({content[0]}): a relation "
                "relates two different times"
            )
        rows.append(values)
    if not rows:
        raise InputError(f"{path}: no relations in file (expected lines of {COLUMNS})")
    table = np.array(rows, dtype=float)
    planar = not np.any(table[:, [4, 5, 6]])
    poses = table[:, [2, 3, 7]] if planar else table[:, 2:8]
    return Relations(
        times=table[:, :2].copy(), poses=poses.copy(), source=str(path), max_diff_s=max_diff_s
    )


def relations_from_trajectory(trajectory: Trajectory, pairs: np.ndarray) -> Relations:
    """The relations a trajectory implies between its own poses (for tests and simulated
    truth): relation k is the pose ``pairs[k, 1]`` in the frame of pose ``pairs[k, 0]``.

    Args:
        trajectory: planar or spatial poses.
        pairs: pose index pairs, shape (R, 2) int.

    Returns:
        ``Relations`` at the poses' times, planar (R, 3) for a planar trajectory, else
        (R, 6) [x, y, z, roll, pitch, yaw].
    """
    pairs = np.asarray(pairs, dtype=int).reshape(-1, 2)
    poses = trajectory.homogeneous()
    relative = np.einsum("nij,njk->nik", _inverse(poses[pairs[:, 0]]), poses[pairs[:, 1]])
    times = trajectory.t[pairs]
    if trajectory.dimension == 2:
        yaw = np.arctan2(relative[:, 1, 0], relative[:, 0, 0])
        return Relations(times, np.column_stack([relative[:, :2, 2], yaw]))
    yaw_pitch_roll = (
        Rotation.from_matrix(relative[:, :3, :3]).as_euler("ZYX")
        if len(pairs)
        else relative[:, 0, :3]
    )
    return Relations(times, np.column_stack([relative[:, :3, 3], yaw_pitch_roll[:, ::-1]]))


@dataclass(frozen=True)
class RelationsResult:
    """The relations metric of one estimate.

    Attributes:
        relations: what was scored.
        max_diff_s: the stamp tolerance used [s].
        used: indices of the scored relations, shape (U,) int.
        translation_errors_m: ||trans(delta)|| per scored relation [m], shape (U,).
        rotation_errors_deg: |angle(rot(delta))| per scored relation [deg], shape (U,).
        stamp_offsets_s: |estimate stamp - relation time| of the poses taken for t1 and
            t2 [s], shape (U, 2).
        reasons: per relation, the ``SKIP_REASONS`` key it was skipped for, or "" when it
            was scored; length R.
        estimate_poses: poses in the scored trajectory.
    """

    relations: Relations
    max_diff_s: float
    used: np.ndarray
    translation_errors_m: np.ndarray
    rotation_errors_deg: np.ndarray
    stamp_offsets_s: np.ndarray
    reasons: tuple[str, ...]
    estimate_poses: int = 0
    skipped_counts: dict[str, int] = field(init=False)

    def __post_init__(self) -> None:
        counts = {key: self.reasons.count(key) for key in SKIP_REASONS}
        object.__setattr__(self, "skipped_counts", {k: n for k, n in counts.items() if n})

    @property
    def used_count(self) -> int:
        return int(len(self.used))

    @property
    def skipped_count(self) -> int:
        return int(sum(self.skipped_counts.values()))

    def statistics(self) -> dict[str, float | None]:
        """Mean, sample std (ddof 1) and the mean and std of the squares of both errors:
        ``trans_error_{mean,std}_m``, ``trans_error_sq_{mean,std}_m2``,
        ``rot_error_{mean,std}_deg``, ``rot_error_sq_{mean,std}_deg2``. None where
        undefined (no relation scored; a std of fewer than two)."""
        found: dict[str, float | None] = {}
        for name, errors, unit in (
            ("trans_error", self.translation_errors_m, "m"),
            ("rot_error", self.rotation_errors_deg, "deg"),
        ):
            for suffix, values, value_unit in (
                ("", errors, unit),
                ("_sq", errors**2, f"{unit}2"),
            ):
                found[f"{name}{suffix}_mean_{value_unit}"] = _mean(values)
                found[f"{name}{suffix}_std_{value_unit}"] = _sample_std(values)
        return found

    def skipped_text(self) -> str | None:
        """The skipped relations as one line (``"2 no_pose_near_t1, 1 outside_span"``), or
        None when none was skipped."""
        if not self.skipped_counts:
            return None
        return ", ".join(f"{count} {reason}" for reason, count in self.skipped_counts.items())

    def report(self) -> dict[str, object]:
        """A JSON-serialisable dict: ``statistics()`` plus ``relations`` (count), ``used``,
        ``skipped``, ``skipped_reasons`` (reason: count), ``max_diff_s`` [s],
        ``max_stamp_offset_s`` (the largest stamp difference of a pose taken [s], None when
        none was scored), ``estimate_poses`` and ``relations_file``."""
        offsets = self.stamp_offsets_s
        return {
            **self.statistics(),
            "relations": int(len(self.relations)),
            "used": self.used_count,
            "skipped": self.skipped_count,
            "skipped_reasons": dict(self.skipped_counts),
            "max_diff_s": float(self.max_diff_s),
            "max_stamp_offset_s": float(offsets.max()) if offsets.size else None,
            "estimate_poses": int(self.estimate_poses),
            "relations_file": self.relations.source or None,
        }


def relation_errors(
    trajectory: Trajectory, relations: Relations, max_diff_s: float | None = None
) -> RelationsResult:
    """Score ``trajectory`` against ``relations`` (see the module docstring for the
    formulas, after Kümmerle et al. 2009).

    Args:
        trajectory: the estimate, planar (x, y, theta) or spatial (quaternions w, x, y, z).
        relations: the given relative poses.
        max_diff_s: stamp tolerance [s]; None: ``relations.max_diff_s``, else
            ``DEFAULT_MAX_DIFF_S`` (0.01 s).

    Returns:
        ``RelationsResult``: per-relation errors of the scored ones, skip reasons of the
        others.

    Raises:
        InputError: a tolerance that is not a positive finite number.
    """
    tolerance = _tolerance(max_diff_s, relations)
    count = len(relations)
    times = np.asarray(relations.times, dtype=float)
    stamps = np.asarray(trajectory.t, dtype=float)
    nearest = np.full((count, 2), -1, dtype=int)
    for column in range(2):
        queries, found = matching_time_indices(times[:, column], stamps, tolerance)
        nearest[queries, column] = found

    reasons = np.full(count, "", dtype=object)
    if len(stamps):
        outside = (times < stamps[0] - tolerance) | (times > stamps[-1] + tolerance)
        outside = outside.any(axis=1)
    else:
        outside = np.ones(count, dtype=bool)
    finite = np.isfinite(trajectory.positions).all(axis=1)
    rotation_finite = np.isfinite(trajectory.rotations)
    finite &= rotation_finite.all(axis=1) if rotation_finite.ndim == 2 else rotation_finite
    matched = (nearest >= 0).all(axis=1)
    finite_pair = np.zeros(count, dtype=bool)
    finite_pair[matched] = finite[nearest[matched]].all(axis=1)
    for reason, applies in (
        ("outside_span", outside),
        ("no_pose_near_t1", nearest[:, 0] < 0),
        ("no_pose_near_t2", nearest[:, 1] < 0),
        ("same_pose", matched & (nearest[:, 0] == nearest[:, 1])),
        ("non_finite_pose", matched & ~finite_pair),
    ):
        reasons[(reasons == "") & applies] = reason
    used = np.flatnonzero(reasons == "")

    poses = lift_to_3d(trajectory).homogeneous() if len(used) else np.zeros((0, 4, 4))
    first, second = nearest[used, 0], nearest[used, 1]
    estimated = np.einsum("nij,njk->nik", _inverse(poses[first]), poses[second])
    given = _given_transforms(relations)[used]
    delta = np.einsum("nij,njk->nik", _inverse(given), estimated)  # G^-1 (T_1^-1 T_2)
    offsets = np.abs(np.column_stack([stamps[first], stamps[second]]) - times[used])
    return RelationsResult(
        relations=relations,
        max_diff_s=tolerance,
        used=used,
        translation_errors_m=np.linalg.norm(delta[:, :3, 3], axis=1),
        rotation_errors_deg=np.rad2deg(rotation_angles(delta[:, :3, :3])),
        stamp_offsets_s=offsets.reshape(-1, 2),
        reasons=tuple(str(reason) for reason in reasons),
        estimate_poses=len(stamps),
    )


def _tolerance(max_diff_s: float | None, relations: Relations) -> float:
    value = max_diff_s if max_diff_s is not None else relations.max_diff_s
    value = DEFAULT_MAX_DIFF_S if value is None else float(value)
    if not (value > 0 and math.isfinite(value)):
        raise InputError(f"relations max_diff_s must be a positive number of seconds, got {value}")
    return value


def _given_transforms(relations: Relations) -> np.ndarray:
    """The given relative poses as homogeneous SE(3) transforms, shape (R, 4, 4)."""
    poses = np.asarray(relations.poses, dtype=float)
    transforms = np.tile(np.eye(4), (len(poses), 1, 1))
    if relations.dimension == 2:
        cos, sin = np.cos(poses[:, 2]), np.sin(poses[:, 2])
        transforms[:, 0, 0], transforms[:, 0, 1] = cos, -sin
        transforms[:, 1, 0], transforms[:, 1, 1] = sin, cos
        transforms[:, :2, 3] = poses[:, :2]
        return transforms
    if len(poses):
        # Rz(yaw) Ry(pitch) Rx(roll): intrinsic z-y'-x'' from the yaw, pitch, roll columns
        transforms[:, :3, :3] = Rotation.from_euler("ZYX", poses[:, [5, 4, 3]]).as_matrix()
    transforms[:, :3, 3] = poses[:, :3]
    return transforms


def _inverse(transforms: np.ndarray) -> np.ndarray:
    """Inverses of homogeneous rigid transforms, shape (K, n, n)."""
    size = transforms.shape[-1] - 1
    inverse = np.tile(np.eye(size + 1), (len(transforms), 1, 1))
    rotation_t = np.transpose(transforms[:, :size, :size], (0, 2, 1))
    inverse[:, :size, :size] = rotation_t
    inverse[:, :size, size] = -np.einsum("nij,nj->ni", rotation_t, transforms[:, :size, size])
    return inverse


def _mean(values: np.ndarray) -> float | None:
    return float(np.mean(values)) if len(values) else None


def _sample_std(values: np.ndarray) -> float | None:
    return float(np.std(values, ddof=1)) if len(values) > 1 else None
