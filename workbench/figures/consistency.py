"""NEES and NIS per degree of freedom against their chi-square bands.

``consistency``: per table block (pose, velocity, biases, map, NIS), the per-step average
over runs of every estimator on one axes. A band depends only on the summed dof D of a step
(``chi2.ppf([.025, .975], D) / D``): estimators with the same constant D share one band,
drawn once in grey and labelled with its dof; a curve whose D changes from step to step (the
map, NIS: the landmarks in view) has its own band, drawn as thin lines in its colour. No
translucent band per estimator, whose overlap turned grey.

``nis``: each update's NIS / dof of the chosen seed, a panel per estimator; an update is a
filled dot inside its own 95 % band (that of its dof), a ring outside; the bands of the
smallest and largest dof bracket all others (chi-square bands per dof are nested).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from workbench.figures.common import (
    LEGEND_FONT,
    NamedFigure,
    TimeAxis,
    curve_label,
    legend_outside,
    log_y_if_wide,
    plain_numbers,
    plt,
    proxy,
    runs_text,
)
from workbench.metrics.consistency import CONFIDENCE, per_dof_band
from workbench.results.consistency import TABLE_BLOCKS, AveragedSeries
from workbench.style import BAND_COLOUR, band_linestyle, curve_style

if TYPE_CHECKING:
    from workbench.figures.view import DatasetView

QUANTITIES = {
    "pose": "pose NEES",
    "velocity": "velocity NEES",
    "gyro_bias": "gyro-bias NEES",
    "accel_bias": "accelerometer-bias NEES",
    "map": "map NEES",
    "nis": "NIS",
}
"""What each block's axes plots (its y-label reads ``QUANTITY / dof``)."""
BLOCK_NOTES = {
    "map": "joint NEES of each map snapshot",
    "nis": "each update against its prediction",
}
PERCENT = f"{100 * CONFIDENCE:.0f} %"


def band(dof: np.ndarray | int, confidence: float = CONFIDENCE) -> tuple[np.ndarray, np.ndarray]:
    """The two-sided chi-square band of a statistic per dof: (lower, upper) / dof."""
    return per_dof_band(np.maximum(np.asarray(dof, dtype=float), 1.0), confidence)


@dataclass(frozen=True)
class Curve:
    """One estimator's averaged series on a block's axes."""

    estimator: str
    kind: str
    has_causal: bool
    series: AveragedSeries

    @property
    def constant_dof(self) -> int | None:
        """The summed dof D when it is the same at every step, else None."""
        dof = np.unique(self.series.dof)
        return int(dof[0]) if len(dof) == 1 else None

    def label(self) -> str:
        parts = [runs_text(self.series.runs)]
        if self.constant_dof is None:
            dof = self.series.dof // max(self.series.runs, 1)
            parts.append(f"{int(dof.min())}-{int(dof.max())} dof per run")
        if self.kind == "smoothed" and not self.has_causal:
            parts.insert(0, "no causal estimate")
        name = curve_label(self.estimator, self.kind, has_causal=True)
        return f"{name} ({'; '.join(parts)})"


def _band_label(curves: list[Curve], summed: int) -> str:
    """``95 % band, 6 dof`` or, averaged over R runs, ``95 % band, 6 dof x 3 runs``."""
    parts = []
    for curve in curves:
        runs = curve.series.runs
        per_run = summed // runs if runs and summed % runs == 0 else summed
        part = (
            f"{per_run} dof" if runs == 1 or per_run == summed else f"{per_run} dof x {runs} runs"
        )
        if part not in parts:
            parts.append(part)
    return f"{PERCENT} band, " + " = ".join(parts)


def consistency_on_axes(
    axes: plt.Axes,
    curves: list[Curve],
    time: TimeAxis,
    quantity: str,
    missing: list[tuple[str, str]] = (),
) -> None:
    """Per-dof averages over time of several estimators with their chi-square bands (one
    per distinct constant dof, grey, labelled; a varying one per curve, thin, in its
    colour); ``missing``: (estimator, why) named in the legend."""
    shared: dict[int, list[Curve]] = {}
    for curve in curves:
        if curve.constant_dof is not None:
            shared.setdefault(curve.constant_dof, []).append(curve)
    extent = []
    for index, (summed, owners) in enumerate(sorted(shared.items())):
        lower, upper = band(summed)
        style = band_linestyle(index)
        axes.axhline(
            float(lower),
            color=BAND_COLOUR,
            linestyle=style,
            linewidth=0.9,
            label=_band_label(owners, summed),
        )
        axes.axhline(float(upper), color=BAND_COLOUR, linestyle=style, linewidth=0.9)
        if len(shared) == 1:
            axes.axhspan(float(lower), float(upper), color=BAND_COLOUR, alpha=0.08, linewidth=0)
        extent += [lower, upper]
    varying = False
    for curve in curves:
        series = curve.series
        style = curve_style(curve.estimator, curve.kind)
        t = time(series.t) if np.all(np.isfinite(series.t)) else np.arange(len(series.t))
        axes.plot(t, series.mean, linewidth=1.0, label=curve.label(), **style.keywords(len(t)))
        extent.append(series.mean)
        if curve.constant_dof is None:
            varying = True
            for bound in (series.lower, series.upper):
                axes.step(
                    t,
                    bound,
                    where="mid",
                    color=style.color,
                    linewidth=0.5,
                    alpha=0.6,
                    label="_band",
                )
            extent += [series.lower, series.upper]
    if varying:
        proxy(
            axes,
            f"{PERCENT} band of each curve whose dof varies (thin, its colour)",
            color=BAND_COLOUR,
            linewidth=0.5,
        )
    for estimator, why in missing:
        proxy(axes, f"{estimator} ({why})", **curve_style(estimator).keywords())
    axes.axhline(1.0, color="0.3", linewidth=0.6, label="_expected")
    log_y_if_wide(axes, extent)
    axes.set_ylabel(f"{quantity} / dof")
    time.on_axes(axes)
    axes.grid(True, alpha=0.3)
    legend_outside(axes)


