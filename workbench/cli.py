"""The ``workbench`` command.

Bad input (a missing file, a malformed line, an unknown name, a bad ``--set`` key) prints
one ``error: ...`` line and exits with status 2; no traceback unless ``WORKBENCH_DEBUG=1``.
"""

from __future__ import annotations

import importlib
import os
import sys
import traceback
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import typer
from typer.exceptions import TyperException

from datasets.errors import InputError
from datasets.options import parse_assignments
from workbench.completion import dataset_names, estimator_names
from workbench.estimator_settings import settings_by_estimator
from workbench.owned_folders import COLLECTION, RUN, check_writable, claim_collection, exclusive
from workbench.plot_formats import parse_plot_formats
from workbench.registry import DATASETS, ESTIMATORS

app = typer.Typer(
    add_completion=True,
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


def _version(value: bool) -> None:
    if value:
        from importlib.metadata import version

        typer.echo(f"workbench {version('slam-workbench')}")
        raise typer.Exit()


@app.callback()
def _main_options(
    version: Annotated[
        bool,
        typer.Option(
            "--version", callback=_version, is_eager=True, help="print the version and exit"
        ),
    ] = False,
) -> None:
    """Compare SLAM filters and smoothers on the same measurements."""


SetOption = Annotated[
    list[str] | None,
    typer.Option("--set", help="estimator option key=value or ESTIMATOR.key=value (repeatable)"),
]
DataOption = Annotated[
    list[str] | None, typer.Option("--data", help="dataset option key=value (repeatable)")
]


@dataclass(frozen=True)
class _Listed:
    """One line of ``workbench list``: a name, its summary, and how to get its options."""

    section: str
    name: str
    summary: str
    options: Callable[[], list[str]]


def _block_of(lines: list[str], name: str, names: tuple[str, ...]) -> list[str]:
    """The part of a family's option lines about ``name`` (the simulator describes its
    scenarios one after the other, each headed ``NAME: ...``); all of them otherwise."""
    if len(names) < 2:
        return lines
    starts = [i for i, line in enumerate(lines) if line.startswith(f"{name}: ")]
    if not starts:
        return lines
    end = next(
        (i for i in range(starts[0] + 1, len(lines)) if not lines[i].startswith(" ")), len(lines)
    )
    return lines[starts[0] : end]


def _listed() -> list[_Listed]:
    from datasets.options import describe_model
    from workbench.suite_files import builtin_suites, get_suite

    items = []
    for entry in DATASETS:
        names = entry.examples or (
            (entry.prefix + (f":{entry.argument}" if entry.argument else "")),
        )
        for name in names:
            items.append(
                _Listed(
                    "datasets",
                    name,
                    entry.summary,
                    lambda entry=entry, name=name, names=names: _block_of(
                        entry.describe(), name, names
                    ),
                )
            )

    def lidar_corridor_options() -> list[str]:
        from datasets.synthetic_lidar import describe

        return describe()

    items.append(
        _Listed(
            "simulate-only scenarios (workbench simulate NAME)",
            "lidar-corridor",
            "synthetic lidar bag (ROS 1/ROS 2) of a corridor world, read back as bag:PATH",
            lidar_corridor_options,
        )
    )
    for entry in ESTIMATORS:
        items.append(
            _Listed(
                "estimators",
                entry.name,
                entry.summary,
                lambda entry=entry: describe_model(entry.load().Config),
            )
        )
    for name in builtin_suites():
        items.append(
            _Listed(
                "suites (workbench bench NAME; workbench suite NAME prints its YAML)",
                name,
                get_suite(name).description,
                lambda name=name: [
                    f"{spec.title}: {spec.name}" for spec in get_suite(name).datasets
                ],
            )
        )
    return items


@app.command("list")
def list_command(
    name: Annotated[
        str | None,
        typer.Argument(help="only the entries whose name contains this, with their options"),
    ] = None,
    verbose: Annotated[
        bool, typer.Option("--verbose", "-v", help="the options of every entry")
    ] = False,
) -> None:
    """List datasets, estimators and suites, one line each (with NAME: those matching it, and their options)."""
    items = _listed()
    if name is not None:
        exact = [item for item in items if item.name == name]
        items = exact or [item for item in items if name in item.name]
        if not items:
            known = ", ".join(item.name for item in _listed())
            raise InputError(f"list: nothing is called '{name}' or contains it (known: {known})")
    section = None
    for item in items:
        if item.section != section:
            section = item.section
            typer.echo(f"{section}:")
        typer.echo(f"  {item.name:<42} {item.summary}")
        if verbose or name is not None:
            for line in item.options():
                typer.echo(f"      {line}")


@app.command("simulate")
def simulate_command(
    scenario: Annotated[
        str, typer.Argument(help="scenario name, e.g. aghili-rover (see `workbench list`)")
    ],
    out: Annotated[Path, typer.Option("--out", help="output folder (bag path for lidar-corridor)")],
    seed: Annotated[int, typer.Option("--seed", help="random seed", min=0)] = 0,
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
        typer.echo(f"wrote {path} (score against its truth with --truth-topic /ground_truth)")
        return
    else:
        from datasets.simulation.folder_format import write_sequence_folder
        from datasets.simulation.scenarios import load_scenario

        with exclusive(out):
            check_writable(out, COLLECTION)
            sequence = load_scenario(scenario, seed, options)
            path = write_sequence_folder(sequence, claim_collection(out))
    typer.echo(f"wrote {path}")


@app.command("run")
def run_command(
    estimator: Annotated[
        str,
        typer.Argument(
            help="estimator name (see `workbench list`)", autocompletion=estimator_names
        ),
    ],
    dataset: Annotated[
        str,
        typer.Argument(help="dataset name, e.g. sim:aghili-rover", autocompletion=dataset_names),
    ],
    out: Annotated[Path, typer.Option("--out", help="run folder to write")],
    seed: Annotated[
        int | None,
        typer.Option("--seed", help="random seed of the dataset (default 0, or --config's)", min=0),
    ] = None,
    config: Annotated[
        Path | None,
        typer.Option(
            "--config",
            help="estimator options as YAML, or a run folder's config.yaml (its seed and data "
            "options too; flags given here override them)",
        ),
    ] = None,
    set_: SetOption = None,
    data: DataOption = None,
    plots: Annotated[bool, typer.Option("--plots/--no-plots", help="write figures")] = True,
    plot_format: Annotated[
        str, typer.Option("--plot-format", help="figure formats, comma-separated: png, pdf, svg")
    ] = "png",
) -> None:
    """Run one estimator on one dataset and write the run folder."""
    from workbench.progress import sequence_progress
    from workbench.run_folder import dump_json, write_run_folder
    from workbench.runner import RunRequest, execute, recorded_run

    plot_formats = parse_plot_formats(plot_format)  # checked before the run, not after
    data_options = parse_assignments(data or [], "--data")
    recorded = None if config is None else recorded_run(config)
    if recorded is not None:
        # a run folder's config.yaml reproduces that run: its seed and data options too,
        # unless given here (and what is given here is said)
        if recorded.estimator != estimator:
            raise InputError(
                f"--config {config} records a run of {recorded.estimator}, not {estimator}: "
                f"its options are {recorded.estimator}'s (workbench rerun runs it again)"
            )
        overridden = [f"--seed {seed}"] if seed is not None and seed != recorded.seed else []
        overridden += [
            f"--data {key}={value}"
            for key, value in data_options.items()
            if dict(recorded.data_options).get(key) != value
        ]
        if dataset != recorded.dataset:
            overridden.append(f"dataset {dataset} (it ran on {recorded.dataset})")
        data_options = {**dict(recorded.data_options), **data_options}
        seed = recorded.seed if seed is None else seed
        taken = ", ".join(
            [f"seed {recorded.seed}"] + [f"{key}={value}" for key, value in recorded.data_options]
        )
        typer.echo(
            f"--config {config}: the recorded run ({taken})"
            + (f"; given here: {', '.join(overridden)}" if overridden else ""),
            err=True,
        )
    request = RunRequest(
        estimator=estimator,
        dataset=dataset,
        seed=0 if seed is None else seed,
        config_file=config,
        overrides=tuple(settings_by_estimator(set_ or [], [estimator])[estimator].items()),
        data_options=tuple(data_options.items()),
    )
    with exclusive(out):
        check_writable(out, RUN)  # before the run, not after it
        with sequence_progress(disable=not sys.stderr.isatty()) as progress:
            task = progress.add_task(f"{estimator} on {dataset}", total=None)
            result = execute(request, on_step=lambda t: progress.update(task, completed=t))
        metrics = write_run_folder(result, out, plot_formats if plots else ())
    shown = {
        key: value
        for key, value in metrics.items()
        if not isinstance(value, dict) and key not in ("warnings", "decisions")
    }
    typer.echo(dump_json(shown), nl=False)
    for line in metrics.get("decisions") or ():
        typer.echo(f"note: {dataset}: {line}", err=True)
    for line in metrics["warnings"]:
        typer.echo(f"warning: {line}", err=True)
    typer.echo(f"run folder: {out}")


@app.command("rerun")
def rerun_command(
    run_dir: Annotated[Path, typer.Argument(help="a run folder (its config.yaml)")],
    out: Annotated[Path, typer.Option("--out", help="run folder to write")],
    plots: Annotated[bool, typer.Option("--plots/--no-plots", help="write figures")] = True,
) -> None:
    """Run again what a run folder's config.yaml records: estimator, dataset, seed, data
    options and the resolved estimator options."""
    from workbench.run_files import CONFIG_FILE
    from workbench.run_folder import write_run_folder
    from workbench.runner import RunRequest, execute, recorded_run

    config_file = Path(run_dir) / CONFIG_FILE
    if not config_file.is_file():
        raise InputError(f"{run_dir}: not a run folder (no config.yaml)")
    recorded = recorded_run(config_file)
    if recorded is None:
        raise InputError(
            f"{config_file}: not a run folder's config.yaml (needs estimator, dataset, seed, "
            "config)"
        )
    request = RunRequest(
        estimator=recorded.estimator,
        dataset=recorded.dataset,
        seed=recorded.seed,
        config_file=config_file,
        data_options=recorded.data_options,
    )
    with exclusive(out):
        check_writable(out, RUN)
        metrics = write_run_folder(execute(request), out, ("png",) if plots else ())
    for line in metrics.get("decisions") or ():
        typer.echo(f"note: {recorded.dataset}: {line}", err=True)
    for line in metrics["warnings"]:
        typer.echo(f"warning: {line}", err=True)
    typer.echo(f"run folder: {out}")


@app.command("config")
def config_command(
    estimator: Annotated[
        str,
        typer.Argument(
            help="estimator name (see `workbench list`)", autocompletion=estimator_names
        ),
    ],
) -> None:
    """Print an estimator's default options as YAML, each with its description as a comment
    (edit it, pass it with --config)."""
    from workbench.registry import estimator_entry

    defaults = estimator_entry(estimator).load().Config()
    typer.echo(commented_yaml(defaults), nl=False)


def commented_yaml(config) -> str:
    """``config`` (a pydantic model) as YAML, every field preceded by its description as
    ``#`` comment lines (wrapped at 90 columns); loads back to the same values."""
    import textwrap

    import yaml

    values = config.model_dump(mode="json")
    blocks = []
    for name, field in type(config).model_fields.items():
        lines = textwrap.wrap(field.description or "", 88) if field.description else []
        comment = "".join(f"# {line}\n" for line in lines)
        blocks.append(comment + yaml.safe_dump({name: values[name]}, sort_keys=False))
    return "".join(blocks)


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
        # without standalone mode click *returns* the code of a typer.Exit (bench's 3 when a
        # run failed) instead of exiting with it
        status = command.main(args=argv, prog_name="workbench", standalone_mode=False)
    except InputError as error:
        # one line whatever the message holds (a library's multi-line text folded)
        print(f"error: {' '.join(str(error).split())}", file=sys.stderr)
        return 2
    except typer.Exit as exit_request:
        return int(exit_request.exit_code or 0)
    except typer.Abort:
        print("error: aborted", file=sys.stderr)
        return 130
    except TyperException as error:  # usage errors: unknown command, missing option, bad value
        print(f"error: {error.format_message()}", file=sys.stderr)
        return int(getattr(error, "exit_code", 2) or 2)
    except OSError as error:  # the machine, not the workbench: a full disk, a read-only folder
        if os.environ.get("WORKBENCH_DEBUG"):
            traceback.print_exc()
        where = f"{error.filename}: " if error.filename else ""
        print(f"error: {where}{error.strerror or error}", file=sys.stderr)
        return 2
    except Exception as error:  # noqa: BLE001 - the CLI never shows a bare traceback
        if os.environ.get("WORKBENCH_DEBUG"):
            traceback.print_exc()
        print(
            f"error: internal error: {type(error).__name__}: {error} (WORKBENCH_DEBUG=1 shows the traceback)",
            file=sys.stderr,
        )
        return 1
    return status if isinstance(status, int) else 0


if __name__ == "__main__":
    sys.exit(main())
