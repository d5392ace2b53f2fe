"""Shared fixtures: the real CMU library beside the checkout, a seeded rng, a private cache."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

# The tests run beside a background build (``prebuild``) on a machine of two cores: a
# BLAS of two threads in each process would wait on the other's core (the learned
# metric's eigensolver took 0.7 s instead of 0.01 s). Set before numpy is imported, and
# inherited by every process a test starts.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
# Where bytecode may not be written (PYTHONDONTWRITEBYTECODE, which some machines set for
# every process), each process a test starts compiles the project's modules anew, and
# each session rewrites every test module's asserts anew. Written once into
# ``__pycache__`` (beside numba's own caches, ignored by git), they are read by every
# later process and session (here from the test modules on: ``sys`` below).
os.environ.pop("PYTHONDONTWRITEBYTECODE", None)

import numpy as np
import pytest

from control.motion import Library, load_library

sys.dont_write_bytecode = False

REPO = Path(__file__).resolve().parents[1]


def _mocap_root() -> Path:
    env = os.environ.get("MIMIC_MOCAP")
    return Path(env) if env else REPO.parent / "shared" / "mocap"


MOCAP = _mocap_root()
SUBJECTS = MOCAP / "cmu" / "subjects"
BVH_DIR = MOCAP / "cmu-bvh"


@pytest.fixture(scope="session")
def mocap() -> Path:
    if not (MOCAP / "cmu" / "subjects").is_dir():
        pytest.fail(
            f"the CMU motion data is missing at {MOCAP}; tests read it from ../shared/mocap"
        )
    return MOCAP


@pytest.fixture(scope="session")
def dask_cluster(_private_cache: None) -> Iterator[str]:
    """The address of a local Dask cluster of two worker processes, started once for the
    tests that build on a cluster (as a user's ``dask scheduler`` + two ``dask worker``
    would serve them; ``local:N``'s own start and stop is tested apart)."""
    from distributed import LocalCluster

    cluster = LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0"
    )
    _DASK["cluster"] = cluster
    try:
        yield str(cluster.scheduler_address)
    finally:
        _close_dask()


#: the session's Dask cluster while it runs, and the last test that uses it
_DASK: dict[str, Any] = {}


def _close_dask() -> None:
    cluster = _DASK.pop("cluster", None)
    if cluster is not None:
        cluster.close()


#: session fixtures that build a library's graph, layer or bank, start a cluster or a
#: pose model: a test that uses one is ``slow`` (``pytest -m "not slow"``, the inner loop)
HEAVY = frozenset(
    {
        "actions", "banks", "chainer", "dask_cluster", "exercise", "graph", "lib",
        "films", "medium_lib", "playground", "playground_lib", "pose_bank", "setup", "squats",
        "walk", "walk_lib", "walks",
    }
)  # fmt: skip


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    users = [i.nodeid for i in items if "dask_cluster" in getattr(i, "fixturenames", ())]
    _DASK["last"] = users[-1] if users else None
    for item in items:
        # (a test's own parameter named as a fixture is not that fixture)
        params = getattr(getattr(item, "callspec", None), "params", {})
        heavy = HEAVY & (set(getattr(item, "fixturenames", ())) - set(params))
        if heavy or item.get_closest_marker("gl") is not None:
            item.add_marker(pytest.mark.slow)


@pytest.hookimpl(trylast=True)
def pytest_runtest_teardown(item: pytest.Item) -> None:
    # An idle cluster's scheduler thread and workers take about 3% of a core each: close
    # it after the last test that uses it, not at the session's end.
    if item.nodeid == _DASK.get("last"):
        _close_dask()


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(20021122)


