"""Suites as YAML files: the built-in ones load, a copied and edited one runs, a broken one
is one error line naming the file and the key; ``--set ESTIMATOR.key=value`` in every
command; ``list NAME``; shell completion."""

from __future__ import annotations

import csv
import json
import os
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from datasets.errors import InputError
from workbench.cli import main
from workbench.estimator_settings import settings_by_estimator
from workbench.registry import ESTIMATORS
from workbench.suite_files import builtin_suites, get_suite, option_text


def test_every_built_in_suite_loads_with_registered_estimators() -> None:
    registered = {entry.name for entry in ESTIMATORS}
    assert builtin_suites()[:2] == ["tiny", "quick"]
    for name in builtin_suites():
        suite = get_suite(name)
        assert suite.name == name and suite.description and suite.default_runs >= 1
        assert {spec.name for spec in suite.estimators} <= registered
        for dataset in suite.datasets:
            assert {estimator for estimator, _ in dataset.estimator_options} <= registered


def test_yaml_values_reach_the_options_as_the_cli_text_would() -> None:
    """The suite file's YAML values become the same text ``--set`` would carry."""
    assert [option_text(v) for v in (10, 0.0025, False, None, [0.01, 0.0025], "polar")] == [
        "10",
        "0.0025",
        "false",
        "null",
        "[0.01, 0.0025]",
        "polar",
    ]
    loop = next(
        d
        for d in get_suite("consistency").datasets
        if d.title == "sim:guerreiro-loop (model-matched)"
    )
    assert ("speed_reversion_s", "null") in loop.options
    assert loop.options_for("sensor-based") == (
        ("velocity_walk_m_s_sqrt_s", "[0.01, 0.0025]"),
        ("landmark_walk_m_sqrt_s", "0"),
    )


def test_a_copied_and_edited_suite_runs(tmp_path: Path, capsys) -> None:
    assert main(["suite", "tiny"]) == 0
    values = yaml.safe_load(capsys.readouterr().out)
    values["datasets"] = [
        {
            "name": "sim:circle",
            "data": {"duration_s": 3},
            "label": "circle 3 s",
            "left_out": {"sensor-based": "not this time"},
        }
    ]
    values["estimators"] = [
        "dead-reckoning",
        "sensor-based",
        {
            "name": "ekf-slam",
            "label": "ekf-slam (slow walk)",
            "set": {"velocity_walk_m_s_sqrt_s": 0.05},
        },
    ]
    values["runs"] = 1
    suite_file = tmp_path / "mine.yaml"
    suite_file.write_text(yaml.safe_dump(values))
    out = tmp_path / "bench"
    assert main(["bench", str(suite_file), "--out", str(out), "--no-plots"]) == 0
    planned = _pairs_with_status(out)
    assert planned == [
        ("circle 3 s", "dead-reckoning", "ok"),
        ("circle 3 s", "sensor-based", "n/a"),
        ("circle 3 s", "ekf-slam (slow walk)", "ok"),
    ]
    # the report of the runs on disk keeps the suite's order and its left-out pairs
    (out / "table.csv").unlink()
    report = ["bench", str(suite_file), "--out", str(out), "--no-plots", "--report-only"]
    assert main(report) == 0
    assert _pairs_with_status(out) == planned
    assert "not this time" in (out / "table.md").read_text()
    request = json.loads(
        (
            out / "runs" / "circle-3-s" / "ekf-slam-slow-walk" / "seed-0" / "bench_request.json"
        ).read_text()
    )
    assert request["overrides"] == {"velocity_walk_m_s_sqrt_s": "0.05"}


def _pairs_with_status(out: Path) -> list[tuple[str, str, str]]:
    rows = list(csv.DictReader((out / "table.csv").open()))
    return [(row["dataset"], row["estimator"], row["status"]) for row in rows]


@pytest.mark.parametrize(
    ("text", "expected"),
    [
        ("datasets: [sim:circle]\nestimators: [ekf-slam]\nrun: 3\n", "run"),
        ("datasets: [sim:circle]\nestimators: [{name: ekf-slam, sett: {}}]\n", "sett"),
        ("datasets: []\nestimators: [ekf-slam]\n", "datasets"),
        ("datasets: [{name: 'bag:x', generate: nope}]\nestimators: [ekf-slam]\n", "nope"),
        ("datasets: [sim:circle, sim:circle]\nestimators: [ekf-slam]\n", "listed twice"),
        ("- just\n- a list\n", "YAML mapping"),
        ("datasets: [sim:circle\n", "not a YAML suite file"),
    ],
)
def test_a_broken_suite_file_is_one_error_naming_file_and_key(
    tmp_path: Path, capsys, text: str, expected: str
) -> None:
    suite_file = tmp_path / "broken.yaml"
    suite_file.write_text(text)
    assert main(["bench", str(suite_file), "--out", str(tmp_path / "out")]) == 2
    error = capsys.readouterr().err
    assert error.count("\n") == 1 and str(suite_file) in error and expected in error
    assert not (tmp_path / "out").exists()


