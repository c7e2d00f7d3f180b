"""The terminal table fits the terminal it is printed on: a table too wide closes up or
splits; a dataset whose only accuracy figure is a GPS hold-out shows it. (``workbench bench
tiny`` under ``COLUMNS=100``, the whole command's output, is checked in
``tests/test_bench.py`` on the run its other tests read.)"""

from __future__ import annotations

from rich.console import Console

from workbench.metrics.verdicts import CellStatistic, Verdict
from workbench.results.consistency import TABLE_BLOCKS, ConsistencyCell
from workbench.results.summary import PairSummary, Stat
from workbench.results.tables import terminal_tables


def _rendered(tables: list, width: int) -> list[str]:
    console = Console(width=width, color_system=None, force_terminal=False)
    with console.capture() as captured:
        for table in tables:
            console.print(table)
    return captured.get().splitlines()


def _kitti_like() -> list[PairSummary]:
    """kitti-imu-gps as the quick suite has it: the GPS hold-out is the only accuracy
    figure (seed 0, 60 s: iSAM2 1.66 m causal, the batch smoother 1.152 m smoothed)."""
    return [
        PairSummary(
            "kitti-imu-gps",
            "smoother-isam2",
            "smoother-isam2",
            "ok",
            1,
            1,
            None,
            stats={
                "gps_holdout_rmse_m": Stat(1.66, None, 1),
                "gps_holdout_rmse_smoothed_m": Stat(1.1507, None, 1),
            },
        ),
        PairSummary(
            "kitti-imu-gps",
            "smoother-batch",
            "smoother-batch",
            "ok",
            1,
            1,
            None,
            stats={"gps_holdout_rmse_smoothed_m": Stat(1.1521, None, 1)},
        ),
    ]


def test_a_gps_hold_out_is_shown_where_it_is_the_only_accuracy_figure() -> None:
    lines = _rendered(terminal_tables(_kitti_like(), "suite quick", width=100), 100)
    text = "\n".join(lines)
    assert "GPS hold-out" in text and "ATE" not in text
    (isam2,) = [line for line in lines if "smoother-isam2" in line]
    (batch,) = [line for line in lines if "smoother-batch" in line]
    assert "1.66" in isam2 and "1.15ˢ" in batch  # the batch smoother's is its smoothed one


def test_a_table_too_wide_for_the_terminal_splits_its_consistency_columns() -> None:
    cell = ConsistencyCell(
        "pose", "causal", CellStatistic(1.234, 0.9, 1.1, Verdict.OPTIMISTIC, 3, 9.0), None
    )
    row = PairSummary(
        "sim:guerreiro-loop (model-matched)",
        "smoother-fixed-lag [lag_s=2]",
        "smoother-fixed-lag",
        "ok",
        3,
        3,
        None,
        stats={"ate_rmse_m": Stat(0.0123, 0.001, 3), "time_total_s": Stat(4.5, 0.2, 3)},
        cells={block: cell for block in TABLE_BLOCKS},
    )
    wide = terminal_tables([row], "suite x")
    assert len(wide) == 1
    natural = max(len(line) for line in _rendered(wide, 1000))
    assert natural > 80
    narrow = terminal_tables([row], "suite x", width=80)
    assert len(narrow) == 2  # accuracy and cost, then the NEES and NIS columns
    lines = _rendered(narrow, 80)
    assert max(len(line) for line in lines) <= 80
    assert sum("▲" in line for line in lines) == 1 and "(consistency)" in "\n".join(lines)
