"""Per-point times of spinning-lidar clouds that carry none (``--data point_times=azimuth``,
or ``point_times=auto`` where ``datasets.lidar.sweep_timing`` finds the sweeps raw).

A point's time comes from its azimuth in the lidar's own frame: the sensor spins at a
constant rate, so the angle turned since the sweep began, over a full turn, is the fraction
of the sweep (one frame interval) elapsed. Three things fix the rule, and scan folders and
bags share them (``SweepOptions``): the spin direction, the azimuth where a sweep begins
(both found in the data by ``sweep_timing`` unless stated), and where in the sweep the
frame's stamp lies, which no cloud can tell (stated; by default where the sweep faces
forward, +x, as KITTI raw's camera trigger does). KITTI raw's velodyne_points are a
clockwise sweep from behind (KISS-ICP's KITTI-raw loader computes the same times): the
defaults of ``azimuth_point_times``.
"""

from __future__ import annotations

from typing import Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.errors import InputError

CLOCKWISE, COUNTERCLOCKWISE = -1, 1
"""Spin directions seen from above (z up): the sign of the azimuth's change with time."""

POINT_TIMES_DESCRIPTION = (
    "per-point times: 'auto' decides from the first clouds whether the sweeps are "
    "motion-compensated (datasets.lidar.sweep_timing; the decision and its evidence are "
    "printed): clouds with a time field keep it, raw sweeps without one are timed by azimuth, "
    "compensated ones (or an undecided recording, with a warning) get none; 'field', from a "
    "time field where a cloud has one (none otherwise: the clouds are taken as "
    "motion-compensated); 'azimuth', from each point's azimuth, for clouds of a spinning lidar "
    "that are not motion-compensated and carry no times (spin direction and start from the "
    "data or sweep.direction / sweep.start_deg); a cloud with times of its own is refused"
)


class SweepOptions(BaseModel):
    """How a spinning lidar's sweep is timed, where the data cannot tell or the user knows
    (``--data sweep.KEY=VALUE``)."""

    model_config = ConfigDict(extra="forbid")

    direction: Literal["auto", "clockwise", "counterclockwise"] = Field(
        "auto",
        description="spin direction seen from above (auto: found in the data where a sweep's "
        "seam shows; KITTI raw's velodyne: clockwise)",
    )
    start_deg: float | None = Field(
        None,
        ge=-180.0,
        le=360.0,
        description="azimuth where a sweep begins [deg], lidar frame (0 = +x forward, 90 = +y "
        "left) (default: found in the data; KITTI raw's velodyne: 180, behind)",
    )
    stamp: Literal["forward", "start", "end"] = Field(
        "forward",
        description="where in the sweep a cloud's stamp lies: where it faces forward (+x; "
        "KITTI raw's camera trigger), at its start or at its end (no cloud tells this)",
    )
    frames: int = Field(
        10,
        ge=3,
        le=100,
        description="clouds read at load to decide the sweep timing (point_times=auto)",
    )


class AzimuthSweep(float):
    """One sweep [s] of a spinning lidar whose clouds are timed by azimuth: the float's own
    value (what ``datasets.bags.read_report.ReadSettings.azimuth_sweep_s`` and ``point_times_for``
    expect), with the spin ``direction`` (``CLOCKWISE`` / ``COUNTERCLOCKWISE``), the azimuth
    ``start_deg`` [deg] where a sweep begins and where its ``stamp`` lies. A plain float is
    KITTI raw's sweep (clockwise from behind, stamped facing forward)."""

    direction: int
    start_deg: float
    stamp: str

    def __new__(
        cls,
        sweep_s: float,
        direction: int = CLOCKWISE,
        start_deg: float = 180.0,
        stamp: str = "forward",
    ) -> AzimuthSweep:
        value = super().__new__(cls, sweep_s)
        value.direction, value.start_deg, value.stamp = int(direction), float(start_deg), stamp
        return value

    def __repr__(self) -> str:
        spin = "clockwise" if self.direction == CLOCKWISE else "counterclockwise"
        return f"AzimuthSweep({float(self)!r} s, {spin} from {self.start_deg:g} deg, {self.stamp})"

    def describe(self) -> str:
        """E.g. ``clockwise from 180.0 deg over 0.100 s, stamped facing forward``."""
        spin = "clockwise" if self.direction == CLOCKWISE else "counterclockwise"
        where = {"forward": "facing forward (+x)", "start": "at its start", "end": "at its end"}
        return (
            f"{spin} from {self.start_deg:.1f} deg over {float(self):.3f} s, stamped "
            f"{where[self.stamp]}"
        )


