"""``workbench bag``'s front-end stage (step 1 of ``workbench.commands.bag``): one pass over
the bag's stream with a progress bar, the front end's files in ``DIR/frontend/`` and its
figures, and what the loader decided and warned, printed."""

from __future__ import annotations

import csv
import io
import time
from pathlib import Path

import numpy as np
import typer

from datasets.errors import InputError
from datasets.lidar.frontend_diagnostics import HEADING_CHECK_FRAMES


def run_front_end(sequence, source, lidar_messages: int, disable_progress: bool) -> float:
    """One pass over the sequence (fills the front-end cache); returns the wall time [s]."""
    from datasets.measurements import PointCloud

    started = time.perf_counter()
    from workbench.progress import count_progress

    with count_progress(disable_progress, rate=True) as progress:
        task = progress.add_task(
            "front end (KISS-ICP + corners)", total=lidar_messages or None, rate=""
        )
        frames = 0
        for measurement in sequence.measurements():
            if isinstance(measurement, PointCloud):
                frames += 1
                elapsed = time.perf_counter() - started
                progress.update(
                    task, completed=frames, rate=f"{frames / max(elapsed, 1e-9):.1f} frames/s"
                )
    return time.perf_counter() - started


def corners_csv(frames) -> str:
    """One line per detection: frame time, index, position, covariance (upper triangle)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(
        ["t", "index", "x", "y", "z", "cov_xx", "cov_xy", "cov_xz", "cov_yy", "cov_yz", "cov_zz"]
    )
    for frame in frames:
        if frame.corners is None:
            continue
        for index, (point, covariance) in enumerate(
            zip(frame.corners.points, frame.corners.covariances)
        ):
            padded = np.zeros(3)
            padded[: len(point)] = point
            full = np.zeros((3, 3))
            full[: len(point), : len(point)] = covariance
            writer.writerow(
                [
                    f"{frame.t:.9f}",
                    index,
                    *(f"{v:.6f}" for v in padded),
                    *(
                        f"{full[i, j]:.3e}"
                        for i, j in ((0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2))
                    ),
                ]
            )
    return buffer.getvalue()


def front_end_metrics(sequence, source, seconds: float) -> dict:
    """The front end's figures (``DIR/frontend/metrics.json``, ``workbench.commands.bag``)."""
    from datasets.lidar.corner_truth import (
        corner_error_statistics,
        read_corner_truth,
        score_corners,
    )

    front_end = source.front_end
    report = sequence.front_end  # the typed report (datasets.lidar.frontend_report)
    frames = front_end.frames
    # over the first frames only: a constant yaw-rate error is a model for a short span, and
    # the fit's corner clustering grows with the square of the pairs (LidarFrontEnd)
    yaw_rate = front_end.corner_yaw_rate(HEADING_CHECK_FRAMES)
    metrics: dict = {
        "frames": len(frames),
        "points_per_frame_mean": float(np.mean([f.points for f in frames])) if frames else None,
        "kiss_icp_ms_mean": 1000.0 * float(np.mean([f.icp_seconds for f in frames]))
        if frames
        else None,
        "kiss_icp_ms_median": 1000.0 * float(np.median([f.icp_seconds for f in frames]))
        if frames
        else None,
        "corner_ms_mean": 1000.0 * float(np.mean([f.corner_seconds for f in frames]))
        if frames
        else None,
        "corners_per_frame_mean": float(
            np.mean([len(f.corners.points) for f in frames if f.corners is not None])
        )
        if frames and front_end.settings.corners
        else None,
        "frames_per_s": len(frames) / seconds if seconds > 0 else None,
        "kiss_icp_ate_rmse_m": None,
        "corner_precision": None,
        "corner_recall": None,
        "skipped": source.report.lines(),
        "nonfinite_points_dropped": int(source.report.nonfinite_points),
        "topics": sequence.topics.as_dict() if sequence.topics is not None else None,
        # corners found again where they were (KISS-ICP's poses), and how far they moved
        # against their covariances (datasets.lidar.corner_tracking)
        **(report.reobservation.summary() if report.reobservation is not None else {}),
        # the covariance of KISS-ICP's increments at the last frame, and the fit behind it
        # (datasets.lidar.increment_noise)
        **(report.increment_noise.summary() if report.increment_noise is not None else {}),
        # when KISS-ICP's motion had settled by the corners, and how many increments (and
        # their corners) were inflated before (datasets.lidar.motion_settling)
        **(report.settling.summary() if report.settling is not None else {}),
        # the constant yaw-rate error of KISS-ICP that the corners imply [deg/s] over the
        # first HEADING_CHECK_FRAMES frames, and its standard error (jackknife over corners):
        # a disagreement, which either side may cause (datasets.lidar.increment_noise)
        "kiss_icp_corner_yaw_rate_deg_s": None
        if yaw_rate is None
        else float(np.rad2deg(yaw_rate[0])),
        "kiss_icp_corner_yaw_rate_se_deg_s": None
        if yaw_rate is None
        else float(np.rad2deg(yaw_rate[1])),
    }
    truth = sequence.ground_truth.pose if sequence.ground_truth is not None else None
    trajectory = front_end.trajectory()
    if truth is not None and len(truth) >= 2 and trajectory is not None and len(trajectory) >= 3:
        from workbench.metrics.ate import ate_report

        try:
            report = ate_report(
                truth, trajectory, align="se3", max_diff_s=0.05, allow_degenerate=True
            )
            metrics["kiss_icp_ate_rmse_m"] = report["rmse_m"]
            metrics["kiss_icp_ate"] = report
        except InputError as error:
            metrics["kiss_icp_ate_error"] = str(error)
    sidecar = sequence.corner_sidecar
    if sidecar is not None and truth is not None and front_end.settings.corners:
        config = front_end.settings.corner
        corner_truth = read_corner_truth(sidecar)
        metrics.update(
            score_corners(
                [(f.t, f.corners.points) for f in frames],
                corner_truth,
                truth,
                config.min_range_m,
                config.max_range_m,
                config.azimuth_resolution_deg,
            )
        )
        metrics.update(
            corner_error_statistics(
                [(f.t, f.corners.points, f.corners.covariances) for f in frames],
                corner_truth,
                truth,
            )
        )
    return metrics


