"""The lidar front end end to end on synthetic bags (ROS 1 and ROS 2), and its pieces:
KISS-ICP timestamps, the SE(3) deskew against an independent reference, odometry."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import numpy as np
import pytest
from scipy.linalg import expm

from datasets.lidar.kiss_icp_odometry import deskew_to_end, normalized_point_times, se3_log
from datasets.rotations import so3_exp
from datasets.synthetic_lidar import write_lidar_bag
from workbench.commands.bag import bag_command

# a study: the second tier (`pytest -m study`, run by .ci/run after the default tier)
pytestmark = pytest.mark.study

# 3 s from 5 s into the loop: the end of the bottom corridor and the first turn
SEGMENT = {"duration_s": "3", "start_s": "5", "columns": "1024"}


@pytest.fixture(scope="module")
def runs(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("frontend")
    out = {}
    for name, fmt, extra in (("ros1", "ros1", {}), ("ros2", "ros2", {"storage": "mcap"})):
        bag = write_lidar_bag(root / f"corridor_{name}", 7, fmt, {**SEGMENT, **extra})
        rows = bag_command(
            bag,
            root / f"out_{name}",
            None,
            None,
            "/ground_truth",
            ["dead-reckoning"],
            ["kiss.max_num_threads=1"],
            plots=False,
            quiet=True,
        )
        assert [row["estimator"] for row in rows] == ["kiss-icp (front end)", "dead-reckoning"]
        out[name] = root / f"out_{name}"
    return out


@pytest.mark.parametrize("name", ["ros1", "ros2"])
def test_corner_precision_recall_and_ate(runs, name):
    metrics = json.loads((runs[name] / "frontend" / "metrics.json").read_text())
    assert metrics["frames"] == 30
    assert metrics["frames_scored"] == 30
    assert metrics["corner_precision"] >= 0.95, metrics
    assert metrics["corner_recall"] >= 0.80, metrics
    assert metrics["observable"] >= 100
    assert metrics["kiss_icp_ate_rmse_m"] is not None and metrics["kiss_icp_ate_rmse_m"] < 0.5
    # nothing skipped; only the IMU samples of the first sweep are trimmed (the sequence
    # starts at the first lidar pose, the sweep's end)
    (trimmed,) = metrics["skipped"]
    assert trimmed.startswith("trimmed 20 x /imu") and "end of the first sweep" in trimmed
    assert metrics["nonfinite_points_dropped"] > 0
    # the covariances (with the model floor) cover the errors of the correct detections;
    # the warm-up's inflated corners (datasets.lidar.motion_settling) pull the mean NEES
    # down (0.27 on this bag, 0.31 without the warm-up)
    assert metrics["corner_error_rms_m"] < 0.04 and 0.2 < metrics["corner_nees_mean"] < 3.0
    # KISS-ICP settles by the corners within the bag, after inflated increments
    assert 3 <= metrics["kiss_icp_settled_frame"] < 30
    assert metrics["kiss_icp_warmup_inflated_increments"] >= 1
    assert metrics["kiss_icp_warmup_gave_up_frame"] is None
    # the one table writer: a row per estimator and the front end's own (its trajectory
    # against the truth), KISS-ICP's own figures in a note
    table = (runs[name] / "table.md").read_text()
    assert table.startswith("| dataset | estimator | runs | ATE [m]")
    assert "| dead-reckoning | 1 |" in table and "front end kiss-icp" in table
    rows = list(csv.DictReader((runs[name] / "table.csv").open()))
    assert [row["estimator"] for row in rows] == ["front end (kiss-icp)", "dead-reckoning"]
    assert float(rows[0]["ate_rmse_m"]) > 0  # the synthetic bag has truth
    tum = np.loadtxt(runs[name] / "frontend" / "kiss_icp.tum")
    assert tum.shape == (30, 8)
    corners = np.genfromtxt(runs[name] / "frontend" / "corners.csv", delimiter=",", names=True)
    assert len(corners) == metrics["detections"] and np.all(corners["cov_xx"] > 0)
    assert (runs[name] / "dead-reckoning" / "metrics.json").is_file()
    # KISS-ICP's increment covariance: the fit from the re-observations, never below the
    # stated default; and the yaw-rate disagreement with the corners, with its error
    assert metrics["kiss_icp_covariance_source"].startswith("re-observations")
    assert metrics["kiss_icp_sigma_rotation_rad"] >= 0.002
    assert metrics["kiss_icp_sigma_translation_m"] >= 0.02
    assert metrics["kiss_icp_sigma_translation_m"] == pytest.approx(
        max(0.02, metrics["kiss_icp_fit_sigma_translation_m"])
    )
    assert np.isfinite(metrics["kiss_icp_corner_yaw_rate_deg_s"])
    assert metrics["kiss_icp_corner_yaw_rate_se_deg_s"] > 0


def test_ros1_and_ros2_agree(runs):
    one = json.loads((runs["ros1"] / "frontend" / "metrics.json").read_text())
    two = json.loads((runs["ros2"] / "frontend" / "metrics.json").read_text())
    # same world and seed, float32 "time" seconds vs uint32 "t" nanoseconds: same front end
    assert one["detections"] == pytest.approx(two["detections"], rel=0.05)
    assert one["kiss_icp_ate_rmse_m"] == pytest.approx(two["kiss_icp_ate_rmse_m"], abs=0.05)


def test_normalized_times():
    assert normalized_point_times(None).size == 0
    assert (
        normalized_point_times(np.full(5, 0.03)).size == 0
    )  # one time: KISS-ICP would divide by zero
    assert np.allclose(normalized_point_times(np.array([0.02, 0.07, 0.12])), [0.0, 0.5, 1.0])


def _twist_matrix(xi: np.ndarray) -> np.ndarray:
    matrix = np.zeros((4, 4))
    rho, phi = xi[:3], xi[3:]
    matrix[:3, :3] = np.array([[0, -phi[2], phi[1]], [phi[2], 0, -phi[0]], [-phi[1], phi[0], 0]])
    matrix[:3, 3] = rho
    return matrix


def test_se3_log_and_deskew_against_matrix_exponential():
    rng = np.random.default_rng(3)
    xi = np.array([0.15, -0.02, 0.01, 0.01, -0.02, 0.3])
    delta = expm(_twist_matrix(xi))
    assert np.allclose(se3_log(delta), xi, atol=1e-10)
    points = rng.normal(size=(20, 3)) * 5.0
    s = rng.uniform(0.0, 1.0, 20)
    expected = np.array(
        [(expm((si - 1.0) * _twist_matrix(xi)) @ np.append(p, 1.0))[:3] for p, si in zip(points, s)]
    )
    assert np.allclose(deskew_to_end(points, s, delta), expected, atol=1e-10)
    assert np.allclose(deskew_to_end(points, np.ones(20), delta), points)
    assert np.allclose(so3_exp(xi[3:]), delta[:3, :3])


def test_workbench_bag_twice_gives_the_same_table(tmp_path: Path, capsys) -> None:
    """Determinism: KISS-ICP runs on one thread by default, so the same bag gives the same
    numbers on any machine (timing columns aside)."""
    from workbench.cli import main
    from workbench.results.tables import non_timing_columns

    bag = write_lidar_bag(tmp_path / "corridor", 3, "ros1", {**SEGMENT, "duration_s": "2"})
    tables = []
    for name in ("first", "second"):
        out = tmp_path / name
        argv = ["bag", str(bag), "--out", str(out), "--estimator", "dead-reckoning"]
        argv += ["--estimator", "ekf-slam"]
        assert main([*argv, "--no-plots"]) == 0
        tables.append(non_timing_columns((out / "table.csv").read_text()))
    capsys.readouterr()
    assert tables[0] == tables[1] and len(tables[0]) >= 2


def test_heading_warning_only_for_untimed_clouds_and_a_significant_disagreement(
    monkeypatch,
) -> None:
    """The rule of ``LidarFrontEnd.heading_warning`` on its own: clouds mostly without
    per-point times, and a corner yaw-rate disagreement beyond three standard errors, fitted
    over the first ``HEADING_CHECK_FRAMES`` frames and once per number of frames."""
    from datasets.lidar.frontend import FrontEndFrame, LidarFrontEnd
    from datasets.lidar.frontend_diagnostics import HEADING_CHECK_FRAMES
    from datasets.lidar.frontend_settings import FrontEndSettings

    calls = []

    def front_end(untimed: int, rate_deg_s: float, error_deg_s: float) -> LidarFrontEnd:
        made = LidarFrontEnd(FrontEndSettings())
        made.frames = [
            FrontEndFrame(0.1 * k, 0.1 * k, 1000, np.eye(4), None, None, 0.0, 0.0)
            for k in range(10)
        ]
        made.untimed_frames = untimed
        disagreement = (np.deg2rad(rate_deg_s), np.deg2rad(error_deg_s))
        monkeypatch.setattr(
            made, "corner_yaw_rate", lambda frames=None: calls.append(frames) or disagreement
        )
        return made

    warned = front_end(10, -0.41, 0.10)
    text = warned.heading_warning()
    assert text is not None and "-0.41 +- 0.10 deg/s" in text and "10 of 10 clouds" in text
    assert warned.heading_warning() == text and calls == [HEADING_CHECK_FRAMES]
    assert "point_times=azimuth" in text
    assert front_end(10, -0.29, 0.10).heading_warning() is None  # within 3 standard errors
    assert front_end(4, -0.41, 0.10).heading_warning() is None  # most clouds carry times
    assert front_end(5, 0.41, 0.10).heading_warning() is not None  # either sign, half untimed
