"""Corrupted configuration, suite and option files, resource-sized options, damaged results
on disk, bad Dask schedulers and a full disk, through the CLI (``tests/test_bad_input_corpus.py``
has the data files): every case exits 2 with one ``error:`` line naming the culprit (file
and line, key, option and value, or address), no traceback, and an earlier run folder
given as ``--out`` is left as it was. Inputs are generated in ``tmp_path``."""

from __future__ import annotations

import errno
import shutil
import socket
import threading
import time
import zipfile
from collections.abc import Callable, Iterator
from pathlib import Path

import numpy as np
import pytest

from tests.test_bad_input_corpus import earlier_run  # noqa: F401 - the shared earlier run
from workbench.cli import main

Builder = Callable[[Path, Path], list[str]]
"""Writes the case's files into a folder (given the earlier run folder to copy from) and
returns the command's arguments."""


def _one_error(status: int, err: str, culprit: str) -> str:
    """The case's single error line, after the checks every case makes."""
    lines = [line for line in err.splitlines() if line.strip()]
    assert status == 2, (status, err)
    assert len(lines) == 1 and lines[0].startswith("error: "), lines
    assert culprit in lines[0], lines[0]
    assert "Traceback" not in err and "internal error" not in err
    return lines[0]


# --------------------------------------------------------------------- YAML files
def _config(content: str | bytes) -> Builder:
    def build(folder: Path, _: Path) -> list[str]:
        path = folder / "config.yaml"
        path.write_bytes(content) if isinstance(content, bytes) else path.write_text(content)
        data = ["--data", "duration_s=1", "--no-plots"]
        return ["run", "ekf-slam", "sim:circle", *data, "--config", str(path)]

    return build


def _suite(content: str | bytes) -> Builder:
    def build(folder: Path, _: Path) -> list[str]:
        path = folder / "mine.yaml"
        path.write_bytes(content) if isinstance(content, bytes) else path.write_text(content)
        return ["bench", str(path), "--out", str(folder / "bench")]

    return build


def _laughs(levels: int = 9) -> str:
    """The billion-laughs suite: each level nine aliases of the one before (a few hundred
    bytes that would expand to 9**9 strings)."""
    lines = ["description: &a [lol, lol, lol, lol, lol, lol, lol, lol, lol]"]
    for level in range(1, levels):
        name, previous = chr(ord("a") + level), chr(ord("a") + level - 1)
        lines.append(f"x{name}: &{name} [{', '.join(['*' + previous] * 9)}]")
    return "\n".join(lines) + "\ndatasets: [sim:circle]\nestimators: [ekf-slam]\n"


SUITE_OK = "datasets: [sim:circle]\nestimators: [dead-reckoning]\n"
BIG = "# " + "x" * (1 << 20) + "\n"  # over the 1 MiB limit, all comment

# --------------------------------------------------------------------- rerun config.yaml


def _rerun(edit: Callable[[str], str | bytes]) -> Builder:
    """A copy of the earlier run whose config.yaml ``edit`` rewrites, rerun into --out."""

    def build(folder: Path, earlier: Path) -> list[str]:
        copy = folder / "recorded"
        shutil.copytree(earlier, copy)
        text = edit((copy / "config.yaml").read_text())
        path = copy / "config.yaml"
        path.write_bytes(text) if isinstance(text, bytes) else path.write_text(text)
        return ["rerun", str(copy), "--no-plots"]

    return build


def _top_level(key: str, value: str) -> Callable[[str], str]:
    """Replace a top-level ``key: ...`` line (nested keys of the same name are indented)."""

    def edit(text: str) -> str:
        lines = text.splitlines()
        index = next(i for i, line in enumerate(lines) if line.startswith(f"{key}:"))
        # a block value continues on indented lines: replace them with the new value too
        end = index + 1
        while end < len(lines) and lines[end].startswith(" "):
            end += 1
        return "\n".join([*lines[:index], f"{key}: {value}", *lines[end:]]) + "\n"

    return edit


