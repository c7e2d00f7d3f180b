"""Bad bags: each gives an ``InputError`` naming file, topic and time, or a counted skip;
the CLI prints one line and exits 2; results already written stay valid."""

from __future__ import annotations

import csv
import json
import shutil
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import StoragePlugin
from rosbags.rosbag2 import Writer as Writer2
from rosbags.typesys import Stores, get_typestore

from datasets.bags.pointcloud2 import encode_pointcloud2
from datasets.bags.read_report import ReadReport, ReadSettings
from datasets.bags.reader import read_stream
from datasets.bags.source import load_bag
from datasets.errors import InputError
from datasets.measurements import ImuSample, PointCloud, Sensor
from datasets.synthetic_lidar import write_lidar_bag
from workbench.cli import main

TYPESTORE = get_typestore(Stores.ROS2_HUMBLE)
T = TYPESTORE.types


def _header(t: float):
    ns = int(round(t * 1e9))
    return T["std_msgs/msg/Header"](
        stamp=T["builtin_interfaces/msg/Time"](sec=ns // 10**9, nanosec=ns % 10**9), frame_id="x"
    )


def _imu(t: float, value: float = 0.0):
    v = T["geometry_msgs/msg/Vector3"]
    return T["sensor_msgs/msg/Imu"](
        header=_header(t),
        orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        orientation_covariance=np.zeros(9),
        angular_velocity=v(x=value, y=0.0, z=0.0),
        angular_velocity_covariance=np.zeros(9),
        linear_acceleration=v(x=0.0, y=0.0, z=9.81),
        linear_acceleration_covariance=np.zeros(9),
    )


def _cloud(t: float, points: np.ndarray, names=("x", "y", "z")):
    records = np.zeros(len(points), dtype=[(name, "<f4") for name in names])
    for k, name in enumerate(names):
        records[name] = points[:, k]
    return encode_pointcloud2(TYPESTORE, _header(t), records, is_dense=False)


def write_ros2(path: Path, messages: list[tuple[str, str, float, object]]) -> Path:
    """A sqlite3 ROS 2 bag of ``(topic, type, log time, message)``."""
    with Writer2(path, version=9, storage_plugin=StoragePlugin.SQLITE3) as writer:
        connections = {}
        for topic, msgtype, log_t, message in messages:
            if topic not in connections:
                connections[topic] = writer.add_connection(topic, msgtype, typestore=TYPESTORE)
            writer.write(
                connections[topic],
                int(round(log_t * 1e9)),
                TYPESTORE.serialize_cdr(message, msgtype),
            )
    return path


def _box_points(rng: np.random.Generator) -> np.ndarray:
    """Points on the walls of a 10 m x 8 m room around the sensor (enough for a cloud)."""
    angles = rng.uniform(-np.pi, np.pi, 2000)
    ranges = np.minimum(
        5.0 / np.maximum(np.abs(np.cos(angles)), 1e-6),
        4.0 / np.maximum(np.abs(np.sin(angles)), 1e-6),
    )
    z = rng.uniform(-0.5, 1.0, angles.size)
    return np.column_stack([ranges * np.cos(angles), ranges * np.sin(angles), z])


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory) -> Path:
    return write_lidar_bag(
        tmp_path_factory.mktemp("synthetic") / "good",
        2,
        "ros1",
        {"duration_s": "0.5", "columns": "256"},
    )


