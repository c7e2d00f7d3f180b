"""``workbench report RUN_DIR... [--out DIR] [--table PRESET|COL,...] [--paper DIR]``: one
table and the figures of any run folders (from different suites, bags, days): the same
tables and plots a suite writes (``workbench.reporting``); with ``--paper``, a paper pack
(``workbench.paper_pack``: LaTeX tables, PDF figures, the evaluation protocol)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from workbench.plot_formats import parse_plot_formats
from workbench.results.columns import DEFAULT_TABLE, TABLE_HELP


def register(app: typer.Typer) -> None:
    @app.command("report")
    def report_command(
        paths: Annotated[
            list[Path], typer.Argument(help="run folders, or folders holding run folders")
        ],
        out: Annotated[
            Path | None,
            typer.Option(
                "--out",
                help="where the tables and plots go (default: report; with --paper: only if given)",
            ),
        ] = None,
        seed: Annotated[
            int | None,
            typer.Option("--seed", help="the run per-seed figures show (default: the first)"),
        ] = None,
        plots: Annotated[bool, typer.Option("--plots/--no-plots", help="write the figures")] = True,
        plot_format: Annotated[
            str,
            typer.Option("--plot-format", help="figure formats, comma-separated: png, pdf, svg"),
        ] = "png",
        reference: Annotated[
            str | None,
            typer.Option(
                "--reference",
                help="an estimator every row's ATE is divided by, per dataset (e.g. smoother-isam2)",
            ),
        ] = None,
        table: Annotated[str, typer.Option("--table", help=TABLE_HELP)] = DEFAULT_TABLE,
        paper: Annotated[
            Path | None,
            typer.Option(
                "--paper",
                help="write a paper pack here: tables/*.tex, figures/<dataset>/*.pdf, evaluation.tex",
            ),
        ] = None,
    ) -> None:
        """Compare any run folders in one table (Markdown, LaTeX, CSV) and figures; with
        --paper, the LaTeX tables, PDF figures and evaluation protocol for a paper."""
        from workbench.commands.bench import show_report
        from workbench.owned_folders import claim_collection, exclusive
        from workbench.paper_pack import write_paper_pack
        from workbench.reporting import write_report
        from workbench.results.columns import parse_table_choice
        from workbench.results.runs import load_runs

        formats = parse_plot_formats(plot_format) if plots else ()
        parse_table_choice(table)  # before any folder is read or written
        records = load_runs(paths)
        report = None
        if paper is None or out is not None:
            out = out or Path("report")
            with exclusive(out):
                report = write_report(
                    records,
                    claim_collection(out),
                    plot_formats=formats,
                    seed=seed,
                    reference=reference,
                    table=table,
                )
        if paper is not None:
            with exclusive(paper, "--paper"):
                pack = write_paper_pack(
                    records,
                    claim_collection(paper, "--paper"),
                    table=table,
                    figures=plots,
                    seed=seed,
                    reference=reference,
                )
            report = report or pack.report
        show_report(report, f"{len(records)} run(s)")
        if paper is not None:
            parts = [name for name in ("tables", "figures") if (paper / name).is_dir()]
            typer.echo(
                f"paper pack: {paper} ({len(pack.files)} files: "
                + ", ".join([f"{name}/" for name in parts] + ["evaluation.tex"])
                + ")"
            )
