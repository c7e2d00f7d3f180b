"""Figures comparing the estimators of one dataset (``workbench bench``, ``workbench report``).

``OUT/plots/<dataset>/`` receives (PNG; PDF or SVG with ``--plot-format``):
    ``trajectories``        top view of each estimator's trajectory (one seed: the first by
                            default; causal solid, smoothed dashed) against the reference,
                            which is named by its source (simulated truth, Vicon, ...);
    ``pose_errors``         per-axis pose errors of that seed with +/-3 sigma envelopes, one
                            row per estimator; a row that cannot be drawn says why;
    ``consistency``         NEES (and NIS) per degree of freedom averaged over the runs, per
                            table block, over time, each with its two-sided 95 % chi-square
                            band shaded in the estimator's colour, runs and dof in the legend;
    ``nis``                 each update's NIS per dof of that seed with its 95 % band;
    ``landmark_count``      landmarks in the state over time (that seed);
    ``time_vs_landmarks``   mean time per processed measurement against the landmarks in the
                            state (every run).
Colours and markers come from ``workbench.style`` (the same estimator looks the same in
every axes of every figure); times are relative to the dataset's first stamp.
Functions come in pairs as in ``workbench.plots``: ``*_on_axes`` draws, the builder returns
the figure.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from datasets.trajectory_io import read_tum  # noqa: E402
from workbench.plot_formats import DEFAULT_PLOT_FORMATS  # noqa: E402
from workbench.plots import NamedFigure, save_figure, trajectory_on_axes  # noqa: E402
from workbench.results.consistency import TABLE_BLOCKS, AveragedSeries, ErrorSeries  # noqa: E402
from workbench.results.runs import RunRecord  # noqa: E402
from workbench.results.summary import PairSummary  # noqa: E402
from workbench.style import REFERENCE_COLOUR, estimator_style  # noqa: E402

BLOCK_TITLES = {
    "pose": "pose",
    "velocity": "velocity",
    "gyro_bias": "gyro bias",
    "accel_bias": "accelerometer bias",
    "map": "map (joint NEES of each snapshot)",
    "nis": "NIS (each update against its prediction)",
}


def chosen_run(pair: PairSummary, seed: int | None) -> RunRecord | None:
    """The finished run with ``seed`` (None: the lowest seed), or None."""
    runs = pair.finished_runs
    if seed is None:
        return runs[0] if runs else None
    return next((run for run in runs if run.seed == seed), None)


def _npz(folder: Path, *keys: str) -> tuple[np.ndarray, ...]:
    """Arrays of a run's estimate.npz (checked: a damaged file is an ``InputError``)."""
    from workbench.results.estimate_file import load_arrays

    data = load_arrays(folder / "estimate.npz")
    return tuple(data[key] if key in data else np.zeros(0) for key in keys)


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


def _say(axes: plt.Axes, text: str) -> None:
    """A panel that cannot be drawn says why (nothing is dropped silently)."""
    axes.text(
        0.5, 0.5, text, ha="center", va="center", fontsize=8, transform=axes.transAxes, wrap=True
    )
    axes.set_xticks([])
    axes.set_yticks([])


def time_label(t0: float) -> str:
    """The relative time axis' label: ``t [s]`` when the data starts at 0."""
    return "t [s]" if t0 == 0.0 else f"t - {t0:.6g} [s]"


def seed_text(seed: int | None) -> str:
    return "first seed" if seed is None else f"seed {seed}"


def dof_text(averaged: AveragedSeries) -> str:
    low, high = int(averaged.dof.min()), int(averaged.dof.max())
    return f"{low} dof" if low == high else f"{low}-{high} dof"


COMPONENT_LINESTYLES = ("-", "--", ":")
"""Components of one quantity (x, y, z) in an estimator's row: told apart by line style, so
that the row keeps the estimator's colour (``workbench.style``)."""


