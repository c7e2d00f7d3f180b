"""Table layout: the cells of rows x columns with the best in bold, the estimated width of
a table, the parts (``table`` floats) a preset's rows and columns are split into so that
each fits, and the ``tabular`` of one part.

Width: a table is typeset in ``\\footnotesize`` (never smaller) and its width estimated
from Computer Modern's 8 pt glyph widths (a 10 pt article's footnotesize) plus the column
separation. A table wider than the narrowest 1-inch-margin text width (A4: 452.97 pt;
letter: 469.75 pt) is split: datasets into several tables, and a dataset whose own columns
do not fit into several column groups. No ``\\resizebox``, no scaling.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

from workbench.results.columns import Column
from workbench.results.latex_cells import _EMPTY, Cell, best_rows, column_value, make_cell
from workbench.results.latex_text import latex_escape
from workbench.results.latex_width import (
    COLUMN_SEPARATION_PT,
    TEXT_WIDTH_PT,
    WIDTH_MARGIN,
    text_width_pt,
)
from workbench.results.summary import PairSummary


def _runs_text(row: PairSummary) -> str:
    if row.status == "n/a":
        return "--"
    return str(row.finished) if row.finished == row.planned else f"{row.finished}/{row.planned}"


def _has_value(row: PairSummary, column: Column) -> bool:
    return row.status not in ("n/a", "failed", "missing") and column_value(row, column) is not None


@dataclass(frozen=True)
class TablePart:
    """One ``table`` float: its datasets (in row order) and columns."""

    datasets: tuple[str, ...]
    columns: tuple[Column, ...]


def _header_lines(columns: tuple[Column, ...]) -> list[list[str]]:
    """The header rows below the group row: names (one or more lines) then units."""
    depth = max((len(column.header) for column in columns), default=1)
    return [
        [column.header[level] if level < len(column.header) else "" for column in columns]
        for level in range(depth)
    ]


def _groups(columns: tuple[Column, ...]) -> list[tuple[str, int, int]]:
    """(group, first, last) of each run of adjacent columns sharing a non-empty group."""
    found: list[tuple[str, int, int]] = []
    for index, column in enumerate(columns):
        if found and column.group and found[-1][0] == column.group and found[-1][2] == index - 1:
            found[-1] = (column.group, found[-1][1], index)
        elif column.group:
            found.append((column.group, index, index))
    return found


def _rows_of(rows: list[PairSummary], datasets: tuple[str, ...]) -> list[PairSummary]:
    return [row for row in rows if row.dataset in datasets]


def _cells(rows: list[PairSummary], columns: tuple[Column, ...]) -> list[list[Cell]]:
    """Cells of ``rows`` x ``columns`` with the best of each dataset's column in bold."""
    grid = [
        [make_cell(row, column) if _has_value(row, column) else _EMPTY for column in columns]
        for row in rows
    ]
    for dataset in dict.fromkeys(row.dataset for row in rows):
        members = [index for index, row in enumerate(rows) if row.dataset == dataset]
        for at, column in enumerate(columns):
            best = best_rows([grid[index][at] for index in members], column.direction)
            for position in best:
                index = members[position]
                grid[index][at] = replace(grid[index][at], bold=True)
    return grid


def table_width_pt(rows: list[PairSummary], columns: tuple[Column, ...]) -> float:
    """Estimated width [pt] of the table of ``rows`` (with their dataset headings) and
    ``columns``, estimator and runs columns included."""
    grid = _cells(rows, columns)
    widths = [
        max([text_width_pt("estimator")] + [text_width_pt(row.estimator) for row in rows]),
        max([text_width_pt("runs")] + [text_width_pt(_runs_text(row)) for row in rows]),
    ]
    headers = _header_lines(columns)
    for at in range(len(columns)):
        shown = [text_width_pt(line[at]) for line in headers]
        shown += [row_cells[at].width_pt() for row_cells in grid]
        shown += [text_width_pt(row.status) for row in rows if row.status in ("n/a", "failed")]
        widths.append(max(shown))
    for group, first, last in _groups(columns):
        spanned = sum(widths[2 + first : 3 + last]) + COLUMN_SEPARATION_PT * (last - first)
        widths[2 + last] += max(0.0, text_width_pt(group) - spanned)
    total = sum(widths) + COLUMN_SEPARATION_PT * (len(widths) - 1)
    headings = [text_width_pt(dataset) for dataset in dict.fromkeys(row.dataset for row in rows)]
    return max([total, *headings])


