"""One time base for bags (issue 15): an IMU that starts before the lidar and a wheel-odometry
topic. Every estimator runs, the wheel odometry is never taken as truth, and every stream is
trimmed to the common interval (the latest first stamp to the earliest last stamp of the
lidar, the IMU and, when named, the truth topic), loudly.

Before the time base, naming the truth topic of such a bag put the initial state at the
truth's first stamp while the IMU began 50 ms earlier, and dead-reckoning, sensor-based and
ekf-slam failed with ``time goes backwards at ImuSample t=1699999999.950000 s (previous
1700000000.000000 s)``.

``aghili`` on a bag (no surveyed landmarks) runs with its defaults: ``anchor_source=auto``
takes its anchors from their first observation and says so in the run's notes (it was
refused with ``anchor_source=known``, "the dataset offers 0").
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest

from datasets.bags.bag_file import open_bag
from datasets.bags.ground_truth import read_ground_truth
from datasets.bags.read_report import ReadReport, ReadSettings
from datasets.bags.reader import read_stream
from datasets.bags.time_base import common_time_base
from datasets.bags.topics import topic_types
from datasets.errors import InputError
from datasets.measurements import Odometry, PointCloud
from datasets.synthetic_lidar import write_lidar_bag
from datasets.synthetic_lidar.writer import EPOCH_S, WHEEL_SCALE_ERROR, WHEEL_YAW_DRIFT_RAD_S
from workbench.registry import ESTIMATORS, load_dataset
from workbench.runner import RunRequest, execute, is_compatible

SHORT = {"duration_s": "3", "columns": "512"}
LEADING = {**SHORT, "imu_lead_s": "0.05", "wheel_odometry_rate_hz": "20"}
DATA = {"kiss.max_num_threads": "1"}
NAMED = {**DATA, "ground_truth_topic": "/ground_truth"}
REFUSED: dict[str, str] = {}  # every estimator runs on these bags with its defaults


@pytest.fixture(scope="module")
def bags(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("time_base")
    return {
        fmt: write_lidar_bag(root / f"leading_{fmt}", 5, fmt, LEADING) for fmt in ("ros2", "ros1")
    }


def _messages(path: Path, topic: str) -> list:
    """Every measurement of ``topic`` as the bag has it (no time base)."""
    return [m for _, m in read_stream(Path(path), [topic], ReadSettings(), ReadReport())]


def _stamps(path: Path, topic: str) -> np.ndarray:
    return np.array([m.t for m in _messages(path, topic)])


def test_writer_options_lead_the_imu_and_add_drifting_wheel_odometry(tmp_path, bags) -> None:
    small = {"duration_s": "0.5", "columns": "64"}
    plain = write_lidar_bag(tmp_path / "plain", 5, "ros2", small)
    lead = write_lidar_bag(tmp_path / "lead", 5, "ros2", {**small, "imu_lead_s": "0.05"})
    with open_bag(plain) as reader:
        assert "/wheel/odometry" not in topic_types(reader)
    imu_plain, imu_lead = _stamps(plain, "/imu") - EPOCH_S, _stamps(lead, "/imu") - EPOCH_S
    assert imu_plain[0] == pytest.approx(0.0, abs=1e-6)
    assert len(imu_lead) == len(imu_plain) + 10 and imu_lead[0] == pytest.approx(-0.05, abs=1e-6)
    # lidar and truth unchanged; the IMU samples from the first sweep on too (own noise stream)
    clouds = [_messages(p, "/points") for p in (plain, lead)]
    assert [c.t for c in clouds[0]] == [c.t for c in clouds[1]]
    assert all(np.array_equal(a.points, b.points) for a, b in zip(*clouds))
    imus = [_messages(p, "/imu") for p in (plain, lead)]
    assert all(np.array_equal(a.gyro, b.gyro) for a, b in zip(imus[0], imus[1][10:]))
    np.testing.assert_array_equal(
        read_ground_truth(plain, "/ground_truth", ReadReport())[1],
        read_ground_truth(lead, "/ground_truth", ReadReport())[1],
    )
    # the wheel odometry: 2 % long on distance, heading drifting, clearly not the truth
    bag = bags["ros2"]
    with open_bag(bag) as reader:
        assert topic_types(reader)["/wheel/odometry"] == "nav_msgs/msg/Odometry"
        connection = next(c for c in reader.connections if c.topic == "/wheel/odometry")
        _, _, raw = next(reader.messages(connections=[connection]))
        assert reader.deserialize(raw, connection.msgtype).child_frame_id == "base_link"
    t_wheel, p_wheel, q_wheel = read_ground_truth(bag, "/wheel/odometry", ReadReport())
    t_true, p_true, q_true = read_ground_truth(bag, "/ground_truth", ReadReport())
    assert len(t_wheel) == 60
    inside = np.searchsorted(t_true, t_wheel)
    assert np.allclose(t_true[inside], t_wheel)
    p_true, q_true = p_true[inside], q_true[inside]

    def length(p):
        return np.sum(np.linalg.norm(np.diff(p, axis=0), axis=1))

    assert length(p_wheel) / length(p_true) == pytest.approx(1 + WHEEL_SCALE_ERROR, abs=0.005)
    yaw_error = 2 * np.arctan2(q_wheel[-1, 3], q_wheel[-1, 0]) - 2 * np.arctan2(
        q_true[-1, 3], q_true[-1, 0]
    )
    assert yaw_error == pytest.approx(WHEEL_YAW_DRIFT_RAD_S * (t_wheel[-1] - t_wheel[0]), abs=0.01)
    assert np.linalg.norm(p_wheel[-1] - p_true[-1]) > 0.05


def test_common_time_base_is_the_overlap_of_the_spans() -> None:
    spans = {"/points": (0.0, 2.9999), "/imu": (-0.05, 2.995), "/ground_truth": (0.2, 3.0)}
    base = common_time_base(Path("x"), spans)
    assert (base.start_s, base.end_s) == (0.2, 2.995)
    assert (base.start_by, base.end_by) == ("first stamp on /ground_truth", "last stamp on /imu")
    assert base.contains(0.2) and base.contains(2.995) and not base.contains(0.19)
    assert common_time_base(Path("x"), {}) is None
    with pytest.raises(
        InputError, match=r"x: the streams do not overlap in time .*/imu starts after /points ends"
    ):
        common_time_base(Path("x"), {"/points": (0.0, 1.0), "/imu": (2.0, 3.0)})


def _check_time_base(sequence) -> list:
    """The stream is time-ordered and starts at the initial state, which is the end of the
    first lidar sweep (the first KISS-ICP pose): the first odometry increment starts there,
    the first sweep is read but not emitted, and the IMU's lead and the samples during the
    first sweep are trimmed and said so. Returns the measurements."""
    measurements = list(sequence.measurements())
    stamps = np.array([m.t for m in measurements])
    assert np.all(np.diff(stamps) >= 0)
    base = sequence.metadata["time_base"]
    first_sweep = _messages(sequence.metadata["source"], "/points")[0]
    sweep_end = first_sweep.t + float(np.max(first_sweep.point_times))
    assert base["first_cloud_s"] == first_sweep.t and sweep_end > first_sweep.t + 0.09
    assert sequence.initial_state.t == base["start_s"] == sweep_end
    assert base["start_by"] == "end of the first sweep on /points, the first lidar pose"
    assert stamps[0] >= sequence.initial_state.t
    first_cloud = next(m.t for m in measurements if isinstance(m, PointCloud))
    assert first_cloud > sweep_end  # the first sweep itself is not in the stream
    first_odometry = next(m for m in measurements if isinstance(m, Odometry))
    assert first_odometry.t - first_odometry.dt == pytest.approx(sequence.initial_state.t, abs=1e-9)
    assert base["spans"]["/imu"][0] == pytest.approx(EPOCH_S - 0.05, abs=1e-6)
    assert stamps[-1] <= base["spans"]["/points"][1] + 1e-9  # the last sweep's end
    before = [m.t for m in _messages(sequence.metadata["source"], "/imu") if m.t < sweep_end]
    assert len(before) > 10  # the 10 of the lead and those of the first sweep
    trimmed = [w for w in sequence.all_warnings() if w.startswith("trimmed")]
    assert trimmed == [
        f"trimmed {len(before)} x /imu at t={before[0]:.9f}..{before[-1]:.9f}: before the start "
        f"of the common time base t={sweep_end:.9f} (end of the first sweep on /points, the "
        "first lidar pose)"
    ]
    return measurements


def _run_every_estimator(sequence, name: str) -> dict[str, str]:
    """Status per registered estimator: ``ok``, or the reason it was refused before it
    consumed a measurement (a failure while running fails the test)."""
    statuses = {}
    for entry in ESTIMATORS:
        assert is_compatible(entry.load(), sequence), entry.name
        steps: list[float] = []
        try:
            result = execute(RunRequest(entry.name, name), sequence=sequence, on_step=steps.append)
        except InputError as error:
            assert not steps, f"{entry.name} failed while running: {error}"
            statuses[entry.name] = str(error)
            continue
        timing = result.estimate.timing
        assert timing.t.size and timing.t[0] >= sequence.initial_state.t, entry.name
        statuses[entry.name] = "ok"
    return statuses


def _assert_every_estimator_runs(sequence, name: str) -> None:
    statuses = _run_every_estimator(sequence, name)
    refused = {n: s for n, s in statuses.items() if s != "ok"}
    assert set(refused) == set(REFUSED), statuses
    # Aghili's filter chose its anchors from what the bag offers, and says so
    notes = execute(RunRequest("aghili", name), sequence=sequence).estimate.notes
    assert any("anchors from their first observation" in note for note in notes), notes


def test_without_deskewing_the_start_is_the_first_kept_cloud(tmp_path) -> None:
    """``kiss.deskew=false``, and the bag's first cloud is empty: the front end's first pose
    is the second cloud's stamp, and the sequence starts there, where the first odometry
    increment starts (not at the empty cloud's stamp, one frame of motion earlier)."""
    from tests.test_bags_bad_input import _box_points, _cloud, _imu, write_ros2

    rng = np.random.default_rng(4)
    messages = [
        (
            "/cloud",
            "sensor_msgs/msg/PointCloud2",
            t,
            _cloud(t, _box_points(rng) if k else np.zeros((0, 3))),
        )
        for k, t in enumerate(1.0 + 0.1 * np.arange(6))
    ]
    messages += [
        ("/imu", "sensor_msgs/msg/Imu", 0.9 + 0.01 * k, _imu(0.9 + 0.01 * k)) for k in range(70)
    ]
    messages.sort(key=lambda item: item[2])
    bag = write_ros2(tmp_path / "empty_first_cloud", messages)
    sequence = load_dataset(f"bag:{bag}", 0, {**DATA, "kiss.deskew": "false"})
    measurements = list(sequence.measurements())
    base = sequence.metadata["time_base"]
    assert sequence.initial_state.t == base["start_s"] == pytest.approx(1.1)
    assert base["start_by"] == "first kept cloud on /cloud, the first lidar pose"
    first_odometry = next(m for m in measurements if isinstance(m, Odometry))
    assert first_odometry.t - first_odometry.dt == pytest.approx(1.1, abs=1e-9)
    assert min(m.t for m in measurements) >= base["start_s"]


@pytest.mark.study
def test_leading_imu_and_wheel_odometry_without_truth(bags) -> None:
    name = f"bag:{bags['ros2']}"
    sequence = load_dataset(name, 0, DATA)
    # no truth at all: not the wheel odometry, nor the sidecar's corners (they are in the
    # truth topic's world frame, and this sequence's world is its first body frame)
    assert sequence.ground_truth is None
    assert sequence.reference_source is None
    assert "/wheel/odometry" not in sequence.topics.as_dict().values()
    (unnamed,) = [w for w in sequence.all_warnings() if "not taken as truth" in w]
    assert "pose topic(s) /ground_truth, /wheel/odometry not taken as truth unless named" in unnamed
    assert sequence.initial_state.velocity is None and np.allclose(
        sequence.initial_state.position, 0
    )
    _check_time_base(sequence)
    _assert_every_estimator_runs(sequence, name)


@pytest.mark.study
def test_leading_imu_with_the_truth_named(bags) -> None:
    name = f"bag:{bags['ros2']}"
    sequence = load_dataset(name, 0, NAMED)
    truth = sequence.ground_truth.pose
    assert sequence.reference_source == "topic /ground_truth"
    assert not any("not taken as truth" in w for w in sequence.all_warnings())
    _check_time_base(sequence)
    # the initial state is the truth at the start of the common interval (the first lidar
    # pose, one sweep after the truth's first pose: 0.15 m further on at 1.5 m/s)
    start = sequence.initial_state.t
    assert truth.t[0] < start
    expected = [np.interp(start, truth.t, truth.positions[:, axis]) for axis in range(3)]
    np.testing.assert_allclose(sequence.initial_state.position, expected, atol=1e-9)
    assert np.linalg.norm(sequence.initial_state.position - truth.positions[0]) > 0.1
    _assert_every_estimator_runs(sequence, name)


@pytest.mark.study
def test_ros1_bag_with_two_odometry_topics(bags) -> None:
    """ROS 1: truth and wheel odometry are both nav_msgs/Odometry; neither is truth unless
    named, and the three filters that failed before run with the truth named."""
    name = f"bag:{bags['ros1']}"
    unnamed = load_dataset(name, 0, DATA)
    assert unnamed.ground_truth is None or unnamed.ground_truth.pose is None
    assert any(
        "/ground_truth, /wheel/odometry not taken as truth" in w for w in unnamed.all_warnings()
    )
    _check_time_base(unnamed)
    named = load_dataset(name, 0, NAMED)
    _check_time_base(named)
    for estimator in ("dead-reckoning", "sensor-based", "ekf-slam"):
        execute(RunRequest(estimator, name), sequence=named)


@pytest.mark.study
def test_workbench_bag_command_runs_every_estimator(bags, tmp_path, capsys) -> None:
    from workbench.cli import main

    out = tmp_path / "out"
    argv = ["bag", str(bags["ros2"]), "--out", str(out), "--no-plots", "--threads", "1"]
    assert main(argv) == 0  # every estimator with its defaults, aghili included
    err = capsys.readouterr().err
    assert re.search(r"trimmed \d+ x /imu", err) and "/wheel/odometry not taken as truth" in err
    table = (out / "table.md").read_text()
    for entry in ESTIMATORS:
        (row,) = [line for line in table.splitlines() if f"| {entry.name} |" in line]
        assert "failed" not in row, row


def test_a_truth_topic_that_starts_late_sets_the_start(tmp_path) -> None:
    """Truth named and starting 0.3 s after the lidar (IMU 0.1 s before it): the clouds and
    IMU samples before the truth's first pose are trimmed, and the initial state is there."""
    from tests.test_bags_bad_input import _box_points, _cloud, _imu, _odometry, write_ros2

    rng = np.random.default_rng(4)
    messages = []
    for k in range(8):
        t = 1.0 + 0.1 * k
        messages.append(("/cloud", "sensor_msgs/msg/PointCloud2", t, _cloud(t, _box_points(rng))))
        if t > 1.25:
            messages.append(("/odom", "nav_msgs/msg/Odometry", t, _odometry(t, 0.0)))
    messages += [
        ("/imu", "sensor_msgs/msg/Imu", 0.9 + 0.01 * k, _imu(0.9 + 0.01 * k)) for k in range(90)
    ]
    messages.sort(key=lambda item: item[2])
    bag = write_ros2(tmp_path / "late_truth", messages)
    name = f"bag:{bag}"
    sequence = load_dataset(name, 0, {**DATA, "ground_truth_topic": "/odom"})
    measurements = list(sequence.measurements())
    stamps = [m.t for m in measurements]
    assert stamps == sorted(stamps) and sequence.initial_state.t == stamps[0] == pytest.approx(1.3)
    assert [round(m.t, 3) for m in measurements if isinstance(m, PointCloud)] == [
        1.3,
        1.4,
        1.5,
        1.6,
        1.7,
    ]
    base = sequence.metadata["time_base"]
    assert base["start_s"] == pytest.approx(1.3) and base["start_by"] == "first stamp on /odom"
    assert base["end_s"] == pytest.approx(1.7) and base["end_by"] == "last stamp on /cloud"
    trimmed = sorted(w for w in sequence.all_warnings() if w.startswith("trimmed"))
    assert trimmed == [
        "trimmed 3 x /cloud at t=1.000000000..1.200000000: before the start of the common "
        "time base t=1.300000000 (first stamp on /odom)",
        "trimmed 40 x /imu at t=0.900000000..1.290000000: before the start of the common "
        "time base t=1.300000000 (first stamp on /odom)",
        "trimmed 9 x /imu at t=1.710000000..1.790000000: after the end of the common "
        "time base t=1.700000000 (last stamp on /cloud)",
    ]
    for estimator in ("dead-reckoning", "ekf-slam", "sensor-based"):
        execute(RunRequest(estimator, name), sequence=sequence)


def test_a_simulated_bag_loaded_by_name_scores_its_map_against_the_true_corners(bags) -> None:
    """``workbench run``/suites load a bag through the registry: the corners' true ids must be
    attached there too, or the map is scored by equal ids (landmark RMSE 12 m, map NEES 1e6
    on this bag before; ``datasets.lidar.corner_truth.with_true_corner_ids``)."""
    from workbench.metrics.summary import compute_metrics

    name = f"bag:{bags['ros2']}"
    sequence = load_dataset(name, 0, NAMED)
    scan_ids = sequence.ground_truth.scan_ids
    assert len(scan_ids) > 10
    known = np.concatenate([ids for _, ids in scan_ids])
    assert np.mean(known >= 0) > 0.8  # most corners are true corners
    metrics = compute_metrics(
        execute(RunRequest("ekf-slam", name), sequence=sequence).estimate, sequence
    )
    assert metrics["landmarks_mapped"] >= 5
    assert metrics["landmark_rmse_m"] < 0.3, metrics["landmark_rmse_m"]
    assert metrics["association_precision"] > 0.9
