"""Paper tables in LaTeX: one ``table`` float per preset (``results.columns``), with a
caption that says what the cells are, booktabs rules, values rounded to their uncertainty
and the best value of each column in bold, each fitting ``\\textwidth``.

Modules: ``latex_rounding`` (numbers rounded to their uncertainty), ``latex_text`` (LaTeX
escaping, verdict marks), ``latex_cells`` (a row's value as a cell, the bold rule),
``latex_width`` (glyph widths), ``latex_layout`` (table widths, the split into parts, the
``tabular``), ``latex_captions`` (captions); this module writes the ``table`` floats.
"""

from __future__ import annotations

from workbench.results.columns import Column
from workbench.results.latex_captions import caption
from workbench.results.latex_layout import _rows_of, plan_parts, tabular
from workbench.results.latex_text import latex_escape
from workbench.results.summary import PairSummary


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
