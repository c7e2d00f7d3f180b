"""``workbench bench-speed [--json FILE] [--only KEY ...]``: the named speed figures
(``workbench.speed``) measured in one process, printed as a table with the ratios the
project holds itself to (each against an anchor measured in the same run).

Time small matrices with one BLAS thread on a shared machine:
``OPENBLAS_NUM_THREADS=1 workbench bench-speed``.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Annotated

import typer

from datasets.errors import InputError

KEYS = (
    "aghili_update_ms",
    "ekf_slam_update_ms",
    "filterpy_update_ms",
    "aghili_propagate_us_n10",
    "aghili_propagate_us_n200",
    "sensor_based_step_ms_n200",
    "sensor_based_step_ms_n400",
    "isam2_keyframe_ms_n200",
    "isam2_keyframe_ms_n200_qr",
    "smoother_finish_s_n200",
    "ekf_slam_scan_ms_loop",
    "ekf_slam_mht_hypothesis_scan_ms_loop",
)

RATIOS = (
    ("filterpy / aghili scan update", "filterpy_update_ms", "aghili_update_ms", ">= 10"),
    ("filterpy / ekf-slam scan update", "filterpy_update_ms", "ekf_slam_update_ms", ">= 10"),
    (
        "aghili propagation n=200 / n=10",
        "aghili_propagate_us_n200",
        "aghili_propagate_us_n10",
        "<= 1.5",
    ),
    (
        "sensor-based step n=400 / n=200",
        "sensor_based_step_ms_n400",
        "sensor_based_step_ms_n200",
        "<= 4.5",
    ),
    ("iSAM2 keyframe QR / Cholesky", "isam2_keyframe_ms_n200_qr", "isam2_keyframe_ms_n200", ">= 8"),
    # every hypothesis is a full ekf-slam (between scans all but the leader compose the
    # odometry and predict once) plus the ranking of its next scan's interpretations
    # (Murty's k-best, joint rescoring): 1.33-1.36 measured on the 2-core machine (2.6-2.7,
    # with a one-run anchor, before Murty's subproblems became masks)
    (
        "ekf-slam-mht per hypothesis / ekf-slam, per scan",
        "ekf_slam_mht_hypothesis_scan_ms_loop",
        "ekf_slam_scan_ms_loop",
        "<= 2",
    ),
)


def ratio_rows(found: dict[str, float | None]) -> list[tuple[str, float | None, str]]:
    """(label, numerator / denominator or None, target) for every ratio both sides of
    which were measured."""
    rows = []
    for label, numerator, denominator, target in RATIOS:
        top, bottom = found.get(numerator), found.get(denominator)
        if numerator in found or denominator in found:
            value = top / bottom if top is not None and bottom else None
            rows.append((label, value, target))
    return rows


def register(app: typer.Typer) -> None:
    @app.command("bench-speed")
    def bench_speed_command(
        json_file: Annotated[
            Path | None, typer.Option("--json", help="also write the figures as JSON to FILE")
        ] = None,
        only: Annotated[
            list[str] | None,
            typer.Option(
                "--only", help=f"measure only this figure (repeatable): {', '.join(KEYS)}"
            ),
        ] = None,
    ) -> None:
        """Measure the named speed figures (filters' updates and propagation, the
        sensor-based step, the smoothers' keyframe and finish, filterpy if installed)."""
        from rich.console import Console
        from rich.table import Table

        from workbench.speed import figures

        unknown = sorted(set(only or ()) - set(KEYS))
        if unknown:
            raise InputError(
                f"--only {', '.join(unknown)}: unknown figure (known: {', '.join(KEYS)})"
            )
        threads = os.environ.get("OPENBLAS_NUM_THREADS")
        if threads != "1":
            typer.echo(
                f"note: OPENBLAS_NUM_THREADS={threads or 'unset'}; small-matrix timings on a shared "
                "machine are steadier with OPENBLAS_NUM_THREADS=1",
                err=True,
            )
        found = figures(set(only) if only else None)
        console = Console()
        table = Table(title="workbench bench-speed")
        table.add_column("figure")
        table.add_column("value", justify="right")
        for key, value in found.items():
            table.add_row(key, "not installed" if value is None else f"{value:.4g}")
        console.print(table)
        ratios = Table(title="ratios (same run)")
        for column in ("ratio", "value", "target"):
            ratios.add_column(column, justify="right" if column != "ratio" else "left")
        for label, value, target in ratio_rows(found):
            ratios.add_row(label, "n/a" if value is None else f"{value:.3g}", target)
        console.print(ratios)
        if json_file is not None:
            from datasets.trajectory_io import write_atomic

            write_atomic(Path(json_file), json.dumps(found, indent=2, sort_keys=True) + "\n")
            typer.echo(f"figures: {json_file}")
