"""Issue 14's UTIAS table: every planar estimator on every robot of MRCLAM dataset 1
(``../shared/data/utias-mrclam1``), with the scans' ids and without, one Markdown row each.

Columns: SE(2)-aligned and raw ATE of the causal estimate, the smoothed ATE (smoothers),
pose NEES per run (3 dof; causal and smoothed), association precision / recall, the rejected
and inflated fractions of sightings, the final map size and NIS per dof: the run's own
``metrics.json`` values (``workbench.metrics.summary.compute_metrics``), nothing recomputed.
The last lines give each estimator's ATE over the batch smoother's smoothed ATE with ids, per
robot (the issue asks ekf-slam and sensor-based for 2x or less), and over iSAM2's causal ATE
(the best causal estimate under the same models: a filter's causal reference).

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_utias_table.py [--robot 1 ...]
    [--estimator NAME ...] [--ids yes|no|both] [--duration SECONDS] [--data KEY=VALUE ...]
The whole table (6 estimators x 5 robots x 2) took 31 min on one core beside a running
suite (806 s with ids, 1058 s without).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from workbench.commands.bag_estimators import choose_estimators
from workbench.metrics.summary import compute_metrics
from workbench.registry import load_dataset
from workbench.runner import RunRequest, execute

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "utias-mrclam1"
COLUMNS = (
    ("ate_rmse_m", "ATE SE(2) [m]"),
    ("ate_rmse_raw_m", "ATE raw [m]"),
    ("ate_rmse_smoothed_m", "ATE smoothed [m]"),
    ("nees_pose_per_dof", "NEES/dof"),
    ("nees_pose_per_dof_smoothed", "NEES/dof smoothed"),
    ("association_precision", "assoc. P"),
    ("association_recall", "assoc. R"),
    ("association_rejected_fraction", "rejected"),
    ("association_inflated_fraction", "inflated"),
    ("landmarks_in_map", "landmarks"),
    ("nis_per_dof", "NIS/dof"),
)


def cell(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.4g}"
    return str(value)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--robot", type=int, action="append", default=[])
    parser.add_argument("--estimator", action="append", default=[])
    parser.add_argument("--ids", choices=("yes", "no", "both"), default="both")
    parser.add_argument("--duration", type=float, default=None, help="seconds of each run")
    parser.add_argument(
        "--data", action="append", default=[], help="a loader option KEY=VALUE (repeatable)"
    )
    args = parser.parse_args()
    if not DATA.is_dir():
        raise SystemExit(f"{DATA}: UTIAS MRCLAM dataset 1 not found")
    robots = args.robot or [1, 2, 3, 4, 5]
    id_modes = {"yes": [True], "no": [False], "both": [True, False]}[args.ids]
    print("| estimator | robot | ids | " + " | ".join(title for _, title in COLUMNS) + " |")
    print("|---|---|---|" + "---|" * len(COLUMNS))
    ate: dict[tuple[str, int, bool], float | None] = {}
    started = time.perf_counter()
    for ids in id_modes:
        for robot in robots:
            options = dict(item.split("=", 1) for item in args.data)
            options["ids"] = str(ids).lower()
            if args.duration:
                options["duration_s"] = str(args.duration)
            dataset = f"utias:{DATA}#robot{robot}"
            sequence = load_dataset(dataset, 0, options)
            # the requested ones, or every registered estimator UTIAS allows
            for name in choose_estimators(args.estimator, sequence):
                try:
                    result = execute(RunRequest(name, dataset), sequence=sequence)
                except Exception as error:  # a benchmark reports failures, it does not stop
                    print(f"| {name} | {robot} | {'yes' if ids else 'no'} | failed: {error} |")
                    continue
                metrics = compute_metrics(result.estimate, sequence)
                key = "ate_rmse_smoothed_m" if name == "smoother-batch" else "ate_rmse_m"
                ate[(name, robot, ids)] = metrics.get(key)
                values = " | ".join(cell(metrics.get(column)) for column, _ in COLUMNS)
                print(f"| {name} | {robot} | {'yes' if ids else 'no'} | {values} |", flush=True)
    print(f"\n{time.perf_counter() - started:.0f} s")
    # two references: the batch smoother's smoothed ATE (what the issue names) and iSAM2's
    # causal ATE (the best causal estimate under the same models)
    references = (
        ("smoother-batch", "the batch smoother's smoothed ATE"),
        ("smoother-isam2", "iSAM2's causal ATE"),
    )
    for reference, title in references:
        for name in dict.fromkeys(name for name, _, _ in ate):
            if name == reference:
                continue
            ratios = []
            for robot in robots:
                own, base = ate.get((name, robot, True)), ate.get((reference, robot, True))
                ratios.append("-" if not own or not base else f"{own / base:.2f}")
            if any(ratio != "-" for ratio in ratios):
                print(f"{name}: ATE over {title} (ids), robots {robots}: {ratios}")


if __name__ == "__main__":
    main()
