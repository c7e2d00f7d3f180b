"""``workbench.compare`` (the Python API) shows the rows ``workbench report`` shows: runs that
differ in more than their seed are separate rows, and it writes only where the workbench may
(issue 36's run identity, issue 40's --out safety)."""

from __future__ import annotations

from pathlib import Path

import pytest

from datasets.errors import InputError


def test_compare_keeps_experiments_apart_and_never_writes_into_a_user_folder(
    tmp_path: Path,
) -> None:
    from workbench import compare, run

    for duration in (1, 2):
        run(
            "dead-reckoning",
            "sim:circle",
            seed=0,
            data={"duration_s": duration},
            out=tmp_path / "runs" / f"d{duration}",
        )
    table = compare([tmp_path / "runs"])
    assert len(table) == 2  # one row per setting, never a mean over both
    # each row labelled by what differs
    assert sorted(table["dataset"]) == ["sim:circle [duration_s=1]", "sim:circle [duration_s=2]"]

    user = tmp_path / "mine"
    user.mkdir()
    (user / "notes.txt").write_text("my notes")
    with pytest.raises(InputError, match="notes.txt"):
        compare([tmp_path / "runs"], out=user)
    assert sorted(p.name for p in user.iterdir()) == ["notes.txt"]
    written = compare([tmp_path / "runs"], out=tmp_path / "report")
    assert len(written) == 2 and (tmp_path / "report" / "table.csv").is_file()
