"""docs/layout.md lists every module of the four packages, once, and nothing that is gone: the
page a newcomer reads to find where an idea lives stays true."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("datasets", "filters", "smoothers", "workbench")


def test_layout_page_lists_exactly_the_modules_on_disk() -> None:
    listed = re.findall(
        r"^- `([^`]+\.py)` \(\d+\): ", (ROOT / "docs" / "layout.md").read_text(), re.M
    )
    on_disk = sorted(
        path.relative_to(ROOT).as_posix()
        for package in PACKAGES
        for path in (ROOT / package).rglob("*.py")
        if "__pycache__" not in path.parts
    )
    assert len(listed) == len(set(listed)), "a module listed twice"
    missing = sorted(set(on_disk) - set(listed))
    gone = sorted(set(listed) - set(on_disk))
    assert not missing and not gone, f"docs/layout.md: add {missing}, remove {gone}"
