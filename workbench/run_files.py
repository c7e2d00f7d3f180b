"""The names of a run folder's files: one owner for every module that writes or reads them
(``workbench.run_folder`` writes them, ``workbench.results`` reads them, the sweep resumes by
them). Names only: importing this never loads numpy, GTSAM or matplotlib."""

from __future__ import annotations

CONFIG_FILE = "config.yaml"
"""The resolved run: estimator, dataset, seed, data options, the estimator's options."""
METRICS_FILE = "metrics.json"
"""Flat metrics with units and provenance; written last: its presence marks a finished run."""
ESTIMATE_FILE = "estimate.npz"
"""Every numeric array of the ``Estimate`` (``workbench.results.estimate_file``)."""
EVENTS_FILE = "events.json"
"""The estimator's notes and discrete events."""
CONSISTENCY_FILE = "consistency.npz"
"""Per-step NEES/NIS series (``workbench.results.consistency``)."""
FRONT_END_FILE = "frontend.tum"
"""The lidar front end's own trajectory (``Sequence.front_end``), on a lidar source."""
ERROR_FILE = "error.json"
"""A sweep's failed run: the error."""
REQUEST_FILE = "bench_request.json"
"""A sweep's request (compared on resume)."""
