"""Consistency of every estimator on the synthetic lidar bag: one bag per seed (its own
lidar and IMU noise), the simulator's truth named, the table's verdicts.

Each seed writes ``workbench simulate lidar-corridor`` as a ROS 2 bag, loads it with
``ground_truth_topic=/ground_truth`` (truth is never guessed), and runs each estimator; the
cells are the workbench's own (``workbench.results.consistency``: per-step NEES averaged over
runs, the map as one joint NEES per run, the verdict rule of ``workbench.metrics.verdicts``).
A suite cannot do this yet: a suite's recording is one file whatever ``--runs`` says.

Each seed also prints the front end against the truth (``front_end_against_truth``): KISS-ICP's
forward error accumulated over the first frames against its stated per-frame sigma, its
per-frame NEES, and the corners' error against their stated covariance. These are the inputs
every estimator shares, so they say what the cells can be expected to read. Beside the cells,
each estimator's mean raw ATE and landmark RMSE over the bags: consistency bought with
accuracy shows there.

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_lidar_bag_consistency.py [--runs 10]
    [--duration 8] [--estimator NAME ...] [--data KEY=VALUE ...]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from datasets.bags.bag_options import BagOptions
from datasets.bags.source import bag_sequence
from datasets.lidar.corner_truth import interpolate_poses, with_true_corner_ids
from datasets.measurements import LandmarkScan, Odometry
from datasets.options import nest_dotted
from datasets.rotations import matrix_from_quat_wxyz, so3_exp, so3_log
from datasets.synthetic_lidar import write_lidar_bag
from workbench.metrics.summary import compute_metrics, smoothed_key
from workbench.registry import ESTIMATORS
from workbench.results.consistency import consistency_cells, run_consistency
from workbench.runner import RunRequest, execute

ACCURACY = ("ate_rmse_raw_m", "landmark_rmse_m")
"""Accuracy printed beside the cells (means over bags; the batch smoother's are smoothed)."""

# no surveyed corners in a bag: Aghili's anchors from their first sighting (as the paper suite)
OVERRIDES = {"aghili": (("anchor_source", "first-observation"),)}


def front_end_against_truth(sequence) -> str:
    """One line: KISS-ICP's odometry and the corners against the named truth (the corners
    matched by their true ids, ``GroundTruth.scan_ids``)."""
    truth = sequence.ground_truth
    measurements = list(sequence.measurements())

    def pose_at(t: float) -> tuple[np.ndarray, np.ndarray]:
        positions, quats = interpolate_poses(truth.pose, np.array([t]))
        return matrix_from_quat_wxyz(quats[0]), positions[0]

    forward, sigma, odometry_nees = [], [], []
    for item in (m for m in measurements if isinstance(m, Odometry)):
        (r0, p0), (r1, p1) = pose_at(item.t - item.dt), pose_at(item.t)
        true_rotation, true_translation = r0.T @ r1, r0.T @ (p1 - p0)
        error = np.concatenate(
            [
                so3_log(true_rotation.T @ so3_exp(item.relative_pose[:3])),
                item.relative_pose[3:] - true_translation,
            ]
        )
        forward.append(error[3])
        sigma.append(np.sqrt(item.covariance[3, 3]))
        odometry_nees.append(error @ np.linalg.solve(item.covariance, error) / 6)
    cumulative = np.cumsum(forward)
    stated = np.sqrt(np.cumsum(np.square(sigma)))
    positions = dict(zip(truth.landmarks.ids.tolist(), truth.landmarks.positions, strict=True))
    scans = [m for m in measurements if isinstance(m, LandmarkScan)]
    errors, corner_nees = [], []
    for scan, (_, ids) in zip(scans, truth.scan_ids, strict=True):
        rotation, position = pose_at(scan.t)
        for point, covariance, true_id in zip(scan.points, scan.covariances, ids, strict=True):
            if int(true_id) in positions:
                error = point - rotation.T @ (positions[int(true_id)] - position)
                errors.append(error)
                corner_nees.append(error[:2] @ np.linalg.solve(covariance[:2, :2], error[:2]) / 2)
    errors = 100 * np.array(errors)
    late = slice(20, None)
    early, later = min(10, len(forward)), min(40, len(forward))  # a short bag has fewer
    return (
        f"KISS-ICP forward error after {early} / {later} frames "
        f"{100 * cumulative[early - 1]:+.0f} / {100 * cumulative[later - 1]:+.0f} cm (stated "
        f"sigma {100 * stated[early - 1]:.0f} / {100 * stated[later - 1]:.0f}), per-frame NEES/dof frames 1-20 "
        f"{np.mean(odometry_nees[:20]):.2f}, later {np.mean(odometry_nees[late]):.2f}; corners "
        f"(body x, y) error {errors[:, 0].mean():+.1f} +- {errors[:, 0].std():.1f}, "
        f"{errors[:, 1].mean():+.1f} +- {errors[:, 1].std():.1f} cm, z {np.abs(errors[:, 2]).max():.1f} "
        f"cm at most, horizontal NEES/dof {np.mean(corner_nees):.2f}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=10)
    parser.add_argument("--duration", type=float, default=8.0, help="bag length [s]")
    parser.add_argument("--estimator", action="append", default=[])
    parser.add_argument(
        "--data",
        action="append",
        default=[],
        help="bag option KEY=VALUE (e.g. kiss.covariance=stated)",
    )
    args = parser.parse_args()
    names = tuple(args.estimator) or tuple(entry.name for entry in ESTIMATORS)  # all run on a bag
    runs: dict[str, list] = {name: [] for name in names}
    failures: dict[str, list[str]] = {name: [] for name in names}
    accuracy = {name: {key: [] for key in ACCURACY} for name in names}
    started = time.perf_counter()
    with tempfile.TemporaryDirectory() as folder:
        for seed in range(args.runs):
            bag = write_lidar_bag(
                Path(folder) / f"seed{seed}", seed, "ros2", {"duration_s": str(args.duration)}
            )
            dataset = f"bag:{bag}"
            sequence, source = bag_sequence(
                str(bag),
                BagOptions.model_validate(
                    nest_dotted(
                        {"ground_truth_topic": "/ground_truth"}
                        | dict(item.split("=", 1) for item in args.data)
                    )
                ),
            )
            for _ in sequence.measurements():  # the front end runs once (cached)
                pass
            sequence = with_true_corner_ids(sequence, source.front_end)
            print(f"seed {seed}: {front_end_against_truth(sequence)}", flush=True)
            for name in names:
                request = RunRequest(name, dataset, seed, overrides=OVERRIDES.get(name, ()))
                try:
                    result = execute(request, sequence=sequence)
                except Exception as error:  # a benchmark reports failures, it does not stop
                    failures[name].append(f"seed {seed}: {type(error).__name__}: {error}")
                    continue
                runs[name].append(run_consistency(result.estimate, sequence))
                metrics = compute_metrics(result.estimate, sequence)
                for key in ACCURACY:
                    value = metrics.get(key)
                    value = metrics.get(smoothed_key(key)) if value is None else value
                    accuracy[name][key].append(np.nan if value is None else value)
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
        print(
            f"{'':20s} mean "
            + ", ".join(
                f"{key} {np.nanmean(values):.3f}" if np.isfinite(values).any() else f"{key} n/a"
                for key, values in (
                    (k, np.array(v, dtype=float)) for k, v in accuracy[name].items()
                )
            )
        )
        for line in failures[name][:3]:
            print(f"{'':20s} failed {line}")


if __name__ == "__main__":
    main()
