"""The lidar front end: KISS-ICP odometry and corner landmarks for each cloud, cached.

With odometry on, corners are extracted from KISS-ICP's deskewed frame, so a corner scan and
the odometry of a frame share one time (the latest point's) and one body frame. With
odometry off, corners come from the raw cloud at its stamp. Clouds with per-point times are
deskewed by KISS-ICP's constant-velocity prediction, or, with ``imu_deskew`` (a bag with an
IMU topic), by the gyro's rotation over the sweep (``datasets.lidar.imu_deskew``).

Results are cached by frame index: KISS-ICP is sequential, so the cache is always a prefix
of the frames and a second pass over a sequence (another estimator) costs nothing.

Its settings are ``datasets.lidar.frontend_settings``; what it reports on a pass (the
settings KISS-ICP resolved, the warnings) ``datasets.lidar.frontend_diagnostics``; its
place in a sequence's stream ``datasets.lidar.frontend_stream.with_front_end``.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace

import numpy as np

from datasets.errors import InputError
from datasets.lidar.corner_scan import azimuth_scan_indices
from datasets.lidar.corner_tracking import CornerTracker
from datasets.lidar.corners import Corners, scan_corners
from datasets.lidar.frontend_diagnostics import FrontEndDiagnostics
from datasets.lidar.frontend_report import FrontEndReport
from datasets.lidar.frontend_settings import FrontEndSettings
from datasets.lidar.imu_deskew import GyroBuffer, SweepMotion
from datasets.lidar.increment_noise import IncrementNoiseFit
from datasets.lidar.kiss_icp_odometry import (
    KissIcpOdometry,
    KissIcpSettings,
    deskew_to_end,
    normalized_point_times,
    pose_time,
    time_span,
)
from datasets.lidar.motion_settling import MotionSettling
from datasets.measurements import ImuSample, Odometry, PointCloud
from datasets.trajectory import Trajectory


@dataclass(frozen=True)
class FrontEndFrame:
    """The front end's output for one cloud.

    Attributes:
        cloud_t: the cloud's stamp [s].
        t: time of the pose, odometry and corners [s].
        points: number of points in the cloud.
        pose: (4, 4) KISS-ICP body-to-world pose, or None without odometry.
        odometry: relative pose since the previous frame (None for the first / without).
        corners: the corners, or None without corner extraction.
        icp_seconds, corner_seconds: wall time spent [s].
    """

    cloud_t: float
    t: float
    points: int
    pose: np.ndarray | None
    odometry: Odometry | None
    corners: Corners | None
    icp_seconds: float
    corner_seconds: float


class LidarFrontEnd(FrontEndDiagnostics):
    """KISS-ICP + corner extractor over a stream of clouds, with a prefix cache; its
    reports on a pass (``resolved``, the warnings) are ``FrontEndDiagnostics``."""

    def __init__(self, settings: FrontEndSettings, sole_motion_input: bool = True) -> None:
        """``sole_motion_input``: the sequence offers no motion input but this front end's
        increments (``FrontEndReport.sole_motion_input``)."""
        self.settings = settings
        self.frames: list[FrontEndFrame] = []
        self.untimed_frames = 0  # clouds without per-point times (taken as compensated)
        self._heading_checked: tuple[int, str | None] = (-1, None)  # (frames, warning)
        self._odometry = KissIcpOdometry(settings.kiss) if settings.odometry else None
        self.tracker = CornerTracker()
        # what the pass made, typed, for the Sequence (datasets.lidar.frontend_report)
        self.report = FrontEndReport(
            sole_motion_input=sole_motion_input,
            reobservation=self.tracker.stats if settings.corners else None,
        )
        self.increment_noise = IncrementNoiseFit(
            settings.kiss.rotation_sigma_rad, settings.kiss.translation_sigma_m
        )
        self.settling = MotionSettling()
        if settings.odometry:  # the warm-up's state, as the report shows it
            self.report.settling = self.settling
        self._gyro = GyroBuffer()
        self.imu_deskewed_frames = 0
        self.imu_fallback_stamps: list[float] = []  # imu_deskew frames the IMU did not cover

    def add_imu(self, sample: ImuSample) -> None:
        """Keep a gyro sample for the IMU deskew (a no-op without it; samples already kept,
        as in a second pass over the stream, are ignored)."""
        if self.settings.imu_deskew:
            self._gyro.add(sample.t, sample.gyro)

    def waits_for_imu(self, cloud: PointCloud) -> bool:
        """Whether ``cloud`` is deskewed with the IMU, so that its frame must wait for the
        IMU samples up to its sweep end (``with_front_end``)."""
        return (
            self.settings.imu_deskew
            and self._odometry is not None
            and self.settings.kiss.deskew
            and time_span(cloud.point_times) is not None
        )

    def output_time(self, cloud: PointCloud) -> float:
        """Time [s] of the pose, odometry and corners the front end gives ``cloud``."""
        if self._odometry is None:
            return cloud.t
        return pose_time(cloud.t, cloud.point_times, self.settings.kiss.deskew)

    def frame(self, index: int, cloud: PointCloud) -> FrontEndFrame:
        """The result for the ``index``-th cloud (computed once, then cached)."""
        if index < len(self.frames):
            cached = self.frames[index]
            if abs(cached.cloud_t - cloud.t) > 1e-9:
                raise InputError(
                    f"lidar front end: frame {index} has stamp {cloud.t:.9f}, cached {cached.cloud_t:.9f} (the source changed)"
                )
            return cached
        if index != len(self.frames):
            raise InputError(
                f"lidar front end: frame {index} requested before frame {len(self.frames)}"
            )
        started = time.perf_counter()
        self.untimed_frames += cloud.point_times is None
        # The corners' pass over the whole cloud comes first, while the cloud is still in the
        # caches from its reading: after KISS-ICP it costs 0.25 ms more on a KITTI scan.
        scan = (
            azimuth_scan_indices(cloud.points, self.settings.corner)
            if self.settings.corners
            else None
        )
        selected = time.perf_counter()
        # the gyro's rotation over the sweep, when the IMU deskews it (counted as KISS-ICP's
        # time, which it replaces)
        motion = self._imu_motion(cloud) if self.waits_for_imu(cloud) else None
        pose, odometry, t = None, None, cloud.t
        if self._odometry is not None:
            registered = self._odometry.register(self._imu_deskewed(cloud, motion))
            pose, odometry, t = registered.pose, registered.odometry, registered.t
        icp_done = time.perf_counter()
        corners = self._corners(cloud, odometry, motion, *scan) if scan is not None else None
        if (
            corners is not None
            and cloud.point_times is not None
            and len(self.frames) < self.settings.warmup_frames
        ):
            corners = _select(corners, np.zeros(len(corners.points), dtype=bool))
        steps = (np.zeros((0, 2)), np.zeros((0, 2, 2)))  # this frame's corners vs the last
        if corners is not None and pose is not None and len(corners.points):
            d = corners.points.shape[1]
            seen = len(self.tracker.stats.pairs)
            confirmed = self.tracker.confirm(
                len(self.frames), pose[:d, :d], pose[:d, 3], corners.points, corners.covariances
            )
            steps = (self.tracker.step_residuals, self.tracker.step_covariances)
            if self.settings.confirm_corners:
                corners = _select(corners, confirmed)
            if self.settings.kiss.covariance == "re-observations":
                frames = self.frames
                self.increment_noise.update(
                    len(frames),
                    self.tracker.stats.pairs[seen:],
                    lambda k: pose if k == len(frames) else frames[k].pose,
                )
        if odometry is not None and self.settings.kiss.covariance == "re-observations":
            # this frame's increment: the larger of the stated covariance and the fit over the
            # re-observations up to this frame
            odometry = replace(odometry, covariance=self.increment_noise.current.covariance())
        # the warm-up (datasets.lidar.motion_settling): until the corners accept KISS-ICP's
        # increments, each increment and the frame's corners are inflated by the error the
        # corners show
        extra = (
            self.settling.increment_inflation(len(self.frames), *steps)
            if odometry is not None
            else None
        )
        if extra is not None:
            odometry = self._inflated_increment(odometry, extra)
            if corners is not None and len(corners.points):
                corners = _inflated_corners(corners, pose, extra)
        result = FrontEndFrame(
            cloud.t,
            t,
            len(cloud.points),
            pose,
            odometry,
            corners,
            icp_done - selected,
            time.perf_counter() - icp_done + selected - started,
        )
        self.frames.append(result)
        if odometry is not None:
            self.report.increment_noise = self.increment_noise.current
        self.report.add_frame(
            t,
            pose,
            None if odometry is None else odometry.covariance,
            result.icp_seconds,
            result.corner_seconds,
            0 if corners is None else len(corners.points),
            cloud.point_times is None,
        )
        return result

    def _inflated_increment(self, odometry: Odometry, extra: np.ndarray) -> Odometry:
        """The increment with ``extra`` (2, 2) world-frame [m^2] added to its horizontal
        translation covariance (``motion_settling``), turned into the frame of the previous
        pose, in which the increment's translation is expressed."""
        covariance = np.array(odometry.covariance, dtype=float)
        covariance[3:6, 3:6] += _horizontal_in_body(extra, self.frames[-1].pose[:3, :3])
        return replace(odometry, covariance=covariance)

    def _imu_motion(self, cloud: PointCloud) -> SweepMotion | None:
        """The body's rotation over the sweep of ``cloud`` from the gyro, or None when the
        IMU samples do not cover it (counted in ``imu_fallback_stamps`` but for the first
        frame: a bag's time base starts at the first sweep's end, ``start_at_first_pose``,
        so its IMU samples before it are trimmed, and KISS-ICP, with no motion yet, does not
        deskew that sweep either)."""
        earliest, latest = time_span(cloud.point_times)
        start, end = cloud.t + earliest, cloud.t + latest
        previous = self.frames[-1].t if self.frames else start
        self._gyro.forget_before(min(start, previous))
        if not self._gyro.covers(start, end):
            if self.frames:
                self.imu_fallback_stamps.append(cloud.t)
            return None
        self.imu_deskewed_frames += 1
        return self._gyro.motion(start, end)

    def _imu_deskewed(self, cloud: PointCloud, motion: SweepMotion | None) -> PointCloud:
        """``cloud`` moved to its sweep end by ``motion`` and the previous frame's body
        velocity, as a cloud without times stamped there (KISS-ICP then does not deskew
        it); ``cloud`` itself without a motion."""
        if motion is None:
            return cloud
        points = motion.to_end(
            cloud.points, cloud.t + cloud.point_times, self._odometry.last_velocity()
        )
        return PointCloud(t=float(motion.times[-1]), points=points)

    def _corners(
        self,
        cloud: PointCloud,
        odometry: Odometry | None,
        motion: SweepMotion | None,
        chosen: np.ndarray,
        bins: np.ndarray,
    ) -> Corners:
        """Corners of the azimuth scan ``chosen`` (point indices) / ``bins``
        (``azimuth_scan_indices``), deskewed to the frame's pose time with the frame's own
        estimated motion (better than KISS-ICP's deskew by the previous frame's motion, which
        lags when the vehicle turns): its rotation from the IMU when ``motion`` is given,
        its velocity from the frame's KISS-ICP increment. Without odometry or times, the raw
        slab points."""
        config = self.settings.corner
        # Only the azimuth scan (about one point per bin) is deskewed, keeping the order and
        # bins the sensor measured them in (``scan_corners``).
        points = cloud.points[chosen]
        if motion is not None and odometry is not None:
            points = motion.to_end(
                points, cloud.t + cloud.point_times[chosen], self._odometry.last_velocity()
            )
        elif odometry is not None and self.settings.kiss.deskew:
            times = normalized_point_times(cloud.point_times)
            if times.size:
                points = deskew_to_end(points, times[chosen], self._odometry.last_delta())
        return scan_corners(np.ascontiguousarray(points[:, :2]), bins, config)

    @property
    def kiss_settings(self) -> KissIcpSettings | None:
        """The KISS-ICP settings in use (the max range resolved from the first scan once
        one has arrived), or None without odometry."""
        return None if self._odometry is None else self._odometry.settings

    def trajectory(self) -> Trajectory | None:
        """KISS-ICP poses of the frames so far (world = first body frame), or None."""
        return None if self._odometry is None else self._odometry.trajectory()


def _inflated_corners(corners: Corners, pose: np.ndarray, extra: np.ndarray) -> Corners:
    """Corners with ``extra`` (2, 2) world-frame [m^2] added to their horizontal covariance,
    turned into the body frame of ``pose`` (4, 4): a frame deskewed with an increment off by
    ``delta`` moves each point by up to ``delta`` (``motion_settling``)."""
    d = corners.points.shape[1]
    return replace(
        corners, covariances=corners.covariances + _horizontal_in_body(extra, pose[:d, :d])
    )


def _horizontal_in_body(extra: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """A world-frame horizontal covariance ``extra`` (2, 2) [m^2] as a (d, d) covariance in
    the body frame of ``rotation`` (d, d), body-to-world."""
    d = rotation.shape[0]
    world = np.zeros((d, d))
    world[:2, :2] = extra
    return rotation.T @ world @ rotation


def _select(corners: Corners, keep: np.ndarray) -> Corners:
    return replace(
        corners,
        points=corners.points[keep],
        covariances=corners.covariances[keep],
        directions=None if corners.directions is None else corners.directions[keep],
    )
