"""What every named scenario shares: the common options (length, noise scale, landmark
scans), the seeded generators, the drawn and stated noise factors, the stated ``NoiseSpec``,
the metadata and the size of the landmark scan stream for ``check_size``.

Seeds: the sensor noise comes from ``seed`` through independent generators per purpose
(``seeded_generators``), so changing one sensor's option does not change another sensor's
noise.

Noise scale: ``noise_scale`` multiplies every drawn noise std (inertial white noise, bias
walks, initial biases, landmark noise). The stated noise (``NoiseSpec``, scan
covariances) is scaled alike, except at ``noise_scale=0``: the data are then noise-free
but the stated noise stays nominal, so estimators keep invertible covariances (NEES is
meaningless there).
"""

from __future__ import annotations

import numpy as np
from pydantic import BaseModel, ConfigDict, Field

from datasets.sequence import NoiseSpec
from datasets.simulation.assembly import SCAN_BYTES, SIGHTING_BYTES, SizedStream
from datasets.simulation.imu import InertialNoise


class CommonOptions(BaseModel):
    model_config = ConfigDict(extra="forbid")

    duration_s: float | None = Field(
        None, gt=0, description="length of the sequence [s]; default: the scenario's own"
    )
    noise_scale: float = Field(
        1.0, ge=0, description="multiplies every noise std (0: noise-free data)"
    )
    ids: bool = Field(True, description="scans carry the true landmark ids (false: ids withheld)")
    landmark_rate_hz: float = Field(10.0, gt=0, le=1000, description="landmark scan rate [Hz]")
    range_m: float = Field(20.0, gt=0, description="maximum landmark range [m]")
    fov_deg: float = Field(
        360.0, gt=0, le=360, description="horizontal field of view centred on body x [deg]"
    )


def noise_factors(noise_scale: float) -> tuple[float, float]:
    """(scale of drawn noise, scale of stated noise): stated stays nominal at 0."""
    return noise_scale, (noise_scale if noise_scale > 0 else 1.0)


def seeded_generators(seed: int) -> dict[str, np.random.Generator]:
    """Independent generators per purpose, all from ``seed``."""
    # spawn keys are indices: adding a name at the end leaves the others' streams unchanged
    names = ("inertial", "landmarks", "spare", "initial", "motion", "drift", "odometry")
    children = np.random.SeedSequence(seed).spawn(len(names))
    return {name: np.random.default_rng(child) for name, child in zip(names, children)}


def scenario_metadata(
    scenario: str, seed: int, options: BaseModel, **extra: object
) -> dict[str, object]:
    return {
        "source": "simulator",
        "scenario": scenario,
        "seed": seed,
        "options": options.model_dump(mode="json"),
        **extra,
    }


def duration_text(options: CommonOptions, duration_s: float, default: str) -> str:
    """How the sequence's length was chosen, for ``check_size``'s message: the option as
    given, or the scenario's default and what it follows from."""
    if options.duration_s is not None:
        return f"duration_s={options.duration_s:g}"
    return f"duration_s (default {duration_s:.6g} s: {default})"


def scan_stream(options: CommonOptions, landmarks: int, count_option: str) -> SizedStream:
    """The landmark scans as ``check_size`` counts them: every landmark in every scan (the
    most the field of view can let through)."""
    return SizedStream(
        f"landmark_rate_hz={options.landmark_rate_hz:g} and {count_option}",
        options.landmark_rate_hz,
        SCAN_BYTES + landmarks * SIGHTING_BYTES,
    )


def noise_spec(
    noise: InertialNoise,
    landmark_sigma_m: float,
    rates: dict[str, float],
    planar: bool,
    options: CommonOptions,
) -> NoiseSpec:
    return NoiseSpec(
        landmark_field_of_view_deg=options.fov_deg,
        landmark_range_m=options.range_m,
        gyro_noise_density=noise.gyro_noise_density,
        accel_noise_density=None if planar else noise.accel_noise_density,
        gyro_bias_walk=noise.gyro_bias_walk,
        accel_bias_walk=None if planar else noise.accel_bias_walk,
        gyro_bias_sigma_rad_s=noise.gyro_bias_sigma_rad_s,
        accel_bias_sigma_m_s2=None if planar else noise.accel_bias_sigma_m_s2,
        landmark_sigma_m=landmark_sigma_m,
        rate_hz=rates,
    )
