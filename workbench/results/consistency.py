"""Consistency of runs: each run's per-step NEES and NIS series on disk, and the cells of a
consistency table built from the runs of one (dataset, estimator) pair.

Per run (``save_run_consistency`` -> ``consistency.npz`` in the run folder), for the causal
and the smoothed history alike: every state block's NEES per step (pose, attitude,
position, velocity, biases; ``landmarks``: every landmark of a snapshot summed, a
diagnostic), the map's joint NEES per snapshot (``map``), and the stacked NIS of every
update (``nis``), each with its degrees of freedom; plus the per-axis errors and sigmas of
the causal blocks for the error plots. Steps the truth cannot vouch for (inside
``GroundTruth.excluded``, or across a gap of the truth) are in none of them
(``workbench.metrics.state_errors``).

Per pair (``consistency_cells``), for each table block (pose, velocity, gyro bias,
accel bias, map, NIS): the scored history (causal when the estimator has one, else the
smoothed one, and said so), the cell's statistic, band and verdict
(``workbench.metrics.verdicts``: runs are the unit of independence), and the per-step
average over runs with its chi-square band (``average_runs``) for the plots.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from datasets.estimate import Estimate
from datasets.sequence import Sequence
from datasets.trajectory_io import save_npz_atomic
from workbench.metrics.consistency import CONFIDENCE, inside_fraction, per_dof_band
from workbench.metrics.data_association import landmark_id_mapping
from workbench.metrics.state_errors import (
    NeesSeries,
    block_error_series,
    map_nees_series,
    nees_series,
    pose_error_series,
)
from workbench.metrics.verdicts import CellStatistic, cell_statistic

HISTORIES = ("causal", "smoothed")
SERIES_BLOCKS = (
    "pose",
    "attitude",
    "position",
    "velocity",
    "gyro_bias",
    "accel_bias",
    "map",
    "landmarks",
)
TABLE_BLOCKS = ("pose", "velocity", "gyro_bias", "accel_bias", "map", "nis")
"""The blocks a consistency table shows, in its order."""
NIS = "nis"

_STAMP_RESOLUTION_S = 1e-6


@dataclass(frozen=True)
class StepSeries:
    """NEES (or NIS) of one block of one run, summed per step.

    Attributes:
        t: step times [s], shape (K,), increasing (NaN for a map without a time).
        values: sum of the finite values at each step, shape (K,).
        dof: sum of their degrees of freedom, shape (K,).
        units: number of values summed (1 per pose or map; landmarks in a snapshot), (K,).
    """

    t: np.ndarray
    values: np.ndarray
    dof: np.ndarray
    units: np.ndarray


def per_step(series: NeesSeries) -> StepSeries:
    """Sum a ``NeesSeries`` per distinct time, skipping NaN values (singular covariances)."""
    finite = np.isfinite(series.nees)
    t, values, dofs = series.t[finite], series.nees[finite], series.dof[finite]
    if t.size == 0:
        return StepSeries(np.zeros(0), np.zeros(0), np.zeros(0, dtype=int), np.zeros(0, dtype=int))
    keys = np.where(np.isfinite(t), t, np.inf)
    times, inverse = np.unique(keys, return_inverse=True)
    return StepSeries(
        t=np.where(np.isfinite(times), times, np.nan),
        values=np.bincount(inverse, weights=values, minlength=len(times)),
        dof=np.bincount(inverse, weights=dofs, minlength=len(times)).astype(int),
        units=np.bincount(inverse, minlength=len(times)).astype(int),
    )


def run_consistency(estimate: Estimate, sequence: Sequence) -> dict[str, StepSeries]:
    """Every series of one run, keyed ``"causal/pose"``, ``"smoothed/map"``, ``"nis"``:
    the blocks of both histories that have a truth to compare with, and the stacked NIS.

    A final map that no history snapshot holds (an estimator that records none) counts as
    the scored history's map at the last pose time."""
    found: dict[str, StepSeries] = {}
    truth = sequence.ground_truth
    diagnostics = estimate.diagnostics
    if len(diagnostics.scan_nis):
        found[NIS] = per_step(
            NeesSeries(diagnostics.scan_nis_t, diagnostics.scan_nis, diagnostics.scan_nis_dof)
        )
    if truth is None:
        return found
    mapping = landmark_id_mapping(diagnostics, truth)
    for name, history in (("causal", estimate.causal), ("smoothed", estimate.smoothed)):
        if history is None:
            continue
        for block, series in nees_series(history, truth, mapping).items():
            if block in SERIES_BLOCKS:
                found[f"{name}/{block}"] = per_step(series)
    final_map = estimate.landmarks
    if not any(key.endswith("/map") for key in found) and final_map is not None:
        final = map_nees_series((final_map,), mapping, truth)
        if final is not None:
            scored = "causal" if estimate.causal.pose is not None else "smoothed"
            pose = (estimate.causal if scored == "causal" else estimate.smoothed).pose
            last_t = float(pose.t[-1]) if pose is not None and len(pose) else np.nan
            found[f"{scored}/map"] = per_step(NeesSeries(np.full(1, last_t), final.nees, final.dof))
    return found


