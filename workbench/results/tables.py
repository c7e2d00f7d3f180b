"""The one table writer: Markdown (compact), LaTeX (``results.latex``: paper tables per
preset), CSV (every column), and the terminal table (rich), from the rows of
``results.summary``. Suites (``workbench bench``), bags (``workbench bag``) and
``workbench report`` all write through it.

A consistency cell reads ``1.02 ✓``: the NEES (or NIS) per degree of freedom averaged over
runs (1 is consistent) and its verdict (``workbench.metrics.verdicts``): ✓ consistent,
▲ optimistic (errors larger than the covariance claims), ▼ conservative, · no verdict (too
few runs for a NEES cell, too few updates for a NIS cell). A superscript ˢ marks a cell that
scores the smoothed estimate (the batch smoother has no causal one; a smoother's map is its
final smoothed map). The bands are in ``table.csv``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from datasets.trajectory_io import write_atomic
from workbench.metrics.verdicts import MIN_POOLED_UPDATES, MIN_RUNS, Verdict
from workbench.results.columns import CUSTOM, DEFAULT_TABLE, PRESETS, parse_table_choice
from workbench.results.consistency import TABLE_BLOCKS, ConsistencyCell
from workbench.results.latex import latex_tables
from workbench.results.summary import (
    FRONT_END_ROW,
    REFERENCE_KEY,
    PairSummary,
    Stat,
    summary_frame,
)

VERDICT_MARKS = {
    Verdict.CONSISTENT: "✓",
    Verdict.OPTIMISTIC: "▲",
    Verdict.CONSERVATIVE: "▼",
    Verdict.TOO_FEW_RUNS: "·",
}
BLOCK_NAMES = {
    "pose": "pose",
    "velocity": "velocity",
    "gyro_bias": "gyro bias",
    "accel_bias": "accel bias",
    "map": "map",
    "nis": "NIS",
}
BLOCK_HEADERS = {
    **{block: f"NEES/dof {name}" for block, name in BLOCK_NAMES.items()},
    "nis": "NIS/dof",
}


@dataclass(frozen=True)
class StatColumn:
    """A mean ± std column of a metrics.json key."""

    key: str
    header: str


STAT_COLUMNS = (
    StatColumn("ate_rmse_m", "ATE [m]"),
    # a suite's reference estimator (``reference:``): ATE over its ATE on the same dataset
    StatColumn(REFERENCE_KEY, "ATE ÷ ref"),
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

# a lidar dataset's (one with a front end): each estimate against the front end's own
# trajectory, and every frame and its cost (``workbench.metrics.frontend_agreement``)
FRONT_END_COLUMNS = (
    StatColumn("frontend_max_deviation_m", "vs front end: max dev. [m]"),
    StatColumn("frontend_max_deviation_percent_path", "max dev. [% path]"),
    StatColumn("frontend_final_yaw_diff_deg", "final yaw diff. [deg]"),
    StatColumn("frames", "frames"),
    StatColumn("frames_without_pose", "frames without pose"),
    StatColumn("time_per_frame_ms", "time/frame [ms]"),
)

NO_VERDICT = (
    f"· no verdict (a NEES cell needs {MIN_RUNS} runs, a NIS cell {MIN_POOLED_UPDATES} updates)"
)
LEGEND = (
    "Mean ± std over runs. Consistency: NEES (for NIS: the innovation of each update against "
    "the prediction before it) per degree of freedom averaged over runs, 1 is consistent; "
    f"✓ consistent, ▲ optimistic (errors larger than the covariance says), ▼ conservative, "
    f"{NO_VERDICT}; a cell scores the causal estimate, ˢ the smoothed one "
    "(the batch smoother has no causal estimate; smoother maps are their final smoothed "
    "maps); bands and verdict rule in table.csv and workbench/metrics/verdicts.py. "
    "NIS/dof pooled: every update of every run summed over their summed dof. Columns named "
    "time_* in table.csv are wall-clock cost."
)
TERMINAL_LEGEND = (
    "Means over runs (± std and every column in table.md and table.csv). NEES and NIS per "
    "degree of freedom averaged over runs, 1 is consistent: ✓ consistent, ▲ optimistic "
    "(errors larger than the covariance says), ▼ conservative, "
    f"{NO_VERDICT}; ˢ scores the smoothed estimate (the estimator has no causal one)."
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


def _has_front_end(rows: list[PairSummary]) -> bool:
    return any(row.estimator_name == FRONT_END_ROW for row in rows)


def _front_end_note(row: PairSummary) -> str:
    """What a front-end row is (``summary.front_end_row``), with its corners' NIS."""
    nis = (
        ""
        if row.nis_per_dof is None
        else f"; NIS/dof of its corners' re-observations {format_number(row.nis_per_dof, 3)}"
    )
    return (
        f"{row.dataset} / {row.estimator}: the lidar front end alone (its own trajectory's "
        f"ATE where there is truth, its time per frame{nis}); every other row's max dev., "
        "% path and final yaw are that estimate against this trajectory, both from the same "
        "start (workbench/metrics/frontend_agreement.py)"
    )


