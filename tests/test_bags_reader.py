"""Reading ROS 1 / ROS 2 (sqlite3, mcap) bags written with rosbags' own Writer."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from rosbags.typesys import Stores, get_typestore

from datasets.bags.bag_file import open_bag
from datasets.bags.convert import first_gps_origin
from datasets.bags.gps import geodetic_to_enu
from datasets.bags.ground_truth import read_ground_truth
from datasets.bags.pointcloud2 import decode_pointcloud2, encode_pointcloud2
from datasets.bags.read_report import ReadReport, ReadSettings
from datasets.bags.reader import read_stream
from datasets.bags.topics import discover_topics, topic_types
from datasets.errors import InputError
from datasets.measurements import GpsFix, ImuSample, PointCloud
from datasets.synthetic_lidar import write_lidar_bag
from datasets.synthetic_lidar.writer import enu_to_geodetic

SMALL = {"duration_s": "0.5", "columns": "256", "gps_rate_hz": "4"}


@pytest.fixture(scope="module")
def bags(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("bags")
    return {
        "ros1": write_lidar_bag(root / "small", 1, "ros1", SMALL),
        "sqlite3": write_lidar_bag(root / "small_sqlite", 1, "ros2", SMALL),
        "mcap": write_lidar_bag(root / "small_mcap", 1, "ros2", {**SMALL, "storage": "mcap"}),
    }


@pytest.mark.parametrize("kind", ["ros1", "sqlite3", "mcap"])
def test_stream_is_stamp_ordered_and_complete(bags, kind):
    path = bags[kind]
    with open_bag(path) as reader:
        topics = discover_topics(path, topic_types(reader), ground_truth="/ground_truth")
        origin = first_gps_origin(reader, path, topics.gps)
        unnamed = discover_topics(path, topic_types(reader))
    assert (topics.lidar, topics.imu, topics.ground_truth, topics.gps) == (
        "/points",
        "/imu",
        "/ground_truth",
        "/gps",
    )
    # a pose topic is truth only when named
    assert unnamed.ground_truth is None and unnamed.unnamed_truth == ("/ground_truth",)
    report = ReadReport()
    items = list(
        read_stream(
            path, [topics.lidar, topics.imu, topics.gps], ReadSettings(gps_origin=origin), report
        )
    )
    stamps = np.array([m.t for _, m in items])
    assert np.all(np.diff(stamps) >= 0)
    kinds = [type(m) for _, m in items]
    assert (
        kinds.count(PointCloud) == 5 and kinds.count(ImuSample) == 100 and kinds.count(GpsFix) == 2
    )
    assert not report.skipped
    cloud = next(m for _, m in items if isinstance(m, PointCloud))
    # ros1 carries float32 seconds in "time", ros2 uint32 nanoseconds in "t": both -> seconds
    assert (
        cloud.point_times is not None
        and 0.0 <= cloud.point_times.min()
        and cloud.point_times.max() < 0.1
    )
    assert cloud.point_times.max() > 0.09
    assert (
        np.all(np.isfinite(cloud.points)) and report.nonfinite_points > 0
    )  # organized cloud with misses
    imu = next(m for _, m in items if isinstance(m, ImuSample))
    assert imu.accel[2] == pytest.approx(9.81, abs=0.05)
    t, positions, quats = read_ground_truth(path, topics.ground_truth, ReadReport())
    assert (
        len(t) == 26
        and np.allclose(positions[0], [15.0, 2.5, 1.0])
        and np.allclose(quats[0], [1, 0, 0, 0])
    )
    fixes = [m for _, m in items if isinstance(m, GpsFix)]
    # the GPS origin is the first fix, the truth's first position: ENU differences match the truth
    expected = (
        np.array([np.interp(fixes[1].t, t, positions[:, k]) for k in range(3)]) - positions[0]
    )
    assert np.allclose(fixes[1].position, expected, atol=1e-3)


def test_geodetic_round_trip():
    origin = (48.137, 11.575, 520.0)
    enu = np.array([[0.0, 0.0, 0.0], [1000.0, -2000.0, 30.0], [-5.0, 7.0, -1.0]])
    assert np.allclose(geodetic_to_enu(enu_to_geodetic(enu, origin), origin), enu, atol=1e-6)


def _cloud(
    typestore, fields, records: np.ndarray, height=1, width=None, row_padding=0, bigendian=False
):
    types = typestore.types
    width = width if width is not None else records.size // height
    data = records.tobytes()
    row_bytes = records.dtype.itemsize * width
    if row_padding:
        rows = [
            data[r * row_bytes : (r + 1) * row_bytes] + b"\0" * row_padding for r in range(height)
        ]
        data = b"".join(rows)
    header = types["std_msgs/msg/Header"](
        stamp=types["builtin_interfaces/msg/Time"](sec=100, nanosec=0), frame_id="lidar"
    )
    return types["sensor_msgs/msg/PointCloud2"](
        header=header,
        height=height,
        width=width,
        fields=[
            types["sensor_msgs/msg/PointField"](name=n, offset=o, datatype=d, count=1)
            for n, o, d in fields
        ],
        is_bigendian=bigendian,
        point_step=records.dtype.itemsize,
        row_step=row_bytes + row_padding,
        data=np.frombuffer(data, dtype=np.uint8),
        is_dense=False,
    )


def test_pointcloud2_layouts():
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    # float64 xyz, big-endian, absolute float64 "timestamp" seconds, padded rows, organized with NaN
    dtype = np.dtype(
        {
            "names": ["x", "y", "z", "timestamp"],
            "formats": [">f8", ">f8", ">f8", ">f8"],
            "offsets": [0, 8, 16, 28],
            "itemsize": 40,
        }
    )
    records = np.zeros(6, dtype=dtype)
    records["x"] = [1, 2, np.nan, 4, 5, 6]
    records["y"], records["z"] = 0.5, -0.25
    records["timestamp"] = 100.0 + np.linspace(0, 0.05, 6)
    message = _cloud(
        typestore,
        [("x", 0, 8), ("y", 8, 8), ("z", 16, 8), ("timestamp", 28, 8)],
        records,
        height=2,
        row_padding=7,
        bigendian=True,
    )
    cloud = decode_pointcloud2(message, 100.0, "test")
    assert cloud.nonfinite == 1 and cloud.time_field == "timestamp"
    assert np.allclose(cloud.points[:, 0], [1, 2, 4, 5, 6]) and np.allclose(
        cloud.points[:, 1:], [0.5, -0.25]
    )
    assert np.allclose(cloud.point_times, np.linspace(0, 0.05, 6)[[0, 1, 3, 4, 5]], atol=1e-9)
    # Livox-style uint32 nanoseconds "offset_time"
    dtype = np.dtype(
        {
            "names": ["x", "y", "z", "offset_time"],
            "formats": ["<f4", "<f4", "<f4", "<u4"],
            "offsets": [0, 4, 8, 12],
            "itemsize": 18,
        }
    )
    records = np.zeros(3, dtype=dtype)
    records["x"], records["offset_time"] = [1, 2, 3], [0, 50_000_000, 99_000_000]
    cloud = decode_pointcloud2(
        _cloud(typestore, [("x", 0, 7), ("y", 4, 7), ("z", 8, 7), ("offset_time", 12, 6)], records),
        100.0,
        "test",
    )
    assert np.allclose(cloud.point_times, [0.0, 0.05, 0.099])


def test_pointcloud2_without_xyz_names_where():
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    records = np.zeros(3, dtype=[("intensity", "<f4")])
    message = _cloud(typestore, [("intensity", 0, 7)], records)
    with pytest.raises(
        InputError, match=r"bag\.db3, topic /points, t=100.*no x/y/z field \(fields: intensity\)"
    ):
        decode_pointcloud2(message, 100.0, "bag.db3, topic /points, t=100.000000000")


def test_pointcloud2_short_data_is_an_error():
    typestore = get_typestore(Stores.ROS2_HUMBLE)
    records = np.zeros(4, dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4")])
    message = _cloud(typestore, [("x", 0, 7), ("y", 4, 7), ("z", 8, 7)], records)
    short = type(message)(
        **{
            **{
                k: getattr(message, k)
                for k in (
                    "header",
                    "height",
                    "width",
                    "fields",
                    "is_bigendian",
                    "point_step",
                    "row_step",
                    "is_dense",
                )
            },
            "data": message.data[:20],
        }
    )
    with pytest.raises(InputError, match="20 bytes"):
        decode_pointcloud2(short, 100.0, "here")


def test_topic_discovery_lists_candidates():
    types = {
        "/a/points": "sensor_msgs/msg/PointCloud2",
        "/b/points": "sensor_msgs/msg/PointCloud2",
        "/imu": "sensor_msgs/msg/Imu",
    }
    with pytest.raises(
        InputError,
        match=r"several lidar topics: /a/points \[sensor_msgs/msg/PointCloud2\], /b/points .*"
        r"choose one with --data lidar_topic=TOPIC \(workbench bag: --lidar-topic TOPIC\)",
    ):
        discover_topics(Path("x.bag"), types)
    assert discover_topics(Path("x.bag"), types, lidar="/b/points").lidar == "/b/points"
    # no lidar is no error here: a bag of other sensors runs what they allow (#37)
    assert discover_topics(Path("x.bag"), {"/imu": "sensor_msgs/msg/Imu"}).lidar is None
    with pytest.raises(InputError, match="is sensor_msgs/msg/Imu, not sensor_msgs/msg/PointCloud2"):
        discover_topics(Path("x.bag"), types, lidar="/imu")
    truth = {
        **types,
        "/odom": "nav_msgs/msg/Odometry",
        "/ground_truth": "geometry_msgs/msg/PoseStamped",
    }
    found = discover_topics(Path("x.bag"), truth, lidar="/a/points")
    assert found.ground_truth is None and found.unnamed_truth == ("/ground_truth", "/odom")
    named = discover_topics(Path("x.bag"), truth, lidar="/a/points", ground_truth="/odom")
    assert named.ground_truth == "/odom" and named.unnamed_truth == ()


def test_lidar_to_body_extrinsic(bags):
    from datasets.bags.source import load_bag

    options = {"odometry": "false", "corners": "false"}
    plain = next(
        m
        for m in load_bag(str(bags["ros1"]), 0, options).measurements()
        if isinstance(m, PointCloud)
    )
    # lidar 0.2 m ahead of and 0.1 m above the IMU, yawed by 90 degrees
    half = float(np.sqrt(0.5))
    moved = next(
        m
        for m in load_bag(
            str(bags["ros1"]),
            0,
            {**options, "lidar_to_body": "[0.2, 0, 0.1, %r, 0, 0, %r]" % (half, half)},
        ).measurements()
        if isinstance(m, PointCloud)
    )
    expected = np.column_stack(
        [-plain.points[:, 1] + 0.2, plain.points[:, 0], plain.points[:, 2] + 0.1]
    )
    assert np.allclose(moved.points, expected, atol=1e-9)
    with pytest.raises(InputError, match="zero length"):
        load_bag(str(bags["ros1"]), 0, {"lidar_to_body": "[0, 0, 0, 0, 0, 0, 0]"})


def test_encoded_pointcloud2_decodes_to_its_records():
    """``encode_pointcloud2`` (the writers' side) round-trips through the decoder: an
    organized, padded ROS 1 cloud with NaN misses and nanosecond ``t``."""
    typestore = get_typestore(Stores.ROS1_NOETIC)
    dtype = np.dtype(
        {
            "names": ["x", "y", "z", "t"],
            "formats": ["<f4"] * 3 + ["<u4"],
            "offsets": [0, 4, 8, 16],
            "itemsize": 24,
        }
    )
    records = np.zeros((2, 3), dtype=dtype)
    rng = np.random.default_rng(0)
    xyz = rng.normal(size=(2, 3, 3)).astype(np.float32)
    records["x"], records["y"], records["z"] = xyz[..., 0], xyz[..., 1], xyz[..., 2]
    records["t"] = [[0, 50_000_000, 99_000_000]] * 2
    records["x"][1, 2] = np.nan
    header = typestore.types["std_msgs/msg/Header"](
        seq=0,
        stamp=typestore.types["builtin_interfaces/msg/Time"](sec=100, nanosec=0),
        frame_id="l",
    )
    message = encode_pointcloud2(typestore, header, records, is_dense=False)
    assert (message.height, message.width, message.point_step, message.row_step) == (2, 3, 24, 72)
    decoded = decode_pointcloud2(message, 100.0, "test")
    assert decoded.nonfinite == 1 and decoded.time_field == "t"
    assert np.array_equal(decoded.points, xyz.reshape(-1, 3)[:5].astype(float))
    assert np.allclose(decoded.point_times, [0.0, 0.05, 0.099, 0.0, 0.05])
    with pytest.raises(ValueError, match="field 'x'"):
        encode_pointcloud2(typestore, header, np.zeros(2, dtype=[("x", ">f4")]), is_dense=True)