@dataclass(frozen=True)
class ErrorSeries:
    """Per-axis errors (truth - estimate, in the estimate's convention) and the estimate's
    standard deviations, per step.

    Attributes:
        t: times [s], shape (K,).
        errors: shape (K, k); pose: the interface tangent order (3-D [rotation [rad],
            body translation [m]]; 2-D [body x, body y [m], heading [rad]]).
        sigmas: square roots of the covariance diagonal, shape (K, k).
    """

    t: np.ndarray
    errors: np.ndarray
    sigmas: np.ndarray


def error_series(estimate: Estimate, sequence: Sequence) -> dict[str, ErrorSeries]:
    """Errors and sigmas of the causal pose and vector blocks that have covariances and a
    truth (``state_errors``: truth looked up at the estimate's times)."""
    truth = sequence.ground_truth
    if truth is None:
        return {}
    found: dict[str, ErrorSeries] = {}
    pose = estimate.causal.pose
    if pose is not None and pose.covariances is not None:
        pose_found = pose_error_series(pose, truth)
        if pose_found is not None and len(pose_found[0]):
            t, errors, valid = pose_found
            variances = np.diagonal(pose.covariances[valid], axis1=1, axis2=2)
            found["pose"] = ErrorSeries(t, errors, np.sqrt(np.maximum(variances, 0.0)))
    for name, block in estimate.causal.blocks.items():
        if block.covariances is None:
            continue
        block_found = block_error_series(name, block, truth)
        if block_found is not None and len(block_found[0]):
            t, errors, valid = block_found
            variances = np.diagonal(block.covariances[valid], axis1=1, axis2=2)
            found[str(name)] = ErrorSeries(t, errors, np.sqrt(np.maximum(variances, 0.0)))
    return found


def save_run_consistency(estimate: Estimate, sequence: Sequence, path: Path) -> None:
    """Write ``run_consistency`` (keys ``{series}:t``, ``:values``, ``:dof``, ``:units``) and
    ``error_series`` (keys ``errors/{block}:t``, ``:errors``, ``:sigmas``) as one npz."""
    arrays: dict[str, np.ndarray] = {}
    for key, series in run_consistency(estimate, sequence).items():
        for field in ("t", "values", "dof", "units"):
            arrays[f"{key}:{field}"] = getattr(series, field)
    for block, series in error_series(estimate, sequence).items():
        for field in ("t", "errors", "sigmas"):
            arrays[f"errors/{block}:{field}"] = getattr(series, field)
    save_npz_atomic(Path(path), arrays)


def _grouped(path: Path, prefix_filter) -> dict[str, dict[str, np.ndarray]]:
    with np.load(Path(path)) as data:
        grouped: dict[str, dict[str, np.ndarray]] = {}
        for name in data.files:
            key, _, field = name.rpartition(":")
            if prefix_filter(key):
                grouped.setdefault(key, {})[field] = data[name]
    return grouped


def load_run_consistency(path: Path) -> dict[str, StepSeries]:
    """The series of a file written by ``save_run_consistency``."""
    grouped = _grouped(path, lambda key: not key.startswith("errors/"))
    return {key: StepSeries(**fields) for key, fields in grouped.items()}


def load_error_series(path: Path) -> dict[str, ErrorSeries]:
    """The error series of a file written by ``save_run_consistency``."""
    grouped = _grouped(path, lambda key: key.startswith("errors/"))
    return {key.removeprefix("errors/"): ErrorSeries(**fields) for key, fields in grouped.items()}


# ---------------------------------------------------------------------------- averages


@dataclass(frozen=True)
class AveragedSeries:
    """NEES (or NIS) averaged over runs per aligned step, per degree of freedom.

    Attributes:
        t: step times [s] (of the first run when aligned by index), shape (K,).
        mean: ``S / D`` at each step, S the summed values and D their summed dof over runs,
            shape (K,) (1 for a consistent estimator).
        lower, upper: the two-sided 95% chi-square band ``chi2.ppf([.025, .975], D) / D``.
        dof: D at each step, shape (K,). runs: number of runs averaged.
        aligned_by: ``"time"`` or ``"index"``.
    """

    t: np.ndarray
    mean: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    dof: np.ndarray
    runs: int
    aligned_by: str

    @property
    def inside_fraction(self) -> float | None:
        """Fraction of steps with ``lower <= mean <= upper`` (None without steps): a
        diagnostic; the cell's verdict is ``ConsistencyCell.statistic``."""
        if self.mean.size == 0:
            return None
        return float(np.mean((self.mean >= self.lower) & (self.mean <= self.upper)))


