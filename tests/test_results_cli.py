"""The results layer from the command line: one table from run folders of different
commands; a sweep with a failed run exits non-zero with the table written; files get the
user's umask."""

from __future__ import annotations

import csv
import os
import stat
from pathlib import Path

import yaml

from workbench.cli import main


def _rows(folder: Path) -> list[dict[str, str]]:
    return list(csv.DictReader((folder / "table.csv").open()))


def test_report_compares_run_folders_of_different_commands(tmp_path: Path, capsys) -> None:
    run_dir, bench_dir, report_dir = tmp_path / "run", tmp_path / "bench", tmp_path / "report"
    assert main(["run", "ekf-slam", "sim:circle", "--data", "duration_s=4", "--no-plots",
                 "--out", str(run_dir)]) == 0  # fmt: skip
    assert main(["bench", "tiny", "--runs", "1", "--dataset", "sim:circle", "--estimator",
                 "dead-reckoning", "--no-plots", "--out", str(bench_dir)]) == 0  # fmt: skip
    assert (
        main(["report", str(run_dir), str(bench_dir), "--no-plots", "--out", str(report_dir)]) == 0
    )
    capsys.readouterr()
    rows = _rows(report_dir)
    assert sorted((row["dataset"], row["estimator"]) for row in rows) == [
        ("sim:circle", "dead-reckoning"),
        ("sim:circle", "ekf-slam"),
    ]
    assert all(row["ate_rmse_m"] for row in rows)
    assert (report_dir / "table.tex").read_text().count("sim:circle") >= 1


def test_a_sweep_with_a_failed_run_exits_3_and_still_writes_the_table(
    tmp_path: Path, capsys
) -> None:
    suite = {
        "description": "one run fails: dead reckoning refuses the 10 ms IMU gaps",
        "runs": 1,
        "datasets": [{"name": "sim:circle", "data": {"duration_s": 2}}],
        "estimators": ["ekf-slam", {"name": "dead-reckoning", "set": {"max_gap_s": 0.001}}],
    }
    suite_file = tmp_path / "failing.yaml"
    suite_file.write_text(yaml.safe_dump(suite))
    out = tmp_path / "bench"
    assert main(["bench", str(suite_file), "--out", str(out), "--no-plots"]) == 3
    captured = capsys.readouterr()
    assert "1 run(s) failed" in captured.err
    rows = {row["estimator"]: row for row in _rows(out)}
    assert rows["ekf-slam"]["status"] == "ok" and rows["ekf-slam"]["ate_rmse_m"]
    assert rows["dead-reckoning"]["status"] == "failed"
    assert "max_gap_s" in (out / "table.md").read_text()


def test_output_files_follow_the_umask(tmp_path: Path, capsys) -> None:
    previous = os.umask(0o022)
    try:
        assert main(["run", "ekf-slam", "sim:circle", "--data", "duration_s=2",
                     "--out", str(tmp_path / "run")]) == 0  # fmt: skip
    finally:
        os.umask(previous)
    capsys.readouterr()
    modes = {
        path.relative_to(tmp_path).as_posix(): stat.S_IMODE(path.stat().st_mode)
        for path in (tmp_path / "run").rglob("*")
    }
    assert len(modes) > 10
    for name, mode in modes.items():
        expected = 0o755 if (tmp_path / name).is_dir() else 0o644
        assert mode == expected, (name, oct(mode))
