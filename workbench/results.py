"""Reading a sweep's run folders back, pair by pair, for the tables and the plots."""

from __future__ import annotations

import json
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np

from workbench.monte_carlo import (
    BLOCKS,
    NEES_FILE,
    AveragedSeries,
    ErrorSeries,
    RunNees,
    average_runs,
    load_error_series,
    load_run_nees,
)
from workbench.suites import DatasetSpec, EstimatorSpec
from workbench.sweep.plan import ERROR_FILE, METRICS_FILE, Cell, Plan


@dataclass(frozen=True)
class RunSeries:
    """Per-step arrays of one run from its ``estimate.npz`` (empty arrays when absent).

    Attributes:
        timing_t, timing_seconds: wall clock per processed measurement [s].
        count_t, count: landmarks in the state after each scan.
        nis_t, nis, nis_dof: one entry per innovation.
        final_landmarks: size of the final map (None without a map or counts).
    """

    timing_t: np.ndarray
    timing_seconds: np.ndarray
    count_t: np.ndarray
    count: np.ndarray
    nis_t: np.ndarray
    nis: np.ndarray
    nis_dof: np.ndarray
    final_landmarks: int | None


def read_run_series(folder: Path) -> RunSeries:
    """The per-step arrays of the run folder ``folder``."""
    empty = np.zeros(0)
    with np.load(Path(folder) / "estimate.npz") as data:

        def get(key: str) -> np.ndarray:
            return data[key] if key in data.files else empty

        count = get("diag_landmark_count")
        if "landmarks_ids" in data.files:
            final: int | None = int(len(data["landmarks_ids"]))
        else:
            final = int(count[-1]) if len(count) else None
        return RunSeries(
            get("timing_t"),
            get("timing_seconds"),
            get("diag_landmark_count_t"),
            count,
            get("diag_nis_t"),
            get("diag_nis"),
            get("diag_nis_dof"),
            final,
        )


@dataclass(frozen=True)
class PairResults:
    """The runs of one (dataset, estimator) pair.

    Attributes:
        cells: the planned cells, by seed.
        finished: the cells whose run folder is complete.
        errors: the first line of ``error.json`` of every failed cell.
        not_applicable: why the pair cannot run, or None.
    """

    dataset: DatasetSpec
    estimator: EstimatorSpec
    cells: tuple[Cell, ...]
    finished: tuple[Cell, ...]
    errors: tuple[str, ...]
    not_applicable: str | None

    @cached_property
    def metrics(self) -> tuple[dict[str, Any], ...]:
        return tuple(json.loads((cell.folder / METRICS_FILE).read_text()) for cell in self.finished)

    def values(self, key: str) -> list[float]:
        """The finite values of a ``metrics.json`` key over the finished runs."""
        found = []
        for metrics in self.metrics:
            value = metrics.get(key)
            if (
                isinstance(value, (int, float))
                and not isinstance(value, bool)
                and np.isfinite(value)
            ):
                found.append(float(value))
        return found

    @cached_property
    def run_nees(self) -> tuple[dict[str, RunNees], ...]:
        return tuple(
            load_run_nees(cell.folder / NEES_FILE)
            for cell in self.finished
            if (cell.folder / NEES_FILE).is_file()
        )

    @cached_property
    def averaged_nees(self) -> dict[str, AveragedSeries]:
        """NEES averaged over the finished runs, per block (``monte_carlo.average_runs``)."""
        averaged = {}
        for block in BLOCKS:
            runs = [run[block] for run in self.run_nees if block in run]
            found = average_runs(runs) if runs else None
            if found is not None:
                averaged[block] = found
        return averaged

    @cached_property
    def series(self) -> tuple[RunSeries, ...]:
        return tuple(read_run_series(cell.folder) for cell in self.finished)

    def first_errors(self) -> dict[str, ErrorSeries]:
        """Error series of the first finished run (lowest seed), or {}."""
        if not self.finished or not (self.finished[0].folder / NEES_FILE).is_file():
            return {}
        return load_error_series(self.finished[0].folder / NEES_FILE)


def _error_line(folder: Path) -> str | None:
    try:
        return str(json.loads((folder / ERROR_FILE).read_text()).get("error"))
    except (OSError, ValueError):
        return None


def collect(plan: Plan) -> list[PairResults]:
    """One ``PairResults`` per (dataset, estimator) of the plan, in suite order."""
    pairs = []
    for dataset in plan.datasets:
        for estimator in plan.estimators:
            cells = tuple(sorted(plan.cells_of(dataset, estimator), key=lambda cell: cell.seed))
            finished = tuple(cell for cell in cells if cell.is_finished())
            errors = tuple(
                f"seed {cell.seed}: {line}"
                for cell in cells
                if cell not in finished and (line := _error_line(cell.folder))
            )
            pairs.append(
                PairResults(
                    dataset,
                    estimator,
                    cells,
                    finished,
                    errors,
                    plan.not_applicable_reason(dataset, estimator),
                )
            )
    return pairs
