"""What a lidar front end says about its pass beside its frames (``FrontEndDiagnostics``,
a base of ``datasets.lidar.frontend.LidarFrontEnd``): what KISS-ICP ran with and how the
clouds were deskewed, for the run's metadata (``resolved``), and the warnings a pass can
earn: the corners disagreeing with KISS-ICP's heading on clouds without per-point times
(``heading_warning``), a warm-up that never settled (``settling_warning``), clouds the IMU
deskew had to leave to KISS-ICP (``imu_deskew_warning``).
"""

from __future__ import annotations

import numpy as np

from datasets.lidar.increment_noise import yaw_rate_disagreement

HEADING_DISAGREEMENT_SE = 3.0
"""Standard errors of the corners' yaw-rate disagreement with KISS-ICP above which clouds
without per-point times get a warning (``LidarFrontEnd.heading_warning``)."""

HEADING_CHECK_FRAMES = 300
"""Frames (30 s at 10 Hz) whose re-observations the heading warning fits."""


class FrontEndDiagnostics:
    """The reports of a ``LidarFrontEnd`` on its pass so far (module docstring). They read
    the state the front end keeps and change none of it but the heading check's memo: its
    ``settings``, ``frames``, ``untimed_frames``, ``tracker``, ``settling``,
    ``increment_noise``, ``imu_deskewed_frames``, ``imu_fallback_stamps``,
    ``kiss_settings``, ``_odometry`` and ``_heading_checked`` (frames checked, warning)."""

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
