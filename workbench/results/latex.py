"""Paper tables in LaTeX: one ``table`` float per preset (``results.columns``), with a
caption that says what the cells are, booktabs rules, values rounded to their uncertainty
and the best value of each column in bold, each fitting ``\\textwidth``.

Rounding (one convention, stated in every caption): a mean over runs is shown with its
sample std rounded to two significant digits, the mean to the same decimal place, the std in
parentheses in units of the mean's last digit, as siunitx's compact uncertainty does:
0.006716 ± 3.1e-04 -> ``0.00672(31)``; 67.43 ± 12.2 -> ``67(12)``; 1234 ± 156 ->
``1230(160)``. A std of 0 (every run alike) shows the value with up to four significant
digits and ``(0)``: ``27(0)``; one run (no std) shows three significant digits, as do
consistency cells and ratios. Means below 1e-3 or from 1e5 up are written with a power of
ten: ``1.50(30)\\times10^{-5}``.

Bold: per dataset and column, the best mean where the column has a direction (the lowest
error or time, the highest precision, the NEES or NIS closest to 1 by ``|ln x|``), when at
least two rows have a value; rows whose shown value ties with it are bold too.

Width: a table is typeset in ``\\footnotesize`` (never smaller) and its width estimated
from Computer Modern's 8 pt glyph widths (a 10 pt article's footnotesize) plus the column
separation. A table wider than the narrowest 1-inch-margin text width (A4: 452.97 pt;
letter: 469.75 pt) is split: datasets into several tables, and a dataset whose own columns
do not fit into several column groups. No ``\\resizebox``, no scaling.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from workbench.metrics.verdicts import (
    CELL_FALSE_ALARM,
    FEW_RUNS,
    FEW_RUNS_FALSE_ALARM,
    MIN_POOLED_UPDATES,
    MIN_RUNS,
    Verdict,
)
from workbench.results.columns import CELL, LOWER, ONE, POOLED, RATIO, Column
from workbench.results.summary import PairSummary, Stat

TEXT_WIDTH_PT = 452.97
"""\\textwidth of a one-column article on A4 with 1-inch margins (597.51 pt - 2 x 72.27 pt),
the narrower of A4 and letter."""
WIDTH_MARGIN = 0.97
"""Share of the text width a table may fill: the glyph model is Computer Modern's, other
fonts differ by a few per cent."""
COLUMN_SEPARATION_PT = 12.0
"""2 \\tabcolsep (6 pt each side) between two columns; the outer edges are ``@{}``."""
FONT_SIZE_PT = 8.0
"""\\footnotesize of a 10 pt article."""
BOLD_FACTOR = 1.16
"""Computer Modern bold extended over roman at 8 pt (digits 4.90 pt against 4.25 pt)."""

# cmr8 glyph widths in em (its TFM), ASCII; anything else counts as 0.8 em
_GLYPHS_EM = {
    **dict.fromkeys("!',.:;[]`il", 0.295),
    **dict.fromkeys("fj", 0.325),
    "-": 0.354,
    " ": 0.354,
    "I": 0.383,
    **dict.fromkeys("()trs", 0.415),
    **dict.fromkeys("cez", 0.472),
    "?": 0.502,
    **dict.fromkeys('"$*/0123456789\\^ago{}~_', 0.531),
    "J": 0.545,
    **dict.fromkeys("kqvxy", 0.561),
    **dict.fromkeys("Sbdhnpu", 0.59),
    "Z": 0.649,
    "L": 0.664,
    "F": 0.693,
    **dict.fromkeys("EP", 0.723),
    "B": 0.752,
    **dict.fromkeys("CTw", 0.767),
    "R": 0.782,
    **dict.fromkeys("AHNUVXY", 0.796),
    "D": 0.811,
    "K": 0.825,
    **dict.fromkeys("&+=@OQ", 0.826),
    "G": 0.834,
    **dict.fromkeys("#%m", 0.885),
    "M": 0.973,
    "W": 1.091,
}
# what a mark or a sign is typeset as, and its width [em]
_SYMBOLS_EM = {
    "✓": 0.833,  # \checkmark (msam)
    "▲": 0.778,  # \blacktriangle
    "▼": 0.778,
    "·": 0.278,  # \cdot
    "ˢ": 0.35,  # \textsuperscript{s} at 70 %
    "×": 0.778,
    "÷": 0.778,
    "±": 0.778,
    " ": 0.354,
}


def text_width_pt(text: str, bold: bool = False, size_pt: float = FONT_SIZE_PT) -> float:
    """Estimated typeset width [pt] of ``text`` (as shown, not as LaTeX source)."""
    em = sum(_GLYPHS_EM.get(char, _SYMBOLS_EM.get(char, 0.8)) for char in text)
    return em * size_pt * (BOLD_FACTOR if bold else 1.0)


# --------------------------------------------------------------------------- rounding


@dataclass(frozen=True)
class Rounded:
    """A number as shown: ``digits`` (the mean, or the mantissa with ``exponent``), the
    uncertainty's digits in units of its last digit (None without one)."""

    digits: str
    uncertainty: str | None = None
    exponent: int | None = None

    def plain(self) -> str:
        """``0.00672(31)``, ``1.50(30)e-05``: for Markdown, terminals and tests."""
        text = self.digits + (f"({self.uncertainty})" if self.uncertainty is not None else "")
        return text if self.exponent is None else f"{text}e{self.exponent:+03d}"

    def shown(self) -> str:
        """What the reader sees (for widths): ``1.50(30)×10-5``."""
        text = self.digits + (f"({self.uncertainty})" if self.uncertainty is not None else "")
        return text if self.exponent is None else f"{text}×10{self.exponent}"

    def latex(self, bold: bool = False) -> str:
        text = self.digits + (f"({self.uncertainty})" if self.uncertainty is not None else "")
        if self.exponent is None:
            return f"\\textbf{{{text}}}" if bold else text
        math = f"{text}\\times10^{{{self.exponent}}}"
        return f"{{\\boldmath${math}$}}" if bold else f"${math}$"


