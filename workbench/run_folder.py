"""The run folder of DESIGN.md: one folder per run, every file written atomically.

Layout (all directly in the folder)::

    config.yaml            resolved estimator config, dataset, seed, data options
    estimate.tum           causal trajectory (TUM, loadable by evo), when there is a pose
    estimate_smoothed.tum  smoothed trajectory (smoothers)
    reference.tum          ground-truth trajectory, when known
    frontend.tum           the lidar front end's own trajectory, on a lidar source
    *.kitti                the same trajectories as KITTI poses (3x4 rows; times in the .tum)
    ape.zip, rpe.zip       evo result files (``evo_res`` reads them as they are; and
                           ``*_smoothed.zip``), see ``workbench.evo_results``
    estimate.npz           covariances, state blocks, final map, diagnostics, timing
    consistency.npz        per-step NEES of every block (causal and smoothed), map NEES, NIS
    events.json            discrete events (loop closures, skips) and the estimator's notes
    metrics.json           flat metrics with units, plus provenance (git revision, seed, versions)
    plots/*.png            figures (see ``workbench.plots``; PDF/SVG with --plot-format)

``metrics.json`` is written last: its presence marks a finished run (Monte Carlo resume
relies on that).
"""

from __future__ import annotations

import json
import subprocess
from importlib import metadata
from pathlib import Path
from typing import Any

import numpy as np
import yaml

from datasets.trajectory_io import save_npz_atomic, write_atomic, write_kitti, write_tum
from workbench.evo_results import write_evo_results
from workbench.results.consistency import save_run_consistency
from workbench.results.estimate_file import estimate_arrays
from workbench.run_files import (
    CONFIG_FILE,
    CONSISTENCY_FILE,
    ERROR_FILE,
    ESTIMATE_FILE,
    EVENTS_FILE,
    FRONT_END_FILE,
    METRICS_FILE,
    REQUEST_FILE,
)
from workbench.runner import RunResult

_TRACKED_PACKAGES = ("gtsam", "numpy", "scipy", "kiss-icp", "rosbags", "pydantic", "slam-workbench")


def git_revision() -> str | None:
    """The git revision of the workbench source (``+dirty`` when modified), or None."""
    source = Path(__file__).resolve().parent
    try:
        revision = subprocess.run(
            ["git", "rev-parse", "HEAD"],
            cwd=source,
            capture_output=True,
            text=True,
            timeout=5,
            check=True,
        ).stdout.strip()
        dirty = subprocess.run(
            ["git", "status", "--porcelain", "--untracked-files=no"],
            cwd=source,
            capture_output=True,
            text=True,
            timeout=5,
        ).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return None
    return revision + ("+dirty" if dirty else "")


def package_versions() -> dict[str, str | None]:
    versions: dict[str, str | None] = {}
    for name in _TRACKED_PACKAGES:
        try:
            versions[name] = metadata.version(name)
        except metadata.PackageNotFoundError:
            versions[name] = None
    return versions


def _json_default(value: Any) -> Any:
    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def dump_json(data: Any) -> str:
    """Deterministic JSON text (sorted keys, numpy scalars converted)."""
    return json.dumps(data, indent=2, sort_keys=True, default=_json_default) + "\n"


def run_provenance(result: RunResult) -> dict[str, Any]:
    request = result.request
    truth = result.sequence.ground_truth
    excluded = () if truth is None else truth.excluded
    dataset_label, estimator_label = request.labels
    return {
        "estimator": request.estimator,
        "dataset": result.sequence.name,
        "dataset_label": dataset_label if request.dataset_label else result.sequence.name,
        "estimator_label": estimator_label,
        "seed": request.seed,
        "reference_source": result.sequence.reference_source,
        # truth the loader excluded from the scoring (e.g. Vicon glitches) [s]
        "excluded_truth_s": result.sequence.excluded_truth_s,
        # the truth's untrusted intervals, scored nowhere (datasets.truth_quality)
        "excluded_truth": [interval.line() for interval in excluded],
        # what the loader fitted its models on (UTIAS: other robots' Vicon, or the scored one's)
        "calibration": result.sequence.calibration,
        "git_revision": git_revision(),
        "package_versions": package_versions(),
    }


def run_warnings(result: RunResult) -> list[str]:
    """The degradations of this run (``workbench.degradations``): data the loader dropped
    or repaired, sightings the estimator did not use as stated."""
    from workbench.degradations import association_warnings, data_warnings

    return data_warnings(result.sequence) + association_warnings(
        result.estimate, result.sequence, result.request.estimator
    )


def frames_warning(metrics: dict[str, Any], estimator: str, dataset: str) -> list[str]:
    """The frames the estimate has no pose at (``metrics.summary.frame_metrics``), if any:
    a figure or a metric must not pass over them in silence."""
    missing = metrics.get("frames_without_pose")
    if not missing:
        return []
    times = metrics["frames_without_pose_t"]
    shown = ", ".join(f"{t:.2f}" for t in times[:5]) + (", ..." if missing > 5 else "")
    return [
        f"{estimator} on {dataset}: {missing} of {metrics['frames']} frames (landmark scans or "
        f"lidar frames) have no pose (t = {shown} s): it estimated none there"
    ]


