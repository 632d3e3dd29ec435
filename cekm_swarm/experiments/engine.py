"""Where an experiment's many independent runs go: Dask (``distributed``). Every experiment
that runs many runs (``tracking --grid``, ``tracking``'s seeds, ``obstacles``, ``sweep``,
``target-reaching --master-seeds``)
hands its jobs to :func:`run_jobs`, which runs them

* in this process, for one worker (``--workers 1``: no cluster to start);
* on a local Dask cluster of ``--workers`` processes (one thread each), the default;
* on a running Dask scheduler, ``--cluster tcp://HOST:PORT`` (its workers run
  ``dask worker tcp://HOST:PORT`` with this package installed at the same version, and
  read the model file at the same path: a shared disk).

The results come back in job order whatever the engine, the number of workers or which
worker ran what: each run is a pure function of its job (seeded), so ``results.json`` is
the same bit for bit. A worker that dies mid-run (killed, out of memory, its host gone)
loses only its runs in flight: the scheduler gives them to another worker (Dask's own
rule, up to ``distributed.scheduler.allowed-failures`` deaths per run). A progress bar
counts the runs as they end."""

from __future__ import annotations

import contextlib
import contextvars
import logging
import os
from collections.abc import Callable, Iterator, Sequence
from typing import Any, TypeVar

from ..errors import CekmError

T = TypeVar("T")
R = TypeVar("R")

_CLUSTER: contextvars.ContextVar[str | None] = contextvars.ContextVar("cekm_cluster", default=None)


@contextlib.contextmanager
def on_cluster(address: str | None) -> Iterator[None]:
    """Within the block, :func:`run_jobs` sends its jobs to the Dask scheduler at ``address``
    (``tcp://HOST:PORT``; None: a local cluster)."""
    token = _CLUSTER.set(address)
    try:
        yield
    finally:
        _CLUSTER.reset(token)


class ClusterAddressError(CekmError):
    """A ``--cluster`` address that is not ``tcp://HOST:PORT``."""


def cluster_address() -> str | None:
    """The Dask scheduler :func:`on_cluster` set for this block (None: none)."""
    return _CLUSTER.get()


def check_address(value: str) -> str:
    """``value`` when it reads as a Dask scheduler's address (``tcp://HOST:PORT`` or
    ``tls://HOST:PORT``), else :class:`ClusterAddressError` saying so."""
    scheme, sep, rest = value.partition("://")
    host, colon, port = rest.rpartition(":")
    if not sep or scheme not in ("tcp", "tls") or not colon or not host or not port.isdigit():
        raise ClusterAddressError(f"{value!r}: give the Dask scheduler's address as tcp://HOST:PORT")
    return value


def default_workers(jobs: int, cap: int | None = None) -> int:
    """One local worker per core, no more than there are jobs (nor ``cap``)."""
    n = max(1, min(jobs, os.cpu_count() or 1))
    return min(n, cap) if cap else n


def run_jobs(fn: Callable[[T], R], jobs: Sequence[T], workers: int | None = None, *, desc: str = "runs",
             progress: bool = True, cluster: str | None = None) -> list[R]:
    """``fn(job)`` for every job, in job order (see the module's docstring for where they
    run). ``fn`` must be a module-level function (the workers import it by name); ``cluster``
    overrides :func:`on_cluster`'s address."""
    from tqdm import tqdm  # noqa: PLC0415 -- lazy: tqdm

    address = cluster or _CLUSTER.get()
    workers = workers or default_workers(len(jobs))
    bar = tqdm(total=len(jobs), disable=not progress, desc=desc, unit="run")
    try:
        if address is None and (workers == 1 or len(jobs) <= 1):
            out = []
            for job in jobs:
                out.append(fn(job))
                bar.update()
            return out
        with _client(address, min(workers, len(jobs))) as client:
            return _gather(client, fn, jobs, bar)
    finally:
        bar.close()


@contextlib.contextmanager
def _client(address: str | None, workers: int) -> Iterator[Any]:
    from distributed import Client, LocalCluster

    if address is not None:
        with Client(address, set_as_default=False) as client:
            yield client
        return
    with LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None,
                      memory_limit=0, silence_logs=logging.ERROR) as local, \
            Client(local, set_as_default=False) as client:
        yield client


def _gather(client: Any, fn: Callable[[T], R], jobs: Sequence[T], bar: Any) -> list[R]:
    """Submit every job (largest first is the caller's order), collect as they end."""
    from distributed import as_completed

    futures = client.map(fn, list(jobs), pure=False)
    index = {f.key: i for i, f in enumerate(futures)}
    out: list[Any] = [None] * len(jobs)
    for fut in as_completed(futures, loop=client.loop):
        out[index[fut.key]] = fut.result()
        fut.release()
        bar.update()
    return out
