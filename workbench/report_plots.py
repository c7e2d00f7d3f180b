"""Figures of a whole sweep (``workbench bench``), per dataset, comparing the estimators.

``OUT/plots/<dataset>/`` receives, as PNG (and PDF or SVG on request, ``--plot-format``):
    ``trajectories``        top view of each estimator's trajectory (first seed; causal, and
                            smoothed for smoothers) against the truth, one panel each;
    ``pose_errors``         per-axis pose errors of the first seed with their +/-3 sigma
                            envelopes, a row per estimator (velocity and bias errors are in
                            each run folder's own plots with ``--run-plots``);
    ``anees``               NEES averaged over the runs, per block, over time, with the
                            two-sided 95% chi-square band (``monte_carlo``);
    ``nis``                 NIS over time (first seed) with the 95% bound of its dof;
    ``landmark_count``      landmarks in the state over time (first seed);
    ``time_vs_landmarks``   mean time per processed measurement against the number of
                            landmarks in the state (all runs), filters solid, smoothers dashed.

Functions come in pairs as in ``workbench.plots``: ``*_on_axes`` draws, the wrapper saves.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from datasets.trajectory_io import read_tum  # noqa: E402
from workbench.monte_carlo import AveragedSeries, ErrorSeries  # noqa: E402
from workbench.plot_formats import DEFAULT_PLOT_FORMATS  # noqa: E402
from workbench.plots import (  # noqa: E402
    NamedFigure,
    nis_on_axes,
    save_figure,
    trajectory_on_axes,
)
from workbench.registry import estimator_entry  # noqa: E402
from workbench.results import PairResults, RunSeries, collect  # noqa: E402
from workbench.suites import DatasetSpec  # noqa: E402
from workbench.sweep.plan import Plan  # noqa: E402

NEES_BLOCK_TITLES = {
    "pose": "pose",
    "velocity": "velocity",
    "gyro_bias": "gyro bias",
    "accel_bias": "accelerometer bias",
    "landmarks": "landmarks (per landmark)",
}


def is_smoother(estimator_name: str) -> bool:
    """Whether the registered estimator lives in ``smoothers/`` (by its registry target)."""
    return estimator_entry(estimator_name).target.startswith("smoothers.")


def _line_style(pair: PairResults) -> str:
    return "--" if is_smoother(pair.estimator.name) else "-"


# ---------------------------------------------------------------------------- drawing


def _log_y(axes: plt.Axes) -> None:
    """Log y axis with plain tick labels and no minor ticks (mathtext tick labels and minor
    tick layout otherwise dominate the drawing time)."""
    from matplotlib.ticker import FormatStrFormatter, LogLocator, NullLocator

    axes.set_yscale("log")
    axes.yaxis.set_major_locator(LogLocator(subs=(1.0, 2.0, 5.0)))
    axes.yaxis.set_minor_locator(NullLocator())
    axes.yaxis.set_major_formatter(FormatStrFormatter("%g"))


def _legend_outside(axes: plt.Axes) -> None:
    axes.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0), borderaxespad=0.0)


def errors_on_axes(
    axes: plt.Axes,
    series: ErrorSeries,
    components: tuple[int, ...],
    names: tuple[str, ...],
    scale: float = 1.0,
) -> None:
    """Several error components on one axes, each with its +/-3 sigma envelope in the same
    colour (values multiplied by ``scale``, e.g. rad -> deg)."""
    for index, (component, name) in enumerate(zip(components, names)):
        color = f"C{index}"
        sigma = 3.0 * scale * series.sigmas[:, component]
        axes.fill_between(series.t, -sigma, sigma, color=color, alpha=0.15, linewidth=0)
        axes.plot(
            series.t, scale * series.errors[:, component], color=color, linewidth=0.8, label=name
        )
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize=7, loc="upper right", ncol=len(components))


def _common_constant_band(series: list[AveragedSeries]) -> tuple[float, float] | None:
    """The band shared by every series when each one's bounds are constant over its steps
    and equal to the others' (same runs and dof), else None."""
    bands = set()
    for item in series:
        if len(item.t) == 0 or np.ptp(item.lower) > 1e-9 or np.ptp(item.upper) > 1e-9:
            return None
        bands.add((round(float(item.lower[0]), 9), round(float(item.upper[0]), 9)))
    return bands.pop() if len(bands) == 1 else None


