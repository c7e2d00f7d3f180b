"""Top views: the reference and every estimator on one axes, aligned as the ATE aligns them
(``trajectories``), and one estimator's path coloured by its aligned position error
(``error_path``, evo's ``ape`` map plot)."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
from matplotlib.collections import LineCollection

from workbench.figures.aligned import AlignedPath
from workbench.figures.common import (
    LEGEND_FONT,
    NamedFigure,
    legend_outside,
    plain_numbers,
    plt,
    proxy,
)
from workbench.style import REFERENCE_STYLE, curve_style

if TYPE_CHECKING:
    from workbench.figures.view import DatasetView


def _top_view(axes: plt.Axes) -> None:
    axes.set_xlabel("x [m]")
    axes.set_ylabel("y [m]")
    axes.set_aspect("equal", adjustable="datalim")
    axes.grid(True, alpha=0.3)


def overlay_on_axes(
    axes: plt.Axes,
    reference: np.ndarray | None,
    reference_label: str | None,
    paths: list,
    missing: list[tuple[str, str, str]] = (),
) -> None:
    """Top view (x, y) of the reference (N, 3; NaN rows break the line) and of ``paths``
    (``AlignedPath`` or ``view.Unaligned``: label, estimator, kind, positions), each in its
    estimator's style (``workbench.style``); ``missing``: (label, estimator, why) of
    estimators that ran but have no path here, named in the legend."""
    if reference is not None:
        axes.plot(reference[:, 0], reference[:, 1], label=reference_label, **REFERENCE_STYLE)
    for path in paths:
        style = curve_style(path.estimator, path.kind)
        axes.plot(
            path.positions[:, 0],
            path.positions[:, 1],
            label=path.label,
            linewidth=1.0,
            **style.keywords(len(path.positions)),
        )
    for label, estimator, why in missing:
        proxy(axes, f"{label} ({why})", **curve_style(estimator).keywords())
    _top_view(axes)
    legend_outside(axes)


def _align_text(paths: list[AlignedPath]) -> str:
    kinds = sorted({"SE(3)" if path.align == "se3" else "SE(2)" for path in paths})
    return "/".join(kinds)


def trajectory_overlay_figure(view: DatasetView) -> NamedFigure | None:
    """The reference and every estimator of the chosen seed on one top view, each aligned
    to the reference as its ATE is (the batch smoother's smoothed path, dashed, as it has
    no causal one; a bag's front end too); without a reference, the paths as estimated."""
    if not view.chosen:
        return None
    aligned = view.reference_positions is not None
    paths = view.paths if aligned else view.unaligned
    drawn = {path.estimator for path in paths}
    missing = [(pair.estimator, pair.estimator, why) for pair, why in view.not_drawn(drawn)]
    if not paths:
        return None
    figure, axes = plt.subplots(figsize=(9.0, 6.0))
    overlay_on_axes(axes, view.reference_positions, view.reference_label, paths, missing)
    if aligned:
        how = f"aligned to the reference as for the ATE ({_align_text(paths)})"
    else:
        how = "as estimated (no reference trajectory in the runs: not aligned)"
    axes.set_title(f"{view.title}: trajectories {how}, {view.seed_label}", fontsize=9)
    return "trajectories", plain_numbers(figure)


def error_path_on_axes(
    axes: plt.Axes,
    path: AlignedPath,
    reference: np.ndarray | None,
    reference_label: str | None,
) -> None:
    """``path``'s poses paired with the reference, coloured by their aligned position error
    (colour bar in metres, from 0), over the reference in grey."""
    if reference is not None:
        axes.plot(
            reference[:, 0],
            reference[:, 1],
            color="0.6",
            linewidth=0.8,
            label=reference_label,
        )
    points = path.error_positions[:, :2]
    segments = np.stack([points[:-1], points[1:]], axis=1)
    colours = 0.5 * (path.errors[:-1] + path.errors[1:])
    lines = LineCollection(segments, cmap="viridis", linewidths=2.0, label=path.label)
    lines.set_array(colours)
    lines.set_clim(0.0, float(np.max(path.errors)) or 1.0)
    axes.add_collection(lines)
    axes.autoscale_view()
    colourbar = axes.figure.colorbar(lines, ax=axes, fraction=0.046, pad=0.02)
    colourbar.set_label("aligned position error [m]")
    _top_view(axes)
    axes.legend(fontsize=LEGEND_FONT, loc="best")


def error_path_figure(view: DatasetView) -> NamedFigure | None:
    """The path of the causal estimator with the lowest ATE of the chosen seed (of any
    estimator when none is causal), coloured by its aligned position error (the ATE's e_i
    at each paired pose)."""
    paths = [path for path in view.paths if path.estimator and len(path.errors) >= 2]
    if not paths:
        return None
    causal = [path for path in paths if path.kind == "causal"]
    best = min(causal or paths, key=lambda path: path.rmse)
    figure, axes = plt.subplots(figsize=(8.0, 6.0))
    error_path_on_axes(axes, best, view.reference_positions, view.reference_label)
    which = "causal estimate" if causal else "estimate"
    axes.set_title(
        f"{view.title}: {best.label}, the lowest ATE of a {which} ({best.rmse:.3g} m),\n"
        f"its path coloured by its aligned position error, {view.seed_label}",
        fontsize=9,
    )
    return "error_path", plain_numbers(figure)
