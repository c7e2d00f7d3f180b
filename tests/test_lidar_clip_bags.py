"""Every lidar-only estimator on the real KITTI HDL-64 clip (``../shared/data/kitti-hdl64-clip``:
30 binary PCD scans at 10 Hz, no per-point times, no IMU, no truth) read three ways: as
``scans:FOLDER``, and from a ROS 1 bag and a ROS 2 bag (sqlite3) made of the same scans as
sensor_msgs/PointCloud2 (float32 x, y, z; no per-point time field). The three sources must
give the same KISS-ICP trajectory and corners, the bags must not invent a ground truth, and
every estimator must follow KISS-ICP's trajectory (dead reckoning composes its increments)
closely on each.

Measured on the current code (identical on all three sources; max position deviation from
KISS-ICP [m], share of KISS-ICP's path length [%], max yaw deviation [deg]), with the clouds
read as the clip's readme once said (motion-compensated, ``point_times=field``) and as what
they are (KITTI raw's uncompensated sweeps), which the defaults now decide from the first ten
scans (``point_times=auto``: raw, clockwise from 181.7 deg, timed by azimuth;
``datasets.lidar.sweep_timing``, ``benchmarks/kitti_clip_sweep_seam.py``):

                         point_times=field           defaults (timed by azimuth)
    estimator            max dev  % path  max yaw    max dev  % path  max yaw
    dead-reckoning         0.000    0.00    0.000      0.000    0.00    0.000  (the reference)
    ekf-slam               0.057    0.31    0.721      0.058    0.31    0.187
    sensor-based           0.101    0.54    0.856      0.139    0.74    0.151
    smoother-isam2         0.057    0.31    0.715      0.058    0.31    0.181
    smoother-fixed-lag     0.057    0.31    0.715      0.058    0.31    0.181
    smoother-batch         0.050    0.27    0.715      0.057    0.30    0.129  (smoothed)

KISS-ICP's path over the clip is about 18.5 m. (The same figures as
benchmarks/bench_lidar_clip.py prints for ``scans:``.)

The issue asks for yaw within 0.5 deg. Read as compensated, the corners disagree with
KISS-ICP's heading (-0.41 +- 0.10 deg/s; the run warns, naming the option) and the
estimators, following them, end 0.72-0.86 deg off, so yaw is held to 1.0 deg there; read as
uncompensated sweeps (the defaults) every estimator is within 0.19 deg, held to 0.5.
Position is held to 1 % of the path either way.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from datasets.bags.pointcloud2 import encode_pointcloud2
from datasets.measurements import LandmarkScan, Odometry, Sensor
from datasets.rotations import matrix_from_quat_wxyz, so3_log
from tests.test_lidar_only import CLIP, LIDAR_ONLY

pytestmark = [
    pytest.mark.skipif(
        not CLIP.is_dir(), reason="../shared/data/kitti-hdl64-clip (real data) absent"
    ),
    # a study: the second tier (`pytest -m study`, run by .ci/run after the default tier)
    pytest.mark.study,
]

EPOCH_NS = 1_317_000_000 * 1_000_000_000  # late September 2011, when KITTI was recorded
PERIOD_NS = 100_000_000  # 10 Hz
TOPIC = "/velodyne_points"
SOURCES = ("scans", "ros1", "ros2")
POSITION_SHARE_PERCENT = 1.0
YAW_DEG = 1.0  # read as compensated: the estimators sit at 0.72-0.86 deg (module docstring)
AZIMUTH_YAW_DEG = 0.5  # the bound, read as uncompensated sweeps (the defaults)


def _pointcloud2(typestore, ros1: bool, points: np.ndarray, stamp_ns: int):
    """An unorganized PointCloud2 of float32 x, y, z (ROS 1: plus a zero intensity, 16-byte
    points, as a Velodyne driver writes; ROS 2: 12-byte points), no per-point time."""
    types = typestore.types
    names = ("x", "y", "z", "intensity") if ros1 else ("x", "y", "z")
    records = np.zeros(len(points), dtype=[(name, "<f4") for name in names])
    for k, axis in enumerate("xyz"):
        records[axis] = points[:, k]
    stamp = types["builtin_interfaces/msg/Time"](
        sec=stamp_ns // 1_000_000_000, nanosec=stamp_ns % 1_000_000_000
    )
    header_type = types["std_msgs/msg/Header"]
    header = (
        header_type(seq=0, stamp=stamp, frame_id="velodyne")
        if ros1
        else header_type(stamp=stamp, frame_id="velodyne")
    )
    return encode_pointcloud2(typestore, header, records, is_dense=True)


def _write_bag(out: Path, ros1: bool, scans: list[np.ndarray]) -> Path:
    from rosbags.typesys import Stores, get_typestore

    typestore = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if ros1:
        from rosbags.rosbag1 import Writer

        writer = Writer(out)
        serialize = typestore.serialize_ros1
    else:
        from rosbags.rosbag2 import Writer

        writer = Writer(out, version=9)  # sqlite3, the default storage
        serialize = typestore.serialize_cdr
    with writer:
        connection = writer.add_connection(
            TOPIC, "sensor_msgs/msg/PointCloud2", typestore=typestore
        )
        for index, points in enumerate(scans):
            stamp_ns = EPOCH_NS + index * PERIOD_NS
            message = _pointcloud2(typestore, ros1, points, stamp_ns)
            writer.write(connection, stamp_ns, serialize(message, message.__msgtype__))
    return out


@pytest.fixture(scope="module")
def sources(tmp_path_factory) -> dict[str, str]:
    """Dataset names of the three sources, bags written once."""
    from datasets.scan_folder import read_scan

    files = sorted(CLIP.glob("*.pcd"))
    assert len(files) == 30
    scans = [read_scan(path, 0.1 * index).points for index, path in enumerate(files)]
    folder = tmp_path_factory.mktemp("clip_bags")
    return {
        "scans": f"scans:{CLIP}",
        "ros1": f"bag:{_write_bag(folder / 'clip.bag', True, scans)}",
        "ros2": f"bag:{_write_bag(folder / 'clip_ros2', False, scans)}",
    }


def _yaw_deg(reference_quat: np.ndarray, quat: np.ndarray) -> float:
    """|z component| of the rotation vector from ``reference_quat`` to ``quat`` [deg]."""
    relative = matrix_from_quat_wxyz(reference_quat).T @ matrix_from_quat_wxyz(quat)
    return abs(float(np.rad2deg(so3_log(relative)[2])))


def _deviation(reference, pose) -> tuple[float, float, float]:
    """(largest position deviation [m], its share of the reference's path length [%],
    largest yaw deviation [deg]) of ``pose`` from ``reference``, paired by time (as
    benchmarks/bench_lidar_clip.py)."""
    index = np.clip(np.searchsorted(reference.t, pose.t - 1e-6), 0, len(reference.t) - 1)
    assert np.all(np.abs(reference.t[index] - pose.t) < 1e-6)
    position = np.linalg.norm(pose.positions - reference.positions[index], axis=1)
    path = float(np.sum(np.linalg.norm(np.diff(reference.positions, axis=0), axis=1)))
    yaw = [_yaw_deg(reference.rotations[i], q) for q, i in zip(pose.rotations, index, strict=True)]
    return float(position.max()), 100.0 * float(position.max()) / path, float(max(yaw))


def _run_sources(sources: dict[str, str], options: dict[str, str]) -> dict[str, dict]:
    """Per source: the sequence, its stream's odometry and corner counts, and each
    estimator's pose history."""
    from workbench.registry import load_dataset
    from workbench.runner import RunRequest, execute

    results = {}
    for source, name in sources.items():
        sequence = load_dataset(name, 0, options)
        stream = list(sequence.measurements())
        odometry = [m for m in stream if isinstance(m, Odometry)]
        corners = [m for m in stream if isinstance(m, LandmarkScan)]
        poses = {}
        for estimator in LIDAR_ONLY:
            estimate = execute(RunRequest(estimator, name), sequence=sequence).estimate
            history = estimate.causal if estimate.causal.pose else estimate.smoothed
            poses[estimator] = history.pose
        results[source] = {
            "sequence": sequence,
            "odometry": odometry,
            "corner_scans": len(corners),
            "first_corner_t": corners[0].t,
            "corners": sum(len(scan.points) for scan in corners),
            "poses": poses,
        }
    return results