def table_notes(rows: list[PairSummary], notes: list[str] = ()) -> list[str]:
    """Notes under a table: the plan's notes, what each dataset's models were fitted on
    (its calibration), n/a pairs with the reason, failures, the runs'
    warnings (dropped rows, sightings not used as stated), the rows whose causal
    columns are blank because the estimator has no causal estimate, and what a front-end
    row is."""
    found = list(notes)
    for row in rows:
        if row.estimator_name == FRONT_END_ROW:
            found.append(_front_end_note(row))
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
    if _has_front_end(rows):
        stats += _shown_stats(rows, FRONT_END_COLUMNS)
    blocks = _shown_blocks(rows)
    header = ["dataset", "estimator", "runs"] + [c.header for c in stats]
    header += [BLOCK_HEADERS[b] for b in blocks] + ["NIS/dof pooled"] + [c.header for c in tail]
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


def csv_table(rows: list[PairSummary]) -> str:
    """Every column (``summary.summary_frame``), numbers with 6 significant digits, empty
    when not defined."""
    frame = summary_frame(rows)
    return frame.to_csv(index=False, float_format="%.6g", lineterminator="\n")


def write_tables(
    rows: list[PairSummary],
    out: Path,
    notes: list[str] = (),
    table: str = DEFAULT_TABLE,
    label: str | None = None,
) -> dict[str, Path]:
    """``table.md``, ``table.csv`` and the LaTeX tables in ``out``: ``table_NAME.tex`` for
    each table ``table`` chooses (``columns.parse_table_choice``: a preset, ``all``, or a
    column list, ``table_custom.tex``) and ``table.tex`` holding them all. ``label``: the
    LaTeX labels' prefix (``tab:LABEL-NAME``; default the folder's name). Returns the paths
    by key: ``md``, ``csv``, ``tex`` and ``tex:NAME``."""
    from workbench.suites import slug

    out = Path(out)
    chosen = parse_table_choice(table)
    prefix = slug(label if label is not None else out.name).lower()
    paths = {
        "md": write_atomic(out / "table.md", markdown_table(rows, list(notes))),
        "csv": write_atomic(out / "table.csv", csv_table(rows)),
    }
    texts = []
    for name, columns in chosen:
        text = latex_tables(rows, name, columns, f"tab:{prefix}-{name}")
        paths[f"tex:{name}"] = write_atomic(out / f"table_{name}.tex", text)
        texts.append(text)
    # a table an earlier report here chose and this one did not would read as this report's
    for name in (*PRESETS, CUSTOM):
        if f"tex:{name}" not in paths:
            (out / f"table_{name}.tex").unlink(missing_ok=True)
    paths["tex"] = write_atomic(out / "table.tex", "\n".join(texts))
    return paths


VERDICT_STYLES = {
    Verdict.CONSISTENT: "green",
    Verdict.OPTIMISTIC: "bold red",
    Verdict.CONSERVATIVE: "yellow",
    Verdict.TOO_FEW_RUNS: "dim",
}


@dataclass(frozen=True)
class TerminalColumn:
    """A terminal column: its header lines (name, then unit or normalisation), whether it
    is a consistency column (the part a table too wide for the terminal moves to a second
    table), and its cell of a row (str or rich ``Text``)."""

    header: tuple[str, str]
    consistency: bool
    cell: object  # Callable[[PairSummary], str | Text]


def _mean_text(row: PairSummary, causal: str, smoothed: str) -> str:
    """The causal mean of a row, else its smoothed one marked ˢ (3 significant digits)."""
    stat = row.stats.get(causal)
    if stat is not None:
        return format_number(stat.mean, 3)
    stat = row.stats.get(smoothed)
    return "" if stat is None else format_number(stat.mean, 3) + "ˢ"


def _verdict_text(cell: ConsistencyCell | None):
    from rich.text import Text

    if cell is None:
        return ""
    return Text(cell_text(cell), style=VERDICT_STYLES[cell.statistic.verdict])


