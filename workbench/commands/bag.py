"""``workbench bag PATH --out DIR``: a lidar bag end to end.

1. Reads the bag (``bag:PATH``) and runs the front end (KISS-ICP, corners) once, with a
   progress bar in frames per second; writes ``DIR/frontend/``: ``kiss_icp.tum``,
   ``corners.csv`` (every detection with its covariance), ``metrics.json`` (frames, times,
   ``kiss_icp_ate_rmse_m`` when the bag has ground truth, ``corner_precision`` and
   ``corner_recall`` when a corner sidecar lies next to the bag, counted skips).
2. Runs each chosen estimator (default: every registered one the bag's sensors allow) on the
   resulting stream (the front end is cached, so it runs once) and writes ``DIR/<name>/``
   run folders with the workbench runner.
3. Writes ``DIR/table.md``, ``table.tex`` and ``table.csv`` and the comparison figures
   (``DIR/plots/``) through the one report writer (``workbench.reporting``): a row per
   estimator (a failed one says why), KISS-ICP's own figures in a note under it; prints the
   table as ``bench`` and ``report`` do (``show_report``).

Every file is written atomically, the front end's before any estimator runs, so a failure
later leaves what was already written valid. An estimator that fails is reported in its
table row and the others still run.
"""

from __future__ import annotations

import csv
import io
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Annotated

import numpy as np
import typer

from datasets.errors import InputError
from datasets.lidar.corner_truth import with_true_corner_ids
from datasets.lidar.frontend_diagnostics import HEADING_CHECK_FRAMES
from datasets.options import build_model, nest_dotted, parse_assignments
from workbench.completion import estimator_names
from workbench.estimator_settings import settings_by_estimator
from workbench.plot_formats import parse_plot_formats


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
    """The front end's figures (see the module docstring)."""
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


def _status(text: str, limit: int = 160) -> str:
    """One table-safe line: no newlines or pipes, at most ``limit`` characters."""
    flat = " ".join(text.split()).replace("|", "/")
    return flat if len(flat) <= limit else flat[: limit - 3] + "..."


def not_applicable(requested: list[str] | None, sequence) -> dict[str, str]:
    """Every registered estimator the sequence's sensors or dimension do not allow, with the
    reason (``workbench.runner.check_compatible``, as ``bench`` says it), when none were
    requested by name (a requested one that cannot run fails in its own row)."""
    from workbench.registry import ESTIMATORS
    from workbench.runner import check_compatible

    if requested:
        return {}
    reasons = {}
    for entry in ESTIMATORS:
        try:
            check_compatible(entry.name, entry.load(), sequence)
        except InputError as error:
            reasons[entry.name] = str(error)
    return reasons


def choose_estimators(requested: list[str] | None, sequence) -> list[str]:
    """The requested names (checked), or every registered estimator the sequence allows."""
    from workbench.registry import ESTIMATORS, estimator_entry
    from workbench.runner import is_compatible

    if requested:
        for name in requested:
            estimator_entry(name)  # InputError listing the known ones
        return list(dict.fromkeys(requested))
    return [entry.name for entry in ESTIMATORS if is_compatible(entry.load(), sequence)]


def bag_command(
    path: Path,
    out: Path,
    lidar_topic: str | None,
    imu_topic: str | None,
    ground_truth_topic: str | None,
    estimators: list[str] | None,
    data: list[str],
    plots: bool,
    quiet: bool = False,
    settings_overrides: list[str] | None = None,
    plot_formats: tuple[str, ...] = ("png",),
) -> list[dict]:
    """The whole command (module docstring); returns the table rows. ``out`` must be new,
    empty or an earlier output of the workbench's (``workbench.owned_folders``). ``quiet``:
    no progress bars and no table on the terminal (the files are written all the same)."""
    from workbench.owned_folders import COLLECTION, check_writable, claim_collection, exclusive

    out = Path(out)
    with exclusive(out):
        check_writable(out, COLLECTION)  # before the bag is read, not after
        return _bag_command(
            path,
            out,
            lidar_topic,
            imu_topic,
            ground_truth_topic,
            estimators,
            data,
            plots,
            quiet,
            settings_overrides,
            plot_formats,
            claim=lambda: claim_collection(out),
        )


