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

Step 1 is ``workbench.commands.bag_front_end`` (and a bag without lidar's pass there),
steps 2 and 3 ``workbench.commands.bag_estimators``; this module reads the options and
the bag and runs them in turn.
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from pathlib import Path
from typing import Annotated

import typer

from datasets.lidar.corner_truth import with_true_corner_ids
from datasets.options import build_model, nest_dotted, parse_assignments
from workbench.commands.bag_estimators import choose_estimators, not_applicable, run_estimators
from workbench.commands.bag_front_end import lidar_front_end, sensor_front_end
from workbench.completion import estimator_names
from workbench.estimator_settings import settings_by_estimator
from workbench.plot_formats import parse_plot_formats


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

    front = lidar_front_end(path, sequence, source, settings, lidar_messages, out, disable, claim)
    sequence = with_true_corner_ids(sequence, source.front_end)
    rows = [{"estimator": "kiss-icp (front end)", "status": "ok"}]
    front_note = f"front end kiss-icp: {front['kiss_icp_ms_median']:.3g} ms per frame (median)" + (
        f", ATE {front['kiss_icp_ate_rmse_m']:.4g} m against {sequence.reference_source}"
        if front["kiss_icp_ate_rmse_m"] is not None
        else ""
    )
    return run_estimators(sequence, out, rows=rows, notes=[front_note], **run)


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