@pytest.fixture(scope="module")
def runs(sources) -> dict[str, dict]:
    """Every source read as the clip's readme once said (motion-compensated clouds,
    ``point_times=field``: no per-point times)."""
    return _run_sources(sources, {"point_times": "field"})


@pytest.fixture(scope="module")
def azimuth_runs(sources) -> dict[str, dict]:
    """Every source read with the defaults: as what the clip is, KITTI raw's uncompensated
    sweeps, which ``point_times=auto`` decides from the first scans and times by azimuth
    (``datasets.lidar.sweep_timing``; ``benchmarks/kitti_clip_sweep_seam.py``)."""
    return _run_sources(sources, {})


@pytest.mark.parametrize("source", SOURCES)
def test_every_estimator_follows_kiss_icp(runs, source) -> None:
    run = runs[source]
    reference = run["poses"]["dead-reckoning"]
    # dead reckoning composes KISS-ICP's 29 increments from the start: one pose per scan
    assert len(run["odometry"]) == 29
    assert len(reference) == 30
    start, end = reference.t[0], reference.t[-1]
    assert end - start == pytest.approx(2.9, abs=1e-6)
    figures = {}
    for estimator, pose in run["poses"].items():
        # covers the clip: a pose for every corner scan at least (the sensor-based filter
        # and the smoothers step on corner scans; the first arrives with the third cloud,
        # where corner confirmation first succeeds), from the first corner scan to the end
        assert pose is not None and len(pose) >= run["corner_scans"], (source, estimator)
        assert pose.t[0] <= run["first_corner_t"] + 1e-6, (source, estimator, pose.t[0])
        assert pose.t[-1] >= end - 1e-6, (source, estimator, pose.t[-1])
        assert np.all(np.isfinite(pose.positions)), (source, estimator)
        figures[estimator] = _deviation(reference, pose)
    print(source, {k: tuple(round(v, 3) for v in f) for k, f in figures.items()})
    for estimator, (deviation, share, yaw) in figures.items():
        assert share < POSITION_SHARE_PERCENT, (source, estimator, deviation, share)
        assert yaw < YAW_DEG, (source, estimator, yaw)


