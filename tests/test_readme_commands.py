"""Every command the README and the docs show is one the CLI takes: the command and its options exist,
and the estimators, datasets, suites and suite parts it names are known (the consistency
example once named a suite label that had been renamed, and nothing noticed). The
getting-started page's commands run for real in ``tests/test_docs.py``."""

from __future__ import annotations

import re
import shlex

import click
import pytest
import typer

from tests.conftest import REPO_ROOT
from workbench.cli import _register_command_modules, app
from workbench.registry import dataset_entry, estimator_entry
from workbench.suite_files import get_suite
from workbench.suites import restrict


def _readme_commands() -> list[list[str]]:
    """The README's Commands block and every bash block of the docs pages."""
    text = (REPO_ROOT / "README.md").read_text()
    section = text.split("## Commands", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```bash\n(.*?)```", section, flags=re.S)[:1]
    for page in sorted((REPO_ROOT / "docs").rglob("*.md")):
        blocks += re.findall(r"```bash\n(.*?)```", page.read_text(), flags=re.S)
    commands = []
    for line in "\n".join(blocks).splitlines():
        for part in line.split("&&"):
            words = shlex.split(part.split(" # ")[0].strip().split(">")[0], comments=False)
            while words and re.fullmatch(r"[A-Z_]+=\S*", words[0]):  # VAR=value workbench ...
                words = words[1:]
            # a synopsis shows optional parts in brackets: the command without them
            words = [word for word in words if not word.startswith("[")]
            if words and words[0] == "workbench":
                commands.append(words[1:])
    return commands


COMMANDS = _readme_commands()


def test_the_readme_shows_commands() -> None:
    assert len(COMMANDS) >= 20


@pytest.mark.parametrize("argv", COMMANDS, ids=[" ".join(argv)[:60] for argv in COMMANDS])
def test_every_readme_command_parses_and_names_known_things(argv: list[str]) -> None:
    _register_command_modules()
    group = typer.main.get_command(app)
    context = click.Context(group, info_name="workbench")
    name, command, rest = group.resolve_command(context, list(argv))
    if isinstance(command, click.Group):
        name, command, rest = command.resolve_command(context, rest)
    sub = command.make_context(name, rest, parent=context)  # unknown options raise here
    params = sub.params
    if name == "run":
        estimator_entry(params["estimator"])
        dataset_entry(params["dataset"])
    if name == "bench" and params.get("suite") and not params["suite"].endswith(".yaml"):
        suite = get_suite(params["suite"])
        restrict(suite, params.get("dataset"), params.get("estimator"))
