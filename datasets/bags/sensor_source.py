"""``bag:PATH`` without a lidar: IMU, wheel odometry, GPS and 2-D laser in any combination.

``datasets.bags.source.bag_sequence`` hands a bag without a PointCloud2 topic here. What the
sequence holds is decided from the bag and printed (``metadata["decisions"]``, shown by
``workbench run`` as ``note:`` and by ``workbench bag`` as ``front end:``):

- **3-D** (the default): ``ImuSample`` from the Imu topic, ``GpsFix`` from the NavSatFix
  topic (local ENU about the first fix, ``datasets.bags.gps``) and ``Odometry`` increments
  from the wheel odometry (``datasets.bags.topic_roles`` decides which pose topic that is;
  ``datasets.bags.wheel_odometry`` makes the increments and their covariance). Sensors:
  IMU, GPS, ODOMETRY, whichever the bag has.
- **2-D laser** (a ``LaserScan`` topic and wheel odometry): a planar sequence with the CARMEN
  loader's shape (``datasets.carmen``): at every scan after the first an
  ``Odometry(frame=True)`` increment, the wheel odometry interpolated to the scans' stamps,
  then the scan's corners from the 2-D laser front end (``datasets.laser2d``) as a
  ``LandmarkScan`` without ids. The IMU and GPS are not used (said in the decisions;
  ``--data laser_topic=none`` gives the 3-D sequence instead). A LaserScan topic without
  wheel odometry is not used: the front end needs the motion between scans.

World frame and start (``initial_state``, at the start of the common time base):
- with GPS, the world is ENU about the first fix; the start is at the origin (its sigma the
  first fix's), the orientation from the IMU's own orientation where its messages state one
  (REP-103/REP-145: ENU), else the heading from the GPS course against the wheel odometry's
  over the first ``GPS_COURSE_MIN_M`` metres, else east with a warning. A named truth topic
  is then only scored (after alignment: its frame is not assumed to be the GPS's ENU);
- without GPS, from the truth topic when named (as for lidar bags), else the first body
  frame (the IMU's orientation where it states one) at the origin;
- the velocity from the truth, else from the wheel odometry's twist, else zero.

Time base: the common interval of the IMU, the wheel odometry, the 2-D laser and the named
truth (``datasets.bags.time_base.common_time_base``); GPS fixes outside it are dropped and
counted, as for lidar bags.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np

from datasets.bags.bag_file import iter_messages, open_bag
from datasets.bags.convert import first_gps_origin
from datasets.bags.first_messages import imu_rate_and_noise
from datasets.bags.ground_truth import (
    ground_truth_from_topic,
    initial_state_from_truth,
    read_ground_truth,
)
from datasets.bags.read_report import ReadReport, ReadSettings, check_skips
from datasets.bags.reader import read_stream
from datasets.bags.spans import topic_spans
from datasets.bags.time_base import TimeBase, common_time_base
from datasets.bags.topic_roles import OdometryRole, choose_odometry
from datasets.bags.topics import BagTopics, topic_types
from datasets.bags.wheel_odometry import (
    PoseSample,
    WheelIncrements,
    WheelNoise,
    pose_at,
)
from datasets.errors import InputError
from datasets.laser2d.frontend import Laser2dFrontEnd
from datasets.laser2d.scan import PlanarScan
from datasets.measurements import Measurement, Odometry, Sensor
from datasets.rotations import matrix_from_quat_wxyz, wrap_angle
from datasets.sequence import InitialState, NoiseSpec, Sequence
from datasets.state import GroundTruth, StateHistory
from datasets.trajectory import Trajectory

GPS_COURSE_MIN_M = 10.0
"""How far [m] the GPS track must have moved from its first fix before its course fixes
the start's heading (at 1 m GPS noise, 0.1 rad)."""
GPS_COURSE_WINDOW_S = 120.0
"""How long [s] from the start the GPS course is looked for."""


