"""The comparison table of a sweep: one row per (dataset, estimator), in Markdown, LaTeX
(booktabs) and CSV.

Columns (``COLUMNS``, in this order):
    accuracy, mean +/- std over runs (sample std, ddof 1) of the ``metrics.json`` values:
        ATE RMSE of the causal estimate and of the smoothed one (smoothers), 1-frame RPE
        (translation, rotation), final orientation error (Aghili eq. (43)), RMSE against
        held-out GPS fixes (KITTI);
    consistency: the NEES of each block averaged over the runs (``monte_carlo``), averaged
        again over the steps, with the two-sided 95% chi-square interval of the per-step
        average (for landmarks, whose number varies, the median interval over the steps)
        and the percentage of steps inside it; mean NIS (mean +/- std over runs);
    map: landmarks in the final map (mean +/- std);
    cost, named ``time_*`` so that a comparison can leave them out: median and 99th
        percentile of the time per processed measurement [ms], and total run time [s].

Rows follow the suite's order (datasets, then estimators), so the table is deterministic.
A pair that cannot run says n/a (the reason is listed under the table); a pair with failed
runs shows the runs that finished, and the failures are listed.
"""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from datasets.trajectory_io import write_atomic
from workbench.results import PairResults, collect
from workbench.sweep.plan import Plan


@dataclass(frozen=True)
class Column:
    """A table column: key (CSV prefix), header, and where its value comes from.

    ``source`` is a ``metrics.json`` key (kind ``metric``), a NEES block (kind ``nees``) or
    ``landmarks`` (kind ``landmarks``).
    """

    key: str
    header: str
    kind: str
    source: str


COLUMNS: tuple[Column, ...] = (
    Column("ate_rmse_m", "ATE [m]", "metric", "ate_rmse_m"),
    Column("ate_smoothed_rmse_m", "ATE smoothed [m]", "metric", "ate_rmse_smoothed_m"),
    Column("rpe_trans_rmse_m", "RPE trans [m]", "metric", "rpe_trans_rmse_m"),
    Column("rpe_rot_rmse_deg", "RPE rot [deg]", "metric", "rpe_rot_rmse_deg"),
    Column(
        "final_orientation_error_deg",
        "final orient. [deg]",
        "metric",
        "final_orientation_error_deg",
    ),
    Column("gps_holdout_rmse_m", "GPS hold-out [m]", "metric", "gps_holdout_rmse_m"),
    Column("anees_pose", "ANEES pose", "nees", "pose"),
    Column("anees_velocity", "ANEES velocity", "nees", "velocity"),
    Column("anees_gyro_bias", "ANEES gyro bias", "nees", "gyro_bias"),
    Column("anees_accel_bias", "ANEES accel bias", "nees", "accel_bias"),
    Column("anees_landmarks", "ANEES landmarks", "nees", "landmarks"),
    Column("nis_mean", "mean NIS", "metric", "nis_mean"),
    Column("landmarks", "landmarks", "landmarks", "landmarks"),
    Column("time_step_median_ms", "time/step median [ms]", "metric", "time_per_step_ms_median"),
    Column("time_step_p99_ms", "time/step p99 [ms]", "metric", "time_per_step_ms_p99"),
    Column("time_total_s", "time total [s]", "metric", "time_total_s"),
)


@dataclass(frozen=True)
class Stat:
    """Mean and sample standard deviation (None for a single value) over runs."""

    mean: float
    std: float | None
    count: int

    @staticmethod
    def of(values: list[float]) -> Stat | None:
        if not values:
            return None
        array = np.asarray(values, dtype=float)
        return Stat(
            float(np.mean(array)),
            float(np.std(array, ddof=1)) if len(array) > 1 else None,
            len(array),
        )


@dataclass(frozen=True)
class NeesCell:
    """Averaged NEES of one block for a table cell."""

    mean: float
    lower: float
    upper: float
    inside_pct: float
    runs: int


@dataclass(frozen=True)
class Row:
    """One table row; ``status`` is ``ok``, ``partial`` (some runs failed), ``failed`` or ``n/a``."""

    dataset: str
    estimator: str
    status: str
    finished: int
    planned: int
    stats: dict[str, Stat | None]
    nees: dict[str, NeesCell | None]


