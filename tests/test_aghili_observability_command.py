"""``workbench observability``: eq. (22) per segment and eqs. (30)/(32) over segments along
the rover's true path, with 3 and 1 anchors; and the trajectory function on a straight line."""

from __future__ import annotations

import numpy as np

from filters.aghili.observability import observability_along_trajectory
from workbench.cli import main


def table(argv, capsys) -> list[list[str]]:
    assert main(argv) == 0
    lines = capsys.readouterr().out.splitlines()
    return [line.split() for line in lines[2:]]


def test_three_anchors_full_rank_at_every_segment(capsys) -> None:
    rows = table(
        ["observability", "sim:aghili-rover", "--set", "anchors=3", "--set", "step_s=30"], capsys
    )
    assert len(rows) == 5  # 144 s lap: t = 0, 30, ..., 120
    for t, rank, _, pi_sv, collinear, total, _, stripped, _ in rows:
        assert rank == "24" and collinear == "False" and float(pi_sv) > 1e-3
    assert [row[5] for row in rows] == ["-", "-", "24", "24", "24"]


def test_one_anchor_deficient_per_segment_total_and_stripped_reported(capsys) -> None:
    """Per segment rank 21 of 24 (rotation about gravity and the two tilts through the anchor
    are lost); the total/stripped matrices over moving segments are what they are: full
    rank on the rover (the piecewise-constant artefact), printed, not forced."""
    rows = table(
        ["observability", "sim:aghili-rover", "--set", "anchors=1", "--set", "step_s=30"], capsys
    )
    for row in rows:
        assert int(row[1]) == 21 and float(row[2]) < 1e-9 and row[3] == "-"
    ranks = [int(row[5]) for row in rows if row[5] != "-"]
    assert ranks and all(21 <= rank <= 24 for rank in ranks)


def test_bad_option_is_one_error_line(capsys) -> None:
    assert main(["observability", "sim:aghili-rover", "--set", "step_s=-1"]) == 2
    assert "step_s > 0" in capsys.readouterr().err


def test_trajectory_function_finite_difference_inputs_on_a_straight_path() -> None:
    """A constant-velocity straight line with no rotation: the per-segment matrices are the
    same everywhere, so total and stripped ranks equal the per-segment rank with one anchor
    (no change of geometry to exploit beyond the translation)."""
    times = np.linspace(0.0, 40.0, 401)
    positions = np.c_[times * 1.0, np.zeros_like(times), np.zeros_like(times)]
    rotations = np.repeat(np.eye(3)[None], len(times), axis=0)
    anchors = np.array([[5.0, 3.0, 1.0]])
    landmarks = np.array([[10.0, -4.0, 2.0], [20.0, 5.0, 0.5]])
    reports = observability_along_trajectory(
        times, rotations, positions, anchors, landmarks, 10.0, 2, window=3
    )
    assert [report.segment.rank for report in reports] == [18] * 4
    assert reports[2].total is not None and reports[2].total.rank >= 18