def errors_on_axes(
    axes: plt.Axes,
    series: ErrorSeries,
    t0: float,
    components: tuple[int, ...],
    names: tuple[str, ...],
    colour: str,
    scale: float = 1.0,
) -> None:
    """Error components with their +/-3 sigma envelopes (``scale``: e.g. rad -> deg), all in
    the estimator's ``colour``; component k in line style k, its envelope a thin line of the
    same style."""
    for index, (component, name) in enumerate(zip(components, names, strict=True)):
        linestyle = COMPONENT_LINESTYLES[index % len(COMPONENT_LINESTYLES)]
        sigma = 3.0 * scale * series.sigmas[:, component]
        t = series.t - t0
        axes.plot(
            t,
            scale * series.errors[:, component],
            color=colour,
            linestyle=linestyle,
            linewidth=0.9,
            label=name,
        )
        if np.all(np.isfinite(sigma)):
            for sign in (1.0, -1.0):
                axes.plot(
                    t,
                    sign * sigma,
                    color=colour,
                    linestyle=linestyle,
                    linewidth=0.5,
                    alpha=0.5,
                    label="_envelope",
                )
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize=7, loc="upper right", ncol=len(components))


def consistency_on_axes(
    axes: plt.Axes, curves: list[tuple[str, str, AveragedSeries]], t0: float
) -> None:
    """Per-dof averages over time of several estimators, each with its own shaded 95 %
    band: ``curves`` of (estimator label, scored kind, series)."""
    for label, kind, series in curves:
        style = estimator_style(label, kind)
        t = series.t - t0 if np.all(np.isfinite(series.t)) else np.arange(len(series.t))
        axes.fill_between(
            t, series.lower, series.upper, color=style.color, alpha=0.12, linewidth=0, step="mid"
        )
        suffix = " smoothed" if kind == "smoothed" else ""
        axes.plot(
            t,
            series.mean,
            linewidth=1.0,
            label=f"{label}{suffix} ({series.runs} runs, band: {dof_text(series)})",
            **style.keywords(len(t)),
        )
    axes.axhline(1.0, color="0.3", linewidth=0.6)
    _log_y(axes)
    axes.set_ylabel("per dof")
    axes.grid(True, alpha=0.3)
    _legend_outside(axes)


def nis_on_axes(
    axes: plt.Axes, label: str, t: np.ndarray, nis: np.ndarray, dof: np.ndarray
) -> None:
    """Each update's NIS per dof with its two-sided 95 % band (per update: dofs differ)."""
    from scipy.stats import chi2

    style = estimator_style(label)
    order = np.argsort(t)
    t, nis, dof = t[order], nis[order], np.maximum(dof[order], 1)
    axes.fill_between(
        t,
        chi2.ppf(0.025, dof) / dof,
        chi2.ppf(0.975, dof) / dof,
        color=style.color,
        alpha=0.15,
        linewidth=0,
        step="mid",
        label="95 % band",
    )
    axes.plot(t, nis / dof, ".", color=style.color, markersize=2, label=f"{label}: NIS / dof")
    _log_y(axes)
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize=7, loc="upper right")


# ---------------------------------------------------------------------------- figures


def _reference_label(run: RunRecord) -> str:
    source = (run.metrics or {}).get("reference_source")
    return f"reference ({source})" if source else "reference"


def trajectory_figure(pairs: list[PairSummary], title: str, seed: int | None) -> NamedFigure | None:
    if not pairs:
        return None
    columns = min(3, len(pairs))
    rows = int(np.ceil(len(pairs) / columns))
    figure, axes = plt.subplots(rows, columns, figsize=(4.5 * columns, 4.2 * rows), squeeze=False)
    for ax, pair in zip(axes.ravel(), pairs, strict=False):
        run = chosen_run(pair, seed)
        if (
            run is None
            or not (run.folder / "estimate.tum").is_file()
            and not (run.folder / "estimate_smoothed.tum").is_file()
        ):
            _say(ax, "no world trajectory" if run is not None else f"no finished run (seed {seed})")
            ax.set_title(pair.estimator, fontsize=9)
            continue
        trajectories, styles = {}, {}
        if (run.folder / "reference.tum").is_file():
            label = _reference_label(run)
            trajectories[label] = read_tum(run.folder / "reference.tum")
            styles[label] = {"color": REFERENCE_COLOUR, "linestyle": "-", "linewidth": 0.8}
        for kind, name in (("causal", "estimate.tum"), ("smoothed", "estimate_smoothed.tum")):
            if (run.folder / name).is_file():
                trajectories[kind] = read_tum(run.folder / name)
                styles[kind] = estimator_style(pair.estimator, kind).keywords()
        trajectory_on_axes(ax, trajectories, styles=styles)
        ax.set_title(f"{pair.estimator} (seed {run.seed})", fontsize=9)
    for ax in axes.ravel()[len(pairs) :]:
        ax.set_visible(False)
    figure.suptitle(title)
    return "trajectories", figure


