"""Figures of one run, in pairs: ``*_on_axes`` draws on given axes, the wrapper makes and
saves the figure (GTSAM python's style). PNG by default (PDF, SVG on request), Agg backend,
no screen needed. The rules of the comparison figures (``workbench.figures``) hold here too:
time relative to the run's first pose (t0 stated in the title), no offset text on any axis,
no axes without data, chi-square bands per distinct dof.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from datasets.estimate import Estimate
from datasets.sequence import Sequence
from datasets.state import BlockName, StateBlock
from datasets.trajectory import Trajectory
from workbench.figures.common import (
    NamedFigure,
    TimeAxis,
    log_y_if_wide,
    plain_numbers,
    plt,
    save_figure,
)
from workbench.figures.consistency import band, band_dofs, nis_on_axes
from workbench.plot_formats import DEFAULT_PLOT_FORMATS
from workbench.style import REFERENCE_COLOUR

__all__ = [
    "NamedFigure",
    "block_on_axes",
    "run_nis_on_axes",
    "save_figure",
    "trajectory_on_axes",
    "write_run_plots",
]

ESTIMATE_COLOUR = "C3"


def trajectory_on_axes(
    axes: plt.Axes,
    trajectories: dict[str, Trajectory],
    landmarks: dict[str, np.ndarray] | None = None,
    styles: dict[str, dict] | None = None,
) -> None:
    """Top view (x, y) of named trajectories (with optional ``plot`` keywords per name) and
    optional named landmark sets (k, >=2)."""
    for label, trajectory in trajectories.items():
        keywords = {"linewidth": 1.2, **(styles or {}).get(label, {})}
        axes.plot(trajectory.positions[:, 0], trajectory.positions[:, 1], label=label, **keywords)
    for label, points in (landmarks or {}).items():
        if len(points):
            axes.scatter(
                points[:, 0],
                points[:, 1],
                s=12,
                marker="x" if "true" in label else "o",
                label=label,
            )
    axes.set_xlabel("x [m]")
    axes.set_ylabel("y [m]")
    axes.set_aspect("equal", adjustable="datalim")
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize=8)


def block_on_axes(
    axes: np.ndarray,
    block: StateBlock,
    truth: StateBlock | None,
    unit: str,
    time: TimeAxis | None = None,
) -> None:
    """Each component of a state block with its +/-3 sigma envelope, and truth when known
    (``time``: the run's time axis, t - t0)."""
    time = time or TimeAxis()
    t = time(block.t)
    for component, ax in enumerate(axes):
        values = block.values[:, component]
        ax.plot(t, values, color=ESTIMATE_COLOUR, linewidth=1.0, label="estimate")
        if block.covariances is not None:
            sigma = np.sqrt(np.maximum(block.covariances[:, component, component], 0.0))
            ax.fill_between(
                t,
                values - 3 * sigma,
                values + 3 * sigma,
                color=ESTIMATE_COLOUR,
                alpha=0.2,
                label="+/-3 sigma",
            )
        if truth is not None and truth.values.shape[1] > component:
            ax.plot(
                time(truth.t),
                truth.values[:, component],
                color=REFERENCE_COLOUR,
                linewidth=0.8,
                linestyle="--",
                label="truth",
            )
        ax.set_ylabel(f"[{component}] [{unit}]")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    time.on_axes(axes[-1])


def run_nis_on_axes(
    axes: plt.Axes,
    times: np.ndarray,
    nis: np.ndarray,
    dof: np.ndarray,
    time: TimeAxis | None = None,
) -> None:
    """NIS / dof of each associated measurement: a dot inside the two-sided 95 % band of its
    own dof, a ring outside; the bands of the distinct dofs (at most the widest and the
    narrowest) as grey lines labelled with their dof; a log axis where the values span a
    decade."""
    time = time or TimeAxis()
    order = np.argsort(times, kind="stable")
    times, nis, dof = times[order], nis[order], np.maximum(dof[order], 1)
    drawn = band_dofs(dof)
    nis_on_axes(axes, "estimate", time(times), nis, dof, drawn, ESTIMATE_COLOUR, "measurements")
    log_y_if_wide(axes, [nis / dof, *band(np.array(drawn))])
    time.on_axes(axes)


_BLOCK_UNITS = {
    BlockName.VELOCITY: "m/s",
    BlockName.GYRO_BIAS: "rad/s",
    BlockName.ACCEL_BIAS: "m/s^2",
}


def run_time_axis(estimate: Estimate, sequence: Sequence) -> TimeAxis:
    """t0 of a run's figures: its first pose (estimate or truth)."""
    starts = []
    for history in (estimate.causal, estimate.smoothed):
        if history is not None and history.pose is not None and len(history.pose):
            starts.append(float(history.pose.t[0]))
    truth = sequence.ground_truth
    if truth is not None and truth.pose is not None and len(truth.pose):
        starts.append(float(truth.pose.t[0]))
    return TimeAxis.starting_at(starts)


def write_run_plots(
    estimate: Estimate,
    sequence: Sequence,
    out_dir: Path,
    title: str,
    formats: tuple[str, ...] = DEFAULT_PLOT_FORMATS,
) -> list[Path]:
    """The standard figures of a run folder: trajectory (as estimated, not aligned), state
    blocks with 3 sigma, NIS, landmark count, in each of ``formats``. Returns the files
    written; a figure with nothing to draw is not written."""
    written: list[Path] = []
    time = run_time_axis(estimate, sequence)
    truth = sequence.ground_truth
    trajectories: dict[str, Trajectory] = {}
    styles: dict[str, dict] = {}
    if truth is not None and truth.pose is not None and len(truth.pose):
        source = sequence.reference_source
        label = f"reference ({source})" if source else "reference"
        trajectories[label] = truth.pose
        styles[label] = {"color": REFERENCE_COLOUR, "linewidth": 1.0}
    if estimate.causal.pose is not None and len(estimate.causal.pose):
        trajectories["estimate (causal)"] = estimate.causal.pose
        styles["estimate (causal)"] = {"color": ESTIMATE_COLOUR}
    if estimate.smoothed is not None and estimate.smoothed.pose is not None:
        if len(estimate.smoothed.pose):
            trajectories["estimate (smoothed)"] = estimate.smoothed.pose
            styles["estimate (smoothed)"] = {"color": ESTIMATE_COLOUR, "linestyle": "--"}
    if trajectories:
        landmarks = {}
        if truth is not None and truth.landmarks is not None:
            landmarks["true landmarks"] = truth.landmarks.positions
        if estimate.landmarks is not None and estimate.landmarks.frame == "world":
            landmarks["estimated landmarks"] = estimate.landmarks.positions
        figure, axes = plt.subplots(figsize=(7, 6))
        trajectory_on_axes(axes, trajectories, landmarks, styles)
        axes.set_title(f"{title} (as estimated, not aligned)")
        written += save_figure(plain_numbers(figure), out_dir / "trajectory", formats)
    for name, block in estimate.causal.blocks.items():
        if len(block.t) == 0:
            continue
        truth_block = None
        if truth is not None:
            truth_block = (
                truth.body_velocity
                if (name == BlockName.VELOCITY and block.frame == "body")
                else truth.history.block(name)
            )
            if truth_block is not None and len(truth_block.t) == 0:
                truth_block = None
        figure, axes = plt.subplots(
            block.values.shape[1],
            1,
            figsize=(7, 2 * block.values.shape[1] + 0.4),
            sharex=True,
            squeeze=False,
        )
        block_on_axes(axes[:, 0], block, truth_block, _BLOCK_UNITS.get(name, ""), time)
        axes[0, 0].set_title(time.titled(f"{title}: {name} ({block.frame} frame)"))
        written += save_figure(plain_numbers(figure), out_dir / f"{name}", formats)
    diagnostics = estimate.diagnostics
    if len(diagnostics.nis):
        figure, axes = plt.subplots(figsize=(9, 3.8))
        run_nis_on_axes(axes, diagnostics.nis_t, diagnostics.nis, diagnostics.nis_dof, time)
        axes.set_title(time.titled(f"{title}: NIS / dof per measurement"), fontsize=10)
        written += save_figure(plain_numbers(figure), out_dir / "nis", formats)
    if len(diagnostics.landmark_count):
        figure, axes = plt.subplots(figsize=(7, 3))
        axes.step(
            time(diagnostics.landmark_count_t),
            diagnostics.landmark_count,
            where="post",
            color=ESTIMATE_COLOUR,
        )
        time.on_axes(axes)
        axes.set_ylabel("landmarks in state")
        axes.grid(True, alpha=0.3)
        axes.set_title(time.titled(title))
        written += save_figure(plain_numbers(figure), out_dir / "landmark_count", formats)
    return written
