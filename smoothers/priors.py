"""``InitialPriors``: the priors on a smoother's keyframe 0, which every motion model uses
(``smoothers.motion_model``)."""

from __future__ import annotations

from dataclasses import dataclass

from datasets.errors import InputError


@dataclass(frozen=True)
class InitialPriors:
    """Standard deviations of the priors on keyframe 0 (GTSAM tangent coordinates).

    Attributes:
        position_sigma_m: [m] per axis.
        rotation_sigma_rad: [rad] per axis (2-D: heading).
        velocity_sigma_m_s: [m/s] per axis.
        gyro_bias_sigma_rad_s: [rad/s] per axis.
        accel_bias_sigma_m_s2: [m/s^2] per axis (3-D only).
    """

    position_sigma_m: float
    rotation_sigma_rad: float
    velocity_sigma_m_s: float
    gyro_bias_sigma_rad_s: float
    accel_bias_sigma_m_s2: float

    def __post_init__(self) -> None:
        for name, value in self.__dict__.items():
            if not value > 0.0:
                raise InputError(
                    f"initial prior {name} must be positive (a zero sigma makes the system singular), got {value}"
                )
