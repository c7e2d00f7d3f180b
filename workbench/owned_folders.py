"""Folders the workbench owns: it replaces or writes into an ``--out`` folder only when it
wrote that folder itself, and one writer at a time.

- A marker file (``MARKER_FILE``) in every folder the workbench writes says which kind of
  folder it is: ``run`` (a run folder, replaced as a whole by ``workbench.folder_swap``)
  or ``collection`` (a suite's, a bag's or a report's output, or a simulated sequence:
  the workbench writes files *into* it). Folders written before the marker existed are
  recognised by their file names alone (``LEGACY_RUN_ENTRIES``, ``LEGACY_COLLECTION_ENTRIES``).
- A run folder may replace an empty folder or an earlier run folder; nothing else. A
  collection may be written into an empty folder or an earlier collection. Anything else
  (a user's folder holding ``thesis.tex``) is an ``InputError`` naming the folder and one
  of its files: nothing of the user's is touched.
- ``exclusive(folder)`` holds an advisory lock (``fcntl.flock`` on a hidden file beside the
  folder) for as long as a command writes there: a second writer exits 2 naming the
  process that holds it. The lock is released by the kernel when a process dies, so a
  killed run never blocks the next one. Locks are re-entrant within one process (a
  command that locks ``--out`` and then writes the run folder through
  ``replaced_as_a_whole``, which locks it too).
"""

from __future__ import annotations

import fcntl
import json
import os
from collections.abc import Iterator
from contextlib import contextmanager
from fnmatch import fnmatch
from pathlib import Path

from datasets.errors import InputError

MARKER_FILE = ".workbench-folder"
RUN = "run"
COLLECTION = "collection"
KINDS = (RUN, COLLECTION)

# What a run folder held before it carried a marker (run_folder.py's layout, a failed
# run's request and error, a sweep's request).
LEGACY_RUN_ENTRIES = (
    "config.yaml",
    "*.tum",
    "*.kitti",
    "*.zip",
    "estimate.npz",
    "consistency.npz",
    "events.json",
    "metrics.json",
    "plots",
    "bench_request.json",
    "error.json",
)
# What a suite's, a bag's or a report's folder, or a simulated sequence, held: tables,
# figures, sweep and data folders, the bag's front end, and a simulated sequence's files.
LEGACY_COLLECTION_ENTRIES = (
    "runs",
    "data",
    "plots",
    "frontend",
    "table.md",
    "table.tex",
    "table.csv",
    "*.csv",
    "sequence.json",
    "README.md",
    "ground_truth",
)


def _matches(name: str, patterns: tuple[str, ...]) -> bool:
    return any(fnmatch(name, pattern) for pattern in patterns)


def folder_kind(folder: Path) -> str | None:
    """``'run'`` or ``'collection'`` when the workbench wrote ``folder``, ``'empty'`` for
    an empty folder, None when it holds something else (or does not exist)."""
    folder = Path(folder)
    if not folder.is_dir():
        return None
    marker = folder / MARKER_FILE
    if marker.is_file():
        try:
            kind = json.loads(marker.read_text(encoding="utf-8")).get("kind")
        except (OSError, ValueError, AttributeError):
            kind = None
        return kind if kind in KINDS else None
    entries = [entry for entry in folder.iterdir()]
    if not entries:
        return "empty"
    names = [entry.name for entry in entries]
    if any(name in ("config.yaml", "metrics.json", "error.json") for name in names) and all(
        _matches(name, LEGACY_RUN_ENTRIES) for name in names
    ):
        return RUN
    if any(name in ("table.md", "runs", "sequence.json") for name in names):
        # a bag's or report's folder also holds one run folder per estimator
        if all(
            _matches(entry.name, LEGACY_COLLECTION_ENTRIES)
            or (entry.is_dir() and folder_kind(entry) == RUN)
            for entry in entries
        ):
            return COLLECTION
    return None


def _foreign_example(folder: Path) -> str:
    names = sorted(entry.name for entry in folder.iterdir() if entry.name != MARKER_FILE)
    return names[0] if names else "?"


def check_writable(folder: Path, kind: str, option: str = "--out") -> None:
    """Raise ``InputError`` unless the workbench may write a ``kind`` folder at ``folder``:
    it does not exist, is empty, or is a folder of that kind the workbench wrote."""
    folder = Path(folder)
    if not folder.exists():
        return
    if not folder.is_dir():
        raise InputError(f"{option} {folder}: exists and is not a folder")
    found = folder_kind(folder)
    if found == "empty" or found == kind:
        return
    if found is None:
        raise InputError(
            f"{option} {folder}: holds files the workbench did not write "
            f"(e.g. '{_foreign_example(folder)}'); nothing was changed. Choose a new or empty "
            "folder"
        )
    what = "a run folder" if found == RUN else "a suite, bag or report folder"
    wanted = "a run folder" if kind == RUN else "a suite, bag or report folder"
    raise InputError(
        f"{option} {folder}: is {what}, not {wanted}; nothing was changed. Choose a new or "
        "empty folder"
    )


def mark(folder: Path, kind: str) -> None:
    """Write the marker that says the workbench wrote ``folder`` (a ``kind`` folder)."""
    from datasets.trajectory_io import write_atomic

    write_atomic(Path(folder) / MARKER_FILE, json.dumps({"kind": kind}) + "\n")


def claim_collection(folder: Path, option: str = "--out") -> Path:
    """Create ``folder`` (or check an existing one is empty or an earlier collection of the
    workbench's) and mark it as a collection; return it."""
    folder = Path(folder)
    check_writable(folder, COLLECTION, option)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InputError(f"{option} {folder}: cannot create it ({error.strerror})") from None
    if not (folder / MARKER_FILE).is_file():
        mark(folder, COLLECTION)
    return folder


def lock_path(folder: Path) -> Path:
    """The hidden lock file beside ``folder``."""
    folder = Path(folder).absolute()
    return folder.parent / f".{folder.name}.lock"


_held: dict[Path, int] = {}  # lock file -> how many times this process holds it


@contextmanager
def exclusive(folder: Path, option: str = "--out") -> Iterator[None]:
    """Hold the lock of ``folder`` (module docstring); ``InputError`` when another process
    holds it."""
    path = lock_path(folder)
    if path in _held:
        _held[path] += 1
        try:
            yield
        finally:
            _held[path] -= 1
        return
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
    except OSError as error:
        raise InputError(
            f"{option} {folder}: cannot create its parent ({error.strerror})"
        ) from None
    while True:
        try:
            descriptor = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
        except OSError as error:
            raise InputError(f"{option} {folder}: cannot write there ({error.strerror})") from None
        try:
            fcntl.flock(descriptor, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            try:
                holder = os.read(descriptor, 64).decode("ascii", "replace").strip() or "?"
            finally:
                os.close(descriptor)
            raise InputError(
                f"{option} {folder}: another workbench process (pid {holder}) is writing it; "
                "wait for it to finish or choose another folder"
            ) from None
        # the previous holder may have removed the file between our open and our lock
        try:
            same = os.stat(path).st_ino == os.fstat(descriptor).st_ino
        except FileNotFoundError:
            same = False
        if same:
            break
        os.close(descriptor)
    os.ftruncate(descriptor, 0)
    os.write(descriptor, f"{os.getpid()}\n".encode())
    _held[path] = 1
    try:
        yield
    finally:
        del _held[path]
        try:
            path.unlink(missing_ok=True)
        finally:
            os.close(descriptor)  # releases the lock
