"""Monte Carlo consistency of the sensor-based filter on ``sim:guerreiro-loop``.

Runs the filter on ``--runs`` seeds (fresh sensor noise, same world) and prints the
averaged NEES of the vehicle state ``[v (body), b]`` (3 dof, joint covariance) with its
two-sided 95% bounds, the fraction of steps inside, the per-block averaged NEES, mean NIS
and association precision/recall (when the filter runs JCBB).

    /work/venv/bin/python benchmarks/bench_sensor_based_mc.py --runs 50 --duration 60 \
        [--association ids|jcbb] [--set velocity_walk_m_s_sqrt_s=0.03 ...] [--data noise_scale=1]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from datasets.options import yaml_value
from datasets.simulation.scenarios import load_scenario
from filters.sensor_based.config import SensorBasedConfig
from filters.sensor_based.filter import SensorBasedSlam
from workbench.metrics.consistency import averaged_nees
from workbench.metrics.data_association import score_associations


def vehicle_nees(estimate, sequence, rows: slice = slice(None)) -> tuple[np.ndarray, np.ndarray]:
    """(times, NEES of [v, b][rows]) against the simulator's body velocity and bias."""
    extras = estimate.diagnostics.extras
    t = extras["vehicle_t"]
    states = extras["vehicle_state"]
    covs = extras["vehicle_covariance"].reshape(len(t), states.shape[1], states.shape[1])
    truth = sequence.ground_truth
    index = np.clip(
        np.searchsorted(truth.body_velocity.t, t - 1e-9), 0, len(truth.body_velocity.t) - 1
    )
    bias = truth.history.block("gyro_bias")
    true_states = np.hstack([truth.body_velocity.values[index], bias.values[index]])
    errors = (true_states - states)[:, rows]
    covs = covs[:, rows, rows]
    return t, np.einsum("ni,ni->n", errors, np.linalg.solve(covs, errors[:, :, None])[:, :, 0])


def run_once(seed: int, duration_s: float, association: str, overrides: dict, data: dict):
    sequence = load_scenario(
        "guerreiro-loop",
        seed,
        {"duration_s": str(duration_s), "ids": str(association == "ids").lower(), **data},
    )
    config = SensorBasedConfig(association=association, **overrides)
    estimator = SensorBasedSlam(config, sequence)
    for measurement in sequence.measurements():
        estimator.process(measurement)
    return sequence, estimator.estimate()


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=50)
    parser.add_argument("--duration", type=float, default=60.0)
    parser.add_argument("--association", choices=["ids", "jcbb"], default="ids")
    parser.add_argument("--set", nargs="*", default=[], help="filter config key=value")
    parser.add_argument("--data", nargs="*", default=[], help="scenario option key=value")
    args = parser.parse_args()
    overrides = {k: yaml_value(v) for k, v in (item.split("=", 1) for item in args.set)}
    data = dict(item.split("=", 1) for item in args.data)
    runs, velocity_runs, bias_runs, nis, precision, recall = [], [], [], [], [], []
    start = time.perf_counter()
    for seed in range(args.runs):
        sequence, estimate = run_once(seed, args.duration, args.association, overrides, data)
        t, values = vehicle_nees(estimate, sequence)
        runs.append(values)
        velocity_runs.append(vehicle_nees(estimate, sequence, slice(0, 2))[1])
        bias_runs.append(vehicle_nees(estimate, sequence, slice(2, 3))[1])
        nis.append(np.mean(estimate.diagnostics.nis / estimate.diagnostics.nis_dof))
        score = score_associations(estimate.diagnostics, sequence.ground_truth.scan_ids)
        precision.append(score.precision)
        recall.append(score.recall)
    length = min(len(r) for r in runs)
    stacked = np.stack([r[:length] for r in runs])
    result = averaged_nees(stacked, dof=3)
    print(
        f"runs={args.runs} duration={args.duration}s association={args.association} set={overrides} data={data}"
    )
    print(f"wall time {time.perf_counter() - start:.1f} s")
    print(
        f"vehicle NEES (3 dof) averaged: mean over steps {np.mean(result.mean):.2f}, bounds [{result.lower:.2f}, {result.upper:.2f}], inside {100 * result.inside_fraction:.1f}% of {length} steps"
    )
    half = length // 2
    print(
        f"  first half mean {np.mean(result.mean[:half]):.2f}, second half mean {np.mean(result.mean[half:]):.2f}"
    )
    velocity = averaged_nees(np.stack([r[:length] for r in velocity_runs]), dof=2)
    bias = averaged_nees(np.stack([r[:length] for r in bias_runs]), dof=1)
    print(
        f"  velocity (2 dof): mean {np.mean(velocity.mean):.2f} inside {100 * velocity.inside_fraction:.1f}%; bias (1 dof): mean {np.mean(bias.mean):.2f} inside {100 * bias.inside_fraction:.1f}%"
    )
    print(f"mean NIS/dof over runs {np.mean(nis):.3f}")
    if args.association == "jcbb":
        print(
            f"association precision {np.mean(precision):.4f} (min {np.min(precision):.4f}), recall {np.mean(recall):.4f} (min {np.min(recall):.4f})"
        )


if __name__ == "__main__":
    main()