def _needs_exponent(value: float) -> bool:
    return value != 0 and not 1e-3 <= abs(value) < 1e5


def _fixed(value: float, decimals: int) -> str:
    """``value`` rounded to ``decimals`` decimal places (negative: to tens, hundreds)."""
    if decimals > 0:
        return f"{value:.{decimals}f}"
    text = f"{round(value, decimals):.0f}"
    return "0" if text == "-0" else text


def significant(value: float, digits: int = 3) -> Rounded:
    """``value`` to ``digits`` significant digits, trailing zeros kept (``1.00``)."""
    if not math.isfinite(value):
        return Rounded("")
    exponent = None
    if _needs_exponent(value):
        exponent = math.floor(math.log10(abs(value)))
        value = value / 10**exponent
    if value == 0:
        return Rounded("0", None, exponent)
    decimals = digits - 1 - math.floor(math.log10(abs(value)))
    rounded = round(value, decimals)
    if rounded != 0 and math.floor(math.log10(abs(rounded))) > math.floor(math.log10(abs(value))):
        decimals -= 1  # 9.996 -> 10.0, not 10.00
    return Rounded(_fixed(value, max(decimals, 0)), None, exponent)


def round_to_uncertainty(mean: float, std: float | None, digits: int = 2) -> Rounded:
    """The mean rounded to its std (module docstring: the std's ``digits`` significant
    digits, the mean to the same decimal place); ``significant(mean)`` without a std."""
    if std is None or not math.isfinite(std):
        return significant(mean)
    if std == 0:  # every run gave the same value (a landmark count): shown as it is
        exponent = math.floor(math.log10(abs(mean))) if _needs_exponent(mean) else None
        scaled = mean if exponent is None else mean / 10**exponent
        return Rounded(f"{scaled:.4g}", "0", exponent)
    exponent = None
    if _needs_exponent(mean):
        exponent = math.floor(math.log10(abs(mean)))
        mean, std = mean / 10**exponent, std / 10**exponent
    decimals = digits - 1 - math.floor(math.log10(std))
    if round(std, decimals) >= 10 ** (digits - decimals):
        decimals -= 1  # 0.0996 -> 0.10: two digits of the rounded std, not three
    uncertainty = round(std * 10**decimals) if decimals > 0 else round(std, decimals)
    return Rounded(_fixed(mean, decimals), str(int(uncertainty)), exponent)


# --------------------------------------------------------------------------- cells

VERDICT_LATEX = {
    Verdict.CONSISTENT: r"$\checkmark$",
    Verdict.OPTIMISTIC: r"$\blacktriangle$",
    Verdict.CONSERVATIVE: r"$\blacktriangledown$",
    Verdict.TOO_FEW_RUNS: r"$\cdot$",
}
VERDICT_SHOWN = {
    Verdict.CONSISTENT: "✓",
    Verdict.OPTIMISTIC: "▲",
    Verdict.CONSERVATIVE: "▼",
    Verdict.TOO_FEW_RUNS: "·",
}
SMOOTHED_LATEX = r"\textsuperscript{s}"

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
    "÷": r"$\div$",
    "±": r"$\pm$",
    "×": r"$\times$",
    "≥": r"$\geq$",
    "≤": r"$\leq$",
    "ˢ": SMOOTHED_LATEX,
}


