"""The plan of a sweep: the (dataset, estimator, seed) cells of a suite, their run folders,
and the pairs that cannot run (probed once per dataset on the backend).

Seeds are fixed per cell (run n of a seeded dataset uses seed n), so a resumed sweep gives
the same numbers as an uninterrupted one (timing aside). Submission order is seed-major, so
an interrupted sweep has a first run of every pair early.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from datasets.errors import InputError, one_line
from workbench.results.summary import PlannedPair
from workbench.run_files import METRICS_FILE, REQUEST_FILE
from workbench.suites import DatasetSpec, EstimatorSpec, Suite, available_parts, prepare_dataset

if TYPE_CHECKING:
    from workbench.sweep.backends import Backend


@dataclass(frozen=True)
class Cell:
    """One run of the sweep: an estimator on a dataset with one seed, and its run folder."""

    dataset: DatasetSpec
    dataset_name: str  # with ``{data}`` resolved
    estimator: EstimatorSpec
    seed: int
    folder: Path

    @property
    def overrides(self) -> tuple[tuple[str, str], ...]:
        """The estimator's ``--set`` options, then those the dataset adds for it."""
        return self.estimator.overrides + self.dataset.options_for(self.estimator.name)

    def request_record(self) -> dict[str, Any]:
        """What defines the run (compared on resume)."""
        return {
            "dataset": self.dataset_name,
            "dataset_label": self.dataset.title,
            "estimator_label": self.estimator.title,
            "data_options": dict(self.dataset.options),
            "estimator": self.estimator.name,
            "overrides": dict(self.overrides),
            "seed": self.seed,
        }

    def is_finished(self) -> bool:
        """``metrics.json`` exists and ``bench_request.json`` describes this very request."""
        if not (self.folder / METRICS_FILE).is_file():
            return False
        try:
            return json.loads((self.folder / REQUEST_FILE).read_text()) == self.request_record()
        except (OSError, ValueError):
            return False

    def describe(self) -> str:
        return f"{self.estimator.title} on {self.dataset.title}, seed {self.seed}"


@dataclass(frozen=True)
class NotApplicable:
    """A (dataset, estimator) pair that cannot run, and why (the table says n/a)."""

    dataset: DatasetSpec
    estimator: EstimatorSpec
    reason: str


@dataclass(frozen=True)
class DatasetProbe:
    """What planning needs to know of a dataset: its sensors and dimension, or why it
    could not be loaded."""

    sensors: frozenset[str] = frozenset()
    dimension: int = 0
    compatible: dict[str, str | None] = field(default_factory=dict)  # estimator -> None or reason
    error: str | None = None


@dataclass(frozen=True)
class Plan:
    """Every cell of a sweep, in submission order, with the pairs that cannot run."""

    suite: Suite
    runs: int
    out: Path
    datasets: tuple[DatasetSpec, ...]
    estimators: tuple[EstimatorSpec, ...]
    cells: tuple[Cell, ...]
    not_applicable: tuple[NotApplicable, ...]
    notes: tuple[str, ...]

    def cells_of(self, dataset: DatasetSpec, estimator: EstimatorSpec) -> list[Cell]:
        return [
            cell for cell in self.cells if cell.dataset == dataset and cell.estimator == estimator
        ]

    def not_applicable_reason(self, dataset: DatasetSpec, estimator: EstimatorSpec) -> str | None:
        for item in self.not_applicable:
            if item.dataset == dataset and item.estimator == estimator:
                return item.reason
        return None


def run_folder(out: Path, dataset: DatasetSpec, estimator: EstimatorSpec, seed: int) -> Path:
    """``OUT/runs/<dataset>/<estimator>/seed-<n>``."""
    return Path(out) / "runs" / dataset.folder_name / estimator.folder_name / f"seed-{seed}"


def seeds_for(dataset: DatasetSpec, runs: int) -> range:
    """Seeds 0..runs-1 for a simulated dataset; only seed 0 for a fixed recording."""
    return range(runs if dataset.seeded else 1)


