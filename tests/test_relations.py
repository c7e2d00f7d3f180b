"""The relations metric (Kümmerle et al. 2009): against GTSAM's ``between`` in 2-D and 3-D,
on relations drawn from simulated truth, on bad files, on relations it cannot score, and
through ``workbench metrics relations`` and ``workbench run --data relations=FILE``."""

from __future__ import annotations

import json
import math
from pathlib import Path

import gtsam
import numpy as np
import pytest

from datasets.errors import InputError
from datasets.state import Relations
from datasets.trajectory import Trajectory
from datasets.trajectory_io import read_tum, write_kitti, write_tum
from workbench.cli import main
from workbench.metrics.relations import read_relations, relation_errors
from workbench.metrics.summary import relations_metrics
from workbench.registry import load_dataset

SIM = "sim:guerreiro-loop"
SIM_OPTIONS = {"duration_s": "10"}


def _pose2(trajectory: Trajectory, index: int) -> gtsam.Pose2:
    x, y = trajectory.positions[index]
    return gtsam.Pose2(float(x), float(y), float(trajectory.rotations[index]))


def _pose3(trajectory: Trajectory, index: int) -> gtsam.Pose3:
    w, x, y, z = trajectory.rotations[index]
    return gtsam.Pose3(gtsam.Rot3.Quaternion(w, x, y, z), trajectory.positions[index])


def _write_relations(path: Path, times: np.ndarray, rows: list[list[float]]) -> Path:
    """A relations file in the field's format (``t1 t2 x y z roll pitch yaw``)."""
    lines = ["# t1 t2 x y z roll pitch yaw", ""]
    for (t1, t2), values in zip(times, rows):
        lines.append(" ".join(f"{value:.17g}" for value in (t1, t2, *values)))
    path.write_text("\n".join(lines) + "\n")
    return path


def _planar_rows(given: list[gtsam.Pose2]) -> list[list[float]]:
    return [[pose.x(), pose.y(), 0.0, 0.0, 0.0, pose.theta()] for pose in given]


def _independent_statistics(trans: np.ndarray, rot_deg: np.ndarray) -> dict[str, float]:
    return {
        "trans_error_mean_m": float(np.mean(trans)),
        "trans_error_std_m": float(np.std(trans, ddof=1)),
        "trans_error_sq_mean_m2": float(np.mean(trans**2)),
        "rot_error_mean_deg": float(np.mean(rot_deg)),
        "rot_error_std_deg": float(np.std(rot_deg, ddof=1)),
        "rot_error_sq_mean_deg2": float(np.mean(rot_deg**2)),
    }


def _random_pairs(rng: np.random.Generator, count: int, size: int) -> np.ndarray:
    pairs = rng.integers(0, count, size=(size, 2))
    return pairs[pairs[:, 0] != pairs[:, 1]]


def test_planar_errors_equal_gtsam_pose2_between(tmp_path) -> None:
    rng = np.random.default_rng(7)
    count = 60
    t = 100.0 + np.cumsum(rng.uniform(0.05, 0.3, count))  # irregular stamps
    trajectory = Trajectory(
        t, np.cumsum(rng.normal(size=(count, 2)), axis=0), rng.uniform(-np.pi, np.pi, count)
    )
    pairs = _random_pairs(rng, count, 40)
    given = [gtsam.Pose2(*rng.normal(scale=3.0, size=2), rng.uniform(-np.pi, np.pi)) for _ in pairs]
    # relation times a few ms off the stamps: the nearest pose within 0.01 s is the one meant
    times = t[pairs] + rng.uniform(-0.004, 0.004, size=pairs.shape)
    relations = read_relations(_write_relations(tmp_path / "r.txt", times, _planar_rows(given)))
    assert relations.dimension == 2 and relations.poses.shape == (len(pairs), 3)

    result = relation_errors(trajectory, relations)

    trans, rot = [], []
    for (i, j), expected in zip(pairs, given):
        error = expected.between(_pose2(trajectory, i).between(_pose2(trajectory, j)))
        trans.append(np.linalg.norm(error.translation()))
        rot.append(abs(math.degrees(error.theta())))
    assert result.used_count == len(pairs) and result.skipped_count == 0
    np.testing.assert_allclose(result.translation_errors_m, trans, rtol=0, atol=1e-9)
    np.testing.assert_allclose(result.rotation_errors_deg, rot, rtol=0, atol=1e-9)
    statistics = result.statistics()
    for key, value in _independent_statistics(np.array(trans), np.array(rot)).items():
        assert statistics[key] == pytest.approx(value, rel=1e-9, abs=1e-9), key
    assert np.all(result.stamp_offsets_s <= 0.004 + 1e-9)