def _bag_command(
    path: Path,
    out: Path,
    lidar_topic: str | None,
    imu_topic: str | None,
    ground_truth_topic: str | None,
    estimators: list[str] | None,
    data: list[str],
    plots: bool,
    quiet: bool,
    settings_overrides: list[str] | None,
    plot_formats: tuple[str, ...],
    claim: Callable[[], Path],
) -> list[dict]:
    from datasets.bags.bag_options import BagOptions
    from datasets.bags.source import bag_sequence
    from datasets.trajectory_io import write_atomic, write_tum
    from workbench.run_folder import dump_json

    options = parse_assignments(data, "--data")
    for key, value in (
        ("lidar_topic", lidar_topic),
        ("imu_topic", imu_topic),
        ("ground_truth_topic", ground_truth_topic),
    ):
        if value:
            options[key] = value
    settings = build_model(BagOptions, nest_dotted(options), f"bag:{path}")
    sequence, source = bag_sequence(str(path), settings)
    # the bag's index, read when it was opened to load (not opened again for it)
    lidar_messages = source.lidar_messages or 0
    if settings.max_frames:
        lidar_messages = min(lidar_messages, settings.max_frames)
    names = choose_estimators(estimators, sequence)
    skipped = not_applicable(estimators, sequence)
    overrides = settings_by_estimator(settings_overrides or [], names)
    disable = quiet or not sys.stderr.isatty()
    run = dict(
        names=names,
        skipped=skipped,
        overrides=overrides,
        data_options=tuple(options.items()),
        plots=plots,
        quiet=quiet,
        plot_formats=plot_formats,
        disable=disable,
    )
    if source.front_end is None:  # no lidar (datasets.bags.sensor_source): no KISS-ICP
        notes = sensor_front_end(sequence, source, out, disable, claim)
        return run_estimators(sequence, out, rows=[], notes=notes, **run)

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
    resolved = source.front_end.resolved()  # the range, its origin and the voxel
    if resolved:
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
    report = sequence.front_end
    if report.increment_noise is not None and report.settling is not None:
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
    write_atomic(front_dir / "metrics.json", dump_json(front))
    # what the loader decided from the data (sweep timing), with its evidence
    for line in sequence.decisions or ():
        typer.echo(f"front end: {line}", err=True)
    # the loader's and the front end's: skipped messages, pose topics not taken as truth
    for line in sequence.all_warnings():
        typer.echo(f"warning: {sequence.name}: {line}", err=True)

    sequence = with_true_corner_ids(sequence, source.front_end)
    rows = [{"estimator": "kiss-icp (front end)", "status": "ok"}]
    front_note = f"front end kiss-icp: {front['kiss_icp_ms_median']:.3g} ms per frame (median)" + (
        f", ATE {front['kiss_icp_ate_rmse_m']:.4g} m against {sequence.reference_source}"
        if front["kiss_icp_ate_rmse_m"] is not None
        else ""
    )
    return run_estimators(sequence, out, rows=rows, notes=[front_note], **run)


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
    for line in sequence.decisions or ():
        typer.echo(f"front end: {line}", err=True)
    for line in sequence.all_warnings():
        typer.echo(f"warning: {sequence.name}: {line}", err=True)
    return notes


def run_estimators(
    sequence,
    out: Path,
    rows: list[dict],
    notes: list[str],
    names: list[str],
    skipped: dict[str, str],
    overrides: dict,
    data_options: tuple,
    plots: bool,
    quiet: bool,
    plot_formats: tuple[str, ...],
    disable: bool,
) -> list[dict]:
    """Each of ``names`` on ``sequence`` into ``out/<name>/``, then the table and figures
    of them, with an n/a row and its reason for each of ``skipped`` (``bench``'s rows);
    returns ``rows`` with a row per estimator run."""
    from workbench.reporting import write_report
    from workbench.results.runs import load_runs
    from workbench.results.summary import PlannedPair
    from workbench.run_folder import write_failed_run, write_run_folder
    from workbench.runner import RunRequest, execute

    for name in names:
        row = {"estimator": name, "status": "ok"}
        try:
            from workbench.progress import sequence_progress

            with sequence_progress(disable) as progress:
                start = sequence.initial_state.t if sequence.initial_state else 0.0
                task = progress.add_task(name, total=None)
                result = execute(
                    RunRequest(
                        estimator=name,
                        dataset=sequence.name,
                        overrides=tuple(overrides[name].items()),
                        data_options=data_options,
                    ),
                    sequence=sequence,
                    on_step=lambda t, task=task, start=start: progress.update(
                        task, completed=t - start
                    ),
                )
            write_run_folder(result, out / name, plot_formats if plots else ())
        except InputError as error:
            row["status"] = _status(f"not run: {error}")
            typer.echo(f"warning: {name}: {error}", err=True)
        except Exception as error:  # one estimator's failure must not lose the others' results
            row["status"] = _status(f"failed: {type(error).__name__}: {error}")
            typer.echo(f"warning: {name} failed: {row['status']}", err=True)
        if row["status"] != "ok":
            request = {"dataset": sequence.name, "estimator": name, "seed": 0}
            write_failed_run(out / name, request, row["status"])
        rows.append(row)
    folders = [out / name for name in names]
    records = load_runs(folders)
    # the estimators the bag's sensors do not allow: n/a rows with the reason, as bench's
    planned = [
        PlannedPair(record.dataset_label, record.estimator_label, record.estimator, 1)
        for record in records
    ] + [PlannedPair(sequence.name, name, name, 0, reason) for name, reason in skipped.items()]
    for name, reason in skipped.items():
        typer.echo(f"n/a: {name}: {reason}", err=True)
    # the comparison figures as bench draws them, in the formats asked for
    report = write_report(
        records, out, planned, notes=notes, plot_formats=plot_formats if plots else ()
    )
    if not quiet:
        from workbench.commands.bench import show_report

        show_report(report, "")  # the dataset is the bag: the tables are titled with it
    return rows


