"""Bags of any sensor set (#37) and LaserScan topics (#38).

A robot_localization-style bag (IMU + wheel odometry + NavSatFix GPS, no lidar, written from
simulated data in ``tests.bag_sensor_sets_support``) runs dead reckoning and the GPS-aided
smoothers, says n/a with the reason for the rest, and decides which pose topic is wheel
odometry from the messages, printing why. LaserScan messages decode to the ranges, angles,
limits and beam times that were written (ROS 1, ROS 2 sqlite3 and MCAP) and go through the
2-D laser front end."""

from __future__ import annotations

import csv
import json
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from datasets.bags.laserscan import MalformedScan, decode_laserscan
from datasets.bags.read_report import ReadReport, ReadSettings
from datasets.bags.reader import read_stream
from datasets.bags.source import load_bag
from datasets.bags.wheel_odometry import (
    WHEEL_ODOMETRY_NOISE,
    PoseSample,
    WheelIncrements,
    WheelNoise,
    compose,
    relative_pose,
)
from datasets.errors import InputError
from datasets.laser2d.scan import PlanarScan
from datasets.measurements import GpsFix, ImuSample, Odometry, Sensor
from datasets.rotations import so3_exp
from tests.bag_sensor_sets_support import (
    DURATION_S,
    EPOCH_S,
    START_YAW_DEG,
    Drive,
    write_laser_bag,
    write_robot_localization_bag,
)
from workbench.cli import main

TRUTH = {"ground_truth_topic": "/ground_truth"}


@pytest.fixture(scope="module")
def robot_bags(tmp_path_factory) -> dict[str, Path]:
    folder = tmp_path_factory.mktemp("robot_localization")
    return {
        "ros1": write_robot_localization_bag(folder / "rl", ros1=True),
        "ros2": write_robot_localization_bag(folder / "rl2", ros1=False),
    }


def _rows(out: Path) -> dict[str, dict[str, str]]:
    return {row["estimator"]: row for row in csv.DictReader((out / "table.csv").open())}


def test_a_robot_localization_bag_runs_what_its_sensors_allow(robot_bags, tmp_path, capsys):
    out = tmp_path / "out"
    argv = ["bag", str(robot_bags["ros1"]), "--out", str(out), "--truth-topic", "/ground_truth"]
    assert main([*argv, "--no-plots"]) == 0
    err = capsys.readouterr().err
    # the roles, decided from the messages and printed with their evidence
    assert (
        "front end: odometry: /odom is the wheel odometry (nav_msgs/Odometry, frame 'odom' -> 'base_link', 50 Hz"
        in err
    )
    assert "/odometry/filtered not: its name says an estimator's output" in err
    assert "/odometry/gps not: its name says" in err
    assert (
        "front end: odometry noise: covariance from the messages' twist covariance for yaw, x, y"
        in err
    )
    assert "world: ENU about the first fix of /gps/fix" in err
    assert "orientation: orientation from /imu/data" in err
    rows = _rows(out)
    for name in ("dead-reckoning", "smoother-batch", "smoother-isam2", "smoother-fixed-lag"):
        assert rows[name]["status"] == "ok", rows[name]
    for name in ("aghili", "sensor-based", "ekf-slam", "ekf-slam-mht"):
        assert rows[name]["status"] == "n/a" and name not in {p.name for p in out.iterdir()}
    table = (out / "table.md").read_text()
    assert (
        "n/a bag:" in table
        and "needs sensor(s)" in table
        and "(it provides: gps, imu, odometry)" in table
    )
    assert not (out / "frontend").exists()  # no lidar, no 2-D laser: no front end
    # against the simulated truth (DURATION_S long): dead reckoning of a good IMU from the IMU's
    # own orientation, the smoothers held by 0.5 m GPS
    assert float(rows["dead-reckoning"]["ate_rmse_m"]) < 0.2
    assert float(rows["smoother-isam2"]["ate_rmse_m"]) < 0.5
    assert float(rows["smoother-batch"]["ate_rmse_smoothed_m"]) < 0.5
    run = json.loads((out / "smoother-isam2" / "metrics.json").read_text())
    assert any(
        line.startswith("odometry: /odom is the wheel odometry") for line in run["decisions"]
    )