class SensorSource:
    """What a pass over a bag without lidar skipped (``report``), and the 2-D laser front
    end when its scans are used (else None); ``front_end`` is None (no lidar front end) and
    ``lidar_messages`` None (no lidar topic), as ``LidarSource`` names them."""

    front_end = None
    lidar_messages = None

    def __init__(self, laser_front_end: Laser2dFrontEnd | None = None) -> None:
        self.laser_front_end = laser_front_end
        self.report = ReadReport()

    def record_warnings(self, warnings: list[str]) -> None:
        for line in self.report.lines():
            if line not in warnings:
                warnings.append(line)


def _yaw(quaternion: np.ndarray) -> float:
    rotation = matrix_from_quat_wxyz(quaternion / np.linalg.norm(quaternion))
    return float(np.arctan2(rotation[1, 0], rotation[0, 0]))


def _imu_orientation(reader, path: Path, topic: str, start_s: float):
    """The orientation (w, x, y, z) the Imu topic states at ``start_s`` (its first message
    at or after it), its sigma [rad] and a phrase of evidence; (None, None, why) where its
    messages state none (``orientation_covariance[0] == -1``, the ROS convention, or not a
    unit quaternion)."""
    for _, _, stamp, message in iter_messages(reader, path, [topic], report=ReadReport()):
        if stamp < start_s:
            continue
        covariance = np.asarray(message.orientation_covariance, dtype=float).reshape(3, 3)
        q = message.orientation
        quaternion = np.array([q.w, q.x, q.y, q.z], dtype=float)
        norm = float(np.linalg.norm(quaternion))
        if covariance[0, 0] == -1.0:
            return None, None, f"{topic} states no orientation (orientation_covariance[0] = -1)"
        if not (np.all(np.isfinite(quaternion)) and abs(norm - 1.0) < 0.01):
            return None, None, f"{topic}'s orientation is not a unit quaternion (norm {norm:.3g})"
        diagonal = np.diag(covariance)
        stated = bool(np.all(np.isfinite(diagonal)) and np.any(diagonal > 0))
        sigma = float(np.sqrt(np.max(diagonal))) if stated else 0.1
        rotation = matrix_from_quat_wxyz(quaternion / norm)
        roll = np.arctan2(rotation[2, 1], rotation[2, 2])
        pitch = -np.arcsin(np.clip(rotation[2, 0], -1.0, 1.0))
        text = (
            f"orientation from {topic} at t={stamp:.3f} (roll {np.rad2deg(roll):.1f}, pitch "
            f"{np.rad2deg(pitch):.1f}, yaw {np.rad2deg(_yaw(quaternion)):.1f} deg; sigma "
            + (
                f"{sigma:.3g} rad from its covariance)"
                if stated
                else "0.1 rad: its covariance is zero, unknown)"
            )
        )
        return quaternion / norm, sigma, text
    return None, None, f"{topic} has no message after the start"