def _t0(pairs: list[PairSummary], seed: int | None) -> float:
    starts = []
    for pair in pairs:
        run = chosen_run(pair, seed)
        if run is not None and "pose" in run.errors and len(run.errors["pose"].t):
            starts.append(float(run.errors["pose"].t[0]))
        for cell in pair.cells.values():
            if (
                cell.averaged is not None
                and len(cell.averaged.t)
                and np.isfinite(cell.averaged.t[0])
            ):
                starts.append(float(cell.averaged.t[0]))
    return min(starts) if starts else 0.0


def _no_errors_reason(run: RunRecord | None) -> str:
    """Why a run has no causal pose errors to draw (said in its panel)."""
    if run is None:
        return "no finished run"
    metrics = run.metrics or {}
    if metrics.get("reference_source") is None:
        return "no ground truth in this dataset"
    if metrics.get("ate_rmse_m") is None and metrics.get("ate_rmse_smoothed_m") is not None:
        return "no causal estimate (a batch solution exists only at the end)"
    return "its causal pose has no covariance (a derived estimate)"


def error_figure(pairs: list[PairSummary], title: str, seed: int | None) -> NamedFigure | None:
    """Pose errors of one seed, a row per estimator (attitude, position)."""
    if not pairs:
        return None
    t0 = _t0(pairs, seed)
    figure, axes = plt.subplots(
        len(pairs), 2, figsize=(10, 2.2 * len(pairs) + 0.6), sharex=True, squeeze=False
    )
    for row, pair in enumerate(pairs):
        run = chosen_run(pair, seed)
        series = None if run is None else run.errors.get("pose")
        if series is None:
            _say(axes[row, 0], f"{pair.estimator}: {_no_errors_reason(run)}")
            _say(axes[row, 1], "")
            continue
        colour = estimator_style(pair.estimator).color
        degrees = np.rad2deg(1.0)
        if series.errors.shape[1] == 6:  # 3-D: [rotation (body), translation (body)]
            errors_on_axes(axes[row, 0], series, t0, (0, 1, 2), ("x", "y", "z"), colour, degrees)
            errors_on_axes(axes[row, 1], series, t0, (3, 4, 5), ("x", "y", "z"), colour)
            axes[row, 0].set_ylabel(f"{pair.estimator}\nrotation [deg]", fontsize=8)
        else:  # 2-D: [body x, body y, heading]
            errors_on_axes(axes[row, 0], series, t0, (2,), ("heading",), colour, degrees)
            errors_on_axes(axes[row, 1], series, t0, (0, 1), ("x", "y"), colour)
            axes[row, 0].set_ylabel(f"{pair.estimator}\nheading [deg]", fontsize=8)
        axes[row, 1].set_ylabel(f"{pair.estimator}\nposition (body) [m]", fontsize=8)
    axes[-1, 0].set_xlabel(time_label(t0))
    axes[-1, 1].set_xlabel(time_label(t0))
    figure.suptitle(
        f"{title}: pose errors (truth - estimate) with +/-3 sigma, {seed_text(seed)}",
        fontsize=10,
    )
    return "pose_errors", figure


def consistency_figure(pairs: list[PairSummary], title: str) -> NamedFigure | None:
    blocks = [block for block in TABLE_BLOCKS if any(block in pair.cells for pair in pairs)]
    if not blocks:
        return None
    t0 = _t0(pairs, None)
    figure, axes = plt.subplots(len(blocks), 1, figsize=(9.5, 2.8 * len(blocks)), squeeze=False)
    for ax, block in zip(axes[:, 0], blocks, strict=True):
        curves = [
            (pair.estimator, pair.cells[block].scored, pair.cells[block].averaged)
            for pair in pairs
            if block in pair.cells and pair.cells[block].averaged is not None
        ]
        consistency_on_axes(ax, curves, t0)
        ax.set_title(f"{title}: {BLOCK_TITLES[block]}, averaged over runs, 95% band", fontsize=9)
        ax.set_xlabel(time_label(t0))
    return "consistency", figure