def test_a_ros2_robot_localization_bag_under_workbench_run(robot_bags, tmp_path, capsys):
    bag = robot_bags["ros2"]
    out = tmp_path / "dr"
    argv = ["run", "dead-reckoning", f"bag:{bag}", "--data", "ground_truth_topic=/ground_truth"]
    assert main([*argv, "--out", str(out), "--no-plots"]) == 0
    err = capsys.readouterr().err
    assert f"note: bag:{bag}: odometry: /odom is the wheel odometry" in err
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["ate_rmse_m"] < 0.2
    sequence = load_bag(str(bag), 0, TRUTH)
    assert sequence.sensors == {Sensor.IMU, Sensor.GPS, Sensor.ODOMETRY}
    assert sequence.topics.odometry == "/odom"
    # the start's heading is the IMU's (0.02 rad noise), not east and not the truth's
    yaw = 2 * np.arctan2(sequence.initial_state.rotation[3], sequence.initial_state.rotation[0])
    assert abs(np.rad2deg(yaw) - START_YAW_DEG) < 5.0 and np.allclose(
        sequence.initial_state.position, 0
    )
    stream = list(sequence.measurements())
    odometry = [m for m in stream if isinstance(m, Odometry)]
    assert (
        sum(isinstance(m, ImuSample) for m in stream) == int(DURATION_S * 50) + 1
    )  # 50 Hz, both ends
    assert sum(isinstance(m, GpsFix) for m in stream) == int(DURATION_S * 5) + 1  # 5 Hz
    # 50 Hz composed to 10 Hz, never a frame, with the distance the wheels read (0.5 % long)
    assert len(odometry) == int(DURATION_S * 10) and not any(m.frame for m in odometry)
    assert all(abs(m.dt - 0.1) < 1e-6 for m in odometry)
    travelled = sum(np.linalg.norm(m.relative_pose[3:]) for m in odometry)
    drive = Drive()
    end = int(DURATION_S * 1000) + 1  # the 1 kHz grid up to the last sample
    true_path = np.sum(np.hypot(np.diff(drive.x_grid[:end]), np.diff(drive.y_grid[:end])))
    assert abs(travelled / true_path - 1.005) < 0.003


def test_topic_options_are_checked_with_hints(robot_bags):
    bag = str(robot_bags["ros1"])
    with pytest.raises(
        InputError, match=r"no topic '/odm' \(odometry_topic\) \(did you mean '/odom'\?\)"
    ):
        load_bag(bag, 0, {"odometry_topic": "/odm"})
    with pytest.raises(
        InputError, match=r"no topic '/imu/dat' \(imu_topic\) \(did you mean '/imu/data'\?\)"
    ):
        load_bag(bag, 0, {"imu_topic": "/imu/dat"})
    with pytest.raises(
        InputError, match=r"no topic '/gps/fx' \(gps_topic\) \(did you mean '/gps/fix'\?\)"
    ):
        load_bag(bag, 0, {"gps_topic": "/gps/fx"})
    with pytest.raises(InputError, match=r"\(did you mean '/ground_truth'\?\)"):
        load_bag(bag, 0, {"ground_truth_topic": "/groundtruth"})
    with pytest.raises(InputError, match="is sensor_msgs/msg/Imu, not nav_msgs/msg/Odometry"):
        load_bag(bag, 0, {"odometry_topic": "/imu/data"})
    with pytest.raises(
        InputError, match="named both as the odometry input .* and as the ground truth"
    ):
        load_bag(bag, 0, {**TRUTH, "odometry_topic": "/ground_truth"})
    # named against the evidence: used, and the decision says what the evidence said
    named = load_bag(bag, 0, {"odometry_topic": "/odometry/filtered", "gps": "false"})
    (line,) = [d for d in named.decisions if d.startswith("odometry: /odometry/filtered as named")]
    assert (
        "as named (odometry_topic)" in line
        and "by the evidence it would not be taken (its name says" in line
    )
    # without a wheel odometry and a GPS: the IMU alone, its start in its own orientation
    imu_only = load_bag(bag, 0, {"wheel_odometry": "false", "gps": "false"})
    assert imu_only.sensors == {Sensor.IMU}
    assert "odometry: not used (wheel_odometry=false)" in imu_only.decisions


def test_wheel_increments_compose_to_the_pose_difference():
    rng = np.random.default_rng(1)
    samples, position, rotation = [], np.zeros(3), np.eye(3)
    for k in range(11):
        if k:
            rotation = rotation @ so3_exp(rng.normal(0, 0.05, 3))
            position = position + rotation @ np.array([0.1, 0.01, 0.0])
        from datasets.rotations import quat_wxyz_from_matrix

        samples.append(
            PoseSample(
                t=0.02 * k, position=position.copy(), quaternion=quat_wxyz_from_matrix(rotation)
            )
        )
    noise = WheelNoise(WHEEL_ODOMETRY_NOISE, use_twist=False, message_interval_s=0.02)
    increments = WheelIncrements(noise, max_rate_hz=10.0)
    emitted = [o for o in map(increments.add, samples) if o is not None]
    assert len(emitted) == 2 and increments.composed == 8
    direct = [relative_pose(samples[0], samples[5]), relative_pose(samples[5], samples[10])]
    for odometry, expected in zip(emitted, direct):
        assert np.allclose(odometry.relative_pose, expected, atol=1e-12)
    # composing the covariances adds them in the frame the increment ends in
    a, b = np.diag([1e-4] * 6), np.diag([2e-4] * 6)
    _, covariance = compose(np.zeros(6), a, np.zeros(6), b)
    assert np.allclose(covariance, a + b)


@pytest.fixture(scope="module")
def laser_bags(tmp_path_factory) -> dict[str, tuple[Path, list]]:
    folder = tmp_path_factory.mktemp("laser")
    return {
        kind: write_laser_bag(folder / f"laser_{kind}", ros1=kind == "ros1", storage=kind)
        for kind in ("ros1", "sqlite3", "mcap")
    }


