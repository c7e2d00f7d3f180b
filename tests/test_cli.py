"""The ``workbench`` command end to end: list, simulate, run, metrics, and bad input."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

from workbench.cli import main

SHORT = ["--data", "duration_s=20"]


def run_cli(argv, capsys):
    status = main(argv)
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_list_names_scenarios_and_dead_reckoning(capsys):
    status, out, _ = run_cli(["list"], capsys)
    assert status == 0
    for name in (
        "sim:aghili-rover",
        "sim:guerreiro-loop",
        "sim:circle",
        "sim:static",
        "dead-reckoning",
    ):
        assert name in out


def test_list_verbose_documents_dataset_options(capsys):
    status, out, _ = run_cli(["list", "--verbose"], capsys)
    assert status == 0
    for option in ("duration_s", "noise_scale", "ids"):
        assert option in out


def folder_bytes(folder):
    return {
        path.relative_to(folder).as_posix(): path.read_bytes()
        for path in sorted(folder.rglob("*"))
        if path.is_file()
    }


def test_simulate_same_seed_gives_identical_files(tmp_path, capsys):
    for name, seed in (("a", 1), ("b", 1), ("c", 2)):
        assert (
            run_cli(
                ["simulate", "aghili-rover", "--seed", str(seed), "--out", str(tmp_path / name)]
                + SHORT,
                capsys,
            )[0]
            == 0
        )
    first, second, other = (folder_bytes(tmp_path / name) for name in "abc")
    assert first and first == second
    assert first.keys() == other.keys()
    assert any(first[key] != other[key] for key in first)


@pytest.fixture(scope="module")
def dead_reckoning_run(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "dr"
    status = main(
        ["run", "dead-reckoning", "sim:aghili-rover", "--seed", "1", "--out", str(out)] + SHORT
    )
    assert status == 0
    return out


def test_run_writes_the_run_folder(dead_reckoning_run):
    for name in (
        "config.yaml",
        "estimate.tum",
        "reference.tum",
        "estimate.npz",
        "metrics.json",
        "events.json",
    ):
        assert (dead_reckoning_run / name).is_file(), name
    assert list((dead_reckoning_run / "plots").glob("*.png"))
    metrics = json.loads((dead_reckoning_run / "metrics.json").read_text())
    for key in (
        "ate_rmse_m",
        "rpe_trans_rmse_m",
        "rpe_rot_rmse_deg",
        "final_orientation_error_deg",
        "nees_pose_per_dof",
        "nees_velocity_per_dof",
        "nees_gyro_bias_per_dof",
        "nees_accel_bias_per_dof",
        "nees_landmarks_per_dof",
        "nees_pose_inside_fraction",
        "nis_measurement_per_dof",
        "nis_dof",
        "landmark_rmse_m",
        "steps",
        "time_per_step_ms_median",
        "time_per_step_ms_p99",
        "seed",
        "git_revision",
    ):
        assert key in metrics, key
    assert metrics["seed"] == 1
    assert metrics["ate_rmse_m"] > 0
    assert metrics["nis_measurement_per_dof"] is None  # dead reckoning makes no updates


def test_run_folder_tum_files_load_in_evo(dead_reckoning_run):
    from evo.tools import file_interface

    estimate = file_interface.read_tum_trajectory_file(str(dead_reckoning_run / "estimate.tum"))
    reference = file_interface.read_tum_trajectory_file(str(dead_reckoning_run / "reference.tum"))
    assert estimate.num_poses == reference.num_poses > 100


def test_metrics_ate_prints_json(dead_reckoning_run, capsys):
    status, out, _ = run_cli(
        [
            "metrics",
            "ate",
            "--ref",
            str(dead_reckoning_run / "reference.tum"),
            "--est",
            str(dead_reckoning_run / "estimate.tum"),
        ],
        capsys,
    )
    assert status == 0
    report = json.loads(out)
    metrics = json.loads((dead_reckoning_run / "metrics.json").read_text())
    assert np.isclose(report["rmse_m"], metrics["ate_rmse_m"], rtol=1e-6)


def bad_inputs(tmp_path):
    good = tmp_path / "good.tum"
    good.write_text("0 0 0 0 0 0 0 1\n1 1 0 0 0 0 0 1\n2 2 0 0 0 0 0 1\n")
    malformed = tmp_path / "malformed.tum"
    malformed.write_text("0 0 0 0 0 0 0 1\n1 1 0\n")
    later = tmp_path / "later.tum"
    later.write_text("100 0 0 0 0 0 0 1\n101 1 0 0 0 0 0 1\n102 2 0 0 0 0 0 1\n")
    return {
        "missing file": (
            ["metrics", "ate", "--ref", str(tmp_path / "nope.tum"), "--est", str(good)],
            "nope.tum",
        ),
        "malformed line": (
            ["metrics", "ate", "--ref", str(malformed), "--est", str(good)],
            "malformed.tum:2",
        ),
        "no overlap": (["metrics", "ate", "--ref", str(later), "--est", str(good)], "matching"),
        "unknown estimator": (
            ["run", "nope", "sim:circle", "--out", str(tmp_path / "x")],
            "unknown estimator",
        ),
        "unknown dataset": (
            ["run", "dead-reckoning", "sim:nowhere", "--out", str(tmp_path / "x")],
            "nowhere",
        ),
        "bad --set key": (
            [
                "run",
                "dead-reckoning",
                "sim:circle",
                "--set",
                "no_such_key=1",
                "--out",
                str(tmp_path / "x"),
            ],
            "no_such_key",
        ),
        "bad --data key": (
            [
                "run",
                "dead-reckoning",
                "sim:circle",
                "--data",
                "no_such_key=1",
                "--out",
                str(tmp_path / "x"),
            ],
            "no_such_key",
        ),
        "bad align": (
            ["metrics", "ate", "--ref", str(good), "--est", str(good), "--align", "affine"],
            "--align",
        ),
    }


@pytest.mark.parametrize(
    "case",
    [
        "missing file",
        "malformed line",
        "no overlap",
        "unknown estimator",
        "unknown dataset",
        "bad --set key",
        "bad --data key",
        "bad align",
    ],
)
def test_bad_input_prints_one_error_line_and_exits_2(tmp_path, capsys, case):
    argv, expected = bad_inputs(tmp_path)[case]
    status, _, err = run_cli(argv, capsys)
    assert status == 2
    lines = err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), err
    assert expected in lines[0]
    assert "Traceback" not in err


def test_console_script_reports_usage_error_without_traceback():
    completed = subprocess.run(
        [sys.executable, "-m", "workbench.cli", "run", "dead-reckoning"],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert completed.returncode == 2
    assert completed.stderr.strip().startswith("error: ")
    assert "Traceback" not in completed.stderr


def test_run_writes_png_figures_by_default_and_pdf_on_request(tmp_path, capsys):
    base = ["run", "dead-reckoning", "sim:circle", "--data", "duration_s=2"]
    assert run_cli(base + ["--out", str(tmp_path / "default")], capsys)[0] == 0
    default = {path.suffix for path in (tmp_path / "default" / "plots").iterdir()}
    assert default == {".png"}
    both = base + ["--out", str(tmp_path / "both"), "--plot-format", "pdf,png"]
    assert run_cli(both, capsys)[0] == 0
    names = {path.name for path in (tmp_path / "both" / "plots").iterdir()}
    assert "trajectory.png" in names and "trajectory.pdf" in names
    status, _, err = run_cli(
        base + ["--out", str(tmp_path / "bad"), "--plot-format", "jpg"], capsys
    )
    assert status == 2 and "--plot-format" in err and "png, pdf, svg" in err
