"""One cell of a sweep: run it and write its run folder (the worker task).

A cell is finished when its ``metrics.json`` exists (``run_folder`` writes it last) and its
``bench_request.json`` (written first) describes the same request. A failed run writes
``error.json`` instead of ``metrics.json`` and is tried again by the next sweep.
"""

from __future__ import annotations

import time
import traceback
from dataclasses import dataclass
from pathlib import Path

from datasets.errors import one_line
from workbench.run_files import REQUEST_FILE
from workbench.sweep.plan import Cell


@dataclass(frozen=True)
class CellOutcome:
    """How a cell ended: seconds of wall clock, and the error line when it failed."""

    folder: Path
    seconds: float
    error: str | None = None


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
        # the folder is replaced as a whole: a kill leaves the earlier run or this one
        write_run_folder(result, folder, plot_formats, {REQUEST_FILE: cell.request_record()})
    except Exception as error:  # noqa: BLE001 - one failed run must not stop the sweep
        message = one_line(error)
        write_failed_run(folder, cell.request_record(), message, traceback.format_exc())
        return CellOutcome(folder, time.perf_counter() - start, message)
    return CellOutcome(folder, time.perf_counter() - start)
