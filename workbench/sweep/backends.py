"""Where the cells of a sweep run: local processes (the default) or a Dask cluster.

Both run the same top-level worker functions (``plan.probe_dataset``, ``cell.run_cell``).
"""

from __future__ import annotations

import os
import re
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


SCHEDULER_TIMEOUT_S = 10.0
"""How long connecting to a Dask scheduler and its first handshake may take, together."""
SCHEDULER_FORMS = (
    "tcp://HOST:PORT (e.g. tcp://127.0.0.1:8786), tls://HOST:PORT for TLS (docs/dask.md), "
    "ws://HOST:PORT or wss://HOST:PORT over websockets"
)
_ADDRESS = re.compile(r"(?:(?:tcp|tls|ws|wss)://)?(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9._-]+):(\d{1,5})")


def check_scheduler_address(address: str) -> None:
    """``InputError`` naming ``--scheduler`` and the value unless it is an address a Dask
    client can dial (``SCHEDULER_FORMS``; ``inproc://`` for a cluster in this process)."""
    if address.startswith("inproc://"):
        return
    match = _ADDRESS.fullmatch(address)
    if match is None or not 0 < int(match.group(1)) < 65536:
        raise InputError(
            f"--scheduler '{address}': not a Dask scheduler address; expected {SCHEDULER_FORMS}"
        )


def _handshake(address: str, timeout_s: float) -> None:
    """Connect to ``address`` and exchange Dask's handshake, all within ``timeout_s``.

    ``distributed.Client`` bounds only the TCP connect: a peer that accepts and then stays
    silent holds its handshake forever, and the reply's 8-byte length prefix is allocated as
    announced (a garbage reply asked for 3 EiB after 83 s). distributed has no setting that
    caps what it receives (``distributed.comm.shard`` only splits what it sends), so this
    probe runs the same handshake under one deadline, without deserializing the reply: a
    length the allocator refuses fails at once, any other reply is cut off at the deadline
    (so what it can hold is what arrives in ``timeout_s``). Errors propagate."""
    import asyncio

    from distributed.comm import connect
    from distributed.security import Security

    async def exchange() -> None:
        arguments = Security().get_connection_args("client")
        comm = await connect(address, timeout=timeout_s, deserialize=False, **arguments)
        await comm.close()

    asyncio.run(asyncio.wait_for(exchange(), timeout_s))


class DaskBackend:
    """An existing Dask distributed scheduler at ``address`` (``tcp://host:8786``).

    The scheduler and its workers are trusted with this process: Dask's protocol unpickles
    what they send (docs/dask.md). The address is checked first (``check_scheduler_address``)
    and its handshake bounded in time and size (``_handshake``), so that a wrong address is
    an ``InputError`` naming it within ``SCHEDULER_TIMEOUT_S``."""

    def __init__(self, address: str, timeout_s: float | None = None) -> None:
        timeout_s = SCHEDULER_TIMEOUT_S if timeout_s is None else timeout_s
        check_scheduler_address(address)
        where = f"--scheduler {address}"
        if not address.startswith("inproc://"):  # a cluster in this process answers as one
            try:
                _handshake(address, timeout_s)
            except TimeoutError:
                raise InputError(
                    f"{where}: no Dask scheduler handshake within {timeout_s:g} s (the address "
                    "accepts connections but does not answer as a Dask scheduler)"
                ) from None
            except OSError as error:
                raise InputError(
                    f"{where}: cannot connect to a Dask scheduler ({one_line(error)})"
                ) from None
            except Exception as error:  # any other reply: MemoryError, struct.error, ...
                raise InputError(
                    f"{where}: answered, but not as a Dask scheduler ({one_line(error)})"
                ) from None
        from distributed import Client

        try:
            self._client = Client(address, timeout=f"{timeout_s}s")
        except (OSError, TimeoutError) as error:
            raise InputError(
                f"{where}: cannot connect to a Dask scheduler ({one_line(error)})"
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
