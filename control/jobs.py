"""Where a build's jobs run (a bank's render jobs, a graph's blocks of frame pairs): in
this process, in spawned local processes, or on a Dask cluster (``distributed``).

A cluster is named by ``cluster`` (``mimic bank build --cluster``, ``mimic graph build
--cluster``) or, failing that, the
environment variable ``MIMIC_CLUSTER``: a scheduler's address (``tcp://host:8786``, as
``dask scheduler`` prints it) or ``local:N`` (a cluster of ``N`` worker processes on this
machine, started for the build and closed after it). The jobs are the same everywhere and
every job's result comes back to this process, which writes it: so a cluster's workers
need the project installed but no shared disk, and a bank built on a cluster is the local
build bit for bit. A worker lost mid-build has its jobs run again by the scheduler (up to
``RETRIES`` times); a build stopped altogether keeps what it wrote and resumes: the bank
its shards, other builds each finished job's result (``JobStore``).

Why Dask and not Ray (``benchmarks/bench_cluster.py``: a local cluster of 2 workers,
the 18-view bank of 13_29 + 13_30): the render jobs take as long on either, an empty
task's overhead (a millisecond or so on both) does not matter for jobs of a second or
more, a Dask cluster starts several times faster; Dask installs as 24 MB of pure Python
(Ray: 240 MB with its own daemon and object store), its client API is
``concurrent.futures``'s, and a worker is one command per machine (``dask worker
tcp://scheduler:8786``).
"""

from __future__ import annotations

import functools
import json
import logging
import multiprocessing
import os
import shutil
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import numpy as np

from .artifacts import atomic_write, read_checked_npz, write_checked_npz

__all__ = [
    "CLUSTER_ENV",
    "RETRIES",
    "SCHEMES",
    "ClusterError",
    "JobStore",
    "cluster_address",
    "map_jobs",
    "run_jobs",
]

log = logging.getLogger(__name__)

#: the environment variable naming a cluster when no ``cluster`` argument does
CLUSTER_ENV = "MIMIC_CLUSTER"
#: times a job whose worker was lost is run again
RETRIES = 3


class ClusterError(RuntimeError):
    """A cluster that cannot be reached or that failed mid-build (names the address), or
    a local pool that lost a worker process (says the likely causes)."""


#: the address schemes of Dask's comms (``distributed.comm.registry``)
SCHEMES = ("tcp", "tls", "inproc", "ucx", "ws", "wss")


def cluster_address(cluster: str | None = None) -> str | None:
    """The cluster to build on: ``cluster``, else ``$MIMIC_CLUSTER``, else ``None``
    (this machine). ``""`` is none. An address of no form Dask or ``local:N`` has is a
    ``ClusterError`` that names it and where it came from, here, before anything is
    loaded or imported for the build (Dask itself would say so only on connecting)."""
    given = cluster if cluster is not None else os.environ.get(CLUSTER_ENV, "")
    address = given.strip()
    if not address:
        return None
    source = "--cluster" if cluster is not None else f"${CLUSTER_ENV}"
    forms = "a scheduler's address (tcp://host:8786, or host:8786) or local:N (N >= 1)"
    if address.startswith("local:"):
        count = address.split(":", 1)[1]
        if not count.isdigit() or int(count) < 1:
            raise ClusterError(
                f"cluster {address!r} ({source}): local:N needs a number of workers N >= 1"
            )
        return address
    scheme, sep, rest = address.partition("://")
    if not sep:
        scheme, rest = "tcp", address
    if scheme not in SCHEMES or not rest or any(c.isspace() for c in rest):
        raise ClusterError(
            f"cluster {address!r} ({source}) is not {forms}; the schemes are "
            + ", ".join(f"{s}://" for s in SCHEMES)
        )
    return address


