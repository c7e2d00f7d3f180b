"""Monte Carlo sweeps: plan the (dataset, estimator, seed) cells of a suite, run them on
local processes or a Dask cluster, resume what a killed sweep left.

Layout under the output folder ``OUT``::

    OUT/runs/<dataset>/<estimator>/seed-<n>/   one run folder per cell (``run_folder``)
    OUT/data/                                  files a suite generates (the lidar bag)

A cell is finished when its ``metrics.json`` exists (``run_folder`` writes it last) and its
``bench_request.json`` (written first) describes the same request: a re-run of the same
sweep skips finished cells and redoes the rest; a cell whose suite definition changed is
redone. Seeds are fixed per cell (run n of a seeded dataset uses seed n), so a resumed
sweep gives the same numbers as an uninterrupted one (timing aside). A failed run writes
``error.json`` instead of ``metrics.json`` and is tried again by the next sweep.

Work goes to a ``concurrent.futures.ProcessPoolExecutor`` (``LocalBackend``, the default)
or to an existing Dask distributed scheduler (``DaskBackend``, ``--scheduler ADDRESS``);
both run the same top-level functions, ``probe_dataset`` and ``run_cell``.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

from workbench.sweep.backends import Backend
from workbench.sweep.cell import CellOutcome, run_cell
from workbench.sweep.plan import Cell, Plan


@dataclass(frozen=True)
class SweepSummary:
    """Counts of a finished sweep: cells skipped (already done), run, and failed."""

    skipped: int
    ran: int
    failed: tuple[CellOutcome, ...]


def pending_cells(plan: Plan) -> tuple[list[Cell], int]:
    """The cells still to run, and how many are finished already."""
    pending = [cell for cell in plan.cells if not cell.is_finished()]
    return pending, len(plan.cells) - len(pending)


def run_sweep(
    plan: Plan,
    backend: Backend,
    run_plot_formats: tuple[str, ...] = (),
    on_done: Callable[[Cell, CellOutcome], None] | None = None,
    cells: list[Cell] | None = None,
) -> SweepSummary:
    """Run every unfinished cell of the plan (or the given ``cells``) on the backend, each
    run folder with its own figures in ``run_plot_formats`` (none when empty); ``on_done``
    after each."""
    pending, skipped = pending_cells(plan)
    if cells is not None:
        pending = cells
    futures = {backend.submit(run_cell, cell, run_plot_formats): cell for cell in pending}
    failed = []
    for future in backend.as_completed(futures):
        cell = futures[future]
        outcome = future.result()
        if outcome.error is not None:
            failed.append(outcome)
        if on_done is not None:
            on_done(cell, outcome)
    return SweepSummary(skipped, len(pending), tuple(failed))
