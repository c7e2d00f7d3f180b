"""One style per estimator in every figure of every dataset: its colour and marker come from
its name, never from its position in a panel; the estimate kind is the line style (causal
solid, smoothed dashed); the reference is black.

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
KIND_LINESTYLES = {"causal": "-", "smoothed": "--", "innovation": "-"}
REFERENCE_COLOUR = "black"


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


def estimator_style(label: str, kind: str = "causal") -> LineStyle:
    """The style of estimator ``label``'s ``kind`` curve (causal / smoothed)."""
    if label in ESTIMATOR_COLOURS:
        colour, marker = ESTIMATOR_COLOURS[label], ESTIMATOR_MARKERS[label]
    else:
        index = zlib.crc32(label.encode()) % len(EXTRA_COLOURS)
        colour, marker = EXTRA_COLOURS[index], EXTRA_MARKERS[index]
    return LineStyle(colour, KIND_LINESTYLES.get(kind, "-"), marker)
