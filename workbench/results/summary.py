"""One row per (dataset, estimator) pair: the statistics a comparison table shows.

Rows group runs by their labels (``RunRecord.dataset_label``, ``estimator_label``), so runs
from different suites, bags or days compare in one table. Accuracy, map, association and
cost figures are the mean and sample std (ddof 1) over the finished runs of the
``metrics.json`` value under the same key; consistency cells come from the runs' NEES and
NIS series (``results.consistency``). A sweep passes its plan (``PlannedPair``) so that a
pair that could not run says n/a with the reason, and one with failed runs says so.

``summary_frame`` is ``table.csv``: the metrics.json keys (``{key}`` the mean, ``{key}_std``),
and for each consistency block B ``anees_B_per_dof``, ``anees_B_per_dof_lower``,
``anees_B_per_dof_upper``,
``verdict_B``, ``scored_B`` (causal / smoothed / innovation), ``inside_B`` (fraction of steps
inside the per-step 95 % band, a diagnostic); ``nis_per_dof`` and ``nis_inside_fraction``
pooled over every update of every run; cost columns start with ``time_``.

A dataset whose runs had a lidar front end (metrics.json ``frontend_*``) gets a row for the
front end itself first (``front_end_row``: its own ATE, ms per frame, the NIS of its corners'
re-observations), and each estimator's agreement with it (``FRONT_END_KEYS``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from workbench.registry import ESTIMATORS
from workbench.results.consistency import (
    TABLE_BLOCKS,
    ConsistencyCell,
    consistency_cells,
    pooled_nis,
)
from workbench.results.runs import RunRecord

ACCURACY_KEYS = (
    "ate_rmse_m",
    "ate_rmse_smoothed_m",
    "ate_rmse_raw_m",
    "rpe_trans_rmse_m",
    "rpe_rot_rmse_deg",
    "final_orientation_error_deg",
    "gps_holdout_rmse_m",
    "gps_holdout_rmse_smoothed_m",
    "relations_trans_error_mean_m",
    "relations_trans_error_mean_smoothed_m",
)
MAP_KEYS = (
    "landmarks_in_map",
    "landmarks_mapped",
    "landmark_rmse_m",
    "association_precision",
    "association_recall",
    "association_rejected_fraction",
    "association_inflated_fraction",
    "loop_closures",
    "loop_closure_precision",
)
FRONT_END_KEYS = (
    "frontend_max_deviation_m",
    "frontend_max_deviation_percent_path",
    "frontend_final_yaw_diff_deg",
)
"""Each estimate against its lidar front end's trajectory (``metrics.frontend_agreement``)."""
FRAME_KEYS = ("frames", "frames_without_pose")
COST_KEYS = ("time_per_step_ms_median", "time_per_step_ms_p99", "time_total_s", "time_per_frame_ms")
STAT_KEYS = ACCURACY_KEYS + FRONT_END_KEYS + MAP_KEYS + FRAME_KEYS + COST_KEYS

FRONT_END_ROW = "front end"
"""``PairSummary.estimator_name`` of a dataset's front-end row (``front_end_rows``)."""


@dataclass(frozen=True)
class Stat:
    """Mean and sample standard deviation (None for a single value) over runs."""

    mean: float
    std: float | None
    count: int

    @staticmethod
    def of(values: list[float]) -> Stat | None:
        if not values:
            return None
        array = np.asarray(values, dtype=float)
        std = float(np.std(array, ddof=1)) if len(array) > 1 else None
        return Stat(float(np.mean(array)), std, len(array))


@dataclass(frozen=True)
class PlannedPair:
    """What a sweep planned for a pair: how many runs, or why none (n/a)."""

    dataset: str
    estimator: str
    estimator_name: str
    planned: int
    not_applicable: str | None = None


