"""Estimator option names that issue 39 replaced (one name per idea, its unit in the name):
an old name in ``--set``, ``--config``, a suite file or an old run folder's ``config.yaml``
still works, mapped to the new one, and says so in one warning line.

An old name maps to its new one only for an estimator whose config has the new name; for
any other it stays as it is, and the config rejects it as it rejects a misspelt key.
"""

from __future__ import annotations

from collections.abc import Callable, Collection, Mapping
from dataclasses import dataclass
from typing import Any

from datasets.errors import InputError


def _interpolation(value: Any) -> Any:
    """``imu_interpolation: true|false`` -> ``interval_rate: average|hold``."""
    return {True: "average", False: "hold"}.get(value, value) if isinstance(value, bool) else value


def _motion_input(value: Any) -> Any:
    """``motion_input: auto|odometry|gyro`` -> ``use_odometry: true|true|false``."""
    return {"auto": True, "odometry": True, "gyro": False}.get(value, value)


@dataclass(frozen=True)
class Renamed:
    """An option that now has another name (and, for two, another value vocabulary)."""

    old: str
    new: str
    convert: Callable[[Any], Any] | None = None


RENAMED: tuple[Renamed, ...] = (
    # the body-velocity random walk (white acceleration density) of the gyro-driven models
    Renamed("gyro_velocity_sigma_m_s2", "velocity_walk_m_s_sqrt_s"),  # dead-reckoning
    Renamed("sigma_velocity_m_s", "velocity_walk_m_s_sqrt_s"),  # sensor-based
    Renamed("acceleration_density", "velocity_walk_m_s_sqrt_s"),  # ekf-slam
    Renamed("planar_velocity_walk_m_s2", "velocity_walk_m_s_sqrt_s"),  # smoothers
    # the gyro's noise
    Renamed("gyro_noise_density", "gyro_noise_density_rad_s_sqrt_hz"),  # sensor-based, ekf-slam
    Renamed("planar_gyro_density", "gyro_noise_density_rad_s_sqrt_hz"),  # smoothers
    Renamed("gyro_bias_walk", "gyro_bias_walk_rad_s_sqrt_s"),  # ekf-slam
    Renamed("sigma_gyro_bias_rad_s", "gyro_bias_walk_rad_s_sqrt_s"),  # sensor-based
    # the rate over a gyro / IMU interval
    Renamed("rate_interpolation", "interval_rate"),  # sensor-based
    Renamed("gyro_interval_rate", "interval_rate"),  # ekf-slam
    Renamed("imu_interpolation", "interval_rate", _interpolation),  # smoothers
    # motion input
    Renamed("motion_input", "use_odometry", _motion_input),  # ekf-slam
    Renamed("max_imu_gap_s", "max_gap_s"),  # smoothers
    # initial priors
    Renamed("position_sigma_m", "initial_position_sigma_m"),  # smoothers
    Renamed("rotation_sigma_rad", "initial_rotation_sigma_rad"),  # smoothers
    Renamed("velocity_sigma_m_s", "initial_velocity_sigma_m_s"),  # smoothers
    Renamed("gyro_bias_sigma_rad_s", "initial_gyro_bias_sigma_rad_s"),  # ekf-slam, smoothers
    Renamed("accel_bias_sigma_m_s2", "initial_accel_bias_sigma_m_s2"),  # smoothers
    # landmark noise: a measurement noise (aghili) and a process noise (sensor-based)
    Renamed("landmark_sigma_m", "landmark_measurement_sigma_m"),  # aghili
    Renamed("sigma_landmark_m", "landmark_walk_m_sqrt_s"),  # sensor-based
    Renamed("sigma_direction", "direction_walk_per_sqrt_s"),  # sensor-based
    Renamed("field_of_view_deg", "landmark_field_of_view_deg"),  # sensor-based
    Renamed("prune_single_sightings_after_s", "probation_s"),  # ekf-slam (min_observations 2)
)
BY_OLD_NAME: dict[str, Renamed] = {entry.old: entry for entry in RENAMED}


def renamed_options(
    values: Mapping[str, Any], fields: Collection[str], estimator: str
) -> tuple[dict[str, Any], list[str]]:
    """``values`` with every old name that ``fields`` (the estimator's config fields) has a
    new name for replaced by it (its value converted where the vocabulary changed), and one
    warning line (without the ``warning:`` prefix) per old name. ``InputError`` when an old
    name and its new one are both given with different values."""
    renamed: dict[str, Any] = {}
    given_as: dict[str, str] = {}  # new name -> the key that gave it
    warnings: list[str] = []
    for key, value in values.items():
        entry = BY_OLD_NAME.get(key)
        if entry is None or entry.new not in fields or key in fields:
            name, new_value = key, value
        else:
            name = entry.new
            new_value = entry.convert(value) if entry.convert else value
            shown = f" ({key}={_text(value)}: {name}={_text(new_value)})" if entry.convert else ""
            warnings.append(f"{estimator} option '{key}' is now '{name}'{shown}")
        if name in renamed and renamed[name] != new_value:
            raise InputError(
                f"{estimator} options: '{given_as[name]}' and '{key}' both set '{name}', to "
                f"{_text(renamed[name])} and {_text(new_value)}: give '{name}' only"
            )
        renamed[name] = new_value
        given_as.setdefault(name, key)
    return renamed, warnings


def _text(value: Any) -> str:
    if isinstance(value, bool):
        return str(value).lower()
    return "null" if value is None else str(value)
