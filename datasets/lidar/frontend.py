"""The lidar front end: KISS-ICP odometry and corner landmarks for each cloud, cached.

With odometry on, corners are extracted from KISS-ICP's deskewed frame, so a corner scan and
the odometry of a frame share one time (the latest point's) and one body frame. With
odometry off, corners come from the raw cloud at its stamp. Clouds with per-point times are
deskewed by KISS-ICP's constant-velocity prediction, or, with ``imu_deskew`` (a bag with an
IMU topic), by the gyro's rotation over the sweep (``datasets.lidar.imu_deskew``).

Results are cached by frame index: KISS-ICP is sequential, so the cache is always a prefix
of the frames and a second pass over a sequence (another estimator) costs nothing.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.errors import InputError
from datasets.lidar.corner_tracking import CornerTracker
from datasets.lidar.corners import CornerConfig, Corners, azimuth_scan_indices, scan_corners
from datasets.lidar.frontend_report import FrontEndReport
from datasets.lidar.imu_deskew import GyroBuffer, SweepMotion
from datasets.lidar.increment_noise import IncrementNoiseFit, yaw_rate_disagreement
from datasets.lidar.kiss_icp_odometry import (
    KissIcpOdometry,
    KissIcpSettings,
    deskew_to_end,
    normalized_point_times,
    pose_time,
    time_span,
)
from datasets.lidar.motion_settling import MotionSettling
from datasets.lidar.sweep_times import POINT_TIMES_DESCRIPTION, SweepOptions
from datasets.measurements import ImuSample, Odometry, PointCloud
from datasets.trajectory import Trajectory

HEADING_DISAGREEMENT_SE = 3.0
"""Standard errors of the corners' yaw-rate disagreement with KISS-ICP above which clouds
without per-point times get a warning (``LidarFrontEnd.heading_warning``)."""

HEADING_CHECK_FRAMES = 300
"""Frames (30 s at 10 Hz) whose re-observations the heading warning fits."""


class FrontEndSettings(BaseModel):
    """What the front end computes, and how."""

    model_config = ConfigDict(extra="forbid")

    odometry: bool = Field(True, description="run KISS-ICP")
    corners: bool = Field(True, description="extract corner landmarks")
    warmup_frames: int = Field(
        1,
        ge=0,
        description="withhold the corners of this many first frames of clouds with per-point times (no motion estimate to deskew them with yet)",
    )
    kiss: KissIcpSettings = Field(default_factory=KissIcpSettings, description="KISS-ICP settings")
    imu_deskew: bool = Field(
        False,
        description="deskew clouds with per-point times by the IMU's rotation "
        "(datasets.lidar.imu_deskew; the stream must carry ImuSample), not KISS-ICP's "
        "constant-velocity prediction",
    )
    corner: CornerConfig = Field(
        default_factory=CornerConfig, description="corner extractor settings"
    )
    confirm_corners: bool = Field(
        True,
        description="emit a corner only once it is found again where it was in the previous frame (KISS-ICP's poses): sliding outlines are never landmarks",
    )


class LidarSourceOptions(BaseModel):
    """``--data`` options every point-cloud source shares (bags and scan folders): how to
    read per-point times, and what the front end emits."""

    model_config = ConfigDict(extra="forbid")

    point_time_unit: str = Field(
        "auto", pattern="^(auto|s|ms|us|ns)$", description="unit of per-point times"
    )
    point_times: Literal["auto", "field", "azimuth"] = Field(
        "auto", description=POINT_TIMES_DESCRIPTION
    )
    sweep: SweepOptions = Field(
        default_factory=SweepOptions,
        description="spinning-lidar sweep timing, as sweep.KEY=VALUE (listed below)",
    )
    point_clouds: bool = Field(True, description="emit the clouds themselves in the stream")
    max_frames: int | None = Field(None, ge=1, description="stop after this many clouds")
    odometry: bool = Field(True, description="KISS-ICP odometry")
    corners: bool = Field(True, description="corner landmarks")
    warmup_frames: int = Field(
        1, ge=0, description="withhold the corners of this many first frames (not yet deskewable)"
    )
    kiss: KissIcpSettings = Field(
        default_factory=KissIcpSettings,
        description="KISS-ICP settings, as kiss.KEY=VALUE (listed below)",
    )
    corner: CornerConfig = Field(
        default_factory=CornerConfig,
        description="corner extractor settings, as corner.KEY=VALUE (listed below)",
    )
    confirm_corners: bool = Field(
        True,
        description="emit a corner only once it is found again where it was in the previous frame (KISS-ICP's poses; datasets.lidar.corner_tracking): the outline of a car slides with the viewpoint and is never a landmark",
    )

    def front_end_settings(self) -> FrontEndSettings:
        """The front end's share of these options."""
        return FrontEndSettings(
            **{
                name: getattr(self, name)
                for name in FrontEndSettings.model_fields
                if name in type(self).model_fields
            }
        )