def _terminal_columns(rows: list[PairSummary]) -> list[TerminalColumn]:
    """The columns one dataset's rows fill, those that matter first: accuracy (ATE, the
    reference ratio, the GPS hold-out when the dataset has one), consistency (pose first,
    NIS last), time per run."""

    def filled(*keys: str) -> bool:
        return any(key in row.stats for row in rows for key in keys)

    columns = []
    if filled("ate_rmse_m", "ate_rmse_smoothed_m"):
        columns.append(
            TerminalColumn(
                ("ATE", "[m]"), False, lambda r: _mean_text(r, "ate_rmse_m", "ate_rmse_smoothed_m")
            )
        )
    if filled(REFERENCE_KEY):
        columns.append(
            TerminalColumn(
                ("ATE ÷ ref", ""),
                False,
                lambda r: (
                    format_number(r.stats[REFERENCE_KEY].mean, 3)
                    if REFERENCE_KEY in r.stats
                    else ""
                ),
            )
        )
    # kitti-imu-gps has no truth of the path: its only accuracy figure is the hold-out
    if filled("gps_holdout_rmse_m", "gps_holdout_rmse_smoothed_m"):
        columns.append(
            TerminalColumn(
                ("GPS hold-out", "[m]"),
                False,
                lambda r: _mean_text(r, "gps_holdout_rmse_m", "gps_holdout_rmse_smoothed_m"),
            )
        )
    if _has_front_end(rows):
        columns += _front_end_terminal_columns(rows)
    for block in _shown_blocks(rows):
        header = ("NIS", "per dof") if block == "nis" else (BLOCK_NAMES[block], "NEES/dof")
        columns.append(
            TerminalColumn(header, True, lambda r, b=block: _verdict_text(r.cells.get(b)))
        )
    if filled("time_total_s"):
        columns.append(
            TerminalColumn(
                ("time/run", "[s]"),
                False,
                lambda r: (
                    format_number(r.stats["time_total_s"].mean, 3)
                    if "time_total_s" in r.stats
                    else ""
                ),
            )
        )
    return columns


def _frames_text(row: PairSummary) -> str:
    """``posed/frames`` (means over runs), "" without frames."""
    frames, missing = row.stats.get("frames"), row.stats.get("frames_without_pose")
    if frames is None:
        return ""
    posed = frames.mean - (0.0 if missing is None else missing.mean)
    return f"{format_number(posed, 4)}/{format_number(frames.mean, 4)}"


def _front_end_terminal_columns(rows: list[PairSummary]) -> list[TerminalColumn]:
    """A lidar dataset's columns: each estimate against the front end's trajectory (max
    deviation, its share of the path, final yaw difference), frames with a pose of all
    frames, and the time per frame."""

    def mean(key: str, digits: int = 3):
        return lambda r: format_number(r.stats[key].mean, digits) if key in r.stats else ""

    return [
        TerminalColumn(("vs front end", "max dev [m]"), False, mean("frontend_max_deviation_m")),
        TerminalColumn(("", "[% path]"), False, mean("frontend_max_deviation_percent_path")),
        TerminalColumn(("final yaw", "[deg]"), False, mean("frontend_final_yaw_diff_deg", 2)),
        TerminalColumn(("frames", "posed/all"), False, _frames_text),
        TerminalColumn(("time/frame", "[ms]"), False, mean("time_per_frame_ms")),
    ]


def _terminal_table(
    rows: list[PairSummary], heading: str, columns: list[TerminalColumn], compact: bool
):
    from rich import box
    from rich.table import Table
    from rich.text import Text

    # labels are Text, never markup: "ekf-slam [velocity_walk_m_s_sqrt_s=0.2]" is a label, and
    # so is a unit: "[m]" would read as a style
    table = Table(
        title=Text(heading),
        title_justify="left",
        box=box.SIMPLE_HEAD,
        show_edge=False,
        pad_edge=False,
        collapse_padding=compact,
    )
    table.add_column(Text("estimator"), vertical="bottom")
    table.add_column(Text("runs"), justify="right", no_wrap=True)
    for column in columns:
        table.add_column(Text("\n".join(column.header)), justify="right", no_wrap=True)
    for row in rows:
        if row.status in ("n/a", "failed", "missing"):
            table.add_row(Text(row.estimator), _runs_text(row), *([row.status] if columns else []))
            continue
        table.add_row(Text(row.estimator), _runs_text(row), *(c.cell(row) for c in columns))
    return table


def _table_width(table) -> int:
    from rich.console import Console

    return Console(width=100_000).measure(table).maximum


def terminal_tables(rows: list[PairSummary], title: str = "", width: int | None = None) -> list:
    """One rich ``Table`` per dataset (titled with it, so no column repeats it), the columns
    that matter first (``_terminal_columns``); headers carry units. Where the table is wider
    than ``width`` (the terminal's, None: no limit) its columns close up, and where that
    is not enough the consistency columns go to a second table below it. The full table
    stays in the files."""
    tables = []
    for dataset in dict.fromkeys(row.dataset for row in rows):
        own = [row for row in rows if row.dataset == dataset]
        heading = f"{title}: {dataset}" if title else dataset
        columns = _terminal_columns(own)
        candidates = [_terminal_table(own, heading, columns, compact) for compact in (False, True)]
        fitting = [t for t in candidates if width is None or _table_width(t) <= width]
        if fitting:
            tables.append(fitting[0])
            continue
        first = [column for column in columns if not column.consistency]
        second = [column for column in columns if column.consistency]
        tables.append(_terminal_table(own, heading, first, compact=False))
        if second:
            tables.append(_terminal_table(own, f"{heading} (consistency)", second, False))
    return tables


def non_timing_columns(csv_text: str) -> list[dict[str, str]]:
    """The rows of a ``table.csv`` without the ``time_*`` columns (for comparisons)."""
    import csv
    import io

    return [
        {key: value for key, value in record.items() if not key.startswith("time_")}
        for record in csv.DictReader(io.StringIO(csv_text))
    ]
