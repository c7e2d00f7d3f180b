"""The ``real`` suite (every shared UTIAS robot, with ids and without, against iSAM2's causal
estimate) and the machinery it rests on: ``{shared}`` dataset names and the ``reference``
column (``ATE ÷ ref``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from workbench.cli import main
from workbench.suite_files import get_suite
from workbench.suites import SHARED_DATA_VARIABLE, shared_data_folder

UTIAS = Path(__file__).resolve().parents[2] / "shared" / "data" / "utias-mrclam1"


def test_the_real_suite_covers_every_robot_with_ids_and_without() -> None:
    suite = get_suite("real")
    assert suite.reference == "smoother-isam2"
    names = sorted((spec.name, dict(spec.options)["ids"]) for spec in suite.datasets)
    assert names == sorted(
        (f"utias:{{shared}}/utias-mrclam1#robot{robot}", ids)
        for robot in range(1, 6)
        for ids in ("true", "false")
    )
    estimators = {spec.name for spec in suite.estimators}
    assert {"ekf-slam", "sensor-based", "ekf-slam-mht", "smoother-isam2", "smoother-batch"} <= (
        estimators
    )


def test_shared_names_follow_the_variable(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv(SHARED_DATA_VARIABLE, str(tmp_path))
    assert shared_data_folder() == tmp_path
    spec = get_suite("real").datasets[0]
    assert spec.resolved_name(tmp_path / "out") == f"utias:{tmp_path}/utias-mrclam1#robot1"


@pytest.mark.study
@pytest.mark.skipif(not UTIAS.is_dir(), reason=f"UTIAS MRCLAM data absent (expected at {UTIAS})")
def test_every_row_is_divided_by_the_references_ate(tmp_path: Path, monkeypatch) -> None:
    """A two-estimator slice of the real suite on 60 s of robot 4: the ratio column is each
    row's ATE over iSAM2's on the same dataset (iSAM2's own reads 1)."""
    import pandas as pd

    monkeypatch.setenv(SHARED_DATA_VARIABLE, str(UTIAS.parent))
    suite = tmp_path / "slice.yaml"
    suite.write_text(
        "runs: 1\nreference: smoother-isam2\ndatasets:\n"
        "  - name: utias:{shared}/utias-mrclam1#robot4\n    seeded: false\n"
        "    data: {duration_s: 60}\n"
        "estimators:\n  - dead-reckoning\n  - smoother-isam2\n"
    )
    out = tmp_path / "out"
    assert main(["bench", str(suite), "--no-plots", "--workers", "1", "--out", str(out)]) == 0
    table = pd.read_csv(out / "table.csv").set_index("estimator")
    assert table.loc["smoother-isam2", "ate_over_reference"] == pytest.approx(1.0)
    expected = table.loc["dead-reckoning", "ate_rmse_m"] / table.loc["smoother-isam2", "ate_rmse_m"]
    assert table.loc["dead-reckoning", "ate_over_reference"] == pytest.approx(expected, rel=1e-4)
    markdown = (out / "table.md").read_text()
    assert "ATE ÷ ref" in markdown and "over smoother-isam2's on the same dataset" in markdown


def test_a_reference_outside_the_suite_is_an_error(tmp_path: Path, capsys) -> None:
    suite = tmp_path / "bad.yaml"
    suite.write_text("reference: smoother-isam2\ndatasets: [sim:circle]\nestimators: [ekf-slam]\n")
    assert main(["bench", str(suite), "--out", str(tmp_path / "o")]) == 2
    assert (
        "reference 'smoother-isam2' is not one of the suite's estimators" in capsys.readouterr().err
    )