def test_spatial_errors_equal_gtsam_pose3_between(tmp_path) -> None:
    rng = np.random.default_rng(11)
    count = 40
    t = np.arange(count) * 0.1
    quaternions = rng.normal(size=(count, 4))
    quaternions /= np.linalg.norm(quaternions, axis=1, keepdims=True)
    trajectory = Trajectory(t, rng.normal(scale=5.0, size=(count, 3)), quaternions)
    pairs = _random_pairs(rng, count, 30)
    rows = [
        [*rng.normal(scale=2.0, size=3), *rng.uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi])]
        for _ in pairs
    ]
    relations = read_relations(_write_relations(tmp_path / "r.txt", t[pairs], rows))
    assert relations.dimension == 3 and relations.poses.shape == (len(pairs), 6)

    result = relation_errors(trajectory, relations)

    trans, rot = [], []
    for (i, j), (x, y, z, roll, pitch, yaw) in zip(pairs, rows):
        expected = gtsam.Pose3(gtsam.Rot3.RzRyRx(roll, pitch, yaw), np.array([x, y, z]))
        error = expected.between(_pose3(trajectory, i).between(_pose3(trajectory, j)))
        trans.append(np.linalg.norm(error.translation()))
        rot.append(math.degrees(np.linalg.norm(gtsam.Rot3.Logmap(error.rotation()))))
    assert result.used_count == len(pairs)
    np.testing.assert_allclose(result.translation_errors_m, trans, rtol=0, atol=1e-9)
    np.testing.assert_allclose(result.rotation_errors_deg, rot, rtol=0, atol=1e-9)
    statistics = result.statistics()
    for key, value in _independent_statistics(np.array(trans), np.array(rot)).items():
        assert statistics[key] == pytest.approx(value, rel=1e-9, abs=1e-9), key


@pytest.fixture(scope="module")
def sim_truth() -> Trajectory:
    truth = load_dataset(SIM, 0, SIM_OPTIONS).ground_truth.pose
    assert truth.dimension == 2 and len(truth) > 50
    return truth


@pytest.fixture(scope="module")
def truth_relations(sim_truth, tmp_path_factory) -> tuple[Path, np.ndarray, list[gtsam.Pose2]]:
    """Relations between random pairs of the simulated truth's poses (GTSAM ``between``)."""
    rng = np.random.default_rng(3)
    pairs = _random_pairs(rng, len(sim_truth), 25)
    given = [_pose2(sim_truth, i).between(_pose2(sim_truth, j)) for i, j in pairs]
    path = tmp_path_factory.mktemp("relations") / "sim.relations"
    return _write_relations(path, sim_truth.t[pairs], _planar_rows(given)), pairs, given


