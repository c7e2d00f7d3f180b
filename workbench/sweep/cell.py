"""One cell of a sweep: run it and write its run folder (the worker task).

A cell is finished when its ``metrics.json`` exists (``run_folder`` writes it last) and its
``bench_request.json`` (written first) describes the same request. A failed run writes
``error.json`` instead of ``metrics.json`` and is tried again by the next sweep.
"""

from __future__ import annotations

import json
import time
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from datasets.errors import one_line
from workbench.sweep.plan import ERROR_FILE, METRICS_FILE, REQUEST_FILE, Cell


@dataclass(frozen=True)
class CellOutcome:
    """How a cell ended: seconds of wall clock, and the error line when it failed."""

    folder: Path
    seconds: float
    error: str | None = None


def _write_json(path: Path, data: Any) -> None:
    from datasets.trajectory_io import write_atomic

    write_atomic(path, json.dumps(data, indent=2, sort_keys=True) + "\n")


def run_cell(cell: Cell, plot_formats: tuple[str, ...] = ()) -> CellOutcome:
    """Run one cell and write its run folder, with its own figures in ``plot_formats`` (none
    by default), as a worker task. Never raises: a failure is recorded in ``error.json``
    and returned."""
    from workbench.run_folder import write_failed_run, write_run_folder
    from workbench.runner import RunRequest, execute

    start = time.perf_counter()
    folder = cell.folder
    if cell.is_finished():  # done meanwhile, e.g. by another sweep into the same folder
        return CellOutcome(folder, 0.0)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / METRICS_FILE).unlink(missing_ok=True)
    (folder / ERROR_FILE).unlink(missing_ok=True)
    _write_json(folder / REQUEST_FILE, cell.request_record())
    request = RunRequest(
        estimator=cell.estimator.name,
        dataset=cell.dataset_name,
        seed=cell.seed,
        overrides=cell.overrides,
        data_options=cell.dataset.options,
        dataset_label=cell.dataset.title,
        estimator_label=cell.estimator.title,
    )
    try:
        result = execute(request)
        write_run_folder(result, folder, plot_formats)  # writes metrics.json last
    except Exception as error:  # noqa: BLE001 - one failed run must not stop the sweep
        message = one_line(error)
        write_failed_run(folder, cell.request_record(), message, traceback.format_exc())
        return CellOutcome(folder, time.perf_counter() - start, message)
    return CellOutcome(folder, time.perf_counter() - start)