def test_sources_agree_on_the_front_end(runs) -> None:
    reference = runs["scans"]["poses"]["dead-reckoning"]
    for source in ("ros1", "ros2"):
        pose = runs[source]["poses"]["dead-reckoning"]
        assert len(pose) == len(reference)
        # bag stamps carry the epoch: compare by frame index, relative to the first frame
        np.testing.assert_allclose(pose.t - pose.t[0], reference.t - reference.t[0], atol=1e-6)
        # the bag's header stamps are the times, epoch included (not bag-relative)
        assert pose.t[0] == pytest.approx(EPOCH_NS * 1e-9, abs=1e-6)
        np.testing.assert_allclose(
            pose.positions - pose.positions[0],
            reference.positions - reference.positions[0],
            atol=1e-6,
        )
        # both start at the identity: the rotations are already relative to the first frame
        dots = np.abs(np.sum(pose.rotations * reference.rotations, axis=1))
        np.testing.assert_allclose(dots, 1.0, atol=1e-12)
        assert runs[source]["corners"] == runs["scans"]["corners"], source
        assert runs[source]["corner_scans"] == runs["scans"]["corner_scans"], source
        counts = ("corners_detected", "corners_confirmed", "reobservation_pairs")
        ours, theirs = (
            runs[key]["sequence"].pass_report.figures["corner_reobservation"]
            for key in (source, "scans")
        )
        assert {k: ours[k] for k in counts} == {k: theirs[k] for k in counts}, source


