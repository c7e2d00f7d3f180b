"""``workbench metrics ate|rpe``: evaluate any pair of TUM files and print JSON."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from datasets.errors import InputError
from datasets.trajectory_io import read_tum

ALIGNMENTS = ("se3", "sim3", "se2", "none")

RefOption = Annotated[Path, typer.Option("--ref", help="reference trajectory (TUM)")]
EstOption = Annotated[Path, typer.Option("--est", help="estimated trajectory (TUM)")]
AlignOption = Annotated[str, typer.Option("--align", help="alignment: se3, sim3, se2 or none")]
MaxDiffOption = Annotated[
    float, typer.Option("--max-diff", help="max time difference when pairing stamps [s]")
]


def _check_align(align: str) -> None:
    if align not in ALIGNMENTS:
        raise InputError(f"--align must be one of {', '.join(ALIGNMENTS)}, got '{align}'")


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
        report = ate_report(read_tum(ref), read_tum(est), align=align, max_diff_s=max_diff)
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
        if unit not in ("frames", "m"):
            raise InputError(f"--unit must be frames or m, got '{unit}'")
        report = rpe_report(
            read_tum(ref), read_tum(est), delta=delta, unit=unit, align=align, max_diff_s=max_diff
        )
        typer.echo(dump_json(report), nl=False)

    app.add_typer(metrics_app, name="metrics")