def _stamp_keys(t: np.ndarray) -> np.ndarray:
    return np.round(
        np.nan_to_num(np.asarray(t, dtype=float), nan=-1.0) / _STAMP_RESOLUTION_S
    ).astype(np.int64)


def _aligned(runs: list[StepSeries]) -> tuple[np.ndarray, list[np.ndarray], str]:
    """(times, per-run index arrays into each run, how) for the steps common to all runs."""
    keys = [_stamp_keys(run.t) for run in runs]
    common = keys[0]
    for other in keys[1:]:
        common = np.intersect1d(common, other)
    shortest = min(len(run.t) for run in runs)
    if len(common) >= 0.5 * shortest and len(common) > 0:
        indices = [np.searchsorted(k, common) for k in keys]
        return runs[0].t[indices[0]], indices, "time"
    indices = [np.arange(shortest) for _ in runs]
    return runs[0].t[:shortest], indices, "index"


def average_runs(runs: list[StepSeries], confidence: float = CONFIDENCE) -> AveragedSeries | None:
    """Average one block over runs, step by step (runs aligned by time stamp, else by step
    index), per degree of freedom, with the chi-square band of the summed dof; None
    without runs."""
    runs = [run for run in runs if len(run.t)]
    if not runs:
        return None
    times, indices, how = _aligned(runs)
    total = np.sum([run.values[index] for run, index in zip(runs, indices, strict=True)], axis=0)
    dof = np.sum([run.dof[index] for run, index in zip(runs, indices, strict=True)], axis=0)
    keep = dof > 0
    times, total, dof = times[keep], total[keep], dof[keep]
    lower, upper = per_dof_band(dof, confidence)
    return AveragedSeries(
        t=np.asarray(times, dtype=float),
        mean=total / dof,
        lower=lower,
        upper=upper,
        dof=dof.astype(int),
        runs=len(runs),
        aligned_by=how,
    )


# ---------------------------------------------------------------------------- cells


@dataclass(frozen=True)
class ConsistencyCell:
    """One block of one pair's consistency table.

    Attributes:
        block: the table block (``TABLE_BLOCKS``).
        scored: which estimate the cell scores: ``causal``, ``smoothed`` or, for NIS,
            ``innovation`` (the prediction before each update).
        statistic: value per dof, band and verdict (``metrics.verdicts``).
        averaged: the per-step average over runs for the plots, or None.
    """

    block: str
    scored: str
    statistic: CellStatistic
    averaged: AveragedSeries | None


def _scored_history(runs: list[dict[str, StepSeries]], block: str) -> str | None:
    for history in HISTORIES:
        if any(f"{history}/{block}" in run for run in runs):
            return history
    return None


def consistency_cell(runs: list[dict[str, StepSeries]], block: str) -> ConsistencyCell | None:
    """The cell of ``block`` over the runs' series, or None when no run has it."""
    if block == NIS:
        key, scored = NIS, "innovation"
    else:
        history = _scored_history(runs, block)
        if history is None:
            return None
        key, scored = f"{history}/{block}", history
    series = [run[key] for run in runs if key in run and len(run[key].t)]
    if not series:
        return None
    # innovations are white under consistency: judged from their pooled updates at any
    # run count (``verdicts.MIN_POOLED_UPDATES``); per-step NEES needs runs
    statistic = cell_statistic(
        [s.values for s in series], [s.dof for s in series], pooled=block == NIS
    )
    if statistic is None:
        return None
    return ConsistencyCell(block, scored, statistic, average_runs(series))


def consistency_cells(runs: list[dict[str, StepSeries]]) -> dict[str, ConsistencyCell]:
    """Every table block's cell that the runs can fill (``TABLE_BLOCKS`` order)."""
    cells = {}
    for block in TABLE_BLOCKS:
        cell = consistency_cell(runs, block)
        if cell is not None:
            cells[block] = cell
    return cells


def pooled_nis(runs: list[dict[str, StepSeries]]) -> tuple[float | None, float | None]:
    """(sum of NIS / sum of dof over every update of every run, fraction of updates whose
    NIS lies inside its two-sided 95% chi-square band); Nones without updates."""
    series = [run[NIS] for run in runs if NIS in run]
    if not series:
        return None, None
    values = np.concatenate([s.values for s in series])
    dofs = np.concatenate([s.dof for s in series])
    if dofs.sum() == 0:
        return None, None
    return float(values.sum() / dofs.sum()), inside_fraction(values, dofs)