def fits(rows: list[PairSummary], columns: tuple[Column, ...]) -> bool:
    return table_width_pt(rows, columns) <= TEXT_WIDTH_PT * WIDTH_MARGIN


def plan_parts(rows: list[PairSummary], columns: tuple[Column, ...]) -> list[TablePart]:
    """The tables ``rows`` x ``columns`` take (module docstring): per dataset the columns it
    fills; consecutive datasets share a table while their columns together fit; a dataset
    that does not fit alone gets one table per group of columns that fits. Datasets that
    fill no column are in none."""
    datasets = list(dict.fromkeys(row.dataset for row in rows))
    filled = {
        dataset: tuple(
            column
            for column in columns
            if any(_has_value(row, column) for row in rows if row.dataset == dataset)
        )
        for dataset in datasets
    }
    parts: list[TablePart] = []
    current: list[str] = []
    for dataset in (name for name in datasets if filled[name]):
        joined = current + [dataset]
        union = tuple(c for c in columns if any(c in filled[name] for name in joined))
        if fits(_rows_of(rows, tuple(joined)), union):
            current = joined
            continue
        if current:
            union = tuple(c for c in columns if any(c in filled[name] for name in current))
            parts.append(TablePart(tuple(current), union))
        current = [dataset]
        if not fits(_rows_of(rows, (dataset,)), filled[dataset]):
            parts += _column_groups(rows, dataset, filled[dataset])
            current = []
    if current:
        union = tuple(c for c in columns if any(c in filled[name] for name in current))
        parts.append(TablePart(tuple(current), union))
    return parts


def _column_groups(rows: list[PairSummary], dataset: str, columns: tuple[Column, ...]):
    """One dataset's columns in consecutive groups that each fit (a single column that does
    not fit alone still gets its table: nothing narrower can be made)."""
    own = _rows_of(rows, (dataset,))
    groups: list[TablePart] = []
    chunk: list[Column] = []
    for column in columns:
        if chunk and not fits(own, (*chunk, column)):
            groups.append(TablePart((dataset,), tuple(chunk)))
            chunk = []
        chunk.append(column)
    if chunk:
        groups.append(TablePart((dataset,), tuple(chunk)))
    return groups


def tabular(rows: list[PairSummary], part: TablePart) -> list[str]:
    """The ``tabular`` of one part: estimator and runs, then the columns; a heading row per
    dataset; booktabs rules."""
    rows = _rows_of(rows, part.datasets)
    columns = part.columns
    width = 2 + len(columns)
    lines = [f"\\begin{{tabular}}{{@{{}}lr{'r' * len(columns)}@{{}}}}", "\\toprule"]
    groups = _groups(columns)
    if groups:
        cells = ["", ""]
        rules = []
        at = 0
        for group, first, last in groups:
            cells += [""] * (first - at)
            span = last - first + 1
            cells.append(f"\\multicolumn{{{span}}}{{c}}{{{latex_escape(group)}}}")
            rules.append(f"\\cmidrule(lr){{{3 + first}-{3 + last}}}")
            at = last + 1
        cells += [""] * (len(columns) - at)
        lines.append(" & ".join(cells) + " \\\\")
        lines.append(" ".join(rules))
    headers = _header_lines(columns)
    for level, line in enumerate(headers):
        lead = ["estimator", "runs"] if level == 0 else ["", ""]
        if not any(line) and level > 0:
            continue
        # a unit such as [m] is braced: "\\ [m]" would read as a row skip
        cells = lead + [f"{{{latex_escape(text)}}}" if text else "" for text in line]
        lines.append(" & ".join(cells) + " \\\\")
    lines.append("\\midrule")
    grid = _cells(rows, columns)
    previous = None
    for row, row_cells in zip(rows, grid, strict=True):
        if row.dataset != previous:
            if previous is not None:
                lines.append("\\addlinespace")
            heading = latex_escape(row.dataset)
            lines.append(f"\\multicolumn{{{width}}}{{@{{}}l}}{{\\textit{{{heading}}}}} \\\\")
            previous = row.dataset
        cells = [latex_escape(row.estimator), _runs_text(row)]
        if row.status in ("n/a", "failed", "missing"):
            cells += [row.status] + [""] * (len(columns) - 1)
        else:
            cells += [cell.latex for cell in row_cells]
        lines.append(" & ".join(cells) + " \\\\")
    lines += ["\\bottomrule", "\\end{tabular}"]
    return lines
