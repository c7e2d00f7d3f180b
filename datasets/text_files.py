"""Opening the text files the loaders read, with one clear ``InputError`` for everything
that is not a readable UTF-8 text file: missing, a folder, a FIFO or a device (reading one
would block or never end), unreadable, binary, or in another encoding. A UTF-8 byte-order
mark is accepted and dropped."""

from __future__ import annotations

import os
import stat
from collections.abc import Iterator
from pathlib import Path

from datasets.errors import InputError


def check_regular_file(path: Path, what: str = "file") -> Path:
    """``path`` if it is a regular file this process may read; ``InputError`` naming it and
    what it is otherwise. Never opens it (a FIFO would block)."""
    path = Path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise InputError(f"{path}: no such file") from None
    except OSError as error:
        raise InputError(f"{path}: cannot be read ({error.strerror})") from None
    if stat.S_ISDIR(mode):
        raise InputError(f"{path}: is a folder, not a {what}")
    if not stat.S_ISREG(mode):
        kind = "a FIFO" if stat.S_ISFIFO(mode) else "a device or socket"
        raise InputError(f"{path}: is {kind}, not a regular {what}")
    if not os.access(path, os.R_OK):
        raise InputError(f"{path}: no permission to read it")
    return path


def text_lines(path: Path, what: str = "file") -> Iterator[tuple[int, str]]:
    """(1-based line number, line) of a UTF-8 text file (a BOM dropped); ``InputError``
    naming the file (and the byte) for anything else."""
    yield from enumerate(read_text(path, what).splitlines(), start=1)


def read_text(path: Path, what: str = "file") -> str:
    """The whole UTF-8 text of a file (a BOM dropped); ``InputError`` naming the file (and
    the byte) for anything else."""
    path = check_regular_file(path, what)
    try:
        data = path.read_bytes()
    except OSError as error:
        raise InputError(f"{path}: cannot be read ({error.strerror})") from None
    try:
        text = data.decode("utf-8-sig")
    except UnicodeDecodeError as error:
        raise InputError(
            f"{path}: not a UTF-8 text {what} (byte {error.start} is 0x{data[error.start]:02x})"
        ) from None
    if "\x00" in text:
        raise InputError(f"{path}: not a text {what} (it contains NUL bytes)")
    return text