def consistency_figure(view: DatasetView) -> NamedFigure | None:
    """NEES (and NIS) per dof averaged over the runs per step, a panel per table block."""
    pairs = view.pairs
    blocks = [block for block in TABLE_BLOCKS if any(block in pair.cells for pair in pairs)]
    if not blocks:
        return None
    time = view.time_axis
    figure, axes = plt.subplots(len(blocks), 1, figsize=(10.0, 2.9 * len(blocks)), squeeze=False)
    for ax, block in zip(axes[:, 0], blocks, strict=True):
        curves, missing = [], []
        for pair in pairs:
            cell = pair.cells.get(block)
            run = view.run(pair)
            if cell is not None and cell.averaged is not None:
                has_causal = run is None or view.files(run).has_pose("causal")
                curves.append(Curve(pair.estimator, cell.scored, has_causal, cell.averaged))
            elif run is not None and block != "nis" and view.files(run).lacks_covariance(block):
                missing.append((pair.estimator, "no covariance"))
        consistency_on_axes(ax, curves, time, QUANTITIES[block], missing)
        note = f" ({BLOCK_NOTES[block]})" if block in BLOCK_NOTES else ""
        ax.set_title(
            f"{view.title}: {QUANTITIES[block]}{note} per dof, mean over runs at each step",
            fontsize=9,
        )
    if time.note:
        axes[0, 0].set_title(f"{axes[0, 0].get_title()}; {time.note}", fontsize=9)
    return "consistency", plain_numbers(figure)


# ---------------------------------------------------------------------------- per update


def nis_on_axes(
    axes: plt.Axes,
    estimator: str,
    t: np.ndarray,
    nis: np.ndarray,
    dof: np.ndarray,
    bands: list[int],
    colour: str | None = None,
    what: str = "updates",
) -> None:
    """Each update's NIS / dof: a dot inside the 95 % band of its own dof, a ring outside;
    the bands of the dofs ``bands`` as grey lines, labelled with their dof (``colour``: the
    estimator's, by default; ``what`` the points are, for the legend)."""
    dof = np.maximum(np.asarray(dof), 1)
    ratio = nis / dof
    lower, upper = band(dof)
    inside = (ratio >= lower) & (ratio <= upper)
    colour = colour or curve_style(estimator).color
    share = 100.0 * float(np.mean(inside)) if len(inside) else 0.0
    axes.plot(
        t[inside],
        ratio[inside],
        ".",
        color=colour,
        markersize=2.5,
        label=f"{estimator}: {share:.0f} % of {len(ratio)} {what} inside their band",
    )
    if np.any(~inside):
        axes.plot(
            t[~inside],
            ratio[~inside],
            "o",
            color=colour,
            markersize=2.5,
            markerfacecolor="none",
            markeredgewidth=0.6,
            label=f"{estimator}: outside their band",
        )
    # only the extremes drawn: say so, the other dofs' bands lie between them
    extremes = len(np.unique(dof)) > len(bands)
    for index, value in enumerate(bands):
        low, high = band(value)
        style = band_linestyle(index)
        which = "" if not extremes else " (widest)" if index == 0 else " (narrowest)"
        axes.axhline(
            float(low),
            color=BAND_COLOUR,
            linestyle=style,
            linewidth=0.8,
            label=f"{PERCENT} band, {value} dof{which}",
        )
        axes.axhline(float(high), color=BAND_COLOUR, linestyle=style, linewidth=0.8)
    axes.set_ylabel("NIS / dof")
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize=LEGEND_FONT, loc="upper left", bbox_to_anchor=(1.01, 1.0))


def band_dofs(dofs: np.ndarray) -> list[int]:
    """Every distinct dof when there are at most three, else the smallest and the largest
    (their bands bracket the others': the widest and the narrowest)."""
    distinct = sorted({int(value) for value in np.maximum(dofs, 1)})
    return distinct if len(distinct) <= 3 else [distinct[0], distinct[-1]]


def nis_figure(view: DatasetView) -> NamedFigure | None:
    """Each update's NIS / dof of the chosen seed, a panel per estimator with updates."""
    panels = []
    for pair, run in view.chosen:
        if "nis" not in pair.cells:
            continue
        t, nis, dof = view.files(run).arrays(
            "diag_scan_nis_t", "diag_scan_nis", "diag_scan_nis_dof"
        )
        if len(t):
            order = np.argsort(t, kind="stable")
            panels.append((pair, t[order], nis[order], dof[order]))
    if not panels:
        return None
    time = view.time_axis
    figure, axes = plt.subplots(
        len(panels),
        1,
        figsize=(10.0, 2.3 * len(panels) + 0.5),
        sharex=True,
        sharey=True,
        squeeze=False,
    )
    pooled = []
    for ax, (pair, t, nis, dof) in zip(axes[:, 0], panels, strict=True):
        drawn = band_dofs(dof)
        nis_on_axes(ax, pair.estimator, time(t), nis, dof, drawn)
        pooled += [nis / np.maximum(dof, 1), *band(np.array(drawn))]
    log_y_if_wide(axes[0, 0], pooled)
    time.on_axes(axes[-1, 0])
    figure.suptitle(
        time.titled(f"{view.title}: NIS / dof of each update, {view.seed_label}"), fontsize=10
    )
    return "nis", plain_numbers(figure)
