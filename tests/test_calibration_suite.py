"""The workbench's self-test, small: every registered estimator on scenarios drawn exactly
from its own model (``workbench bench calibration``, shortened and with 10 runs) reads
``consistent`` in every consistency cell it fills."""

from __future__ import annotations

import csv
from dataclasses import replace

import pytest

from workbench.registry import ESTIMATORS
from workbench.reporting import write_report
from workbench.results.consistency import TABLE_BLOCKS
from workbench.results.runs import load_runs
from workbench.suite_files import get_suite
from workbench.sweep import run_sweep
from workbench.sweep.backends import LocalBackend
from workbench.sweep.plan import plan_sweep

# a study: the second tier (`pytest -m study`, run by .ci/run after the default tier)
pytestmark = pytest.mark.study

RUNS = 10  # the fewest that give a verdict
# Scenario lengths [s]: circle 5, loops 6 (the sweep takes 58 s on the 2-core machine; with
# the loops at 10 s, 82 s, the verdicts the same). The full suite is ``workbench bench
# calibration``.


def _shortened(spec, duration_s: str):
    options = tuple((k, duration_s if k == "duration_s" else v) for k, v in spec.options)
    return replace(spec, options=options)


@pytest.fixture(scope="module")
def calibration_table(tmp_path_factory: pytest.TempPathFactory) -> list[dict[str, str]]:
    out = tmp_path_factory.mktemp("calibration")
    full = get_suite("calibration")
    circle, loop, odometry_loop = full.datasets
    suite = replace(
        full,
        name="calibration-small",
        datasets=(
            _shortened(circle, "5"),
            _shortened(loop, "6"),
            _shortened(odometry_loop, "6"),
        ),
        default_runs=RUNS,
    )
    backend = LocalBackend(2)
    try:
        plan = plan_sweep(suite, RUNS, out, backend)
        summary = run_sweep(plan, backend)
    finally:
        backend.close()
    assert not summary.failed, [outcome.error for outcome in summary.failed]
    write_report(load_runs([out / "runs"]), out, plot_formats=())
    return list(csv.DictReader((out / "table.csv").open()))


def test_every_registered_estimator_is_calibrated_somewhere(calibration_table) -> None:
    calibrated = {row["estimator"] for row in calibration_table if row["status"] == "ok"}
    assert {entry.name for entry in ESTIMATORS} <= calibrated


def test_every_filled_cell_reads_consistent(calibration_table) -> None:
    verdicts = {
        (row["dataset"], row["estimator"], block): row[f"verdict_{block}"]
        for row in calibration_table
        for block in TABLE_BLOCKS
        if row.get(f"verdict_{block}")
    }
    assert len(verdicts) >= 40
    assert {key: v for key, v in verdicts.items() if v != "consistent"} == {}
