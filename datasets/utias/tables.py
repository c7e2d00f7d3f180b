"""The MRCLAM text files as numeric tables, and the time base of their rows.

Every file is whitespace-separated numbers with '#' comments. ``read_table`` names the
file and line of anything that is not a finite number; ``grid_times`` recovers the row
times of the resampled copies whose printed times are rounded (``datasets.utias``).
"""

from __future__ import annotations

import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas

from datasets.errors import InputError
from datasets.text_files import read_text, text_lines


@dataclass(frozen=True)
class Table:
    """A parsed numeric file: values (n, k), the 1-based line number of every row and the
    number of decimals printed in its first column (the time's printing resolution)."""

    values: np.ndarray
    lines: np.ndarray
    path: Path
    first_decimals: np.ndarray


_CORRECTLY_ROUNDED = (
    {} if int(pandas.__version__.split(".")[0]) >= 3 else {"float_precision": "round_trip"}
)
"""pandas 3 parses floats correctly rounded by default (and deprecates the option); 2.x
needs ``round_trip`` for it."""


def read_table(path: Path, columns: tuple[str, ...]) -> Table:
    """Read a whitespace-separated numeric file ('#' comments); ``InputError`` names file and line.

    pandas' C parser reads a well-formed file (``_CORRECTLY_ROUNDED``: every value the
    correctly rounded double Python's ``float`` gives, so the table is bit-identical to the
    row-by-row reading); anything it does not read cleanly (a wrong column count, a field
    that is not a finite number, an empty file) is read again row by row
    (``_read_table_checked``), which names the file and line. A UTIAS load reads 17 tables of
    the five robots (the default calibration pools the others): 3.0 s row by row, 1.3 s here
    (measured together on a loaded machine; robot 1's whole load 8.3 -> 6.9 s quiet).

    Args:
        path: the file.
        columns: names of the expected columns (their count is enforced on every row).
    """
    text = read_text(path, "MRCLAM file")
    lines = text.splitlines()
    data = [(number, line) for number, line in enumerate(lines, 1) if line.split("#", 1)[0].strip()]
    if not data:
        return _read_table_checked(path, columns)
    try:
        values = pandas.read_csv(
            io.StringIO(text),
            sep=r"\s+",
            comment="#",
            header=None,
            skip_blank_lines=True,
            engine="c",
            dtype=float,
            **_CORRECTLY_ROUNDED,
        ).to_numpy(dtype=float)
    except (ValueError, pandas.errors.ParserError, pandas.errors.EmptyDataError):
        return _read_table_checked(path, columns)
    if values.shape != (len(data), len(columns)) or not np.isfinite(values).all():
        return _read_table_checked(path, columns)
    decimals = [
        len(line.split(None, 1)[0].lower().split("e")[0].partition(".")[2]) for _, line in data
    ]
    return Table(values, np.array([number for number, _ in data]), path, np.array(decimals))


def _read_table_checked(path: Path, columns: tuple[str, ...]) -> Table:
    """``read_table`` row by row in Python: the reference, and where a file has anything wrong
    (``InputError`` names file and line).

    Args:
        path: the file.
        columns: names of the expected columns (their count is enforced on every row).
    """
    rows: list[list[str]] = []
    lines: list[int] = []
    for number, line in text_lines(path, "MRCLAM file"):
        text = line.split("#", 1)[0].strip()
        if not text:
            continue
        fields = text.split()
        if len(fields) != len(columns):
            raise InputError(
                f"{path}:{number}: expected {len(columns)} columns ({', '.join(columns)}), got {len(fields)}: '{text}'"
            )
        rows.append(fields)
        lines.append(number)
    if not rows:
        raise InputError(f"{path}: no data rows")
    # one conversion of the whole table (a per-row float() loop took 1.5 s per UTIAS load);
    # on failure, the row-by-row pass below finds the line to name
    try:
        values = np.array(rows, dtype=float)
    except ValueError:
        values = None
    if values is None or not np.isfinite(values).all():
        checked = []
        for fields, number in zip(rows, lines):
            try:
                row = [float(field) for field in fields]
            except ValueError:
                raise InputError(f"{path}:{number}: not a number in '{' '.join(fields)}'") from None
            if not np.all(np.isfinite(row)):
                raise InputError(f"{path}:{number}: non-finite value in '{' '.join(fields)}'")
            checked.append(row)
        values = np.array(checked)  # what Python reads and numpy did not (e.g. "1_0")
    decimals = [len(fields[0].lower().split("e")[0].partition(".")[2]) for fields in rows]
    return Table(values, np.array(lines), path, np.array(decimals))


def printing_resolution(t: np.ndarray, significant_digits: int = 5) -> np.ndarray:
    """Resolution [s] of times printed with ``significant_digits`` (0.1 s for 1000-9999 s)."""
    magnitude = np.floor(np.log10(np.maximum(np.abs(t), 1e-12)))
    return 10.0 ** (magnitude - (significant_digits - 1))


def grid_times(
    printed: np.ndarray, step_s: float, decimals: np.ndarray | None = None
) -> np.ndarray | None:
    """Row-index times ``t0 + i * step_s`` when every printed time agrees within its printing
    resolution, else None.

    The resolution of a row is the finer of "5 significant digits" (this copy's format) and
    the decimals actually printed (so that long unix times with 3 decimals are judged at
    1 ms); the tolerance is half of it plus float slack.
    """
    grid = printed[0] + np.arange(len(printed)) * step_s
    resolution = printing_resolution(grid)
    if decimals is not None:
        resolution = np.minimum(resolution, 10.0 ** (-np.asarray(decimals, dtype=float)))
    tolerance = 0.5 * resolution + 1e-9
    return grid if np.all(np.abs(printed - grid) <= tolerance) else None


def first_backward(t: np.ndarray) -> int:
    """Index of the first time not after its predecessor (0 when there is none)."""
    backward = np.flatnonzero(np.diff(t) <= 0)
    return int(backward[0] + 1) if backward.size else 0


def increasing(t: np.ndarray, values: np.ndarray) -> tuple[np.ndarray, np.ndarray, int]:
    """Keep rows whose time increases strictly over every earlier kept row."""
    keep = np.zeros(len(t), dtype=bool)
    latest = -np.inf
    for i, time in enumerate(t):
        if time > latest:
            keep[i] = True
            latest = time
    return t[keep], values[keep], int((~keep).sum())
