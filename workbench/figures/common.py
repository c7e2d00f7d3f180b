"""What every comparison figure shares: the time axis (t - t0, no offset text), log axes with
at least two labelled ticks, legends, a layout that keeps clear of a figure's title and
legend, saving, and lazy access to a run folder's arrays."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import (  # noqa: E402
    FormatStrFormatter,
    LogLocator,
    NullLocator,
    ScalarFormatter,
)

from workbench.plot_formats import DEFAULT_PLOT_FORMATS  # noqa: E402

NamedFigure = tuple[str, plt.Figure]
"""A figure and the file name (without suffix) it is saved under."""

LEGEND_FONT = 7


# ---------------------------------------------------------------------------- time


@dataclass(frozen=True)
class TimeAxis:
    """Time relative to the sequence start ``t0`` [s], the same for every figure of a
    dataset: the axis reads ``t - t0 [s]`` and the figure's title states t0 once, so that no
    axis needs matplotlib's offset text (``+1.7e9``) to show epoch stamps."""

    t0: float = 0.0

    def __call__(self, t: np.ndarray) -> np.ndarray:
        return np.asarray(t, dtype=float) - self.t0

    @property
    def label(self) -> str:
        return "t [s]" if self.t0 == 0.0 else "t - t0 [s]"

    @property
    def note(self) -> str:
        """``t0 = ... s`` for the title (empty when the data start at 0)."""
        return "" if self.t0 == 0.0 else f"t0 = {self.t0:.3f} s (first pose)"

    def titled(self, text: str) -> str:
        return f"{text}; {self.note}" if self.note else text

    def on_axes(self, axes: plt.Axes) -> None:
        axes.set_xlabel(self.label)
        plain_numbers_on_axis(axes.xaxis)

    @staticmethod
    def starting_at(starts: list[float]) -> TimeAxis:
        """The axis whose t0 is the earliest finite start (0 without one)."""
        finite = [float(start) for start in starts if np.isfinite(start)]
        return TimeAxis(min(finite) if finite else 0.0)


# ---------------------------------------------------------------------------- axes


def plain_numbers_on_axis(axis) -> None:
    """Tick labels that are the numbers themselves: no offset (``+1.7e9``) and no
    multiplier (``1e-3``) text beside the axis, which readers miss."""
    formatter = axis.get_major_formatter()
    if isinstance(formatter, ScalarFormatter):
        formatter.set_useOffset(False)
        formatter.set_scientific(False)


def plain_numbers(figure: plt.Figure) -> plt.Figure:
    """``plain_numbers_on_axis`` on every linear axis of ``figure`` (colour bars included)."""
    for axes in figure.axes:
        plain_numbers_on_axis(axes.xaxis)
        plain_numbers_on_axis(axes.yaxis)
    return figure


def log_y_if_wide(
    axes: plt.Axes,
    values: list[np.ndarray],
    min_ratio: float = 10.0,
    limits: list[np.ndarray] | None = None,
) -> bool:
    """A log y axis when the positive finite ``values`` span at least ``min_ratio`` (a log axis
    helps only then), with plain tick labels (1, 2, 5 per decade over a few decades, fewer
    decades labelled over many) and no minor ticks; the limits are those of ``limits``
    (default: ``values``) with a margin. Linear otherwise, and also when fewer than two
    labelled ticks would fall inside the limits. Returns whether the axis is log."""
    low, high = _positive_range(values)
    if low is None or high < min_ratio * low:
        return False
    if limits is not None:
        low, high = _positive_range(limits)
    low, high = low / 1.25, high * 1.25
    # several subs per decade over many decades make LogLocator give up (no tick at all)
    subs = (1.0, 2.0, 5.0) if np.log10(high / low) <= 4.0 else (1.0,)
    locator = LogLocator(subs=subs)
    axes.set_yscale("log")
    axes.yaxis.set_major_locator(locator)
    axes.yaxis.set_minor_locator(NullLocator())
    axes.yaxis.set_major_formatter(FormatStrFormatter("%g"))
    axes.set_ylim(low, high)
    ticks = locator.tick_values(low, high)
    if np.count_nonzero((ticks >= low) & (ticks <= high)) >= 2:
        return True
    axes.set_yscale("linear")  # a log axis with one labelled tick is unreadable
    axes.yaxis.set_major_formatter(ScalarFormatter())
    axes.autoscale(axis="y")
    return False


def _positive_range(values: list[np.ndarray]) -> tuple[float | None, float | None]:
    found = [np.asarray(v, dtype=float).ravel() for v in values if np.size(v)]
    pooled = np.concatenate(found) if found else np.zeros(0)
    pooled = pooled[np.isfinite(pooled) & (pooled > 0)]
    if pooled.size == 0:
        return None, None
    return float(pooled.min()), float(pooled.max())