def test_unknown_suite_names_the_built_in_ones(capsys) -> None:
    assert main(["suite", "nope"]) == 2
    assert "tiny, quick, paper" in capsys.readouterr().err


def test_set_names_its_estimator_everywhere() -> None:
    assert settings_by_estimator(
        ["aghili.anchor_source=first-observation"], ["aghili", "ekf-slam"]
    ) == {"aghili": {"anchor_source": "first-observation"}, "ekf-slam": {}}
    # a bare key where one estimator runs
    assert settings_by_estimator(["anchors=2"], ["aghili"]) == {"aghili": {"anchors": "2"}}
    with pytest.raises(InputError, match="not among the estimators this command runs"):
        settings_by_estimator(["smoother-batch.x=1"], ["aghili"])
    with pytest.raises(InputError, match="name the estimator, ESTIMATOR.key=value"):
        settings_by_estimator(["x=1"], ["aghili", "ekf-slam"])


def test_run_takes_the_prefixed_set_and_bench_labels_what_was_set(tmp_path: Path, capsys) -> None:
    out = tmp_path / "run"
    argv = ["run", "ekf-slam", "sim:circle", "--data", "duration_s=2", "--no-plots"]
    assert main([*argv, "--out", str(out), "--set", "ekf-slam.velocity_walk_m_s_sqrt_s=0.2"]) == 0
    assert yaml.safe_load((out / "config.yaml").read_text())["config"][
        "velocity_walk_m_s_sqrt_s"
    ] == pytest.approx(0.2)
    assert main([*argv, "--out", str(tmp_path / "x"), "--set", "aghili.anchors=2"]) == 2
    assert "not among the estimators" in capsys.readouterr().err

    bench = tmp_path / "bench"
    argv = ["bench", "tiny", "--runs", "1", "--out", str(bench), "--no-plots"]
    assert (
        main([*argv, "--dataset", "sim:circle", "--set", "ekf-slam.velocity_walk_m_s_sqrt_s=0.2"])
        == 0
    )
    shown = capsys.readouterr().out
    # the terminal table shows the label whole (rich markup would eat "[...]")
    assert "ekf-slam [velocity_walk" in shown
    rows = list(csv.DictReader((bench / "table.csv").open()))
    assert {row["estimator"] for row in rows} == {
        "dead-reckoning",
        "ekf-slam [velocity_walk_m_s_sqrt_s=0.2]",
    }


def test_list_name_shows_the_matching_entries_with_their_options(capsys) -> None:
    assert main(["list", "sim:circle"]) == 0
    out = capsys.readouterr().out
    assert "radius_m" in out and "sim:aghili-rover" not in out and "estimators:" not in out
    assert main(["list", "smoother"]) == 0
    out = capsys.readouterr().out
    assert out.count("  smoother-") == 3 and "lag_s" in out and "dead-reckoning" not in out
    assert main(["list", "quick"]) == 0
    assert "kitti-imu-gps" in capsys.readouterr().out
    assert main(["list", "nothing-like-this"]) == 2
    assert "known: sim:aghili-rover" in capsys.readouterr().err


@pytest.mark.study
def test_shell_completion_offers_the_registered_names() -> None:
    def complete(words: str) -> list[str]:
        environment = dict(
            os.environ,
            _WORKBENCH_COMPLETE="complete_bash",
            COMP_WORDS=words,
            COMP_CWORD=str(len(words.split()) - 1),
        )
        script = "import sys; from workbench.cli import main; sys.exit(main())"
        result = subprocess.run(
            [sys.executable, "-c", script],
            env=environment,
            capture_output=True,
            text=True,
            timeout=60,
        )
        return result.stdout.split()

    assert complete("workbench run smoo") == [
        "smoother-batch",
        "smoother-isam2",
        "smoother-fixed-lag",
    ]
    assert "sim:guerreiro-loop" in complete("workbench run ekf-slam sim")
    assert complete("workbench bench c") == ["consistency", "calibration"]
    assert "list" in complete("workbench li")