def anees_on_axes(axes: plt.Axes, curves: dict[str, tuple[AveragedSeries, str]]) -> None:
    """Averaged NEES over time of several estimators with the 95% band: one grey band when
    every estimator has the same constant one (same runs and dof), otherwise each
    estimator's bounds as dotted lines in its colour."""
    shared = _common_constant_band([series for series, _ in curves.values()])
    if shared is not None:
        axes.axhspan(shared[0], shared[1], color="0.6", alpha=0.3, linewidth=0, label="95% band")
    for index, (label, (series, style)) in enumerate(curves.items()):
        color = f"C{index % 10}"
        marker = "o" if len(series.t) < 3 else None
        axes.plot(
            series.t,
            series.mean,
            style,
            color=color,
            linewidth=1.0,
            marker=marker,
            markersize=4,
            label=f"{label} ({series.runs} runs)",
        )
        if not shared:
            axes.plot(series.t, series.lower, ":", color=color, linewidth=0.8)
            axes.plot(series.t, series.upper, ":", color=color, linewidth=0.8)
    _log_y(axes)
    axes.set_xlabel("t [s]")
    axes.set_ylabel("averaged NEES")
    axes.grid(True, alpha=0.3)
    _legend_outside(axes)


def landmark_count_on_axes(axes: plt.Axes, counts: dict[str, tuple[RunSeries, str]]) -> None:
    for label, (series, style) in counts.items():
        axes.step(series.count_t, series.count, style, where="post", label=label, linewidth=1.0)
    axes.set_xlabel("t [s]")
    axes.set_ylabel("landmarks in state")
    axes.grid(True, alpha=0.3)
    _legend_outside(axes)


def time_per_landmarks(series: RunSeries) -> tuple[np.ndarray, np.ndarray]:
    """(landmarks in the state at each processed measurement, its time [s]); a step before
    the first count has 0 landmarks."""
    if len(series.timing_t) == 0:
        return np.zeros(0, dtype=int), np.zeros(0)
    if len(series.count_t) == 0:
        return np.zeros(len(series.timing_t), dtype=int), series.timing_seconds
    index = np.searchsorted(series.count_t, series.timing_t, side="right") - 1
    counts = np.where(index >= 0, series.count[np.clip(index, 0, None)], 0)
    return counts.astype(int), series.timing_seconds


def time_vs_landmarks_on_axes(axes: plt.Axes, runs: dict[str, tuple[list[RunSeries], str]]) -> None:
    """Mean time per step [ms] against landmarks in the state, pooled over runs."""
    for label, (series_list, style) in runs.items():
        pooled = [time_per_landmarks(series) for series in series_list]
        counts = np.concatenate([c for c, _ in pooled]) if pooled else np.zeros(0, dtype=int)
        seconds = np.concatenate([s for _, s in pooled]) if pooled else np.zeros(0)
        if counts.size == 0:
            continue
        values = np.unique(counts)
        means = np.array([1000.0 * np.mean(seconds[counts == value]) for value in values])
        axes.plot(values, means, style, marker=".", markersize=3, linewidth=1.0, label=label)
    axes.set_xlabel("landmarks in state")
    axes.set_ylabel("mean time per step [ms]")
    _log_y(axes)
    axes.grid(True, alpha=0.3)
    _legend_outside(axes)


# ---------------------------------------------------------------------------- figures


def _trajectory_figure(pairs: list[PairResults], title: str) -> NamedFigure | None:
    panels = [
        pair
        for pair in pairs
        if pair.finished and (pair.finished[0].folder / "estimate.tum").is_file()
    ]
    if not panels:
        return None
    columns = min(3, len(panels))
    rows = int(np.ceil(len(panels) / columns))
    figure, axes = plt.subplots(rows, columns, figsize=(4.5 * columns, 4.2 * rows), squeeze=False)
    for ax, pair in zip(axes.ravel(), panels):
        folder = pair.finished[0].folder
        trajectories = {}
        if (folder / "reference.tum").is_file():
            trajectories["truth"] = read_tum(folder / "reference.tum")
        trajectories["causal"] = read_tum(folder / "estimate.tum")
        if (folder / "estimate_smoothed.tum").is_file():
            trajectories["smoothed"] = read_tum(folder / "estimate_smoothed.tum")
        trajectory_on_axes(ax, trajectories)
        ax.set_title(f"{pair.estimator.title} (seed {pair.finished[0].seed})", fontsize=9)
    for ax in axes.ravel()[len(panels) :]:
        ax.set_visible(False)
    figure.suptitle(title)
    return "trajectories", figure