def legend_outside(axes: plt.Axes, **keywords) -> None:
    """The legend to the right of the axes, clear of the data."""
    axes.legend(
        fontsize=LEGEND_FONT,
        loc="upper left",
        bbox_to_anchor=(1.01, 1.0),
        borderaxespad=0.0,
        **keywords,
    )


def proxy(axes: plt.Axes, label: str, **keywords) -> None:
    """A legend entry without data (``axes.plot([], [])``): an estimator that ran but has
    nothing to draw here is named in the legend, not given an empty panel."""
    axes.plot([], [], label=label, **keywords)


def say(figure: plt.Figure, text: str) -> None:
    """A line under the figure (what is not drawn, and why)."""
    figure.text(0.01, 0.005, text, fontsize=LEGEND_FONT, ha="left", va="bottom", wrap=True)


# ---------------------------------------------------------------------------- figures


def lay_out(figure: plt.Figure) -> None:
    """``tight_layout`` inside the room the figure-level texts (a suptitle, a note) and
    legends leave: tight_layout ignores them, which put a title over the top legend."""
    artists = [*figure.texts, *figure.legends]
    if not artists:
        figure.tight_layout()
        return
    renderer = figure.canvas.get_renderer()
    height = figure.bbox.height
    top, bottom = 1.0, 0.0
    for artist in artists:
        box = artist.get_window_extent(renderer)
        if box.y0 + box.y1 > height:  # centre in the upper half: the axes stay below it
            top = min(top, box.y0 / height - 0.005)
        else:
            bottom = max(bottom, box.y1 / height + 0.005)
    figure.tight_layout(rect=(0.0, bottom, 1.0, top))


def save_figure(
    figure: plt.Figure, path_without_suffix: Path, formats: tuple[str, ...] = DEFAULT_PLOT_FORMATS
) -> list[Path]:
    """Lay out once, save in each of ``formats``, close; returns the files written.

    ``lay_out`` once rather than ``bbox_inches="tight"``, which draws every file twice.
    """
    path_without_suffix.parent.mkdir(parents=True, exist_ok=True)
    lay_out(figure)
    # tight_layout leaves a placeholder layout engine behind, for which savefig draws the
    # whole figure once more before printing it; the layout is done, so drop it
    figure.set_layout_engine(None)
    written = []
    for suffix in formats:
        path = path_without_suffix.with_suffix(f".{suffix}")
        figure.savefig(path, dpi=120)
        written.append(path)
    plt.close(figure)
    return written


def curve_label(label: str, kind: str, has_causal: bool = True) -> str:
    """The legend label of an estimator's curve: its name for the causal estimate;
    ``NAME smoothed`` for a smoothed one, said to stand in when there is no causal one."""
    if kind != "smoothed":
        return label
    return f"{label} smoothed" if has_causal else f"{label} smoothed (no causal estimate)"


def runs_text(runs: int) -> str:
    return f"{runs} run" if runs == 1 else f"{runs} runs"


# ---------------------------------------------------------------------------- run folders


class RunFiles:
    """A run folder's ``estimate.npz``, read lazily: the key list once, then only the
    arrays a figure asks for (the file was checked when the run was read,
    ``results.runs.read_run``; loading every array per figure was most of the drawing
    time)."""

    def __init__(self, folder: Path) -> None:
        self.folder = Path(folder)
        self._arrays: dict[str, np.ndarray] = {}

    @property
    def path(self) -> Path:
        return self.folder / "estimate.npz"

    @cached_property
    def keys(self) -> frozenset[str]:
        if not self.path.is_file():
            return frozenset()
        with np.load(self.path, allow_pickle=False) as data:
            return frozenset(data.files)

    def arrays(self, *keys: str) -> tuple[np.ndarray, ...]:
        """The arrays under ``keys`` (an empty array for a key the file lacks)."""
        wanted = [key for key in keys if key in self.keys and key not in self._arrays]
        if wanted:
            with np.load(self.path, allow_pickle=False) as data:
                for key in wanted:
                    self._arrays[key] = data[key]
        return tuple(self._arrays.get(key, np.zeros(0)) for key in keys)

    def has_pose(self, kind: str) -> bool:
        return f"{'smoothed_' if kind == 'smoothed' else ''}pose_t" in self.keys

    def lacks_covariance(self, block: str) -> bool:
        """Whether the scored history holds ``block`` without its covariance (an estimator
        that derives it, e.g. the sensor-based filter's pose): said in the legend."""
        prefix = "" if self.has_pose("causal") else "smoothed_"
        if block == "map":
            ids = [key for key in self.keys if key.startswith(f"{prefix}map_") and "_ids" in key]
            return bool(ids) and not any(
                key.startswith(f"{prefix}map_") and key.endswith("_covariances")
                for key in self.keys
            )
        return f"{prefix}{block}_t" in self.keys and f"{prefix}{block}_covariances" not in self.keys
