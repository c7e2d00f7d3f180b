"""``workbench metrics ate|rpe``: evaluate any pair of trajectory files (TUM, or KITTI poses
paired by index) and print JSON."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from datasets.errors import InputError
from datasets.trajectory_io import read_kitti, read_tum

ALIGNMENTS = ("se3", "sim3", "se2", "none")

RefOption = Annotated[
    Path, typer.Option("--ref", help="reference trajectory (TUM; .kitti: KITTI poses)")
]
EstOption = Annotated[
    Path, typer.Option("--est", help="estimated trajectory (TUM; .kitti: KITTI poses)")
]
AlignOption = Annotated[str, typer.Option("--align", help="alignment: se3, sim3, se2 or none")]
MaxDiffOption = Annotated[
    float, typer.Option("--max-diff", help="max time difference when pairing stamps [s]")
]


def _check_align(align: str) -> None:
    if align not in ALIGNMENTS:
        raise InputError(f"--align must be one of {', '.join(ALIGNMENTS)}, got '{align}'")


def _check_positive(name: str, value: float) -> None:
    if not (value > 0 and math.isfinite(value)):
        raise InputError(f"{name} must be a positive number, got {value}")


def read_trajectory(path: Path):
    """A TUM file, or KITTI poses (``.kitti``: 3x4 a line, no times: the pose index is
    the time, so two KITTI files pair pose by pose)."""
    if Path(path).suffix.lower() == ".kitti":
        return read_kitti(path)
    return read_tum(path)


def register(app: typer.Typer) -> None:
    metrics_app = typer.Typer(
        help="Evaluate TUM trajectory files (prints JSON).", no_args_is_help=True
    )

    @metrics_app.command("ate")
    def ate_command(
        ref: RefOption, est: EstOption, align: AlignOption = "se3", max_diff: MaxDiffOption = 0.01
    ) -> None:
        """Absolute trajectory error (translation RMSE after alignment), as evo_ape."""
        from workbench.metrics.ate import ate_report
        from workbench.run_folder import dump_json

        _check_align(align)
        _check_positive("--max-diff", max_diff)
        report = ate_report(
            read_trajectory(ref), read_trajectory(est), align=align, max_diff_s=max_diff
        )
        typer.echo(dump_json(report), nl=False)

    @metrics_app.command("rpe")
    def rpe_command(
        ref: RefOption,
        est: EstOption,
        delta: Annotated[
            float, typer.Option("--delta", help="offset between compared poses")
        ] = 1.0,
        unit: Annotated[
            str, typer.Option("--unit", help="unit of --delta: frames or m")
        ] = "frames",
        align: AlignOption = "none",
        max_diff: MaxDiffOption = 0.01,
    ) -> None:
        """Relative pose error (translation and rotation RMSE), as evo_rpe."""
        from workbench.metrics.rpe import rpe_report
        from workbench.run_folder import dump_json

        _check_align(align)
        _check_positive("--max-diff", max_diff)
        _check_positive("--delta", delta)
        if unit not in ("frames", "m"):
            raise InputError(f"--unit must be frames or m, got '{unit}'")
        report = rpe_report(
            read_trajectory(ref),
            read_trajectory(est),
            delta=delta,
            unit=unit,
            align=align,
            max_diff_s=max_diff,
        )
        typer.echo(dump_json(report), nl=False)

    app.add_typer(metrics_app, name="metrics")
