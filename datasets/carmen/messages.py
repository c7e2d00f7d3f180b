"""The CARMEN log messages the loader uses, as typed records (one line of a ``.clf`` each).

Formats (CARMEN's ``readlog.c``, ``carmen_string_to_robot_laser_message[_orig]`` and
``carmen_string_to_base_odometry_message``; every line ends ``ipc_timestamp ipc_hostname
logger_timestamp``):

- ``FLASER n r_1 .. r_n x y theta odom_x odom_y odom_theta`` (front laser) and ``RLASER``
  (rear laser, same fields). The line does not say its beam angles; CARMEN guesses them from
  ``n`` (``carmen_laser_guess_angle_increment``): 1 deg for 180 or 181 beams, 0.5 deg for
  360 or 361, 0.25 deg for 400 or 401, else ``pi / (n - 1)``; the first beam at -90 deg
  (robot frame, x forward, counter-clockwise), the rear laser's turned by 180 deg. Maximum
  range 80 m (``config.maximum_range``): CARMEN's SICK driver reports "no return" as its
  largest reading (81.83 and 81.91 m in the shared logs), which is never a wall.
- ``ROBOTLASER1 laser_type start_angle fov angular_resolution max_range accuracy
  remission_mode n r_1 .. r_n m e_1 .. e_m laser_x laser_y laser_theta robot_x robot_y
  robot_theta tv rv forward_safety side_safety turn_axis``: the beam geometry stated; the
  laser's mounting is the laser pose in the frame of the robot pose.
- ``ODOM x y theta tv rv accel``: the wheel odometry pose [m, m, rad], translational [m/s]
  and rotational [rad/s] velocity, acceleration.
- ``PARAM name value``: a robot parameter (``robot_frontlaser_offset`` [m], along the robot's
  x axis, and the like).

``x y theta`` of a laser line is the pose the logging software of the day assigned to the
laser (on some logs corrected by a scan matcher): kept for reference only, never used as
truth.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

LASER_KINDS = ("FLASER", "RLASER", "ROBOTLASER1")
"""Laser messages read (``ROBOTLASER1`` is the front laser of the newer format)."""

FRONT_LASERS = ("FLASER", "ROBOTLASER1")
"""Laser messages of the front laser."""

NO_RETURN_RANGE_M = 80.0
"""CARMEN's stated SICK maximum range [m]: a reading at or beyond it is no return."""


def guessed_angle_step_rad(beams: int) -> float:
    """CARMEN's ``carmen_laser_guess_angle_increment``: the beam spacing [rad] of an old
    ``FLASER``/``RLASER`` line with ``beams`` readings, which does not state it."""
    if beams in (180, 181):
        return float(np.pi / 180.0)
    if beams in (360, 361):
        return float(np.pi / 360.0)
    if beams in (400, 401):
        return float(np.pi / 720.0)
    return float(np.pi / max(beams - 1, 1))


@dataclass(frozen=True)
class LaserMessage:
    """One laser scan line.

    Attributes:
        kind: ``FLASER``, ``RLASER`` or ``ROBOTLASER1``.
        line: its 1-based line number in the log.
        stamp: its ``ipc_timestamp`` as written (text: a repair may re-read it).
        ranges: (n,) [m], beam ``i`` at ``start_angle_rad + i * angle_step_rad``.
        start_angle_rad, angle_step_rad: beam geometry in the laser frame [rad].
        max_range_m: readings at or beyond it are no return [m].
        odometry: (3,) the odometry pose (x [m], y [m], theta [rad]) the log gives the scan.
        logged_pose: (3,) the laser pose the log gives (not truth: module docstring).
        mounting: (3,) laser pose in the robot frame (x [m], y [m], theta [rad]) where the line
            states it (``ROBOTLASER1``), else None (``PARAM`` lines give it).
    """

    kind: str
    line: int
    stamp: str
    ranges: np.ndarray
    start_angle_rad: float
    angle_step_rad: float
    max_range_m: float
    odometry: np.ndarray
    logged_pose: np.ndarray
    mounting: np.ndarray | None = None

    @property
    def t(self) -> float:
        """``ipc_timestamp`` [s] as written."""
        return float(self.stamp)

    @property
    def front(self) -> bool:
        """Whether this is a front-laser scan."""
        return self.kind in FRONT_LASERS

    def angles(self) -> np.ndarray:
        """Beam angles in the laser frame, (n,) [rad]."""
        return self.start_angle_rad + self.angle_step_rad * np.arange(len(self.ranges))


@dataclass(frozen=True)
class OdometryMessage:
    """One ``ODOM`` line.

    Attributes:
        line: 1-based line number.
        stamp: ``ipc_timestamp`` as written.
        pose: (3,) x [m], y [m], theta [rad] in the odometry frame.
        velocity: (2,) tv [m/s], rv [rad/s].
    """

    line: int
    stamp: str
    pose: np.ndarray
    velocity: np.ndarray

    @property
    def t(self) -> float:
        """``ipc_timestamp`` [s] as written."""
        return float(self.stamp)


@dataclass(frozen=True)
class Parameter:
    """One ``PARAM`` line: name, value (text), 1-based line number."""

    name: str
    value: str
    line: int
