"""Where the cells of a sweep run: local processes (the default) or a Dask cluster.

Both run the same top-level worker functions (``plan.probe_dataset``, ``cell.run_cell``).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Iterable, Iterator
from typing import Any, Protocol

from datasets.errors import InputError, one_line

# One BLAS/OpenMP thread per worker: the workers already fill the cores, and a fixed thread
# count keeps floating-point reductions identical between local and Dask workers.
_SINGLE_THREAD_ENVIRONMENT = {
    "OMP_NUM_THREADS": "1",
    "OPENBLAS_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
}


class Backend(Protocol):
    def submit(self, function: Callable[..., Any], *args: Any) -> Any: ...

    def as_completed(self, futures: Iterable[Any]) -> Iterator[Any]: ...

    def close(self) -> None: ...


def _exit_with_sweep(sweep_pid: int, poll_s: float = 0.5) -> None:
    """Worker initializer: exit as soon as the sweep's main process is gone.

    A killed sweep must leave no worker behind that would go on writing a run folder while
    the next sweep redoes it. Neither the pool nor the OS does this for us: a worker learns
    of its pool's death only between tasks, and a fork-server worker's parent is the fork
    server, which itself waits for its workers (they hold its liveness pipe). So a daemon
    thread polls the main process and ends the worker with ``os._exit``; every file of a
    run folder is written atomically, so nothing half-written is left behind."""
    import threading

    def watch() -> None:
        while True:
            time.sleep(poll_s)
            try:
                os.kill(sweep_pid, 0)
            except ProcessLookupError:
                os._exit(1)
            except PermissionError:
                pass  # exists, owned by someone else (cannot happen for our own parent)

    threading.Thread(target=watch, name="exit-with-sweep", daemon=True).start()


class LocalBackend:
    """Local worker processes (``concurrent.futures.ProcessPoolExecutor``).

    Workers start from a fork server (a clean process, not a fork of this one with its
    progress-bar thread) with one BLAS thread each."""

    def __init__(self, workers: int | None = None) -> None:
        import concurrent.futures
        import multiprocessing

        self.workers = max(1, workers or os.cpu_count() or 1)
        os.environ.update(_SINGLE_THREAD_ENVIRONMENT)  # inherited by the fork server
        context = multiprocessing.get_context("forkserver")
        context.set_forkserver_preload(
            ["workbench.sweep", "workbench.runner", "workbench.results.consistency"]
        )
        self._executor = concurrent.futures.ProcessPoolExecutor(
            self.workers, mp_context=context, initializer=_exit_with_sweep, initargs=(os.getpid(),)
        )

    def submit(self, function: Callable[..., Any], *args: Any) -> Any:
        return self._executor.submit(function, *args)

    def as_completed(self, futures: Iterable[Any]) -> Iterator[Any]:
        import concurrent.futures

        return concurrent.futures.as_completed(list(futures))

    def close(self) -> None:
        self._executor.shutdown(wait=True, cancel_futures=True)

    def describe(self) -> str:
        return f"{self.workers} local process(es)"


class DaskBackend:
    """An existing Dask distributed scheduler at ``address`` (``tcp://host:8786``)."""

    def __init__(self, address: str) -> None:
        from distributed import Client

        try:
            self._client = Client(address, timeout="20s")
        except (OSError, TimeoutError) as error:
            raise InputError(
                f"--scheduler {address}: cannot connect to a Dask scheduler ({one_line(error)})"
            ) from None
        self.address = address

    def submit(self, function: Callable[..., Any], *args: Any) -> Any:
        return self._client.submit(function, *args, pure=False)

    def as_completed(self, futures: Iterable[Any]) -> Iterator[Any]:
        from distributed import as_completed

        return iter(as_completed(list(futures)))

    def close(self) -> None:
        self._client.close()

    def describe(self) -> str:
        return f"Dask scheduler {self.address}"


def make_backend(scheduler: str | None, workers: int | None) -> LocalBackend | DaskBackend:
    """Dask when a scheduler address is given, local processes otherwise."""
    return DaskBackend(scheduler) if scheduler else LocalBackend(workers)
