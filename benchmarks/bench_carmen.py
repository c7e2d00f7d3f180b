"""Issue 38's CARMEN table: every applicable estimator on the three shared 2-D laser logs
(``../shared/data/carmen-logs``: Intel, Freiburg 079, MIT CSAIL), one Markdown row each.

Columns, per log and estimator (the run's own ``metrics.json`` values,
``workbench.metrics.summary.compute_metrics``, except the agreement):
- agreement with the batch smoother: max and RMS distance [m] of the estimator's final
  trajectory (smoothed for a smoother, else causal) from ``smoother-batch``'s smoothed one,
  at the scans' stamps, after the SE(2) alignment that minimises it (Umeyama);
- corner NIS per dof (``nis_measurement_per_dof``: the corner sightings the estimator used,
  2 dof each) and the stacked NIS per dof of its updates (``nis_per_dof``);
- landmarks in the final map; association without ids: the contested, rejected and inflated
  fractions of the sightings, loop closures;
- ms per scan: the estimator's processing time over the scans (the front end's is a column
  of the log's line, it is shared by every estimator);
- with ``--relations LOG=FILE``: the relations error of the field (Kümmerle et al. 2009;
  ``--data relations=FILE``, ``workbench.metrics.relations``): mean translational [m] and
  rotational [deg] error.
A run that diverged (``workbench.metrics.divergence``) gets a line with the time and the
evidence. Per log, one line with the front end's figures: corners per scan, confirmed fraction, the
re-observation NIS per dof (consecutive scans, odometry increment's covariance included) and
its gated expectation, front end ms per scan.

Other modes:
- ``--calibrate``: the odometry noise model fitted against the batch smoother on the three
  logs pooled (``datasets.carmen.noise``), iterated, then checked per log (NEES per dof of
  the pooled model on each log's 1.25 / 5 / 20 s windows) and left-one-out (fitted on two,
  checked on the third); then the corner covariance scale fitted by maximum likelihood on
  the re-observation pairs of the three logs pooled (``datasets.laser2d.reobservation``), with
  each log's re-observation NIS per dof at the fitted scale.
- ``--scan-matching``: KISS-ICP on the planar points of every log against the wheel
  odometry and against the batch smoother (``datasets.laser2d.scan_matching``).

Usage: OPENBLAS_NUM_THREADS=1 python benchmarks/bench_carmen.py [--log intel ...]
    [--estimator NAME ...] [--data KEY=VALUE ...] [--relations LOG=FILE ...]
    [--calibrate [--iterations N]] [--scan-matching]
"""

from __future__ import annotations

import argparse
import tempfile
import time
from pathlib import Path

import numpy as np

from datasets.trajectory import Trajectory
from workbench.metrics.summary import compute_metrics
from workbench.registry import load_dataset
from workbench.runner import RunRequest, execute

DATA = Path(__file__).resolve().parents[2] / "shared" / "data" / "carmen-logs"
LOGS = ("intel", "fr079", "mit-csail")
ESTIMATORS = (
    "smoother-batch",  # first: the reference of the agreement column
    "dead-reckoning",
    "ekf-slam",
    "ekf-slam-mht",
    "sensor-based",
    "smoother-isam2",
    "smoother-fixed-lag",
)
COLUMNS = (
    "agree max [m]",
    "agree RMS [m]",
    "corner NIS/dof",
    "NIS/dof",
    "landmarks",
    "contested",
    "rejected",
    "inflated",
    "loops",
    "ms/scan",
    "relations t [m]",
    "relations r [deg]",
)


def cell(value) -> str:
    if value is None:
        return "-"
    if isinstance(value, float):
        return f"{value:.3g}"
    return str(value)


def final_trajectory(estimate) -> Trajectory:
    """The smoothed trajectory of a smoother, else the causal one."""
    smoothed = estimate.smoothed
    if smoothed is not None and smoothed.pose is not None:
        return smoothed.pose
    return estimate.causal.pose


def agreement(reference: Trajectory, trajectory: Trajectory) -> tuple[float, float]:
    """(max, RMS) distance [m] after the SE(2) alignment of ``trajectory`` onto ``reference``
    at their shared stamps (``workbench.metrics.ate``)."""
    from workbench.metrics.ate import ate_errors, paired_trajectories

    paired_reference, paired = paired_trajectories(reference, trajectory, 0.01)
    errors, _, _ = ate_errors(paired_reference, paired, "se2", allow_degenerate=True)
    return float(errors.max()), float(np.sqrt(np.mean(errors**2)))


