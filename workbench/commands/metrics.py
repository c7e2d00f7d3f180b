"""``workbench metrics ate|rpe``: evaluate any pair of trajectory files (TUM, or KITTI poses
paired by index; which one a file is, its rows say) and print JSON. ``workbench metrics
relations``: score a TUM trajectory against a relations file (``workbench.metrics.relations``)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Annotated

import typer

from datasets.errors import InputError
from datasets.state import Relations
from datasets.trajectory import Trajectory
from datasets.trajectory_io import read_kitti, read_tum, trajectory_format

ALIGNMENTS = ("se3", "sim3", "se2", "none")

RefOption = Annotated[
    Path, typer.Option("--ref", help="reference trajectory (TUM or KITTI poses, told by its rows)")
]
EstOption = Annotated[
    Path, typer.Option("--est", help="estimated trajectory (TUM or KITTI poses, told by its rows)")
]
AlignOption = Annotated[str, typer.Option("--align", help="alignment: se3, sim3, se2 or none")]
MaxDiffOption = Annotated[
    float, typer.Option("--max-diff", help="max time difference when pairing stamps [s]")
]


DEFAULT_RELATIONS_MAX_DIFF_S = 0.01
"""``workbench.metrics.relations.DEFAULT_MAX_DIFF_S`` (evo's), repeated so that ``--help``
does not import the metrics."""


def _check_align(align: str) -> None:
    if align not in ALIGNMENTS:
        raise InputError(f"--align must be one of {', '.join(ALIGNMENTS)}, got '{align}'")


def _check_positive(name: str, value: float) -> None:
    if not (value > 0 and math.isfinite(value)):
        raise InputError(f"{name} must be a positive number, got {value}")


def read_pair(ref: Path, est: Path) -> tuple[Trajectory, Trajectory]:
    """The two trajectories to compare. TUM files keep their stamps (paired by time within
    ``--max-diff``). KITTI poses carry no time, so a KITTI file is never paired by seconds:
    it is paired with the other file pose by pose, which needs equally many poses (a pose
    missing in the middle would shift every later pair), and takes the other's stamps when
    that is a TUM file (the pose index otherwise)."""
    formats = (trajectory_format(ref), trajectory_format(est))
    if "kitti" not in formats:
        return read_tum(ref), read_tum(est)
    pair = [
        read_kitti(path) if kind == "kitti" else read_tum(path)
        for path, kind in zip((ref, est), formats)
    ]
    if len(pair[0]) != len(pair[1]):
        raise InputError(
            f"--ref {ref} holds {len(pair[0])} poses and --est {est} holds {len(pair[1])}: "
            "KITTI poses carry no time and pair by index, which needs equally many poses; "
            "give TUM files (with times) to pair by time"
        )
    times = pair[formats.index("tum")].t if "tum" in formats else pair[0].t
    return Trajectory(times, pair[0].positions, pair[0].rotations), Trajectory(
        times, pair[1].positions, pair[1].rotations
    )


def register(app: typer.Typer) -> None:
    metrics_app = typer.Typer(
        help="Evaluate trajectory files, TUM or KITTI poses (prints JSON).", no_args_is_help=True
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
        report = ate_report(*read_pair(ref, est), align=align, max_diff_s=max_diff)
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
            *read_pair(ref, est),
            delta=delta,
            unit=unit,
            align=align,
            max_diff_s=max_diff,
        )
        typer.echo(dump_json(report), nl=False)

    @metrics_app.command("relations")
    def relations_command(
        est: Annotated[
            Path, typer.Option("--est", help="estimated trajectory (TUM: relations pair times)")
        ],
        relations: Annotated[
            Path,
            typer.Option("--relations", help="relations file: t1 t2 x y z roll pitch yaw per line"),
        ],
        max_diff: Annotated[
            float,
            typer.Option(
                "--max-diff", help="max time difference between a relation's time and a pose [s]"
            ),
        ] = DEFAULT_RELATIONS_MAX_DIFF_S,
    ) -> None:
        """Relations error (Kuemmerle et al. 2009): mean, std and squared translational and
        rotational error of the estimate's relative poses, relations used and skipped."""
        from workbench.metrics.relations import read_relations
        from workbench.run_folder import dump_json

        _check_positive("--max-diff", max_diff)
        typer.echo(dump_json(relations_report(est, read_relations(relations), max_diff)), nl=False)

    app.add_typer(metrics_app, name="metrics")


def relations_report(est: Path, relations: Relations, max_diff_s: float) -> dict[str, object]:
    """The JSON of ``workbench metrics relations``: ``RelationsResult.report()``.

    A relation pairs two times, so the estimate must carry stamps: a KITTI pose file (no
    time) is refused. ``InputError`` too when no relation could be scored, naming both files
    and why the relations were skipped (a time base that differs between the files, most
    likely), rather than a report of nothing.
    """
    from workbench.metrics.relations import relation_errors

    if trajectory_format(est) == "kitti":
        raise InputError(
            f"--est {est}: KITTI poses carry no time, and relations pair times: "
            "give the estimate as a TUM file"
        )
    estimate = read_tum(est)
    result = relation_errors(estimate, relations, max_diff_s)
    if result.used_count == 0:
        raise InputError(
            f"--relations {relations.source}: none of its {len(relations)} relations could be "
            f"scored on --est {est} ({result.skipped_text()}; relation times "
            f"{relations.times.min():.6f}..{relations.times.max():.6f} s, estimate "
            f"{estimate.t[0]:.6f}..{estimate.t[-1]:.6f} s, --max-diff {max_diff_s:g} s)"
        )
    return result.report()