def _gps_course_heading(
    reader, path: Path, gps_topic: str, odometry: str, odometry_type: str, origin, start_s: float
) -> tuple[float | None, str]:
    """The start's yaw [rad] in ENU from the GPS course against the wheel odometry's: the
    first fix ``GPS_COURSE_MIN_M`` from the first one, its ENU displacement against the
    odometry's displacement between the two fixes' stamps in the odometry's body frame at
    the first, carried back to ``start_s`` by the odometry's own turn. (None, why) where the
    track does not move that far within ``GPS_COURSE_WINDOW_S``."""
    from datasets.bags.gps import geodetic_to_enu
    from datasets.bags.wheel_odometry import pose_sample

    fixes: list[tuple[float, np.ndarray]] = []
    samples: list[PoseSample] = []
    end_s = start_s + GPS_COURSE_WINDOW_S
    for topic, _, stamp, message in iter_messages(
        reader, path, [gps_topic, odometry], report=ReadReport()
    ):
        if stamp > end_s:
            break
        if topic == odometry:
            sample = pose_sample(message, odometry_type, stamp)
            if np.all(np.isfinite(sample.position)) and (not samples or stamp > samples[-1].t):
                samples.append(sample)
            continue
        if stamp < start_s or message.status.status < 0:
            continue
        fix = np.array([[message.latitude, message.longitude, message.altitude]], dtype=float)
        if np.all(np.isfinite(fix)):
            fixes.append((stamp, geodetic_to_enu(fix, origin)[0]))
        if len(fixes) > 1 and np.hypot(*(fixes[-1][1] - fixes[0][1])[:2]) >= GPS_COURSE_MIN_M:
            break
    if len(fixes) < 2 or np.hypot(*(fixes[-1][1] - fixes[0][1])[:2]) < GPS_COURSE_MIN_M:
        return (
            None,
            f"the GPS track moves less than {GPS_COURSE_MIN_M:g} m in its first {GPS_COURSE_WINDOW_S:g} s",
        )
    (t0, p0), (t1, p1) = fixes[0], fixes[-1]
    if len(samples) < 2 or samples[0].t > start_s or samples[-1].t < t1:
        return None, f"{odometry} does not cover the GPS fixes at t={t0:.3f}..{t1:.3f}"
    a_pos, a_q = pose_at(samples, t0)
    b_pos, _ = pose_at(samples, t1)
    s_pos, s_q = pose_at(samples, start_s)
    body = matrix_from_quat_wxyz(a_q).T @ (b_pos - a_pos)
    yaw_at_fix = np.arctan2(p1[1] - p0[1], p1[0] - p0[0]) - np.arctan2(body[1], body[0])
    yaw = float(wrap_angle(yaw_at_fix - (_yaw(a_q) - _yaw(s_q))))
    return yaw, (
        f"heading {np.rad2deg(yaw):.1f} deg (ENU, from east) from the GPS course over "
        f"{np.hypot(*(p1 - p0)[:2]):.1f} m (t={t0:.3f}..{t1:.3f}) against {odometry}'s "
        "displacement over the same stamps"
    )


def _yaw_quaternion(yaw: float) -> np.ndarray:
    return np.array([np.cos(0.5 * yaw), 0.0, 0.0, np.sin(0.5 * yaw)])


def _odometry_velocity(
    reader, path: Path, role: OdometryRole, start_s: float, rotation: np.ndarray
) -> tuple[np.ndarray | None, str]:
    """World-frame velocity at ``start_s`` from the wheel odometry's twist (its first
    message at or after it), with ``rotation`` the start's orientation."""
    from datasets.bags.wheel_odometry import pose_sample

    if (
        role.topic is None
        or role.evidence is None
        or role.evidence.msgtype != "nav_msgs/msg/Odometry"
    ):
        return None, "zero (no wheel odometry twist)"
    for _, msgtype, stamp, message in iter_messages(
        reader, path, [role.topic], report=ReadReport()
    ):
        if stamp < start_s:
            continue
        sample = pose_sample(message, msgtype, stamp)
        if sample.linear is None or not np.all(np.isfinite(sample.linear)):
            break
        velocity = matrix_from_quat_wxyz(rotation) @ sample.linear
        return (
            velocity,
            f"{np.linalg.norm(velocity):.3g} m/s from {role.topic}'s twist at t={stamp:.3f}",
        )
    return None, "zero (no wheel odometry twist at the start)"