def test_truth_scores_zero_and_a_heading_offset_scores_its_known_error(
    sim_truth, truth_relations
) -> None:
    path, pairs, given = truth_relations
    relations = read_relations(path)

    exact = relation_errors(sim_truth, relations)
    assert exact.used_count == len(pairs)
    assert exact.translation_errors_m.max() < 1e-9 and exact.rotation_errors_deg.max() < 1e-9

    # a rigid motion of the whole estimate (gauge) leaves every relative pose unchanged
    angle, shift = 0.7, np.array([3.0, -2.0])
    rotation = np.array([[math.cos(angle), -math.sin(angle)], [math.sin(angle), math.cos(angle)]])
    moved = Trajectory(
        sim_truth.t, sim_truth.positions @ rotation.T + shift, sim_truth.rotations + angle
    )
    assert relation_errors(moved, relations).translation_errors_m.max() < 1e-9

    # every heading off by phi, positions exact: T1^-1 T2 keeps its rotation but its
    # translation turns by -phi, so ||delta t|| = 2 |sin(phi / 2)| ||t*||, rotation error 0
    phi = 0.05
    offset = Trajectory(sim_truth.t, sim_truth.positions, sim_truth.rotations + phi)
    result = relation_errors(offset, relations)
    lengths = np.array([np.linalg.norm(pose.translation()) for pose in given])
    expected = 2 * abs(math.sin(phi / 2)) * lengths
    np.testing.assert_allclose(result.translation_errors_m, expected, rtol=0, atol=1e-9)
    assert result.rotation_errors_deg.max() < 1e-9
    statistics = result.statistics()
    assert statistics["trans_error_mean_m"] == pytest.approx(expected.mean(), abs=1e-9)
    assert statistics["trans_error_sq_mean_m2"] == pytest.approx(np.mean(expected**2), abs=1e-9)
    assert expected.mean() > 1e-3  # the offset is seen: the test could fail


def test_relations_that_cannot_be_scored_are_counted_with_their_reasons() -> None:
    t = np.round(np.arange(0.0, 10.0001, 0.1), 6)
    keep = (t < 4.0) | (t > 6.0)  # a gap in the estimate from 4 to 6 s
    positions = np.column_stack([t, np.zeros_like(t)])
    positions[t == 8.0] = np.nan  # one pose the estimator lost
    estimate = Trajectory(t[keep], positions[keep], np.zeros(int(keep.sum())))
    cases = [
        ((1.0, 2.0), ""),
        ((2.0, 9.0), ""),
        ((1.0, 5.0), "no_pose_near_t2"),  # inside the gap: nothing interpolated across it
        ((5.0, 7.0), "no_pose_near_t1"),
        ((3.0, 10.5), "outside_span"),
        ((-1.0, 3.0), "outside_span"),
        ((2.0, 2.004), "same_pose"),
        ((7.0, 8.0), "non_finite_pose"),
        ((3.0, 3.125), "no_pose_near_t2"),  # 25 ms off any stamp
    ]
    times = np.array([pair for pair, _ in cases])
    relations = Relations(times, np.column_stack([times[:, 1] - times[:, 0], 0 * times]))

    result = relation_errors(estimate, relations)

    assert result.reasons == tuple(reason for _, reason in cases)
    assert result.used.tolist() == [0, 1]
    assert result.skipped_counts == {
        "outside_span": 2,
        "no_pose_near_t1": 1,
        "no_pose_near_t2": 2,
        "same_pose": 1,
        "non_finite_pose": 1,
    }
    np.testing.assert_allclose(result.translation_errors_m, 0.0, atol=1e-12)
    # a wider tolerance scores the 25 ms relation (and no other)
    wider = relation_errors(estimate, relations, max_diff_s=0.03)
    assert wider.used.tolist() == [0, 1, 8]

    metrics = relations_metrics(estimate, _truth_with(relations))
    assert metrics["relations_used"] == 2 and metrics["relations_skipped"] == 7
    assert metrics["relations_max_diff_s"] == 0.01
    for reason in result.skipped_counts:
        assert reason in metrics["relations_skipped_reasons"]
    assert metrics["relations_trans_error_mean_m"] == pytest.approx(0.0, abs=1e-12)
    assert set(relations_metrics(estimate, None).values()) == {None}