def describe_lidar_options(model: type[LidarSourceOptions]) -> list[str]:
    """Option lines of a lidar source for ``workbench list --verbose``: its own, then the
    nested sweep timing, KISS-ICP and corner settings as ``sweep.KEY``, ``kiss.KEY`` and
    ``corner.KEY``."""
    from datasets.options import describe_model

    return (
        describe_model(model)
        + [f"sweep.{line}" for line in describe_model(SweepOptions)]
        + [f"kiss.{line}" for line in describe_model(KissIcpSettings)]
        + [f"corner.{line}" for line in describe_model(CornerConfig)]
    )


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


class LidarFrontEnd:
    """KISS-ICP + corner extractor over a stream of clouds, with a prefix cache."""

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

    def resolved(self) -> dict[str, object]:
        """What KISS-ICP runs with, for the run's metadata: max range and voxel [m], where
        the range came from, and the covariance of its increments at the last frame (empty
        before the first scan or without odometry)."""
        settings = self.kiss_settings
        if settings is None or settings.max_range_m is None or not self.frames:
            return {}
        voxel = settings.voxel_size_m or settings.max_range_m / 100.0
        return {
            "max_range_m": float(settings.max_range_m),
            "voxel_size_m": float(voxel),
            "max_range_source": self._odometry.range_source,
            **self._deskew_summary(),
            **self.settling.summary(),
            **self.increment_noise.current.summary(),
        }

    def _deskew_summary(self) -> dict[str, object]:
        """How the clouds were deskewed, for ``resolved``."""
        if self.untimed_frames == len(self.frames):
            return {"deskew": "none (no per-point times: taken as motion-compensated)"}
        if not self.settings.imu_deskew:
            return {"deskew": "kiss-icp" if self.settings.kiss.deskew else "off"}
        return {
            "deskew": "imu",
            "imu_deskewed_frames": self.imu_deskewed_frames,
            "imu_deskew_fallback_frames": len(self.imu_fallback_stamps),
        }

    def corner_yaw_rate(self, frames: int | None = None) -> tuple[float, float] | None:
        """The constant yaw-rate error of KISS-ICP's poses that the corners' re-observations
        so far imply, and its standard error (jackknife over corners) [rad/s]
        (``increment_noise.yaw_rate_disagreement``); over the re-observations made in the
        first ``frames`` frames when given. None without odometry or pairs."""
        if not self.frames or any(frame.pose is None for frame in self.frames):
            return None
        poses = np.array([frame.pose for frame in self.frames])
        pairs = self.tracker.stats.pairs
        if frames is not None:
            pairs = [pair for pair in pairs if pair.frame < frames]
        return yaw_rate_disagreement(
            pairs,
            poses[:, :2, 3],
            poses[:, :2, :2],
            np.array([frame.t for frame in self.frames]),
        )

    def heading_warning(self) -> str | None:
        """A warning when the corners' re-observations disagree with KISS-ICP's heading by
        more than ``HEADING_DISAGREEMENT_SE`` standard errors (``corner_yaw_rate``) on clouds
        that carry no per-point times, None otherwise.

        Such clouds are taken as motion-compensated, and an uncompensated spinning sweep
        read that way makes exactly this disagreement: on the real KITTI clip -0.41 +- 0.10
        deg/s by default, the estimators 0.7 deg off in heading; its clouds are not
        compensated (``benchmarks/kitti_clip_sweep_seam.py``), and with
        ``point_times=azimuth`` the disagreement is -0.18 +- 0.27 deg/s. A disagreement of
        clouds with times is left to the printed figure: either side may be wrong.

        Over the first ``HEADING_CHECK_FRAMES`` frames: a constant yaw-rate error is a model
        for a short span, and the fit's corner clustering grows with the square of the
        pairs. Computed once per number of frames (each pass over a sequence asks again)."""
        if not self.frames or 2 * self.untimed_frames < len(self.frames):
            return None
        if self._heading_checked[0] != len(self.frames):
            self._heading_checked = (len(self.frames), self._heading_text())
        return self._heading_checked[1]

    def _heading_text(self) -> str | None:
        """``heading_warning``'s text, computed."""
        disagreement = self.corner_yaw_rate(HEADING_CHECK_FRAMES)
        if disagreement is None:
            return None
        omega, error = (float(np.rad2deg(value)) for value in disagreement)
        if not abs(omega) > HEADING_DISAGREEMENT_SE * error:
            return None
        checked = self.frames[:HEADING_CHECK_FRAMES]
        span = checked[-1].t - checked[0].t
        return (
            f"the corners disagree with KISS-ICP's heading by {omega:+.2f} +- {error:.2f} deg/s "
            f"({omega * span:+.2f} deg over the first {span:.1f} s; +- : jackknife over "
            "corners), and "
            f"{self.untimed_frames} of {len(self.frames)} clouds carry no per-point times, so "
            "they were taken as motion-compensated: an uncompensated sweep read that way "
            "does this (the estimators follow the corners in heading). If the clouds are "
            "KITTI raw's, rerun with --data point_times=azimuth"
        )

    def settling_warning(self) -> str | None:
        """A warning when the warm-up ended without KISS-ICP settling by the corners
        (``motion_settling.LIMIT_FRAMES``), None otherwise."""
        frame = self.settling.gave_up_frame
        if frame is None:
            return None
        return (
            f"warm-up: the corners never accepted KISS-ICP's increments three frames in a row "
            f"up to frame {frame}; its first {self.settling.inflated_frames} increments and "
            "their corners were inflated by the error the corners showed, and nothing after "
            "(datasets.lidar.motion_settling)"
        )

    def imu_deskew_warning(self) -> str | None:
        """A warning naming the frames the IMU deskew had to leave to KISS-ICP's
        constant-velocity deskew (IMU samples missing over their sweep), None otherwise."""
        stamps = self.imu_fallback_stamps
        if not stamps:
            return None
        return (
            f"IMU deskew: {len(stamps)} of {len(stamps) + self.imu_deskewed_frames} clouds "
            f"had no IMU samples over their sweep (first at t={stamps[0]:.3f} s) and were "
            "deskewed by KISS-ICP's constant-velocity prediction instead"
        )

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


