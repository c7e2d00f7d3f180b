"""A folder written as a whole: the new content goes to a hidden sibling that then takes
the folder's place, so a process killed at any moment leaves the complete old folder or
the complete new one, never a mix.

The swap is one ``renameat2(RENAME_EXCHANGE)`` (Linux: the two directories trade places
atomically), then the old content, now in the sibling, is removed. Where the kernel or the
file system has no exchange, two renames stand in (the old folder aside, the new one in
place): a kill between them leaves the folder missing, and ``recover`` (called before the
next write of the same folder) puts the complete one back. Leftover siblings of earlier
kills are removed by the next write.
"""

from __future__ import annotations

import ctypes
import errno
import os
import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

_PARTIAL = "partial"
_REPLACED = "replaced"
_AT_FDCWD = -100
_RENAME_EXCHANGE = 2


def _sibling(folder: Path, kind: str) -> Path:
    return folder.parent / f".{folder.name}.{kind}-{os.getpid()}"


def _siblings(folder: Path, kind: str) -> list[Path]:
    return sorted(folder.parent.glob(f".{folder.name}.{kind}-*"))


def _marker(staging: Path) -> Path:
    """The file beside a staging folder that says its content is complete."""
    return staging.with_name(staging.name + ".complete")


def _remove(path: Path) -> None:
    if path.is_dir() and not path.is_symlink():
        shutil.rmtree(path, ignore_errors=True)
    else:
        path.unlink(missing_ok=True)


def recover(folder: Path) -> None:
    """Tidy what earlier killed writes of ``folder`` left: a complete new folder that did
    not take its place yet goes there (when the folder itself is missing), the rest goes."""
    folder = Path(folder)
    if not folder.exists():
        complete = [
            candidate
            for candidate in _siblings(folder, _PARTIAL)
            if candidate.is_dir() and _marker(candidate).exists()
        ]
        aside = [candidate for candidate in _siblings(folder, _REPLACED) if candidate.is_dir()]
        if complete:
            os.replace(complete[0], folder)
        elif aside:
            os.replace(aside[0], folder)
    for leftover in _siblings(folder, _PARTIAL) + _siblings(folder, _REPLACED):
        _remove(leftover)


def _exchange(first: Path, second: Path) -> bool:
    """Swap two paths atomically; False where the system cannot."""
    try:
        libc = ctypes.CDLL(None, use_errno=True)
        renameat2 = libc.renameat2
    except (OSError, AttributeError):
        return False
    result = renameat2(
        _AT_FDCWD, os.fsencode(first), _AT_FDCWD, os.fsencode(second), _RENAME_EXCHANGE
    )
    if result == 0:
        return True
    code = ctypes.get_errno()
    if code in (errno.EINVAL, errno.ENOSYS, errno.EOPNOTSUPP):
        return False
    raise OSError(code, os.strerror(code), str(first))


@contextmanager
def replaced_as_a_whole(folder: Path) -> Iterator[Path]:
    """Yield a hidden sibling to write ``folder``'s new content into; on a normal exit it
    takes ``folder``'s place (module docstring), on an error it is removed and ``folder``
    is left as it was."""
    from datasets.errors import InputError
    from workbench.owned_folders import RUN, check_writable, exclusive, mark

    folder = Path(folder)
    if folder.name in ("", ".", ".."):
        raise InputError(
            f"--out '{folder}': name a folder of its own (it would replace the current folder "
            "or its parent)"
        )
    try:
        folder.parent.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InputError(f"--out {folder}: cannot create its parent ({error.strerror})") from None
    with exclusive(folder):
        recover(folder)
        check_writable(folder, RUN)  # never replaces a folder the workbench did not write
        with _staged(folder) as staging:
            mark(staging, RUN)
            yield staging


@contextmanager
def _staged(folder: Path) -> Iterator[Path]:
    from datasets.errors import InputError

    staging = _sibling(folder, _PARTIAL)
    shutil.rmtree(staging, ignore_errors=True)
    try:
        staging.mkdir()
    except OSError as error:
        raise InputError(f"--out {folder}: cannot write there ({error.strerror})") from None
    try:
        yield staging
    except BaseException:
        shutil.rmtree(staging, ignore_errors=True)
        raise
    _marker(staging).touch()
    if not folder.exists():
        os.replace(staging, folder)
    elif _exchange(staging, folder):
        shutil.rmtree(staging, ignore_errors=True)  # the old content, now in the sibling
    else:
        aside = _sibling(folder, _REPLACED)
        os.replace(folder, aside)
        os.replace(staging, folder)
        shutil.rmtree(aside, ignore_errors=True)
    _marker(staging).unlink(missing_ok=True)
