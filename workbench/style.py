"""One style per estimator in every figure of every dataset: its colour and marker come from
its name, never from its position in a panel; the estimate kind is the line style (causal
solid, smoothed dashed); the reference is black; a front end's own trajectory (a bag's
KISS-ICP) is dash-dotted olive; chi-square bands are grey, one line style per distinct dof.

A label that is not a registered name (a suite's variant, ``ekf-slam (tuned)``) gets a
colour of its own from a second palette, chosen by a stable hash of the label, so it also
keeps it everywhere.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

ESTIMATOR_COLOURS = {
    "dead-reckoning": "#7f7f7f",
    "aghili": "#1f77b4",
    "sensor-based": "#ff7f0e",
    "ekf-slam": "#2ca02c",
    "ekf-slam-mht": "#17becf",
    "smoother-isam2": "#d62728",
    "smoother-fixed-lag": "#9467bd",
    "smoother-batch": "#8c564b",
}
ESTIMATOR_MARKERS = {
    "dead-reckoning": "",
    "aghili": "o",
    "sensor-based": "s",
    "ekf-slam": "^",
    "ekf-slam-mht": "<",
    "smoother-isam2": "v",
    "smoother-fixed-lag": "D",
    "smoother-batch": "x",
}
EXTRA_COLOURS = ("#e377c2", "#bcbd22", "#393b79", "#637939", "#8c6d31", "#843c39")
EXTRA_MARKERS = ("P", "*", "h", ">", "p", "d")
KIND_LINESTYLES = {"causal": "-", "smoothed": "--", "innovation": "-", "front end": "-."}
REFERENCE_COLOUR = "black"
REFERENCE_STYLE = {"color": REFERENCE_COLOUR, "linestyle": "-", "linewidth": 1.4}
"""The reference drawn under the estimates (``plot`` keywords)."""
FRONT_END_COLOUR = "#808000"
BAND_COLOUR = "0.35"
BAND_LINESTYLES = ("--", ":", "-.", (0, (5, 2, 1, 2, 1, 2)))
"""Chi-square bands of distinct dof on one axes, told apart by line style (in grey: a band
belongs to no estimator)."""


@dataclass(frozen=True)
class LineStyle:
    """Matplotlib keywords of one curve."""

    color: str
    linestyle: str
    marker: str

    def keywords(self, points: int = 0) -> dict:
        """``plot`` keywords; markers sparse enough to tell overlapping curves apart."""
        found = {"color": self.color, "linestyle": self.linestyle}
        if self.marker and points:
            found.update(marker=self.marker, markevery=max(1, points // 12), markersize=4)
        return found


def curve_style(estimator: str, kind: str = "causal") -> LineStyle:
    """``estimator_style``, and the front end's for ``kind == "front end"`` (whose estimator
    label is empty)."""
    if kind == "front end":
        return LineStyle(FRONT_END_COLOUR, KIND_LINESTYLES[kind], "")
    return estimator_style(estimator, kind)


def band_linestyle(index: int):
    """The line style of the ``index``-th distinct chi-square band of an axes."""
    return BAND_LINESTYLES[index % len(BAND_LINESTYLES)]


def estimator_style(label: str, kind: str = "causal") -> LineStyle:
    """The style of estimator ``label``'s ``kind`` curve (causal / smoothed)."""
    if label in ESTIMATOR_COLOURS:
        colour, marker = ESTIMATOR_COLOURS[label], ESTIMATOR_MARKERS[label]
    else:
        index = zlib.crc32(label.encode()) % len(EXTRA_COLOURS)
        colour, marker = EXTRA_COLOURS[index], EXTRA_MARKERS[index]
    return LineStyle(colour, KIND_LINESTYLES.get(kind, "-"), marker)