def table(logs: list[str], estimators: list[str], data: dict, relations: dict) -> None:
    print("| log | estimator | " + " | ".join(COLUMNS) + " |")
    print("|" + "---|" * (len(COLUMNS) + 2))
    notes = []
    for log in logs:
        dataset = f"carmen:{DATA / f'{log}.clf.bz2'}"
        options = dict(data)
        if log in relations:
            options["relations"] = relations[log]
        sequence = load_dataset(dataset, 0, options)
        reference = None
        scans = sequence.metadata["totals"]["scans_used"]
        for name in estimators:
            request = RunRequest(name, dataset, data_options=tuple(options.items()))
            started = time.perf_counter()
            result = execute(request, sequence=sequence)
            wall = time.perf_counter() - started
            metrics = compute_metrics(result.estimate, sequence)
            trajectory = final_trajectory(result.estimate)
            if name == "smoother-batch":
                reference = trajectory
            agree = agreement(reference, trajectory) if reference is not None else (None, None)
            values = [
                *agree,
                metrics.get("nis_measurement_per_dof"),
                metrics.get("nis_per_dof"),
                metrics.get("landmarks_in_map"),
                metrics.get("association_contested_fraction"),
                metrics.get("association_rejected_fraction"),
                metrics.get("association_inflated_fraction"),
                metrics.get("loop_closures"),
                1e3 * float(metrics["time_total_s"]) / scans,
                metrics.get("relations_trans_error_mean_m"),
                metrics.get("relations_rot_error_mean_deg"),
            ]
            print(f"| {log} | {name} | " + " | ".join(cell(v) for v in values) + " |", flush=True)
            if metrics.get("frames_without_pose"):
                notes.append(
                    f"{log} {name}: {metrics['frames_without_pose']} of {metrics['frames']} "
                    "scans without a pose"
                )
            if metrics.get("diverged_at_s") is not None:
                notes.append(
                    f"{log} {name}: diverged at t={metrics['diverged_at_s']:.1f} s: "
                    f"{metrics['divergence']}"
                )
            notes.append(f"{log} {name}: {wall:.0f} s wall")
        corners = sequence.pass_report.figures["corners"]  # filled by the runs
        notes.append(
            f"{log}: {scans} scans, {corners['corners_detected'] / scans:.2f} corners per scan, "
            f"{corners['corners_confirmed'] / max(corners['corners_detected'], 1):.2f} "
            f"confirmed, re-observation NIS/dof {cell(corners['reobservation_nis_per_dof'])} "
            f"({corners['reobservation_pairs']} pairs; gated expectation "
            f"{corners['reobservation_nis_expected_per_dof']:.3f}), front end "
            f"{corners['front_end_ms_per_scan']:.2f} ms per scan"
        )
    print()
    for note in notes:
        print(f"- {note}")


def smoothed_reference(dataset: str, options: dict) -> tuple:
    """(sequence, smoother-batch's smoothed trajectory) of a log with ``options`` (without
    the per-keyframe innovation NIS, which the reference does not need and which costs most
    of the smoother's time on a map of hundreds of corners)."""
    sequence = load_dataset(dataset, 0, options)
    request = RunRequest("smoother-batch", dataset, overrides=(("innovation_nis", "false"),))
    result = execute(request, sequence=sequence)
    return sequence, result.estimate.smoothed.pose


def calibrate(logs: list[str], iterations: int, window_s: float) -> None:
    """``--calibrate`` (module docstring)."""
    from datasets.carmen import CarmenOptions, parse_log
    from datasets.carmen.assembly import carmen_source
    from datasets.laser2d.reobservation import fit_scales
    from datasets.odometry_calibration import (
        build_windows,
        concatenate_windows,
        fit_odometry_noise,
        window_nees,
    )
    from workbench.calibration.calibrate import Calibration
    from workbench.calibration.odometry_sources import planar_increments

    datasets = {log: f"carmen:{DATA / f'{log}.clf.bz2'}" for log in logs}
    with tempfile.TemporaryDirectory(prefix="carmen-calibration-") as scratch:
        model_file = Path(scratch) / "odometry_noise.yaml"
        options: dict[str, str] = {}
        for iteration in range(1, iterations + 1):
            references, increments, sequences = {}, {}, {}
            for log, dataset in datasets.items():
                started = time.perf_counter()
                sequence, reference = smoothed_reference(dataset, options)
                sequences[log], references[log] = sequence, reference
                increments[log] = planar_increments(sequence)
                print(
                    f"iteration {iteration}: {log}: smoother-batch "
                    f"{time.perf_counter() - started:.0f} s",
                    flush=True,
                )
            windows = {
                log: build_windows(
                    increments[log],
                    references[log].t,
                    references[log].positions,
                    references[log].rotations,
                    window_s,
                )
                for log in logs
            }
            source = (
                f"fitted against the batch smoother on {', '.join(logs)} pooled "
                f"({iteration} iteration{'s' if iteration > 1 else ''}, {window_s:g} s windows)"
            )
            fit = fit_odometry_noise(concatenate_windows(list(windows.values())), source)
            print(
                f"iteration {iteration}: pooled fit on {fit.windows} windows, "
                f"{len(fit.excluded)} excluded, NEES/dof {fit.nees_per_dof:.3g}"
            )
            for line in fit.model.describe():
                print("   ", line)
            Calibration(fit, "smoother", window_s, {}).write(model_file, "+".join(logs))
            options = {"odometry_noise": str(model_file)}
        print("\nrates (time, distance, turn) x (x, y, theta):")
        print(np.array2string(fit.model.rates, precision=3, separator=", "))
        print("\nthe pooled model on each log (NEES per dof, mean / median, by window):")
        for log in logs:
            parts = []
            for factor in (0.25, 1.0, 4.0):
                built = build_windows(
                    increments[log],
                    references[log].t,
                    references[log].positions,
                    references[log].rotations,
                    window_s * factor,
                )
                per_dof = window_nees(fit.model.rates, built) / 3.0
                parts.append(
                    f"{window_s * factor:g} s {np.mean(per_dof):.2f} / {np.median(per_dof):.2f}"
                )
            print(f"  {log}: " + ", ".join(parts))
        if len(logs) > 1:
            print("\nleft out (fitted on the others, NEES per dof on the one left out, 5 s):")
            for log in logs:
                others = concatenate_windows([windows[other] for other in logs if other != log])
                held = fit_odometry_noise(others, "leave-one-out")
                per_dof = window_nees(held.model.rates, windows[log]) / 3.0
                print(f"  {log}: mean {np.mean(per_dof):.2f}, median {np.median(per_dof):.2f}")
        # the corner scale, with the fitted odometry model's increments
        print("\ncorner covariance scale (re-observation pairs, pooled maximum likelihood):")
        groups = {}
        for log in logs:
            path = DATA / f"{log}.clf.bz2"
            settings = CarmenOptions(**options)
            sequence, front_end = carmen_source(parse_log(path), settings, f"carmen:{path}")
            for _ in sequence.measurements():
                pass
            groups[log] = list(front_end.log.groups)
        pooled = [group for log in logs for group in groups[log]]
        scale, motion = fit_scales(pooled)
        print(f"  fitted corner scale {scale:.3f} (motion scale {motion:.3f}, not applied)")
        from datasets.laser2d.reobservation import ReobservationLog

        for log in logs:
            record = ReobservationLog(groups=groups[log])
            values = record.nis(scale)
            own_scale, own_motion = fit_scales(groups[log])
            print(
                f"  {log}: {values.size} pairs, re-observation NIS/dof at the pooled scale "
                f"{values.mean() / 2:.3f} (this log alone would fit {own_scale:.3f}, motion "
                f"{own_motion:.3f})"
            )