def nis_figure(pairs: list[PairSummary], title: str, seed: int | None) -> NamedFigure | None:
    panels = [(pair, chosen_run(pair, seed)) for pair in pairs if "nis" in pair.cells]
    panels = [(pair, run) for pair, run in panels if run is not None]
    if not panels:
        return None
    t0 = _t0(pairs, seed)
    figure, axes = plt.subplots(
        len(panels), 1, figsize=(8, 2.4 * len(panels)), sharex=True, squeeze=False
    )
    for ax, (pair, run) in zip(axes[:, 0], panels, strict=True):
        t, nis, dof = _npz(run.folder, "diag_scan_nis_t", "diag_scan_nis", "diag_scan_nis_dof")
        nis_on_axes(ax, pair.estimator, t - t0, nis, dof)
        ax.set_title(f"{title}: {pair.estimator}, seed {run.seed}", fontsize=9)
    axes[-1, 0].set_xlabel(time_label(t0))
    return "nis", figure


def landmark_count_figure(
    pairs: list[PairSummary], title: str, seed: int | None
) -> NamedFigure | None:
    found = []
    for pair in pairs:
        run = chosen_run(pair, seed)
        if run is not None:
            t, count = _npz(run.folder, "diag_landmark_count_t", "diag_landmark_count")
            if len(count):
                found.append((pair.estimator, t, count))
    if not found:
        return None
    t0 = min(float(t[0]) for _, t, _ in found)
    figure, axes = plt.subplots(figsize=(9, 3.2))
    for label, t, count in found:
        axes.step(
            t - t0,
            count,
            where="post",
            label=label,
            linewidth=1.0,
            **estimator_style(label).keywords(),
        )
    axes.set_xlabel(time_label(t0))
    axes.set_ylabel("landmarks in state")
    axes.grid(True, alpha=0.3)
    _legend_outside(axes)
    axes.set_title(
        f"{title}: landmarks in the state ({seed_text(seed)})",
        fontsize=9,
    )
    return "landmark_count", figure


def time_per_landmarks(folder: Path) -> tuple[np.ndarray, np.ndarray]:
    """(landmarks in the state at each processed measurement, its time [s]) of one run."""
    timing_t, seconds, count_t, count = _npz(
        folder, "timing_t", "timing_seconds", "diag_landmark_count_t", "diag_landmark_count"
    )
    if len(timing_t) == 0:
        return np.zeros(0, dtype=int), np.zeros(0)
    if len(count_t) == 0:
        return np.zeros(len(timing_t), dtype=int), seconds
    index = np.searchsorted(count_t, timing_t, side="right") - 1
    counts = np.where(index >= 0, count[np.clip(index, 0, None)], 0)
    return counts.astype(int), seconds


def time_figure(pairs: list[PairSummary], title: str) -> NamedFigure | None:
    found = []
    for pair in pairs:
        pooled = [time_per_landmarks(run.folder) for run in pair.finished_runs]
        counts = np.concatenate([c for c, _ in pooled]) if pooled else np.zeros(0, dtype=int)
        seconds = np.concatenate([s for _, s in pooled]) if pooled else np.zeros(0)
        if counts.size:
            values = np.unique(counts)
            means = np.array([1000.0 * np.mean(seconds[counts == value]) for value in values])
            found.append((pair.estimator, values, means))
    if not found:
        return None
    figure, axes = plt.subplots(figsize=(9, 3.6))
    for label, values, means in found:
        axes.plot(
            values,
            means,
            linewidth=1.0,
            label=label,
            **estimator_style(label).keywords(len(values)),
        )
    axes.set_xlabel("landmarks in state")
    axes.set_ylabel("mean time per step [ms]")
    _log_y(axes)
    axes.grid(True, alpha=0.3)
    _legend_outside(axes)
    axes.set_title(f"{title}: time per step vs landmarks (every run)", fontsize=9)
    return "time_vs_landmarks", figure


def dataset_figures(
    pairs: list[PairSummary], title: str, seed: int | None = None
) -> list[NamedFigure]:
    """Every figure of one dataset's pairs (those with finished runs)."""
    pairs = [pair for pair in pairs if pair.finished_runs]
    builders = (
        lambda: trajectory_figure(pairs, title, seed),
        lambda: error_figure(pairs, title, seed),
        lambda: consistency_figure(pairs, title),
        lambda: nis_figure(pairs, title, seed),
        lambda: landmark_count_figure(pairs, title, seed),
        lambda: time_figure(pairs, title),
    )
    return [built for build in builders if (built := build()) is not None]


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