# --------------------------------------------------------------------- results on disk
def _report(change: Callable[[Path], None]) -> Builder:
    """A copy of the earlier run, damaged by ``change``, given to ``workbench report``."""

    def build(folder: Path, earlier: Path) -> list[str]:
        copy = folder / "run"
        shutil.copytree(earlier, copy)
        change(copy)
        return ["report", str(copy), "--out", str(folder / "report"), "--no-plots"]

    return build


def _npz_arrays(run: Path) -> dict[str, np.ndarray]:
    with np.load(run / "estimate.npz") as stored:
        return {key: stored[key] for key in stored.files}


def _npz_edit(edit: Callable[[dict[str, np.ndarray]], None]) -> Callable[[Path], None]:
    def change(run: Path) -> None:
        arrays = _npz_arrays(run)
        edit(arrays)
        np.savez_compressed(run / "estimate.npz", **arrays)

    return change


def _npz_bytes(data: Callable[[bytes], bytes]) -> Callable[[Path], None]:
    def change(run: Path) -> None:
        path = run / "estimate.npz"
        path.write_bytes(data(path.read_bytes()))

    return change


def _zip_of_text(run: Path) -> None:
    with zipfile.ZipFile(run / "estimate.npz", "w") as archive:
        archive.writestr("hello.txt", "not an array")


def _header_claims_more(run: Path) -> None:
    """An npz whose ``pose_t`` header states 10**12 samples over 80 bytes of data (the
    reader would allocate 8 TB)."""
    arrays = _npz_arrays(run)
    with zipfile.ZipFile(run / "estimate.npz", "w") as archive:
        for key, value in arrays.items():
            with archive.open(f"{key}.npy", "w") as member:
                if key == "pose_t":
                    header = {"descr": "<f8", "fortran_order": False, "shape": (10**12,)}
                    np.lib.format.write_array_header_1_0(member, header)
                    member.write(np.zeros(10).tobytes())
                else:
                    np.lib.format.write_array(member, value, allow_pickle=False)


def _metrics(edit: Callable[[str], str | bytes]) -> Callable[[Path], None]:
    def change(run: Path) -> None:
        path = run / "metrics.json"
        text = edit(path.read_text())
        path.write_bytes(text) if isinstance(text, bytes) else path.write_text(text)

    return change


def _json_value(key: str, value: str) -> Callable[[str], str]:
    """Set a top-level metrics.json key to the JSON text ``value`` (the file is written with
    one key a line, ``run_folder.dump_json``)."""

    def edit(text: str) -> str:
        lines = text.splitlines()
        index = next(i for i, line in enumerate(lines) if line.startswith(f'  "{key}": '))
        comma = "," if lines[index].rstrip().endswith(",") else ""
        lines[index] = f'  "{key}": {value}{comma}'
        return "\n".join(lines) + "\n"

    return edit


def _cli(*argv: str) -> Builder:
    return lambda folder, earlier: list(argv)


