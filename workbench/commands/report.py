"""``workbench report RUN_DIR... [--out DIR]``: one table and the figures of any run folders
(from different suites, bags, days): the same tables and plots a suite writes
(``workbench.reporting``)."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated

import typer

from workbench.plot_formats import parse_plot_formats


def register(app: typer.Typer) -> None:
    @app.command("report")
    def report_command(
        paths: Annotated[
            list[Path], typer.Argument(help="run folders, or folders holding run folders")
        ],
        out: Annotated[Path, typer.Option("--out", help="where the tables and plots go")] = Path(
            "report"
        ),
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
    ) -> None:
        """Compare any run folders in one table (Markdown, LaTeX, CSV) and figures."""
        from workbench.commands.bench import show_report
        from workbench.owned_folders import claim_collection, exclusive
        from workbench.reporting import write_report
        from workbench.results.runs import load_runs

        formats = parse_plot_formats(plot_format) if plots else ()
        records = load_runs(paths)
        with exclusive(out):
            report = write_report(
                records, claim_collection(out), plot_formats=formats, seed=seed, reference=reference
            )
        show_report(report, f"{len(records)} run(s)")