def run_jobs(
    fn: Callable[..., Any],
    jobs: Sequence[Any],
    on_result: Callable[[int, Any], None],
    workers: int | None = None,
    cluster: str | None = None,
    shared: Any = None,
) -> None:
    """``on_result(i, fn(jobs[i]))`` for every job, in this process, as the results
    come (in any order on a cluster; in order otherwise). On the cluster ``cluster``
    (see the module) when one is named; else in ``workers`` spawned processes (default:
    the cores, at most 4) when more than one, else here. With ``shared`` (not ``None``),
    ``fn(shared, jobs[i])``: ``shared`` is sent to each worker once (scattered to every
    worker of a cluster; given to each local process as it starts), not with every job."""
    address = cluster_address(cluster)
    if not jobs:
        return
    call: Callable[[Any], Any] = fn if shared is None else functools.partial(_with_shared, fn)
    if address is not None:
        _on_cluster(address, fn, jobs, on_result, shared)
        return
    n_workers = min(workers or min(os.cpu_count() or 1, 4), len(jobs))
    if n_workers <= 1:
        for i, job in enumerate(jobs):
            on_result(i, fn(job) if shared is None else fn(shared, job))
        return
    # spawn, not fork: numba's OpenMP threads in this process make fork unsafe
    ctx = multiprocessing.get_context("spawn")
    try:
        with ProcessPoolExecutor(
            n_workers, mp_context=ctx, initializer=_keep_shared, initargs=(shared,)
        ) as pool:
            for i, out in enumerate(pool.map(call, jobs)):
                on_result(i, out)
    except BrokenProcessPool as exc:
        raise ClusterError(
            f"a worker process of the local pool ({n_workers} processes) died: killed, out "
            "of memory, or unable to start (a spawned worker imports the main script again, "
            "so code run from standard input or a notebook, or a script without an "
            "'if __name__ == \"__main__\":' guard, cannot use it); build with workers=1 "
            "(--workers 1) to render in this process"
        ) from exc


def map_jobs(
    fn: Callable[..., Any],
    jobs: Sequence[Any],
    workers: int | None = None,
    cluster: str | None = None,
    shared: Any = None,
) -> list[Any]:
    """``run_jobs``' results in the order of ``jobs`` (held until the last has come)."""
    got: dict[int, Any] = {}
    run_jobs(fn, jobs, got.__setitem__, workers, cluster, shared)
    return [got[i] for i in range(len(jobs))]


class JobStore:
    """The finished jobs of one build, each job's arrays a file in ``folder``
    (``part-000012.npz``, checksummed, written whole or not at all), so that a build
    stopped (Ctrl-C, a lost machine, a cluster gone) runs only the jobs it had not
    finished when it runs again. ``key`` names the build and its job table: a folder left
    by another build (other options, library or job sizes) is emptied, never mixed in.
    The build removes the folder once its result is stored (``remove``)."""

    _MANIFEST = "jobs.json"

    def __init__(self, folder: str | Path, key: str) -> None:
        self.folder, self.key = Path(folder), key
        manifest = self.folder / self._MANIFEST
        try:
            same = json.loads(manifest.read_text()).get("key") == key
        except (OSError, ValueError, AttributeError):
            same = False
        if not same:
            self.remove()
            self.folder.mkdir(parents=True, exist_ok=True)
            with atomic_write(manifest) as fh:
                json.dump({"key": key}, fh)

    def _path(self, i: int) -> Path:
        return self.folder / f"part-{i:06d}.npz"

    def done(self, n_jobs: int, keys: Sequence[str]) -> dict[int, dict[str, np.ndarray]]:
        """The arrays ``keys`` of every job of the ``n_jobs`` finished before; a part
        that cannot be read back (damaged, cut short) is said, removed and run again."""
        got = {i: self.read(i, keys) for i in range(n_jobs) if self._path(i).is_file()}
        return {i: a for i, a in got.items() if a is not None}

    def read(self, i: int, keys: Sequence[str]) -> dict[str, np.ndarray] | None:
        """Job ``i``'s arrays ``keys``, or ``None`` where it has none that can be read
        back (a damaged part is said and removed: the job is to run again). One part at
        a time, for results too large to hold all at once."""
        path = self._path(i)
        if not path.is_file():
            return None
        try:
            return read_checked_npz(path, keys, _PartError, "a finished job's part")
        except _PartError as exc:
            log.warning("running a job again: %s", exc)
            path.unlink(missing_ok=True)
            return None

    def save(self, i: int, arrays: dict[str, np.ndarray]) -> None:
        """Job ``i``'s result, kept (its folder made again if it was removed meanwhile)."""
        self.folder.mkdir(parents=True, exist_ok=True)
        write_checked_npz(self._path(i), arrays)

    def remove(self) -> None:
        """The folder and every part in it, gone."""
        shutil.rmtree(self.folder, ignore_errors=True)


