"""Errors over time: the aligned position error of every estimator on one axes
(``position_error``: the ATE's e_i, evo's ``ape`` plot for several estimates), and the
per-axis pose errors of each estimator with a covariance against its +/-3 sigma
(``pose_errors``)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from matplotlib.lines import Line2D

from workbench.figures.aligned import AlignedPath
from workbench.figures.common import (
    LEGEND_FONT,
    NamedFigure,
    TimeAxis,
    legend_outside,
    log_y_if_wide,
    plain_numbers,
    plt,
    proxy,
)
from workbench.results.consistency import ErrorSeries
from workbench.style import curve_style

if TYPE_CHECKING:
    from workbench.figures.view import DatasetView


def position_error_on_axes(
    axes: plt.Axes,
    paths: list[AlignedPath],
    time: TimeAxis,
    missing: list[tuple[str, str]] = (),
) -> None:
    """Each path's aligned position error over time, labelled with its RMSE (the ATE); a
    log y axis when the errors span a decade or more (dead reckoning beside SLAM);
    ``missing``: (estimator, why) of those without errors, named in the legend."""
    for path in paths:
        axes.plot(
            time(path.error_t),
            path.errors,
            label=f"{path.label}: ATE {path.rmse:.3g} m",
            linewidth=1.0,
            **curve_style(path.estimator, path.kind).keywords(len(path.errors)),
        )
    # the ratio of the curves' typical sizes decides, not a near-zero crossing of one curve;
    # the limits still hold every error down to 1e-4 of the largest
    typical = [np.percentile(path.errors, [10, 100]) for path in paths if len(path.errors)]
    largest = max(float(np.max(path.errors)) for path in paths)
    every = [np.maximum(path.errors, 1e-4 * largest) for path in paths]
    if not log_y_if_wide(axes, typical, limits=every):
        axes.set_ylim(bottom=0.0)
    for estimator, why in missing:
        proxy(axes, f"{estimator} ({why})", **curve_style(estimator).keywords())
    axes.set_ylabel("aligned position error [m]")
    time.on_axes(axes)
    axes.grid(True, alpha=0.3)
    legend_outside(axes)


def position_error_figure(view: DatasetView) -> NamedFigure | None:
    """Aligned position error over time of every estimator of the chosen seed (and the
    front end's), the same errors whose RMSE is the table's ATE."""
    if not view.paths:
        return None
    drawn = {path.estimator for path in view.paths}
    missing = [(pair.estimator, why) for pair, why in view.not_drawn(drawn)]
    figure, axes = plt.subplots(figsize=(10.0, 4.2))
    position_error_on_axes(axes, view.paths, view.time_axis, missing)
    title = f"{view.title}: position error after the ATE's alignment, {view.seed_label}"
    axes.set_title(view.time_axis.titled(title), fontsize=9)
    return "position_error", plain_numbers(figure)


COMPONENT_LINESTYLES = ("-", "--", ":")
"""Components of one quantity (x, y, z) in an estimator's row: told apart by line style, so
that the row keeps the estimator's colour (``workbench.style``)."""


def pose_errors_on_axes(
    axes: plt.Axes,
    series: ErrorSeries,
    time: TimeAxis,
    components: tuple[int, ...],
    names: tuple[str, ...],
    colour: str,
    scale: float = 1.0,
) -> None:
    """Error components with their +/-3 sigma envelopes (``scale``: e.g. rad -> deg), all in
    the estimator's ``colour``; component k in line style k, its envelope a thin line of the
    same style. No legend: the figure's one legend names the line styles."""
    t = time(series.t)
    for index, (component, name) in enumerate(zip(components, names, strict=True)):
        linestyle = COMPONENT_LINESTYLES[index % len(COMPONENT_LINESTYLES)]
        sigma = 3.0 * scale * series.sigmas[:, component]
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


def _no_errors_reason(view: DatasetView, pair) -> str:
    """Why an estimator has no causal pose errors with sigmas to draw (said in the legend)."""
    run = view.run(pair)
    if run is None:
        return "no finished run"
    files = view.files(run)
    if not files.has_pose("causal"):
        return "no causal estimate" if files.has_pose("smoothed") else "no pose"
    if files.lacks_covariance("pose"):
        return "no covariance"
    return "no pose paired with the reference"


def pose_error_figure(view: DatasetView) -> NamedFigure | None:
    """Per-axis pose errors (truth - estimate, body frame) of the chosen seed with +/-3 sigma,
    a row per estimator whose causal pose has a covariance; the others are named in the
    legend with the reason."""
    rows = []
    for pair, run in view.chosen:
        series = run.errors.get("pose")
        if series is not None and len(series.t):
            rows.append((pair, series))
    if not rows:
        return None
    drawn = {id(pair) for pair, _ in rows}
    missing = [pair for pair in view.pairs if id(pair) not in drawn]
    time = view.time_axis
    figure, axes = plt.subplots(
        len(rows), 2, figsize=(10, 1.9 * len(rows) + 1.4), sharex=True, squeeze=False
    )
    degrees = np.rad2deg(1.0)
    planar = rows[0][1].errors.shape[1] == 3
    for row, (pair, series) in enumerate(rows):
        colour = curve_style(pair.estimator).color
        if series.errors.shape[1] == 6:  # 3-D: [rotation (body), translation (body)]
            pose_errors_on_axes(axes[row, 0], series, time, (0, 1, 2), "xyz", colour, degrees)
            pose_errors_on_axes(axes[row, 1], series, time, (3, 4, 5), "xyz", colour)
            axes[row, 0].set_ylabel(f"{pair.estimator}\nrotation [deg]", fontsize=8)
        else:  # 2-D: [body x, body y, heading]
            pose_errors_on_axes(axes[row, 0], series, time, (2,), ("heading",), colour, degrees)
            pose_errors_on_axes(axes[row, 1], series, time, (0, 1), "xy", colour)
            axes[row, 0].set_ylabel(f"{pair.estimator}\nheading [deg]", fontsize=8)
        axes[row, 1].set_ylabel(f"{pair.estimator}\nposition (body) [m]", fontsize=8)
    time.on_axes(axes[-1, 0])
    time.on_axes(axes[-1, 1])
    handles = [
        Line2D([], [], color="0.2", linestyle=style, linewidth=0.9, label=name)
        for style, name in zip(
            COMPONENT_LINESTYLES, ("x / heading", "y") if planar else "xyz", strict=False
        )
    ]
    handles.append(Line2D([], [], color="0.2", linewidth=0.5, alpha=0.5, label="+/-3 sigma (thin)"))
    for pair in missing:
        handles.append(
            Line2D(
                [],
                [],
                label=f"{pair.estimator} ({_no_errors_reason(view, pair)})",
                **curve_style(pair.estimator).keywords(),
            )
        )
    figure.legend(
        handles=handles,
        loc="lower center",
        ncol=min(len(handles), 4),
        fontsize=LEGEND_FONT,
        frameon=False,
    )
    title = f"{view.title}: pose errors (truth - estimate) with +/-3 sigma, {view.seed_label}"
    figure.suptitle(time.titled(title), fontsize=10)
    return "pose_errors", plain_numbers(figure)
