"""``workbench bench`` on the ``tiny`` suite: tables and plots, resume after SIGKILL, and the
same table through a Dask scheduler; plus the Monte Carlo averaging and table formatting."""

from __future__ import annotations

import csv
import io
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from workbench.commands.bench import bench
from workbench.metrics.consistency import averaged_nees
from workbench.results.consistency import StepSeries, average_runs
from workbench.results.summary import PairSummary, Stat
from workbench.results.tables import markdown_table, non_timing_columns

RUNS = 2


def _bench_tiny(out: Path, *options: str) -> list[str]:
    """The command a user types to run the tiny suite's ``RUNS`` runs into ``out``."""
    return [
        sys.executable, "-m", "workbench.cli", "bench", "tiny", "--runs", str(RUNS),
        "--out", str(out), *options,
    ]  # fmt: skip


@pytest.fixture(scope="module")
def uninterrupted_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, str, str]:
    """The tiny suite, run once without interruption on two local processes, through the
    command a user types, in a terminal 100 columns wide: (out, stdout, stderr)."""
    out = tmp_path_factory.mktemp("bench") / "tiny"
    environment = {**os.environ, "COLUMNS": "100", "OPENBLAS_NUM_THREADS": "1"}
    environment.pop("LINES", None)
    # PNG is the default; the PDF is asked for, as a paper figure would be.
    done = subprocess.run(
        _bench_tiny(out, "--workers", "2", "--plot-format", "png,pdf"),
        capture_output=True,
        text=True,
        env=environment,
        timeout=600,
    )
    assert done.returncode == 0, done.stderr
    return out, done.stdout, done.stderr


@pytest.fixture(scope="module")
def uninterrupted(uninterrupted_run: tuple[Path, str, str]) -> Path:
    return uninterrupted_run[0]


def test_bench_tiny_fits_100_columns(uninterrupted_run: tuple[Path, str, str]) -> None:
    """The terminal table fits the terminal it is printed on: no line longer than 100
    characters under ``COLUMNS=100``, units in the headers, the legend under the tables
    (``tests/test_terminal_width.py`` has the table-level cases)."""
    out, stdout, stderr = uninterrupted_run
    long = [line for line in (stdout + stderr).splitlines() if len(line) > 100]
    assert not long, long
    assert "[m]" in stdout and "[s]" in stdout and "NEES/dof" in stdout and "per dof" in stdout
    for mark in ("✓", "▲", "▼", "·", "ˢ"):
        assert mark in stdout.split("sim:guerreiro-loop")[-1], mark
    assert "sim:circle" in stdout and f"table: {out / 'table.md'}" in stdout


def _metrics_files(out: Path) -> list[Path]:
    return sorted((out / "runs").glob("*/*/seed-*/metrics.json"))


def test_tiny_writes_tables_and_plots(uninterrupted: Path) -> None:
    for name in ("table.md", "table.tex", "table.csv"):
        assert (uninterrupted / name).is_file(), name
    records = list(csv.DictReader(io.StringIO((uninterrupted / "table.csv").read_text())))
    pairs = {(record["dataset"], record["estimator"]) for record in records}
    assert pairs == {
        (d, e) for d in ("sim:circle", "sim:guerreiro-loop") for e in ("dead-reckoning", "ekf-slam")
    }
    for record in records:
        assert record["status"] == "ok" and record["runs"] == str(RUNS)
        assert float(record["ate_rmse_m"]) > 0
        assert float(record["time_per_step_ms_median"]) > 0
        assert record["anees_pose_per_dof"] != "" and record["verdict_pose"] == "too few runs"
    assert len(_metrics_files(uninterrupted)) == 4 * RUNS
    markdown = (uninterrupted / "table.md").read_text()
    assert "| sim:circle | ekf-slam | 2 |" in markdown
    latex = (uninterrupted / "table.tex").read_text()
    assert "\\toprule" in latex and "\\bottomrule" in latex and "$\\pm$" in latex
    for dataset in ("sim-circle", "sim-guerreiro-loop"):
        folder = uninterrupted / "plots" / dataset
        for figure in (
            "trajectories",
            "pose_errors",
            "consistency",
            "landmark_count",
            "time_vs_landmarks",
            "nis",
        ):
            assert (folder / f"{figure}.png").is_file() and (folder / f"{figure}.pdf").is_file(), (
                f"{dataset}/{figure}"
            )


