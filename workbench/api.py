"""The Python API: what the command line does, for a notebook or a script.

    from workbench import run, compare, load_runs

    filter_run = run("ekf-slam", "sim:circle", seed=1, data={"duration_s": 10}, out="runs/ekf")
    smoother_run = run("smoother-isam2", "sim:circle", seed=1, data={"duration_s": 10},
                       out="runs/isam2")
    table = compare(["runs/ekf", "runs/isam2"])      # pandas DataFrame, table.csv's columns
    runs = load_runs(["runs"])                        # one row per run, metrics.json's keys
    estimate = load_estimate("runs/ekf")              # the datasets.Estimate a folder holds

Options are Python values (``{"gate_probability": 0.99, "velocity_walk_m_s_sqrt_s": [0.02,
0.005]}``), validated exactly as ``--set`` / ``--data`` are.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from datasets.estimate import Estimate
from datasets.sequence import Sequence


@dataclass(frozen=True)
class Run:
    """One run.

    Attributes:
        estimate: what the estimator returned (``datasets.Estimate``).
        sequence: the dataset it ran on (with its ground truth, where known).
        config: the resolved estimator options (a pydantic model).
        metrics: the flat metrics of metrics.json (keys with units), with ``warnings``.
        folder: the run folder, when one was written.
    """

    estimate: Estimate
    sequence: Sequence
    config: Any
    metrics: dict[str, Any]
    folder: Path | None


def _as_text(options: dict[str, Any] | None) -> tuple[tuple[str, str], ...]:
    """Python values as the ``key=value`` text the CLI parses (JSON is YAML)."""
    return tuple(
        (str(key), value if isinstance(value, str) else json.dumps(value))
        for key, value in (options or {}).items()
    )


def run(
    estimator: str,
    dataset: str,
    seed: int = 0,
    options: dict[str, Any] | None = None,
    data: dict[str, Any] | None = None,
    out: str | Path | None = None,
    plots: bool = False,
) -> Run:
    """Run ``estimator`` on ``dataset`` (names as ``workbench list`` shows them); with
    ``out``, write the run folder as ``workbench run`` does. ``InputError`` for bad input."""
    from workbench.run_folder import run_warnings, write_run_folder
    from workbench.runner import RunRequest, execute

    request = RunRequest(
        estimator=estimator,
        dataset=dataset,
        seed=int(seed),
        overrides=_as_text(options),
        data_options=_as_text(data),
    )
    result = execute(request)
    if out is not None:
        folder = Path(out)
        metrics = write_run_folder(result, folder, ("png",) if plots else ())
    else:
        from workbench.metrics.summary import compute_metrics

        folder = None
        metrics = compute_metrics(result.estimate, result.sequence)
        metrics["warnings"] = run_warnings(result)
    return Run(result.estimate, result.sequence, result.config, metrics, folder)


def compare(paths: list[str | Path], out: str | Path | None = None, plots: bool = False):
    """The comparison table of run folders (or folders holding them) as a pandas
    DataFrame, one row per (dataset, estimator), table.csv's columns; with ``out``, also
    write the tables (and, with ``plots``, the figures) as ``workbench report`` does."""
    from workbench.owned_folders import claim_collection, exclusive
    from workbench.reporting import report_rows, write_report
    from workbench.results.runs import load_runs as read_records
    from workbench.results.summary import summary_frame

    records = read_records([Path(p) for p in paths])
    if out is None:
        # the rows workbench report shows: one experiment per row (runs that differ in
        # more than their seed are separate rows, labelled by what differs)
        return summary_frame(report_rows(records).rows)
    with exclusive(Path(out)):
        report = write_report(
            records, claim_collection(Path(out)), plot_formats=("png",) if plots else ()
        )
    return summary_frame(report.rows)


def load_runs(paths: list[str | Path]):
    """Every run under ``paths`` as a pandas DataFrame: one row per run, identity columns
    (dataset, estimator, seed, folder, status) then metrics.json's keys."""
    from workbench.results.runs import load_runs as read_records
    from workbench.results.runs import runs_frame

    return runs_frame(read_records([Path(p) for p in paths]))


def load_estimate(folder: str | Path) -> Estimate:
    """The ``datasets.Estimate`` a run folder holds (its ``estimate.npz`` and
    ``events.json``; ``workbench.results.estimate_file`` says what is kept)."""
    from workbench.results.estimate_file import read_estimate

    return read_estimate(folder)