def sweep_fraction(points: np.ndarray, direction: int, start_deg: float) -> np.ndarray:
    """The fraction [0, 1) of a sweep elapsed when each point (n, 3) [m] (lidar frame) was
    measured: the angle turned from ``start_deg`` in the spin ``direction``, over a turn."""
    azimuth = np.arctan2(points[:, 1], points[:, 0])
    turned = np.mod(direction * (azimuth - np.deg2rad(start_deg)), 2.0 * np.pi)
    return turned / (2.0 * np.pi)


def azimuth_point_times(
    points: np.ndarray,
    sweep_s: float,
    direction: int = CLOCKWISE,
    start_deg: float = 180.0,
    stamp: str = "forward",
) -> np.ndarray:
    """Per-point times [s] relative to the frame's stamp, (n,), of a spinning lidar's cloud
    that carries none: the sweep's elapsed fraction (``sweep_fraction``) minus the fraction
    at the stamp, times ``sweep_s``.

    The defaults are KITTI raw's timing, ``-atan2(y, x) / (2 pi) * sweep_s``: a clockwise
    sweep seen from above that starts behind (azimuth +180 deg, ``-sweep_s / 2``), faces
    forward at the stamp and ends behind (``+sweep_s / 2``). Its velodyne_points are not
    motion-compensated, and the camera is triggered as the sensor faces forward (the raw
    data's readme; KISS-ICP's KITTI-raw loader uses the same rule).

    Args:
        points: (n, 3) [m], sensor frame (x forward, y left, z up). sweep_s: one revolution
        [s]. direction: ``CLOCKWISE`` or ``COUNTERCLOCKWISE``. start_deg: azimuth where a
        sweep begins [deg]. stamp: ``forward`` (the stamp where the sweep faces +x),
        ``start`` or ``end``.
    """
    fraction = sweep_fraction(points, direction, start_deg)
    if stamp == "start":
        at_stamp = 0.0
    elif stamp == "end":
        at_stamp = 1.0
    else:
        at_stamp = float(np.mod(direction * -np.deg2rad(start_deg), 2.0 * np.pi) / (2.0 * np.pi))
    return (fraction - at_stamp) * sweep_s


def point_times_for(
    points: np.ndarray, own_times: np.ndarray | None, azimuth_sweep_s: float | None, where: str
) -> np.ndarray | None:
    """The per-point times [s] a cloud is read with: its ``own_times`` (or None), or, with
    ``azimuth_sweep_s`` set (clouds timed by azimuth), ``azimuth_point_times`` of its
    lidar-frame ``points`` (n, 3) [m]: an ``AzimuthSweep`` carries its spin, start and stamp,
    a plain float is KITTI raw's sweep. ``InputError`` naming ``where`` (file, or bag, topic
    and time) for a cloud that has times of its own then: azimuth times are for clouds
    without them, and do not override a sensor's own."""
    if azimuth_sweep_s is None:
        return own_times
    if own_times is not None:
        raise InputError(
            f"{where}: has per-point times of its own; point_times=azimuth is for clouds "
            "without them"
        )
    if isinstance(azimuth_sweep_s, AzimuthSweep):
        return azimuth_point_times(
            points,
            float(azimuth_sweep_s),
            azimuth_sweep_s.direction,
            azimuth_sweep_s.start_deg,
            azimuth_sweep_s.stamp,
        )
    return azimuth_point_times(points, float(azimuth_sweep_s))


def sweep_period(stamps: np.ndarray, where: str) -> float:
    """One sweep [s]: the median positive interval of the frame ``stamps`` [s];
    ``InputError`` naming ``where`` when no two stamps differ."""
    steps = np.diff(np.asarray(stamps, dtype=float))
    steps = steps[steps > 0]
    if steps.size == 0:
        raise InputError(
            f"{where}: point_times=azimuth needs the sweep period, and fewer than two frames "
            "with increasing stamps give none"
        )
    return float(np.median(steps))