def _group_alive(group: int) -> bool:
    """Whether any process of the process group still exists (zombies aside)."""
    for status in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = status.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[2]) == group and fields[0] != "Z":  # fields: state, ppid, pgrp, ...
            return True
    return False


def test_killed_sweep_resumes_without_redoing_runs(uninterrupted: Path, tmp_path: Path) -> None:
    out = tmp_path / "killed"
    command = _bench_tiny(out, "--workers", "1", "--no-plots")
    process = subprocess.Popen(
        command, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True
    )
    deadline = time.monotonic() + 60
    try:
        while not _metrics_files(out):
            assert process.poll() is None, "the sweep ended before any run finished"
            assert time.monotonic() < deadline, "no run finished within 60 s"
            time.sleep(0.02)
        process.send_signal(signal.SIGKILL)  # the CLI's main process only
        process.wait()
        # its worker must notice and exit by itself (then the fork server follows)
        deadline = time.monotonic() + 15
        while _group_alive(process.pid):
            assert time.monotonic() < deadline, "workers outlived the killed sweep"
            time.sleep(0.1)
    finally:
        if _group_alive(process.pid):
            os.killpg(process.pid, signal.SIGKILL)
        process.wait()
    finished = {path: path.stat().st_mtime_ns for path in _metrics_files(out)}
    assert 0 < len(finished) < 4 * RUNS, "the kill should leave the sweep unfinished"

    bench("tiny", RUNS, out, workers=2, plots=False, show_progress=False)

    for path, mtime in finished.items():
        assert path.stat().st_mtime_ns == mtime, f"{path} was redone"
    assert len(_metrics_files(out)) == 4 * RUNS
    assert non_timing_columns((out / "table.csv").read_text()) == non_timing_columns(
        (uninterrupted / "table.csv").read_text()
    )


def test_dask_scheduler_gives_the_same_table(uninterrupted: Path, tmp_path: Path) -> None:
    from distributed import LocalCluster

    out = tmp_path / "dask"
    with LocalCluster(
        n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None
    ) as cluster:
        bench(
            "tiny", RUNS, out, scheduler=cluster.scheduler_address, plots=False, show_progress=False
        )
    assert len(_metrics_files(out)) == 4 * RUNS
    assert non_timing_columns((out / "table.csv").read_text()) == non_timing_columns(
        (uninterrupted / "table.csv").read_text()
    )


def test_unknown_suite_is_a_clear_error(capsys: pytest.CaptureFixture[str]) -> None:
    from workbench.cli import main

    assert main(["bench", "no-such-suite", "--out", "unused"]) == 2
    assert "unknown suite 'no-such-suite'" in capsys.readouterr().err


def test_average_runs_equals_the_classic_averaged_nees_for_poses() -> None:
    rng = np.random.default_rng(3)
    runs, steps, dof = 7, 40, 6
    values = rng.chisquare(dof, size=(runs, steps))
    t = np.arange(steps) * 0.1
    ours = average_runs(
        [StepSeries(t, row, np.full(steps, dof), np.ones(steps, dtype=int)) for row in values]
    )
    classic = averaged_nees(values, dof)  # per run, not per dof
    np.testing.assert_allclose(ours.mean * dof, classic.mean)
    np.testing.assert_allclose(ours.lower * dof, classic.lower)
    np.testing.assert_allclose(ours.upper * dof, classic.upper)
    assert ours.inside_fraction == pytest.approx(classic.inside_fraction)
    assert ours.aligned_by == "time"