def build_row(pair: PairResults) -> Row:
    """Aggregate the runs of one pair."""
    stats: dict[str, Stat | None] = {}
    nees: dict[str, NeesCell | None] = {}
    for column in COLUMNS:
        if column.kind == "metric":
            stats[column.key] = Stat.of(pair.values(column.source))
        elif column.kind == "landmarks":
            stats[column.key] = Stat.of(
                [float(s.final_landmarks) for s in pair.series if s.final_landmarks is not None]
            )
        else:
            averaged = pair.averaged_nees.get(column.source)
            bounds = averaged.typical_bounds if averaged is not None else None
            if averaged is None or bounds is None:
                nees[column.key] = None
            else:
                nees[column.key] = NeesCell(
                    averaged.overall_mean,
                    bounds[0],
                    bounds[1],
                    100.0 * averaged.inside_fraction,
                    averaged.runs,
                )
    if pair.not_applicable is not None:
        status = "n/a"
    elif not pair.finished:
        status = "failed" if pair.errors else "missing"
    elif len(pair.finished) < len(pair.cells):
        status = "partial"
    else:
        status = "ok"
    return Row(
        pair.dataset.title,
        pair.estimator.title,
        status,
        len(pair.finished),
        len(pair.cells),
        stats,
        nees,
    )


def build_rows(plan: Plan) -> tuple[list[Row], list[str]]:
    """The rows of the plan's table, and the notes to print under it."""
    pairs = collect(plan)
    notes = list(plan.notes)
    for pair in pairs:
        if pair.not_applicable is not None:
            notes.append(
                f"n/a {pair.dataset.title} / {pair.estimator.title}: {pair.not_applicable}"
            )
        for error in pair.errors:
            notes.append(f"failed {pair.dataset.title} / {pair.estimator.title} {error}")
    return [build_row(pair) for pair in pairs], notes


# ---------------------------------------------------------------------------- formatting


def format_number(value: float | None, digits: int = 4) -> str:
    """``digits`` significant digits; scientific notation outside [1e-3, 1e5)."""
    if value is None or not math.isfinite(value):
        return ""
    if value != 0 and not 1e-3 <= abs(value) < 1e5:
        return f"{value:.{digits - 1}e}"
    return f"{value:.{digits}g}"


def _stat_text(stat: Stat | None, plus_minus: str) -> str:
    if stat is None:
        return ""
    if stat.std is None:
        return format_number(stat.mean)
    return f"{format_number(stat.mean)}{plus_minus}{format_number(stat.std, 2)}"


def _nees_text(cell: NeesCell | None, percent: str = "%") -> str:
    if cell is None:
        return ""
    return f"{format_number(cell.mean, 3)} [{format_number(cell.lower, 3)}, {format_number(cell.upper, 3)}] {cell.inside_pct:.0f}{percent}"


def _runs_text(row: Row) -> str:
    return str(row.finished) if row.finished == row.planned else f"{row.finished}/{row.planned}"


def _cell_text(
    row: Row, column: Column, plus_minus: str, percent: str = "%", first: bool = False
) -> str:
    if row.status in ("n/a", "failed", "missing"):
        return row.status if first else ""
    if column.kind == "nees":
        return _nees_text(row.nees.get(column.key), percent)
    return _stat_text(row.stats.get(column.key), plus_minus)


def _shown_columns(rows: list[Row]) -> list[Column]:
    """Columns with at least one value (Markdown and LaTeX leave out empty ones)."""
    shown = []
    for column in COLUMNS:
        for row in rows:
            if (
                row.status in ("ok", "partial")
                and (
                    row.nees.get(column.key) if column.kind == "nees" else row.stats.get(column.key)
                )
                is not None
            ):
                shown.append(column)
                break
    return shown


def markdown_table(rows: list[Row], notes: list[str]) -> str:
    """The table in Markdown (GitHub pipes), with the notes as a list under it."""
    columns = _shown_columns(rows)
    header = ["dataset", "estimator", "runs"] + [column.header for column in columns]
    lines = [
        "| " + " | ".join(header) + " |",
        "|" + "|".join(["---"] * 3 + ["---:"] * len(columns)) + "|",
    ]
    for row in rows:
        cells = [row.dataset, row.estimator, _runs_text(row) if row.status != "n/a" else "-"]
        cells += [
            _cell_text(row, column, " ± ", first=index == 0) for index, column in enumerate(columns)
        ]
        lines.append("| " + " | ".join(cell.replace("|", "\\|") for cell in cells) + " |")
    lines.append("")
    lines.append(
        "Mean ± std over runs. ANEES: NEES averaged over runs (and landmarks), mean over steps "
        "[95% chi-square bounds] % of steps inside. Causal estimates unless marked smoothed. "
        "Columns named time_* in table.csv are wall-clock cost."
    )
    if notes:
        lines.append("")
        lines += [f"- {note}" for note in notes]
    return "\n".join(lines) + "\n"


