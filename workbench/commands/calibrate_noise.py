"""``workbench calibrate-noise DATASET``: fit a planar dataset's odometry noise model
(variances growing with time, distance and turn; ``datasets.odometry_noise``) against its
truth, or against the batch smoother where it has none (``workbench.calibration``)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from datasets.options import parse_assignments


def register(app: typer.Typer) -> None:
    @app.command("calibrate-noise")
    def calibrate_noise_command(
        dataset: Annotated[str, typer.Argument(help="a planar dataset with odometry")],
        data: Annotated[
            list[str] | None, typer.Option("--data", help="dataset option key=value (repeatable)")
        ] = None,
        reference: Annotated[
            str,
            typer.Option(
                "--reference",
                help="auto (truth when the dataset has it), truth, or smoother (the batch "
                "smoother's estimate, iterated)",
            ),
        ] = "auto",
        window_s: Annotated[
            float, typer.Option("--window-s", help="fitting window [s]", min=0.1)
        ] = 5.0,
        iterations: Annotated[
            int, typer.Option("--iterations", help="smoother reference: fit/re-run rounds", min=1)
        ] = 3,
        out: Annotated[
            Path | None,
            typer.Option("--out", help="write the model as YAML (--data odometry_noise=FILE)"),
        ] = None,
        seed: Annotated[int, typer.Option("--seed", help="dataset seed (simulations)", min=0)] = 0,
    ) -> None:
        """Fit the odometry noise model of DATASET and print it with its check at other
        window lengths."""
        from workbench.calibration.calibrate import calibrate
        from workbench.registry import load_dataset
        from workbench.runner import RunRequest, execute

        base = parse_assignments(data or [], "--data")

        def load(extra: dict[str, str]):
            return load_dataset(dataset, seed, {**base, **extra})

        def smoother(sequence):
            result = execute(RunRequest("smoother-batch", dataset, seed), sequence=sequence)
            smoothed = result.estimate.smoothed
            if smoothed is None or smoothed.pose is None:
                raise RuntimeError("smoother-batch returned no smoothed trajectory")
            return smoothed.pose

        calibration = calibrate(dataset, load, reference, window_s, iterations, smoother)
        for line in calibration.lines(dataset):
            typer.echo(line)
        if out is not None:
            calibration.write(out, dataset)
            typer.echo(f"wrote {out} (use it with --data odometry_noise={out})")
