"""Sweep timing decided from the data (``datasets.lidar.sweep_timing``, ``point_times=auto``):
both real KITTI clips are raw sweeps, clockwise from behind; the synthetic corridor's sweeps
are raw without a time field (counterclockwise from behind, its sensor's own timing) and
compensated once moved to their stamp's pose; a sensor standing still leaves it undecided
(a warning, read as compensated); ``point_times=field`` / ``azimuth`` and ``sweep.*`` state
it instead."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from datasets.bags.bag_file import iter_messages, open_bag
from datasets.bags.pointcloud2 import decode_pointcloud2
from datasets.bags.read_report import ReadReport
from datasets.lidar.sweep_times import (
    CLOCKWISE,
    COUNTERCLOCKWISE,
    AzimuthSweep,
    azimuth_point_times,
    point_times_for,
)
from datasets.measurements import PointCloud
from datasets.synthetic_lidar.path import LoopPath
from datasets.synthetic_lidar.writer import EPOCH_S, LIDAR_TOPIC, write_lidar_bag
from tests.test_bags_bad_input import _cloud, write_ros2
from workbench.registry import load_dataset

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
CLIPS = ("kitti-hdl64-clip", "kitti-hdl64-clip-b")
QUIET = {"kiss.max_num_threads": "1"}
BAG = {"duration_s": "1.1"}  # 11 sweeps: the decision reads 10


def _timing(sequence) -> dict:
    return sequence.metadata["sweep_timing"]


@pytest.mark.parametrize("clip", CLIPS)
def test_the_real_kitti_clips_are_decided_raw_sweeps_clockwise_from_behind(clip):
    """From the first 10 scans: a raw cut (a ring's step equal to the range change one sweep
    makes there) in at least 3 rings, all within 30 deg of behind, clockwise, at least 3x
    the counterclockwise ones; no compensated cut on the ground; so the scans are timed by
    azimuth, clockwise from (about) 180 deg, as KISS-ICP's KITTI-raw loader times them.
    Said as a decision line, not a warning."""
    folder = DATA / clip
    if not folder.is_dir():
        pytest.skip(f"the real KITTI clip is absent (../shared/data/{clip})")
    sequence = load_dataset(f"scans:{folder}", 0, QUIET)
    timing = _timing(sequence)
    evidence = timing["evidence"]
    assert timing["outcome"] == "raw" and timing["point_times"] == "azimuth"
    assert timing["source"] == "data" and timing["frames"] == 10
    assert timing["direction"] == "clockwise"
    assert abs(timing["start_deg"] - 180.0) < 10.0
    assert timing["sweep_s"] == pytest.approx(0.1, abs=1e-3)
    clockwise = evidence["raw_cut_rings_clockwise"]
    assert clockwise >= 3 and clockwise >= 3 * evidence["raw_cut_rings_counterclockwise"]
    low, high = evidence["cut_spread_deg"]
    assert 150.0 < low <= high < 210.0
    assert evidence["compensated_cut_clouds_fraction"] < 0.7
    assert evidence["travel_m_per_sweep"] > 0.4  # 4-8 m/s
    assert sequence.decisions == (timing["text"],)
    assert "not motion-compensated" in timing["text"] and "clockwise" in timing["text"]
    assert not any("sweep timing" in line for line in sequence.all_warnings())


@pytest.fixture(scope="module")
def corridor(tmp_path_factory) -> dict[str, Path]:
    """The synthetic corridor (1.5 m/s, 0.1 s sweeps of 16 x 1024) as ROS 1 bags: with a
    time field, raw without one, and compensated (each point moved to the pose at its
    cloud's stamp, the sweep's start, by the true path; no time field: a ROS 2 bag of the
    clouds alone)."""
    folder = tmp_path_factory.mktemp("corridor")
    timed = write_lidar_bag(folder / "timed", 0, "ros1", BAG)
    raw = write_lidar_bag(folder / "raw", 0, "ros1", {**BAG, "time_field": "none"})
    path = LoopPath()
    messages = []
    with open_bag(timed) as reader:
        for _, _, stamp, message in iter_messages(
            reader, timed, [LIDAR_TOPIC], report=ReadReport()
        ):
            cloud = decode_pointcloud2(message, stamp, "corridor")
            at = path.sample(stamp - EPOCH_S + cloud.point_times)
            ref = path.sample(np.array([stamp - EPOCH_S]))
            c, s = np.cos(at.yaw), np.sin(at.yaw)
            x, y, z = cloud.points.T
            world = np.column_stack([c * x - s * y, s * x + c * y]) + at.position
            offset = world - ref.position[0]
            c0, s0 = np.cos(ref.yaw[0]), np.sin(ref.yaw[0])
            moved = np.column_stack(
                [c0 * offset[:, 0] + s0 * offset[:, 1], -s0 * offset[:, 0] + c0 * offset[:, 1], z]
            )
            messages.append(("/points", "sensor_msgs/msg/PointCloud2", stamp, _cloud(stamp, moved)))
    compensated = write_ros2(folder / "compensated", messages)
    return {"timed": timed, "raw": raw, "compensated": compensated}


def _first_cloud(bag: Path, options: dict[str, str]) -> tuple[object, PointCloud]:
    sequence = load_dataset(f"bag:{bag}", 0, {**QUIET, "max_frames": "2", **options})
    return sequence, next(m for m in sequence.measurements() if isinstance(m, PointCloud))


def test_a_synthetic_bag_without_times_is_decided_raw_and_timed_as_its_sensor_was(corridor):
    """The corridor's sensor sweeps counterclockwise from behind (azimuth -180 deg) and
    stamps a cloud at its first column: found so (raw cuts at 180 deg in every ring that
    faces a wall there, none clockwise), and with the stamp stated (``sweep.stamp=start``)
    every point's time from azimuth equals the time field of the same bag written with one,
    to within a column (0.1 ms)."""
    sequence, cloud = _first_cloud(corridor["raw"], {"sweep.stamp": "start"})
    timing = _timing(sequence)
    evidence = timing["evidence"]
    assert timing["outcome"] == "raw" and timing["direction"] == "counterclockwise"
    assert abs(timing["start_deg"] - 180.0) < 1.0
    assert evidence["raw_cut_rings_counterclockwise"] >= 3
    assert evidence["raw_cut_rings_clockwise"] == 0
    assert evidence["compensated_cut_clouds_fraction"] == 0
    _, timed = _first_cloud(corridor["timed"], {})
    assert _timing(load_dataset(f"bag:{corridor['timed']}", 0, QUIET))["outcome"] == "times"
    assert cloud.t == timed.t and len(cloud.points) == len(timed.points)
    np.testing.assert_allclose(cloud.point_times, timed.point_times, atol=1e-4, rtol=0)
    assert sequence.decisions == (timing["text"],)


def test_a_synthetic_compensated_bag_is_decided_compensated(corridor):
    """The same sweeps moved to one time: no raw cut in any ring; the ground's rings jump at
    the cut behind by the travel of one sweep in every cloud (they line up once shifted by
    the motion KISS-ICP finds), so the clouds are read without times."""
    sequence = load_dataset(f"bag:{corridor['compensated']}", 0, QUIET)
    timing = _timing(sequence)
    evidence = timing["evidence"]
    assert timing["outcome"] == "compensated" and timing["point_times"] == "field"
    assert evidence["raw_cut_rings_clockwise"] + evidence["raw_cut_rings_counterclockwise"] == 0
    assert evidence["compensated_cut_clouds_fraction"] >= 0.7
    assert abs(evidence["compensated_cut_at_deg"] - 180.0) <= 2.0
    assert evidence["compensated_cut_ratio"] >= 3.0
    assert sequence.decisions == (timing["text"],)
    clouds = [m for m in sequence.measurements() if isinstance(m, PointCloud)]
    assert clouds and all(cloud.point_times is None for cloud in clouds[:3])


def test_a_sensor_standing_still_leaves_the_timing_undecided_with_a_warning(tmp_path):
    """At 1 mm/s nothing a sweep's cut could show stands out of the noise: undecided, said
    as a warning, and the clouds are read as the stated default (without times)."""
    still = write_lidar_bag(
        tmp_path / "still", 0, "ros1", {**BAG, "time_field": "none", "speed_m_s": "0.001"}
    )
    sequence = load_dataset(f"bag:{still}", 0, QUIET)
    timing = _timing(sequence)
    assert timing["outcome"] == "undecided" and timing["point_times"] == "field"
    assert timing["evidence"]["travel_m_per_sweep"] < 0.01
    assert "barely moves" in timing["text"]
    assert sequence.decisions == ()
    assert timing["text"] in sequence.all_warnings()


def test_stated_timing_overrides_the_decision(corridor):
    """``point_times=field`` reads no cloud to decide and keeps the raw bag untimed;
    ``point_times=azimuth`` with ``sweep.direction`` and ``sweep.start_deg`` times it as
    stated (here wrongly, to show the statement wins), and says it was stated."""
    sequence, cloud = _first_cloud(corridor["raw"], {"point_times": "field"})
    assert _timing(sequence)["outcome"] == "stated" and cloud.point_times is None
    stated = {"point_times": "azimuth", "sweep.direction": "clockwise", "sweep.start_deg": "90"}
    sequence, cloud = _first_cloud(corridor["raw"], stated)
    timing = _timing(sequence)
    assert timing["source"] == "options" and timing["direction"] == "clockwise"
    assert timing["start_deg"] == 90.0 and "stated" in timing["text"]
    np.testing.assert_allclose(
        cloud.point_times, azimuth_point_times(cloud.points, 0.1, CLOCKWISE, 90.0), atol=1e-6
    )


def test_azimuth_times_follow_direction_start_and_stamp():
    """A quarter turn after the start is a quarter sweep after it, whichever way the sensor
    spins; the stamp sits at the start, the end or where the sweep faces +x; a plain float
    is KITTI raw's sweep (clockwise from behind, stamped facing forward)."""
    bearings = np.radians([91.0, 179.0, -179.0, -89.0, 1.0])
    points = np.column_stack([np.cos(bearings), np.sin(bearings), np.zeros(5)])
    ccw = azimuth_point_times(points, 1.0, COUNTERCLOCKWISE, 90.0, "start")
    np.testing.assert_allclose(ccw, np.array([1.0, 89.0, 91.0, 181.0, 271.0]) / 360.0)
    cw = azimuth_point_times(points, 1.0, CLOCKWISE, 90.0, "end")
    np.testing.assert_allclose(cw, np.array([359.0, 271.0, 269.0, 179.0, 89.0]) / 360.0 - 1.0)
    forward = azimuth_point_times(points, 1.0, CLOCKWISE, 90.0, "forward")
    np.testing.assert_allclose(forward, cw + 1.0 - 90.0 / 360.0)
    kitti = point_times_for(points, None, 0.1, "here")
    np.testing.assert_allclose(kitti, -bearings / (2.0 * np.pi) * 0.1)
    sweep = AzimuthSweep(0.1, COUNTERCLOCKWISE, 90.0, "start")
    assert float(sweep) == 0.1
    np.testing.assert_allclose(point_times_for(points, None, sweep, "here"), 0.1 * ccw)


def test_the_decision_is_printed_and_kept_in_the_run(corridor, tmp_path, capsys):
    """``workbench run`` says the timing decision with its evidence (a ``note:`` line, not a
    warning) and keeps it in metrics.json's ``decisions``."""
    import json

    from workbench.cli import main

    out = tmp_path / "run"
    argv = ["run", "dead-reckoning", f"bag:{corridor['raw']}", "--no-plots", "--out", str(out)]
    argv += ["--data", "kiss.max_num_threads=1", "--data", "max_frames=3"]
    assert main(argv) == 0
    notes = [line for line in capsys.readouterr().err.splitlines() if line.startswith("note:")]
    assert len(notes) == 1 and "raw" in notes[0] and "counterclockwise" in notes[0]
    decisions = json.loads((out / "metrics.json").read_text())["decisions"]
    assert len(decisions) == 1 and decisions[0] in notes[0]