def sensor_sequence(
    argument: str, path: Path, settings, topics: BagTopics
) -> tuple[Sequence, SensorSource]:
    """The sequence of a bag without a lidar (module docstring); ``settings``:
    ``datasets.bags.bag_options.BagOptions``."""
    decisions: list[str] = []
    warnings: list[str] = []
    with open_bag(path) as reader:
        types = topic_types(reader)
        imu_topic = topics.imu if settings.imu else None
        role = (
            choose_odometry(reader, path, types, settings.odometry_topic, topics.ground_truth)
            if settings.wheel_odometry
            else OdometryRole(None, None, "odometry: not used (wheel_odometry=false)")
        )
        if role.text:
            decisions.append(role.text)
        laser_topic = None if settings.laser_topic == "none" else topics.laser
        planar = laser_topic is not None and role.topic is not None
        if laser_topic is not None and role.topic is None:
            decisions.append(
                f"2-D laser {laser_topic} not used: the 2-D laser front end needs the motion "
                "between scans and the bag has no wheel odometry (--data odometry_topic=TOPIC)"
            )
        if planar:
            from datasets.bags.laserscan import describe_laserscan

            first_scan = next(
                (
                    m
                    for _, _, _, m in iter_messages(
                        reader, path, [laser_topic], report=ReadReport()
                    )
                ),
                None,
            )
            if first_scan is not None:
                decisions.append(describe_laserscan(laser_topic, first_scan))
            unused = [t for t in (imu_topic, topics.gps if settings.gps else None) if t]
            decisions.append(
                f"2-D: {laser_topic} with {role.topic} make a planar sequence (odometry at "
                "each scan, corners by split-and-merge, datasets.laser2d)"
                + (f"; not used in 2-D: {', '.join(unused)}" if unused else "")
                + " (--data laser_topic=none for the 3-D sequence of the other sensors)"
            )
            imu_topic = None
        gps_topic = topics.gps if settings.gps and not planar else None
        origin = first_gps_origin(reader, path, gps_topic) if gps_topic else None
        if gps_topic and origin is None:
            warnings.append(f"{gps_topic} has no valid fix; GPS not used")
            gps_topic = None
        if imu_topic is None and role.topic is None:
            listed = "; ".join(f"{t} [{m}]" for t, m in sorted(types.items())) or "no topics"
            raise InputError(
                f"{path}: no sensor an estimator can use: no {'PointCloud2'} topic, no Imu "
                f"topic{' (imu=false)' if topics.imu and not settings.imu else ''} and no "
                f"wheel odometry ({role.text or 'no nav_msgs/Odometry topic'}); topics: {listed}"
            )
        duration = max((reader.end_time - reader.start_time) * 1e-9, 1e-9)
        rates: dict[str, float] = {}
        imu_rate, gyro_density, accel_density = imu_rate_and_noise(reader, imu_topic, path)
        if imu_rate:
            rates["imu"] = float(imu_rate)
        if role.evidence is not None and role.evidence.rate_hz:
            rates["odometry"] = float(role.evidence.rate_hz)
        if gps_topic:
            rates["gps"] = float(reader.topics[gps_topic].msgcount / duration)
        if planar:
            rates["laser"] = float(reader.topics[laser_topic].msgcount / duration)
        defining = [t for t in (imu_topic, role.topic, laser_topic if planar else None) if t]
        spans = topic_spans(reader, path, defining)
    load_report = ReadReport()
    gt = (np.zeros(0), np.zeros((0, 3)), np.zeros((0, 4)))
    if topics.ground_truth:
        gt = read_ground_truth(path, topics.ground_truth, load_report)
        check_skips(path, [topics.ground_truth], settings.max_skipped_fraction, load_report)
        if len(gt[0]) < 2:
            raise InputError(
                f"{path}: ground-truth topic {topics.ground_truth} has {len(gt[0])} usable poses"
            )
        spans[topics.ground_truth] = (float(gt[0][0]), float(gt[0][-1]))
    time_base = common_time_base(path, spans)
    if time_base is None:
        raise InputError(f"{path}: the sensor topics {', '.join(defining)} have no messages")
    ground_truth = ground_truth_from_topic(*gt, None, topics.ground_truth, warnings)
    if topics.unnamed_truth:
        warnings.append(
            f"no ground truth: pose topic(s) {', '.join(topics.unnamed_truth)} not taken "
            "as truth unless named (--data ground_truth_topic=TOPIC, workbench bag --truth-topic)"
        )
    noise_model: WheelNoise | None = None
    if role.topic is not None:
        noise_model, noise_text = role.noise(settings.odometry_noise)
        decisions.append(f"odometry noise: {noise_text}")
    initial, start_text = _start(
        path, settings, time_base, imu_topic, gps_topic, origin, role, ground_truth, warnings
    )
    decisions.append(start_text)
    read_settings = ReadSettings(
        gps_origin=origin,
        gps_sigma_m=settings.gps_sigma_m,
        reorder_window_s=settings.reorder_window_s,
        max_missing_fraction=settings.max_missing_fraction,
        max_skipped_fraction=settings.max_skipped_fraction,
        time_base=time_base,
        laser_mounting=np.asarray(settings.laser_to_body or (0.0, 0.0, 0.0), dtype=float),
    )
    metadata = {
        "source": str(path),
        "reference_source": f"topic {topics.ground_truth}" if topics.ground_truth else None,
        "warnings": warnings,
        "topics": {
            "lidar": None,
            "imu": imu_topic,
            "ground_truth": topics.ground_truth,
            "gps": gps_topic,
            "odometry": role.topic,
            "laser": laser_topic if planar else None,
        },
        "time_base": time_base.as_dict(),
        "gps_origin": list(origin) if origin else None,
        "options": settings.model_dump(mode="json"),
        "decisions": decisions,
    }
    name = f"bag:{argument}"
    if planar:
        return _planar_sequence(
            name, path, settings, read_settings, laser_topic, role, noise_model, time_base,
            ground_truth, initial, rates, metadata, decisions, warnings,
        )  # fmt: skip
    source = SensorSource()
    topic_list = [t for t in (imu_topic, gps_topic, role.topic) if t]
    counts: dict[str, int] = {}

    def stream() -> Iterator[Measurement]:
        report = ReadReport()
        source.report = report
        increments = (
            WheelIncrements(
                noise_model,
                from_twist=role.from_twist,
                max_rate_hz=settings.odometry_max_rate_hz,
                start_s=time_base.start_s,
            )
            if noise_model is not None
            else None
        )
        for _, measurement in read_stream(path, topic_list, read_settings, report):
            if isinstance(measurement, PoseSample):
                odometry = increments.add(measurement)
                if odometry is not None:
                    yield odometry
            else:
                yield measurement
        if increments is not None:
            counts.update(
                odometry_increments=increments.emitted,
                odometry_messages_composed=increments.composed,
            )
        source.record_warnings(warnings)

    sensors = {Sensor.IMU} if imu_topic else set()
    sensors |= {Sensor.GPS} if gps_topic else set()
    sensors |= {Sensor.ODOMETRY} if role.topic else set()
    if role.topic and settings.odometry_max_rate_hz and role.evidence.rate_hz:
        if role.evidence.rate_hz > settings.odometry_max_rate_hz * 1.01:
            decisions.append(
                f"odometry: {role.topic}'s increments composed from {role.evidence.rate_hz:.3g} Hz "
                f"to at most odometry_max_rate_hz={settings.odometry_max_rate_hz:g} Hz (the "
                "smoothers open a keyframe at each)"
            )
    metadata["odometry_counts"] = counts  # filled once the stream has run
    noise = NoiseSpec(
        gyro_noise_density=(settings.gyro_noise_density or gyro_density or 1.7e-4)
        if imu_topic
        else None,
        accel_noise_density=(settings.accel_noise_density or accel_density or 2e-3)
        if imu_topic
        else None,
        gyro_bias_walk=settings.gyro_bias_walk if imu_topic else None,
        accel_bias_walk=settings.accel_bias_walk if imu_topic else None,
        gyro_bias_sigma_rad_s=settings.gyro_bias_sigma_rad_s if imu_topic else None,
        accel_bias_sigma_m_s2=settings.accel_bias_sigma_m_s2 if imu_topic else None,
        gps_sigma_m=settings.gps_sigma_m if gps_topic else None,
        odometry=noise_model.model if noise_model is not None else None,
        rate_hz=rates,
    )
    sequence = Sequence(
        name=name,
        dimension=3,
        sensors=frozenset(sensors),
        stream=stream,
        ground_truth=ground_truth,
        noise=noise,
        initial_state=initial,
        metadata=metadata,
    )
    return sequence, source


