"""Run folders read back: any folders, from any command, suite or day.

A run folder is one that holds ``metrics.json`` (a finished run: ``workbench.run_folder``)
or ``error.json`` (a sweep's failed run, with the request it failed on in
``bench_request.json``). ``load_runs`` finds them below the given paths and returns one
``RunRecord`` each; ``runs_frame`` turns them into the tidy table (pandas, one row per run,
the metrics.json keys as columns): the one vocabulary of metrics.json, table.csv and the
Python API.
"""

from __future__ import annotations

import json
from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

from datasets.errors import InputError, one_line
from workbench.results.consistency import (
    ErrorSeries,
    StepSeries,
    load_error_series,
    load_run_consistency,
)
from workbench.run_files import (
    CONFIG_FILE,
    CONSISTENCY_FILE,
    ERROR_FILE,
    ESTIMATE_FILE,
    METRICS_FILE,
    REQUEST_FILE,
)


@dataclass(frozen=True)
class RunRecord:
    """One run folder.

    Attributes:
        folder: where it is.
        dataset, estimator: the registered names (``sim:circle``, ``ekf-slam``).
        dataset_label, estimator_label: the names tables and plots group by (a suite's
            labels, e.g. ``sim:guerreiro-loop (ids=false)``; the names otherwise).
        seed: the dataset seed.
        metrics: the metrics.json dictionary, None when the run failed.
        error: the failure's one line, None when it finished.
        experiment: what defines the run besides its seed, as sorted ``(key, value)`` text
            pairs: ``dataset`` (the resolved name), ``data.KEY`` (its options), ``config.KEY``
            (the estimator's resolved options) and ``revision`` (the code's git revision).
            Runs of one table row differ in nothing but the seed (``results.summary``).
            Empty for a failed run, which never resolved its config: it joins the row of its
            labels.
    """

    folder: Path
    dataset: str
    estimator: str
    dataset_label: str
    estimator_label: str
    seed: int
    metrics: dict[str, Any] | None = field(default=None, compare=False)
    error: str | None = None
    experiment: tuple[tuple[str, str], ...] = field(default=(), compare=False)

    @property
    def finished(self) -> bool:
        return self.metrics is not None

    @cached_property
    def consistency(self) -> dict[str, StepSeries]:
        """The run's NEES/NIS series ({} when the folder has none)."""
        path = self.folder / CONSISTENCY_FILE
        return load_run_consistency(path) if path.is_file() else {}

    @cached_property
    def errors(self) -> dict[str, ErrorSeries]:
        """The run's causal error series ({} when the folder has none)."""
        path = self.folder / CONSISTENCY_FILE
        return load_error_series(path) if path.is_file() else {}


def _read_json(path: Path) -> dict[str, Any]:
    try:
        found = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, ValueError) as error:  # UnicodeDecodeError is a ValueError
        raise InputError(f"{path}: not a readable JSON file ({one_line(error)})") from None
    if not isinstance(found, dict):
        raise InputError(f"{path}: expected a JSON object")
    return found


def _seed(found: dict[str, Any], path: Path) -> int:
    """The record's ``seed`` (0 when absent): a whole number >= 0, as ``--seed`` takes it."""
    seed = found.get("seed") or 0
    if isinstance(seed, bool) or not isinstance(seed, int) or seed < 0:
        raise InputError(f"{path}: seed: expected a whole number >= 0, got {seed!r}")
    return seed


def _check_metrics(metrics: dict[str, Any], path: Path) -> None:
    """The values a table shows are numbers (or null: not measured), and ``warnings`` a list
    of lines: a hand-edited or damaged metrics.json is an error naming the key, never a
    blank cell or a warning split into letters."""
    from workbench.results.summary import STAT_KEYS  # summary builds on this module

    for key in STAT_KEYS:
        value = metrics.get(key)
        if value is not None and (isinstance(value, bool) or not isinstance(value, int | float)):
            raise InputError(f"{path}: {key}: expected a number or null, got {value!r}")
    warnings = metrics.get("warnings")
    if warnings is not None and not (
        isinstance(warnings, list) and all(isinstance(line, str) for line in warnings)
    ):
        raise InputError(f"{path}: warnings: expected a list of lines, got {warnings!r}")


def _text(value: Any) -> str:
    return value if isinstance(value, str) else json.dumps(value, sort_keys=True)


def _experiment(dataset: Any, data: Any, config: Any, revision: Any) -> tuple[tuple[str, str], ...]:
    """``RunRecord.experiment`` from what a run recorded (non-mappings count as empty)."""
    pairs = [("dataset", _text(dataset))]
    for prefix, values in (("data", data), ("config", config)):
        if isinstance(values, dict):
            pairs += [(f"{prefix}.{key}", _text(value)) for key, value in values.items()]
    if revision:
        pairs.append(("revision", _text(revision)))
    return tuple(sorted(pairs))