def latex_escape(text: str) -> str:
    """``text`` as LaTeX source that prints it (specials and the signs the tables use)."""
    return "".join(_LATEX_SPECIAL.get(character, character) for character in text)


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


# --------------------------------------------------------------------------- layout


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


# --------------------------------------------------------------------------- captions


def _power(value: float) -> str:
    """``1e-06`` -> ``10^{-6}`` (LaTeX math, without dollars)."""
    exponent = round(math.log10(value))
    if math.isclose(value, 10.0**exponent):
        return f"10^{{{exponent}}}"
    return significant(value, 2).latex().strip("$")


def verdict_rule_latex() -> str:
    """The verdict rule and its false-alarm rates, from ``workbench.metrics.verdicts``."""
    return (
        "Verdict: the cell's value against its band, the two-sided chi-square interval of "
        "$M\\nu$ degrees of freedom divided by $M\\nu$ ($M$ runs, $\\nu$ a run's effective "
        "dof: its summed dof over the integrated autocorrelation time of its per-step "
        f"values), at a false-alarm rate of ${_power(FEW_RUNS_FALSE_ALARM)}$ per cell below "
        f"{FEW_RUNS} runs and ${_power(CELL_FALSE_ALARM)}$ from {FEW_RUNS} runs; "
        f"{VERDICT_LATEX[Verdict.CONSISTENT]} inside, {VERDICT_LATEX[Verdict.OPTIMISTIC]} "
        f"above (optimistic: errors larger than the covariance says), "
        f"{VERDICT_LATEX[Verdict.CONSERVATIVE]} below (conservative), "
        f"{VERDICT_LATEX[Verdict.TOO_FEW_RUNS]} no verdict: a NEES cell needs {MIN_RUNS} "
        f"runs, a NIS cell {MIN_POOLED_UPDATES} updates (at any run count: innovations of a "
        "consistent filter are white)"
    )


def _example(rows: list[PairSummary], columns: tuple[Column, ...]) -> str | None:
    """A shown mean(std) of the table and what it stands for, to state the convention."""
    for row in rows:
        for column in columns:
            stat = row.stats.get(column.key) if column.kind not in (CELL, POOLED) else None
            if stat is None or column.kind == RATIO or not stat.std:
                continue
            shown = round_to_uncertainty(stat.mean, stat.std)
            if shown.exponent is not None:
                continue
            decimals = len(shown.digits.partition(".")[2])
            std = int(shown.uncertainty) / 10**decimals
            return f"{shown.latex()} is {shown.digits} $\\pm$ {std:.{decimals}f}"
    return None


def dof_phrase(rows: list[PairSummary], columns: tuple[Column, ...]) -> str:
    """Degrees of freedom per step of each consistency block shown, read from the runs'
    series: one figure or range per block, or per group of datasets where they differ
    (a 3-D pose has 6, a planar one 3)."""
    phrases = []
    for column in columns:
        if column.kind != CELL:
            continue
        spans: dict[str, list[str]] = {}
        for dataset in dict.fromkeys(row.dataset for row in rows):
            found: set[int] = set()
            for row in (r for r in rows if r.dataset == dataset):
                cell = row.cells.get(column.block)
                if cell is None:
                    continue
                key = "nis" if column.block == "nis" else f"{cell.scored}/{column.block}"
                for run in row.finished_runs:
                    series = run.consistency.get(key)
                    if series is not None and len(series.dof):
                        found.update(int(d) for d in set(series.dof.tolist()))
            if found:
                low, high = min(found), max(found)
                spans.setdefault(str(low) if low == high else f"{low}--{high}", []).append(dataset)
        if not spans:
            continue
        name = {"map": "map (all its landmarks jointly)", "nis": "NIS (the stacked update)"}.get(
            column.block, column.header[0]
        )
        if len(spans) == 1:
            phrases.append(f"{name} {next(iter(spans))}")
        else:
            each = ", ".join(
                f"{span} ({', '.join(latex_escape(d) for d in datasets)})"
                for span, datasets in spans.items()
            )
            phrases.append(f"{name} {each}")
    return "; ".join(phrases)


