"""The ``workbench`` command.

Bad input (a missing file, a malformed line, an unknown name, a bad ``--set`` key) prints
one ``error: ...`` line and exits with status 2; no traceback unless ``WORKBENCH_DEBUG=1``.
"""

from __future__ import annotations

import importlib
import os
import sys
import traceback
from pathlib import Path
from typing import Annotated

import typer
from typer.exceptions import TyperException

from datasets.errors import InputError
from datasets.options import parse_assignments
from workbench.plot_formats import parse_plot_formats
from workbench.registry import DATASETS, ESTIMATORS

app = typer.Typer(
    add_completion=False,
    no_args_is_help=True,
    help="Compare SLAM filters and smoothers on the same measurements.",
    pretty_exceptions_enable=False,
)

# Command groups defined in their own modules, each with ``register(app)`` (explicit list).
COMMAND_MODULES: tuple[str, ...] = (
    "workbench.commands.metrics",
    "workbench.commands.bench",
    "workbench.commands.bag",
    "workbench.commands.observability",
    "workbench.commands.bench_speed",
    "workbench.commands.report",
    "workbench.commands.calibrate_noise",
)

SetOption = Annotated[
    list[str] | None, typer.Option("--set", help="estimator option key=value (repeatable)")
]
DataOption = Annotated[
    list[str] | None, typer.Option("--data", help="dataset option key=value (repeatable)")
]


@app.command("list")
def list_command(
    verbose: Annotated[
        bool, typer.Option("--verbose", "-v", help="options of each dataset")
    ] = False,
) -> None:
    """List datasets and estimators, one line each."""
    typer.echo("datasets:")
    for entry in DATASETS:
        names = entry.examples or (
            (entry.prefix + (f":{entry.argument}" if entry.argument else "")),
        )
        for name in names:
            typer.echo(f"  {name:<42} {entry.summary}")
        if verbose:
            for line in entry.describe():
                typer.echo(f"      {line}")
    typer.echo("simulate-only scenarios (workbench simulate NAME):")
    typer.echo(
        f"  {'lidar-corridor':<42} synthetic lidar bag (ROS 1/ROS 2) of a corridor world, read back as bag:PATH"
    )
    if verbose:
        from datasets.synthetic_lidar import describe as describe_lidar_corridor

        for line in describe_lidar_corridor():
            typer.echo(f"      {line}")
    typer.echo("estimators:")
    for entry in ESTIMATORS:
        typer.echo(f"  {entry.name:<42} {entry.summary}")
        if verbose:
            from datasets.options import describe_model

            for line in describe_model(entry.load().Config):
                typer.echo(f"      {line}")


@app.command("simulate")
def simulate_command(
    scenario: Annotated[
        str, typer.Argument(help="scenario name, e.g. aghili-rover (see `workbench list`)")
    ],
    out: Annotated[Path, typer.Option("--out", help="output folder (bag path for lidar-corridor)")],
    seed: Annotated[int, typer.Option("--seed", help="random seed")] = 0,
    data: DataOption = None,
    format: Annotated[
        str, typer.Option("--format", help="lidar-corridor only: ros1 or ros2")
    ] = "ros1",
) -> None:
    """Simulate a scenario and write its measurements and ground truth."""
    options = parse_assignments(data or [], "--data")
    if scenario == "lidar-corridor":
        from datasets.synthetic_lidar import write_lidar_bag

        path = write_lidar_bag(out, seed, format, options)
    else:
        from datasets.simulation.folder_format import write_sequence_folder
        from datasets.simulation.scenarios import load_scenario

        path = write_sequence_folder(load_scenario(scenario, seed, options), out)
    typer.echo(f"wrote {path}")


@app.command("run")
def run_command(
    estimator: Annotated[str, typer.Argument(help="estimator name (see `workbench list`)")],
    dataset: Annotated[str, typer.Argument(help="dataset name, e.g. sim:aghili-rover")],
    out: Annotated[Path, typer.Option("--out", help="run folder to write")],
    seed: Annotated[int, typer.Option("--seed", help="random seed of the dataset")] = 0,
    config: Annotated[
        Path | None, typer.Option("--config", help="estimator options as YAML")
    ] = None,
    set_: SetOption = None,
    data: DataOption = None,
    plots: Annotated[bool, typer.Option("--plots/--no-plots", help="write figures")] = True,
    plot_format: Annotated[
        str, typer.Option("--plot-format", help="figure formats, comma-separated: png, pdf, svg")
    ] = "png",
) -> None:
    """Run one estimator on one dataset and write the run folder."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    from workbench.run_folder import dump_json, write_run_folder
    from workbench.runner import RunRequest, execute

    plot_formats = parse_plot_formats(plot_format)  # checked before the run, not after
    request = RunRequest(
        estimator=estimator,
        dataset=dataset,
        seed=seed,
        config_file=config,
        overrides=tuple(parse_assignments(set_ or [], "--set").items()),
        data_options=tuple(parse_assignments(data or [], "--data").items()),
    )
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn("t={task.completed:.1f} s"),
        TimeElapsedColumn(),
        transient=True,
        disable=not sys.stderr.isatty(),
    ) as progress:
        task = progress.add_task(f"{estimator} on {dataset}", total=None)
        result = execute(request, on_step=lambda t: progress.update(task, completed=t))
    metrics = write_run_folder(result, out, plot_formats if plots else ())
    shown = {
        key: value
        for key, value in metrics.items()
        if not isinstance(value, dict) and key != "warnings"
    }
    typer.echo(dump_json(shown), nl=False)
    for line in metrics["warnings"]:
        typer.echo(f"warning: {line}", err=True)
    typer.echo(f"run folder: {out}")


_registered: set[str] = set()


def _register_command_modules() -> None:
    for module_name in COMMAND_MODULES:
        if module_name not in _registered:  # main() may be called more than once in-process
            importlib.import_module(module_name).register(app)
            _registered.add(module_name)


def main(argv: list[str] | None = None) -> int:
    """Entry point of the ``workbench`` console script; returns the exit status."""
    _register_command_modules()
    command = typer.main.get_command(app)
    try:
        command.main(args=argv, prog_name="workbench", standalone_mode=False)
    except InputError as error:
        print(f"error: {error}", file=sys.stderr)
        return 2
    except typer.Exit as exit_request:
        return int(exit_request.exit_code or 0)
    except typer.Abort:
        print("error: aborted", file=sys.stderr)
        return 130
    except TyperException as error:  # usage errors: unknown command, missing option, bad value
        print(f"error: {error.format_message()}", file=sys.stderr)
        return int(getattr(error, "exit_code", 2) or 2)
    except Exception as error:  # noqa: BLE001 - the CLI never shows a bare traceback
        if os.environ.get("WORKBENCH_DEBUG"):
            traceback.print_exc()
        print(
            f"error: internal error: {type(error).__name__}: {error} (WORKBENCH_DEBUG=1 shows the traceback)",
            file=sys.stderr,
        )
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
