"""UTIAS recordings damaged for meaning, not form (issue 40): a row faster than any robot,
odometry columns swapped, a Vicon row 1000 m away, a Barcodes.dat of another dataset. Each
is an error naming the file, or a run that says what it dropped or doubts and still scores
right. The recordings are robot 1 of the shared dataset 1 (and robot 2, the calibration's
reference), rewritten into ``tmp_path``."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

import pytest

from workbench.cli import main

UTIAS = Path(__file__).resolve().parents[2] / "shared" / "data" / "utias-mrclam1"
pytestmark = pytest.mark.skipif(not UTIAS.is_dir(), reason=f"UTIAS data absent ({UTIAS})")

RUN = ["run", "dead-reckoning", "--no-plots", "--data", "duration_s=120"]
FAST = ["--data", "calibration=none"]  # nothing to fit: robot 1 alone is read


def _folder(tmp_path: Path, name: str, change: Callable[[list[str]], list[str]]) -> Path:
    """Robot 1 with ``change`` applied to the rows of file ``name``; robot 2 beside it."""
    folder = tmp_path / "mrclam"
    folder.mkdir()
    for path in UTIAS.iterdir():
        if path.name.startswith("Robot1_") and path.name == name:
            lines = path.read_text().splitlines()
            header = [line for line in lines if line.startswith("#")]
            rows = change([line for line in lines if not line.startswith("#")])
            (folder / path.name).write_text("\n".join(header + rows) + "\n")
        elif path.name.startswith(("Robot1_", "Robot2_")) or not path.name.startswith("Robot"):
            (folder / path.name).symlink_to(path)
    return folder


def _run(argv: list[str], capsys) -> tuple[int, list[str], list[str]]:
    status = main(argv)
    err = capsys.readouterr().err.splitlines()
    assert not [line for line in err if "Traceback" in line or "internal error" in line]
    return (
        status,
        [line for line in err if line.startswith("error:")],
        [line for line in err if line.startswith("warning:")],
    )


def _fields(row: str) -> list[str]:
    return row.split()


def test_a_row_faster_than_any_robot_is_dropped_and_said(tmp_path: Path, capsys) -> None:
    def fast(rows: list[str]) -> list[str]:
        t, _, omega = _fields(rows[3000])
        rows[3000] = f"{t} 1000000.0 {omega}"
        return rows

    folder = _folder(tmp_path, "Robot1_Odometry.dat", fast)
    out = tmp_path / "run"
    status, errors, warnings = _run(
        [*RUN, f"utias:{folder}#robot1", *FAST, "--out", str(out)], capsys
    )
    assert status == 0 and errors == []
    assert any("odometry implausible 1" in line for line in warnings)
    clean = tmp_path / "clean"
    assert main([*RUN, f"utias:{UTIAS}#robot1", *FAST, "--out", str(clean)]) == 0
    import json

    read = lambda folder: json.loads((folder / "metrics.json").read_text())["ate_rmse_m"]  # noqa: E731
    assert read(out) == pytest.approx(read(clean), rel=1e-2)  # the row, not the run, is gone


def test_many_implausible_rows_are_an_error_naming_the_file(tmp_path: Path, capsys) -> None:
    def millimetres(rows: list[str]) -> list[str]:  # mm/s written where m/s belongs
        return [f"{t} {float(v) * 1000:.4f} {w}" for t, v, w in map(_fields, rows)]

    folder = _folder(tmp_path, "Robot1_Odometry.dat", millimetres)
    status, errors, _ = _run(
        [*RUN, f"utias:{folder}#robot1", *FAST, "--out", str(tmp_path / "o")], capsys
    )
    assert status == 2 and len(errors) == 1
    assert "Robot1_Odometry.dat" in errors[0] and "max_speed_m_s" in errors[0]
    assert not (tmp_path / "o").exists()


def test_swapped_odometry_columns_are_doubted_out_loud(tmp_path: Path, capsys) -> None:
    def swap(rows: list[str]) -> list[str]:
        return [f"{t} {w} {v}" for t, v, w in map(_fields, rows)]

    folder = _folder(tmp_path, "Robot1_Odometry.dat", swap)
    argv = [*RUN, f"utias:{folder}#robot1", "--data", "odometry_noise=white"]
    argv += ["--data", "sighting_correlation=none", "--data", "detection_probability=none"]
    status, _, warnings = _run([*argv, "--out", str(tmp_path / "o")], capsys)
    assert status == 0
    assert any("odometry and Vicon disagree" in line and "swapped" in line for line in warnings)


def test_a_vicon_row_far_away_is_scored_nowhere(tmp_path: Path, capsys) -> None:
    def far(rows: list[str]) -> list[str]:
        t, _, y, heading = _fields(rows[2000])
        rows[2000] = f"{t} 1000.0 {y} {heading}"
        return rows

    folder = _folder(tmp_path, "Robot1_Groundtruth.dat", far)
    status, _, warnings = _run(
        [*RUN, f"utias:{folder}#robot1", *FAST, "--out", str(tmp_path / "o")], capsys
    )
    assert status == 0
    assert any("Vicon not trusted in 1 interval" in line for line in warnings)


def test_a_barcode_file_of_another_dataset_is_an_error(tmp_path: Path, capsys) -> None:
    def unknown(rows: list[str]) -> list[str]:
        return [f"{t} 99 {r} {b}" for t, _, r, b in map(_fields, rows)]

    folder = _folder(tmp_path, "Robot1_Measurement.dat", unknown)
    argv = [*RUN, f"utias:{folder}#robot1", "--data", "calibration=own-truth"]
    status, errors, _ = _run([*argv, "--out", str(tmp_path / "o")], capsys)
    assert status == 2 and len(errors) == 1
    assert "Robot1_Measurement.dat" in errors[0] and "Barcodes.dat" in errors[0]