@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap"])
def test_truncated_bag_names_the_file(tmp_path, kind):
    options = {"duration_s": "0.5", "columns": "256"}
    if kind == "ros1":
        good = write_lidar_bag(tmp_path / "whole", 3, "ros1", options)
        broken = tmp_path / "truncated.bag"
        broken.write_bytes(good.read_bytes()[: good.stat().st_size // 2])
    else:
        good = write_lidar_bag(tmp_path / "whole", 3, "ros2", {**options, "storage": kind})
        broken = tmp_path / "truncated"
        shutil.copytree(good, broken)
        storage = next(p for p in broken.iterdir() if p.suffix in (".db3", ".mcap"))
        storage.rename(broken / storage.name.replace("whole", "truncated"))
        (broken / "metadata.yaml").write_text(
            (broken / "metadata.yaml").read_text().replace("whole", "truncated")
        )
        storage = broken / storage.name.replace("whole", "truncated")
        storage.write_bytes(storage.read_bytes()[: storage.stat().st_size // 2])
    with pytest.raises(InputError, match=str(broken.name)):
        sequence = load_bag(str(broken), 0, {"kiss.max_num_threads": "1"})
        for _ in sequence.measurements():
            pass


def test_bag_without_pointcloud2(tmp_path):
    # a bag without lidar runs what its sensors allow (#37): an IMU alone is dead reckoning
    path = write_ros2(
        tmp_path / "imu_only",
        [("/imu", "sensor_msgs/msg/Imu", 1.0 + 0.01 * k, _imu(1.0 + 0.01 * k)) for k in range(5)],
    )
    sequence = load_bag(str(path), 0, {})
    assert sequence.sensors == {Sensor.IMU} and len(list(sequence.measurements())) == 5
    with pytest.raises(
        InputError,
        match=r"imu_only: no sensor an estimator can use: no PointCloud2 topic, no Imu topic "
        r"\(imu=false\) and no wheel odometry .*topics: /imu \[sensor_msgs/msg/Imu\]",
    ):
        load_bag(str(path), 0, {"imu": "false"})


def test_cloud_without_xyz_names_file_topic_time(tmp_path):
    rng = np.random.default_rng(0)
    path = write_ros2(
        tmp_path / "no_xyz",
        [
            (
                "/cloud",
                "sensor_msgs/msg/PointCloud2",
                2.5,
                _cloud(2.5, _box_points(rng)[:, :1], names=("intensity",)),
            )
        ],
    )
    with pytest.raises(
        InputError,
        match=r"no_xyz, topic /cloud, t=2\.500000000: PointCloud2 has no x/y/z field \(fields: intensity\)",
    ):
        list(read_stream(path, ["/cloud"], ReadSettings(), ReadReport()))


def test_empty_and_nan_clouds_and_backward_stamps_are_counted(tmp_path):
    rng = np.random.default_rng(1)
    nan_cloud = _box_points(rng)
    nan_cloud[:100] = np.nan
    messages = [
        ("/cloud", "sensor_msgs/msg/PointCloud2", 1.1, _cloud(1.0, _box_points(rng))),
        ("/cloud", "sensor_msgs/msg/PointCloud2", 1.2, _cloud(1.1, np.zeros((0, 3)))),  # empty
        (
            "/cloud",
            "sensor_msgs/msg/PointCloud2",
            1.3,
            _cloud(1.2, np.full((50, 3), np.nan)),
        ),  # only NaN
        ("/cloud", "sensor_msgs/msg/PointCloud2", 1.4, _cloud(1.3, nan_cloud)),  # some NaN
    ]
    imu_times = [1.00, 1.01, 1.02, 0.50, 1.03, 1.04]  # one stamp going backwards
    messages += [
        ("/imu", "sensor_msgs/msg/Imu", 1.0 + 0.01 * k, _imu(stamp))
        for k, stamp in enumerate(imu_times)
    ]
    messages.sort(key=lambda item: item[2])
    path = write_ros2(tmp_path / "odd", messages)
    # half the clouds skipped: by default an error naming the topic and the first skip
    with pytest.raises(
        InputError,
        match=r"2 of the 4 messages on /cloud skipped \(first: /cloud at t=1\.100000000: empty cloud.*max_skipped_fraction=0\.05",
    ):
        list(read_stream(path, ["/cloud", "/imu"], ReadSettings(), ReadReport()))
    report = ReadReport()
    accept = ReadSettings(max_skipped_fraction=1.0)
    items = list(read_stream(path, ["/cloud", "/imu"], accept, report))
    stamps = [m.t for _, m in items]
    assert stamps == sorted(stamps)
    clouds = [m for _, m in items if isinstance(m, PointCloud)]
    assert [round(c.t, 3) for c in clouds] == [1.0, 1.3] and len(clouds[1].points) == 1900
    assert sum(isinstance(m, ImuSample) for _, m in items) == 5
    assert report.nonfinite_points == 150
    assert report.skipped[("/cloud", "empty cloud (no finite points)")] == 2
    assert report.skipped[("/imu", "stamp went backwards (or repeated)")] == 1
    assert any(
        "/imu at t=0.500000000: stamp went backwards (or repeated) (previous 1.020000000)" in line
        for line in report.lines()
    )
    # the whole pipeline (KISS-ICP on the two usable clouds) runs and still reports the skips;
    # without the IMU, whose samples end at 1.04 s, the clouds' interval is the time base
    options = {"kiss.max_num_threads": "1", "max_skipped_fraction": "1", "imu": "false"}
    sequence = load_bag(str(path), 0, options)
    kinds = [type(m).__name__ for m in sequence.measurements()]
    assert kinds.count("PointCloud") == 2 and kinds.count("Odometry") == 1
    warned = sequence.all_warnings()
    assert any("skipped 2 x /cloud at t=1.100000000: empty cloud" in line for line in warned)
    # with it, the clouds after its last sample are trimmed, counted and said
    sequence = load_bag(str(path), 0, {**options, "imu": "true"})
    kinds = [type(m).__name__ for m in sequence.measurements()]
    assert kinds.count("PointCloud") == 1
    assert (
        "trimmed 3 x /cloud at t=1.100000000..1.300000000: after the end of the common time "
        "base t=1.040000000 (last stamp on /imu)" in sequence.all_warnings()
    )


def test_cli_error_is_one_line_and_earlier_results_stay_valid(tmp_path, synthetic, capsys):
    out = tmp_path / "out"
    assert (
        main(
            [
                "bag",
                str(synthetic),
                "--out",
                str(out),
                "--estimator",
                "dead-reckoning",
                "--no-plots",
                "--data",
                "kiss.max_num_threads=1",
            ]
        )
        == 0
    )
    before = (out / "frontend" / "metrics.json").read_text()
    table = (out / "table.md").read_text()
    assert "dead-reckoning" in table and "kiss-icp" in table
    capsys.readouterr()
    broken = tmp_path / "broken.bag"
    broken.write_bytes(synthetic.read_bytes()[:3000])
    assert main(["bag", str(broken), "--out", str(out), "--no-plots"]) == 2
    err = capsys.readouterr().err
    assert (
        err.startswith("error: ")
        and "broken.bag" in err
        and "Traceback" not in err
        and err.count("\n") == 1
    )
    assert (out / "frontend" / "metrics.json").read_text() == before
    json.loads(before)
    assert (out / "table.md").read_text() == table


@pytest.mark.study
def test_a_damaged_mcap_reading_fewer_clouds_than_its_index_is_loud(tmp_path) -> None:
    """64 KiB zeroed in the middle of a ROS 2 mcap bag: the reader skips what the damaged
    chunk held; fewer messages than the index lists is an error beyond the threshold, a
    counted warning line below it."""
    from pathlib import Path

    from datasets.bags.source import load_bag
    from datasets.synthetic_lidar import write_lidar_bag

    bag = Path(
        write_lidar_bag(tmp_path / "damaged", 2, "ros2", {"duration_s": "4", "storage": "mcap"})
    )
    chunk = next(bag.glob("*.mcap"))
    data = bytearray(chunk.read_bytes())
    middle = len(data) // 2
    data[middle : middle + 65536] = bytes(65536)
    chunk.write_bytes(bytes(data))
    with pytest.raises(InputError, match=r"read \d+ of the 40 messages its index lists on /points"):
        for _ in load_bag(str(bag), 0, {"kiss.max_num_threads": "1"}).measurements():
            pass
    accepted = load_bag(str(bag), 0, {"kiss.max_num_threads": "1", "max_missing_fraction": "0.5"})
    for _ in accepted.measurements():
        pass


def _odometry(t: float, x: float):
    vector = T["geometry_msgs/msg/Vector3"]
    return T["nav_msgs/msg/Odometry"](
        header=_header(t),
        child_frame_id="base",
        pose=T["geometry_msgs/msg/PoseWithCovariance"](
            pose=T["geometry_msgs/msg/Pose"](
                position=T["geometry_msgs/msg/Point"](x=x, y=0.0, z=0.0),
                orientation=T["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            ),
            covariance=np.zeros(36),
        ),
        twist=T["geometry_msgs/msg/TwistWithCovariance"](
            twist=T["geometry_msgs/msg/Twist"](
                linear=vector(x=0.0, y=0.0, z=0.0), angular=vector(x=0.0, y=0.0, z=0.0)
            ),
            covariance=np.zeros(36),
        ),
    )


def _room_bag(path: Path, truth_x: float, imu_value: float = 0.0) -> Path:
    """Eight clouds of a still room, 100 Hz IMU, an Odometry topic /odom at 10 Hz."""
    rng = np.random.default_rng(4)
    messages = []
    for k in range(8):
        t = 1.0 + 0.1 * k
        messages.append(("/cloud", "sensor_msgs/msg/PointCloud2", t, _cloud(t, _box_points(rng))))
        messages.append(("/odom", "nav_msgs/msg/Odometry", t, _odometry(t, truth_x)))
    messages += [
        ("/imu", "sensor_msgs/msg/Imu", 1.0 + 0.01 * k, _imu(1.0 + 0.01 * k, imu_value))
        for k in range(80)
    ]
    messages.sort(key=lambda item: item[2])
    return write_ros2(path, messages)


def test_a_pose_topic_is_truth_only_when_named(tmp_path: Path, capsys) -> None:
    bag = _room_bag(tmp_path / "room", 0.0)
    sequence = load_bag(str(bag), 0, {"kiss.max_num_threads": "1"})
    assert sequence.ground_truth is None and sequence.reference_source is None
    assert any("/odom not taken as truth unless named" in w for w in sequence.all_warnings())
    named = load_bag(str(bag), 0, {"kiss.max_num_threads": "1", "ground_truth_topic": "/odom"})
    assert len(named.ground_truth.pose) == 8 and named.reference_source == "topic /odom"
    out = tmp_path / "out"
    argv = ["bag", str(bag), "--out", str(out), "--estimator", "dead-reckoning", "--no-plots"]
    assert main(argv) == 0
    captured = capsys.readouterr()
    assert "warning: bag:" in captured.err and "/odom not taken as truth" in captured.err
    rows = {row["estimator"]: row for row in csv.DictReader((out / "table.csv").open())}
    # the estimator asked for, and the lidar front end's own row (issue 37's reference)
    assert sorted(rows) == ["dead-reckoning", "front end (kiss-icp)"], sorted(rows)
    assert rows["dead-reckoning"]["ate_rmse_m"] == ""


def test_non_finite_truth_or_imu_is_an_error_not_a_quiet_run(tmp_path: Path, capsys) -> None:
    nan_truth = _room_bag(tmp_path / "nan_truth", np.nan)
    with pytest.raises(InputError, match=r"8 of the 8 messages on /odom skipped .*non-finite pose"):
        load_bag(str(nan_truth), 0, {"ground_truth_topic": "/odom"})
    nan_imu = _room_bag(tmp_path / "nan_imu", 0.0, imu_value=np.nan)
    out = tmp_path / "out"
    assert main(["bag", str(nan_imu), "--out", str(out), "--no-plots"]) == 2
    error = capsys.readouterr().err
    assert "80 of the 80 messages on /imu skipped" in error and "non-finite IMU sample" in error


def test_bag_exits_non_zero_when_no_estimator_ran(tmp_path: Path, capsys) -> None:
    bag = _room_bag(tmp_path / "room", 0.0)
    out = tmp_path / "out"
    # aghili told to use surveyed anchors, which a bag does not have (its default,
    # anchor_source=auto, takes them from first observations and runs)
    argv = ["bag", str(bag), "--out", str(out), "--estimator", "aghili", "--no-plots"]
    argv += ["--set", "anchor_source=known"]
    assert main(argv) == 3
    captured = capsys.readouterr()
    assert "error: no estimator ran on this bag" in captured.err
    assert "anchors=3 known landmarks requested" in (out / "table.md").read_text()