def _truth_with(relations: Relations):
    from datasets.state import GroundTruth, StateHistory

    return GroundTruth(history=StateHistory(), relations=relations)


GOOD = "1.0 2.0 0.5 0.0 0 0 0 0.1"


@pytest.mark.parametrize(
    "text, found",
    [
        (f"{GOOD}\n1.0 2.0 0.5 0.0 0 0 0.1\n", ":2: expected 8 columns"),
        (f"# header\n\n{GOOD}\n1.0 2.0 abc 0.0 0 0 0 0.1\n", ":4: x is not a number: 'abc'"),
        (f"{GOOD}\n1.0 2.0 nan 0.0 0 0 0 0.1\n", ":2: x not finite"),
        (f"{GOOD}\n3.0 3.0 0.5 0.0 0 0 0 0.1\n", ":2: t1 and t2 are the same time"),
        ("# only a comment\n\n", ": no relations in file"),
        (
            "1.0 2.0 0.5 0.0 0 0 0 0.1 9\n",
            ":1: expected 8 columns (t1 t2 x y z roll pitch yaw), got 9",
        ),
    ],
)
def test_bad_relation_files_give_one_error_naming_file_and_line(tmp_path, text, found) -> None:
    path = tmp_path / "bad.relations"
    path.write_text(text)
    with pytest.raises(InputError) as caught:
        read_relations(path)
    assert str(caught.value).startswith(str(path)) and found in str(caught.value)


def test_a_relation_file_may_run_backwards_and_carries_comments(tmp_path) -> None:
    path = tmp_path / "r.txt"
    path.write_text("2.0 1.0 -0.5 0 0 0 0 0  # t2 before t1\n1.0 2.0 0.5 0 0 0.2 0 0\n")
    relations = read_relations(path)
    assert relations.times.tolist() == [[2.0, 1.0], [1.0, 2.0]]
    assert relations.poses.shape == (2, 6)  # a pitch: spatial


def _cli(argv: list[str], capsys) -> tuple[int, str, str]:
    status = main(argv)
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_cli_prints_the_report_and_refuses_what_it_cannot_score(
    tmp_path, sim_truth, truth_relations, capsys
) -> None:
    path, pairs, given = truth_relations
    phi = 0.05
    estimate = write_tum(
        tmp_path / "offset.tum",
        Trajectory(sim_truth.t, sim_truth.positions, sim_truth.rotations + phi),
    )
    status, out, _ = _cli(
        ["metrics", "relations", "--est", str(estimate), "--relations", str(path)], capsys
    )
    assert status == 0
    report = json.loads(out)
    lengths = np.array([np.linalg.norm(pose.translation()) for pose in given])
    expected = 2 * abs(math.sin(phi / 2)) * lengths
    assert report["used"] == len(pairs) and report["skipped"] == 0
    assert report["trans_error_mean_m"] == pytest.approx(expected.mean(), abs=1e-7)
    assert report["rot_error_mean_deg"] == pytest.approx(0.0, abs=1e-6)
    assert report["max_diff_s"] == 0.01 and report["relations_file"] == str(path)

    kitti = write_kitti(tmp_path / "offset.kitti", read_tum(estimate))
    late = write_tum(
        tmp_path / "late.tum",
        Trajectory(sim_truth.t + 100.0, sim_truth.positions, sim_truth.rotations),
    )
    bad_file = tmp_path / "bad.relations"
    bad_file.write_text("1 2 3\n")
    for argv, found in (
        (["--est", str(kitti), "--relations", str(path)], "KITTI poses carry no time"),
        (["--est", str(late), "--relations", str(path)], f"{len(pairs)} outside_span"),
        (["--est", str(estimate), "--relations", str(bad_file)], f"{bad_file}:1:"),
        (["--est", str(estimate), "--relations", str(path), "--max-diff", "0"], "--max-diff"),
    ):
        status, out, err = _cli(["metrics", "relations", *argv], capsys)
        lines = err.strip().splitlines()
        assert status == 2 and out == "" and len(lines) == 1, (argv, err)
        assert lines[0].startswith("error:") and found in lines[0], (argv, err)


