"""Paper tables (``workbench.results.latex``, ``results.columns``) on hand-made rows: the
rounding rule, the bold-best rule, the caption, the split of a table too wide for the page,
and the ``--table`` / suite ``table:`` choices. No run, no TeX: seconds."""

from __future__ import annotations

import math
import re
from pathlib import Path

import pytest

from datasets.errors import InputError
from workbench.cli import main
from workbench.metrics.verdicts import (
    CELL_FALSE_ALARM,
    FEW_RUNS_FALSE_ALARM,
    MIN_POOLED_UPDATES,
    MIN_RUNS,
    CellStatistic,
    Verdict,
)
from workbench.results.columns import COLUMNS, PRESETS, parse_table_choice
from workbench.results.consistency import ConsistencyCell
from workbench.results.latex import latex_tables
from workbench.results.latex_cells import Cell, best_rows
from workbench.results.latex_layout import table_width_pt
from workbench.results.latex_rounding import round_to_uncertainty, significant
from workbench.results.latex_width import TEXT_WIDTH_PT
from workbench.results.summary import PairSummary, Stat
from workbench.suite_files import load_suite_file, suite_table


@pytest.mark.parametrize(
    ("mean", "std", "shown"),
    [
        (0.006716, 3.1e-4, "0.00672(31)"),  # the example
        (67.43, 12.2, "67(12)"),
        (1234.0, 156.0, "1230(160)"),  # the std's two digits reach the tens
        (1.2345, 0.0996, "1.23(10)"),  # 0.0996 rounds up to 0.10: two digits, not three
        (1.5e-5, 3e-6, "1.50(30)e-05"),  # below 1e-3: a power of ten
        (123456.0, 789.0, "1.2346(79)e+05"),
        (27.0, 0.0, "27(0)"),  # every run alike
        (0.05424, None, "0.0542"),  # one run: three significant digits
        (1.0, None, "1.00"),
        (9.996, None, "10.0"),
        (220.6, None, "221"),
    ],
)
def test_a_mean_is_rounded_to_two_digits_of_its_std(mean, std, shown) -> None:
    assert round_to_uncertainty(mean, std).plain() == shown


def test_the_latex_of_a_rounded_number() -> None:
    assert round_to_uncertainty(1.5e-5, 3e-6).latex() == "$1.50(30)\\times10^{-5}$"
    assert round_to_uncertainty(0.006716, 3.1e-4).latex(bold=True) == "\\textbf{0.00672(31)}"
    assert significant(2.5e-6).latex(bold=True) == "{\\boldmath$2.50\\times10^{-6}$}"


def test_the_best_cell_is_the_lowest_or_the_closest_to_one() -> None:
    def cells(*values):
        return [Cell(None if v is None else significant(v), v) for v in values]

    assert best_rows(cells(0.05, 0.03, None, 0.04), "lower") == {1}
    assert best_rows(cells(0.5, 0.9), "higher") == {1}
    # closest to 1 on a log scale: 1.1 (|ln| 0.095) beats 0.8 (0.22) and 2.0 (0.69)
    assert best_rows(cells(0.8, 1.1, 2.0), "one") == {1}
    assert best_rows(cells(0.5, 2.0), "one") == {0, 1}  # equally far
    # ties as shown are bold together; a lone value or no direction: nothing bold
    assert best_rows(cells(0.030001, 0.030002, 0.5), "lower") == {0, 1}
    assert best_rows(cells(0.05, None), "lower") == set()
    assert best_rows(cells(0.05, 0.03), None) == set()


def _cell(block: str, value: float, verdict: Verdict, scored: str = "causal") -> ConsistencyCell:
    return ConsistencyCell(block, scored, CellStatistic(value, 0.9, 1.1, verdict, 3, 50.0), None)


def _rows() -> list[PairSummary]:
    """Three estimators on one dataset: a, b with ATE over 3 runs, c n/a; NEES cells."""
    return [
        PairSummary(
            "sim:x",
            "a",
            "a",
            "ok",
            3,
            3,
            None,
            stats={"ate_rmse_m": Stat(0.05, 0.004, 3), "time_total_s": Stat(2.0, 0.1, 3)},
            cells={
                "pose": _cell("pose", 0.8, Verdict.TOO_FEW_RUNS),
                "nis": _cell("nis", 1.02, Verdict.CONSISTENT),
            },
        ),
        PairSummary(
            "sim:x",
            "b",
            "b",
            "ok",
            3,
            3,
            None,
            stats={"ate_rmse_m": Stat(0.006716, 3.1e-4, 3), "time_total_s": Stat(9.0, 1.0, 3)},
            cells={
                "pose": _cell("pose", 1.1, Verdict.TOO_FEW_RUNS, "smoothed"),
                "nis": _cell("nis", 0.3, Verdict.CONSERVATIVE),
            },
        ),
        PairSummary("sim:x", "c", "c", "n/a", 0, 0, "needs imu"),
    ]


def _lines_of(text: str, estimator: str) -> str:
    (line,) = [line for line in text.splitlines() if line.startswith(f"{estimator} & ")]
    return line