def divergence_warning(metrics: dict[str, Any], estimator: str, dataset: str) -> list[str]:
    """The run's divergence as a warning line (``workbench.metrics.divergence``), if any."""
    if metrics.get("diverged_at_s") is None:
        return []
    return [
        f"{estimator} on {dataset} diverged at t={metrics['diverged_at_s']:.1f} s: "
        f"{metrics['divergence']}"
    ]


def write_run_folder(
    result: RunResult,
    out_dir: Path,
    plot_formats: tuple[str, ...] = ("png",),
    extra_files: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Write the run folder for ``result`` (figures in each of ``plot_formats``, none when
    empty; ``extra_files``: name -> JSON content, e.g. a sweep's request) and return its
    metrics dictionary. The folder is replaced as a whole (``workbench.folder_swap``):
    killed at any moment, ``out_dir`` holds the complete earlier run or the complete new
    one."""
    from workbench.folder_swap import replaced_as_a_whole
    from workbench.metrics.frontend_agreement import departure_warning
    from workbench.metrics.summary import compute_metrics

    out_dir = Path(out_dir)
    with replaced_as_a_whole(out_dir) as folder:
        request = result.request
        resolved = {
            "estimator": request.estimator,
            "dataset": result.sequence.name,
            "seed": request.seed,
            "data_options": dict(request.data_options),
            # the source's description (datasets.sequence.Sequence.description)
            "dataset_metadata": result.sequence.description(),
            "config": result.config.model_dump(mode="json"),
        }
        write_atomic(folder / CONFIG_FILE, yaml.safe_dump(resolved, sort_keys=True))
        for name, content in (extra_files or {}).items():
            write_atomic(folder / name, dump_json(content))
        estimate = result.estimate
        truth = result.sequence.ground_truth
        reference = None if truth is None else truth.pose
        # the pose pairs are computed once, for metrics.json and the evo files alike
        scored: dict = {}
        metrics = compute_metrics(estimate, result.sequence, scored)
        histories = (("", "causal", estimate.causal), ("_smoothed", "smoothed", estimate.smoothed))
        for suffix, name, history in histories:
            if history is None or history.pose is None or len(history.pose) == 0:
                continue
            write_tum(folder / f"estimate{suffix}.tum", history.pose)
            write_kitti(folder / f"estimate{suffix}.kitti", history.pose)
            if name in scored:
                label = f"{request.estimator} on {result.sequence.name} seed {request.seed}"
                write_evo_results(folder, scored[name], label + suffix.replace("_", " "), suffix)
        if reference is not None and len(reference):
            write_tum(folder / "reference.tum", reference)
            write_kitti(folder / "reference.kitti", reference)
        front_end = result.sequence.front_end
        front_trajectory = None if front_end is None else front_end.trajectory()
        if front_trajectory is not None:  # the lidar front end's own, for the figures
            write_tum(folder / FRONT_END_FILE, front_trajectory)
        save_npz_atomic(folder / ESTIMATE_FILE, estimate_arrays(estimate))
        events = {
            "notes": list(estimate.notes),
            "events": [
                {"t": event.t, "kind": event.kind, **event.details}
                for event in estimate.diagnostics.events
            ],
        }
        write_atomic(folder / EVENTS_FILE, dump_json(events))
        save_run_consistency(estimate, result.sequence, folder / CONSISTENCY_FILE)
        metrics["warnings"] = (
            run_warnings(result)
            + divergence_warning(metrics, request.estimator, result.sequence.name)
            + frames_warning(metrics, request.estimator, result.sequence.name)
            + departure_warning(metrics, request.estimator, result.sequence.name)
        )
        # what a loader or front end decided from the data, with its evidence (printed as
        # notes): kept beside the run so a reader knows how the data were read
        metrics["decisions"] = list(result.sequence.decisions or ())
        metrics.update(run_provenance(result))
        if plot_formats:
            from workbench.plots import write_run_plots

            write_run_plots(
                estimate,
                result.sequence,
                folder / "plots",
                title=f"{request.estimator} on {result.sequence.name}",
                formats=plot_formats,
            )
        write_atomic(folder / METRICS_FILE, dump_json(metrics))
    return metrics


def write_failed_run(
    folder: Path, request: dict[str, Any], message: str, details: str = ""
) -> None:
    """A failed run's folder: the request it failed on (``bench_request.json``) and the
    error (``error.json``), which ``workbench.results`` reads as a failed row."""
    from workbench.folder_swap import replaced_as_a_whole

    with replaced_as_a_whole(Path(folder)) as staging:
        write_atomic(staging / REQUEST_FILE, dump_json(request))
        write_atomic(staging / ERROR_FILE, dump_json({"error": message, "traceback": details}))
