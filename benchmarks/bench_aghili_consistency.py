"""Monte Carlo consistency of the Aghili filter on ``sim:aghili-rover``: averaged NEES of the
pose (6 dof), gyro bias and accelerometer bias (3 dof each) with two-sided 95% bounds and
the fraction of steps inside, over ``--runs`` seeds (fresh noise, same world).

Run: ``OPENBLAS_NUM_THREADS=1 python benchmarks/bench_aghili_consistency.py --runs 20
[--duration 144] [--noise-scale 1] [--anchors 3] [--set key=value ...]``.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from datasets.options import yaml_value
from datasets.simulation.scenarios import load_scenario
from filters.aghili.filter import AghiliConfig, AghiliFilter
from workbench.metrics.consistency import averaged_nees, nees, pose_errors


def block_nees(estimate, sequence, name: str) -> np.ndarray:
    """NEES (N,) of a 3-dof state block against the simulator's truth at the estimate's times."""
    block = estimate.causal.block(name)
    truth = sequence.ground_truth.history.block(name)
    index = np.clip(np.searchsorted(truth.t, block.t - 1e-9), 0, len(truth.t) - 1)
    errors = truth.values[index] - block.values
    return np.einsum(
        "ni,ni->n", errors, np.linalg.solve(block.covariances, errors[:, :, None])[:, :, 0]
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument(
        "--duration", type=float, default=None, help="seconds (default: the full 144 s lap)"
    )
    parser.add_argument("--noise-scale", type=float, default=1.0)
    parser.add_argument("--anchors", type=int, default=3)
    parser.add_argument("--set", nargs="*", default=[], help="filter config key=value")
    args = parser.parse_args()
    overrides = {key: yaml_value(value) for key, value in (item.split("=", 1) for item in args.set)}
    data = {"noise_scale": str(args.noise_scale)}
    if args.duration is not None:
        data["duration_s"] = str(args.duration)
    pose_runs: list[np.ndarray] = []
    blocks: dict[str, list[np.ndarray]] = {"gyro_bias": [], "accel_bias": []}
    start = time.perf_counter()
    for seed in range(args.runs):
        sequence = load_scenario("aghili-rover", seed, data)
        f = AghiliFilter(AghiliConfig(anchors=args.anchors, **overrides), sequence)
        for measurement in sequence.measurements():
            f.process(measurement)
        estimate = f.estimate()
        pose, truth = estimate.causal.pose, sequence.ground_truth.pose
        index = np.clip(np.searchsorted(truth.t, pose.t), 0, len(truth.t) - 1)
        pose_runs.append(nees(pose_errors(pose, truth.select(index)), pose.covariances))
        for name in blocks:
            blocks[name].append(block_nees(estimate, sequence, name))
    print(
        f"runs={args.runs} duration={args.duration or 'full'} noise_scale={args.noise_scale} anchors={args.anchors} set={overrides}"
    )
    for name, runs, dof in [
        ("pose", pose_runs, 6),
        ("gyro_bias", blocks["gyro_bias"], 3),
        ("accel_bias", blocks["accel_bias"], 3),
    ]:
        steps = min(len(r) for r in runs)
        result = averaged_nees(np.stack([r[:steps] for r in runs]), dof=dof)
        print(
            f"{name:>10}: ANEES mean {np.mean(result.mean):.2f} (dof {dof}), band [{result.lower:.2f}, {result.upper:.2f}], "
            f"inside {result.inside_fraction:.1%} of {steps} steps"
        )
    print(f"wall time {time.perf_counter() - start:.0f} s")


if __name__ == "__main__":
    main()
