"""Which distributed engine builds the bank (issue 21): Dask distributed against Ray, and
both against the local process pool, on the same shards.

For each engine: the time to start a local cluster of ``--workers`` worker processes, the
overhead of 200 empty tasks, and the wall time of a bank build of ``--clips`` (the
project's shard jobs, every result sent back to this process, which writes the shards)
with its bank checked bit for bit against the one-process build. Ray is measured when it
is importable (it is not a dependency: install it in another environment and run this
script there with ``PYTHONPATH`` at the checkout).

    python -m benchmarks.bench_cluster [--engines local,dask,ray] [--workers 2]
"""

from __future__ import annotations

import argparse
import importlib.util
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._report import machine, save
from control.jobs import run_jobs
from control.motion import default_library_path, load_library
from silhouette_bank import BankSettings, build_bank
from silhouette_bank import _bank as bank_module
from silhouette_bank._metric import metric_jobs


def _noop(x: int) -> int:
    return x


def _dask(workers: int, jobs: list[Any]) -> dict[str, Any]:
    """A local Dask cluster's start and empty-task cost, and the jobs run through the
    project's own path to a cluster (``run_jobs`` with the scheduler's address)."""
    from distributed import Client, LocalCluster

    t0 = time.perf_counter()
    with (
        LocalCluster(
            n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None
        ) as cl,
        Client(cl) as client,
    ):
        client.wait_for_workers(workers)
        start = time.perf_counter() - t0
        t1 = time.perf_counter()
        client.gather(client.map(_noop, range(200), pure=False))
        empty = (time.perf_counter() - t1) / 200
        t2 = time.perf_counter()
        out: dict[int, Any] = {}
        run_jobs(bank_module._run_job, jobs, out.__setitem__, cluster=cl.scheduler_address)
        build = time.perf_counter() - t2
    return {"start_s": start, "empty_task_ms": empty * 1e3, "render_s": build, "shards": out}


def _ray(workers: int, jobs: list[Any]) -> dict[str, Any]:
    import ray

    t0 = time.perf_counter()
    ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False)
    noop = ray.remote(_noop)
    run = ray.remote(bank_module._run_job)
    ray.get([noop.remote(0) for _ in range(workers)])  # the workers are up
    start = time.perf_counter() - t0
    t1 = time.perf_counter()
    ray.get([noop.remote(i) for i in range(200)])
    empty = (time.perf_counter() - t1) / 200
    t2 = time.perf_counter()
    out = dict(enumerate(ray.get([run.remote(j) for j in jobs])))
    build = time.perf_counter() - t2
    ray.shutdown()
    return {"start_s": start, "empty_task_ms": empty * 1e3, "render_s": build, "shards": out}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--engines", default="local,dask,ray")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--clips", default="13_29,13_30")
    ap.add_argument("--shard-frames", type=int, default=100)
    ap.add_argument("--out", default="benchmarks/results/cluster.json")
    args = ap.parse_args()
    lib = load_library(default_library_path(), clips=args.clips.split(","))
    settings = BankSettings()
    result: dict[str, Any] = {
        "machine": machine(),
        "date": time.strftime("%Y-%m-%d"),
        "clips": args.clips,
        "frames": sum(c.motion.n_frames for c in lib.clips),
        "views": settings.n_views,
        "workers": args.workers,
        "engines": {},
    }
    with tempfile.TemporaryDirectory() as tmp:
        t0 = time.perf_counter()
        ref = build_bank(lib.clips, settings, Path(tmp) / "one", args.shard_frames, workers=1)
        result["one_process_build_s"] = round(time.perf_counter() - t0, 2)
        for engine in args.engines.split(","):
            if (
                engine in ("dask", "ray")
                and importlib.util.find_spec("distributed" if engine == "dask" else engine) is None
            ):
                result["engines"][engine] = "not installed here"
                continue
            if engine == "local":
                t0 = time.perf_counter()
                b = build_bank(
                    lib.clips, settings, Path(tmp) / "pool", args.shard_frames, args.workers
                )
                result["engines"]["local"] = {
                    "build_s": round(time.perf_counter() - t0, 2),
                    "identical": bool(np.array_equal(b.features, ref.features)),
                }
                continue
            folder = Path(tmp) / engine
            manifest = bank_module._start_manifest(lib.clips, settings, folder, args.shard_frames)
            jobs: list[Any] = [
                *bank_module._shards_to_render(lib.clips, settings, folder, manifest)
            ]
            n = len(jobs)
            jobs += metric_jobs(lib.clips, settings.descriptor, settings.ring, settings.body)
            got = (_dask if engine == "dask" else _ray)(args.workers, jobs)
            feats = np.concatenate([got["shards"][i][1]["features"] for i in range(n)])
            result["engines"][engine] = {
                "start_s": round(got["start_s"], 2),
                "empty_task_ms": round(got["empty_task_ms"], 3),
                "render_s": round(got["render_s"], 2),
                "identical": bool(np.array_equal(feats, ref.features)),
            }
            print(engine, result["engines"][engine], flush=True)
    save(result, args.out)


if __name__ == "__main__":
    main()
