"""Table captions: what the cells are, the rounding convention with an example from the
table, the bold rule, and for consistency cells the statistic, the degrees of freedom per
step, the band and the verdict rule (``workbench.metrics.verdicts``)."""

from __future__ import annotations

import math

from workbench.metrics.verdicts import (
    CELL_FALSE_ALARM,
    FEW_RUNS,
    FEW_RUNS_FALSE_ALARM,
    MIN_POOLED_UPDATES,
    MIN_RUNS,
    Verdict,
)
from workbench.results.columns import CELL, LOWER, ONE, POOLED, RATIO, Column
from workbench.results.latex_rounding import round_to_uncertainty, significant
from workbench.results.latex_text import SMOOTHED_LATEX, VERDICT_LATEX, latex_escape
from workbench.results.summary import PairSummary


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
    the cells are, the rounding (``results.latex_rounding``), the bold rule
    (``results.latex_cells``); for consistency cells the statistic, dof, band, runs and
    verdict rule."""
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
