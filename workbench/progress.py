"""The workbench's progress bars (rich), one place for their look: on stderr, off when
stderr is not a terminal (the caller passes ``disable``), never part of a command's output."""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rich.progress import Progress


def sequence_progress(disable: bool) -> Progress:
    """A bar over one estimator's pass: its task's ``completed`` is the sequence time [s]
    reached (the total is unknown: a stream's end is known only when it comes)."""
    from rich.progress import BarColumn, Progress, TextColumn, TimeElapsedColumn

    return Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        TextColumn("t={task.completed:.1f} s"),
        TimeElapsedColumn(),
        transient=True,
        disable=disable,
    )


def count_progress(
    disable: bool, unit: str = "", rate: bool = False, remaining: bool = False
) -> Progress:
    """A bar over counted items (frames, runs): ``M/N``, then ``unit``, the task's
    ``rate`` field (``rate=True``: the caller sets ``fields[rate]``, e.g. "12.3 frames/s")
    and, with ``remaining``, the time left; kept on screen when ``remaining`` (a sweep's
    summary), transient otherwise."""
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    columns = [TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn()]
    if unit:
        columns.append(TextColumn(unit))
    if rate:
        columns.append(TextColumn("{task.fields[rate]}"))
    columns.append(TimeElapsedColumn())
    if remaining:
        columns += [TextColumn("left"), TimeRemainingColumn()]
    return Progress(*columns, transient=not remaining, disable=disable)