def lidar_front_end(
    path: Path, sequence, source, settings, lidar_messages: int, out: Path, disable: bool, claim
) -> dict:
    """A lidar bag: one pass over the stream (``run_front_end``; ``InputError`` without a
    usable cloud), then ``DIR/frontend/`` (``kiss_icp.tum``, ``corners.csv``,
    ``metrics.json``), the front end's settings and warm-up and the loader's decisions and
    warnings printed. Returns the front end's figures (``front_end_metrics``)."""
    from datasets.trajectory_io import write_atomic, write_tum
    from workbench.run_folder import dump_json

    seconds = run_front_end(sequence, source, lidar_messages, disable)
    if not source.front_end.frames:
        raise InputError(
            f"{path}: no usable point clouds on {sequence.topics.lidar}"
            + (f" ({'; '.join(source.report.lines())})" if source.report.skipped else "")
        )
    claim()
    front_dir = out / "frontend"
    front_dir.mkdir(parents=True, exist_ok=True)
    trajectory = source.front_end.trajectory()
    if trajectory is not None and len(trajectory):
        write_tum(front_dir / "kiss_icp.tum", trajectory)
    write_atomic(front_dir / "corners.csv", corners_csv(source.front_end.frames))
    front = front_end_metrics(sequence, source, seconds)
    # --threads (or --data kiss.max_num_threads): with more than one, runs differ at 1e-13
    front["kiss_icp_threads"] = settings.kiss.max_num_threads
    _print_settings(source.front_end.resolved(), front)
    _print_increment_noise(sequence.front_end, front)
    write_atomic(front_dir / "metrics.json", dump_json(front))
    print_loader_lines(sequence)
    return front


def _print_settings(resolved: dict, front: dict) -> None:
    """KISS-ICP's range, its origin, the voxel and the deskew it ran with: printed and added
    to ``front``."""
    if not resolved:
        return
    front["kiss_icp_max_range_m"] = resolved["max_range_m"]
    front["kiss_icp_max_range_source"] = resolved["max_range_source"]
    front["kiss_icp_voxel_size_m"] = resolved["voxel_size_m"]
    typer.echo(
        f"front end: KISS-ICP max range {resolved['max_range_m']:g} m "
        f"({resolved['max_range_source']}), voxel {resolved['voxel_size_m']:g} m",
        err=True,
    )
    front["deskew"] = resolved["deskew"]
    deskew = resolved["deskew"]
    if deskew == "imu":
        front["imu_deskewed_frames"] = resolved["imu_deskewed_frames"]
        front["imu_deskew_fallback_frames"] = resolved["imu_deskew_fallback_frames"]
        deskew = (
            f"the IMU's rotation ({resolved['imu_deskewed_frames']} frames, "
            f"{resolved['imu_deskew_fallback_frames']} fell back to KISS-ICP's)"
        )
    typer.echo(f"front end: deskew: {deskew}", err=True)