@pytest.fixture(scope="session")
def session_cache(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The cache the tests share: what one test builds (a graph, a layer, a bank), the
    next loads, as a user's second run does. Entries are content-addressed and checked
    on load (``control.artifacts``), so a loaded one is the one a build would make."""
    return tmp_path_factory.mktemp("cache")


@pytest.fixture(scope="session", autouse=True)
def _private_cache(session_cache: Path) -> Iterator[None]:
    # Tests never read or write the user's cache: set for the whole session, before any
    # module's fixture is made (a test's own monkeypatch may still point it elsewhere).
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("MIMIC_CACHE", str(session_cache))
        yield


#: the session fixtures whose artifacts tests/prebuild.py builds, and the parts of each
#: (a session of the vision tests also runs the commands on 13_30 with landmarks)
PREBUILT = {
    "playground": ("playground",),
    "actions": ("walks",),
    "setup": ("bank", "mirrored"),
    "films": ("films",),
}


class Prebuild:
    """The background build of ``tests/prebuild.py`` (``None``: none needed)."""

    def __init__(self, proc: subprocess.Popen[bytes] | None, cache: Path) -> None:
        self.proc = proc
        self.cache = cache

    def wait(self, part: str, timeout: float = 900.0) -> None:
        """Until ``part`` is built, or the build ended (whatever its outcome)."""
        t0 = time.monotonic()
        marker = self.cache / f"prebuilt-{part}"
        while self.proc is not None and self.proc.poll() is None and not marker.exists():
            if time.monotonic() - t0 > timeout:
                break
            time.sleep(0.05)


@pytest.fixture(scope="session", autouse=True)
def prebuild(
    _private_cache: None, session_cache: Path, request: pytest.FixtureRequest
) -> Iterator[Prebuild]:
    """Start ``tests/prebuild.py`` on the parts that this session's tests will need."""
    from tests.prebuild import PARTS

    used = {f for item in request.session.items for f in getattr(item, "fixturenames", ())}
    wanted = {p for f in used & set(PREBUILT) for p in PREBUILT[f]}
    parts = [p for p in PARTS if p in wanted]
    # A session of the slow fixtures' tests also compiles the test-only kernels, in a
    # process of its own: the first tests that use them come before the parts are done.
    jobs = [parts, ["kernels"]] if parts else []
    procs = []
    for i, job in enumerate(jobs):
        with open(session_cache / f"prebuild-{i}.log", "wb") as log:
            procs.append(
                subprocess.Popen(
                    [sys.executable, "-m", "tests.prebuild", *job],
                    cwd=REPO,
                    env=dict(os.environ),
                    stdout=log,
                    stderr=subprocess.STDOUT,
                )
            )
    yield Prebuild(procs[0] if procs else None, session_cache)
    for proc in procs:
        if proc.poll() is None:
            proc.kill()
        proc.wait()


@pytest.fixture
def fresh_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty cache of the test's own, for a test about building or about the cache."""
    path = tmp_path / "fresh-cache"
    monkeypatch.setenv("MIMIC_CACHE", str(path))
    return path


def amc_path(clip: str) -> Path:
    return SUBJECTS / clip[:2] / f"{clip}.amc"


def asf_path(clip: str) -> Path:
    return SUBJECTS / clip[:2] / f"{clip[:2]}.asf"


# The libraries below load from the tests' cache (its motion folder, whichever cache the
# first test to ask has set), as a user's second run does: entries are content-addressed
# and checked on load, and clips the background prebuild or an earlier test has parsed
# are not parsed again.


@pytest.fixture(scope="session")
def walk_lib(mocap: Path, session_cache: Path) -> Library:
    """Subject 02's walks, run and jump (164 frames at 15 frames/s): small enough for
    brute force over all pairs."""
    return load_library(mocap, clips=["02_0[1-4]"], cache_dir=session_cache / "motion")


@pytest.fixture(scope="session")
def medium_lib(mocap: Path, session_cache: Path) -> Library:
    """Subjects 02 and 03 (about 3,000 frames): a graph worth walking in."""
    return load_library(mocap, clips=["02_*", "03_*"], cache_dir=session_cache / "motion")


@pytest.fixture(scope="session")
def playground_lib(mocap: Path, session_cache: Path) -> Library:
    """Subject 01, the paper's playground (6,864 frames at 15 frames/s), parsed by
    tests/prebuild.py in the background by the time the first test that needs it runs."""
    return load_library(mocap, clips=["01_*"], cache_dir=session_cache / "motion")