def test_an_accuracy_table_bolds_the_lowest_and_says_what_its_cells_are() -> None:
    ((name, columns),) = parse_table_choice("accuracy")
    text = latex_tables(_rows(), name, columns, "tab:t-accuracy")
    assert text.count("\\begin{table}") == 1 and "\\label{tab:t-accuracy}" in text
    assert "\\toprule" in text and "\\midrule" in text and "\\bottomrule" in text
    assert "\\footnotesize" in text
    assert not re.search(r"\\(resizebox|scalebox|tiny|scriptsize)", text)
    assert _lines_of(text, "a") == "a & 3 & 0.0500(40) \\\\"
    assert _lines_of(text, "b") == "b & 3 & \\textbf{0.00672(31)} \\\\"
    assert _lines_of(text, "c").startswith("c & -- & n/a")
    # the convention, stated with a value of this table
    assert "0.0500(40) is 0.0500 $\\pm$ 0.0040" in text and "lowest" in text
    assert "{ATE} \\\\" in text and "{[m]} \\\\" in text  # units braced: "\\ [m]" is a skip


def test_a_consistency_table_states_the_rule_and_marks_verdicts() -> None:
    ((name, columns),) = parse_table_choice("consistency")
    text = latex_tables(_rows(), name, columns, "tab:t-consistency")
    # closest to 1: 1.1 (b, smoothed) beats 0.8; NIS 1.02 beats 0.3
    assert "\\textbf{1.10}\\textsuperscript{s}\\,$\\cdot$" in _lines_of(text, "b")
    assert "\\textbf{1.02}\\,$\\checkmark$" in _lines_of(text, "a")
    assert "0.300\\,$\\blacktriangledown$" in _lines_of(text, "b")
    caption = re.search(r"\\caption\{(.*)\}\n", text).group(1)
    # the rule's numbers are the code's, not typed in
    assert f"{MIN_RUNS} runs" in caption and f"{MIN_POOLED_UPDATES} updates" in caption
    for level in (CELL_FALSE_ALARM, FEW_RUNS_FALSE_ALARM):
        assert f"$10^{{{round(math.log10(level))}}}$" in caption
    assert "chi-square" in caption and "$M\\nu$" in caption and "per degree of freedom" in caption
    assert "no NEES cell has a verdict" in caption  # every NEES cell here has too few runs
    # only the pose of the NEES blocks is filled: its group heading spans one column
    assert "\\multicolumn{1}{c}{NEES per dof}" in text and "\\cmidrule(lr){3-3}" in text


def test_a_table_wider_than_the_page_is_split_and_every_part_fits() -> None:
    """Every stat column of table.csv for two datasets: far wider than a page."""
    keys = [key for key, column in COLUMNS.items() if column.kind == "stat"]
    stats = {key: Stat(123.456 + i, 7.89, 3) for i, key in enumerate(keys)}
    rows = [
        PairSummary(d, e, e, "ok", 3, 3, None, stats=stats)
        for d in ("sim:one", "sim:two")
        for e in ("smoother-fixed-lag", "ekf-slam")
    ]
    ((name, columns),) = parse_table_choice(",".join(keys))
    assert name == "custom" and len(columns) == len(keys)
    text = latex_tables(rows, name, columns, "tab:wide")
    parts = text.count("\\begin{table}")
    assert parts >= 4  # both datasets, each in several column groups
    assert "\\label{tab:wide-2}" in text and "Table~\\ref{tab:wide}" in text
    for header in re.findall(r"\\begin\{tabular\}.*?\\end\{tabular\}", text, flags=re.S):
        shown = {key for key in keys if f"{{{COLUMNS[key].header[0]}}}" in header}
        assert shown  # no empty part
    # each part's estimated width fits, and every column appears in some part
    from workbench.results.latex_layout import plan_parts

    planned = plan_parts(rows, columns)
    assert len(planned) == parts
    assert {c.key for part in planned for c in part.columns} == set(keys)
    for part in planned:
        own = [row for row in rows if row.dataset in part.datasets]
        assert table_width_pt(own, part.columns) <= TEXT_WIDTH_PT


def test_table_choices_and_their_errors(tmp_path: Path, capsys) -> None:
    assert [name for name, _ in parse_table_choice("all")] == list(PRESETS)
    ((_, columns),) = parse_table_choice("ate_rmse_m, anees_pose_per_dof")
    assert [c.key for c in columns] == ["ate_rmse_m", "anees_pose_per_dof"]
    with pytest.raises(InputError, match="did you mean 'accuracy'"):
        parse_table_choice("acuracy")
    # the command line: one error line naming the culprit, exit 2, before any folder is read
    assert main(["report", str(tmp_path / "none"), "--table", "ate_rmse"]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "'ate_rmse'" in err


def test_a_suite_file_chooses_its_table(tmp_path: Path) -> None:
    suite = tmp_path / "mine.yaml"
    suite.write_text("table: cost\ndatasets: [sim:circle]\nestimators: [ekf-slam]\n")
    load_suite_file(suite)
    assert suite_table(str(suite)) == "cost"
    assert suite_table("quick") == "all" and suite_table("consistency") == "consistency"
    suite.write_text("table: costs\ndatasets: [sim:circle]\nestimators: [ekf-slam]\n")
    with pytest.raises(InputError, match=r"mine\.yaml.*'costs'.*did you mean 'cost'"):
        load_suite_file(suite)
