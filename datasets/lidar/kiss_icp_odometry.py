"""Lidar odometry with KISS-ICP's Python API (``kiss_icp.kiss_icp.KissICP``, ``KISSConfig``).

Timestamps: KISS-ICP's preprocessor normalizes the per-point timestamps it is given to
[0, 1] by their min and max and deskews every point to the *end* of the sweep (normalized
time 1) with the constant-velocity prediction (the previous frame's motion). We hand it
the per-point times already normalized the same way (so a frame with all-equal times, which
would divide by zero inside, is passed without timestamps and not deskewed), and stamp the
resulting pose with the time of the latest point, ``t + max(point_times)``.

Output: the pose of each frame (body = lidar frame, world = the first frame's body frame),
as a ``Trajectory``, and relative poses between consecutive frames as ``Odometry``
measurements ``(rotation vector, translation)`` in the previous body frame, with the stated
per-frame covariance of the settings (KISS-ICP itself reports none; the front end raises it
where the corners' re-observations show more, ``datasets.lidar.increment_noise``).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.measurements import Odometry, PointCloud
from datasets.rotations import so3_log
from datasets.trajectory import Trajectory, trajectory_from_homogeneous


class KissIcpSettings(BaseModel):
    """KISS-ICP parameters used by the workbench (a subset of ``KISSConfig``)."""

    model_config = ConfigDict(extra="forbid")

    max_range_m: float | None = Field(
        None,
        gt=0,
        description="farthest point used [m]; None: from the first scan: KISS-ICP's own "
        "default (100 m) unless the scan is short-range (99.9th range percentile below half "
        "of it), then that percentile rounded up to 5 m (at least 10 m)",
    )
    min_range_m: float = Field(0.0, ge=0, description="nearest point used [m] (KISS-ICP's default)")
    voxel_size_m: float | None = Field(
        None, gt=0, description="map voxel [m] (default: max_range / 100, as KISS-ICP)"
    )
    deskew: bool = Field(
        True, description="motion-compensate with per-point times when the cloud has them"
    )
    max_points_per_voxel: int = Field(20, ge=1, description="KISS-ICP map density")
    max_num_threads: int = Field(
        0,
        ge=0,
        description="registration threads (0, KISS-ICP's default: as many as the machine has; "
        "1: bit-identical results on every machine; on the real KITTI clip the two differ by "
        "4e-15 m)",
    )
    covariance: Literal["re-observations", "stated"] = Field(
        "re-observations",
        description="covariance of a frame-to-frame odometry: per component the larger of the "
        "stated sigma and the one fitted (causally, every five frames) from the corners the "
        "front end re-observes (datasets.lidar.increment_noise), or the stated sigmas "
        "throughout",
    )
    rotation_sigma_rad: float = Field(
        0.002,
        gt=0,
        description="stated std of each rotation component of a frame-to-frame odometry [rad]",
    )
    translation_sigma_m: float = Field(
        0.02,
        gt=0,
        description="stated std of each translation component of a frame-to-frame odometry [m]",
    )

    def kiss_config(self):
        """The equivalent ``kiss_icp.config.KISSConfig`` (``max_range_m`` must be set)."""
        from kiss_icp.config import KISSConfig

        if self.max_range_m is None:
            raise ValueError("KissIcpSettings.kiss_config: resolve the max range first")
        config = KISSConfig()
        config.data.max_range = self.max_range_m
        config.data.min_range = self.min_range_m
        config.data.deskew = self.deskew
        config.mapping.voxel_size = (
            self.voxel_size_m if self.voxel_size_m is not None else self.max_range_m / 100.0
        )
        config.mapping.max_points_per_voxel = self.max_points_per_voxel
        config.registration.max_num_threads = self.max_num_threads
        return config


def time_span(point_times: np.ndarray | None) -> tuple[float, float] | None:
    """(earliest, latest) per-point time [s] of a cloud whose points carry times that
    differ, else None (no times, or one time for all: nothing to deskew)."""
    if point_times is None or len(point_times) == 0:
        return None
    low, high = float(np.min(point_times)), float(np.max(point_times))
    return (low, high) if high > low else None


def normalized_point_times(point_times: np.ndarray | None) -> np.ndarray:
    """Per-point times scaled to [0, 1] as KISS-ICP's deskew expects; empty (no deskew) when
    absent or when the cloud has a single time."""
    span = time_span(point_times)
    if span is None:
        return np.zeros(0)
    low, high = span
    return (np.asarray(point_times, dtype=np.float64) - low) / (high - low)


def pose_time(stamp_s: float, point_times: np.ndarray | None, deskew: bool = True) -> float:
    """Time [s] of the pose KISS-ICP gives a cloud stamped ``stamp_s``: its latest point's
    when the cloud is deskewed (per-point times that differ), else the stamp."""
    span = time_span(point_times) if deskew else None
    return float(stamp_s) + span[1] if span is not None else float(stamp_s)


@dataclass(frozen=True)
class RegisteredFrame:
    """One frame after KISS-ICP.

    Attributes:
        t: pose time [s] (the latest point's time).
        pose: (4, 4) body-to-world.
        points: (m, 3) deskewed, range-cropped points in the body frame at ``t`` [m].
        odometry: the relative pose since the previous frame, None for the first.
    """

    t: float
    pose: np.ndarray
    points: np.ndarray
    odometry: Odometry | None


def kiss_default_max_range() -> float:
    """KISS-ICP's own default max range [m] (``KISSConfig().data.max_range``, 100 m)."""
    from kiss_icp.config import KISSConfig

    return float(KISSConfig().data.max_range)


def range_from_scan(points: np.ndarray) -> tuple[float, str]:
    """The max range for a recording whose first scan is ``points`` (n, 3) [m], and where it
    came from.

    KISS-ICP's own default (100 m) unless the scan is short-range: when its 99.9th range
    percentile (a few stray far returns aside) is below half the default, that percentile
    rounded up to 5 m, at least 10 m. Why this rule: the max range also sets KISS-ICP's
    voxel (range / 100). Outdoors KISS-ICP's defaults are what its authors tuned and what a
    reader compares with; any other range moves the trajectory (on the real KITTI clip,
    whose 99.9th percentile is 78 m, 80 m moved it 3.2 cm in 30 frames; the fixed 30 m used
    before dropped 8 % of its points and took 3.1x the time through its 0.3 m voxel). Indoors the default's
    1 m voxel is too coarse for a corridor (the synthetic corridor bag gets 20 m)."""
    default = kiss_default_max_range()
    ranges = np.linalg.norm(np.asarray(points, dtype=float), axis=1)
    ranges = ranges[np.isfinite(ranges) & (ranges > 0)]
    if ranges.size == 0:
        return default, "KISS-ICP default (first scan empty)"
    percentile = float(np.percentile(ranges, 99.9))
    if percentile >= 0.5 * default:
        return (
            default,
            f"KISS-ICP default (first scan's 99.9th range percentile {percentile:.1f} m)",
        )
    derived = float(max(5.0 * np.ceil(percentile / 5.0), 10.0))
    return derived, f"first scan (short-range: 99.9th range percentile {percentile:.1f} m)"


class KissIcpOdometry:
    """Feeds clouds to KISS-ICP one at a time; remembers poses and times. KISS-ICP is built
    at the first cloud, once a max range left open can be derived from it
    (``range_from_scan``; ``range_source`` says how)."""

    def __init__(self, settings: KissIcpSettings) -> None:
        self.settings = settings
        self._icp = None
        self.range_source = "given"  # or how the max range was derived from the first scan
        self._times: list[float] = []
        self._poses: list[np.ndarray] = []
        covariance = np.diag(
            [settings.rotation_sigma_rad**2] * 3 + [settings.translation_sigma_m**2] * 3
        )
        self._covariance = covariance

    def register(self, cloud: PointCloud) -> RegisteredFrame:
        """Register one cloud (finite points, non-decreasing times across calls)."""
        if self._icp is None:
            from kiss_icp.kiss_icp import KissICP

            if self.settings.max_range_m is None:
                max_range, self.range_source = range_from_scan(cloud.points)
                self.settings = self.settings.model_copy(update={"max_range_m": max_range})
            self._icp = KissICP(self.settings.kiss_config())
        timestamps = (
            normalized_point_times(cloud.point_times) if self.settings.deskew else np.zeros(0)
        )
        t = pose_time(cloud.t, cloud.point_times, self.settings.deskew)
        frame, _ = self._icp.register_frame(
            np.ascontiguousarray(cloud.points, dtype=np.float64), timestamps
        )
        pose = np.array(self._icp.last_pose, dtype=float)
        odometry = None
        if self._poses:
            relative = np.linalg.inv(self._poses[-1]) @ pose
            odometry = Odometry(
                t=t,
                covariance=self._covariance.copy(),
                relative_pose=np.concatenate([so3_log(relative[:3, :3]), relative[:3, 3]]),
                dt=t - self._times[-1],
                frame=True,  # a sweep: the data expect a pose here
            )
        self._times.append(t)
        self._poses.append(pose)
        return RegisteredFrame(t=t, pose=pose, points=np.asarray(frame), odometry=odometry)

    def last_delta(self) -> np.ndarray:
        """(4, 4) motion of the last frame, previous pose^-1 @ last pose (identity at first)."""
        if len(self._poses) < 2:
            return np.eye(4)
        return np.linalg.inv(self._poses[-2]) @ self._poses[-1]

    def last_velocity(self) -> np.ndarray:
        """(3,) body-frame linear velocity [m/s] of the last frame: the translation part of
        the twist ``log(last_delta)`` over its duration (zero before the second frame)."""
        if len(self._poses) < 2 or not self._times[-1] > self._times[-2]:
            return np.zeros(3)
        return se3_log(self.last_delta())[:3] / (self._times[-1] - self._times[-2])

    def trajectory(self) -> Trajectory:
        """Poses so far (world = first body frame)."""
        if not self._poses:
            return Trajectory(np.zeros(0), np.zeros((0, 3)), np.zeros((0, 4)))
        return trajectory_from_homogeneous(np.array(self._times), np.array(self._poses))


def se3_log(pose: np.ndarray) -> np.ndarray:
    """Twist (rho (3,), phi (3,)) of a (4, 4) pose: ``pose = exp([rho, phi]^)``."""
    phi = so3_log(pose[:3, :3])
    theta = float(np.linalg.norm(phi))
    w = _hat(phi)
    if theta < 1e-9:
        v_inverse = np.eye(3) - 0.5 * w
    else:
        half = 0.5 * theta
        v_inverse = (
            np.eye(3) - 0.5 * w + (1.0 - half * np.cos(half) / np.sin(half)) / theta**2 * (w @ w)
        )
    return np.concatenate([v_inverse @ pose[:3, 3], phi])


def _hat(vector: np.ndarray) -> np.ndarray:
    x, y, z = vector
    return np.array([[0.0, -z, y], [z, 0.0, -x], [-y, x, 0.0]])


def deskew_to_end(
    points: np.ndarray, normalized_times: np.ndarray, delta: np.ndarray
) -> np.ndarray:
    """Move points to the sweep end under constant velocity, as KISS-ICP's deskew does
    (``p' = exp((s - 1) xi) p`` with ``xi = log(delta)``, s the normalized time), but with
    the frame's own estimated motion ``delta`` (previous pose^-1 @ this pose) instead of the
    prediction. Vectorized SE(3) exponential: ``R = Exp(a phi)``,
    ``t = V(a phi) a rho`` with ``V(w) = I + (1 - cos q)/q^2 [w] + (q - sin q)/q^3 [w]^2``.

    Args:
        points: (n, 3) [m]; normalized_times: (n,) in [0, 1]; delta: (4, 4).
    """
    from scipy.spatial.transform import Rotation

    xi = se3_log(delta)
    scale = (np.asarray(normalized_times, dtype=float) - 1.0)[:, None]
    phi, rho = scale * xi[3:], scale * xi[:3]
    theta = np.linalg.norm(phi, axis=1)
    small = theta < 1e-9
    safe = np.where(small, 1.0, theta)
    a = np.where(small, 0.5, (1.0 - np.cos(safe)) / safe**2)
    b = np.where(small, 1.0 / 6.0, (safe - np.sin(safe)) / safe**3)
    cross1 = np.cross(phi, rho)
    translation = rho + a[:, None] * cross1 + b[:, None] * np.cross(phi, cross1)
    return Rotation.from_rotvec(phi).apply(points) + translation
