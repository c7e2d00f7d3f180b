"""``workbench report`` pools only runs of one experiment (issue 36): runs that differ in a
dataset or estimator option, or in the code's revision, are separate rows labelled by what
differs; the same run twice is an error naming both folders."""

from __future__ import annotations

import csv
import shutil
from pathlib import Path

from workbench.cli import main

RUN = ["run", "ekf-slam", "sim:circle", "--no-plots"]


def _rows(out: Path) -> dict[tuple[str, str], dict[str, str]]:
    with (out / "table.csv").open() as stream:
        return {(row["dataset"], row["estimator"]): row for row in csv.DictReader(stream)}


def test_runs_that_differ_in_a_dataset_option_are_separate_rows(tmp_path: Path, capsys) -> None:
    for seed, duration in ((0, "4"), (1, "4"), (0, "5")):
        out = tmp_path / "runs" / f"d{duration}-s{seed}"
        argv = [*RUN, "--seed", str(seed), "--data", f"duration_s={duration}"]
        assert main([*argv, "--out", str(out)]) == 0
    report = tmp_path / "report"
    assert main(["report", str(tmp_path / "runs"), "--no-plots", "--out", str(report)]) == 0
    printed = capsys.readouterr().out
    rows = _rows(report)
    assert rows[("sim:circle [duration_s=4]", "ekf-slam")]["runs"] == "2"
    assert rows[("sim:circle [duration_s=5]", "ekf-slam")]["runs"] == "1"
    assert "2 experiments, one row each (they differ in duration_s)" in printed


def test_runs_that_differ_in_an_estimator_option_are_labelled_by_it(tmp_path: Path) -> None:
    for gate in ("0.95", "0.99"):
        out = tmp_path / "runs" / gate
        argv = [*RUN, "--data", "duration_s=3", "--set", f"gate_probability={gate}"]
        assert main([*argv, "--out", str(out)]) == 0
    report = tmp_path / "report"
    assert main(["report", str(tmp_path / "runs"), "--no-plots", "--out", str(report)]) == 0
    assert set(_rows(report)) == {
        ("sim:circle", "ekf-slam [gate_probability=0.95]"),
        ("sim:circle", "ekf-slam [gate_probability=0.99]"),
    }


def test_the_same_run_twice_is_an_error_naming_both(tmp_path: Path, capsys) -> None:
    first = tmp_path / "runs" / "a"
    assert main([*RUN, "--data", "duration_s=3", "--out", str(first)]) == 0
    shutil.copytree(first, tmp_path / "runs" / "b")
    report = tmp_path / "report"
    assert main(["report", str(tmp_path / "runs"), "--no-plots", "--out", str(report)]) == 2
    (line,) = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert str(first) in line and str(tmp_path / "runs" / "b") in line and "same run" in line
