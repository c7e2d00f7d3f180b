"""Tables and figures of any set of runs, the same for ``workbench bench``, ``workbench
report`` and ``workbench bag``: rows per pair (``results.summary``), ``table.md``,
``table.csv``, ``table.tex`` and one ``table_NAME.tex`` per chosen LaTeX table
(``results.tables``, ``results.latex``) and ``plots/<dataset>/`` per dataset
(``report_plots``). ``workbench.paper_pack`` builds on the same rows."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from workbench.plot_formats import DEFAULT_PLOT_FORMATS
from workbench.results.columns import DEFAULT_TABLE
from workbench.results.experiments import split_experiments
from workbench.results.runs import RunRecord
from workbench.results.summary import PairSummary, PlannedPair, summarize
from workbench.results.tables import write_tables
from workbench.suites import slug


@dataclass(frozen=True)
class Report:
    """What a report wrote: the rows, the table files by key (``write_tables``), the plots
    folder (None without figures), and the notes under the table."""

    rows: list[PairSummary]
    tables: dict[str, Path]
    plots: Path | None
    notes: list[str]


@dataclass(frozen=True)
class ReportRows:
    """What a report shows: the records relabelled one experiment per row
    (``split_experiments``), the rows, and the notes (the caller's, then what was split and
    what the reference ratio is)."""

    records: list[RunRecord]
    rows: list[PairSummary]
    notes: list[str]

    def dataset_folders(self) -> dict[str, list[Path]]:
        """The finished runs' folders by dataset label, in row order (one figure set each)."""
        found: dict[str, list[Path]] = {}
        for record in self.records:
            if record.finished:
                found.setdefault(record.dataset_label, []).append(record.folder)
        return found


def report_rows(
    records: list[RunRecord],
    planned: list[PlannedPair] | None = None,
    notes: list[str] = (),
    reference: str | None = None,
) -> ReportRows:
    """The rows of ``records`` (``write_report``'s arguments of the same names)."""
    records, split = split_experiments(records)  # one row, one experiment
    notes = [*notes, *split]
    rows = summarize(records, planned, reference)
    if reference is not None and any("ate_over_reference" in row.stats for row in rows):
        notes = [
            *notes,
            f"ATE ÷ ref: each row's ATE over {reference}'s on the same dataset, causal over "
            "causal (smoothed over smoothed for an estimator with no causal estimate)",
        ]
    return ReportRows(records, rows, list(notes))


def write_report(
    records: list[RunRecord],
    out: Path,
    planned: list[PlannedPair] | None = None,
    notes: list[str] = (),
    plot_formats: tuple[str, ...] = DEFAULT_PLOT_FORMATS,
    seed: int | None = None,
    submit: Callable[..., Any] | None = None,
    reference: str | None = None,
    table: str = DEFAULT_TABLE,
) -> Report:
    """Tables of ``records`` into ``out`` and, unless ``plot_formats`` is empty, the figures
    of each dataset into ``out/plots/<dataset>`` (``seed``: the run the per-run figures
    show, the first by default; ``submit``: a backend's submit to draw datasets in
    parallel; ``reference``: an estimator every row's ATE is divided by, per dataset;
    ``table``: the LaTeX tables, ``results.columns.parse_table_choice``)."""
    from workbench.report_plots import write_dataset_plots

    out = Path(out)
    found = report_rows(records, planned, notes, reference)
    rows, notes = found.rows, found.notes
    tables = write_tables(rows, out, list(notes), table)
    if not plot_formats:
        return Report(rows, tables, None, list(notes))
    jobs = []
    for dataset, folders in found.dataset_folders().items():
        arguments = (folders, dataset, out / "plots" / slug(dataset), plot_formats, seed)
        jobs.append(
            submit(write_dataset_plots, *arguments) if submit else write_dataset_plots(*arguments)
        )
    if submit:
        for job in jobs:
            job.result()
    return Report(rows, tables, out / "plots", list(notes))
