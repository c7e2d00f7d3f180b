"""The 2-D laser front end: corners of every scan, confirmed by the next scan, as
``LandmarkScan`` measurements without ids.

For scan ``j`` and the motion increment from scan ``j - 1`` (its ``Odometry``), the front end
extracts the corners (``datasets.laser2d.corners``), matches them to scan ``j - 1``'s
(``datasets.laser2d.reobservation``) and emits the confirmed ones: body-frame points (k, 2)
with their 2x2 covariances, ``ids=None`` (a laser does not know which corner it sees). The
first sighting of every corner is withheld (it has nothing to be confirmed by), and a corner
that slides with the viewpoint is never emitted. Results are cached by scan index, so a
second pass over a sequence (another estimator) costs nothing.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from pydantic import BaseModel, ConfigDict, Field
from scipy.stats import chi2

from datasets.errors import InputError
from datasets.laser2d.corners import Laser2dCornerSettings, planar_scan_corners
from datasets.laser2d.reobservation import PairGroup, ReobservationLog, match_consecutive
from datasets.laser2d.scan import PlanarScan
from datasets.lidar.corner_config import CornerConfig
from datasets.lidar.corners import Corners
from datasets.measurements import LandmarkScan


class Laser2dFrontEndSettings(BaseModel):
    """What the 2-D laser front end emits, and how."""

    model_config = ConfigDict(extra="forbid")

    corner: Laser2dCornerSettings = Field(
        default_factory=Laser2dCornerSettings,
        description="corner extractor settings, as corner.KEY=VALUE (listed below)",
    )
    confirm_corners: bool = Field(
        True,
        description="emit a corner only once the previous scan saw it in place (carried by "
        "the motion increment, within the confirm_probability gate); false: every corner",
    )
    confirm_probability: float = Field(
        0.99, gt=0, lt=1, description="chi-square gate (2 dof) of the confirmation"
    )
    calibration_probability: float = Field(
        0.999,
        gt=0,
        lt=1,
        description="chi-square gate (2 dof) of the pairs the re-observation NIS is read on",
    )


@dataclass(frozen=True)
class FrontEndScan:
    """The front end's output for one scan.

    Attributes:
        t: the scan's time [s].
        corners: every corner extracted (body frame).
        confirmed: (k,) which of them the previous scan confirmed.
        seconds: wall time spent [s].
    """

    t: float
    corners: Corners
    confirmed: np.ndarray
    seconds: float

    def landmark_scan(self, confirmed_only: bool) -> LandmarkScan | None:
        """The corners to emit as a ``LandmarkScan`` without ids (None when there are none)."""
        keep = self.confirmed if confirmed_only else np.ones(len(self.confirmed), dtype=bool)
        if not keep.any():
            return None
        return LandmarkScan(
            t=self.t,
            points=self.corners.points[keep],
            covariances=self.corners.covariances[keep],
        )


class Laser2dFrontEnd:
    """Corners per scan, confirmed against the previous scan, with a prefix cache and the
    re-observation record (``log``)."""

    def __init__(self, settings: Laser2dFrontEndSettings) -> None:
        self.settings = settings
        self.frames: list[FrontEndScan] = []
        self.log = ReobservationLog()
        self._confirm_gate = float(chi2.ppf(settings.confirm_probability, 2))
        self._calibration_gate = float(chi2.ppf(settings.calibration_probability, 2))
        self._configs: dict[float, CornerConfig] = {}  # extractor settings by beam spacing

    def frame(
        self,
        index: int,
        scan: PlanarScan,
        increment: np.ndarray | None = None,
        increment_covariance: np.ndarray | None = None,
    ) -> FrontEndScan:
        """The result for the ``index``-th scan (computed once, then cached).

        Args:
            scan: the scan.
            increment: (3,) motion from the previous scan (its body frame; None for the first).
            increment_covariance: (3, 3) that increment's covariance.
        """
        if index < len(self.frames):
            cached = self.frames[index]
            if abs(cached.t - scan.t) > 1e-9:
                raise InputError(
                    f"2-D laser front end: scan {index} has stamp {scan.t:.6f}, cached "
                    f"{cached.t:.6f} (the source changed)"
                )
            return cached
        if index != len(self.frames):
            raise InputError(
                f"2-D laser front end: scan {index} requested before scan {len(self.frames)}"
            )
        started = time.perf_counter()
        angles = scan.angles
        step = round(float(angles[-1] - angles[0]) / max(len(angles) - 1, 1), 12)
        config = self._configs.get(step)
        if config is None:
            config = self._configs[step] = self.settings.corner.corner_config(step)
        corners = planar_scan_corners(scan, self.settings.corner, config)
        confirmed = np.zeros(len(corners.points), dtype=bool)
        if increment is not None and self.frames:
            previous = self.frames[-1].corners
            found, residuals, sums, jacobians, _ = match_consecutive(
                previous.points,
                previous.covariances,
                corners.points,
                corners.covariances,
                np.asarray(increment, dtype=float),
                np.asarray(increment_covariance, dtype=float),
                self._calibration_gate,
            )
            if found.any():
                scale = self.settings.corner.covariance_scale
                motion = np.einsum("kia,ab,kjb->kij", jacobians, increment_covariance, jacobians)
                total = sums + motion
                distance = np.einsum("ki,kij,kj->k", residuals, np.linalg.inv(total), residuals)
                confirmed[np.flatnonzero(found)] = distance <= self._confirm_gate
                self.log.groups.append(
                    PairGroup(
                        index,
                        residuals,
                        sums / scale,  # unit corner scale: the fit returns the absolute one
                        jacobians,
                        np.asarray(increment_covariance, dtype=float),
                    )
                )
        self.log.corners += len(corners.points)
        self.log.confirmed += int(confirmed.sum())
        result = FrontEndScan(scan.t, corners, confirmed, time.perf_counter() - started)
        self.frames.append(result)
        return result

    def summary(self) -> dict[str, object]:
        """Corner counts, re-observation NIS and time per scan, JSON-serialisable."""
        seconds = np.array([frame.seconds for frame in self.frames])
        return {
            "scans": len(self.frames),
            **self.log.summary(
                self.settings.corner.covariance_scale, self.settings.calibration_probability
            ),
            "front_end_ms_per_scan": float(1e3 * seconds.mean()) if seconds.size else None,
        }
