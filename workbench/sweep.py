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

import json
import os
import time
import traceback
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

from datasets.errors import InputError
from workbench.suites import (
    DatasetSpec,
    EstimatorSpec,
    Suite,
    available_parts,
    format_options,
    prepare_dataset,
)

REQUEST_FILE = "bench_request.json"
ERROR_FILE = "error.json"
METRICS_FILE = "metrics.json"  # run_folder.METRICS_FILE, without importing matplotlib here

# One BLAS/OpenMP thread per worker: the workers already fill the cores, and a fixed thread
# count keeps floating-point reductions identical between local and Dask workers.
_SINGLE_THREAD_ENVIRONMENT = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}


# ---------------------------------------------------------------------------- the plan


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


def probe_dataset(
    name: str, options: tuple[tuple[str, str], ...], estimators: tuple[str, ...]
) -> DatasetProbe:
    """Load a dataset once (seed 0) and say which estimators can run on it (worker task)."""
    from workbench.registry import estimator_entry, load_dataset
    from workbench.runner import check_compatible

    try:
        sequence = load_dataset(name, 0, dict(options))
    except Exception as error:  # noqa: BLE001 - any loader failure skips the dataset with a note
        return DatasetProbe(error=_one_line(error))
    compatible: dict[str, str | None] = {}
    for estimator in estimators:
        try:
            check_compatible(estimator, estimator_entry(estimator).load(), sequence)
            compatible[estimator] = None
        except InputError as error:
            compatible[estimator] = str(error)
        except Exception as error:  # noqa: BLE001 - an estimator that fails to import is n/a, with the reason
            compatible[estimator] = f"cannot load estimator: {_one_line(error)}"
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
                f"dataset '{spec.title}' skipped: could not generate its file: {_one_line(error)}"
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


# ---------------------------------------------------------------------------- one cell


@dataclass(frozen=True)
class CellOutcome:
    """How a cell ended: seconds of wall clock, and the error line when it failed."""

    folder: Path
    seconds: float
    error: str | None = None


def _one_line(error: BaseException) -> str:
    text = str(error).strip().splitlines()
    return f"{type(error).__name__}: {text[0] if text else ''}".rstrip(": ")


def _write_json(path: Path, data: Any) -> None:
    from datasets.trajectory_io import write_atomic

    write_atomic(path, json.dumps(data, indent=2, sort_keys=True) + "\n")


def run_cell(cell: Cell, run_plots: bool = False) -> CellOutcome:
    """Run one cell and write its run folder (worker task). Never raises: a failure is
    recorded in ``error.json`` and returned."""
    from workbench.monte_carlo import NEES_FILE, save_run_nees
    from workbench.run_folder import write_run_folder
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
    )
    try:
        result = execute(request)
        save_run_nees(result.estimate, result.sequence, folder / NEES_FILE)
        write_run_folder(result, folder, plots=run_plots)  # writes metrics.json last
    except Exception as error:  # noqa: BLE001 - one failed run must not stop the sweep
        message = _one_line(error)
        _write_json(folder / ERROR_FILE, {"error": message, "traceback": traceback.format_exc()})
        return CellOutcome(folder, time.perf_counter() - start, message)
    return CellOutcome(folder, time.perf_counter() - start)


# ---------------------------------------------------------------------------- backends


class Backend(Protocol):
    def submit(self, function: Callable[..., Any], *args: Any) -> Any: ...

    def as_completed(self, futures: Iterable[Any]) -> Iterator[Any]: ...

    def close(self) -> None: ...


def _exit_with_sweep(sweep_pid: int, poll_s: float = 0.5) -> None:
    """Worker initializer: exit as soon as the sweep's main process is gone.

    A killed sweep must leave no worker behind that would go on writing a run folder while
    the next sweep redoes it. Neither the pool nor the OS does this for us: a worker learns
    of its pool's death only between tasks, and a fork-server worker's parent is the fork
    server, which itself waits for its workers (they hold its liveness pipe). So a daemon
    thread polls the main process and ends the worker with ``os._exit``; every file of a
    run folder is written atomically, so nothing half-written is left behind."""
    import threading

    def watch() -> None:
        while True:
            time.sleep(poll_s)
            try:
                os.kill(sweep_pid, 0)
            except ProcessLookupError:
                os._exit(1)
            except PermissionError:
                pass  # exists, owned by someone else (cannot happen for our own parent)

    threading.Thread(target=watch, name="exit-with-sweep", daemon=True).start()


