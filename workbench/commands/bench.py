"""``workbench bench [SUITE|FILE.yaml] --runs N --out DIR [--scheduler ADDRESS] [--workers K]``
and ``workbench suite NAME`` (a built-in suite's YAML, to copy and edit).

Runs a suite (``workbench.suite_files``) as a Monte Carlo sweep (``workbench.sweep``), then
writes ``DIR/table.md``, ``table.csv``, the LaTeX tables ``--table`` (or the suite's
``table:``) chooses (``table.tex``, ``table_NAME.tex``: ``workbench.results.tables``) and the
figures in ``DIR/plots/`` (``workbench.report_plots``), and prints the terminal tables with
their legend (``show_report``) and where the files are. Re-running the same command
resumes: finished runs are not redone.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated

import typer

from datasets.errors import InputError
from workbench.completion import estimator_names, suite_names
from workbench.estimator_settings import settings_by_estimator
from workbench.plot_formats import parse_plot_formats
from workbench.reporting import Report
from workbench.results.columns import TABLE_HELP
from workbench.suite_files import (
    DEFAULT_SUITE,
    builtin_suites,
    get_suite,
    suite_path,
    suite_table,
)
from workbench.suites import Suite, restrict, with_settings


def bench(
    suite_name: str,
    runs: int | None,
    out: Path,
    scheduler: str | None = None,
    workers: int | None = None,
    plots: bool = True,
    run_plots: bool = False,
    show_progress: bool | None = None,
    report_only: bool = False,
    datasets: list[str] | None = None,
    estimators: list[str] | None = None,
    plot_formats: tuple[str, ...] = ("png",),
    settings: list[str] | None = None,
    table: str | None = None,
) -> BenchOutcome:
    """Run the suite and write tables and plots (in each of ``plot_formats``).
    ``report_only``: run nothing, report the runs on disk (no dataset is probed).
    ``datasets`` / ``estimators``: only these of the suite (names or labels).
    ``settings``: ``--set`` options, ``ESTIMATOR.key=value`` (``key=value`` when the suite
    runs one estimator). ``table``: the LaTeX tables (``results.columns.parse_table_choice``;
    default: the suite file's ``table:``, else all presets). ``out`` must be new, empty or an
    earlier output of the workbench's (``workbench.owned_folders``); it is locked while the
    suite runs."""
    from workbench.owned_folders import claim_collection, exclusive
    from workbench.results.columns import parse_table_choice

    suite = restrict(get_suite(suite_name), datasets, estimators)
    table = table or suite_table(suite_name)
    parse_table_choice(table)  # a bad --table is an error before anything runs
    names = list(dict.fromkeys(spec.name for spec in suite.estimators))
    suite = with_settings(suite, settings_by_estimator(settings or [], names))
    runs = suite.default_runs if runs is None else runs
    out = Path(out).resolve()
    if scheduler is not None:
        from workbench.sweep.backends import check_scheduler_address

        check_scheduler_address(scheduler)  # before --out is created
    with exclusive(out):
        claim_collection(out)
        return _bench(
            suite,
            runs,
            out,
            scheduler,
            workers,
            plots,
            run_plots,
            show_progress,
            report_only,
            plot_formats,
            table,
        )


def _bench(
    suite: Suite,
    runs: int,
    out: Path,
    scheduler: str | None,
    workers: int | None,
    plots: bool,
    run_plots: bool,
    show_progress: bool | None,
    report_only: bool,
    plot_formats: tuple[str, ...],
    table: str,
) -> BenchOutcome:
    from workbench.progress import count_progress
    from workbench.reporting import write_report
    from workbench.results.runs import load_runs, read_run
    from workbench.results.summary import PlannedPair
    from workbench.sweep import pending_cells, run_sweep
    from workbench.sweep.backends import make_backend
    from workbench.sweep.plan import pairs_on_disk, plan_sweep

    formats = plot_formats if plots else ()
    if report_only:
        # what is on disk, in the suite's order with its left-out pairs, without probing
        # any dataset again
        records = load_runs([out / "runs"])
        labels = {(record.dataset_label, record.estimator_label) for record in records}
        pairs = pairs_on_disk(suite, runs, labels)
        report = write_report(
            records, out, pairs, plot_formats=formats, reference=suite.reference, table=table
        )
        return BenchOutcome(report, failed=sum(1 for r in report.rows for _ in r.errors()))
    interactive = sys.stderr.isatty() if show_progress is None else show_progress
    backend = make_backend(scheduler, workers)
    try:
        started = time.perf_counter()
        plan = plan_sweep(suite, runs, out, backend)
        for note in plan.notes:
            typer.echo(f"note: {note}", err=True)
        pending, done = pending_cells(plan)
        typer.echo(
            f"suite {suite.name}: {len(plan.cells)} runs ({done} already done, {len(pending)} to run) on {backend.describe()}",
            err=True,
        )
        with count_progress(not interactive, unit="runs", remaining=True) as progress:
            task = progress.add_task(f"bench {suite.name}", total=len(pending))

            def on_done(cell, outcome) -> None:
                progress.advance(task)
                if not interactive:
                    status = f"failed: {outcome.error}" if outcome.error else "done"
                    finished = int(progress.tasks[0].completed)
                    typer.echo(
                        f"[{finished}/{len(pending)}] {cell.describe()}: {status} ({outcome.seconds:.1f} s)",
                        err=True,
                    )

            planned = time.perf_counter()
            summary = run_sweep(
                plan,
                backend,
                run_plot_formats=plot_formats if run_plots else (),
                on_done=on_done,
                cells=pending,
            )
        swept = time.perf_counter()
        records = [
            read_run(cell.folder)
            for cell in plan.cells
            if cell.is_finished() or (cell.folder / "error.json").is_file()
        ]
        pairs = [
            PlannedPair(
                dataset.title,
                estimator.title,
                estimator.name,
                len(plan.cells_of(dataset, estimator)),
                plan.not_applicable_reason(dataset, estimator),
            )
            for dataset in plan.datasets
            for estimator in plan.estimators
        ]
        report = write_report(
            records,
            out,
            pairs,
            list(plan.notes),
            formats,
            submit=backend.submit,
            reference=suite.reference,
            table=table,
        )
        failed = sum(1 for record in records if not record.finished)
        # two lines: one would not fit a 100-column terminal
        typer.echo(
            f"{summary.ran} run(s) done, {summary.skipped} skipped (finished before), "
            f"{failed} failed; {time.perf_counter() - started:.1f} s",
            err=True,
        )
        typer.echo(
            f"  (planning {planned - started:.1f} s, runs {swept - planned:.1f} s, "
            f"tables and plots {time.perf_counter() - swept:.1f} s)",
            err=True,
        )
        return BenchOutcome(report, failed)
    finally:
        backend.close()


@dataclass(frozen=True)
class BenchOutcome:
    """What a bench wrote (``report``) and how many of its runs failed."""

    report: Report
    failed: int

    @property
    def tables(self) -> dict[str, Path]:
        return self.report.tables


def register(app: typer.Typer) -> None:
    @app.command("bench")
    def bench_command(
        suite: Annotated[
            str,
            typer.Argument(
                help=f"a built-in suite ({', '.join(builtin_suites())}) or a suite .yaml file (`workbench suite NAME` prints one to copy)",
                autocompletion=suite_names,
            ),
        ] = DEFAULT_SUITE,
        runs: Annotated[
            int | None,
            typer.Option(
                "--runs", help="Monte Carlo runs (seeds) per pair; default: the suite's", min=1
            ),
        ] = None,
        out: Annotated[
            Path | None, typer.Option("--out", help="output folder (default: runs/<suite>)")
        ] = None,
        scheduler: Annotated[
            str | None,
            typer.Option("--scheduler", help="Dask scheduler address (default: local processes)"),
        ] = None,
        workers: Annotated[
            int | None,
            typer.Option("--workers", help="local worker processes (default: CPU count)"),
        ] = None,
        plots: Annotated[
            bool, typer.Option("--plots/--no-plots", help="write the comparison figures")
        ] = True,
        run_plots: Annotated[
            bool,
            typer.Option("--run-plots", help="also write each run folder's own figures (slower)"),
        ] = False,
        report_only: Annotated[
            bool,
            typer.Option("--report-only", help="run nothing: table and plots of the runs on disk"),
        ] = False,
        plot_format: Annotated[
            str,
            typer.Option("--plot-format", help="figure formats, comma-separated: png, pdf, svg"),
        ] = "png",
        dataset: Annotated[
            list[str] | None,
            typer.Option("--dataset", help="only this dataset of the suite (repeatable)"),
        ] = None,
        estimator: Annotated[
            list[str] | None,
            typer.Option(
                "--estimator",
                help="only this estimator of the suite (repeatable)",
                autocompletion=estimator_names,
            ),
        ] = None,
        set_: Annotated[
            list[str] | None,
            typer.Option(
                "--set",
                help="estimator option ESTIMATOR.key=value (key=value when the suite runs one estimator; repeatable); the label says what was set",
            ),
        ] = None,
        table: Annotated[
            str | None,
            typer.Option(
                "--table",
                help=TABLE_HELP + "; default: the suite's `table:`, else all",
            ),
        ] = None,
    ) -> None:
        """Run a benchmark suite: every estimator on every dataset it can run on, N seeds,
        then the comparison table and plots. Re-running resumes."""
        if workers is not None and workers < 1:
            raise InputError(f"--workers must be at least 1, got {workers}")
        outcome = bench(
            suite,
            runs,
            out or Path("runs") / Path(suite).stem,
            scheduler,
            workers,
            plots,
            run_plots,
            report_only=report_only,
            datasets=dataset,
            estimators=estimator,
            plot_formats=parse_plot_formats(plot_format),
            settings=set_,
            table=table,
        )
        show_report(outcome.report, f"suite {Path(suite).stem}")
        if outcome.failed:
            typer.echo(f"error: {outcome.failed} run(s) failed (listed under the table)", err=True)
            raise typer.Exit(3)  # the tables are written; 1 is kept for bugs, 2 for bad input

    @app.command("suite")
    def suite_command(
        name: Annotated[
            str,
            typer.Argument(
                help=f"a built-in suite: {', '.join(builtin_suites())}", autocompletion=suite_names
            ),
        ],
    ) -> None:
        """Print a suite's YAML file: copy it, edit it, run it with `workbench bench FILE.yaml`."""
        path = suite_path(name)
        get_suite(name)  # a broken file is reported here, not when it is run
        typer.echo(path.read_text(encoding="utf-8"), nl=False)


def show_report(report: Report, title: str) -> None:
    """The compact terminal tables, their legend, the notes, and where the files are.

    Rich decides the width: the terminal's, ``COLUMNS`` when set, 80 for a pipe; tables
    close up or split to fit it (``terminal_tables``) and the legend wraps. Notes stay one
    line each, as they are in table.md: a log is searched by them."""
    from rich.console import Console
    from rich.text import Text

    from workbench.results.tables import TERMINAL_LEGEND, table_notes, terminal_tables

    console = Console(highlight=False)
    for table in terminal_tables(report.rows, title, console.width):
        console.print(table)
    console.print(Text(TERMINAL_LEGEND))
    for note in table_notes(report.rows, report.notes):
        typer.echo(f"- {note}")
    tex = [path.name for key, path in report.tables.items() if key.startswith("tex:")]
    # paths are never wrapped: they are copied from here
    if "md" in report.tables:
        typer.echo(f"table: {report.tables['md']}")
        typer.echo(f"  (.csv: every column; LaTeX: {', '.join(['table.tex', *tex])})")
    if report.plots is not None:
        typer.echo(f"plots: {report.plots}")
