"""The README opens with the two set-up commands, and CI runs the second one verbatim."""

from __future__ import annotations

from tests.conftest import REPO_ROOT


def readme_commands() -> list[str]:
    text = (REPO_ROOT / "README.md").read_text()
    block = text.split("```bash", 1)[1].split("```", 1)[0]
    return [line.strip() for line in block.strip().splitlines()]


def test_readme_opens_with_run_and_test_commands():
    run_command, test_command = readme_commands()
    assert "workbench bench" in run_command
    assert "pytest" in test_command


def test_ci_runs_the_readme_test_command():
    _, test_command = readme_commands()
    assert test_command in (REPO_ROOT / ".ci" / "run").read_text()