def caption(name: str, rows: list[PairSummary], columns: tuple[Column, ...]) -> str:
    """The caption of a preset's tables of ``rows`` x ``columns`` (module docstring): what
    the cells are, the rounding, the bold rule; for consistency cells the statistic, dof,
    band, runs and verdict rule."""
    title = {
        "accuracy": "Accuracy",
        "consistency": "Consistency",
        "cost": "Cost (wall-clock time on the machine that ran them)",
    }.get(name, "Results")
    sentences = [f"{title} of each estimator (rows) on each dataset (italic headings)."]
    cells = [column for column in columns if column.kind == CELL]
    others = [column for column in columns if column.kind != CELL]
    if others:
        example = _example(rows, tuple(others))
        rounding = (
            "Mean over the runs (runs column) and, in parentheses, its sample std rounded to "
            "two significant digits in units of the mean's last digit"
        )
        sentences.append(
            rounding + (f" ({example})" if example else "") + "; a single run: three "
            "significant digits."
        )
        meanings = [column.meaning for column in others if column.meaning]
        if meanings:
            sentences.append(latex_escape("; ".join(meanings)) + ".")
    if cells:
        sentences.append(
            "Each consistency cell is a NEES per degree of freedom (NIS: each update's "
            "innovation against the prediction before it): a run's values summed over its "
            "steps over their summed dof, averaged over the $M$ runs of the runs column; 1 is "
            "consistent; three significant digits."
        )
        dofs = dof_phrase(rows, tuple(cells))
        if dofs:
            sentences.append(f"Dof per step: {dofs}.")
        sentences.append(verdict_rule_latex() + ".")
        if any(
            block in row.cells and row.cells[block].scored == "smoothed"
            for row in rows
            for block in (column.block for column in cells)
        ):
            sentences.append(
                f"{SMOOTHED_LATEX}: the cell scores the smoothed estimate (the estimator has "
                "no causal one)."
            )
        nees = [
            row.cells[c.block].statistic
            for row in rows
            for c in cells
            if c.block != "nis" and c.block in row.cells
        ]
        if nees and all(s.verdict == Verdict.TOO_FEW_RUNS for s in nees):
            most = max(s.runs for s in nees)
            sentences.append(
                f"With at most {most} run{'s' * (most > 1)} here, no NEES cell has a verdict."
            )
        sentences.append("Each cell's band is in table.csv.")
    directions = {column.direction for column in columns if column.direction}
    if directions:
        rule = []
        if LOWER in directions:
            rule.append("lowest")
        if "higher" in directions:
            rule.append("highest (precision, recall)")
        if ONE in directions:
            rule.append("closest to 1 (smallest $|\\ln x|$)")
        sentences.append(f"Bold: per dataset and column the {', or '.join(rule)}.")
    return " ".join(sentences)


def latex_tables(
    rows: list[PairSummary], name: str, columns: tuple[Column, ...], label: str
) -> str:
    """The ``table`` floats of one preset (or column list) ``name``: one per part
    (``plan_parts``), the first with the full caption, the others referring to it.
    Needs ``\\usepackage{booktabs,amssymb}``; sized for a 10 pt article."""
    parts = plan_parts(rows, columns)
    datasets = list(dict.fromkeys(row.dataset for row in rows))
    header = [
        f"% {name} table written by the workbench (workbench/results/latex.py): "
        "\\input it in a 10 pt article;",
        "% needs \\usepackage{booktabs,amssymb}. Fits \\textwidth with 1-inch margins "
        "(A4 or letter) in \\footnotesize.",
    ]
    if not parts:
        return "\n".join([*header, f"% no run has a value in the {name} columns"]) + "\n"
    lines = list(header)
    shown = {dataset for part in parts for dataset in part.datasets}
    columns_shown = tuple(c for c in columns if any(c in part.columns for part in parts))
    left_out = [dataset for dataset in datasets if dataset not in shown]
    for index, part in enumerate(parts):
        own_label = label if index == 0 else f"{label}-{index + 1}"
        if index == 0:
            text = caption(name, _rows_of(rows, tuple(shown)), columns_shown)
            if len(parts) > 1:
                text += f" Continued in {len(parts) - 1} more table{'s' * (len(parts) > 2)}."
            if left_out:
                text += (
                    " No value of these columns on "
                    + ", ".join(latex_escape(dataset) for dataset in left_out)
                    + "."
                )
        else:
            text = (
                f"{latex_escape(name.capitalize())}, continued "
                f"({index + 1} of {len(parts)}): cells as in Table~\\ref{{{label}}}."
            )
        lines += [
            "\\begin{table}[tbp]",
            "\\centering",
            f"\\caption{{{text}}}",
            f"\\label{{{own_label}}}",
            "\\footnotesize",
            *tabular(rows, part),
            "\\end{table}",
        ]
    return "\n".join(lines) + "\n"