def _error_figure(pairs: list[PairResults], title: str) -> NamedFigure | None:
    """Pose errors of the first seed, one row per estimator: attitude and position, each
    component with its +/-3 sigma envelope (shaded)."""
    found = [(pair, pair.first_errors().get("pose")) for pair in pairs]
    found = [(pair, series) for pair, series in found if series is not None]
    if not found:
        return None
    figure, axes = plt.subplots(
        len(found), 2, figsize=(10, 2.2 * len(found) + 0.6), sharex=True, squeeze=False
    )
    for row, (pair, series) in enumerate(found):
        if series.errors.shape[1] == 6:  # 3-D: [rotation (body), translation (body)]
            errors_on_axes(axes[row, 0], series, (0, 1, 2), ("x", "y", "z"), np.rad2deg(1.0))
            errors_on_axes(axes[row, 1], series, (3, 4, 5), ("x", "y", "z"))
            axes[row, 0].set_ylabel(f"{pair.estimator.title}\nrotation [deg]", fontsize=8)
        else:  # 2-D: [body x, body y, heading]
            errors_on_axes(axes[row, 0], series, (2,), ("heading",), np.rad2deg(1.0))
            errors_on_axes(axes[row, 1], series, (0, 1), ("x", "y"))
            axes[row, 0].set_ylabel(f"{pair.estimator.title}\nheading [deg]", fontsize=8)
        axes[row, 1].set_ylabel("position (body) [m]", fontsize=8)
    axes[-1, 0].set_xlabel("t [s]")
    axes[-1, 1].set_xlabel("t [s]")
    figure.suptitle(
        f"{title}: pose errors (truth - estimate) with +/-3 sigma, first seed", fontsize=10
    )
    return "pose_errors", figure


def _anees_figure(pairs: list[PairResults], title: str) -> NamedFigure | None:
    blocks = [
        block for block in NEES_BLOCK_TITLES if any(block in pair.averaged_nees for pair in pairs)
    ]
    if not blocks:
        return None
    figure, axes = plt.subplots(len(blocks), 1, figsize=(9, 2.8 * len(blocks)), squeeze=False)
    for ax, block in zip(axes[:, 0], blocks):
        curves = {
            pair.estimator.title: (pair.averaged_nees[block], _line_style(pair))
            for pair in pairs
            if block in pair.averaged_nees
        }
        anees_on_axes(ax, curves)
        ax.set_title(f"{title}: averaged NEES, {NEES_BLOCK_TITLES[block]}, 95% band", fontsize=9)
    return "anees", figure


def _nis_figure(pairs: list[PairResults], title: str) -> NamedFigure | None:
    panels = [pair for pair in pairs if pair.series and len(pair.series[0].nis)]
    if not panels:
        return None
    figure, axes = plt.subplots(
        len(panels), 1, figsize=(7.5, 2.6 * len(panels)), sharex=True, squeeze=False
    )
    for ax, pair in zip(axes[:, 0], panels):
        series = pair.series[0]
        nis_on_axes(ax, series.nis_t, series.nis, series.nis_dof)
        ax.set_title(
            f"{title}: {pair.estimator.title} NIS, seed {pair.finished[0].seed}", fontsize=9
        )
    return "nis", figure


def _landmark_count_figure(pairs: list[PairResults], title: str) -> NamedFigure | None:
    counts = {
        pair.estimator.title: (pair.series[0], _line_style(pair))
        for pair in pairs
        if pair.series and len(pair.series[0].count)
    }
    if not counts:
        return None
    figure, axes = plt.subplots(figsize=(9, 3.2))
    landmark_count_on_axes(axes, counts)
    axes.set_title(f"{title}: landmarks in the state (first seed)", fontsize=9)
    return "landmark_count", figure


def _time_figure(pairs: list[PairResults], title: str) -> NamedFigure | None:
    runs = {
        pair.estimator.title: (list(pair.series), _line_style(pair))
        for pair in pairs
        if pair.series and any(len(s.timing_t) for s in pair.series)
    }
    if not runs:
        return None
    figure, axes = plt.subplots(figsize=(9, 3.6))
    time_vs_landmarks_on_axes(axes, runs)
    axes.set_title(
        f"{title}: time per step vs landmarks (filters solid, smoothers dashed)", fontsize=9
    )
    return "time_vs_landmarks", figure


def write_dataset_plots(
    plan: Plan, dataset: DatasetSpec, formats: tuple[str, ...] = DEFAULT_PLOT_FORMATS
) -> list[Path]:
    """Every figure of one dataset into ``OUT/plots/<dataset>/`` in each of ``formats``
    (a worker task)."""
    pairs = [pair for pair in collect(plan) if pair.dataset == dataset and pair.finished]
    out = plan.out / "plots" / dataset.folder_name
    written: list[Path] = []
    for figure_builder in (
        _trajectory_figure,
        _error_figure,
        _anees_figure,
        _nis_figure,
        _landmark_count_figure,
        _time_figure,
    ):
        built = figure_builder(pairs, dataset.title)
        if built is not None:
            name, figure = built
            written += save_figure(figure, out / name, formats)
    return written
