"""The bank built on a Dask cluster (``control.jobs``): a local cluster of two
worker processes, as a user's cluster would run it."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from control.jobs import CLUSTER_ENV, SCHEMES, ClusterError, cluster_address, run_jobs
from control.motion import Library
from mimic.cli import main
from silhouette_bank import build_bank
from tests.bank.conftest import SMALL


def test_a_bank_built_on_a_two_worker_cluster_is_the_local_build(
    lib: Library, tmp_path: Path, dask_cluster: str
) -> None:
    here = build_bank(lib.clips, SMALL, tmp_path / "here", shard_frames=20, workers=1)
    done: list[int] = []
    there = build_bank(
        lib.clips,
        SMALL,
        tmp_path / "there",
        shard_frames=20,
        cluster=dask_cluster,
        progress=lambda d, t: done.append(d),
    )
    # 103 frames in 6 shards of 20, counted by their silhouettes as they come
    assert len(done) == 7 and done[-1] == 103 * SMALL.n_views and sorted(done) == done
    # bit for bit: the same arrays, so the same files
    for name in ("bank.npz", "features.npy", "root_motion.npy"):
        assert (tmp_path / "here" / name).read_bytes() == (tmp_path / "there" / name).read_bytes()
    np.testing.assert_array_equal(there.features, here.features)


def _square_or_die(job: tuple[int, str]) -> int:
    """``i * i``; the worker that first runs job 2 dies in it (a machine lost mid-job)."""
    i, marker = job
    if i == 2:
        try:
            fd = os.open(marker, os.O_CREAT | os.O_EXCL | os.O_WRONLY)
        except FileExistsError:
            pass
        else:
            os.close(fd)
            os._exit(1)
    return i * i


@pytest.mark.slow
def test_a_job_whose_worker_dies_is_run_again_on_another(tmp_path: Path) -> None:
    marker = str(tmp_path / "died")
    got: dict[int, int] = {}
    run_jobs(_square_or_die, [(i, marker) for i in range(5)], got.__setitem__, cluster="local:2")
    assert Path(marker).exists()  # a worker did die
    assert got == {i: i * i for i in range(5)}


def test_the_cluster_is_named_by_flag_or_environment(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    monkeypatch.delenv(CLUSTER_ENV, raising=False)
    assert cluster_address() is None
    monkeypatch.setenv(CLUSTER_ENV, " tcp://10.0.0.5:8786 ")
    assert cluster_address() == "tcp://10.0.0.5:8786"
    assert cluster_address("local:3") == "local:3"
    assert cluster_address("") is None  # an explicit "" is this machine
    with pytest.raises(ClusterError, match="local:0"):
        run_jobs(abs, [1, 2], lambda i, r: None, cluster="local:0")
    monkeypatch.setenv(CLUSTER_ENV, "tcp://")
    with pytest.raises(ClusterError, match=r"'tcp://' \(\$MIMIC_CLUSTER\)"):
        run_jobs(abs, [1, 2], lambda i, r: None)
    monkeypatch.delenv(CLUSTER_ENV)
    argv = ["bank", "build", "--clips", "02_01", "--bank", str(tmp_path / "b")]
    assert main([*argv, "--cluster", "nonsense://x"]) == 2
    err = capsys.readouterr().err
    assert "'nonsense://x' (--cluster)" in err and "tcp://host:8786" in err
    assert not (tmp_path / "b").exists()  # said before anything was built
    out = tmp_path / "g.npz"
    assert (
        main(["graph", "build", "--clips", "02_01", "--out", str(out), "--cluster", "local:x"]) == 2
    )
    assert "local:N" in capsys.readouterr().err and not out.exists()


#: addresses as users write them, good and bad
ADDRESSES = [
    "tcp://10.0.0.5:8786",
    "10.0.0.5:8786",
    "scheduler",
    "tls://sched.example.org:8786",
    "tcp://[::1]:8786",
    "inproc://10.0.0.5/123/1",
    "ws://h:8786",
    "nonsense://x",
    "tcp://",
    "udp://h:8786",
    "tcp://h :8786",
]


@pytest.mark.slow  # (importing distributed takes a second)
@pytest.mark.parametrize("address", ADDRESSES)
def test_an_address_is_taken_as_dasks_own_parser_takes_it(address: str) -> None:
    from distributed.comm import registry
    from distributed.comm.addressing import parse_address

    assert set(SCHEMES) == set(registry.backends)
    scheme, location = parse_address(address, strict=False)
    dask_takes = scheme in registry.backends and bool(location) and " " not in location
    try:
        ours = cluster_address(address) == address
    except ClusterError:
        ours = False
    assert ours == dask_takes


class _PoolThatBreaks:
    """A process pool whose worker died (killed, out of memory, or unable to import the
    main script): ``map`` raises as ``ProcessPoolExecutor``'s does then."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        pass

    def __enter__(self) -> _PoolThatBreaks:
        return self

    def __exit__(self, *exc: object) -> None:
        return None

    def map(self, fn: object, jobs: object) -> list[int]:
        from concurrent.futures.process import BrokenProcessPool

        raise BrokenProcessPool("A process in the process pool was terminated abruptly")


def test_a_local_pool_that_loses_a_worker_says_why(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr("control.jobs.ProcessPoolExecutor", _PoolThatBreaks)
    with pytest.raises(ClusterError, match=r"worker process of the local pool .* workers=1"):
        run_jobs(abs, [1, 2], lambda i, r: None, workers=2)


@pytest.mark.slow
def test_a_local_cluster_says_nothing_into_a_quiet_commands_output(
    caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A local cluster's scheduler and nannies run in this process: at mimic's default
    level (warnings) their dozens of lines of progress are not said."""
    import logging

    monkeypatch.setattr(logging.getLogger(), "level", logging.WARNING)
    got: dict[int, int] = {}
    run_jobs(abs, [1, -2, 3], got.__setitem__, cluster="local:1")
    assert got == {0: 1, 1: 2, 2: 3}
    said = [r for r in caplog.records if r.name.startswith("distributed")]
    assert all(r.levelno >= logging.WARNING for r in said), [r.getMessage() for r in said]
