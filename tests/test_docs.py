"""The getting-started page's commands run as written, in order, in an empty folder; and
every registered estimator has its page."""

from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from workbench.cli import main
from workbench.registry import ESTIMATORS

DOCS = Path(__file__).resolve().parents[1] / "docs"


def _commands(page: Path) -> list[list[str]]:
    blocks = re.findall(r"```bash\n(.*?)```", page.read_text(), flags=re.S)
    return [
        shlex.split(line)
        for block in blocks
        for line in block.splitlines()
        if line.startswith("workbench ")
    ]


@pytest.mark.study
def test_getting_started_commands_run(tmp_path: Path, monkeypatch, capsys) -> None:
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("OPENBLAS_NUM_THREADS", "1")
    commands = _commands(DOCS / "getting-started.md")
    assert len(commands) >= 8
    for argv in commands:
        redirect = argv.index(">") if ">" in argv else None
        status = main(argv[1:redirect] if redirect else argv[1:])
        output = capsys.readouterr()
        assert status == 0, (argv, output.err)
        if redirect:
            Path(argv[redirect + 1]).write_text(output.out)
    assert (tmp_path / "runs" / "report" / "table.tex").is_file()
    assert (tmp_path / "runs" / "bag" / "table.csv").is_file()


def test_every_estimator_has_a_page() -> None:
    for entry in ESTIMATORS:
        page = DOCS / "estimators" / f"{entry.name}.md"
        assert page.is_file(), page
        text = page.read_text()
        for heading in ("## Paper", "## Equations", "## Options", "## Known limits"):
            assert heading in text, (page, heading)


def test_estimator_pages_name_only_real_options() -> None:
    """An option a page lists (``- `name`: ...`` under ``## Options``) exists in the
    estimator's Config: a renamed option cannot leave its page stale."""
    for entry in ESTIMATORS:
        text = (DOCS / "estimators" / f"{entry.name}.md").read_text()
        options = text.split("## Options", 1)[1].split("\n## ", 1)[0]
        listed = re.findall(r"^- ((?:`[a-z_]+`(?:, )?)+):", options, flags=re.M)
        names = [name for group in listed for name in re.findall(r"`([a-z_]+)`", group)]
        assert names, entry.name
        fields = entry.load().Config.model_fields
        assert not set(names) - set(fields), (entry.name, set(names) - set(fields))