def with_front_end(
    measurements,
    front_end: LidarFrontEnd,
    emit_clouds: bool = True,
    max_frames: int | None = None,
    emit_from_s: float | None = None,
):
    """Interleave the front end's odometry and corner scans into a stamp-ordered stream.

    Clouds stamped before ``emit_from_s`` (the sequence's start, when its first sweep began
    before it) go through the front end but are not emitted themselves.

    A frame's outputs are stamped at or after its cloud's stamp (``output_time``), and every
    later input is stamped at or after that too, so anything queued up to the current
    input's stamp can be released: the output stays time-ordered without a look-ahead
    window. A cloud the IMU deskews (``waits_for_imu``) is held until an IMU sample at or
    after its sweep end has arrived (or the next cloud, or the stream's end: the front end
    then falls back to KISS-ICP's deskew and counts it), and meanwhile only what is stamped
    before its outputs is released. The holding depends on the stream alone, not on the
    front end's cache, so every pass over a sequence gives the same order. Empty corner
    scans are not emitted. Stops before the ``max_frames + 1``-th cloud when ``max_frames``
    is set.
    """
    import heapq
    import itertools

    queue: list = []
    order = itertools.count()
    index = 0
    held: PointCloud | None = None  # a cloud waiting for the IMU to pass its sweep end
    held_until = np.inf  # its outputs' stamp
    latest_imu = -np.inf  # stamp of the latest IMU sample of this pass

    def run(cloud: PointCloud) -> None:
        nonlocal index
        frame = front_end.frame(index, cloud)
        index += 1
        if frame.odometry is not None:
            heapq.heappush(queue, (frame.t, next(order), frame.odometry))
        if frame.corners is not None and len(frame.corners.points):
            heapq.heappush(queue, (frame.t, next(order), frame.corners.scan(frame.t)))

    for measurement in measurements:
        if isinstance(measurement, PointCloud):
            if max_frames is not None and index + (held is not None) >= max_frames:
                break
            if held is not None:
                run(held)
                held, held_until = None, np.inf
            if emit_clouds and (emit_from_s is None or measurement.t >= emit_from_s):
                heapq.heappush(queue, (measurement.t, next(order), measurement))
            if front_end.waits_for_imu(measurement):
                held, held_until = measurement, front_end.output_time(measurement)
            else:
                run(measurement)
        else:
            heapq.heappush(queue, (measurement.t, next(order), measurement))
            if isinstance(measurement, ImuSample):
                front_end.add_imu(measurement)
                latest_imu = max(latest_imu, measurement.t)
        if held is not None and latest_imu >= held_until:
            run(held)
            held, held_until = None, np.inf
        while queue and queue[0][0] <= measurement.t and queue[0][0] < held_until:
            yield heapq.heappop(queue)[2]
    if held is not None:
        run(held)
    while queue:
        yield heapq.heappop(queue)[2]
