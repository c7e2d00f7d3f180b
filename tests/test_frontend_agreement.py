"""Every estimate against the lidar front end's own trajectory (issue 37): the typed
``FrontEndReport`` on the ``Sequence``, the agreement metrics, the departure check, the
front-end row of the lidar table; on both real KITTI clips and on synthetic corridor bags
(truth known) in the study tier."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from datasets.estimate import EstimateRecorder
from datasets.lidar.frontend_report import FrontEndReport
from datasets.rotations import quat_wxyz_from_matrix, so3_exp
from datasets.sequence import InitialState, Sequence
from datasets.trajectory import Trajectory, trajectory_from_homogeneous
from workbench.metrics.frontend_agreement import (
    FALSE_ALARM_RATE,
    KEYS,
    departure_warning,
    frontend_metrics,
)

SHARED = Path(__file__).resolve().parents[2] / "shared" / "data"
CLIPS = [SHARED / "kitti-hdl64-clip", SHARED / "kitti-hdl64-clip-b"]
# every estimator that runs on lidar odometry and corners alone (workbench list)
LIDAR_ONLY = (
    "dead-reckoning",
    "ekf-slam",
    "ekf-slam-mht",
    "sensor-based",
    "smoother-batch",
    "smoother-isam2",
    "smoother-fixed-lag",
)
LANDMARK_ESTIMATORS = tuple(name for name in LIDAR_ONLY if name != "dead-reckoning")
ROTATION_SIGMA_RAD, TRANSLATION_SIGMA_M = 0.002, 0.02  # KISS-ICP's stated defaults


def _pose(yaw: float, position) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = so3_exp(np.array([0.0, 0.0, yaw]))
    pose[:3, 3] = position
    return pose


def _front_end(frames: int = 30) -> FrontEndReport:
    """A front end driving 0.6 m per frame on a gentle left curve, with KISS-ICP's stated
    increment covariance."""
    report = FrontEndReport()
    step = np.diag([ROTATION_SIGMA_RAD**2] * 3 + [TRANSLATION_SIGMA_M**2] * 3)
    pose = np.eye(4)
    for k in range(frames):
        if k:
            pose = pose @ _pose(0.01, [0.6, 0.0, 0.0])
        report.add_frame(0.1 * k, pose, None if k == 0 else step, 0.01, 0.002, 5, True)
    return report


def _sequence(report: FrontEndReport, initial: InitialState | None = None) -> Sequence:
    return Sequence(
        name="scans:hand-built",
        dimension=3,
        sensors=frozenset(),
        stream=lambda: iter(()),
        initial_state=initial,
        front_end=report,
    )


def _estimate(trajectory: Trajectory, covariances: np.ndarray | None):
    recorder = EstimateRecorder(3)
    for i, t in enumerate(trajectory.t):
        recorder.pose(
            float(t),
            trajectory.positions[i],
            trajectory.rotations[i],
            None if covariances is None else covariances[i],
        )
    return recorder.build()


def _bent(trajectory: Trajectory, at: int, degrees: float) -> Trajectory:
    """``trajectory`` turned by ``degrees`` of yaw about its position at pose ``at`` from
    there on: an estimate that bends away."""
    poses = trajectory.homogeneous()
    pivot = np.eye(4)
    pivot[:3, 3] = poses[at][:3, 3]
    turn = pivot @ _pose(np.deg2rad(degrees), [0.0, 0.0, 0.0]) @ np.linalg.inv(pivot)
    poses[at:] = turn @ poses[at:]
    return replace(trajectory_from_homogeneous(trajectory.t, poses), covariances=None)


def _covariances(report: FrontEndReport, share: float) -> np.ndarray:
    """``share`` of the front end's accumulated covariance: an estimator that the corners
    made more certain than the increments alone."""
    from workbench.metrics.frontend_agreement import accumulated_covariances

    start = InitialState(0.0, np.zeros(3), np.array([1.0, 0, 0, 0]))
    return share * accumulated_covariances(report, start)


def test_agreement_is_measured_from_the_same_start_and_a_bend_departs() -> None:
    report = _front_end()
    front = report.trajectory()
    # the estimator's world is another one: its initial state is there (as a bag with truth
    # gives), and the comparison moves it onto the front end's first pose, not by Umeyama
    world = _pose(1.0, [5.0, -3.0, 0.2])
    moved = trajectory_from_homogeneous(front.t, world @ front.homogeneous())
    initial = InitialState(0.0, moved.positions[0], moved.rotations[0])
    sequence = _sequence(report, initial)
    covariances = _covariances(report, 0.5)
    metrics = frontend_metrics(_estimate(moved, covariances), sequence)
    assert set(metrics) == set(KEYS)
    assert metrics["frontend_frames_compared"] == 30 and metrics["frontend_frames"] == 30
    assert metrics["frontend_max_deviation_m"] < 1e-9
    assert abs(metrics["frontend_final_yaw_diff_deg"]) < 1e-9
    assert metrics["frontend_path_length_m"] == pytest.approx(29 * 0.6)
    assert metrics["frontend_departure_t_s"] is None
    assert metrics["frontend_departure_false_alarm_rate"] == FALSE_ALARM_RATE
    assert "front end minus estimate" in metrics["frontend_departure_covariance"]
    assert departure_warning(metrics, "ekf-slam", sequence.name) == []

    # 2 deg of yaw from frame 5 on: past what one increment (0.11 deg) and the front end's
    # accumulated heading uncertainty allow
    bent = _bent(moved, 5, 2.0)
    metrics = frontend_metrics(_estimate(bent, covariances), sequence)
    assert metrics["frontend_final_yaw_diff_deg"] == pytest.approx(2.0, abs=1e-6)
    # the deviation grows along the rest of the path: 24 frames of 0.6 m turned by 2 deg
    assert metrics["frontend_max_deviation_m"] == pytest.approx(
        np.deg2rad(2.0) * 24 * 0.6, rel=0.05
    )
    assert metrics["frontend_max_deviation_percent_path"] == pytest.approx(
        100 * metrics["frontend_max_deviation_m"] / (29 * 0.6)
    )
    assert metrics["frontend_departure_t_s"] == pytest.approx(0.5)
    assert metrics["frontend_departure_nees"] > metrics["frontend_departure_bound"]
    assert metrics["frontend_departure_yaw_deg"] == pytest.approx(2.0, abs=1e-6)
    (line,) = departure_warning(metrics, "ekf-slam", sequence.name)
    assert "ekf-slam" in line and "t=0.50 s" in line and "+2.00 deg" in line
    assert f"> {metrics['frontend_departure_bound']:.1f}" in line

    # the estimate states no covariance (the sensor-based filter in 3-D): the front end's
    # own bounds the difference's, and the bend still departs
    metrics = frontend_metrics(_estimate(bent, None), sequence)
    assert metrics["frontend_departure_covariance"].startswith("front end only")
    assert metrics["frontend_departure_t_s"] == pytest.approx(0.5)


def test_small_differences_within_the_covariances_do_not_depart() -> None:
    """Estimates that differ from the front end by draws of the covariance the check
    assumes (``P_fe - P_est`` plus one increment) stay within it; with another motion input
    (an IMU) the correlation is not taken and the bound is wider."""
    from workbench.metrics.frontend_agreement import compare_with_front_end

    report = _front_end()
    initial = InitialState(0.0, np.zeros(3), np.array([1.0, 0, 0, 0]))
    covariances = _covariances(report, 0.5)
    front = report.trajectory()
    rng = np.random.default_rng(4)
    fired = []
    for _ in range(200):
        poses = front.homogeneous()
        for k in range(1, len(poses)):
            spread = np.sqrt(
                0.5 * np.diag(covariances[k]) + np.diag(report.increment_covariances[k])
            )
            delta = rng.normal(size=6) * spread
            poses[k] = poses[k] @ np.block(
                [[so3_exp(delta[:3]), delta[3:, None]], [np.zeros((1, 3)), np.ones((1, 1))]]
            )
        noisy = Trajectory(
            front.t,
            poses[:, :3, 3],
            quat_wxyz_from_matrix(poses[:, :3, :3]).reshape(-1, 4),
            covariances,
        )
        found = compare_with_front_end(noisy, report, initial)
        fired.append(found.departure() is not None)
    assert sum(fired) <= 1  # 1e-4 per run: none expected in 200
    report.sole_motion_input = False
    metrics = frontend_metrics(_estimate(front, covariances), _sequence(report, initial))
    assert metrics["frontend_departure_covariance"].startswith("front end plus estimate")
    metrics = frontend_metrics(_estimate(front, None), _sequence(report, initial))
    assert metrics["frontend_departure_covariance"].startswith("not tested")
    assert metrics["frontend_departure_max_nees"] is None


def test_without_a_front_end_every_key_is_none() -> None:
    report = FrontEndReport()
    estimate = _estimate(_front_end().trajectory(), None)
    assert set(frontend_metrics(estimate, _sequence(report)).values()) == {None}
    assert set(frontend_metrics(estimate, replace(_sequence(report), front_end=None)).values()) == {
        None
    }


def test_estimators_never_see_the_front_end() -> None:
    from pydantic import BaseModel

    from workbench.runner import run_estimator

    seen = []

    class Peek:
        class Config(BaseModel):
            pass

        sensor_options = (frozenset(),)
        dimensions = frozenset({3})

        def __init__(self, config, sequence) -> None:
            seen.append((sequence.front_end, sequence.ground_truth))

        def process(self, measurement) -> None:
            pass

        def estimate(self):
            return EstimateRecorder(3).build()

    run_estimator(Peek, Peek.Config(), _sequence(_front_end()))
    assert seen == [(None, None)]


def _record(folder: Path, estimator: str, metrics: dict):
    from workbench.results.runs import RunRecord

    return RunRecord(folder, "scans:x", estimator, "scans:x", estimator, 0, metrics, None)


def test_the_lidar_table_has_a_front_end_row_and_the_agreement_columns() -> None:
    from workbench.results.summary import FRONT_END_ROW, summarize
    from workbench.results.tables import markdown_table, table_notes, terminal_tables

    shared = {
        "frontend_name": "kiss-icp",
        "frontend_frames": 30,
        "frontend_ate_rmse_m": None,
        "frontend_ms_per_frame": 95.0,
        "frontend_reobservation_nis_per_dof": 1.32,
    }
    records = [
        _record(
            Path(name),
            name,
            {
                **shared,
                "frontend_max_deviation_m": deviation,
                "frontend_max_deviation_percent_path": deviation / 18.5 * 100,
                "frontend_final_yaw_diff_deg": yaw,
                "frames": 29,
                "frames_without_pose": 0,
                "time_per_frame_ms": 7.0,
            },
        )
        for name, deviation, yaw in (("ekf-slam", 0.058, 0.059), ("smoother-isam2", 0.058, 0.056))
    ]
    rows = summarize(records)
    assert [row.estimator for row in rows] == ["front end (kiss-icp)", "ekf-slam", "smoother-isam2"]
    front = rows[0]
    assert front.estimator_name == FRONT_END_ROW and front.finished == 1
    assert front.stats["time_per_frame_ms"].mean == 95.0 and "ate_rmse_m" not in front.stats
    assert front.nis_per_dof == pytest.approx(1.32)
    assert rows[1].stats["frontend_final_yaw_diff_deg"].mean == pytest.approx(0.059)
    text = markdown_table(rows)
    assert "vs front end: max dev. [m]" in text and "final yaw diff. [deg]" in text
    assert any("lidar front end alone" in note and "1.32" in note for note in table_notes(rows))
    from rich.console import Console

    console = Console(width=200, color_system=None)
    with console.capture() as captured:
        for table in terminal_tables(rows):
            console.print(table)
    shown = captured.get()
    assert "vs front end" in shown and "[% path]" in shown and "29/29" in shown
    assert "0.059" in shown and "95" in shown


CLIP_B = CLIPS[1]


@pytest.mark.skipif(not CLIP_B.is_dir(), reason=f"{CLIP_B} (real lidar data) absent")
def test_a_short_real_clip_run_writes_the_front_end_and_its_agreement(tmp_path: Path) -> None:
    """``workbench run`` on 8 real scans: the sequence carries the front end's report once
    the estimator has run, metrics.json its agreement keys, the run folder its trajectory."""
    import json

    from workbench.registry import load_dataset
    from workbench.run_folder import write_run_folder
    from workbench.runner import RunRequest, execute

    dataset = f"scans:{CLIP_B}"
    options = {"max_frames": "8", "kiss.max_num_threads": "1"}
    sequence = load_dataset(dataset, 0, options)
    assert sequence.front_end is not None and sequence.front_end.frames == 0  # before a pass
    request = RunRequest("ekf-slam", dataset, data_options=tuple(options.items()))
    result = execute(request, sequence=sequence)
    report = sequence.front_end
    assert report.frames == 8 and report.sole_motion_input
    assert len(report.trajectory()) == 8 and report.increment_covariances[0] is None
    assert report.increment_covariances[1].shape == (6, 6)
    metrics = write_run_folder(result, tmp_path / "run", ())
    assert json.loads((tmp_path / "run" / "metrics.json").read_text())["frontend_name"] == (
        "kiss-icp"
    )
    assert (tmp_path / "run" / "frontend.tum").is_file()
    assert metrics["frontend_frames_compared"] == 8
    assert metrics["frontend_max_deviation_percent_path"] < 1.0
    assert abs(metrics["frontend_final_yaw_diff_deg"]) < 0.5
    assert metrics["frontend_departure_t_s"] is None
    assert metrics["frontend_ms_per_frame"] > 0 and metrics["time_per_frame_ms"] > 0
    # a second pass adds nothing: the front end caches its frames
    for _ in sequence.measurements():
        pass
    assert sequence.front_end.frames == 8


# ---------------------------------------------------------------------------- studies


def _clip_runs(clip: Path) -> dict:
    from workbench.metrics.summary import compute_metrics
    from workbench.registry import load_dataset
    from workbench.runner import RunRequest, execute

    dataset = f"scans:{clip}"
    sequence = load_dataset(dataset, 0, {"kiss.max_num_threads": "1"})
    found = {}
    for name in LIDAR_ONLY:
        estimate = execute(RunRequest(name, dataset), sequence=sequence).estimate
        found[name] = (estimate, compute_metrics(estimate, sequence))
    return {"sequence": sequence, "runs": found}


@pytest.fixture(scope="module", params=CLIPS, ids=[clip.name for clip in CLIPS])
def clip_runs(request) -> dict:
    if not request.param.is_dir():
        pytest.skip(f"{request.param} (real lidar data) absent")
    return _clip_runs(request.param)


@pytest.mark.study
def test_on_both_clips_every_lidar_only_estimator_follows_kiss_icp(clip_runs) -> None:
    """Both real KITTI clips with the defaults (raw sweeps, decided from the data): every
    lidar-only estimator within 0.5 deg of final yaw and 1 % of path length of KISS-ICP
    alone, no departure, a pose at every frame; the corners' re-observation NIS per dof
    within 0.7-1.5 (``benchmarks/bench_lidar_clip.py`` prints the table)."""
    sequence = clip_runs["sequence"]
    assert sequence.all_warnings() == []
    assert 0.7 <= sequence.front_end.reobservation_nis_per_dof() <= 1.5
    for name, (_, metrics) in clip_runs["runs"].items():
        figures = {key: metrics[key] for key in metrics if key.startswith("frontend_")}
        assert metrics["frontend_max_deviation_percent_path"] < 1.0, (name, figures)
        assert abs(metrics["frontend_final_yaw_diff_deg"]) < 0.5, (name, figures)
        assert metrics["frontend_departure_t_s"] is None, (name, figures)
        assert metrics["frames_without_pose"] == 0, (name, metrics["frames_without_pose_t"])
        # every frame but the first (the start, the initial state) is compared
        assert metrics["frontend_frames_compared"] >= sequence.front_end.frames - 1, name


@pytest.mark.study
def test_on_both_clips_a_two_degree_bend_departs(clip_runs) -> None:
    """Every landmark estimator's trajectory bent by 2 deg at its fourth frame departs."""
    sequence = clip_runs["sequence"]
    for name in LANDMARK_ESTIMATORS:
        estimate, _ = clip_runs["runs"][name]
        kind = "causal" if estimate.causal.pose is not None else "smoothed"
        history = getattr(estimate, kind)
        pose = replace(_bent(history.pose, 3, 2.0), covariances=history.pose.covariances)
        bent = replace(estimate, **{kind: replace(history, pose=pose)})
        metrics = frontend_metrics(bent, sequence)
        assert metrics["frontend_departure_t_s"] == pytest.approx(pose.t[3]), name