def scan_matching(logs: list[str]) -> None:
    """``--scan-matching`` (module docstring)."""
    from datasets.carmen import parse_log
    from datasets.carmen.odometry import relative_increments
    from datasets.laser2d.scan import PlanarScan
    from datasets.laser2d.scan_matching import planar_kiss_icp

    for log in logs:
        path = DATA / f"{log}.clf.bz2"
        sequence = load_dataset(f"carmen:{path}", 0, {})
        parsed = parse_log(path)
        fronts = [message for message in parsed.lasers if message.front]
        mounting = np.array(sequence.metadata["laser_mounting"])
        scans = [
            PlanarScan(message.t, message.ranges, message.angles(), 0.1, 20.0, mounting)
            for message in fronts
        ]
        times, kiss, rate = planar_kiss_icp(scans)
        odometry = np.array([message.odometry for message in fronts])
        kiss_turn = relative_increments(kiss)[:, 2]
        odometry_turn = relative_increments(odometry)[:, 2]
        gap = np.rad2deg(np.abs(np.angle(np.exp(1j * (kiss_turn - odometry_turn)))))
        total = np.rad2deg(np.sum(kiss_turn - odometry_turn))
        print(
            f"{log}: KISS-ICP {rate:.0f} scans/s; per-scan heading change minus the odometry's: "
            f"median {np.median(gap):.2f} deg, 90th percentile {np.percentile(gap, 90):.2f} deg, "
            f"summed over the log {total:+.0f} deg",
            flush=True,
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--log", action="append", default=[], choices=LOGS)
    parser.add_argument("--estimator", action="append", default=[])
    parser.add_argument("--data", action="append", default=[], help="loader option KEY=VALUE")
    parser.add_argument(
        "--relations", action="append", default=[], help="LOG=FILE: relations of that log"
    )
    parser.add_argument("--calibrate", action="store_true")
    parser.add_argument("--iterations", type=int, default=3)
    parser.add_argument("--window-s", type=float, default=5.0)
    parser.add_argument("--scan-matching", action="store_true")
    arguments = parser.parse_args()
    logs = arguments.log or list(LOGS)
    missing = [log for log in logs if not (DATA / f"{log}.clf.bz2").is_file()]
    if missing:
        raise SystemExit(f"error: {', '.join(missing)} not found in {DATA}")
    if arguments.calibrate:
        calibrate(logs, arguments.iterations, arguments.window_s)
        return
    if arguments.scan_matching:
        scan_matching(logs)
        return
    estimators = arguments.estimator or list(ESTIMATORS)
    if "smoother-batch" in estimators:
        estimators = ["smoother-batch"] + [name for name in estimators if name != "smoother-batch"]
    data = dict(item.split("=", 1) for item in arguments.data)
    relations = dict(item.split("=", 1) for item in arguments.relations)
    table(logs, estimators, data, relations)


if __name__ == "__main__":
    main()