def _print_increment_noise(report, front: dict) -> None:
    """The covariance of KISS-ICP's increments at the end, when it settled and the corners'
    yaw-rate disagreement (``report``: the sequence's ``FrontEndReport``), printed."""
    if report.increment_noise is None or report.settling is None:
        return
    noise = report.increment_noise
    fitted = (
        ""
        if noise.estimate is None
        else f"; fitted {1e3 * np.sqrt(noise.estimate[0]):.2g} mrad / "
        f"{1e3 * np.sqrt(noise.estimate[1]):.2g} mm"
    )
    typer.echo(
        f"front end: KISS-ICP increment sigma {1e3 * np.sqrt(noise.rotation_variance):.2g} "
        f"mrad / {1e3 * np.sqrt(noise.translation_variance):.2g} mm per frame at the end "
        f"({noise.source}{fitted})",
        err=True,
    )
    settling = report.settling
    if settling.settled_frame is not None:
        typer.echo(
            f"front end: KISS-ICP settled by the corners at frame {settling.settled_frame} "
            f"({settling.inflated_frames} increments and their corners inflated before)",
            err=True,
        )
    if front["kiss_icp_corner_yaw_rate_deg_s"] is not None:
        typer.echo(
            "front end: the corners' re-observations imply KISS-ICP turns "
            f"{front['kiss_icp_corner_yaw_rate_deg_s']:+.3f} +- "
            f"{front['kiss_icp_corner_yaw_rate_se_deg_s']:.3f} deg/s more than they say "
            f"over the first {HEADING_CHECK_FRAMES} frames at most "
            "(+- : jackknife over corners; either side may be the one that is wrong)",
            err=True,
        )


def print_loader_lines(sequence) -> None:
    """The loader's decisions (``front end:``) and the loader's and the pass's warnings."""
    # what the loader decided from the data (sweep timing, topic roles), with its evidence
    for line in sequence.decisions or ():
        typer.echo(f"front end: {line}", err=True)
    # the loader's and the front end's: skipped messages, pose topics not taken as truth
    for line in sequence.all_warnings():
        typer.echo(f"warning: {sequence.name}: {line}", err=True)


def sensor_front_end(sequence, source, out: Path, disable: bool, claim) -> list[str]:
    """A bag without lidar: one pass over the stream (the 2-D laser's corners, where its
    scans are used, are computed once), its decisions printed as ``front end:`` lines and
    its warnings as ``warning:`` lines; ``DIR/frontend/metrics.json`` with the 2-D laser
    front end's figures (corners, re-observation NIS, time per scan) where it ran. Returns
    the notes for the table."""
    from workbench.progress import count_progress
    from workbench.run_folder import dump_json

    started = time.perf_counter()
    with count_progress(disable) as progress:
        task = progress.add_task("reading the bag", total=None)
        for count, _ in enumerate(sequence.measurements(), start=1):
            if count % 1000 == 0:
                progress.update(task, completed=count)
    seconds = time.perf_counter() - started
    claim()
    notes = []
    laser = source.laser_front_end
    if laser is not None:
        front_dir = out / "frontend"
        front_dir.mkdir(parents=True, exist_ok=True)
        summary = laser.summary()
        figures = {**summary, "seconds": seconds, "topics": sequence.topics.as_dict()}
        figures["skipped"] = source.report.lines()
        from datasets.trajectory_io import write_atomic

        write_atomic(front_dir / "metrics.json", dump_json(figures))
        corners = summary.get("corners")
        notes.append(
            f"front end 2-D laser corners: {summary['scans']} scans"
            + (f", {corners} corners" if corners is not None else "")
            + (
                f", {summary['front_end_ms_per_scan']:.3g} ms per scan"
                if summary.get("front_end_ms_per_scan") is not None
                else ""
            )
        )
    used = ", ".join(
        f"{role} {topic}" for role, topic in sequence.topics.as_dict().items() if topic
    )
    notes.append(f"no lidar: no KISS-ICP front end; inputs: {used}")
    print_loader_lines(sequence)
    return notes
