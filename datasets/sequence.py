"""``Sequence``: one recording (simulated or real) as a time-ordered measurement stream."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np

from datasets.detection_probability import DetectionProbability
from datasets.measurements import Measurement, Sensor
from datasets.odometry_noise import OdometryNoiseModel
from datasets.sighting_correlation import SightingCorrelation
from datasets.state import GroundTruth, LandmarkMap

if TYPE_CHECKING:  # the lidar front end's modules load only where a front end runs
    from datasets.lidar.frontend_report import FrontEndReport


@dataclass(frozen=True)
class NoiseSpec:
    """Sensor noise as the source states it; None where the source does not say.

    IMU densities are continuous-time (GTSAM's convention, and the papers' sigma_g, sigma_a,
    sigma_bg, sigma_ba): a sample at rate f has white-noise std ``density * sqrt(f)``.

    Attributes:
        gyro_noise_density: [rad/s/sqrt(Hz)].
        accel_noise_density: [m/s^2/sqrt(Hz)].
        gyro_bias_walk: gyro bias random walk [rad/s^2/sqrt(Hz)].
        accel_bias_walk: accelerometer bias random walk [m/s^3/sqrt(Hz)].
        gyro_bias_sigma_rad_s: std of the initial gyro bias (prior around zero).
        accel_bias_sigma_m_s2: std of the initial accelerometer bias (prior around zero).
        landmark_sigma_m: nominal landmark position noise std (scans carry their own).
        gps_sigma_m: GPS position noise std.
        odometry: the planar odometry noise model the odometry covariances were built from
            (``datasets.odometry_noise``; it also gives the lateral variance that a velocity
            sample's (v, omega) covariance cannot carry), or None.
        landmark_field_of_view_deg: horizontal field of view of the landmark sensor,
            centred on the body x axis [deg] (a landmark outside it cannot be seen).
        landmark_range_m: the landmark sensor's maximum range [m].
        sighting_correlation: how the errors of consecutive sightings of one landmark are
            correlated in time (``datasets.sighting_correlation``; every estimator's
            association policy inflates their noise by it), or None: independent.
        landmark_detection: how often the landmark sensor sights a landmark inside its view,
            by range (``datasets.detection_probability``; ``ekf-slam-mht`` scores missed
            detections with it), or None: not stated.
        rate_hz: nominal sample rate of each sensor.
    """

    gyro_noise_density: float | None = None
    accel_noise_density: float | None = None
    gyro_bias_walk: float | None = None
    accel_bias_walk: float | None = None
    gyro_bias_sigma_rad_s: float | None = None
    accel_bias_sigma_m_s2: float | None = None
    landmark_sigma_m: float | None = None
    gps_sigma_m: float | None = None
    odometry: OdometryNoiseModel | None = None
    landmark_field_of_view_deg: float | None = None
    landmark_range_m: float | None = None
    sighting_correlation: SightingCorrelation | None = None
    landmark_detection: DetectionProbability | None = None
    rate_hz: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class InitialState:
    """What the source tells estimators about the start (the frame-defining prior).

    Attributes:
        t: time [s].
        position: world position [m], shape (d,).
        rotation: 3-D quaternion (w, x, y, z) shape (4,); 2-D heading [rad] shape ().
        velocity: world-frame velocity [m/s], shape (d,), or None when unknown.
        position_sigma_m, rotation_sigma_rad, velocity_sigma_m_s: how well each is known.
    """

    t: float
    position: np.ndarray
    rotation: np.ndarray
    velocity: np.ndarray | None = None
    position_sigma_m: float = 1e-3
    rotation_sigma_rad: float = 1e-3
    velocity_sigma_m_s: float = 0.1


@dataclass(frozen=True)
class Sequence:
    """A measurement stream with whatever truth its source knows.

    Attributes:
        name: dataset name as the user typed it (``sim:aghili-rover``).
        dimension: 2 or 3.
        sensors: the kinds of measurement ``measurements()`` yields.
        stream: zero-argument callable returning a fresh time-ordered iterator (so that a
            sequence can be read more than once).
        ground_truth: truth, or None.
        noise: the stated sensor noise.
        initial_state: the start, or None when the source says nothing.
        known_landmarks: surveyed landmark positions the source offers as known (world
            frame, true ids), ordered by preference for use as anchors: an estimator
            configured with N anchors takes the first N (the simulator orders them so that
            any first three are non-collinear). None when the source has none.
        metadata: source, seed, options (JSON-serialisable).
        front_end: what a lidar front end made of the recording
            (``datasets.lidar.frontend_report.FrontEndReport``: its own pose trajectory,
            the covariance of each increment it fed the estimators, counters), filled by
            the front end during a pass and complete after one; None for sources without a
            front end. Metrics compare estimates with it; the runner hands estimators a view
            of the sequence without it (its poses are not truth, and an estimator must not
            lean on them).
    """

    name: str
    dimension: int
    sensors: frozenset[Sensor]
    stream: Callable[[], Iterator[Measurement]]
    ground_truth: GroundTruth | None = None
    noise: NoiseSpec = field(default_factory=NoiseSpec)
    initial_state: InitialState | None = None
    known_landmarks: LandmarkMap | None = None
    metadata: dict[str, Any] = field(default_factory=dict)
    front_end: FrontEndReport | None = None

    def measurements(self) -> Iterator[Measurement]:
        """A fresh time-ordered iterator over every sensor's measurements."""
        return self.stream()
