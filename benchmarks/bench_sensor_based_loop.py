"""Loop closing and the Earth-frame estimate of the sensor-based filter on ``sim:guerreiro-loop``.

Runs the full loop with ids withheld (JCBB), prints every loop-closure event with the
precision of its fused pairs, the body-frame landmark-map RMSE just before and just after
each closure, and the workbench metrics (ATE of the derived Earth-frame trajectory,
association precision/recall, NIS).

    /work/venv/bin/python benchmarks/bench_sensor_based_loop.py [--seed 0] [--set key=value ...]
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from datasets.options import yaml_value
from datasets.simulation.scenarios import load_scenario
from filters.sensor_based.config import SensorBasedConfig
from filters.sensor_based.filter import SensorBasedSlam
from workbench.metrics.data_association import landmark_id_mapping
from workbench.metrics.state_errors import landmark_errors
from workbench.metrics.summary import compute_metrics


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--set", nargs="*", default=[])
    parser.add_argument("--data", nargs="*", default=[])
    args = parser.parse_args()
    overrides = {k: yaml_value(v) for k, v in (item.split("=", 1) for item in args.set)}
    sequence = load_scenario(
        "guerreiro-loop", args.seed, dict(item.split("=", 1) for item in args.data)
    )
    estimator = SensorBasedSlam(SensorBasedConfig(**{"association": "jcbb", **overrides}), sequence)
    start = time.perf_counter()
    for measurement in sequence.measurements():
        estimator.process(measurement)
    estimate = estimator.estimate()
    print(f"seed {args.seed} set={overrides}: {time.perf_counter() - start:.1f} s wall")
    truth = sequence.ground_truth
    mapping = landmark_id_mapping(estimate.diagnostics, truth)
    snapshots = estimate.causal.landmarks
    snapshot_t = np.array([s.t for s in snapshots])

    def rmse(snapshot) -> float:
        errors, valid = landmark_errors(snapshot, mapping, truth)
        return float(np.sqrt(np.mean(np.sum(errors**2, axis=1)))) if valid.any() else float("nan")

    for event in estimate.diagnostics.events:
        if event.kind != "loop_closure":
            continue
        pairs = event.details["pairs"]
        correct = sum(
            1 for kept, removed in pairs if mapping.get(kept, -1) == mapping.get(removed, -2) != -1
        )
        index = int(np.searchsorted(snapshot_t, event.t))
        before = snapshots[index - 1] if index > 0 else None
        after = snapshots[min(index, len(snapshots) - 1)]
        print(
            f"loop closure t={event.t:.1f}s pairs={len(pairs)} correct={correct} "
            f"map RMSE before {rmse(before) if before is not None else float('nan'):.3f} m (t={before.t if before is not None else float('nan'):.1f}), "
            f"after {rmse(after):.3f} m (t={after.t:.1f})"
        )
    metrics = compute_metrics(estimate, sequence)
    keys = (
        "ate_rmse_m",
        "ate_rmse_raw_m",
        "association_precision",
        "association_recall",
        "loop_closures",
        "loop_closure_precision",
        "nis_measurement_per_dof",
        "nis_below_95_fraction",
        "landmark_rmse_m",
        "landmarks_mapped",
        "nees_velocity_per_dof",
        "nees_gyro_bias_per_dof",
    )
    for key in keys:
        print(f"  {key}: {metrics.get(key)}")
    print("  notes:", "; ".join(estimate.notes))


if __name__ == "__main__":
    main()