def _start(
    path: Path,
    settings,
    time_base: TimeBase,
    imu_topic: str | None,
    gps_topic: str | None,
    origin,
    role: OdometryRole,
    ground_truth: GroundTruth | None,
    warnings: list[str],
) -> tuple[InitialState, str]:
    """The initial state and the decision line saying where it comes from (module
    docstring)."""
    start_s = time_base.start_s
    truth = ground_truth.pose if ground_truth is not None else None
    if gps_topic is None and truth is not None:
        initial = initial_state_from_truth(start_s, truth)
        return initial, f"start: from the truth topic at t={initial.t:.3f} (its frame is the world)"
    with open_bag(path) as reader:
        quaternion, sigma, orientation_text = None, 1e-3, ""
        reasons = []
        if imu_topic:
            quaternion, sigma, imu_text = _imu_orientation(reader, path, imu_topic, start_s)
            orientation_text = imu_text
            if quaternion is None:
                reasons.append(imu_text)
        if quaternion is None and gps_topic and role.topic:
            yaw, course_text = _gps_course_heading(
                reader, path, gps_topic, role.topic, role.evidence.msgtype, origin, start_s
            )
            if yaw is not None:
                quaternion, sigma, orientation_text = _yaw_quaternion(yaw), 0.05, course_text
            else:
                reasons.append(course_text)
        if quaternion is None:
            quaternion, sigma = np.array([1.0, 0.0, 0.0, 0.0]), 1e-3
            why = f" ({'; '.join(reasons)})" if reasons else ""
            if gps_topic:
                orientation_text = f"level, facing east: assumed{why}"
                warnings.append(
                    f"start heading unknown{why}: east assumed; the GPS-aided estimates are "
                    "wrong where the vehicle started facing elsewhere"
                )
            else:
                orientation_text = f"the first body frame{why}"
        velocity, velocity_text = _odometry_velocity(reader, path, role, start_s, quaternion)
    if gps_topic:
        world = (
            f"world: ENU about the first fix of {gps_topic} (lat {origin[0]:.7f}, lon "
            f"{origin[1]:.7f}, alt {origin[2]:.2f} m)"
        )
        if truth is not None:
            world += (
                "; the truth topic is only scored, after alignment (its frame is not assumed "
                "to be this ENU)"
            )
        position_sigma = settings.gps_sigma_m
    else:
        world = "world: the start's body frame at the origin"
        position_sigma = 1e-3
    initial = InitialState(
        t=start_s,
        position=np.zeros(3),
        rotation=np.asarray(quaternion, dtype=float),
        velocity=velocity,
        position_sigma_m=position_sigma,
        rotation_sigma_rad=float(sigma),
    )
    return initial, (
        f"start at t={start_s:.3f} ({time_base.start_by}): {world}; orientation: "
        f"{orientation_text}; velocity: {velocity_text}"
    )