CASES: list[tuple[str, Builder, str]] = [
    # ---- --config YAML (workbench/runner.py)
    (
        "config duplicate key",
        _config("gate_probability: 0.9\nmax_gap_s: 1\ngate_probability: 0.5\n"),
        "config.yaml:3: key 'gate_probability' appears twice in one mapping (first on line 1)",
    ),
    (
        "config duplicate key inside a run config",
        _config(
            "estimator: ekf-slam\ndataset: x\nseed: 0\nconfig:\n  max_gap_s: 1\n  max_gap_s: 2\n"
        ),
        "config.yaml:6: key 'max_gap_s' appears twice",
    ),
    ("config not utf-8", _config(b"gate_probability: 0.9 # caf\xe9\n"), "config.yaml:1: not UTF-8"),
    ("config over 1 MiB", _config(BIG), "config.yaml: larger than 1 MiB"),
    (
        "config anchor and alias",
        _config("gate_probability: &p 0.9\nnew_landmark_probability: *p\n"),
        "config.yaml:1: YAML anchors and aliases",
    ),
    (
        "config python tag",
        _config("gate_probability: !!python/object/apply:os.system ['true']\n"),
        "config.yaml:1: not valid YAML (could not determine a constructor",
    ),
    (
        "config nested too deeply",
        _config("a: " + "[" * 2000),
        "config.yaml:1: not valid YAML (exceeded maximum nesting depth)",
    ),
    (
        "config run config not a mapping",
        _config("estimator: ekf-slam\ndataset: x\nseed: 0\nconfig: [1, 2]\n"),
        "config.yaml: config: expected a mapping",
    ),
    (
        "set value with an anchor",
        _cli("run", "ekf-slam", "sim:circle", "--set", "gate_probability=&a 0.9"),
        "gate_probability: Input should be a valid number, unable to parse string as a number, got '&a 0.9'",
    ),
    # ---- suite files (workbench/suite_files.py)
    ("suite billion laughs", _suite(_laughs()), "mine.yaml:1: YAML anchors and aliases"),
    (
        "suite duplicate key",
        _suite(SUITE_OK + "estimators: [ekf-slam]\n"),
        "mine.yaml:3: key 'estimators' appears twice",
    ),
    (
        "suite not utf-8",
        _suite(b"description: \xff\xfe\n" + SUITE_OK.encode()),
        "mine.yaml:1: not UTF-8",
    ),
    ("suite over 1 MiB", _suite(SUITE_OK + BIG), "mine.yaml: larger than 1 MiB"),
    (
        "suite 5000-digit runs",
        _suite(SUITE_OK + "runs: " + "9" * 5000 + "\n"),
        "mine.yaml: not valid YAML",
    ),
    # ---- rerun's config.yaml (workbench/cli.py rerun_command)
    (
        "rerun seed abc",
        _rerun(_top_level("seed", "abc")),
        "config.yaml: seed: expected a whole number >= 0",
    ),
    (
        "rerun seed negative",
        _rerun(_top_level("seed", "-5")),
        "config.yaml: seed: expected a whole number >= 0 (as --seed takes it), got -5",
    ),
    (
        "rerun seed fractional",
        _rerun(_top_level("seed", "1.5")),
        "config.yaml: seed: expected a whole number",
    ),
    (
        "rerun estimator a list",
        _rerun(_top_level("estimator", "[a, b]")),
        "config.yaml: estimator: expected a name",
    ),
    (
        "rerun data options a list",
        _rerun(_top_level("data_options", "[1, 2]")),
        "config.yaml: data_options: expected a mapping",
    ),
    ("rerun duplicate seed", _rerun(lambda text: text + "seed: 3\n"), "key 'seed' appears twice"),
    (
        "rerun not utf-8",
        _rerun(lambda text: b"# \xff\n" + text.encode()),
        "config.yaml:1: not UTF-8",
    ),
    # ---- dataset options sized against memory (datasets/simulation, synthetic_lidar)
    (
        "options duration 1e308",
        _cli("run", "dead-reckoning", "sim:circle", "--data", "duration_s=1e308"),
        "sim:circle --data: duration_s=1e+308 needs unbounded memory",
    ),
    (
        "options duration inf",
        _cli("run", "dead-reckoning", "sim:circle", "--data", "duration_s=.inf"),
        "duration_s=inf needs unbounded memory",
    ),
    (
        "options duration 1e7",
        _cli("run", "dead-reckoning", "sim:circle", "--data", "duration_s=1e7"),
        "duration_s=1e+07 needs about 1502 GiB of simulated data",
    ),
    (
        "options rover crawling",
        _cli("run", "dead-reckoning", "sim:aghili-rover", "--data", "speed_m_s=1e-12"),
        "one lap at speed_m_s=1e-12",
    ),
    (
        "options landmarks times rate",
        _cli(
            "run",
            "dead-reckoning",
            "sim:static",
            "--data",
            "landmark_count=10000",
            "--data",
            "landmark_rate_hz=1000",
        ),
        "landmark_rate_hz=1000 and 10000 landmarks",
    ),
    (
        "options loop crawling",
        _cli("run", "dead-reckoning", "sim:guerreiro-loop", "--data", "mean_speed_m_s=1e-9"),
        "the 60 m path at mean_speed_m_s=1e-09",
    ),
    (
        "options loop random profile",
        _cli(
            "run",
            "dead-reckoning",
            "sim:guerreiro-loop",
            "--data",
            "mean_speed_m_s=1e-6",
            "--data",
            "speed_profile=random",
        ),
        "its 100 Hz grid",
    ),
    (
        "options simulate folder",
        lambda folder, _: [
            "simulate",
            "circle",
            "--data",
            "duration_s=1e7",
            "--out",
            str(folder / "sim"),
        ],
        "duration_s=1e+07",
    ),
    (
        "options lidar duration",
        lambda folder, _: [
            "simulate",
            "lidar-corridor",
            "--data",
            "duration_s=1e308",
            "--out",
            str(folder / "bag"),
        ],
        "simulate lidar-corridor --data: duration_s=1e+308",
    ),
    (
        "options lidar columns",
        lambda folder, _: [
            "simulate",
            "lidar-corridor",
            "--data",
            "columns=100000",
            "--out",
            str(folder / "bag"),
        ],
        "columns: Input should be less than or equal to 4096, got 100000",
    ),
    (
        "options lidar imu lead",
        lambda folder, _: [
            "simulate",
            "lidar-corridor",
            "--data",
            "imu_lead_s=1e9",
            "--out",
            str(folder / "bag"),
        ],
        "imu_lead_s: Input should be less than or equal to 60",
    ),
    # ---- results on disk (workbench/results)
    (
        "results npz random bytes",
        _report(_npz_bytes(lambda data: bytes(range(256)) * 16)),
        "estimate.npz: not a readable estimate file",
    ),
    (
        "results npz truncated",
        _report(_npz_bytes(lambda data: data[: len(data) // 2])),
        "estimate.npz: not a readable estimate file",
    ),
    (
        "results zip not npz",
        _report(_zip_of_text),
        "estimate.npz: not an estimate file ('hello.txt'",
    ),
    (
        "results npz missing array",
        _report(_npz_edit(lambda arrays: arrays.pop("pose_positions"))),
        "estimate.npz: not an estimate file (no pose_positions)",
    ),
    (
        "results npz lengths differ",
        _report(_npz_edit(lambda arrays: arrays.update(timing_seconds=np.zeros(3)))),
        "estimate.npz: not an estimate file (timing arrays differ in length",
    ),
    (
        "results npz text times",
        _report(_npz_edit(lambda arrays: arrays.update(pose_t=arrays["pose_t"].astype(str)))),
        "estimate.npz: not an estimate file ('pose_t' is a <U",
    ),
    (
        "results npz header claims more",
        _report(_header_claims_more),
        "estimate.npz: not an estimate file ('pose_t' holds 80 bytes",
    ),
    (
        "results metrics ate a string",
        _report(_metrics(_json_value("ate_rmse_m", '"0.5 m"'))),
        "metrics.json: ate_rmse_m: expected a number or null, got '0.5 m'",
    ),
    (
        "results metrics not json",
        _report(_metrics(lambda text: text[:-20])),
        "metrics.json: not a readable JSON file",
    ),
    (
        "results metrics a list",
        _report(_metrics(lambda text: "[1, 2]")),
        "metrics.json: expected a JSON object",
    ),
    (
        "results metrics seed abc",
        _report(_metrics(_json_value("seed", '"abc"'))),
        "metrics.json: seed: expected a whole number",
    ),
    (
        "results metrics warnings a string",
        _report(_metrics(_json_value("warnings", '"one line"'))),
        "metrics.json: warnings: expected a list of lines",
    ),
    # ---- --scheduler addresses (workbench/sweep/backends.py)
    (
        "scheduler not a url",
        lambda folder, _: ["bench", "tiny", "--scheduler", "not a url", "--out", str(folder / "b")],
        "--scheduler 'not a url': not a Dask scheduler address; expected tcp://HOST:PORT",
    ),
    (
        "scheduler without port",
        lambda folder, _: [
            "bench",
            "tiny",
            "--scheduler",
            "tcp://localhost",
            "--out",
            str(folder / "b"),
        ],
        "--scheduler 'tcp://localhost'",
    ),
    (
        "scheduler http url",
        lambda folder, _: [
            "bench",
            "tiny",
            "--scheduler",
            "http://localhost:8786",
            "--out",
            str(folder / "b"),
        ],
        "--scheduler 'http://localhost:8786'",
    ),
]


def _takes_out(argv: list[str]) -> bool:
    return argv[0] in ("run", "rerun") and "--out" not in argv


@pytest.mark.parametrize(("name", "build", "culprit"), CASES, ids=[c[0] for c in CASES])
def test_bad_configuration_is_one_clear_error_and_loses_nothing(
    name: str,
    build: Builder,
    culprit: str,
    tmp_path: Path,
    earlier_run,  # noqa: F811 - the fixture imported above
    capsys,
) -> None:
    folder, before = earlier_run
    argv = build(tmp_path, folder)
    if _takes_out(argv):
        argv = [*argv, "--out", str(folder)]
    capsys.readouterr()
    status = main(argv)
    _one_error(status, capsys.readouterr().err, culprit)
    assert {p.name: p.read_bytes() for p in folder.iterdir()} == before
    assert not [p for p in folder.parent.iterdir() if p.name.startswith(".run.")]
    # nothing written where a refused command would have written
    assert not any((tmp_path / name).exists() for name in ("report", "sim", "bench"))
    assert not [p for p in tmp_path.iterdir() if p.name.startswith((".bag", "bag"))]


def test_the_corpus_covers_every_group() -> None:
    groups = {name.split()[0] for name, _, _ in CASES}
    assert {"config", "suite", "rerun", "options", "results", "scheduler"} <= groups
    assert len(CASES) >= 40


# --------------------------------------------------------------------- a scheduler that is not
@pytest.fixture
def garbage_server(request: pytest.FixtureRequest) -> Iterator[str]:
    """A TCP server on localhost that answers every connection with ``request.param``
    bytes and then holds it open without a word (as a port of some other service would)."""
    server = socket.create_server(("127.0.0.1", 0))
    server.settimeout(0.2)
    held: list[socket.socket] = []
    stop = threading.Event()

    def serve() -> None:
        while not stop.is_set():
            try:
                connection, _ = server.accept()
            except OSError:
                continue
            held.append(connection)
            try:
                connection.sendall(request.param)
            except OSError:
                pass

    thread = threading.Thread(target=serve, daemon=True)
    thread.start()
    yield f"tcp://127.0.0.1:{server.getsockname()[1]}"
    stop.set()
    thread.join()
    for connection in held:
        connection.close()
    server.close()


@pytest.mark.parametrize(
    ("garbage_server", "culprit"),
    [
        # an HTTP reply read as Dask's 8-byte length prefix: 3 EiB announced
        (b"HTTP/1.1 400 Bad Request\r\n\r\n", "answered, but not as a Dask scheduler"),
        # a plausible length, then bytes that are no frame header
        (b"\x10" + bytes(7) + b"garbage-garbage!", "answered, but not as a Dask scheduler"),
        # silence: the handshake never completes
        (b"", "no Dask scheduler handshake within 1 s"),
    ],
    indirect=["garbage_server"],
    ids=["http-reply", "junk-frame", "silent"],
)
def test_a_scheduler_that_answers_garbage_is_one_clear_error_in_bounded_time(
    garbage_server: str, culprit: str, tmp_path: Path, monkeypatch, capsys
) -> None:
    import workbench.sweep.backends

    # the silent case waits for the whole bound: a short one keeps the test quick
    monkeypatch.setattr(workbench.sweep.backends, "SCHEDULER_TIMEOUT_S", 1.0)
    started = time.monotonic()
    status = main(["bench", "tiny", "--scheduler", garbage_server, "--out", str(tmp_path / "b")])
    elapsed = time.monotonic() - started
    line = _one_error(status, capsys.readouterr().err, culprit)
    assert f"--scheduler {garbage_server}" in line
    assert elapsed < 10.0, elapsed
    assert not (tmp_path / "b" / "runs").exists()  # nothing ran


# --------------------------------------------------------------------- a full disk
def _no_space_after(monkeypatch: pytest.MonkeyPatch, good_syncs: int) -> None:
    """``fsync`` fails with ENOSPC after ``good_syncs`` calls, naming no file, as the
    kernel's does: where a full disk shows when ``write_atomic`` flushes."""
    import os

    real = os.fsync
    calls = {"count": 0}

    def fsync(descriptor: int) -> None:
        calls["count"] += 1
        if calls["count"] > good_syncs:
            raise OSError(errno.ENOSPC, "No space left on device")
        real(descriptor)

    monkeypatch.setattr(os, "fsync", fsync)


@pytest.mark.parametrize("good_syncs", [2, 6], ids=["early", "in-ground-truth"])
def test_a_full_disk_while_simulating_a_folder_names_the_file_and_leaves_no_sequence(
    good_syncs: int, tmp_path: Path, monkeypatch, capsys
) -> None:
    out = tmp_path / "sim"
    # the marker file is the first sync; the sequence's files follow
    _no_space_after(monkeypatch, good_syncs)
    status = main(["simulate", "circle", "--data", "duration_s=1", "--out", str(out)])
    line = _one_error(status, capsys.readouterr().err, "No space left on device")
    assert f"error: {out}/" in line  # the file being written, inside --out
    left = sorted(p.relative_to(out).as_posix() for p in out.rglob("*"))
    assert left == [".workbench-folder"], left  # no sequence, no temp file, no empty folder


def _bag_write_fails(monkeypatch: pytest.MonkeyPatch, fmt: str) -> None:
    """The bag writer's storage fails on the first message, as each does on a full disk."""
    import sqlite3

    if fmt == "ros1":
        from rosbags.rosbag1 import Writer

        def write(self, *args, **kwargs) -> None:
            raise OSError(errno.ENOSPC, "No space left on device")

        monkeypatch.setattr(Writer, "write", write)
    else:
        from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer

        def write(self, *args, **kwargs) -> None:
            raise sqlite3.OperationalError("database or disk is full")

        monkeypatch.setattr(Sqlite3Writer, "write", write)


@pytest.mark.parametrize(
    ("fmt", "culprit"),
    [("ros1", "No space left on device"), ("ros2", "database or disk is full")],
)
def test_a_full_disk_while_simulating_a_bag_names_it_and_leaves_no_partial_file(
    fmt: str, culprit: str, tmp_path: Path, monkeypatch, capsys
) -> None:
    _bag_write_fails(monkeypatch, fmt)
    out = tmp_path / "corridor"
    argv = ["simulate", "lidar-corridor", "--data", "duration_s=0.2", "--format", fmt]
    status = main([*argv, "--out", str(out)])
    line = _one_error(status, capsys.readouterr().err, culprit)
    assert f"error: {out}" in line
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no bag, no .partial, no sidecar
