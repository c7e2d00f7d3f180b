"""Each run's trajectory aligned to the reference exactly as its ATE is, for the overlay and
the error figures: the same pairing (``metrics.ate.paired_trajectories``), the same
exclusions (the truth's untrusted intervals, ``excluded_truth`` in metrics.json), the same
alignment (``metrics.ate.ate_errors``: SE(3) for 3-D poses, SE(2) for planar ones, one of
the equally good minimisers on a straight or static path), as
``workbench.metrics.summary.accuracy_metrics`` computes ``ate_rmse_m``. The RMSE of the
errors drawn is the table's ATE (a test holds them equal).
"""

from __future__ import annotations

import re
import warnings
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from datasets.errors import InputError
from datasets.trajectory import Trajectory
from datasets.truth_quality.intervals import TruthInterval, TruthKind, excluded_mask
from workbench.figures.common import RunFiles
from workbench.metrics.alignment import apply_alignment
from workbench.metrics.ate import ate_errors, paired_trajectories
from workbench.metrics.summary import MIN_SCORED_POSES
from workbench.metrics.timestamps import trusted_samples

FRONT_END_FILE = Path("frontend") / "kiss_icp.tum"
"""Where ``workbench bag`` writes its front end's own trajectory, beside the run folders."""
FRONT_END_LABEL = "kiss-icp (front end)"

_INTERVAL = re.compile(r"^\s*(\S+)\s+(-?\d+(?:\.\d*)?)-\s*(-?\d+(?:\.\d*)?) s")
_PRINTED_RESOLUTION_S = 1e-3
"""metrics.json prints the excluded intervals' edges to the millisecond."""


def excluded_intervals(metrics: dict) -> tuple[TruthInterval, ...]:
    """The truth's untrusted intervals a run recorded (metrics.json ``excluded_truth``, one
    ``TruthInterval.line()`` each), each widened by half the printed resolution so that a
    sample on a rounded edge stays out, as it was when the ATE was computed."""
    found = []
    for line in metrics.get("excluded_truth") or ():
        match = _INTERVAL.match(str(line))
        if match is None:
            raise InputError(f"excluded_truth: not an interval line: {line!r}")
        kind, start, end = match.groups()
        half = 0.5 * _PRINTED_RESOLUTION_S
        found.append(
            TruthInterval(float(start) - half, float(end) + half, TruthKind(kind), "read back")
        )
    return tuple(found)


def read_positions_file(path: Path) -> Trajectory | None:
    """A TUM file as a 3-D trajectory (None when absent or empty). NaN rows are kept, as the
    truth held them: pairing drops them after association, as the ATE does."""
    if not path.is_file():
        return None
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", UserWarning)  # an empty file: None below
            table = np.loadtxt(path, comments="#", ndmin=2)
    except ValueError as error:
        raise InputError(f"{path}: not a TUM file ({error})") from None
    if table.shape[0] == 0:
        return None
    if table.shape[1] != 8:
        raise InputError(f"{path}: expected 8 numbers per line (t x y z qx qy qz qw)")
    quats = table[:, [7, 4, 5, 6]]  # TUM: qx qy qz qw -> (w, x, y, z)
    return Trajectory(table[:, 0], table[:, 1:4], quats)


def run_pose(files: RunFiles, kind: str) -> Trajectory | None:
    """A run's causal or smoothed pose history, from estimate.npz (full precision and its
    own dimension, which decides SE(2) or SE(3) as for the ATE)."""
    prefix = "smoothed_" if kind == "smoothed" else ""
    t, positions, rotations = files.arrays(
        f"{prefix}pose_t", f"{prefix}pose_positions", f"{prefix}pose_rotations"
    )
    if len(t) == 0:
        return None
    return Trajectory(t, positions, rotations)


@dataclass(frozen=True)
class AlignedPath:
    """One trajectory after the ATE's alignment.

    Attributes:
        label: the legend label (estimator, ``NAME smoothed ...``, the front end).
        estimator: the estimator label whose style it takes ("" for the front end).
        kind: ``causal``, ``smoothed`` or ``front end``.
        positions: the whole aligned trajectory [m], shape (N, 3) (planar ones at z = 0).
        error_t: stamps of the poses paired with the reference [s], shape (K,).
        error_positions: their aligned positions [m], shape (K, 3).
        errors: their position errors [m], shape (K,): the ATE's e_i.
        align: ``se3`` or ``se2``.
    """

    label: str
    estimator: str
    kind: str
    positions: np.ndarray
    error_t: np.ndarray
    error_positions: np.ndarray
    errors: np.ndarray
    align: str

    @property
    def rmse(self) -> float:
        return float(np.sqrt(np.mean(self.errors**2)))


def align_as_ate(
    reference: Trajectory,
    estimate: Trajectory,
    excluded: tuple[TruthInterval, ...],
    label: str,
    estimator: str,
    kind: str,
) -> AlignedPath | None:
    """``estimate`` aligned to ``reference`` as ``accuracy_metrics`` aligns it for
    ``ate_rmse_m`` (None where the ATE is n/a: no overlap, fewer than
    ``MIN_SCORED_POSES`` trusted pairs)."""
    try:
        ref_paired, est_paired = paired_trajectories(trusted_samples(reference, excluded), estimate)
    except InputError:
        return None
    keep = np.all(np.isfinite(ref_paired.positions), axis=1)
    if excluded:
        keep &= ~excluded_mask(est_paired.t, excluded)
    if int(keep.sum()) < MIN_SCORED_POSES:
        return None
    index = np.flatnonzero(keep)
    ref_paired, est_paired = ref_paired.select(index), est_paired.select(index)
    align = "se3" if estimate.dimension == 3 else "se2"
    errors, alignment, aligned = ate_errors(ref_paired, est_paired, align, allow_degenerate=True)
    whole = apply_alignment(estimate, alignment).positions
    return AlignedPath(
        label=label,
        estimator=estimator,
        kind=kind,
        positions=_spatial(whole),
        error_t=est_paired.t,
        error_positions=_spatial(aligned.positions),
        errors=errors,
        align=align,
    )


def _spatial(positions: np.ndarray) -> np.ndarray:
    if positions.shape[1] == 3:
        return positions
    return np.column_stack([positions, np.zeros(len(positions))])


def reference_for_drawing(reference: Trajectory, excluded: tuple[TruthInterval, ...]) -> np.ndarray:
    """The reference positions (N, 3) with its untrusted samples as NaN: a glitch of the
    truth is not drawn as truth (the line breaks there)."""
    positions = np.array(reference.positions, dtype=float)
    if excluded:
        positions[excluded_mask(reference.t, excluded)] = np.nan
    return positions


def front_end_file(folder: Path) -> Path | None:
    """The front end's own trajectory: the run folder's (``frontend.tum``, written for every
    run on a lidar source), else the one ``workbench bag`` writes beside its run folders
    (``DIR/frontend/kiss_icp.tum`` for ``DIR/NAME/``), or None. The one place to add other
    front ends' files."""
    from workbench.run_files import FRONT_END_FILE as RUN_FRONT_END_FILE

    for path in (Path(folder) / RUN_FRONT_END_FILE, Path(folder).parent / FRONT_END_FILE):
        if path.is_file():
            return path
    return None
