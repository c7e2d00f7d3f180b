"""Configs round-trip: a run folder's config.yaml given back with --config, and
``workbench rerun``, reproduce the run's estimate byte for byte (timing aside), for every
registered estimator; ``workbench config`` prints the defaults ``--config`` accepts."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from workbench.cli import main
from workbench.registry import ESTIMATORS

SHORT = ["--data", "duration_s=2", "--seed", "3", "--no-plots"]


def _estimate_arrays(folder: Path) -> dict[str, np.ndarray]:
    with np.load(folder / "estimate.npz") as data:
        # timing aside: wall-clock figures differ from run to run
        return {
            key: data[key]
            for key in data.files
            if not key.startswith("timing") and "seconds" not in key
        }


def _same_run(first: Path, second: Path) -> None:
    for name in ("estimate.tum", "estimate_smoothed.tum", "reference.tum"):
        if (first / name).exists() or (second / name).exists():
            assert (first / name).read_bytes() == (second / name).read_bytes(), name
    a, b = _estimate_arrays(first), _estimate_arrays(second)
    assert a.keys() == b.keys()
    for key in a:
        numeric = np.issubdtype(a[key].dtype, np.number)
        assert np.array_equal(a[key], b[key], equal_nan=numeric), key


@pytest.mark.parametrize("estimator", [entry.name for entry in ESTIMATORS])
def test_config_yaml_and_rerun_reproduce_the_run(estimator: str, tmp_path: Path, capsys) -> None:
    first, again, rerun = tmp_path / "first", tmp_path / "again", tmp_path / "rerun"
    # a non-default option, so that the config really travels
    assert main(["run", estimator, "sim:circle", *SHORT, "--out", str(first)]) == 0
    config = first / "config.yaml"
    assert (
        main(["run", estimator, "sim:circle", *SHORT, "--config", str(config), "--out", str(again)])
        == 0
    )
    assert main(["rerun", str(first), "--no-plots", "--out", str(rerun)]) == 0
    capsys.readouterr()
    _same_run(first, again)
    _same_run(first, rerun)


def test_config_prints_defaults_that_config_accepts(tmp_path: Path, capsys) -> None:
    assert main(["config", "ekf-slam"]) == 0
    defaults = capsys.readouterr().out
    assert "gate_probability: 0.99" in defaults
    path = tmp_path / "ekf.yaml"
    path.write_text(defaults.replace("gate_probability: 0.99", "gate_probability: 0.95"))
    out = tmp_path / "run"
    assert (
        main(["run", "ekf-slam", "sim:circle", *SHORT, "--config", str(path), "--out", str(out)])
        == 0
    )
    assert "gate_probability: 0.95" in (out / "config.yaml").read_text()


def test_version_and_bad_rerun(tmp_path: Path, capsys) -> None:
    assert main(["--version"]) == 0
    assert capsys.readouterr().out.startswith("workbench ")
    assert main(["rerun", str(tmp_path), "--out", str(tmp_path / "x")]) == 2
    assert "not a run folder" in capsys.readouterr().err