@dataclass(frozen=True)
class PairSummary:
    """One table row.

    Attributes:
        dataset, estimator: the labels. estimator_name: the registered name ("" unknown).
        status: ``ok``, ``partial`` (some runs failed), ``failed`` or ``n/a``.
        finished, planned: run counts. reason: why n/a, or None.
        stats: ``metrics.json`` key -> ``Stat`` over the finished runs.
        cells: table block -> ``ConsistencyCell``.
        nis_per_dof, nis_inside_fraction: pooled over every update of every run.
        runs: the records (finished and failed), by seed.
    """

    dataset: str
    estimator: str
    estimator_name: str
    status: str
    finished: int
    planned: int
    reason: str | None
    stats: dict[str, Stat] = field(default_factory=dict)
    cells: dict[str, ConsistencyCell] = field(default_factory=dict)
    nis_per_dof: float | None = None
    nis_inside_fraction: float | None = None
    runs: tuple[RunRecord, ...] = ()

    @property
    def finished_runs(self) -> tuple[RunRecord, ...]:
        return tuple(run for run in self.runs if run.finished)

    def errors(self) -> list[str]:
        return [f"seed {run.seed}: {run.error}" for run in self.runs if not run.finished]

    def calibrations(self) -> list[str]:
        """What the runs' loaders fitted their noise and calibration models on (metrics.json
        ``calibration``, e.g. UTIAS' other robots), each once."""
        found = [(run.metrics or {}).get("calibration") for run in self.runs]
        return list(dict.fromkeys(str(text) for text in found if text))

    def warnings(self) -> list[str]:
        """The runs' warnings (``workbench.degradations``), each once, with the seeds it
        came from when there are several runs."""
        seeds: dict[str, list[int]] = {}
        for run in self.runs:
            for line in (run.metrics or {}).get("warnings") or ():
                seeds.setdefault(str(line), []).append(run.seed)
        if len(self.runs) <= 1:
            return list(seeds)
        return [
            f"{line} (seed{'s' if len(found) > 1 else ''} {', '.join(map(str, found))})"
            for line, found in seeds.items()
        ]


def _values(records: list[RunRecord], key: str) -> list[float]:
    found = []
    for record in records:
        value = (record.metrics or {}).get(key)
        if isinstance(value, (int, float)) and not isinstance(value, bool) and np.isfinite(value):
            found.append(float(value))
    return found


def _registry_order(name: str) -> int:
    names = [entry.name for entry in ESTIMATORS]
    return names.index(name) if name in names else len(names)


def summarize_pair(
    dataset: str, estimator: str, records: list[RunRecord], planned: PlannedPair | None = None
) -> PairSummary:
    """The row of one pair from its records (and its plan)."""
    records = sorted(records, key=lambda record: record.seed)
    finished = [record for record in records if record.finished]
    name = planned.estimator_name if planned else (records[0].estimator if records else "")
    planned_count = planned.planned if planned else len(records)
    if planned is not None and planned.not_applicable is not None:
        return PairSummary(dataset, estimator, name, "n/a", 0, 0, planned.not_applicable)
    if not finished:
        status = "failed" if records else "missing"
    elif len(finished) < planned_count:
        status = "partial"
    else:
        status = "ok"
    series = [record.consistency for record in finished]
    nis_per_dof, nis_inside = pooled_nis(series)
    return PairSummary(
        dataset,
        estimator,
        name,
        status,
        len(finished),
        planned_count,
        None,
        stats={key: stat for key in STAT_KEYS if (stat := Stat.of(_values(finished, key)))},
        cells=consistency_cells(series),
        nis_per_dof=nis_per_dof,
        nis_inside_fraction=nis_inside,
        runs=tuple(records),
    )


REFERENCE_KEY = "ate_over_reference"
"""The ``summarize(reference=...)`` column: ATE over the reference estimator's."""


def with_reference_ratios(rows: list[PairSummary], reference: str) -> list[PairSummary]:
    """Rows with ``ate_over_reference``: each row's mean ATE over the mean ATE of the
    ``reference`` estimator's row on the same dataset, causal over causal, and smoothed over
    smoothed for a row with no causal ATE (the batch smoother). Rows without either, or
    datasets without the reference, get none."""
    from dataclasses import replace

    references = {row.dataset: row for row in rows if row.estimator_name == reference}
    ratioed = []
    for row in rows:
        base = references.get(row.dataset)
        key = "ate_rmse_m" if "ate_rmse_m" in row.stats else "ate_rmse_smoothed_m"
        own, denominator = row.stats.get(key), None if base is None else base.stats.get(key)
        if own is None or denominator is None or denominator.mean <= 0:
            ratioed.append(row)
            continue
        ratio = Stat(own.mean / denominator.mean, None, own.count)
        ratioed.append(replace(row, stats={**row.stats, REFERENCE_KEY: ratio}))
    return ratioed


