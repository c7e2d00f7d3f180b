"""Dataset ``bag:PATH``: a ROS 1/ROS 2 bag as a ``Sequence`` with the lidar front end.

Sensors: POINT_CLOUD (the clouds), IMU when the bag has an Imu topic, GPS when it has a
NavSatFix topic (local ENU about the first fix, ``datasets.bags.gps``), ODOMETRY (KISS-ICP
relative poses) and LANDMARKS (corners) from the front end. Ground truth: the poses of the
Odometry/PoseStamped topic named by ``ground_truth_topic`` (never one found by type: it may
be wheel odometry), and the true corners when a sidecar ``NAME.corners.json`` (written by
``workbench simulate lidar-corridor``) lies next to the bag, only with those poses (the
corners are in the truth topic's world frame).

Frames: the body frame is the IMU's; clouds are moved into it with the ``lidar_to_body``
option (identity by default: lidar = body). KISS-ICP then tracks the body frame and corners
are body-frame positions, as the estimators expect.

One time base: the streams are trimmed to their common interval, so nothing fails because
one sensor starts earlier (an IMU driver started before the lidar, a truth topic that
begins late). The interval runs from the latest first stamp to the earliest last stamp of
the streams the sequence is built from: the lidar (its last sweep counted to its end), the
IMU when used, and the ground-truth topic when named (``datasets.bags.spans.topic_spans``,
``common_time_base``). GPS fixes outside it are dropped too, but a sparse GPS topic does not
narrow it; topics not read (wheel odometry, an unnamed pose topic) play no part. Every
dropped message is counted in ``metadata["warnings"]`` (``trimmed N x TOPIC at t=..: before
the start of the common time base t=.. (first stamp on /points)``, once the stream has
run); the interval and each stream's span are ``metadata["time_base"]``; the initial state
is at the interval's start. With lidar odometry the interval starts at the front end's
first pose (``start_at_first_pose``): where the first kept sweep ends when it is deskewed,
else at that cloud's stamp. The estimators' first odometry increment starts there, and a
deskewed first sweep is read but not emitted. The front end's odometry and corners of the
last kept cloud are stamped at its sweep end, which the lidar's span includes.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from pydantic import ConfigDict, Field

from datasets.bags.bag_file import iter_messages, open_bag
from datasets.bags.convert import MAX_ACCEL_M_S2, MAX_GYRO_RAD_S, first_gps_origin
from datasets.bags.ground_truth import read_ground_truth
from datasets.bags.message_types import ODOMETRY, POINTCLOUD2
from datasets.bags.pointcloud2 import MalformedCloud, decode_pointcloud2
from datasets.bags.read_report import ReadReport, ReadSettings, check_skips
from datasets.bags.reader import read_stream
from datasets.bags.spans import lidar_sweep_period, max_point_time, start_at_first_pose, topic_spans
from datasets.bags.time_base import common_time_base
from datasets.bags.topic_roles import OdometryRole, choose_odometry, not_wheel_words
from datasets.bags.topics import BagTopics, discover_topics, topic_types
from datasets.bags.wheel_odometry import PoseSample, WheelIncrements
from datasets.errors import InputError
from datasets.laser2d.frontend import Laser2dFrontEndSettings
from datasets.lidar.corner_truth import (
    CornerTruth,
    interpolate_poses,
    read_corner_truth,
    sidecar_for,
    with_true_corner_ids,
)
from datasets.lidar.frontend import (
    LidarFrontEnd,
    LidarSourceOptions,
    describe_lidar_options,
    with_front_end,
)
from datasets.lidar.sweep_timing import SweepTimingDecision, decide_sweep_timing
from datasets.measurements import PointCloud, Sensor
from datasets.options import build_model, yaml_value
from datasets.rotations import matrix_from_quat_wxyz
from datasets.sequence import InitialState, NoiseSpec, Sequence
from datasets.state import Frame, GroundTruth, LandmarkMap, StateHistory
from datasets.trajectory import Trajectory
from datasets.truth_quality.assess import assess_trajectory


class BagOptions(LidarSourceOptions):
    """``--data`` options of ``bag:PATH`` (nested ones as ``kiss.voxel_size_m=0.5``, ``corner.directions=true``)."""

    model_config = ConfigDict(extra="forbid")

    lidar_topic: str | None = Field(None, description="PointCloud2 topic (default: the only one)")
    max_missing_fraction: float = Field(
        0.01,
        ge=0,
        le=1,
        description="fewer messages read on a topic than the bag's index lists is a warning; "
        "more than this fraction missing is an error (a damaged bag)",
    )
    imu_topic: str | None = Field(None, description="Imu topic (default: the only one, if any)")
    ground_truth_topic: str | None = Field(
        None,
        description="Odometry/PoseStamped topic to score against (default: none; a pose topic "
        "is never taken as truth unless named: it may be wheel odometry or another estimator)",
    )
    max_skipped_fraction: float = Field(
        0.05,
        ge=0,
        le=1,
        description="messages skipped on a topic (NaN IMU samples, non-finite poses, empty "
        "clouds, stamps going back) are counted warnings; more than this fraction is an error",
    )
    gps_topic: str | None = Field(
        None, description="NavSatFix topic (default: the only one, if any)"
    )
    imu: bool = Field(True, description="use the IMU topic when there is one")
    imu_deskew: bool = Field(
        True,
        description="with an IMU topic, deskew clouds that carry per-point times by the "
        "gyro's rotation over the sweep (datasets.lidar.imu_deskew) instead of KISS-ICP's "
        "constant-velocity prediction; frames the IMU does not cover fall back to the latter "
        "and are counted in the warnings",
    )
    gps: bool = Field(True, description="use the NavSatFix topic when there is one")
    gps_sigma_m: float = Field(
        1.0, gt=0, description="GPS std when a fix carries no covariance [m]"
    )
    gyro_noise_density: float | None = Field(
        None, gt=0, description="[rad/s/sqrt(Hz)] (default: from the Imu covariance, else 1.7e-4)"
    )
    accel_noise_density: float | None = Field(
        None, gt=0, description="[m/s^2/sqrt(Hz)] (default: from the Imu covariance, else 2e-3)"
    )
    gyro_bias_walk: float = Field(
        2e-5,
        gt=0,
        description="gyro bias random walk [rad/s^2/sqrt(Hz)] (bags do not say; a MEMS-class value)",
    )
    accel_bias_walk: float = Field(
        3e-4, gt=0, description="accelerometer bias random walk [m/s^3/sqrt(Hz)] (bags do not say)"
    )
    gyro_bias_sigma_rad_s: float = Field(
        0.01, gt=0, description="std of the initial gyro bias [rad/s]"
    )
    accel_bias_sigma_m_s2: float = Field(
        0.1, gt=0, description="std of the initial accelerometer bias [m/s^2]"
    )
    lidar_to_body: tuple[float, float, float, float, float, float, float] | None = Field(
        None,
        description="lidar pose in the body (IMU) frame: [x, y, z, qw, qx, qy, qz]; clouds are moved into the body frame (also levels a tilted lidar for the corner slab)",
    )
    reorder_window_s: float = Field(
        1.0, ge=0, description="how far stamps may lag bag order and still be reordered [s]"
    )
    odometry_topic: str | None = Field(
        None,
        description="wheel-odometry topic (nav_msgs/Odometry, or a PoseStamped / "
        "PoseWithCovarianceStamped topic, differenced); default: decided from the bag's "
        "Odometry topics by their frames, rates, covariances, jumps and names (printed); used "
        "as input where no lidar odometry is, never as truth",
    )
    wheel_odometry: bool = Field(
        True, description="use wheel odometry (odometry_topic or the one decided) as an input"
    )
    odometry_noise: str = Field(
        "auto",
        description="wheel-odometry increment covariance: 'auto' (the messages' twist "
        "covariance on the axes where it is meaningful, else the stated default model), "
        "'twist', 'model' (datasets.bags.wheel_odometry.WHEEL_ODOMETRY_NOISE) or a YAML model "
        "file from `workbench calibrate-noise`",
    )
    odometry_max_rate_hz: float | None = Field(
        10.0,
        gt=0,
        description="wheel-odometry increments are composed to at most this rate [Hz] (the "
        "smoothers open a keyframe at each); null: one per message",
    )
    laser_topic: str | None = Field(
        None,
        description="sensor_msgs/LaserScan topic (default: the only one, if any); 'none': "
        "do not use a 2-D laser",
    )
    laser_to_body: tuple[float, float, float] | None = Field(
        None,
        description="2-D laser pose in the body frame: [x, y, theta] [m, m, rad] (default: "
        "the body frame; the bag's /tf_static is not read)",
    )
    laser: Laser2dFrontEndSettings = Field(
        default_factory=Laser2dFrontEndSettings,
        description="2-D laser front end (LaserScan bags), as laser.KEY=VALUE and "
        "laser.corner.KEY=VALUE (datasets.laser2d)",
    )


def nest_dotted(options: dict[str, str]) -> dict[str, object]:
    """``{"kiss.voxel_size_m": "0.5"}`` -> ``{"kiss": {"voxel_size_m": 0.5}}`` (YAML values),
    at any depth (``laser.corner.min_range_m``)."""
    nested: dict[str, object] = {}
    for key, value in options.items():
        *heads, last = key.split(".")
        group = nested
        for depth, head in enumerate(heads):
            group.setdefault(head, {})
            if not isinstance(group[head], dict):
                raise InputError(
                    f"--data {key}: '{'.'.join(heads[: depth + 1])}' is not a group of options"
                )
            group = group[head]  # type: ignore[assignment]
        group[last] = yaml_value(value)
    return nested


class LidarSource:
    """A bag or scan folder with its front end; remembers what the last pass skipped."""

    def __init__(self, front_end: LidarFrontEnd, lidar_messages: int | None = None) -> None:
        """``lidar_messages``: the clouds the bag's index lists on its lidar topic (for a
        progress bar; None where unknown)."""
        self.front_end = front_end
        self.report = ReadReport()
        self.lidar_messages = lidar_messages

    def record_warnings(self, warnings: list[str]) -> None:
        """Add the last pass's skips and the front end's heading, warm-up and IMU deskew
        warnings to ``warnings`` (``datasets.Sequence`` metadata), each once however often
        the stream is read."""
        front_end = [
            self.front_end.heading_warning(),
            self.front_end.settling_warning(),
            self.front_end.imu_deskew_warning(),
        ]
        for line in [*self.report.lines(), *(line for line in front_end if line)]:
            if line not in warnings:
                warnings.append(line)


def extrinsic_matrix(pose: tuple[float, ...] | None) -> np.ndarray | None:
    """[x, y, z, qw, qx, qy, qz] -> (4, 4), or None; ``InputError`` for a zero quaternion."""
    if pose is None:
        return None
    quat = np.asarray(pose[3:], dtype=float)
    norm = np.linalg.norm(quat)
    if not norm > 1e-9:
        raise InputError(f"lidar_to_body: quaternion {list(pose[3:])} has zero length")
    matrix = np.eye(4)
    matrix[:3, :3] = matrix_from_quat_wxyz(quat / norm)
    matrix[:3, 3] = pose[:3]
    return matrix


def _ground_truth(
    times: np.ndarray,
    positions: np.ndarray,
    quats: np.ndarray,
    truth: CornerTruth | None,
    topic: str | None,
    warnings: list[str],
) -> GroundTruth | None:
    """The named truth topic's poses and the sidecar's corners, or None without poses: the
    sidecar's corners are in the truth topic's world frame, while without it the first body
    frame is the world, so a map scored against them would compare two frames (a 9 m
    "landmark RMSE" on a 3 s corridor bag whose map is fine). Where the topic cannot be
    trusted (``datasets.truth_quality``: dropouts, freezes, jumps, ...) is excluded from
    the scoring and said in ``warnings``."""
    if len(times) < 2:
        return None
    pose = Trajectory(times, positions, quats)
    landmarks = (
        LandmarkMap(ids=truth.ids.copy(), positions=truth.positions.copy(), frame=Frame.WORLD)
        if truth is not None
        else None
    )
    excluded, lines = assess_trajectory(times, positions, quats, f"truth topic {topic}")
    warnings.extend(lines)
    return GroundTruth(history=StateHistory(pose=pose), landmarks=landmarks, excluded=excluded)


def _initial_state(start_s: float, truth: Trajectory | None) -> InitialState:
    """At ``start_s`` (the start of the common time base): from the ground truth there when
    the bag has one (velocity by differences); otherwise the first body frame defines the
    world."""
    if truth is None or len(truth) < 2:
        return InitialState(
            t=start_s, position=np.zeros(3), rotation=np.array([1.0, 0.0, 0.0, 0.0]), velocity=None
        )
    t0 = max(start_s, float(truth.t[0]))
    step = float(np.median(np.diff(truth.t)))
    positions, quats = interpolate_poses(truth, np.array([t0, t0 + step]))
    velocity = (positions[1] - positions[0]) / step
    return InitialState(t=t0, position=positions[0], rotation=quats[0], velocity=velocity)


def _imu_noise(
    reader, topic: str | None, path: Path
) -> tuple[float | None, float | None, float | None]:
    """IMU rate and continuous-time noise densities from the first message's covariances
    (a discrete std sigma at rate f is a density sigma / sqrt(f)); None where unknown."""
    if topic is None:
        return None, None, None
    info = reader.topics[topic]
    duration = (reader.end_time - reader.start_time) * 1e-9
    rate = info.msgcount / duration if duration > 0 and info.msgcount > 1 else None
    # a message that does not decode is passed over here: the stream counts it
    for _, _, _, message in iter_messages(reader, path, [topic], report=ReadReport()):
        gyro_var = float(np.asarray(message.angular_velocity_covariance)[0])
        accel_var = float(np.asarray(message.linear_acceleration_covariance)[0])
        if rate is None:
            return None, None, None
        # used only when positive and below the square of the largest plausible reading: a
        # corrupted first message would otherwise set every estimator's noise
        gyro = np.sqrt(gyro_var / rate) if 0 < gyro_var <= MAX_GYRO_RAD_S**2 else None
        accel = np.sqrt(accel_var / rate) if 0 < accel_var <= MAX_ACCEL_M_S2**2 else None
        return rate, gyro, accel
    return rate, None, None


def load_bag(argument: str | None, seed: int, options: dict[str, str]) -> Sequence:
    """``bag:PATH`` -> ``Sequence`` (module docstring). ``seed`` is unused (nothing random)."""
    if not argument:
        raise InputError("dataset bag needs a path: bag:PATH")
    settings = build_model(BagOptions, nest_dotted(options), f"bag:{argument}")
    sequence, source = bag_sequence(argument, settings)
    # a simulator's bag with its truth named: the true id of every corner, so that maps and
    # association are scored (datasets.lidar.corner_truth.with_true_corner_ids)
    return with_true_corner_ids(sequence, source.front_end)


def bag_sequence(argument: str, settings: BagOptions) -> tuple[Sequence, LidarSource]:
    """The sequence of bag ``argument`` and its ``LidarSource`` (front end and skip report)."""
    path = Path(argument)
    gps_note = None
    with open_bag(path) as reader:
        types = topic_types(reader)
        topics = discover_topics(
            path,
            types,
            settings.lidar_topic,
            settings.imu_topic,
            settings.ground_truth_topic,
            settings.gps_topic,
            None if settings.laser_topic == "none" else settings.laser_topic,
        )
        if topics.lidar is None:  # IMU, wheel odometry, GPS, 2-D laser (sensor_source)
            from datasets.bags.sensor_source import sensor_sequence

            return sensor_sequence(argument, path, settings, topics)
        decisions, wheel = _other_inputs(reader, path, types, topics, settings)
        imu_topic = topics.imu if settings.imu else None
        gps_topic = topics.gps if settings.gps else None
        origin = first_gps_origin(reader, path, gps_topic) if gps_topic else None
        if gps_topic and origin is None:
            gps_note = f"{gps_topic} has no valid fix; GPS not used"
            gps_topic = None
        start_s = reader.start_time * 1e-9
        rates = {
            "lidar": float(
                reader.topics[topics.lidar].msgcount
                / max((reader.end_time - reader.start_time) * 1e-9, 1e-9)
            )
        }
        imu_rate, gyro_density, accel_density = _imu_noise(reader, imu_topic, path)
        if imu_rate:
            rates["imu"] = float(imu_rate)
        max_point_time_s = max_point_time(reader, path, topics.lidar)
        # per-point times: the clouds' own, or from azimuth where the sweeps are raw
        # (datasets.lidar.sweep_timing, decided from the first clouds unless stated)
        timing = bag_sweep_timing(reader, path, topics.lidar, settings, max_point_time_s)
        azimuth_sweep_s = timing.azimuth  # an AzimuthSweep (a float: one sweep [s]) or None
        spans = topic_spans(
            reader,
            path,
            [t for t in (topics.lidar, imu_topic) if t],
            settings.point_time_unit,
            azimuth_sweep_s,
            max_point_time_s,
        )
        lidar_messages = int(reader.topics[topics.lidar].msgcount)
        load_report = ReadReport()
        gt = (
            read_ground_truth(path, topics.ground_truth, load_report, reader)
            if topics.ground_truth
            else (np.zeros(0), np.zeros((0, 3)), np.zeros((0, 4)))
        )
        if topics.ground_truth:
            check_skips(path, [topics.ground_truth], settings.max_skipped_fraction, load_report)
            if len(gt[0]) < 2:
                raise InputError(
                    f"{path}: ground-truth topic {topics.ground_truth} has {len(gt[0])} "
                    "usable poses"
                )
            spans[topics.ground_truth] = (float(gt[0][0]), float(gt[0][-1]))
        time_base = common_time_base(path, spans)  # module docstring: one time base
        if time_base is not None and settings.odometry:
            time_base = start_at_first_pose(
                reader,
                path,
                time_base,
                topics.lidar,
                settings.point_time_unit,
                deskew=settings.kiss.deskew,
                azimuth_sweep_s=azimuth_sweep_s,
                max_point_time_s=max_point_time_s,
            )
    sidecar = sidecar_for(path)
    truth = read_corner_truth(sidecar) if sidecar.is_file() else None
    truth_warnings: list[str] = []
    ground_truth = _ground_truth(*gt, truth, topics.ground_truth, truth_warnings)
    read_settings = ReadSettings(
        time_unit=settings.point_time_unit,
        max_point_time_s=max_point_time_s,
        azimuth_sweep_s=azimuth_sweep_s,
        gps_origin=origin,
        gps_sigma_m=settings.gps_sigma_m,
        reorder_window_s=settings.reorder_window_s,
        lidar_to_body=extrinsic_matrix(settings.lidar_to_body),
        max_missing_fraction=settings.max_missing_fraction,
        max_skipped_fraction=settings.max_skipped_fraction,
        time_base=time_base,
    )
    front_end = LidarFrontEnd(
        settings.front_end_settings().model_copy(
            update={"imu_deskew": settings.imu_deskew and imu_topic is not None}
        ),
        # with an IMU the estimators may move by it instead of the front end's increments
        sole_motion_input=imu_topic is None,
    )
    source = LidarSource(front_end, lidar_messages)
    topic_list = [topic for topic in (topics.lidar, imu_topic, gps_topic, wheel.topic) if topic]

    resolved: dict = {}  # filled once the stream has run: the KISS-ICP settings used
    reobservation: dict = {}  # filled once the stream has run: corner_tracking figures
    # datasets.Sequence metadata "warnings": printed by the workbench (prefixed with the
    # dataset's name) and written to every run's metrics.json
    warnings = (
        list(timing.warnings)
        + list(load_report.lines())
        + ([gps_note] if gps_note else [])
        + truth_warnings
    )
    if topics.unnamed_truth:
        warnings.append(
            f"no ground truth: pose topic(s) {', '.join(topics.unnamed_truth)} not taken "
            "as truth unless named (--data ground_truth_topic=TOPIC, workbench bag --truth-topic)"
        )

    def stream():
        report = ReadReport()
        source.report = report
        measurements = (m for _, m in read_stream(path, topic_list, read_settings, report))
        if wheel.topic is not None:  # wheel odometry where the front end gives none
            measurements = wheel_increments(measurements, wheel, settings, time_base)
        yield from with_front_end(
            measurements,
            front_end,
            settings.point_clouds,
            settings.max_frames,
            emit_from_s=time_base.start_s if time_base else None,
        )
        resolved.update(front_end.resolved())
        reobservation.update(front_end.tracker.stats.summary())
        source.record_warnings(warnings)

    sensors = {Sensor.POINT_CLOUD} if settings.point_clouds else set()
    sensors |= {Sensor.IMU} if imu_topic else set()
    sensors |= {Sensor.GPS} if gps_topic else set()
    sensors |= {Sensor.ODOMETRY} if settings.odometry or wheel.topic else set()
    sensors |= {Sensor.LANDMARKS} if settings.corners else set()
    noise = NoiseSpec(
        gyro_noise_density=settings.gyro_noise_density
        or (float(gyro_density) if gyro_density else 1.7e-4)
        if imu_topic
        else None,
        accel_noise_density=settings.accel_noise_density
        or (float(accel_density) if accel_density else 2e-3)
        if imu_topic
        else None,
        gyro_bias_walk=settings.gyro_bias_walk if imu_topic else None,
        accel_bias_walk=settings.accel_bias_walk if imu_topic else None,
        gyro_bias_sigma_rad_s=settings.gyro_bias_sigma_rad_s if imu_topic else None,
        accel_bias_sigma_m_s2=settings.accel_bias_sigma_m_s2 if imu_topic else None,
        landmark_sigma_m=settings.corner.range_sigma_m,
        gps_sigma_m=settings.gps_sigma_m if gps_topic else None,
        rate_hz=rates,
    )
    return Sequence(
        name=f"bag:{argument}",
        dimension=3,
        sensors=frozenset(sensors),
        stream=stream,
        ground_truth=ground_truth,
        noise=noise,
        initial_state=_initial_state(
            time_base.start_s if time_base else start_s,
            ground_truth.pose if ground_truth else None,
        ),
        # the front end's trajectory, increment covariances and counters, filled by the pass
        front_end=front_end.report if settings.odometry else None,
        metadata={
            "source": str(path),
            "reference_source": f"topic {topics.ground_truth}" if topics.ground_truth else None,
            "warnings": warnings,  # datasets.Sequence metadata: printed and in metrics.json
            "topics": {
                "lidar": topics.lidar,
                "imu": imu_topic,
                "ground_truth": topics.ground_truth,
                "gps": gps_topic,
                "odometry": wheel.topic,
                "laser": None,
            },
            # the common interval every stream is trimmed to (module docstring)
            "time_base": time_base.as_dict() if time_base else None,
            "gps_origin": list(origin) if origin else None,
            "kiss_icp": resolved,
            "corner_reobservation": reobservation,  # filled once the stream has run
            "corner_sidecar": str(sidecar) if truth is not None else None,
            "options": settings.model_dump(mode="json"),
            # what the loader decided and why, to print as notes (a clear decision) beside
            # the warnings (datasets.lidar.sweep_timing)
            "decisions": ([timing.text] if timing.clear else []) + decisions,
            "sweep_timing": timing.as_dict(),
        },
    ), source


def _other_inputs(
    reader, path: Path, types: dict[str, str], topics: BagTopics, settings: BagOptions
) -> tuple[list[str], OdometryRole]:
    """Beside a lidar: the decision lines on the bag's 2-D laser and pose topics, and the
    wheel odometry to use (only where the front end gives no odometry, ``odometry=false``:
    one odometry input per sequence)."""
    decisions = []
    if topics.laser:
        decisions.append(
            f"2-D laser {topics.laser} not used: the lidar {topics.lidar} is the bag's range sensor"
        )
    if settings.odometry or not settings.wheel_odometry:
        listed = [
            topic
            for topic, msgtype in sorted(types.items())
            # a topic named as truth or an estimate would never be the wheel odometry
            if msgtype == ODOMETRY and topic != topics.ground_truth and not not_wheel_words(topic)
        ]
        if listed:
            why = (
                "the lidar front end's (KISS-ICP) is the odometry input"
                if settings.odometry
                else "wheel_odometry=false"
            )
            decisions.append(
                f"odometry: {', '.join(listed)} not used as input ({why}; --data "
                "odometry=false uses wheel odometry instead)"
            )
        return decisions, OdometryRole(None, None, "")
    role = choose_odometry(reader, path, types, settings.odometry_topic, topics.ground_truth)
    if role.text:
        decisions.append(role.text)
    if role.topic is not None:
        _, text = role.noise(settings.odometry_noise)
        decisions.append(f"odometry noise: {text}")
    return decisions, role


def wheel_increments(measurements, wheel: OdometryRole, settings: BagOptions, time_base):
    """``measurements`` with the wheel odometry's ``PoseSample`` turned into ``Odometry``
    increments (``datasets.bags.wheel_odometry``)."""
    noise, _ = wheel.noise(settings.odometry_noise)
    increments = WheelIncrements(
        noise,
        from_twist=wheel.from_twist,
        max_rate_hz=settings.odometry_max_rate_hz,
        start_s=time_base.start_s if time_base else None,
    )
    for measurement in measurements:
        if isinstance(measurement, PoseSample):
            odometry = increments.add(measurement)
            if odometry is not None:
                yield odometry
        else:
            yield measurement


def bag_sweep_timing(
    reader, path: Path, topic: str, settings: BagOptions, max_point_time_s: float
) -> SweepTimingDecision:
    """How the clouds of ``topic`` are timed (``datasets.lidar.sweep_timing``), from its
    first ``settings.sweep.frames`` decodable, non-empty clouds in stamp order, in the lidar
    frame (before ``lidar_to_body``: azimuths are the lidar's). One sweep is the topic's
    median frame interval (``lidar_sweep_period``); none is read for ``point_times=field``.
    ``InputError`` (from ``lidar_sweep_period``) where azimuth times need a period and the
    topic gives none."""
    if settings.point_times == "field":
        return decide_sweep_timing([], 0.0, "field", settings.sweep)
    try:
        sweep_s = lidar_sweep_period(reader, path, topic)
    except InputError:
        if settings.point_times == "azimuth":
            raise
        sweep_s = 0.0  # a single cloud: nothing to compare, the decision says so
    clouds: dict[float, PointCloud] = {}
    # broken clouds are passed over here (a throwaway report): the stream counts them
    for _, msgtype, stamp, message in iter_messages(reader, path, [topic], report=ReadReport()):
        if msgtype != POINTCLOUD2 or stamp in clouds:
            continue
        where = f"{path}, topic {topic}, t={stamp:.9f}"
        try:
            cloud = decode_pointcloud2(
                message, stamp, where, settings.point_time_unit, max_point_time_s
            )
        except MalformedCloud:
            continue
        if len(cloud.points):
            clouds[stamp] = PointCloud(t=stamp, points=cloud.points, point_times=cloud.point_times)
        if len(clouds) >= settings.sweep.frames:
            break
    ordered = [clouds[stamp] for stamp in sorted(clouds)]
    return decide_sweep_timing(ordered, sweep_s, settings.point_times, settings.sweep)


def describe() -> list[str]:
    """Option lines for ``workbench list --verbose``."""
    return describe_lidar_options(BagOptions)
