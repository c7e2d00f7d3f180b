"""A run rewriting an earlier run's folder, killed (SIGKILL) at random moments, leaves
exactly the old run or exactly the new one; the next run removes what the kill left."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

# a study: the second tier (`pytest -m study`, run by .ci/run after the default tier)
pytestmark = pytest.mark.study

RUN = [
    sys.executable,
    "-c",
    "import sys; from workbench.cli import main; sys.exit(main(sys.argv[1:]))",
    "run",
    "dead-reckoning",
    "sim:circle",
    "--data",
    "duration_s=2",
    "--no-plots",
]


def _run(folder: Path, seed: int) -> subprocess.Popen:
    env = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}
    return subprocess.Popen(
        [*RUN, "--seed", str(seed), "--out", str(folder)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        env=env,
    )


def _content(folder: Path) -> tuple[frozenset[str], int, bytes]:
    """(file names, the seed its config records, its trajectory bytes)."""
    names = frozenset(path.name for path in folder.iterdir())
    seed = yaml.safe_load((folder / "config.yaml").read_text())["seed"]
    return names, seed, (folder / "estimate.tum").read_bytes()


def _partial(root: Path) -> list[Path]:
    """What a write in progress (or killed) leaves beside the run folder."""
    return [p for p in root.iterdir() if p.name.startswith(".run.partial-")]


def test_a_killed_rewrite_leaves_the_old_run_or_the_new_one(tmp_path: Path) -> None:
    reference_new = tmp_path / "new"
    assert _run(reference_new, 5).wait() == 0
    new = _content(reference_new)
    folder = tmp_path / "run"
    started = time.perf_counter()
    assert _run(folder, 1).wait() == 0
    duration = time.perf_counter() - started
    old = _content(folder)
    assert old[0] == new[0] and old[1:] != new[1:]
    rng = np.random.default_rng(0)
    outcomes = []
    interrupted = 0  # kills that landed while the new folder was being written
    for index in range(12):  # 47 s with 20 on this machine; 6 of these wait for the write
        process = _run(folder, 5 if len(outcomes) % 2 == 0 else 1)
        if index % 2 == 0:  # at a random moment of the whole run
            time.sleep(rng.uniform(0.3 * duration, 1.1 * duration))
        else:  # once the new folder is being written: the moment that matters
            while process.poll() is None and not _partial(tmp_path):
                time.sleep(0.001)
            time.sleep(rng.uniform(0.0, 0.02))
        process.send_signal(signal.SIGKILL)
        process.wait()
        found = _content(folder)
        assert found in (old, new), found[:2]
        outcomes.append(found[1])
        interrupted += bool(_partial(tmp_path))
        # the next write starts from whatever is there: make it the old run again
        if found != old:
            assert _run(folder, 1).wait() == 0
    assert interrupted >= 1, interrupted  # at least one kill hit the write itself
    assert _run(folder, 1).wait() == 0
    assert _content(folder) == old
    leftovers = [p.name for p in tmp_path.iterdir() if p.name.startswith(".run.")]
    assert leftovers == []
