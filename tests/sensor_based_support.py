"""Synthetic planar sequences for the sensor-based filter tests (exact, noise-free or seeded)."""

from __future__ import annotations

import numpy as np

from datasets.measurements import GyroSample, LandmarkScan, Sensor
from datasets.rotations import rot2
from datasets.sequence import InitialState, NoiseSpec, Sequence


def integrated_rotation(yaw_rate: float, t: np.ndarray) -> np.ndarray:
    """``int_0^t R(yaw_rate s) ds``, shape (N, 2, 2) (closed form)."""
    if abs(yaw_rate) < 1e-12:
        return t[:, None, None] * np.eye(2)[None]
    a = yaw_rate * t
    s, c = np.sin(a), np.cos(a)
    return (
        np.stack([np.stack([s, c - 1.0], axis=-1), np.stack([1.0 - c, s], axis=-1)], axis=-2)
        / yaw_rate
    )


def body_frame_landmarks(
    landmarks: np.ndarray, body_velocity: tuple[float, float], yaw_rate: float, t: float
) -> np.ndarray:
    """The world ``landmarks`` (L, 2) in the body frame at ``t`` of ``planar_sequence``'s
    vehicle (constant body velocity and yaw rate from the origin), (L, 2)."""
    position = integrated_rotation(yaw_rate, np.array([t]))[0] @ np.asarray(body_velocity)
    return (landmarks - position) @ rot2(yaw_rate * t)


def planar_sequence(
    duration_s: float,
    body_velocity: tuple[float, float],
    yaw_rate: float,
    landmarks: np.ndarray,
    rate_hz: float = 10.0,
    point_sigma_m: float = 0.05,
    directions: np.ndarray | None = None,
    seed: int | None = None,
    gyro_bias: float = 0.0,
    gyro_noise_density: float = 1e-3,
    blank: tuple[float, float] | None = None,
) -> Sequence:
    """Constant body velocity and yaw rate (a circle or a line), landmarks always visible.

    Args:
        landmarks: world positions (L, 2). directions: optional world unit directions (L, 2).
        seed: None for noise-free measurements (stated covariances stay nominal).
        blank: (t0, t1): scans in this window are empty (no landmark visible).
    """
    t = np.round(np.arange(0.0, duration_s + 1e-9, 1.0 / rate_hz), 9)
    heading = yaw_rate * t
    v = np.asarray(body_velocity, dtype=float)
    positions = integrated_rotation(yaw_rate, t) @ v
    rng = np.random.default_rng(seed) if seed is not None else None
    sample_sigma = gyro_noise_density * np.sqrt(rate_hz)
    measurements = []
    for k, time in enumerate(t):
        rate = yaw_rate + gyro_bias + (rng.normal() * sample_sigma if rng is not None else 0.0)
        measurements.append(GyroSample(t=float(time), rate=np.array([rate])))
        rotation = rot2(float(heading[k]))
        body = (landmarks - positions[k]) @ rotation
        if rng is not None:
            body = body + point_sigma_m * rng.normal(size=body.shape)
        body_directions = None
        if directions is not None:
            body_directions = (directions @ rotation)[:, None, :]
        if blank is not None and blank[0] <= time < blank[1]:
            body = np.zeros((0, 2))
            body_directions = None if directions is None else np.zeros((0, 1, 2))
        covs = np.repeat((point_sigma_m**2 * np.eye(2))[None], len(body), axis=0)
        measurements.append(
            LandmarkScan(
                t=float(time),
                points=body,
                covariances=covs,
                ids=np.arange(len(body)),
                directions=body_directions,
            )
        )
    world_velocity = rot2(0.0) @ v
    return Sequence(
        name="synthetic",
        dimension=2,
        sensors=frozenset({Sensor.GYRO, Sensor.LANDMARKS}),
        stream=lambda: iter(measurements),
        noise=NoiseSpec(gyro_noise_density=gyro_noise_density, gyro_bias_sigma_rad_s=0.01),
        initial_state=InitialState(
            t=0.0,
            position=np.zeros(2),
            rotation=np.array(0.0),
            velocity=world_velocity,
            velocity_sigma_m_s=0.5,
        ),
    )


def run(estimator_class, config, sequence, measurements=None):
    """Feed ``sequence`` (or an explicit measurement list) and return (estimator, estimate)."""
    estimator = estimator_class(config, sequence)
    for measurement in measurements if measurements is not None else sequence.measurements():
        estimator.process(measurement)
    return estimator, estimator.estimate()