class _PartError(ValueError):
    def __init__(self, path: Path, problem: str) -> None:
        super().__init__(f"{path}: {problem}")


#: a local worker process's ``shared`` (``run_jobs``), set as it starts
_SHARED: Any = None


def _keep_shared(shared: Any) -> None:
    global _SHARED
    _SHARED = shared


def _with_shared(fn: Callable[[Any, Any], Any], job: Any) -> Any:
    return fn(_SHARED, job)


@contextmanager
def _client(address: str) -> Iterator[Any]:
    try:
        from distributed import Client
    except ImportError as exc:
        raise ClusterError(
            f"building on the cluster {address!r} needs Dask's distributed "
            "(pip install 'mimic[cluster]' or distributed)"
        ) from exc
    if address.startswith("local:"):
        # the scheduler and the workers' nannies run in this process: their lines of
        # progress (dozens a build) are said only where this process says its own
        # (``mimic --verbose``), not into the command's output
        talk = logging.getLogger("distributed")
        level = talk.level
        if logging.getLogger().getEffectiveLevel() > logging.INFO:
            talk.setLevel(logging.WARNING)
        try:
            with _local_client(address) as client:
                yield client
        finally:
            talk.setLevel(level)
        return
    try:
        client = Client(address, timeout=30)
    except (OSError, TimeoutError, ValueError) as exc:
        raise ClusterError(f"cannot reach the cluster at {address!r}: {exc}") from exc
    with client:
        yield client


@contextmanager
def _local_client(address: str) -> Iterator[Any]:
    """A client of a cluster of ``N`` worker processes on this machine (``local:N``),
    started here and closed after."""
    from distributed import Client, LocalCluster

    n = int(address.split(":", 1)[1])  # (checked by ``cluster_address``)
    with (
        LocalCluster(  # (its dashboard on a free port: None would take 8787, which
            # another cluster on this machine may hold)
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            dashboard_address=":0",
        ) as local,
        Client(local) as client,
    ):
        yield client


def _on_cluster(
    address: str,
    fn: Callable[..., Any],
    jobs: Sequence[Any],
    on_result: Callable[[int, Any], None],
    shared: Any = None,
) -> None:
    from distributed import as_completed

    with _client(address) as client:
        first = () if shared is None else (client.scatter(shared, broadcast=True),)

        def submit(i: int) -> Any:
            key = f"mimic-job-{i}-{os.getpid()}"
            return client.submit(fn, *first, jobs[i], key=key, retries=RETRIES, pure=False)

        # handed over a few at a time (twice the workers), so that jobs that carry their
        # data (a window index's slices of its tables) are not all held at once
        ahead = max(4, 2 * len(client.scheduler_info().get("workers", {})))
        futures = [submit(i) for i in range(min(ahead, len(jobs)))]
        where = {f.key: i for i, f in enumerate(futures)}
        try:
            coming = as_completed(futures, with_results=True)
            for future, out in coming:
                on_result(where[future.key], out)
                if len(futures) < len(jobs):
                    futures.append(nxt := submit(len(futures)))
                    where[nxt.key] = len(futures) - 1
                    coming.add(nxt)
        except Exception as exc:  # a job that failed on every try, or a lost scheduler
            raise ClusterError(
                f"the build on the cluster {address!r} failed ({type(exc).__name__}: {exc}); "
                "a bank's shards finished so far are kept: build again to resume"
            ) from exc
        finally:
            client.cancel(futures)
