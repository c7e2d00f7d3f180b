"""The default tier's check that a run folder is replaced as a whole: a fault injected in
the middle of the write (deterministic) and one real SIGKILL while the new folder is being
written each leave exactly the earlier run, and the next write tidies up. The repeated
random kills are the study tier's (``tests/test_run_folder_kill.py``)."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

import workbench.run_folder
from workbench.cli import main

ARGV = ["run", "dead-reckoning", "sim:circle", "--data", "duration_s=2", "--no-plots"]


def _content(folder: Path) -> dict[str, bytes]:
    return {path.name: path.read_bytes() for path in folder.iterdir() if path.is_file()}


def _leftovers(root: Path) -> list[str]:
    return [path.name for path in root.iterdir() if path.name.startswith(".run.")]


def test_a_fault_in_the_middle_of_the_write_keeps_the_earlier_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    folder = tmp_path / "run"
    assert main([*ARGV, "--seed", "1", "--out", str(folder)]) == 0
    before = _content(folder)

    def fails(*args, **kwargs):
        raise RuntimeError("injected fault after the trajectories were written")

    monkeypatch.setattr(workbench.run_folder, "save_run_consistency", fails)
    assert main([*ARGV, "--seed", "5", "--out", str(folder)]) == 1  # a bug: internal error
    assert "injected fault" in capsys.readouterr().err
    assert _content(folder) == before
    assert _leftovers(tmp_path) == []


def test_a_kill_while_the_new_folder_is_written_leaves_the_earlier_run(tmp_path: Path) -> None:
    folder = tmp_path / "run"
    assert main([*ARGV, "--seed", "1", "--out", str(folder)]) == 0
    before = _content(folder)
    process = subprocess.Popen(
        [sys.executable, "-c", "import sys; from workbench.cli import main; "
         "sys.exit(main(sys.argv[1:]))", *ARGV, "--seed", "5", "--out", str(folder)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1"},
    )  # fmt: skip
    deadline = time.monotonic() + 120
    while not [name for name in _leftovers(tmp_path) if ".partial-" in name]:
        assert process.poll() is None, "the run ended before its folder was written"
        assert time.monotonic() < deadline
        time.sleep(0.001)
    process.send_signal(signal.SIGKILL)
    process.wait()
    assert _content(folder) == before  # the staging sibling never took the folder's place
    assert main([*ARGV, "--seed", "1", "--out", str(folder)]) == 0  # tidies what was left
    again = _content(folder)  # the same run again (its timing aside)
    assert again.keys() == before.keys() and again["estimate.tum"] == before["estimate.tum"]
    assert _leftovers(tmp_path) == []
