"""Errors that help (issue 36): a misspelt name, key, scenario or topic gets the closest
known one as a hint; a bad value of a right key names the estimator as registered and only
that key."""

from __future__ import annotations

import pytest

from workbench.cli import main

RUN = ["run", "--no-plots", "--out", "/nonexistent/never-written"]


@pytest.mark.parametrize(
    ("argv", "hint"),
    [
        (["ekf-slm", "sim:circle"], "did you mean 'ekf-slam'?"),
        (["ekf-slam", "sim:circl"], "did you mean 'circle'?"),
        (["ekf-slam", "utia:x#robot1"], "did you mean 'utias'?"),
        (
            ["ekf-slam", "sim:circle", "--set", "gate_probabilty=0.9"],
            "did you mean 'gate_probability'?",
        ),
        (["ekf-slam", "sim:circle", "--data", "duraton_s=3"], "did you mean 'duration_s'?"),
    ],
)
def test_a_misspelt_name_or_key_gets_the_closest_as_a_hint(argv, hint, capsys) -> None:
    assert main([*RUN[:1], *argv, *RUN[1:]]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("error:") and hint in line


def test_a_bad_value_names_the_estimator_and_only_its_key(capsys) -> None:
    argv = ["run", "ekf-slam", "sim:circle", "--set", "gate_probability=1.5", *RUN[1:]]
    assert main(argv) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("error: ekf-slam options: gate_probability:") and "1.5" in line
    assert "known keys" not in line and "EkfSlam" not in line


def test_a_misspelt_suite_gets_the_closest_as_a_hint(capsys) -> None:
    assert main(["bench", "quik", "--out", "/nonexistent/never-written"]) == 2
    (line,) = capsys.readouterr().err.splitlines()
    assert line.startswith("error: unknown suite 'quik'") and "did you mean 'quick'?" in line
