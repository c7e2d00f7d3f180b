"""``Sequence``: one recording (simulated or real) as a time-ordered measurement stream."""

from __future__ import annotations

from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from datasets.detection_probability import DetectionProbability
from datasets.measurements import Measurement, Sensor
from datasets.odometry_noise import OdometryNoiseModel
from datasets.sighting_correlation import SightingCorrelation
from datasets.state import GroundTruth, LandmarkMap

if TYPE_CHECKING:  # the lidar front end's and the bags' modules load only where they run
    from datasets.bags.topics import SensorTopics
    from datasets.lidar.frontend_report import FrontEndReport
    from datasets.pass_report import PassReport


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
        metadata: the free description of the source (source, scenario, seed, options,
            sizes, ...; JSON-serialisable), written with the run (``description``) and read
            by no other layer: what another layer reads is a typed field below.
        front_end: what a lidar front end made of the recording
            (``datasets.lidar.frontend_report.FrontEndReport``: its own pose trajectory,
            the covariance of each increment it fed the estimators, counters), filled by
            the front end during a pass and complete after one; None for sources without a
            front end. Metrics compare estimates with it; the runner hands estimators a view
            of the sequence without it (its poses are not truth, and an estimator must not
            lean on them).
        reference_source: what the ground truth is (``Vicon``, ``simulated truth``, ``topic
            /ground_truth``, ``held-out GPS fixes``), for figures and ``metrics.json``; None
            without a reference.
        warnings: what the loader dropped, repaired or doubted at load, one line each
            (printed prefixed with the sequence's name, in ``metrics.json``); None for a
            source that keeps no such list (a simulator). What a pass adds is in
            ``pass_report``; ``all_warnings`` gives both.
        counts: rows the loader dropped or repaired, by name (``stale_repeats``,
            ``scan_lines_dropped_duplicate``, ...; zeros included), each non-zero one a
            warning of every run; None for a source that counts none.
        decisions: what the loader decided from the data and why, one line each (sweep
            timing, which pose topic is the wheel odometry, where the start is), printed as
            notes and in ``metrics.json``; None for a source that decides nothing.
        excluded_truth_s: total time [s] of the truth's untrusted intervals (the merged
            ``GroundTruth.excluded``), as the loader states it (UTIAS; ``metrics.json``);
            None where the loader states none.
        calibration: what the loader fitted its noise and odometry models on, one line
            (UTIAS: the other robots' Vicon, the scored robot's own, or none); None for a
            source that fits nothing.
        gravity_m_s2: the gravity magnitude the source's IMU data assume [m/s^2] (KITTI:
            gtsam's example value); None: not stated (estimators take 9.81).
        landmark_ids: the landmark scans carry the landmarks' true ids (the ``ids`` option
            of the simulator, UTIAS, Victoria Park): every sighting counts as a known-id
            one in the association warnings.
        topics: a bag's topic in each role (``datasets.bags.topics.SensorTopics``); None
            for other sources.
        corner_sidecar: the true-corner file (``NAME.corners.json``, written by ``workbench
            simulate lidar-corridor``) read beside a lidar bag, the truth of its corners;
            None without one.
        pass_report: what a pass over the stream found (``datasets.pass_report
            .PassReport``: the pass's warnings and figures), filled at the end of each
            complete pass and complete after one; None for a source whose stream adds
            nothing to what was known at load.
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
    reference_source: str | None = None
    warnings: tuple[str, ...] | None = None
    counts: Mapping[str, int] | None = None
    decisions: tuple[str, ...] | None = None
    excluded_truth_s: float | None = None
    calibration: str | None = None
    gravity_m_s2: float | None = None
    landmark_ids: bool = False
    topics: SensorTopics | None = None
    corner_sidecar: Path | None = None
    pass_report: PassReport | None = None

    def measurements(self) -> Iterator[Measurement]:
        """A fresh time-ordered iterator over every sensor's measurements."""
        return self.stream()

    def all_warnings(self) -> list[str]:
        """The loader's warnings, then those of the passes so far that it does not state."""
        stated = list(self.warnings or ())
        found = self.pass_report.warnings if self.pass_report is not None else []
        return stated + [line for line in found if line not in stated]

    def description(self) -> dict[str, Any]:
        """The source as a run records it (``config.yaml``'s ``dataset_metadata``, a
        simulated folder's ``sequence.json``; JSON-ready): ``metadata``, each typed field
        the source states under its own name, and the passes' figures.

        Stated: ``reference_source`` always (None: no reference); ``corner_sidecar`` (a
        path, or None) with a bag's lidar topic, the one source that looks for it;
        ``warnings`` (with the passes', ``all_warnings``), ``counts``, ``decisions``,
        ``excluded_truth_s``, ``calibration``, ``gravity_m_s2`` and ``topics`` where they are
        not None. ``landmark_ids`` is the ``ids`` option, already in ``metadata``.
        ``split_description`` reads it back.
        """
        described = dict(self.metadata)
        described["reference_source"] = self.reference_source
        if self.topics is not None and self.topics.lidar is not None:
            described["corner_sidecar"] = (
                None if self.corner_sidecar is None else str(self.corner_sidecar)
            )
        typed = {
            "warnings": None if self.warnings is None else self.all_warnings(),
            "counts": None if self.counts is None else dict(self.counts),
            "decisions": None if self.decisions is None else list(self.decisions),
            "excluded_truth_s": self.excluded_truth_s,
            "calibration": self.calibration,
            "gravity_m_s2": self.gravity_m_s2,
            "topics": None if self.topics is None else self.topics.as_dict(),
        }
        described.update({key: value for key, value in typed.items() if value is not None})
        if self.pass_report is not None:
            described.update(
                {key: dict(values) for key, values in self.pass_report.figures.items()}
            )
        return described


_DESCRIBED_FIELDS = {
    "reference_source": str,
    "warnings": tuple,
    "counts": dict,
    "decisions": tuple,
    "excluded_truth_s": float,
    "calibration": str,
    "gravity_m_s2": float,
}
"""The typed fields ``split_description`` reads back, with their types."""


def split_description(described: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """A written ``Sequence.description`` -> (``metadata``, the typed fields' keyword
    arguments). A bag's topics, corner sidecar and pass figures stay in ``metadata`` (only
    simulated sequences are written to folders: they have none)."""
    metadata = dict(described)
    typed = {
        name: convert(metadata.pop(name))
        for name, convert in _DESCRIBED_FIELDS.items()
        if metadata.get(name) is not None
    }
    metadata.pop("reference_source", None)
    return metadata, typed