@pytest.mark.parametrize("source", ("ros1", "ros2"))
def test_bags_have_no_invented_truth(runs, source) -> None:
    sequence = runs[source]["sequence"]
    # a bag of clouds alone: no IMU, no GPS, and no truth made up by the loader
    assert sequence.sensors == {Sensor.POINT_CLOUD, Sensor.ODOMETRY, Sensor.LANDMARKS}
    assert sequence.topics.lidar == TOPIC
    truth = sequence.ground_truth
    assert truth is None or truth.pose is None or len(truth.pose) == 0


@pytest.mark.parametrize("source", SOURCES)
def test_read_as_compensated_every_source_warns_naming_the_option(runs, source) -> None:
    """The clouds carry no per-point times and their corners disagree with KISS-ICP's
    heading beyond three standard errors: the folder and both bags say so (printed, and in
    every run's metrics.json)."""
    warnings = runs[source]["sequence"].all_warnings()
    heading = [line for line in warnings if "disagree with KISS-ICP's heading" in line]
    assert len(heading) == 1 and "point_times=azimuth" in heading[0], warnings


@pytest.mark.parametrize("source", SOURCES)
def test_corner_reobservation_nis_is_consistent(runs, source) -> None:
    summary = runs[source]["sequence"].pass_report.figures["corner_reobservation"]
    nis = summary["reobservation_nis_per_dof"]
    print(source, "corner re-observation NIS/dof", nis)
    assert nis is not None and 0.7 <= nis <= 1.5, (source, summary)


def test_sources_give_every_estimator_the_same_result(runs) -> None:
    """Each estimator's poses agree across the sources by frame index. The bags' stamps are
    epoch seconds (1.317e9 s), which float64 resolves to 2.4e-7 s only, so the scans' time
    steps and the bags' differ by up to 1.9e-7 s. The sensor-based filter integrates its
    velocity state over each step and moves by 1e-6 m over the clip. (It moved 0.21 mm
    while its sub-step count tested 1e-9 of a step: 0.1 s gaps stamped two ways then
    propagated in 2 or 3 steps of its 0.05 s limit.) The others do not use the step lengths
    and agree to 1e-14 m."""
    tolerance_m = {"sensor-based": 1e-5}
    for estimator in LIDAR_ONLY:
        reference = runs["scans"]["poses"][estimator]
        for source in ("ros1", "ros2"):
            pose = runs[source]["poses"][estimator]
            assert len(pose) == len(reference), (source, estimator)
            np.testing.assert_allclose(pose.t - pose.t[0], reference.t - reference.t[0], atol=1e-6)
            np.testing.assert_allclose(
                pose.positions,
                reference.positions,
                atol=tolerance_m.get(estimator, 1e-6),
                err_msg=f"{source} {estimator}",
            )
            dots = np.abs(np.sum(pose.rotations * reference.rotations, axis=1))
            np.testing.assert_allclose(dots, 1.0, atol=1e-9, err_msg=f"{source} {estimator}")


@pytest.mark.parametrize("source", SOURCES)
def test_read_as_uncompensated_sweeps_every_estimator_meets_the_bounds(
    azimuth_runs, source
) -> None:
    """With the clip read as what it is (raw sweeps timed by azimuth, which the defaults
    decide), every estimator stays within 1 % of KISS-ICP's path and 0.5 deg of its yaw, on
    the folder and on both bags, and the corners' re-observation NIS per dof is within
    0.7-1.5; the timing decision is a note, not a warning."""
    run = azimuth_runs[source]
    reference = run["poses"]["dead-reckoning"]
    figures = {name: _deviation(reference, pose) for name, pose in run["poses"].items()}
    print(source, {k: tuple(round(v, 3) for v in f) for k, f in figures.items()})
    for estimator, (deviation, share, yaw) in figures.items():
        assert share < POSITION_SHARE_PERCENT, (source, estimator, deviation, share)
        assert yaw < AZIMUTH_YAW_DEG, (source, estimator, yaw)
    nis = run["sequence"].pass_report.figures["corner_reobservation"]["reobservation_nis_per_dof"]
    assert nis is not None and 0.7 <= nis <= 1.5, (source, nis)
    assert run["sequence"].all_warnings() == [], source
