"""Figures of one run, in pairs: ``*_on_axes`` draws on given axes, the wrapper makes and
saves the figure (GTSAM python's style). PNG by default (PDF, SVG on request), Agg backend,
no screen needed."""

from __future__ import annotations

from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from scipy.stats import chi2  # noqa: E402

from datasets.estimate import Estimate  # noqa: E402
from datasets.sequence import Sequence  # noqa: E402
from datasets.state import BlockName, StateBlock  # noqa: E402
from datasets.trajectory import Trajectory  # noqa: E402
from workbench.plot_formats import DEFAULT_PLOT_FORMATS  # noqa: E402

NamedFigure = tuple[str, plt.Figure]
"""A figure and the file name (without suffix) it is saved under."""


def save_figure(
    figure: plt.Figure, path_without_suffix: Path, formats: tuple[str, ...] = DEFAULT_PLOT_FORMATS
) -> list[Path]:
    """Lay out once, save in each of ``formats``, close; returns the files written.

    ``tight_layout`` once rather than ``bbox_inches="tight"``, which draws every file twice.
    """
    path_without_suffix.parent.mkdir(parents=True, exist_ok=True)
    figure.tight_layout()
    written = []
    for suffix in formats:
        path = path_without_suffix.with_suffix(f".{suffix}")
        figure.savefig(path, dpi=120)
        written.append(path)
    plt.close(figure)
    return written


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


def block_on_axes(axes: np.ndarray, block: StateBlock, truth: StateBlock | None, unit: str) -> None:
    """Each component of a state block with its +/-3 sigma envelope, and truth when known."""
    for component, ax in enumerate(axes):
        values = block.values[:, component]
        ax.plot(block.t, values, color="C3", linewidth=1.0, label="estimate")
        if block.covariances is not None:
            sigma = np.sqrt(np.maximum(block.covariances[:, component, component], 0.0))
            ax.fill_between(
                block.t,
                values - 3 * sigma,
                values + 3 * sigma,
                color="C3",
                alpha=0.2,
                label="+/-3 sigma",
            )
        if truth is not None and truth.values.shape[1] > component:
            ax.plot(
                truth.t,
                truth.values[:, component],
                color="k",
                linewidth=0.8,
                linestyle="--",
                label="truth",
            )
        ax.set_ylabel(f"[{component}] [{unit}]")
        ax.grid(True, alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[-1].set_xlabel("t [s]")


def nis_on_axes(axes: plt.Axes, times: np.ndarray, nis: np.ndarray, dof: np.ndarray) -> None:
    """NIS per innovation with the one-sided 95% chi-square threshold of its dof."""
    axes.plot(times, nis, ".", markersize=2, color="C0", label="NIS")
    for value in np.unique(dof):
        axes.axhline(
            chi2.ppf(0.95, value),
            color="k",
            linestyle="-.",
            linewidth=0.8,
            label=f"95% bound, dof {value}",
        )
    axes.set_xlabel("t [s]")
    axes.set_ylabel("NIS")
    axes.set_yscale("log")
    axes.grid(True, alpha=0.3)
    axes.legend(fontsize=8)


_BLOCK_UNITS = {
    BlockName.VELOCITY: "m/s",
    BlockName.GYRO_BIAS: "rad/s",
    BlockName.ACCEL_BIAS: "m/s^2",
}


def write_run_plots(
    estimate: Estimate,
    sequence: Sequence,
    out_dir: Path,
    title: str,
    formats: tuple[str, ...] = DEFAULT_PLOT_FORMATS,
) -> list[Path]:
    """The standard figures of a run folder: trajectory, state blocks with 3 sigma, NIS,
    landmark count, in each of ``formats``. Returns the files written."""
    written: list[Path] = []
    truth = sequence.ground_truth
    trajectories: dict[str, Trajectory] = {}
    if truth is not None and truth.pose is not None:
        source = sequence.metadata.get("reference_source")
        trajectories[f"reference ({source})" if source else "reference"] = truth.pose
    if estimate.causal.pose is not None:
        trajectories["estimate (causal)"] = estimate.causal.pose
    if estimate.smoothed is not None and estimate.smoothed.pose is not None:
        trajectories["estimate (smoothed)"] = estimate.smoothed.pose
    if trajectories:
        landmarks = {}
        if truth is not None and truth.landmarks is not None:
            landmarks["true landmarks"] = truth.landmarks.positions
        if estimate.landmarks is not None and estimate.landmarks.frame == "world":
            landmarks["estimated landmarks"] = estimate.landmarks.positions
        figure, axes = plt.subplots(figsize=(7, 6))
        trajectory_on_axes(axes, trajectories, landmarks)
        axes.set_title(title)
        written += save_figure(figure, out_dir / "trajectory", formats)
    for name, block in estimate.causal.blocks.items():
        truth_block = None
        if truth is not None:
            candidate = (
                truth.body_velocity
                if (name == BlockName.VELOCITY and block.frame == "body")
                else truth.history.block(name)
            )
            truth_block = candidate
        figure, axes = plt.subplots(
            block.values.shape[1],
            1,
            figsize=(7, 2 * block.values.shape[1]),
            sharex=True,
            squeeze=False,
        )
        block_on_axes(axes[:, 0], block, truth_block, _BLOCK_UNITS.get(name, ""))
        axes[0, 0].set_title(f"{title}: {name} ({block.frame} frame)")
        written += save_figure(figure, out_dir / f"{name}", formats)
    diagnostics = estimate.diagnostics
    if len(diagnostics.nis):
        figure, axes = plt.subplots(figsize=(7, 3.5))
        nis_on_axes(axes, diagnostics.nis_t, diagnostics.nis, diagnostics.nis_dof)
        axes.set_title(title)
        written += save_figure(figure, out_dir / "nis", formats)
    if len(diagnostics.landmark_count):
        figure, axes = plt.subplots(figsize=(7, 3))
        axes.step(diagnostics.landmark_count_t, diagnostics.landmark_count, where="post")
        axes.set_xlabel("t [s]")
        axes.set_ylabel("landmarks in state")
        axes.grid(True, alpha=0.3)
        axes.set_title(title)
        written += save_figure(figure, out_dir / "landmark_count", formats)
    return written
