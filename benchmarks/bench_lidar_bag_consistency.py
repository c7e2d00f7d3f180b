"""Consistency of every estimator on the synthetic lidar bag: one bag per seed (its own
lidar and IMU noise), the simulator's truth named, the table's verdicts.

Each seed writes ``workbench simulate lidar-corridor`` as a ROS 2 bag, loads it with
``ground_truth_topic=/ground_truth`` (truth is never guessed), and runs each estimator; the
cells are the workbench's own (``workbench.results.consistency``: per-step NEES averaged over
runs, the map as one joint NEES per run, the verdict rule of ``workbench.metrics.verdicts``).
A suite cannot do this yet: a suite's recording is one file whatever ``--runs`` says.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_lidar_bag_consistency.py [--runs 10]
    [--duration 8] [--estimator NAME ...]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

from datasets.bags.source import BagOptions, bag_sequence
from datasets.lidar.corner_truth import with_true_corner_ids
from datasets.synthetic_lidar import write_lidar_bag
from workbench.results.consistency import consistency_cells, run_consistency
from workbench.runner import RunRequest, execute

ESTIMATORS = (
    "dead-reckoning",
    "aghili",
    "sensor-based",
    "ekf-slam",
    "smoother-isam2",
    "smoother-fixed-lag",
    "smoother-batch",
)
# no surveyed corners in a bag: Aghili's anchors from their first sighting (as the paper suite)
OVERRIDES = {"aghili": (("anchor_source", "first-observation"),)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--duration", type=float, default=8.0, help="bag length [s]")
    parser.add_argument("--estimator", action="append", default=[])
    args = parser.parse_args()
    names = tuple(args.estimator) or ESTIMATORS
    runs: dict[str, list] = {name: [] for name in names}
    failures: dict[str, list[str]] = {name: [] for name in names}
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        for seed in range(args.runs):
            bag = write_lidar_bag(
                Path(folder) / f"seed{seed}", seed, "ros2", {"duration_s": str(args.duration)}
            )
            dataset = f"bag:{bag}"
            sequence, source = bag_sequence(
                str(bag), BagOptions(ground_truth_topic="/ground_truth")
            )
            for _ in sequence.measurements():  # the front end runs once (cached)
                pass
            sequence = with_true_corner_ids(sequence, source.front_end)
            for name in names:
                request = RunRequest(name, dataset, seed, overrides=OVERRIDES.get(name, ()))
                try:
                    result = execute(request, sequence=sequence)
                except Exception as error:  # a benchmark reports failures, it does not stop
                    failures[name].append(f"seed {seed}: {type(error).__name__}: {error}")
                    continue
                runs[name].append(run_consistency(result.estimate, sequence))
            print(f"seed {seed} done ({time.perf_counter() - started:.0f} s)", flush=True)
    print(f"\n{args.runs} bags of {args.duration:g} s; value [band] verdict per block")
    for name in names:
        cells = consistency_cells(runs[name])
        text = "; ".join(
            f"{block} ({cell.scored}) {cell.statistic.value:.2f} "
            f"[{cell.statistic.lower:.2f}, {cell.statistic.upper:.2f}] {cell.statistic.verdict}"
            for block, cell in cells.items()
        )
        print(f"{name:20s} runs {len(runs[name])}: {text or 'no cells'}")
        for line in failures[name][:3]:
            print(f"{'':20s} failed {line}")


if __name__ == "__main__":
    main()
