"""The 2-D laser sequence of a bag without a lidar (``planar_sequence``; made where
``datasets.bags.sensor_source`` finds a ``LaserScan`` topic and wheel odometry): a planar
sequence with the CARMEN loader's shape (``datasets.carmen``): at every scan after the first
an ``Odometry(frame=True)`` increment, the wheel odometry interpolated to the scans' stamps,
then the scan's corners from the 2-D laser front end (``datasets.laser2d``) as a
``LandmarkScan`` without ids. The start and the truth are the 3-D ones in the plane
(x, y, yaw).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from datasets.bags.read_report import ReadReport, ReadSettings
from datasets.bags.reader import read_stream
from datasets.bags.sequence_sources import SensorSource
from datasets.bags.wheel_odometry import PoseSample, pose_at
from datasets.errors import InputError
from datasets.laser2d.frontend import Laser2dFrontEnd
from datasets.laser2d.scan import PlanarScan
from datasets.measurements import Measurement, Odometry, Sensor
from datasets.pass_report import PassReport
from datasets.rotations import matrix_from_quat_wxyz, wrap_angle, yaw_from_quat_wxyz
from datasets.sequence import InitialState, NoiseSpec, Sequence
from datasets.state import GroundTruth, StateHistory
from datasets.trajectory import Trajectory


def _planar_truth(ground_truth: GroundTruth | None) -> GroundTruth | None:
    """The 3-D truth as planar poses (x, y, yaw)."""
    if ground_truth is None or ground_truth.pose is None:
        return None
    pose = ground_truth.pose
    yaws = np.array([yaw_from_quat_wxyz(q) for q in pose.rotations])
    planar = Trajectory(pose.t.copy(), pose.positions[:, :2].copy(), yaws)
    return GroundTruth(history=StateHistory(pose=planar), excluded=ground_truth.excluded)


def _planar_pose(samples: list[PoseSample], t: float) -> np.ndarray:
    position, quaternion = pose_at(samples, t)
    return np.array([position[0], position[1], yaw_from_quat_wxyz(quaternion)])


def planar_sequence(
    name, path, settings, read_settings, laser_topic, role, noise_model, time_base,
    ground_truth, initial, rates, metadata, described, decisions, warnings, reader,
) -> tuple[Sequence, SensorSource]:  # fmt: skip
    """The 2-D laser sequence (module docstring); ``described``: the typed fields of the
    sequence (reference source, topics) besides its warnings and decisions; ``reader``: the
    bag, open, for the wheel odometry read whole at load."""
    odometry_report = ReadReport()
    samples: list[PoseSample] = [
        m
        for _, m in read_stream(
            path,
            [role.topic],
            ReadSettings(**{**read_settings.__dict__, "time_base": None}),
            odometry_report,
            reader,
        )
        if isinstance(m, PoseSample)
    ]
    if len(samples) < 2:
        raise InputError(f"{path}: odometry topic {role.topic} has {len(samples)} usable poses")
    warnings.extend(odometry_report.lines())
    stamps = np.array([sample.t for sample in samples])
    front_end = Laser2dFrontEnd(settings.laser)
    source = SensorSource(front_end)
    corner = settings.laser.corner
    # filled once the stream has run: the front end's corner figures, the pass's warnings
    pass_report = PassReport.expecting("laser_corners")

    def stream() -> Iterator[Measurement]:
        report = ReadReport()
        source.report = report
        previous: tuple[float, np.ndarray] | None = None
        index = 0
        for _, scan in read_stream(path, [laser_topic], read_settings, report):
            if not isinstance(scan, PlanarScan):
                continue
            if settings.max_frames is not None and index >= settings.max_frames:
                break
            used = PlanarScan(
                t=scan.t,
                ranges=scan.ranges,
                angles=scan.angles,
                min_range_m=max(scan.min_range_m, corner.min_range_m),
                max_range_m=min(scan.max_range_m, corner.max_range_m),
                mounting=scan.mounting,
                beam_times=scan.beam_times,
            )
            pose = _planar_pose(samples, scan.t)
            if previous is None:
                result = front_end.frame(0, used)
            else:
                t0, pose0 = previous
                c, s = np.cos(pose0[2]), np.sin(pose0[2])
                dx, dy = pose[:2] - pose0[:2]
                increment = np.array(
                    [c * dx + s * dy, -s * dx + c * dy, float(wrap_angle(pose[2] - pose0[2]))]
                )
                full = np.array([0.0, 0.0, increment[2], increment[0], increment[1], 0.0])
                # the twist covariance of the odometry message at the scan (where meaningful)
                latest = samples[min(int(np.searchsorted(stamps, scan.t)), len(samples) - 1)]
                covariance6 = noise_model.covariance(full, scan.t - t0, latest.twist_covariance)
                covariance = covariance6[np.ix_([3, 4, 2], [3, 4, 2])]
                result = front_end.frame(index, used, increment, covariance)
                yield Odometry(
                    t=scan.t,
                    covariance=covariance,
                    relative_pose=increment,
                    dt=scan.t - t0,
                    frame=True,
                )
            previous = (scan.t, pose)
            index += 1
            landmarks = result.landmark_scan(settings.laser.confirm_corners)
            if landmarks is not None:
                yield landmarks
        pass_report.record(source.pass_warnings(), laser_corners=front_end.summary())

    metadata["odometry_noise"] = noise_model.model.as_dict()
    rotation = matrix_from_quat_wxyz(initial.rotation)
    planar_initial = InitialState(
        t=initial.t,
        position=initial.position[:2].copy(),
        rotation=np.array(float(np.arctan2(rotation[1, 0], rotation[0, 0]))),
        velocity=None if initial.velocity is None else initial.velocity[:2].copy(),
        position_sigma_m=initial.position_sigma_m,
        rotation_sigma_rad=initial.rotation_sigma_rad,
    )
    noise = NoiseSpec(
        odometry=noise_model.model,
        landmark_sigma_m=float(
            np.sqrt(settings.laser.corner.covariance_scale)
            * np.hypot(settings.laser.corner.model_sigma_m, settings.laser.corner.range_sigma_m)
        ),
        landmark_range_m=settings.laser.corner.max_range_m,
        rate_hz=rates,
    )
    sequence = Sequence(
        name=name,
        dimension=2,
        sensors=frozenset({Sensor.ODOMETRY, Sensor.LANDMARKS}),
        stream=stream,
        ground_truth=_planar_truth(ground_truth),
        noise=noise,
        initial_state=planar_initial,
        metadata=metadata,
        warnings=tuple(warnings),
        decisions=tuple(decisions),
        pass_report=pass_report,
        **described,
    )
    return sequence, source