def register(app: typer.Typer) -> None:
    @app.command("bag")
    def bag(
        path: Annotated[
            Path, typer.Argument(help="ROS 1 .bag file or ROS 2 bag folder (sqlite3 or mcap)")
        ],
        out: Annotated[Path, typer.Option("--out", help="output folder")],
        lidar_topic: Annotated[
            str | None,
            typer.Option("--lidar-topic", help="PointCloud2 topic (default: found by type)"),
        ] = None,
        imu_topic: Annotated[
            str | None, typer.Option("--imu-topic", help="Imu topic (default: found by type)")
        ] = None,
        truth_topic: Annotated[
            str | None,
            typer.Option(
                "--truth-topic",
                help="Odometry/PoseStamped topic to score against (default: none; a pose topic is never taken as truth unless named)",
            ),
        ] = None,
        estimator: Annotated[
            list[str] | None,
            typer.Option(
                "--estimator",
                help="estimator to run (repeatable; default: all the bag allows)",
                autocompletion=estimator_names,
            ),
        ] = None,
        data: Annotated[
            list[str] | None,
            typer.Option(
                "--data",
                help="bag option key=value, e.g. max_frames=50, kiss.voxel_size_m=0.5 (repeatable)",
            ),
        ] = None,
        set_: Annotated[
            list[str] | None,
            typer.Option(
                "--set",
                help="estimator option ESTIMATOR.key=value, e.g. aghili.anchor_source=first-observation; key=value when one estimator runs (repeatable)",
            ),
        ] = None,
        plots: Annotated[
            bool,
            typer.Option(
                "--plots/--no-plots", help="write the comparison figures and each run's own"
            ),
        ] = True,
        plot_format: Annotated[
            str,
            typer.Option("--plot-format", help="figure formats, comma-separated: png, pdf, svg"),
        ] = "png",
        threads: Annotated[
            int,
            typer.Option(
                "--threads",
                min=0,
                help="KISS-ICP threads (default 1: two runs give identical results; 0: all cores, "
                "faster, but results differ from run to run in the last digits)",
            ),
        ] = 1,
    ) -> None:
        """Lidar bag end to end: KISS-ICP + corners, every estimator, a comparison table."""
        rows = bag_command(
            path,
            out,
            lidar_topic,
            imu_topic,
            truth_topic,
            estimator,
            [f"kiss.max_num_threads={threads}", *(data or [])],
            plots,
            settings_overrides=set_ or [],
            plot_formats=parse_plot_formats(plot_format),
        )
        runs = [row for row in rows if row["estimator"] != "kiss-icp (front end)"]
        ran = [row["estimator"] for row in runs if row["status"] == "ok"]
        front = out / "frontend"  # none for a bag without lidar or 2-D laser
        typer.echo(
            (f"frontend: {front}; " if front.is_dir() else "")
            + f"{len(ran)} of {len(runs)} estimator run(s) finished in {out}"
        )
        if not ran:
            typer.echo("error: no estimator ran on this bag (the table says why)", err=True)
            raise typer.Exit(3)
