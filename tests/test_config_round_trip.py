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
    # the config alone: its seed (3) and its data option (2 s) travel with it
    argv = ["run", estimator, "sim:circle", "--no-plots", "--config", str(config)]
    assert main([*argv, "--out", str(again)]) == 0
    said = capsys.readouterr().err
    assert "the recorded run (seed 3, duration_s=2)" in said and "given here" not in said
    assert main(["rerun", str(first), "--no-plots", "--out", str(rerun)]) == 0
    capsys.readouterr()
    _same_run(first, again)
    _same_run(first, rerun)


def test_config_prints_defaults_that_config_accepts(tmp_path: Path, capsys) -> None:
    assert main(["config", "ekf-slam"]) == 0
    defaults = capsys.readouterr().out
    assert "gate_probability: 0.99" in defaults
    # every option with its description as a comment above it
    from filters.ekf_slam.filter import EkfSlam

    described = [name for name, f in EkfSlam.Config.model_fields.items() if f.description]
    lines = defaults.splitlines()
    for name in described:
        index = next(i for i, line in enumerate(lines) if line.startswith(f"{name}:"))
        assert lines[index - 1].startswith("# "), name
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


def test_flags_beside_a_run_config_override_it_and_are_said(tmp_path: Path, capsys) -> None:
    first, other = tmp_path / "first", tmp_path / "other"
    assert main(["run", "dead-reckoning", "sim:circle", *SHORT, "--out", str(first)]) == 0
    argv = ["run", "dead-reckoning", "sim:circle", "--no-plots", "--seed", "4"]
    argv += ["--config", str(first / "config.yaml"), "--out", str(other)]
    assert main(argv) == 0
    assert "given here: --seed 4" in capsys.readouterr().err
    import yaml

    recorded = yaml.safe_load((other / "config.yaml").read_text())
    assert recorded["seed"] == 4 and recorded["data_options"] == {"duration_s": "2"}
    wrong = ["run", "ekf-slam", "sim:circle", "--config", str(first / "config.yaml")]
    assert main([*wrong, "--out", str(tmp_path / "x")]) == 2
    assert "records a run of dead-reckoning, not ekf-slam" in capsys.readouterr().err
