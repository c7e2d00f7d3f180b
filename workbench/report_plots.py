"""Figures comparing the estimators of one dataset (``workbench bench``, ``workbench report``).

``OUT/plots/<dataset>/`` receives (PNG; PDF or SVG with ``--plot-format``), for one seed
(the first by default) unless said otherwise:
    ``trajectories``        top view of the reference and every estimator on one axes, each
                            aligned to the reference as its ATE is (SE(3), or SE(2) for
                            planar poses); the batch smoother's smoothed path, dashed and
                            said so, as it has no causal one; a bag's front end
                            (KISS-ICP), dash-dotted. Without a reference: the paths as
                            estimated, said to be unaligned;
    ``position_error``      the aligned position error over time of every estimator on one
                            axes (the ATE's e_i; the legend gives each RMSE, the table's ATE);
    ``error_path``          the lowest-ATE estimator's path coloured by that error;
    ``pose_errors``         per-axis pose errors with +/-3 sigma envelopes, a row per
                            estimator whose causal pose has a covariance; the others named
                            in the legend with the reason;
    ``consistency``         NEES (and NIS) per dof averaged over every run, per table block,
                            over time; one grey 95 % chi-square band per distinct dof,
                            labelled with it (a band varying per step, thin in the curve's
                            colour); estimators without a covariance named in the legend;
    ``nis``                 each update's NIS / dof, a panel per estimator: dots inside the
                            band of their own dof, rings outside;
    ``landmark_count``      landmarks in the state over time;
    ``time_vs_landmarks``   mean time per processed measurement against the landmarks in the
                            state (every run; only where some estimator keeps landmarks).
Colours and line styles come from ``workbench.style``. Every time axis is ``t - t0`` with one
t0 per dataset (its first pose), stated in the title; no axis carries an offset text; a log
axis only where the values span a decade, with at least two labelled ticks; no axes without
data. The figures live in ``workbench.figures`` (``*_on_axes`` draws, ``*_figure`` builds).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from workbench.figures.common import (
    NamedFigure,
    legend_outside,
    log_y_if_wide,
    plain_numbers,
    plt,
    save_figure,
)
from workbench.figures.consistency import consistency_figure, nis_figure
from workbench.figures.error import pose_error_figure, position_error_figure
from workbench.figures.overlay import error_path_figure, trajectory_overlay_figure
from workbench.figures.view import DatasetView, chosen_run, seed_text
from workbench.plot_formats import DEFAULT_PLOT_FORMATS
from workbench.results.summary import PairSummary
from workbench.style import curve_style

__all__ = ["chosen_run", "dataset_figures", "seed_text", "write_dataset_plots"]


def landmark_count_on_axes(axes: plt.Axes, found: list[tuple[str, np.ndarray, np.ndarray]]) -> None:
    """Landmarks in the state over time (already relative), one step curve per estimator."""
    for label, t, count in found:
        axes.step(
            t, count, where="post", label=label, linewidth=1.0, **curve_style(label).keywords()
        )
    axes.set_ylabel("landmarks in state")
    axes.grid(True, alpha=0.3)
    legend_outside(axes)


def landmark_count_figure(view: DatasetView) -> NamedFigure | None:
    found = []
    for pair, run in view.chosen:
        t, count = view.files(run).arrays("diag_landmark_count_t", "diag_landmark_count")
        if len(count) and np.any(count > 0):
            found.append((pair.estimator, view.time_axis(t), count))
    if not found:
        return None
    figure, axes = plt.subplots(figsize=(10.0, 3.4))
    landmark_count_on_axes(axes, found)
    view.time_axis.on_axes(axes)
    title = f"{view.title}: landmarks in the state, {view.seed_label}"
    axes.set_title(view.time_axis.titled(title), fontsize=9)
    return "landmark_count", plain_numbers(figure)


def time_per_landmarks(view: DatasetView, run) -> tuple[np.ndarray, np.ndarray]:
    """(landmarks in the state at each processed measurement, its time [s]) of one run."""
    timing_t, seconds, count_t, count = view.files(run).arrays(
        "timing_t", "timing_seconds", "diag_landmark_count_t", "diag_landmark_count"
    )
    if len(timing_t) == 0:
        return np.zeros(0, dtype=int), np.zeros(0)
    if len(count_t) == 0:
        return np.zeros(len(timing_t), dtype=int), seconds
    index = np.searchsorted(count_t, timing_t, side="right") - 1
    counts = np.where(index >= 0, count[np.clip(index, 0, None)], 0)
    return counts.astype(int), seconds


def time_on_axes(axes: plt.Axes, found: list[tuple[str, np.ndarray, np.ndarray]]) -> None:
    """Mean time per step [ms] against the landmarks in the state, one curve per estimator
    (a marker at every value where an estimator has few)."""
    for label, values, means in found:
        keywords = curve_style(label).keywords(len(values))
        if len(values) < 3:
            keywords.update(marker=keywords.get("marker") or "o", markersize=4)
        axes.plot(values, means, linewidth=1.0, label=label, **keywords)
    axes.set_xlabel("landmarks in state")
    axes.set_ylabel("mean time per step [ms]")
    log_y_if_wide(axes, [means for _, _, means in found])
    axes.grid(True, alpha=0.3)
    legend_outside(axes)


def time_figure(view: DatasetView) -> NamedFigure | None:
    """Time per step against landmarks in the state, pooled over every run; none where no
    estimator keeps landmarks (the table's cost columns say it all then)."""
    found = []
    for pair in view.pairs:
        pooled = [time_per_landmarks(view, run) for run in pair.finished_runs]
        counts = np.concatenate([c for c, _ in pooled]) if pooled else np.zeros(0, dtype=int)
        seconds = np.concatenate([s for _, s in pooled]) if pooled else np.zeros(0)
        if counts.size:
            values, inverse = np.unique(counts, return_inverse=True)
            means = 1000.0 * np.bincount(inverse, weights=seconds) / np.bincount(inverse)
            found.append((pair.estimator, values, means))
    if not found or all(values.max() == 0 for _, values, _ in found):
        return None
    figure, axes = plt.subplots(figsize=(10.0, 3.8))
    time_on_axes(axes, found)
    axes.set_title(f"{view.title}: time per step vs landmarks (every run)", fontsize=9)
    return "time_vs_landmarks", plain_numbers(figure)


FIGURES = (
    trajectory_overlay_figure,
    position_error_figure,
    error_path_figure,
    pose_error_figure,
    consistency_figure,
    nis_figure,
    landmark_count_figure,
    time_figure,
)
"""Every figure builder of a dataset, in the order they are written."""


def dataset_figures(
    pairs: list[PairSummary], title: str, seed: int | None = None
) -> list[NamedFigure]:
    """Every figure of one dataset's pairs (those with finished runs)."""
    view = DatasetView(pairs, title, seed)
    return [built for build in FIGURES if (built := build(view)) is not None]


def write_dataset_plots(
    folders: list[Path],
    title: str,
    out: Path,
    formats: tuple[str, ...] = DEFAULT_PLOT_FORMATS,
    seed: int | None = None,
) -> list[Path]:
    """Every figure of one dataset's run folders into ``out`` (a worker task)."""
    from workbench.results.runs import read_run
    from workbench.results.summary import summarize

    pairs = summarize([read_run(folder) for folder in folders])
    written: list[Path] = []
    for name, figure in dataset_figures(pairs, title, seed):
        written += save_figure(figure, Path(out) / name, formats)
    return written