class LocalBackend:
    """Local worker processes (``concurrent.futures.ProcessPoolExecutor``).

    Workers start from a fork server (a clean process, not a fork of this one with its
    progress-bar thread) with one BLAS thread each."""

    def __init__(self, workers: int | None = None) -> None:
        import concurrent.futures
        import multiprocessing

        self.workers = max(1, workers or os.cpu_count() or 1)
        os.environ.update(_SINGLE_THREAD_ENVIRONMENT)  # inherited by the fork server
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(
            ["workbench.sweep", "workbench.runner", "workbench.monte_carlo"]
        )
        self._executor = concurrent.futures.ProcessPoolExecutor(
            self.workers, mp_context=context, initializer=_exit_with_sweep, initargs=(os.getpid(),)
        )

    def submit(self, function: Callable[..., Any], *args: Any) -> Any:
        return self._executor.submit(function, *args)

    def as_completed(self, futures: Iterable[Any]) -> Iterator[Any]:
        import concurrent.futures

        return concurrent.futures.as_completed(list(futures))

    def close(self) -> None:
        self._executor.shutdown(wait=True, cancel_futures=True)

    def describe(self) -> str:
        return f"{self.workers} local process(es)"


class DaskBackend:
    """An existing Dask distributed scheduler at ``address`` (``tcp://host:8786``)."""

    def __init__(self, address: str) -> None:
        from distributed import Client

        try:
            self._client = Client(address, timeout="20s")
        except (OSError, TimeoutError) as error:
            raise InputError(
                f"--scheduler {address}: cannot connect to a Dask scheduler ({_one_line(error)})"
            ) from None
        self.address = address

    def submit(self, function: Callable[..., Any], *args: Any) -> Any:
        return self._client.submit(function, *args, pure=False)

    def as_completed(self, futures: Iterable[Any]) -> Iterator[Any]:
        from distributed import as_completed

        return iter(as_completed(list(futures)))

    def close(self) -> None:
        self._client.close()

    def describe(self) -> str:
        return f"Dask scheduler {self.address}"


def make_backend(scheduler: str | None, workers: int | None) -> LocalBackend | DaskBackend:
    """Dask when a scheduler address is given, local processes otherwise."""
    return DaskBackend(scheduler) if scheduler else LocalBackend(workers)


# ---------------------------------------------------------------------------- the sweep


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
    run_plots: bool = False,
    on_done: Callable[[Cell, CellOutcome], None] | None = None,
    cells: list[Cell] | None = None,
) -> SweepSummary:
    """Run every unfinished cell of the plan (or the given ``cells``) on the backend;
    ``on_done`` after each."""
    pending, skipped = pending_cells(plan)
    if cells is not None:
        pending = cells
    futures = {backend.submit(run_cell, cell, run_plots): cell for cell in pending}
    failed = []
    for future in backend.as_completed(futures):
        cell = futures[future]
        outcome = future.result()
        if outcome.error is not None:
            failed.append(outcome)
        if on_done is not None:
            on_done(cell, outcome)
    return SweepSummary(skipped, len(pending), tuple(failed))


def describe_cells(plan: Plan) -> list[str]:
    """One line per (dataset, estimator) pair: seeds to run or why not (for logs)."""
    lines = []
    for dataset in plan.datasets:
        for estimator in plan.estimators:
            reason = plan.not_applicable_reason(dataset, estimator)
            options = format_options(dataset.options + estimator.overrides)
            status = (
                f"n/a ({reason})" if reason else f"{len(plan.cells_of(dataset, estimator))} run(s)"
            )
            lines.append(
                f"{dataset.title} / {estimator.title} {options}: {status}".replace("  ", " ")
            )
    return lines