def pairs_on_disk(
    suite: Suite, runs: int, labels_on_disk: set[tuple[str, str]]
) -> list[PlannedPair]:
    """The suite's pairs in its order, without probing a dataset (``bench --report-only``):
    the pairs with runs on disk (``(dataset label, estimator label)``), planned with the
    suite's seeds, and the pairs the suite leaves out, n/a with its reason. A pair with
    neither is left to the planning run to judge (it may be incompatible)."""
    pairs = []
    for dataset in suite.datasets:
        for estimator in suite.estimators:
            reason = dataset.left_out_reason(estimator.name)
            on_disk = (dataset.title, estimator.title) in labels_on_disk
            if reason is None and not on_disk:
                continue
            pairs.append(
                PlannedPair(
                    dataset.title,
                    estimator.title,
                    estimator.name,
                    0 if reason is not None else len(seeds_for(dataset, runs)),
                    reason,
                )
            )
    return pairs


def probe_dataset(
    name: str, options: tuple[tuple[str, str], ...], estimators: tuple[str, ...]
) -> DatasetProbe:
    """Load a dataset once (seed 0) and say which estimators can run on it (worker task)."""
    from workbench.registry import estimator_entry, load_dataset
    from workbench.runner import check_compatible

    try:
        sequence = load_dataset(name, 0, dict(options))
    except Exception as error:  # noqa: BLE001 - any loader failure skips the dataset with a note
        return DatasetProbe(error=one_line(error))
    compatible: dict[str, str | None] = {}
    for estimator in estimators:
        try:
            check_compatible(estimator, estimator_entry(estimator).load(), sequence)
            compatible[estimator] = None
        except InputError as error:
            compatible[estimator] = str(error)
        except Exception as error:  # noqa: BLE001 - an estimator that fails to import is n/a, with the reason
            compatible[estimator] = f"cannot load estimator: {one_line(error)}"
    return DatasetProbe(frozenset(str(s) for s in sequence.sensors), sequence.dimension, compatible)


def plan_sweep(suite: Suite, runs: int, out: Path, backend: Backend) -> Plan:
    """The cells of ``suite`` with ``runs`` seeds each, in ``out`` (datasets are probed on
    the backend, in parallel). Submission order is seed-major, so an interrupted sweep has
    a first run of every pair early."""
    if runs < 1:
        raise InputError(f"--runs must be at least 1, got {runs}")
    out = Path(out).resolve()
    datasets, estimators, notes_found = available_parts(suite)
    notes = list(notes_found)
    data_folder = out / "data"
    prepared: list[DatasetSpec] = []
    for spec in datasets:
        try:
            prepare_dataset(spec, data_folder)
            prepared.append(spec)
        except Exception as error:  # noqa: BLE001 - a generator that fails skips its dataset
            notes.append(
                f"dataset '{spec.title}' skipped: could not generate its file: {one_line(error)}"
            )
    estimator_names = tuple(dict.fromkeys(spec.name for spec in estimators))
    futures = {
        spec: backend.submit(
            probe_dataset, spec.resolved_name(data_folder), spec.options, estimator_names
        )
        for spec in prepared
    }
    probes = {spec: future.result() for spec, future in futures.items()}
    usable = []
    not_applicable = []
    for spec in prepared:
        probe = probes[spec]
        if probe.error is not None:
            notes.append(f"dataset '{spec.title}' skipped: {probe.error}")
            continue
        usable.append(spec)
        for estimator in estimators:
            reason = probe.compatible.get(estimator.name) or spec.left_out_reason(estimator.name)
            if reason is not None:
                not_applicable.append(NotApplicable(spec, estimator, reason))
    cells = []
    for seed in range(runs):
        for spec in usable:
            if seed not in seeds_for(spec, runs):
                continue
            for estimator in estimators:
                if (
                    probes[spec].compatible.get(estimator.name) is None
                    and spec.left_out_reason(estimator.name) is None
                ):
                    cells.append(
                        Cell(
                            spec,
                            spec.resolved_name(data_folder),
                            estimator,
                            seed,
                            run_folder(out, spec, estimator, seed),
                        )
                    )
    return Plan(
        suite,
        runs,
        out,
        tuple(usable),
        estimators,
        tuple(cells),
        tuple(not_applicable),
        tuple(notes),
    )
