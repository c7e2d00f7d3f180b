"""Averaged NEES over Monte Carlo runs: the per-run NEES series on disk, and their average.

Each run of a sweep saves the NEES of every state block of its causal history, per step, in
``nees.npz`` (``save_run_nees``); the table and the plots average them over the runs of one
(dataset, estimator) cell (``average_runs``). The same file keeps the per-axis errors and
standard deviations of the pose and vector blocks (``error_series``), for the error plots
with their 3-sigma envelopes.

Per step, a run contributes ``(sum of NEES, sum of dof, units)``: one unit for a pose,
velocity or bias value; one unit per landmark for a landmark snapshot (all landmarks of a
snapshot share its time). Over M runs, with S the sum of the NEES of all units at the step,
D the sum of their dof and U the number of units, S is chi-square with D dof for a
consistent estimator (Bar-Shalom, Li, Kirubarajan, sec. 5.4.2), so the averaged NEES per
unit ``S / U`` has the two-sided 95% interval ``chi2.ppf([0.025, 0.975], D) / U``. For a
pose (U = M, D = M n) this is exactly ``consistency.averaged_nees``; for landmarks it
averages over runs *and* landmarks, whose number may differ between runs.

Runs are aligned by time (stamps equal within 1 us, kept when every run has them); when
fewer than half of the shortest run's steps are common to all runs (runs with different
time grids), by step index, truncated to the shortest run.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.stats import chi2

from datasets.estimate import Estimate
from datasets.sequence import Sequence
from datasets.trajectory_io import save_npz_atomic
from workbench.metrics.consistency import CONFIDENCE
from workbench.metrics.data_association import landmark_id_mapping
from workbench.metrics.state_errors import (
    NeesSeries,
    block_error_series,
    landmark_nees_series,
    nees_series,
    pose_error_series,
)

NEES_FILE = "nees.npz"
BLOCKS = ("pose", "attitude", "position", "velocity", "gyro_bias", "accel_bias", "landmarks")
"""Blocks in the order tables and plots show them."""

_STAMP_RESOLUTION_S = 1e-6


@dataclass(frozen=True)
class RunNees:
    """NEES of one block of one run, summed per step.

    Attributes:
        t: step times [s], shape (K,), increasing.
        nees: sum of the finite NEES values at each step, shape (K,).
        dof: sum of their degrees of freedom, shape (K,).
        units: number of values summed (1 per pose; landmarks in the snapshot), shape (K,).
    """

    t: np.ndarray
    nees: np.ndarray
    dof: np.ndarray
    units: np.ndarray


def per_step(series: NeesSeries) -> RunNees:
    """Sum a ``NeesSeries`` per distinct time, skipping NaN values (singular covariances)."""
    finite = np.isfinite(series.nees) & np.isfinite(series.t)
    t, values, dofs = series.t[finite], series.nees[finite], series.dof[finite]
    if t.size == 0:
        return RunNees(np.zeros(0), np.zeros(0), np.zeros(0, dtype=int), np.zeros(0, dtype=int))
    times, inverse = np.unique(t, return_inverse=True)
    return RunNees(
        t=times,
        nees=np.bincount(inverse, weights=values, minlength=len(times)),
        dof=np.bincount(inverse, weights=dofs, minlength=len(times)).astype(int),
        units=np.bincount(inverse, minlength=len(times)).astype(int),
    )


def run_nees(estimate: Estimate, sequence: Sequence) -> dict[str, RunNees]:
    """Per-step NEES of every block of the causal history that has a truth to compare with.

    Landmark ids are mapped to true ids as in ``metrics.json``
    (``data_association.landmark_id_mapping``); without landmark snapshots, the final map
    counts as one step at the last pose time (as ``summary.consistency_metrics`` does)."""
    truth = sequence.ground_truth
    if truth is None:
        return {}
    mapping = landmark_id_mapping(estimate.diagnostics, truth)
    series = nees_series(estimate.causal, truth, mapping)
    final_map = estimate.landmarks
    if "landmarks" not in series and final_map is not None and final_map.covariances is not None:
        found = landmark_nees_series((final_map,), mapping, truth)
        if found is not None:
            pose = estimate.causal.pose
            last_t = float(pose.t[-1]) if pose is not None and len(pose) else 0.0
            series["landmarks"] = NeesSeries(np.full(len(found.t), last_t), found.nees, found.dof)
    return {block: per_step(values) for block, values in series.items() if block in BLOCKS}


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
            found["pose"] = ErrorSeries(
                t,
                errors,
                np.sqrt(np.maximum(np.diagonal(pose.covariances[valid], axis1=1, axis2=2), 0.0)),
            )
    for name, block in estimate.causal.blocks.items():
        if block.covariances is None:
            continue
        block_found = block_error_series(name, block, truth)
        if block_found is not None and len(block_found[0]):
            t, errors, valid = block_found
            sigmas = np.sqrt(
                np.maximum(np.diagonal(block.covariances[valid], axis1=1, axis2=2), 0.0)
            )
            found[str(name)] = ErrorSeries(t, errors, sigmas)
    return found


def save_run_nees(estimate: Estimate, sequence: Sequence, path: Path) -> None:
    """Write ``run_nees`` (keys ``{block}_t``, ``_nees``, ``_dof``, ``_units``) and
    ``error_series`` (keys ``errors_{block}_t``, ``errors_{block}``, ``errors_{block}_sigma``)
    as one npz."""
    arrays: dict[str, np.ndarray] = {}
    for block, values in run_nees(estimate, sequence).items():
        arrays.update(
            {
                f"{block}_t": values.t,
                f"{block}_nees": values.nees,
                f"{block}_dof": values.dof,
                f"{block}_units": values.units,
            }
        )
    for block, series in error_series(estimate, sequence).items():
        arrays.update(
            {
                f"errors_{block}_t": series.t,
                f"errors_{block}": series.errors,
                f"errors_{block}_sigma": series.sigmas,
            }
        )
    save_npz_atomic(Path(path), arrays)


def load_run_nees(path: Path) -> dict[str, RunNees]:
    """Read a file written by ``save_run_nees``."""
    with np.load(Path(path)) as data:
        return {
            block: RunNees(
                data[f"{block}_t"],
                data[f"{block}_nees"],
                data[f"{block}_dof"],
                data[f"{block}_units"],
            )
            for block in BLOCKS
            if f"{block}_t" in data
        }


def load_error_series(path: Path) -> dict[str, ErrorSeries]:
    """The error series of a file written by ``save_run_nees``."""
    with np.load(Path(path)) as data:
        blocks = [
            key[len("errors_") : -len("_t")]
            for key in data.files
            if key.startswith("errors_") and key.endswith("_t")
        ]
        return {
            block: ErrorSeries(
                data[f"errors_{block}_t"], data[f"errors_{block}"], data[f"errors_{block}_sigma"]
            )
            for block in blocks
        }


@dataclass(frozen=True)
class AveragedSeries:
    """NEES averaged over runs (and landmarks), per aligned step.

    Attributes:
        t: step times [s] (of the first run when aligned by index), shape (K,).
        mean: averaged NEES per unit ``S / U``, shape (K,).
        lower, upper: the two-sided 95% interval at each step, shape (K,).
        runs: number of runs averaged.
        aligned_by: ``"time"`` or ``"index"``.
    """

    t: np.ndarray
    mean: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    runs: int
    aligned_by: str

    @property
    def inside_fraction(self) -> float | None:
        """Fraction of steps with ``lower <= mean <= upper`` (None without steps)."""
        if self.mean.size == 0:
            return None
        return float(np.mean((self.mean >= self.lower) & (self.mean <= self.upper)))

    @property
    def overall_mean(self) -> float | None:
        """The averaged NEES averaged over the steps (None without steps)."""
        return float(np.mean(self.mean)) if self.mean.size else None

    @property
    def typical_bounds(self) -> tuple[float, float] | None:
        """Median lower and upper bounds over the steps (the bounds themselves when, as for
        poses and biases, they are the same at every step)."""
        if self.mean.size == 0:
            return None
        return float(np.median(self.lower)), float(np.median(self.upper))


def _stamp_keys(t: np.ndarray) -> np.ndarray:
    return np.round(np.asarray(t, dtype=float) / _STAMP_RESOLUTION_S).astype(np.int64)


def _aligned(runs: list[RunNees]) -> tuple[np.ndarray, list[np.ndarray], str]:
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


def average_runs(runs: list[RunNees], confidence: float = CONFIDENCE) -> AveragedSeries | None:
    """Average the NEES of one block over runs (module docstring); None without runs."""
    runs = [run for run in runs if len(run.t)]
    if not runs:
        return None
    times, indices, how = _aligned(runs)
    total = np.sum([run.nees[index] for run, index in zip(runs, indices)], axis=0)
    dof = np.sum([run.dof[index] for run, index in zip(runs, indices)], axis=0)
    units = np.sum([run.units[index] for run, index in zip(runs, indices)], axis=0)
    keep = units > 0
    times, total, dof, units = times[keep], total[keep], dof[keep], units[keep]
    tail = 0.5 * (1.0 - confidence)
    return AveragedSeries(
        t=np.asarray(times, dtype=float),
        mean=total / units,
        lower=chi2.ppf(tail, dof) / units,
        upper=chi2.ppf(1.0 - tail, dof) / units,
        runs=len(runs),
        aligned_by=how,
    )