def _finished_experiment(folder: Path, metrics: dict[str, Any]) -> tuple[tuple[str, str], ...]:
    """A finished run's experiment, from its config.yaml (what ran) and metrics.json."""
    from datasets.yaml_files import read_yaml_file

    config_file = folder / CONFIG_FILE
    recorded = read_yaml_file(config_file) if config_file.is_file() else {}
    if not isinstance(recorded, dict):
        raise InputError(f"{config_file}: expected a mapping (a run folder's config.yaml)")
    return _experiment(
        recorded.get("dataset", metrics.get("dataset")),
        recorded.get("data_options"),
        recorded.get("config"),
        metrics.get("git_revision"),
    )


def read_run(folder: Path) -> RunRecord:
    """The record of one run folder (``InputError`` when it is not one, or when its
    metrics.json or estimate.npz is damaged: ``_check_metrics``,
    ``estimate_file.check_estimate_file``)."""
    from workbench.results.estimate_file import check_estimate_file

    folder = Path(folder)
    if (folder / METRICS_FILE).is_file():
        metrics = _read_json(folder / METRICS_FILE)
        _check_metrics(metrics, folder / METRICS_FILE)
        if (folder / ESTIMATE_FILE).is_file():
            check_estimate_file(folder / ESTIMATE_FILE)
        return RunRecord(
            folder=folder,
            dataset=str(metrics.get("dataset")),
            estimator=str(metrics.get("estimator")),
            dataset_label=str(metrics.get("dataset_label") or metrics.get("dataset")),
            estimator_label=str(metrics.get("estimator_label") or metrics.get("estimator")),
            seed=_seed(metrics, folder / METRICS_FILE),
            metrics=metrics,
            experiment=_finished_experiment(folder, metrics),
        )
    if (folder / ERROR_FILE).is_file():
        request = _read_json(folder / REQUEST_FILE) if (folder / REQUEST_FILE).is_file() else {}
        failure = _read_json(folder / ERROR_FILE)
        return RunRecord(
            folder=folder,
            dataset=str(request.get("dataset")),
            estimator=str(request.get("estimator")),
            dataset_label=str(request.get("dataset_label") or request.get("dataset")),
            estimator_label=str(request.get("estimator_label") or request.get("estimator")),
            seed=_seed(request, folder / REQUEST_FILE),
            error=str(failure.get("error")),
            # unknown (it never resolved its config): it joins the row of its labels
        )
    raise InputError(f"{folder}: not a run folder (no {METRICS_FILE} or {ERROR_FILE})")


def find_run_folders(paths: list[Path]) -> list[Path]:
    """Run folders at or below ``paths``, in a stable order; ``InputError`` for a path that
    does not exist or holds none."""
    found: list[Path] = []
    for path in map(Path, paths):
        if not path.exists():
            raise InputError(f"{path}: no such file or folder")
        if (path / METRICS_FILE).is_file() or (path / ERROR_FILE).is_file():
            found.append(path)
            continue
        below = sorted(
            {marker.parent for name in (METRICS_FILE, ERROR_FILE) for marker in path.rglob(name)}
        )
        if not below:
            raise InputError(f"{path}: holds no run folder (no {METRICS_FILE} below it)")
        found += below
    return list(dict.fromkeys(found))


def load_runs(paths: list[Path] | Path) -> list[RunRecord]:
    """Every run folder at or below ``paths`` (a path or a list of them)."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    return [read_run(folder) for folder in find_run_folders(list(paths))]


IDENTITY_COLUMNS = (
    "dataset",
    "estimator",
    "dataset_label",
    "estimator_label",
    "seed",
    "folder",
    "status",
    "error",
)


def runs_frame(records: list[RunRecord]):
    """The tidy table: one row per run, identity columns then every metrics.json key
    (nested provenance such as package versions left out)."""
    import pandas as pd

    rows = []
    for record in records:
        row: dict[str, Any] = {
            "dataset": record.dataset,
            "estimator": record.estimator,
            "dataset_label": record.dataset_label,
            "estimator_label": record.estimator_label,
            "seed": record.seed,
            "folder": str(record.folder),
            "status": "ok" if record.finished else "failed",
            "error": record.error,
        }
        for key, value in (record.metrics or {}).items():
            if key not in row and not isinstance(value, (dict, list)):
                row[key] = value
        rows.append(row)
    return pd.DataFrame(rows, columns=None if rows else list(IDENTITY_COLUMNS))