def test_average_runs_aligns_by_time_and_weights_landmark_units() -> None:
    # run B misses the first step: only the common stamps are averaged
    a = StepSeries(
        np.array([0.0, 1.0, 2.0]),
        np.array([2.0, 4.0, 6.0]),
        np.array([2, 4, 6]),
        np.array([1, 2, 3]),
    )
    b = StepSeries(np.array([1.0, 2.0]), np.array([2.0, 4.0]), np.array([2, 2]), np.array([1, 1]))
    averaged = average_runs([a, b])
    np.testing.assert_allclose(averaged.t, [1.0, 2.0])
    np.testing.assert_allclose(averaged.mean, [6.0 / 6, 10.0 / 8])  # summed NEES / summed dof


def test_average_runs_flags_an_overconfident_estimator() -> None:
    rng = np.random.default_rng(5)
    steps, dof = 200, 3
    t = np.arange(steps, dtype=float)
    # errors twice the stated sigma: NEES four times chi-square
    runs = [
        StepSeries(
            t, 4.0 * rng.chisquare(dof, steps), np.full(steps, dof), np.ones(steps, dtype=int)
        )
        for _ in range(20)
    ]
    assert average_runs(runs).inside_fraction < 0.05
    honest = [
        StepSeries(t, rng.chisquare(dof, steps), np.full(steps, dof), np.ones(steps, dtype=int))
        for _ in range(20)
    ]
    assert average_runs(honest).inside_fraction > 0.85


def test_cost_column_is_the_whole_run_not_the_median_step() -> None:
    """A smoother's median step is an IMU sample; its cost is in keyframes and the finish.
    The table's cost column is the run's wall clock (sim:aghili-rover, seed 3: batch
    0.0187 ms median step, 67.4 s a run; ekf-slam 0.154 ms, 1.02 s)."""
    rows = [
        PairSummary(
            "sim:x",
            name,
            name,
            "ok",
            2,
            2,
            None,
            stats={
                "time_per_step_ms_median": Stat(median_ms, 0.0, 2),
                "time_total_s": Stat(total_s, 0.0, 2),
            },
        )
        for name, median_ms, total_s in (("smoother", 0.0187, 67.4), ("filter", 0.154, 1.02))
    ]
    text = markdown_table(rows)
    assert "time/run [s]" in text and "time/step" not in text
    assert "| 67.4 ± 0 |" in text and "| 1.02 ± 0 |" in text
    assert "0.0187" not in text


def test_markdown_says_na_with_the_reason() -> None:
    rows = [
        PairSummary(
            "sim:x",
            "a",
            "a",
            "ok",
            2,
            2,
            None,
            stats={"ate_rmse_m": Stat(1.5, 0.25, 2), "time_per_step_ms_median": Stat(2.0, 0.5, 2)},
        ),
        PairSummary("sim:x", "b", "b", "n/a", 0, 0, "needs imu"),
    ]
    text = markdown_table(rows)
    assert "| sim:x | a | 2 | 1.5 ± 0.25 | " in text
    assert "| sim:x | b | - | n/a |" in text
    assert "- n/a sim:x / b: needs imu" in text


def test_the_smoothed_gps_hold_out_has_its_own_column() -> None:
    """The batch smoother has no causal estimate: its hold-out error is the smoothed one's,
    in its own column (kitti-imu-gps, 60 s, seed 0: causal column blank, smoothed 1.15 m;
    iSAM2 1.66 m causal, 1.15 m smoothed)."""
    rows = [
        PairSummary(
            "kitti-imu-gps",
            name,
            name,
            "ok",
            1,
            1,
            None,
            stats={
                key: Stat(value, None, 1)
                for key, value in (
                    ("gps_holdout_rmse_m", causal),
                    ("gps_holdout_rmse_smoothed_m", smoothed),
                )
                if value is not None
            },
        )
        for name, causal, smoothed in (("isam2", 1.66, 1.1507), ("batch", None, 1.1521))
    ]
    lines = markdown_table(rows).splitlines()
    header = [cell.strip() for cell in lines[0].split("|")]
    causal_at = header.index("GPS hold-out [m]")
    smoothed_at = header.index("GPS hold-out smoothed [m]")
    batch = [cell.strip() for cell in lines[3].split("|")]
    assert batch[causal_at] == "" and batch[smoothed_at] == "1.152"
