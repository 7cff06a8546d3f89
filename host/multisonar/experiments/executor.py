"""Where sweeps run: a ``concurrent.futures``-style executor chosen by one option.

* default: local processes (:class:`concurrent.futures.ProcessPoolExecutor`, ``workers``,
  started by a fork server);
  ``workers=1`` runs every task in this process (no pool start-up, easiest to debug);
* ``scheduler="tcp://HOST:PORT"`` (or any address ``distributed.Client`` accepts, e.g. the
  ``inproc://`` address of an in-process ``LocalCluster``): a Dask distributed cluster through
  ``Client(address).get_executor()`` -- the same ``submit`` / ``result`` interface, so the
  experiment code does not change. dask / distributed are optional imports.

Every task is a top-level function with plain arguments that carries its own random seed,
so the results do not depend on where or in which order the tasks ran
(tests/test_experiments.py checks local processes against a LocalCluster).
"""

from __future__ import annotations

import multiprocessing
import sys
import time
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import Executor, Future, ProcessPoolExecutor, as_completed
from contextlib import contextmanager
from typing import Any, TypeVar

T = TypeVar("T")


class ExecutorError(RuntimeError):
    """The requested executor cannot be set up (missing package, unreachable scheduler)."""


class InlineExecutor(Executor):
    """Runs each task at submit time in this process (``--workers 1``)."""

    def submit(self, fn: Callable[..., T], /, *args: Any, **kwargs: Any) -> Future[T]:
        fut: Future[T] = Future()
        try:
            fut.set_result(fn(*args, **kwargs))
        except BaseException as e:  # noqa: BLE001 - handed to the caller through the future
            fut.set_exception(e)
        return fut


@contextmanager
def make_executor(workers: int | None = None, scheduler: str | None = None) -> Iterator[Executor]:
    """Context manager yielding the executor for a sweep (see the module docstring)."""
    if scheduler:
        try:
            import distributed
        except ImportError:
            raise ExecutorError(f"--scheduler {scheduler} needs the 'distributed' package (Dask): "
                                ".venv/bin/pip install -r requirements.txt") from None
        try:
            client = distributed.Client(scheduler, timeout="10s", set_as_default=False)
        except (OSError, TimeoutError) as e:
            raise ExecutorError(f"cannot reach the Dask scheduler at {scheduler}: {e}") from None
        try:
            yield client.get_executor(pure=False)
        finally:
            client.close()
        return
    n = 1 if workers is None else int(workers)
    if n < 1:
        raise ValueError(f"--workers must be >= 1, got {n}")
    if n == 1:
        yield InlineExecutor()
        return
    # forkserver, not fork: the caller may have threads (a pytest-xdist worker, a GUI, a Dask
    # client); forking a threaded process can deadlock on a lock some thread held
    with ProcessPoolExecutor(max_workers=n, mp_context=multiprocessing.get_context("forkserver")) as ex:
        yield ex


def run_sweep(executor: Executor, fn: Callable[..., T], tasks: Sequence[dict[str, Any]], *,
              label: str = "sweep", progress: bool = True) -> list[T]:
    """``fn(**task)`` for every task on ``executor``; results in task order. Progress (done /
    total, wall time) goes to stderr."""
    t0 = time.time()
    futs = {executor.submit(fn, **task): i for i, task in enumerate(tasks)}
    out: list[Any] = [None] * len(tasks)
    done = 0
    for fut in as_completed(futs):
        out[futs[fut]] = fut.result()
        done += 1
        if progress:
            _bar(label, done, len(tasks), t0)
    if progress and tasks:
        sys.stderr.write("\n")
        sys.stderr.flush()
    return out


def _bar(label: str, done: int, total: int, t0: float) -> None:
    frac = done / max(total, 1)
    sys.stderr.write(f"\r  {label} [{'#' * int(30 * frac):<30}] {done}/{total} tasks, {time.time() - t0:5.1f} s wall")
    sys.stderr.flush()
