"""The one table writer: Markdown and LaTeX (compact), CSV (every column), and the terminal
table (rich), from the rows of ``results.summary``. Suites (``workbench bench``), bags
(``workbench bag``) and ``workbench report`` all write through it.

A consistency cell reads ``1.02 ✓``: the NEES (or NIS) per degree of freedom averaged over
runs (1 is consistent) and its verdict (``workbench.metrics.verdicts``): ✓ consistent,
▲ optimistic (errors larger than the covariance claims), ▼ conservative, · too few runs. A
superscript ˢ marks a cell that scores the smoothed estimate (the batch smoother has no
causal one; a smoother's map is its final smoothed map). The bands are in ``table.csv``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from datasets.trajectory_io import write_atomic
from workbench.metrics.verdicts import MIN_RUNS, Verdict
from workbench.results.consistency import TABLE_BLOCKS, ConsistencyCell
from workbench.results.summary import PairSummary, Stat, summary_frame

VERDICT_MARKS = {
    Verdict.CONSISTENT: "✓",
    Verdict.OPTIMISTIC: "▲",
    Verdict.CONSERVATIVE: "▼",
    Verdict.TOO_FEW_RUNS: "·",
}
LATEX_MARKS = {
    Verdict.CONSISTENT: r"\checkmark",
    Verdict.OPTIMISTIC: r"$\blacktriangle$",
    Verdict.CONSERVATIVE: r"$\blacktriangledown$",
    Verdict.TOO_FEW_RUNS: r"$\cdot$",
}
BLOCK_HEADERS = {
    "pose": "pose",
    "velocity": "velocity",
    "gyro_bias": "gyro bias",
    "accel_bias": "accel bias",
    "map": "map",
    "nis": "NIS",
}


@dataclass(frozen=True)
class StatColumn:
    """A mean ± std column of a metrics.json key."""

    key: str
    header: str


STAT_COLUMNS = (
    StatColumn("ate_rmse_m", "ATE [m]"),
    # a suite's reference estimator (``reference:``): ATE over its ATE on the same dataset
    StatColumn("ate_over_reference", "ATE ÷ ref"),
    StatColumn("ate_rmse_smoothed_m", "ATE smoothed [m]"),
    StatColumn("rpe_trans_rmse_m", "RPE trans [m]"),
    StatColumn("rpe_rot_rmse_deg", "RPE rot [deg]"),
    StatColumn("final_orientation_error_deg", "final orient. [deg]"),
    StatColumn("gps_holdout_rmse_m", "GPS hold-out [m]"),
    # the smoothed trajectory's: the batch smoother's only one (it has no causal estimate)
    StatColumn("gps_holdout_rmse_smoothed_m", "GPS hold-out smoothed [m]"),
)
TAIL_COLUMNS = (
    StatColumn("landmarks_in_map", "landmarks"),
    StatColumn("association_precision", "assoc. precision"),
    StatColumn("association_rejected_fraction", "rejected"),
    # the whole run, final optimisation included: a smoother's median step is an IMU sample
    # (0.017 ms against ekf-slam's 0.15 ms on sim:aghili-rover) while its keyframes and its
    # finish take the time (tens of seconds a run against ekf-slam's 0.8 s), so a per-step
    # median ranks them backwards; the median and 99th percentile per step stay in table.csv
    StatColumn("time_total_s", "time/run [s]"),
)

LEGEND = (
    "Mean ± std over runs. Consistency: NEES (for NIS: the innovation of each update against "
    "the prediction before it) per degree of freedom averaged over runs, 1 is consistent; "
    f"✓ consistent, ▲ optimistic (errors larger than the covariance says), ▼ conservative, "
    f"· too few runs (< {MIN_RUNS}); a cell scores the causal estimate, ˢ the smoothed one "
    "(the batch smoother has no causal estimate; smoother maps are their final smoothed "
    "maps); bands and verdict rule in table.csv and workbench/metrics/verdicts.py. "
    "NIS/dof: every update of every run pooled. Columns named time_* in table.csv are "
    "wall-clock cost."
)


def format_number(value: float | None, digits: int = 4) -> str:
    """``digits`` significant digits; scientific notation outside [1e-3, 1e5)."""
    if value is None or not math.isfinite(value):
        return ""
    if value != 0 and not 1e-3 <= abs(value) < 1e5:
        return f"{value:.{digits - 1}e}"
    return f"{value:.{digits}g}"


def stat_text(stat: Stat | None, plus_minus: str = " ± ") -> str:
    if stat is None:
        return ""
    if stat.std is None:
        return format_number(stat.mean)
    return f"{format_number(stat.mean)}{plus_minus}{format_number(stat.std, 2)}"


def cell_text(
    cell: ConsistencyCell | None, marks: dict[Verdict, str] = VERDICT_MARKS, smoothed: str = "ˢ"
) -> str:
    if cell is None:
        return ""
    mark = marks[cell.statistic.verdict]
    suffix = smoothed if cell.scored == "smoothed" else ""
    return f"{format_number(cell.statistic.value, 3)}{suffix} {mark}"


def _shown_stats(rows: list[PairSummary], columns: tuple[StatColumn, ...]) -> list[StatColumn]:
    return [column for column in columns if any(column.key in row.stats for row in rows)]


def _shown_blocks(rows: list[PairSummary]) -> list[str]:
    return [block for block in TABLE_BLOCKS if any(block in row.cells for row in rows)]


def table_notes(rows: list[PairSummary], notes: list[str] = ()) -> list[str]:
    """Notes under a table: the plan's notes, what each dataset's models were fitted on
    (its calibration), n/a pairs with the reason, failures, the runs'
    warnings (dropped rows, sightings not used as stated), and the rows whose causal
    columns are blank because the estimator has no causal estimate."""
    found = list(notes)
    for row in rows:
        found.extend(f"calibration of {row.dataset}: {text}" for text in row.calibrations())
        if row.status == "n/a":
            found.append(f"n/a {row.dataset} / {row.estimator}: {row.reason}")
        for error in row.errors():
            found.append(f"failed {row.dataset} / {row.estimator} {error}")
        found.extend(f"warning: {line}" for line in row.warnings())
        if "ate_rmse_smoothed_m" in row.stats and "ate_rmse_m" not in row.stats:
            found.append(
                f"{row.dataset} / {row.estimator}: no causal estimate (a batch solution exists "
                "only at the end): causal columns blank, every cell scores the smoothed one"
            )
    return list(dict.fromkeys(found))  # a dataset's warning once, not once per estimator


def _row_cells(
    row: PairSummary, stats, blocks, plus_minus, marks, smoothed, percent=""
) -> list[str]:
    if row.status in ("n/a", "failed", "missing"):
        cells = [row.status] + [""] * (len(stats) + len(blocks) + 1 + len(TAIL_COLUMNS))
        return cells
    cells = [stat_text(row.stats.get(column.key), plus_minus) for column in stats]
    cells += [cell_text(row.cells.get(block), marks, smoothed) for block in blocks]
    cells.append(format_number(row.nis_per_dof, 3))
    return cells


def _runs_text(row: PairSummary) -> str:
    if row.status == "n/a":
        return "-"
    return str(row.finished) if row.finished == row.planned else f"{row.finished}/{row.planned}"


def markdown_table(rows: list[PairSummary], notes: list[str] = ()) -> str:
    """The compact table in Markdown (GitHub pipes), with the legend and notes under it."""
    stats, tail = _shown_stats(rows, STAT_COLUMNS), _shown_stats(rows, TAIL_COLUMNS)
    blocks = _shown_blocks(rows)
    header = ["dataset", "estimator", "runs"] + [c.header for c in stats]
    header += [BLOCK_HEADERS[b] for b in blocks] + ["NIS/dof"] + [c.header for c in tail]
    lines = [
        "| " + " | ".join(header) + " |",
        "|" + "|".join(["---"] * 3 + ["---:"] * (len(header) - 3)) + "|",
    ]
    for row in rows:
        cells = [row.dataset, row.estimator, _runs_text(row)]
        body = _row_cells(row, stats, blocks, " ± ", VERDICT_MARKS, "ˢ")
        if row.status in ("n/a", "failed", "missing"):
            body = [row.status] + [""] * (len(header) - 4)
        else:
            body += [stat_text(row.stats.get(column.key)) for column in tail]
        lines.append("| " + " | ".join(cell.replace("|", "\\|") for cell in cells + body) + " |")
    lines += ["", LEGEND]
    extra = table_notes(rows, list(notes))
    if extra:
        lines.append("")
        lines += [f"- {note}" for note in extra]
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


def latex_table(rows: list[PairSummary]) -> str:
    """The compact table as a LaTeX ``tabular`` (needs booktabs and amssymb)."""
    stats, tail = _shown_stats(rows, STAT_COLUMNS), _shown_stats(rows, TAIL_COLUMNS)
    blocks = _shown_blocks(rows)
    header = ["dataset", "estimator", "runs"] + [c.header for c in stats]
    header += [BLOCK_HEADERS[b] for b in blocks] + ["NIS/dof"] + [c.header for c in tail]
    lines = [
        "% Mean $\\pm$ std over runs; consistency: NEES (NIS) per dof averaged over runs with its",
        "% verdict: \\checkmark consistent, $\\blacktriangle$ optimistic, $\\blacktriangledown$",
        "% conservative, $\\cdot$ too few runs; $^{s}$ scores the smoothed estimate.",
        "% Needs \\usepackage{booktabs,amssymb}.",
        "\\begin{tabular}{ll r" + " r" * (len(header) - 3) + "}",
        "\\toprule",
        " & ".join(latex_escape(cell) for cell in header) + " \\\\",
        "\\midrule",
    ]
    previous = None
    for row in rows:
        if previous is not None and row.dataset != previous:
            lines.append("\\midrule")
        previous = row.dataset
        cells = [latex_escape(row.dataset), latex_escape(row.estimator), _runs_text(row)]
        if row.status in ("n/a", "failed", "missing"):
            cells += [row.status] + [""] * (len(header) - 4)
        else:
            cells += [
                latex_escape(stat_text(row.stats.get(c.key), "\0")).replace("\0", " $\\pm$ ")
                for c in stats
            ]
            cells += [cell_text(row.cells.get(b), LATEX_MARKS, "$^{s}$") for b in blocks]
            cells.append(format_number(row.nis_per_dof, 3))
            cells += [
                latex_escape(stat_text(row.stats.get(c.key), "\0")).replace("\0", " $\\pm$ ")
                for c in tail
            ]
        lines.append(" & ".join(cells) + " \\\\")
    lines += ["\\bottomrule", "\\end{tabular}"]
    return "\n".join(lines) + "\n"


def csv_table(rows: list[PairSummary]) -> str:
    """Every column (``summary.summary_frame``), numbers with 6 significant digits, empty
    when not defined."""
    frame = summary_frame(rows)
    return frame.to_csv(index=False, float_format="%.6g", lineterminator="\n")


def write_tables(rows: list[PairSummary], out: Path, notes: list[str] = ()) -> dict[str, Path]:
    """``table.md``, ``table.tex`` and ``table.csv`` in ``out``; returns the paths by suffix."""
    out = Path(out)
    return {
        "md": write_atomic(out / "table.md", markdown_table(rows, list(notes))),
        "tex": write_atomic(out / "table.tex", latex_table(rows)),
        "csv": write_atomic(out / "table.csv", csv_table(rows)),
    }


VERDICT_STYLES = {
    Verdict.CONSISTENT: "green",
    Verdict.OPTIMISTIC: "bold red",
    Verdict.CONSERVATIVE: "yellow",
    Verdict.TOO_FEW_RUNS: "dim",
}


def terminal_tables(rows: list[PairSummary], title: str = "") -> list:
    """The columns a reader needs first, one rich ``Table`` per dataset (titled with it, so
    no column repeats it): estimator, runs, ATE, the consistency verdicts, NIS/dof, time per
    run. The full table stays in the files."""
    from rich.table import Table
    from rich.text import Text

    tables = []
    datasets = list(dict.fromkeys(row.dataset for row in rows))
    for dataset in datasets:
        blocks = _shown_blocks([row for row in rows if row.dataset == dataset])
        heading = f"{title}: {dataset}" if title else dataset
        # labels are Text, never markup: "ekf-slam [acceleration_density=0.2]" is a label
        table = Table(title=Text(heading), title_justify="left", show_lines=False)
        table.add_column("estimator", no_wrap=True)
        table.add_column("runs", justify="right", no_wrap=True)
        table.add_column("ATE [m]", justify="right", no_wrap=True)
        ratios = any("ate_over_reference" in row.stats for row in rows if row.dataset == dataset)
        if ratios:
            table.add_column("÷ ref", justify="right", no_wrap=True)
        for block in blocks:
            table.add_column(BLOCK_HEADERS[block], justify="right", no_wrap=True)
        table.add_column("NIS/dof", justify="right", no_wrap=True)
        table.add_column("s/run", justify="right", no_wrap=True)
        for row in (r for r in rows if r.dataset == dataset):
            if row.status in ("n/a", "failed", "missing"):
                table.add_row(Text(row.estimator), _runs_text(row), row.status)
                continue
            ate = row.stats.get("ate_rmse_m") or row.stats.get("ate_rmse_smoothed_m")
            smoothed = "ˢ" if "ate_rmse_m" not in row.stats and ate is not None else ""
            cells: list = [
                Text(row.estimator),
                _runs_text(row),
                (format_number(ate.mean, 3) + smoothed) if ate else "",
            ]
            if ratios:
                ratio = row.stats.get("ate_over_reference")
                cells.append(format_number(ratio.mean, 3) if ratio else "")
            for block in blocks:
                cell = row.cells.get(block)
                if cell is None:
                    cells.append("")
                else:
                    cells.append(
                        Text(cell_text(cell), style=VERDICT_STYLES[cell.statistic.verdict])
                    )
            cells.append(format_number(row.nis_per_dof, 3))
            cost = row.stats.get("time_total_s")
            cells.append(format_number(cost.mean, 3) if cost else "")
            table.add_row(*cells)
        tables.append(table)
    return tables


def non_timing_columns(csv_text: str) -> list[dict[str, str]]:
    """The rows of a ``table.csv`` without the ``time_*`` columns (for comparisons)."""
    import csv
    import io

    return [
        {key: value for key, value in record.items() if not key.startswith("time_")}
        for record in csv.DictReader(io.StringIO(csv_text))
    ]
