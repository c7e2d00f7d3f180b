"""``--out`` never destroys what the workbench did not write, every path stays inside it,
and one writer at a time (``workbench.owned_folders``)."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from workbench.cli import main
from workbench.owned_folders import (
    COLLECTION,
    MARKER_FILE,
    RUN,
    exclusive,
    folder_kind,
    lock_path,
)
from workbench.suites import slug

QUICK_RUN = ["dead-reckoning", "sim:circle", "--data", "duration_s=2", "--no-plots"]


def _users_folder(root: Path) -> Path:
    victim = root / "victim"
    (victim / "data").mkdir(parents=True)
    (victim / "thesis.tex").write_text("\\documentclass{article}\n")
    (victim / "data" / "table.csv").write_text("1,2\n")
    return victim


def _untouched(victim: Path) -> bool:
    return (
        sorted(p.name for p in victim.iterdir()) == ["data", "thesis.tex"]
        and (victim / "thesis.tex").read_text() == "\\documentclass{article}\n"
        and (victim / "data" / "table.csv").read_text() == "1,2\n"
    )


def _one_error_line(capsys: pytest.CaptureFixture[str], *names: str) -> str:
    err = capsys.readouterr().err
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert len(lines) == 1, err
    assert "Traceback" not in err
    for name in names:
        assert name in lines[0], lines[0]
    return lines[0]


@pytest.mark.parametrize(
    "command",
    [
        ["run", *QUICK_RUN],
        ["simulate", "circle", "--data", "duration_s=2"],
        ["bench", "tiny", "--runs", "1", "--no-plots"],
        ["report", "RUNS", "--no-plots"],
        ["bag", "NO_SUCH.bag"],  # the folder is checked before the bag is read
    ],
    ids=["run", "simulate", "bench", "report", "bag"],
)
def test_a_users_folder_is_never_written(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], command: list[str]
) -> None:
    victim = _users_folder(tmp_path)
    if "RUNS" in command:
        assert main(["run", *QUICK_RUN, "--out", str(tmp_path / "a-run")]) == 0
        command = [str(tmp_path / "a-run") if part == "RUNS" else part for part in command]
        capsys.readouterr()
    assert main([*command, "--out", str(victim)]) == 2
    _one_error_line(capsys, str(victim), "did not write")
    assert _untouched(victim)
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".victim")]


def test_rerun_into_a_users_folder_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    first = tmp_path / "first"
    assert main(["run", *QUICK_RUN, "--out", str(first)]) == 0
    victim = _users_folder(tmp_path)
    assert main(["rerun", str(first), "--out", str(victim), "--no-plots"]) == 2
    _one_error_line(capsys, str(victim))
    assert _untouched(victim)


def test_the_workbench_replaces_its_own_folders(tmp_path: Path) -> None:
    """A run folder replaces an empty folder, an earlier run folder, and a run folder
    written before folders carried a marker; it never replaces a suite's folder."""
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["run", *QUICK_RUN, "--out", str(empty)]) == 0
    assert folder_kind(empty) == RUN
    assert main(["run", *QUICK_RUN, "--seed", "1", "--out", str(empty)]) == 0
    legacy = tmp_path / "legacy"
    assert main(["run", *QUICK_RUN, "--out", str(legacy)]) == 0
    (legacy / MARKER_FILE).unlink()
    assert folder_kind(legacy) == RUN  # recognised by its file names
    assert main(["run", *QUICK_RUN, "--seed", "2", "--out", str(legacy)]) == 0
    assert (legacy / MARKER_FILE).is_file()
    collection = tmp_path / "collection"
    assert main(["report", str(legacy), "--no-plots", "--out", str(collection)]) == 0
    assert folder_kind(collection) == COLLECTION
    assert main(["run", *QUICK_RUN, "--out", str(collection)]) == 2
    assert (collection / "table.md").is_file()


def test_suite_labels_cannot_leave_out() -> None:
    for label in ("..", ".", "../..", "../x", ".hidden", "/etc/passwd", "a/../../b"):
        name = slug(label)
        assert name not in ("", ".", "..") and "/" not in name and not name.startswith(".")


def test_a_suite_labelled_dot_dot_writes_inside_out(tmp_path: Path) -> None:
    suite = tmp_path / "dots.yaml"
    suite.write_text(
        "runs: 1\ndatasets:\n  - name: sim:circle\n    label: '..'\n"
        "    data: {duration_s: 2}\nestimators:\n  - name: dead-reckoning\n    label: '../..'\n"
    )
    out = tmp_path / "deep" / "out"
    assert main(["bench", str(suite), "--no-plots", "--workers", "1", "--out", str(out)]) == 0
    written = {p.resolve() for p in tmp_path.rglob("*")}
    assert all(out.resolve() in (p, *p.parents) or p == suite for p in written if p != out.parent)


def _cli(*arguments: str) -> list[str]:
    return [sys.executable, "-c", "import sys; from workbench.cli import main; "
            "sys.exit(main(sys.argv[1:]))", *arguments]  # fmt: skip


def test_a_second_writer_exits_2_naming_the_first(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Two runs into one folder at once: the second exits 2 naming the first's process,
    the first's folder is whole."""
    out = tmp_path / "shared"
    first = subprocess.Popen(
        _cli(
            "run",
            "dead-reckoning",
            "sim:circle",
            "--data",
            "duration_s=60",
            "--no-plots",
            "--out",
            str(out),
        ),  # fmt: skip
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        env={**os.environ, "OPENBLAS_NUM_THREADS": "1"},
    )
    try:
        deadline = time.monotonic() + 60
        lock = lock_path(out)
        while not (lock.is_file() and lock.read_text().strip()):
            assert first.poll() is None, first.stderr.read()
            assert time.monotonic() < deadline
            time.sleep(0.02)
        assert main(["run", *QUICK_RUN, "--out", str(out)]) == 2
        _one_error_line(capsys, str(out), f"pid {first.pid}")
    finally:
        assert first.wait(timeout=300) == 0, first.stderr.read()
    assert {"config.yaml", "estimate.tum", "estimate.npz", "metrics.json"} <= {
        p.name for p in out.iterdir()
    }
    assert not lock.exists()


def test_the_lock_is_reentrant_and_released(tmp_path: Path) -> None:
    folder = tmp_path / "f"
    with exclusive(folder), exclusive(folder):
        assert lock_path(folder).read_text().strip() == str(os.getpid())
    assert not lock_path(folder).exists()
    with exclusive(folder):
        pass
