"""Degradations are loud: a run that uses many known-id sightings with inflated noise, and
a loader that dropped rows, say so on the screen and in metrics.json."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from datasets.measurements import Sensor
from datasets.sequence import Sequence
from datasets.victoria_park import default_path
from workbench.cli import main
from workbench.degradations import data_warnings


def test_optimistic_odometry_inflating_sightings_is_a_warning(tmp_path: Path, capsys) -> None:
    if not default_path().is_file():
        pytest.skip("gtsam's victoria_park.txt absent")
    out = tmp_path / "run"
    status = main(
        [
            "run",
            "ekf-slam",
            "victoria-park",
            "--data",
            "max_steps=1000",
            "--data",
            "odometry_noise=file",
            "--set",
            "odometry_noise_scale=0.01",
            "--no-plots",
            "--out",
            str(out),
        ]
    )
    err = capsys.readouterr().err
    assert status == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["association_inflated_fraction"] > 0.05
    assert metrics["warnings"] and "ekf-slam on victoria-park" in metrics["warnings"][0]
    assert "warning: ekf-slam on victoria-park:" in err and "used with inflated noise" in err
    assert " t=" in err  # where it was worst


def test_dropped_rows_are_listed_with_their_names() -> None:
    sequence = Sequence(
        name="utias:x#robot1",
        dimension=2,
        sensors=frozenset({Sensor.ODOMETRY}),
        stream=lambda: iter(()),
        counts={"stale_repeats": 3, "unknown_barcodes": 0},
        warnings=("w",),
    )
    lines = data_warnings(sequence)
    assert lines == [
        "utias:x#robot1: rows dropped or repaired by the loader: stale repeats 3",
        "utias:x#robot1: w",
    ]


def test_contested_single_hypothesis_association_is_a_warning() -> None:
    """A run whose geometric decisions had another interpretation in reach more often than
    CONTESTED_WARNING_FRACTION warns; one under it, or one decided by ids, does not."""
    from datasets.estimate import AssociationDecision, EstimateRecorder
    from datasets.sequence import Sequence
    from workbench.degradations import CONTESTED_WARNING_FRACTION, association_warnings
    from workbench.metrics.summary import contested_fraction

    sequence = Sequence("bag:x", 2, frozenset(), lambda: iter(()))

    def run(contested: int, judged: int = 100):
        recorder = EstimateRecorder(2)
        recorder.pose(0.0, np.zeros(2), 0.0, None)
        for j in range(judged):
            alternatives = 1 if j < contested else 0
            recorder.association(float(j), 0, j, AssociationDecision.MATCHED, "", 1.0, alternatives)
        return recorder.build()

    many = run(int(100 * CONTESTED_WARNING_FRACTION) + 5)
    (line,) = association_warnings(many, sequence, "ekf-slam")
    assert (
        "ekf-slam on bag:x" in line and "another interpretation" in line and "ekf-slam-mht" in line
    )
    assert contested_fraction(many.diagnostics) == pytest.approx(CONTESTED_WARNING_FRACTION + 0.05)
    assert association_warnings(run(int(100 * CONTESTED_WARNING_FRACTION) - 5), sequence, "x") == []
    by_ids = run(0, judged=0)
    assert contested_fraction(by_ids.diagnostics) is None