def _corridor_runs(folder: Path, seed: int, imu: bool) -> dict:
    from datasets.synthetic_lidar.writer import write_lidar_bag
    from workbench.commands.bag_estimators import choose_estimators
    from workbench.metrics.summary import compute_metrics
    from workbench.registry import load_dataset
    from workbench.runner import RunRequest, execute

    bag = folder / f"corridor{seed}"
    if not bag.exists():
        write_lidar_bag(bag, seed, "ros2", {"duration_s": "5"})
    options = {"ground_truth_topic": "/ground_truth", "imu": str(imu).lower()}
    options["kiss.max_num_threads"] = "1"
    dataset = f"bag:{bag}"
    sequence = load_dataset(dataset, 0, options)
    found = {}
    for name in choose_estimators(None, sequence):
        estimate = execute(RunRequest(name, dataset), sequence=sequence).estimate
        found[name] = compute_metrics(estimate, sequence)
    return found


@pytest.mark.study
@pytest.mark.parametrize("imu", (True, False), ids=("lidar+imu", "lidar-only"))
def test_on_corridor_bags_landmark_estimators_beat_kiss_icp_and_never_depart(
    tmp_path_factory, imu: bool
) -> None:
    """Synthetic corridor bags (truth known; two seeds): every landmark estimator's ATE
    (causal, else smoothed) is at most KISS-ICP's alone, and no estimator departs from the
    front end's trajectory, read with the IMU (no correlation taken) and without (the
    estimators fuse the increments)."""
    folder = tmp_path_factory.getbasetemp() / "corridor_bags"
    folder.mkdir(exist_ok=True)
    for seed in (1, 2):
        runs = _corridor_runs(folder, seed, imu)
        front_ate = runs["dead-reckoning"]["frontend_ate_rmse_m"]
        assert front_ate is not None and front_ate > 0
        for name, metrics in runs.items():
            assert metrics["frontend_departure_t_s"] is None, (seed, name, metrics)
            if name == "dead-reckoning":
                continue
            ate = metrics["ate_rmse_m"] or metrics["ate_rmse_smoothed_m"]
            assert ate <= front_ate, (seed, name, ate, front_ate)