def test_run_with_data_relations_puts_the_keys_in_metrics_json(
    tmp_path, truth_relations, capsys
) -> None:
    path, pairs, given = truth_relations
    out = tmp_path / "run"
    data = [f"{key}={value}" for key, value in SIM_OPTIONS.items()] + [f"relations={path}"]
    argv = ["run", "dead-reckoning", SIM, "--out", str(out), "--no-plots"]
    status, _, err = _cli(argv + [word for item in data for word in ("--data", item)], capsys)
    assert status == 0, err
    metrics = json.loads((out / "metrics.json").read_text())

    # independent: GTSAM on the run's own estimate file (a pose at every truth time)
    estimate = read_tum(out / "estimate.tum")
    relation_times = read_relations(path).times
    indices = np.abs(estimate.t[None, None, :] - relation_times[:, :, None]).argmin(axis=2)
    np.testing.assert_allclose(estimate.t[indices], relation_times, atol=1e-6)
    trans, rot = [], []
    for (first, second), expected in zip(indices, given):
        relative = _pose3(estimate, first).between(_pose3(estimate, second))
        error = gtsam.Pose3(gtsam.Rot3.Rz(expected.theta()), [*expected.translation(), 0.0])
        error = error.between(relative)
        trans.append(np.linalg.norm(error.translation()))
        rot.append(math.degrees(np.linalg.norm(gtsam.Rot3.Logmap(error.rotation()))))
    independent = _independent_statistics(np.array(trans), np.array(rot))
    assert metrics["relations_used"] == len(pairs) and metrics["relations_skipped"] == 0
    assert metrics["relations_skipped_reasons"] is None
    assert metrics["relations_max_diff_s"] == 0.01
    for key, value in independent.items():
        assert metrics[f"relations_{key}"] == pytest.approx(value, rel=1e-6, abs=1e-8), key
    assert metrics["relations_trans_error_mean_m"] > 1e-4  # dead reckoning drifts
    assert metrics["relations_used_smoothed"] is None  # a filter has no smoothed history

    from workbench.results.runs import read_run
    from workbench.results.summary import summarize_pair

    row = summarize_pair("d", "e", [read_run(out)])
    stat = row.stats["relations_trans_error_mean_m"]
    assert stat.mean == pytest.approx(metrics["relations_trans_error_mean_m"])


def test_data_relations_options_are_checked_before_the_loader(tmp_path) -> None:
    with pytest.raises(InputError, match="no such file"):
        load_dataset(SIM, 0, {**SIM_OPTIONS, "relations": str(tmp_path / "missing")})
    with pytest.raises(InputError, match="needs --data relations=FILE"):
        load_dataset(SIM, 0, {**SIM_OPTIONS, "relations_max_diff_s": "0.05"})
    path = tmp_path / "r.txt"
    path.write_text(GOOD + "\n")
    with pytest.raises(InputError, match="relations_max_diff_s must be a positive"):
        load_dataset(SIM, 0, {"relations": str(path), "relations_max_diff_s": "-1"})
    with pytest.raises(InputError, match="relation"):  # the loader still forbids unknown keys
        load_dataset(SIM, 0, {"relation": str(path)})


def test_smoothed_key_keeps_squared_units_last() -> None:
    from workbench.metrics.summary import smoothed_key

    assert (
        smoothed_key("relations_trans_error_sq_mean_m2")
        == "relations_trans_error_sq_mean_smoothed_m2"
    )
    assert (
        smoothed_key("relations_rot_error_sq_mean_deg2")
        == "relations_rot_error_sq_mean_smoothed_deg2"
    )
    assert smoothed_key("ate_rmse_m") == "ate_rmse_smoothed_m"
