"""One value of a table (``Cell``): how a row's value in a column becomes a rounded,
marked cell, and which cells are bold.

Bold: per dataset and column, the best mean where the column has a direction (the lowest
error or time, the highest precision, the NEES or NIS closest to 1 by ``|ln x|``), when at
least two rows have a value; rows whose shown value ties with it are bold too.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from workbench.metrics.verdicts import Verdict
from workbench.results.columns import CELL, LOWER, ONE, POOLED, RATIO, Column
from workbench.results.latex_rounding import Rounded, round_to_uncertainty, significant
from workbench.results.latex_text import SMOOTHED_LATEX, VERDICT_LATEX, VERDICT_SHOWN
from workbench.results.latex_width import text_width_pt
from workbench.results.summary import PairSummary, Stat


@dataclass(frozen=True)
class Cell:
    """One value of a table: its number, its decorations and what bold compares.

    Attributes:
        number: the rounded number (None: an empty cell).
        value: the number the best is chosen by (None: no value).
        mark: the verdict of a consistency cell, or None.
        smoothed: whether the cell scores the smoothed estimate (superscript s).
        bold: whether the number is set in bold (``best_rows``).
    """

    number: Rounded | None
    value: float | None = None
    mark: Verdict | None = None
    smoothed: bool = False
    bold: bool = False

    @property
    def tie(self) -> str:
        """What ties compare: the shown number without its uncertainty."""
        if self.number is None:
            return ""
        return f"{self.number.digits}e{self.number.exponent}"

    @property
    def latex(self) -> str:
        if self.number is None:
            return ""
        text = self.number.latex(self.bold) + (SMOOTHED_LATEX if self.smoothed else "")
        return text + (f"\\,{VERDICT_LATEX[self.mark]}" if self.mark is not None else "")

    @property
    def shown(self) -> str:
        if self.number is None:
            return ""
        text = self.number.shown() + ("ˢ" if self.smoothed else "")
        return text + (f" {VERDICT_SHOWN[self.mark]}" if self.mark is not None else "")

    def width_pt(self) -> float:
        """Estimated width [pt]: the number in its weight, the marks in roman."""
        if self.number is None:
            return 0.0
        marks = self.shown[len(self.number.shown()) :]
        return text_width_pt(self.number.shown(), self.bold) + text_width_pt(marks)


_EMPTY = Cell(None)


def column_value(row: PairSummary, column: Column) -> Stat | float | object | None:
    """The row's value of ``column``: a ``Stat``, a ``ConsistencyCell`` or a float."""
    if column.kind == CELL:
        return row.cells.get(column.block)
    if column.kind == POOLED:
        value = row.nis_per_dof
        return value if value is not None and math.isfinite(value) else None
    return row.stats.get(column.key)


def make_cell(row: PairSummary, column: Column) -> Cell:
    """The cell of ``row`` in ``column`` (not bold)."""
    found = column_value(row, column)
    if found is None:
        return _EMPTY
    if column.kind == CELL:
        statistic = found.statistic
        return Cell(
            significant(statistic.value),
            statistic.value,
            statistic.verdict,
            found.scored == "smoothed",
        )
    if column.kind == POOLED:
        return Cell(significant(found), found)
    stat: Stat = found
    if column.kind == RATIO:
        return Cell(significant(stat.mean), stat.mean)
    return Cell(round_to_uncertainty(stat.mean, stat.std), stat.mean)


def best_rows(cells: list[Cell], direction: str | None) -> set[int]:
    """Indices of the best cells (module docstring): none without a direction or with
    fewer than two values; every cell that ties with the best."""
    if direction is None:
        return set()
    scored = {}
    for index, cell in enumerate(cells):
        if cell.value is None or not math.isfinite(cell.value):
            continue
        if direction == ONE:
            if cell.value <= 0:
                continue
            scored[index] = abs(math.log(cell.value))
        else:
            scored[index] = cell.value if direction == LOWER else -cell.value
    if len(scored) < 2:
        return set()
    best = min(scored, key=scored.get)
    return {
        index
        for index in scored
        if scored[index] == scored[best] or cells[index].tie == cells[best].tie
    }