def summarize(
    records: list[RunRecord],
    planned: list[PlannedPair] | None = None,
    reference: str | None = None,
) -> list[PairSummary]:
    """One row per pair: the plan's pairs in its order, then any other pairs of the records
    (by dataset, then the registry's estimator order); with ``reference`` (an estimator's
    registered name) each row's ATE over that estimator's (``with_reference_ratios``)."""
    groups: dict[tuple[str, str], list[RunRecord]] = {}
    for record in records:
        groups.setdefault((record.dataset_label, record.estimator_label), []).append(record)
    rows = []
    for pair in planned or []:
        key = (pair.dataset, pair.estimator)
        rows.append(summarize_pair(pair.dataset, pair.estimator, groups.pop(key, []), pair))
    remaining = sorted(
        groups.items(),
        key=lambda item: (item[0][0], _registry_order(item[1][0].estimator), item[0][1]),
    )
    rows += [summarize_pair(dataset, estimator, runs) for (dataset, estimator), runs in remaining]
    rows = with_front_end_rows(rows)
    return rows if reference is None else with_reference_ratios(rows, reference)


def front_end_row(dataset: str, records: list[RunRecord]) -> PairSummary | None:
    """The row of a dataset's lidar front end, from what its runs' metrics.json say of it
    (``frontend_*``): its own ATE where there is truth (``ate_rmse_m``), its ms per frame
    (``time_per_frame_ms``) and frames, and the NIS per dof of its corners' re-observations
    (``nis_per_dof``). One value per seed (every run of a seed shares its front end); None
    when no run has a front end."""
    by_seed: dict[int, dict] = {}
    for record in records:
        metrics = record.metrics or {}
        if record.finished and metrics.get("frontend_name"):
            by_seed.setdefault(record.seed, metrics)
    if not by_seed:
        return None
    found = list(by_seed.values())

    def stat(key: str) -> Stat | None:
        values = [float(m[key]) for m in found if _is_number(m.get(key))]
        return Stat.of(values)

    stats = {
        key: value
        for key, value in (
            ("ate_rmse_m", stat("frontend_ate_rmse_m")),
            ("time_per_frame_ms", stat("frontend_ms_per_frame")),
            ("frames", stat("frontend_frames")),
            ("frames_without_pose", Stat.of([0.0] * len(found))),
        )
        if value is not None
    }
    nis = stat("frontend_reobservation_nis_per_dof")
    name = str(found[0]["frontend_name"])
    return PairSummary(
        dataset,
        f"{FRONT_END_ROW} ({name})",
        FRONT_END_ROW,
        "ok",
        len(found),
        len(found),
        None,
        stats=stats,
        nis_per_dof=None if nis is None else nis.mean,
    )


def with_front_end_rows(rows: list[PairSummary]) -> list[PairSummary]:
    """``rows`` with each dataset's front-end row (``front_end_row``) before its first row."""
    result: list[PairSummary] = []
    seen: set[str] = set()
    for row in rows:
        if row.dataset not in seen:
            seen.add(row.dataset)
            own = [run for other in rows if other.dataset == row.dataset for run in other.runs]
            front = front_end_row(row.dataset, own)
            if front is not None:
                result.append(front)
        result.append(row)
    return result


def _is_number(value: object) -> bool:
    return (
        isinstance(value, (int, float)) and not isinstance(value, bool) and bool(np.isfinite(value))
    )


def _number(value: float | None) -> float | None:
    return None if value is None or not np.isfinite(value) else float(value)


def summary_frame(rows: list[PairSummary]):
    """``table.csv`` as a DataFrame (the module docstring names every column)."""
    import pandas as pd

    records = []
    for row in rows:
        record: dict[str, object] = {
            "dataset": row.dataset,
            "estimator": row.estimator,
            "status": row.status,
            "runs": row.finished,
            "runs_planned": row.planned,
        }
        for key in STAT_KEYS:
            stat = row.stats.get(key)
            record[key] = None if stat is None else stat.mean
            record[f"{key}_std"] = None if stat is None else stat.std
        if any(REFERENCE_KEY in other.stats for other in rows):
            ratio = row.stats.get(REFERENCE_KEY)
            record[REFERENCE_KEY] = None if ratio is None else ratio.mean
        for block in TABLE_BLOCKS:
            cell = row.cells.get(block)
            statistic = None if cell is None else cell.statistic
            record[f"anees_{block}_per_dof"] = None if statistic is None else statistic.value
            record[f"anees_{block}_per_dof_lower"] = None if statistic is None else statistic.lower
            record[f"anees_{block}_per_dof_upper"] = None if statistic is None else statistic.upper
            record[f"verdict_{block}"] = None if statistic is None else statistic.verdict.value
            record[f"scored_{block}"] = None if cell is None else cell.scored
            inside = (
                None if cell is None or cell.averaged is None else cell.averaged.inside_fraction
            )
            record[f"inside_{block}"] = inside
        record["nis_per_dof"] = _number(row.nis_per_dof)
        record["nis_inside_fraction"] = _number(row.nis_inside_fraction)
        records.append(record)
    return pd.DataFrame(records)