@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap"])
def test_laserscan_messages_decode_to_what_was_written(laser_bags, kind):
    path, written = laser_bags[kind]
    report = ReadReport()
    scans = [
        m
        for _, m in read_stream(path, ["/scan"], ReadSettings(), report)
        if isinstance(m, PlanarScan)
    ]
    assert len(scans) == len(written) and not report.skipped and not report.repaired
    for scan, (t, angle_min, increment, ranges, range_min, range_max, time_increment) in zip(
        scans, written
    ):
        assert scan.t == pytest.approx(t, abs=1e-6)  # float seconds at 1.7e9: 2.4e-7 apart
        assert np.array_equal(scan.ranges, ranges.astype(float), equal_nan=True)
        assert np.allclose(
            scan.angles, np.float32(angle_min) + np.float32(increment) * np.arange(len(ranges))
        )
        assert (scan.min_range_m, scan.max_range_m) == (
            np.float32(range_min),
            np.float32(range_max),
        )
        if time_increment > 0:
            assert np.allclose(scan.beam_times, np.float32(time_increment) * np.arange(len(ranges)))
        else:
            assert scan.beam_times is None
        assert (
            np.isposinf(scan.ranges[7])
            and np.isnan(scan.ranges[200])
            and not scan.returns()[[7, 200]].any()
        )


def test_a_laserscan_bag_is_a_planar_sequence_through_the_laser_front_end(
    laser_bags, tmp_path, capsys
):
    path, written = laser_bags["sqlite3"]
    sequence = load_bag(str(path), 0, {})
    assert sequence.dimension == 2 and sequence.sensors == {Sensor.ODOMETRY, Sensor.LANDMARKS}
    decisions = sequence.decisions
    assert any(
        d.startswith("2-D laser /scan: 361 beams from -135.00 deg by 0.75 deg (angle_max agrees)")
        for d in decisions
    )
    assert any(d.startswith("2-D: /scan with /odom make a planar sequence") for d in decisions)
    stream = list(sequence.measurements())
    frames = [m for m in stream if isinstance(m, Odometry)]
    assert len(frames) == len(written) - 1 and all(
        m.frame and m.relative_pose.shape == (3,) for m in frames
    )
    # the increments are the odometry's between scan stamps: 0.03 m and 0.005 rad each
    assert np.allclose([m.relative_pose[2] for m in frames], 0.005, atol=1e-9)
    assert sequence.pass_report.figures["laser_corners"]["corners_detected"] > 0
    out = tmp_path / "out"
    assert main(["bag", str(path), "--out", str(out), "--estimator", "ekf-slam", "--no-plots"]) == 0
    assert "front end: 2-D: /scan with /odom" in capsys.readouterr().err
    assert _rows(out)["ekf-slam"]["status"] == "ok"
    assert json.loads((out / "frontend" / "metrics.json").read_text())["scans"] == len(written)


def test_a_scan_sweeping_clockwise_is_stored_in_increasing_angle_and_bad_ones_are_named():
    message = SimpleNamespace(
        ranges=np.array([1.0, 2.0, 3.0], dtype=np.float32),
        angle_min=0.5,
        angle_max=-0.5,
        angle_increment=-0.5,
        time_increment=0.001,
        range_min=0.1,
        range_max=10.0,
    )
    scan, dropped = decode_laserscan(message, EPOCH_S)
    assert dropped is None
    assert np.allclose(scan.angles, [-0.5, 0.0, 0.5]) and np.allclose(scan.ranges, [3.0, 2.0, 1.0])
    assert np.allclose(scan.beam_times, [0.002, 0.001, 0.0])
    with pytest.raises(MalformedScan, match="angle_increment 0"):
        decode_laserscan(SimpleNamespace(**{**vars(message), "angle_increment": 0.0}), 0.0)
    with pytest.raises(MalformedScan, match="range_min 10 m, range_max 0.1 m"):
        decode_laserscan(
            SimpleNamespace(**{**vars(message), "range_min": 10.0, "range_max": 0.1}), 0.0
        )
    scan, dropped = decode_laserscan(
        SimpleNamespace(**{**vars(message), "time_increment": 5.0}), 0.0
    )
    assert scan.beam_times is None and "time_increment 5 s spreads 3 beams over 10 s" in dropped


@pytest.mark.parametrize("kind", ("robot_localization", "laser"))
def test_a_sensor_bag_is_opened_once_to_load_and_once_per_pass(
    kind, robot_bags, laser_bags, monkeypatch
) -> None:
    """Issue #39: the load reads what it needs through one open reader (it opened the bag
    four times for a robot_localization bag with named truth and for a 2-D laser bag),
    and each pass over the stream opens it once."""
    from rosbags.highlevel import AnyReader

    opened = []
    original = AnyReader.open
    monkeypatch.setattr(AnyReader, "open", lambda self: opened.append(1) or original(self))
    path = robot_bags["ros1"] if kind == "robot_localization" else laser_bags["ros1"][0]
    sequence = load_bag(str(path), 0, TRUTH if kind == "robot_localization" else {})
    assert len(opened) == 1
    for passes in (1, 2):
        assert sum(1 for _ in sequence.measurements()) > 10
        assert len(opened) == 1 + passes
