"""Is ekf-slam inconsistent as Bailey et al. (2006) predict? NEES over time on sim:guerreiro-loop.

Runs ``ekf-slam`` on several seeds (ids given by default) and prints per run the ATE, the
pose NEES (3 dof) and the heading NEES (1 dof) averaged over 0-50 s, 50-100 s and 100-150 s,
the mean NIS, and the NEES averaged over runs with its two-sided 95% bound
(``chi2.ppf(0.975, runs * 3) / runs``). Bailey et al.'s signature of inconsistency is a
heading NEES that grows with time as the heading uncertainty grows; raise the noise
(``noise_scale=3``) to make the heading uncertainty larger.

Usage: ``python benchmarks/bench_ekf_slam_consistency.py [SEEDS] [dataset options...] [set.option=value ...]``,
e.g. ``python benchmarks/bench_ekf_slam_consistency.py 0,1,2,3,4 noise_scale=3``.
"""

from __future__ import annotations

import sys

import numpy as np
from scipy.stats import chi2

from datasets.options import parse_options
from filters.ekf_slam.config import EkfSlamConfig
from filters.ekf_slam.filter import EkfSlam
from workbench.metrics.consistency import nees, pose_errors
from workbench.metrics.summary import compute_metrics
from workbench.registry import load_dataset
from workbench.runner import run_estimator

WINDOWS = ((0.0, 50.0), (50.0, 100.0), (100.0, 150.0), (150.0, 1e9))


def main(argv: list[str]) -> None:
    seeds = [int(s) for s in (argv[0] if argv else "0,1,2,3,4").split(",")]
    data = dict(a.split("=", 1) for a in argv[1:] if not a.startswith("set."))
    config = parse_options(
        EkfSlamConfig, dict(a[4:].split("=", 1) for a in argv[1:] if a.startswith("set.")), "set"
    )
    print(
        f"ekf-slam on sim:guerreiro-loop, data {data}, config overrides {[a for a in argv[1:] if a.startswith('set.')]}"
    )
    print(
        f"{'seed':>4} {'ATE [m]':>8} {'NEES':>6} {'inside':>6} {'NIS':>5}  pose NEES by window   heading NEES by window"
    )
    means = []
    for seed in seeds:
        sequence = load_dataset("sim:guerreiro-loop", seed, data)
        estimate = run_estimator(EkfSlam, config, sequence)
        metrics = compute_metrics(estimate, sequence)
        pose, truth = estimate.causal.pose, sequence.ground_truth.pose
        index = np.clip(np.searchsorted(truth.t, pose.t - 1e-9), 0, len(truth.t) - 1)
        same = np.abs(truth.t[index] - pose.t) < 1e-6
        errors = pose_errors(pose.select(same), truth.select(index[same]))
        covariances = pose.covariances[same]
        full = nees(errors, covariances)
        heading = nees(errors[:, 2:], covariances[:, 2:, 2:])
        t = pose.t[same]
        by_window = [float(np.nanmean(full[(t >= a) & (t < b)])) for a, b in WINDOWS]
        heading_window = [float(np.nanmean(heading[(t >= a) & (t < b)])) for a, b in WINDOWS]
        means.append(metrics["nees_pose_per_dof"])
        print(
            f"{seed:>4} {metrics['ate_rmse_m']:>8.3f} {metrics['nees_pose_per_dof']:>6.2f} {metrics['nees_pose_inside_fraction']:>6.3f} "
            f"{metrics['nis_measurement_per_dof']:>5.2f}  {' '.join(f'{v:5.2f}' for v in by_window)}    {' '.join(f'{v:5.2f}' for v in heading_window)}"
        )
    runs = len(seeds)
    low, high = chi2.ppf([0.025, 0.975], runs * 3) / runs
    print(
        f"NEES averaged over runs and time: {np.mean(means):.2f} (3 dof; 95% bounds for {runs} runs: [{low:.2f}, {high:.2f}])"
    )


if __name__ == "__main__":
    main(sys.argv[1:])