_LATEX_SPECIAL = {
    "\\": r"\textbackslash{}",
    "&": r"\&",
    "%": r"\%",
    "$": r"\$",
    "#": r"\#",
    "_": r"\_",
    "{": r"\{",
    "}": r"\}",
    "~": r"\textasciitilde{}",
    "^": r"\^{}",
}


def latex_escape(text: str) -> str:
    return "".join(_LATEX_SPECIAL.get(character, character) for character in text)


def latex_table(rows: list[Row]) -> str:
    """The table as a LaTeX ``tabular`` with booktabs rules (needs ``\\usepackage{booktabs}``)."""
    columns = _shown_columns(rows)
    header = ["dataset", "estimator", "runs"] + [column.header for column in columns]
    lines = [
        "% Mean $\\pm$ std over runs; ANEES: averaged NEES, mean over steps [95\\% bounds] \\% of steps inside.",
        "\\begin{tabular}{ll r" + " r" * len(columns) + "}",
        "\\toprule",
        " & ".join(latex_escape(cell) for cell in header) + " \\\\",
        "\\midrule",
    ]
    previous_dataset = None
    for row in rows:
        if previous_dataset is not None and row.dataset != previous_dataset:
            lines.append("\\midrule")
        previous_dataset = row.dataset
        cells = [
            latex_escape(row.dataset),
            latex_escape(row.estimator),
            _runs_text(row) if row.status != "n/a" else "--",
        ]
        for index, column in enumerate(columns):
            text = _cell_text(row, column, "\0", "\1", first=index == 0)
            cells.append(latex_escape(text).replace("\0", " $\\pm$ ").replace("\1", "\\%"))
        lines.append(" & ".join(cells) + " \\\\")
    lines += ["\\bottomrule", "\\end{tabular}"]
    return "\n".join(lines) + "\n"


def csv_header() -> list[str]:
    header = ["dataset", "estimator", "status", "runs", "runs_planned"]
    for column in COLUMNS:
        if column.kind == "nees":
            header += [
                f"{column.key}_mean",
                f"{column.key}_lower",
                f"{column.key}_upper",
                f"{column.key}_inside_pct",
                f"{column.key}_runs",
            ]
        else:
            header += [f"{column.key}_mean", f"{column.key}_std"]
    return header


def csv_table(rows: list[Row]) -> str:
    """Every column (also the empty ones), numbers with 6 significant digits, empty when
    not defined; timing columns start with ``time_``."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(csv_header())
    for row in rows:
        record: list[str] = [
            row.dataset,
            row.estimator,
            row.status,
            str(row.finished),
            str(row.planned),
        ]
        for column in COLUMNS:
            if column.kind == "nees":
                cell = row.nees.get(column.key)
                record += (
                    ["", "", "", "", ""]
                    if cell is None
                    else [
                        format_number(cell.mean, 6),
                        format_number(cell.lower, 6),
                        format_number(cell.upper, 6),
                        f"{cell.inside_pct:.2f}",
                        str(cell.runs),
                    ]
                )
            else:
                stat = row.stats.get(column.key)
                record += (
                    ["", ""]
                    if stat is None
                    else [format_number(stat.mean, 6), format_number(stat.std, 6)]
                )
        writer.writerow(record)
    return buffer.getvalue()


def write_tables(plan: Plan, out: Path | None = None) -> dict[str, Path]:
    """Write ``table.md``, ``table.tex`` and ``table.csv`` into ``out`` (default: the
    sweep's folder); returns the paths by suffix."""
    out = Path(out or plan.out)
    rows, notes = build_rows(plan)
    return {
        "md": write_atomic(out / "table.md", markdown_table(rows, notes)),
        "tex": write_atomic(out / "table.tex", latex_table(rows)),
        "csv": write_atomic(out / "table.csv", csv_table(rows)),
    }


def non_timing_columns(csv_text: str) -> list[dict[str, str]]:
    """The rows of a ``table.csv`` without the ``time_*`` columns (for comparisons)."""
    return [
        {key: value for key, value in record.items() if not key.startswith("time_")}
        for record in csv.DictReader(io.StringIO(csv_text))
    ]
