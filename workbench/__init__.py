"""The application: registry, runner, Monte Carlo, metrics, reports, plots, CLI; and the
Python API (``workbench.api``): ``from workbench import run, compare, load_runs,
load_estimate``.

The API is imported on first use, so that ``import workbench`` (and the CLI's start) stays
light."""

from __future__ import annotations

__all__ = ["run", "compare", "load_runs", "load_estimate", "Run"]


def __getattr__(name: str):
    if name in __all__:
        from workbench import api

        return getattr(api, name)
    raise AttributeError(f"module 'workbench' has no attribute {name!r}")
