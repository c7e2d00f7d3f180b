"""Victoria Park with the file's landmark ids: how far is each estimator's trajectory from
the batch smoother's? (Issue 14 asks ekf-slam for 10 m RMS or less on the full run.)

Victoria Park has no ground truth, so the batch smoother's smoothed trajectory is the
reference. Each estimator's trajectory (its causal one; the sensor-based filter's derived
Earth-frame pose) is scored against it by the workbench's own ATE (``ate_report``: poses
paired by nearest time, SE(2) alignment). Printed with each run: the fractions of sightings rejected and
inflated by the id gate (``workbench.metrics.summary``), so that a close trajectory cannot
hide a silent gate.

    OPENBLAS_NUM_THREADS=1 python benchmarks/victoria_trajectory_agreement.py
        [--estimator NAME ...] [--set NAME:KEY=VALUE ...] [--max-steps N]

The whole file: about 3 minutes for the default five estimators on one core.
"""

from __future__ import annotations

import argparse
import time

from workbench.metrics.ate import ate_report
from workbench.metrics.summary import compute_metrics
from workbench.registry import estimator_entry, load_dataset
from workbench.runner import resolve_config, run_estimator

DEFAULT_ESTIMATORS = (
    "dead-reckoning",
    "ekf-slam",
    "sensor-based",
    "smoother-isam2",
    "smoother-fixed-lag",
)


def run(name: str, sequence, overrides: dict[str, str]):
    """(estimate, seconds) of ``name`` on ``sequence`` with its ``--set`` overrides."""
    estimator_class = estimator_entry(name).load()
    config = resolve_config(estimator_class, overrides=overrides or None)
    start = time.perf_counter()
    estimate = run_estimator(estimator_class, config, sequence)
    return estimate, time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--estimator", action="append", default=[])
    parser.add_argument(
        "--set", action="append", default=[], help="NAME:KEY=VALUE, an estimator option"
    )
    parser.add_argument(
        "--max-steps", type=int, default=None, help="shorten the file (default: all of it)"
    )
    args = parser.parse_args()
    overrides: dict[str, dict[str, str]] = {}
    for item in args.set:
        name, _, assignment = item.partition(":")
        key, _, value = assignment.partition("=")
        overrides.setdefault(name, {})[key] = value
    options = {} if args.max_steps is None else {"max_steps": str(args.max_steps)}
    sequence = load_dataset("victoria-park", 0, options)
    reference, seconds = run("smoother-batch", sequence, overrides.get("smoother-batch", {}))
    reference_pose = reference.smoothed.pose
    print(f"reference: smoother-batch, {len(reference_pose.t)} keyframes, {seconds:.0f} s")
    print(f"{'estimator':<20} {'RMS vs batch [m]':>16} {'rejected':>9} {'inflated':>9} {'s':>6}")
    for name in args.estimator or DEFAULT_ESTIMATORS:
        estimate, seconds = run(name, sequence, overrides.get(name, {}))
        pose = estimate.causal.pose
        rms = ate_report(reference_pose, pose, align="se2")["rmse_m"]
        metrics = compute_metrics(estimate, sequence)
        rejected = metrics.get("association_rejected_fraction")
        inflated = metrics.get("association_inflated_fraction")
        print(
            f"{name:<20} {rms:16.2f} "
            f"{'-' if rejected is None else f'{rejected:.4f}':>9} "
            f"{'-' if inflated is None else f'{inflated:.4f}':>9} {seconds:6.0f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
