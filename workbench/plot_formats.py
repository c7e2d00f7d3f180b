"""The file formats figures are written in, and the ``--plot-format`` option.

Kept apart from ``workbench.plots`` so that commands parse the option without importing
matplotlib.
"""

from __future__ import annotations

from datasets.errors import InputError

PLOT_FORMATS = ("png", "pdf", "svg")
"""File formats a figure can be written in (matplotlib's savefig by suffix)."""
DEFAULT_PLOT_FORMATS: tuple[str, ...] = ("png",)
"""One raster format by default: every extra format renders the figure once more."""


def parse_plot_formats(text: str) -> tuple[str, ...]:
    """``"pdf,png"`` -> ``("pdf", "png")``; ``InputError`` naming the option otherwise."""
    formats = tuple(dict.fromkeys(part.strip().lower() for part in text.split(",") if part.strip()))
    unknown = [name for name in formats if name not in PLOT_FORMATS]
    if not formats or unknown:
        raise InputError(
            f"--plot-format {text!r}: expected a comma-separated list of {', '.join(PLOT_FORMATS)}"
        )
    return formats