def _planar_truth(ground_truth: GroundTruth | None) -> GroundTruth | None:
    """The 3-D truth as planar poses (x, y, yaw)."""
    if ground_truth is None or ground_truth.pose is None:
        return None
    pose = ground_truth.pose
    yaws = np.array([_yaw(q) for q in pose.rotations])
    planar = Trajectory(pose.t.copy(), pose.positions[:, :2].copy(), yaws)
    return GroundTruth(history=StateHistory(pose=planar), excluded=ground_truth.excluded)


def _planar_pose(samples: list[PoseSample], t: float) -> np.ndarray:
    position, quaternion = pose_at(samples, t)
    return np.array([position[0], position[1], _yaw(quaternion)])


def _planar_sequence(
    name, path, settings, read_settings, laser_topic, role, noise_model, time_base,
    ground_truth, initial, rates, metadata, decisions, warnings,
) -> tuple[Sequence, SensorSource]:  # fmt: skip
    """The 2-D laser sequence (module docstring)."""
    odometry_report = ReadReport()
    samples: list[PoseSample] = [
        m
        for _, m in read_stream(
            path,
            [role.topic],
            ReadSettings(**{**read_settings.__dict__, "time_base": None}),
            odometry_report,
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
    figures: dict = {}

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
        figures.update(front_end.summary())
        source.record_warnings(warnings)

    metadata["laser_corners"] = figures  # filled once the stream has run
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
    )
    return sequence, source
