"""Fault injection over every kind of file mimic writes for itself.

Each artifact is built once, pristine. A case copies it, damages one file (a flipped byte,
a truncation, or an edit that keeps the file well formed: a manifest value changed, an
array moved) and loads it the way a command would. The outcome is one of:

``same``     the same result as the pristine artifact gives, no warning;
``rebuilt``  the same result, after a warning that names the damaged file;
``error``    one of the artifact's own errors, whose message names the damaged file;

or a failure: ``wrong data`` (a different result, used silently) or ``traceback`` (any
other exception, or an error that does not name the file). Used by
``tests/test_faults.py`` (a few seeded cases of each) and ``benchmarks/bench_faults.py``
(the sweep whose table goes into the closing note).
"""

from __future__ import annotations

import functools
import json
import logging
import shutil
import tempfile
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from control.clusters import LayerFileError, LayerSettings, cached_higher_layer
from control.graph import GraphFileError, cached_graph, load_graph
from control.motion import (
    MotionFormatError,
    load_library,
    read_motion_arrays,
    write_motion_arrays,
)
from silhouette_bank import BankFileError, BankSettings, CameraRing, ensure_bank
from vision import IndexFileError, Matcher, MatchSettings, WindowTablesError, _tables

GOOD = ("same", "rebuilt", "error")
SMALL_BANK = BankSettings(CameraRing(n_views=4, width=64, height_px=48), descriptor="hu")
CLIPS = ["02_0[1-4]"]  # 164 frames at 15 frames/s, 30 transitions: every build is quick
LAYER_K = 4  # a fixed cluster count: the sweep rebuilds the layer ten times, not a BIC curve


# --- damaging files ------------------------------------------------------------------------


def flip(path: Path, rng: np.random.Generator) -> str:
    data = bytearray(path.read_bytes())
    at = int(rng.integers(len(data)))
    data[at] ^= int(rng.integers(1, 256))
    path.write_bytes(bytes(data))
    return f"flip byte {at}"


def truncate(path: Path, rng: np.random.Generator) -> str:
    data = path.read_bytes()
    at = int(rng.integers(len(data)))
    path.write_bytes(data[:at])
    return f"truncate to {at} bytes"


def edit_npz(path: Path, change: Callable[[dict[str, Any]], object], meta: str) -> None:
    """Rewrite the ``.npz`` at ``path`` with ``change`` applied to its arrays, the JSON
    entry ``meta`` decoded into a dict (a well-formed file, consistently edited)."""
    with np.load(path, allow_pickle=False) as z:
        arrays: dict[str, Any] = {k: z[k] for k in z.files}
    arrays[meta] = json.loads(str(arrays[meta]))
    change(arrays)
    arrays[meta] = np.array(json.dumps(arrays[meta]))
    with path.open("wb") as fh:
        np.savez(fh, **arrays)


def edit_json(path: Path, change: Callable[[Any], Any]) -> None:
    doc = json.loads(path.read_text())
    path.write_text(json.dumps(change(doc)))


def _set(d: dict[str, Any], key: str, value: Any) -> dict[str, Any]:
    d[key] = value
    return d


def _swap_names(d: dict[str, Any], key: str) -> dict[str, Any]:
    d[key] = list(reversed(d[key]))
    return d


# --- the artifacts -------------------------------------------------------------------------


@dataclass
class Artifact:
    """One kind of file, how it is found in a pristine copy, loaded, and compared."""

    name: str
    target: Callable[[Path], Path]  # the file to damage in a copy of the pristine folder
    load: Callable[[Path], Any]  # load from that copy, as a command does
    same: Callable[[Any, Any], bool]  # result vs the pristine one
    errors: tuple[type[Exception], ...]
    edits: dict[str, Callable[[Path], object]] = field(default_factory=dict)
    #: what a message must name: the damaged file, or (a bank) its folder
    named: Callable[[Path], Path] = lambda target: target


def _same_arrays(a: Any, b: Any, names: tuple[str, ...]) -> bool:
    return all(
        np.array_equal(np.asarray(getattr(a, n)), np.asarray(getattr(b, n)), equal_nan=True)
        for n in names
    )


def _same_library(a: Any, b: Any) -> bool:
    return len(a.clips) == len(b.clips) and all(
        x.name == y.name
        and x.motion.fps == y.motion.fps
        and np.array_equal(x.motion.root_pos, y.motion.root_pos)
        and np.array_equal(x.motion.quats, y.motion.quats)
        and np.array_equal(x.contacts.states, y.contacts.states)
        for x, y in zip(a.clips, b.clips, strict=True)
    )


def _same_graph(a: Any, b: Any) -> bool:
    return (
        a.fps == b.fps
        and np.array_equal(a.sigma, b.sigma, equal_nan=True)
        and a.clip_names == b.clip_names
        and _same_arrays(a, b, ("clip_start", "src", "dst", "dist", "align", "in_scc"))
    )


def _same_layer(a: Any, b: Any) -> bool:
    return (
        _same_arrays(a, b, ("states", "q_hat"))
        and np.array_equal(a.clustering.labels, b.clustering.labels)
        and np.array_equal(a.forest.tree_of, b.forest.tree_of)
        and a.forest.bound == b.forest.bound
    )


def _same_bank(a: Any, b: Any) -> bool:
    return (
        a.clip_names == b.clip_names
        and a.settings == b.settings
        and _same_arrays(a, b, ("features", "root_motion", "clip_start"))
    )


def artifacts(mocap: Path, root: Path) -> tuple[list[Artifact], dict[str, Any]]:
    """Build every artifact once under ``root`` (pristine); returns the artifacts and
    each one's pristine result."""
    motion_cache = root / "motion"
    lib = load_library(mocap, clips=CLIPS, cache_dir=motion_cache, workers=1)
    graph, _, _ = cached_graph(lib.clips, cache_dir=root / "graph")
    cached_higher_layer(graph, lib.clips, LayerSettings(k=LAYER_K), cache_dir=root / "graph")
    layer, _, _ = cached_higher_layer(
        graph, lib.clips, LayerSettings(k=LAYER_K), cache_dir=root / "graph"
    )
    bank, _ = ensure_bank(lib.clips, SMALL_BANK, root / "bank", workers=1)
    matcher = Matcher(layer, bank, MatchSettings())
    index = matcher.windows.index()  # stored in the bank's folder, and the tables beside it
    tables = tuple(np.array(t) for t in matcher.windows.tables())
    write_motion_arrays(root / "arrays" / "02_01.motion.npz", lib.clips[0].motion)
    arrays = read_motion_arrays(root / "arrays" / "02_01.motion.npz")

    def one(folder: str, pattern: str) -> Callable[[Path], Path]:
        return lambda r: sorted((r / folder).glob(pattern))[0]

    def load_lib(r: Path) -> Any:
        return load_library(mocap, clips=CLIPS, cache_dir=r / "motion", workers=1)

    def load_parsed(r: Path) -> Any:  # the parsed files' entries, without the whole's
        for p in (r / "motion").glob("library-*.npz"):
            p.unlink()
        return load_lib(r)

    def load_cached_graph(r: Path) -> Any:
        return cached_graph(lib.clips, cache_dir=r / "graph")[0]

    def load_layer(r: Path) -> Any:
        return cached_higher_layer(
            graph, lib.clips, LayerSettings(k=LAYER_K), cache_dir=r / "graph"
        )[0]

    def load_bank(r: Path) -> Any:
        return ensure_bank(lib.clips, SMALL_BANK, r / "bank", workers=1)[0]

    def load_index(r: Path) -> Any:
        stored = ensure_bank(lib.clips, SMALL_BANK, r / "bank", workers=1)[0]
        return Matcher(layer, stored, MatchSettings()).windows.index()

    def load_tables(r: Path) -> Any:
        stored = ensure_bank(lib.clips, SMALL_BANK, r / "bank", workers=1)[0]
        return Matcher(layer, stored, MatchSettings()).windows.tables()

    def moved(a: dict[str, Any], key: str) -> None:
        a[key] = a[key] + np.array([1.0, 0.0, 0.0], dtype=a[key].dtype)  # 1 m along x

    motion_edits: dict[str, Callable[[Path], object]] = {
        "root moved 1 m": lambda p: edit_npz(p, lambda a: moved(a, "root_pos"), "meta"),
        "fps set to 30": lambda p: edit_npz(p, lambda a: _set(a["meta"], "fps", 30.0), "meta"),
        "names swapped": lambda p: edit_npz(p, lambda a: _swap_names(a["meta"], "names"), "meta"),
        "meta a JSON list": lambda p: edit_npz(p, lambda a: _set(a, "meta", [1, 2]), "meta"),
    }

    def first_clip(a: dict[str, Any], key: str, value: Any) -> None:
        a["meta"]["clips"][0][key] = value

    whole_edits: dict[str, Callable[[Path], object]] = {
        "roots moved 1 m": lambda p: edit_npz(p, lambda a: moved(a, "root_pos"), "meta"),
        "a clip one frame longer": lambda p: edit_npz(
            p, lambda a: first_clip(a, "frames", a["meta"]["clips"][0]["frames"] + 1), "meta"
        ),
        "a clip renamed": lambda p: edit_npz(p, lambda a: first_clip(a, "name", "x"), "meta"),
        "contacts cleared": lambda p: edit_npz(
            p, lambda a: _set(a, "states", np.zeros_like(a["states"])), "meta"
        ),
    }
    graph_edits: dict[str, Callable[[Path], object]] = {
        "fps set to 30": lambda p: edit_npz(
            p, lambda a: _set(a["manifest"], "fps", 30.0), "manifest"
        ),
        "sigma NaN": lambda p: edit_npz(
            p, lambda a: _set(a["manifest"], "sigma", float("nan")), "manifest"
        ),
        "clip names swapped": lambda p: edit_npz(
            p, lambda a: _swap_names(a["manifest"], "clip_names"), "manifest"
        ),
        "a transition moved": lambda p: edit_npz(
            p, lambda a: _set(a, "dst", np.roll(a["dst"], 1)), "manifest"
        ),
        "manifest a JSON list": lambda p: edit_npz(
            p, lambda a: _set(a, "manifest", []), "manifest"
        ),
        "no checksum": lambda p: edit_npz(p, lambda a: a["manifest"].pop("checksum"), "manifest"),
    }
    layer_edits: dict[str, Callable[[Path], object]] = {
        "bound changed": lambda p: edit_npz(
            p, lambda a: _set(a["manifest"], "bound", 3), "manifest"
        ),
        "labels rolled": lambda p: edit_npz(
            p, lambda a: _set(a, "c_labels", np.roll(a["c_labels"], 1)), "manifest"
        ),
    }
    bank_manifest_edits: dict[str, Callable[[Path], object]] = {
        "n_views set to 9": lambda p: edit_json(p, lambda d: _set(d, "views", 9)),
        "clip names swapped": lambda p: edit_json(p, lambda d: _swap_names(d, "clip_names")),
        "a JSON list": lambda p: edit_json(p, lambda d: [d]),
        "not UTF-8": lambda p: p.write_bytes(p.read_bytes().replace(b"mimic-bank", b"mimic-\xe9")),
        "marked incomplete": lambda p: edit_json(p, lambda d: _set(d, "complete", False)),
    }

    def nan_features(p: Path) -> None:  # a frame's features NaN, the file well formed
        a = np.load(p, mmap_mode="r+", allow_pickle=False)
        a[0] = np.nan
        a.flush()
        del a

    def clip_start_moved(p: Path) -> None:
        with np.load(p, allow_pickle=False) as z:
            a = {k: z[k] for k in z.files}
        a["clip_start"][1] += 1
        with p.open("wb") as fh:
            np.savez(fh, **a)

    def index_edit(change: Callable[[dict[str, Any]], object]) -> Callable[[Path], None]:
        def edit(p: Path) -> None:  # arrays changed, the checksum kept
            with np.load(p, allow_pickle=False) as z:
                a = {k: z[k] for k in z.files}
            change(a)
            with p.open("wb") as fh:
                np.savez(fh, **a)

        return edit

    def nan_table(p: Path) -> None:  # a value NaN, the file well formed
        a = np.load(p, mmap_mode="r+", allow_pickle=False)
        a[1, 0, 0] = np.nan
        a.flush()
        del a

    index_edits: dict[str, Callable[[Path], object]] = {
        "mean shifted": index_edit(lambda a: _set(a, "mean", a["mean"] + 1.0)),
        "basis of zeros": index_edit(lambda a: _set(a, "basis", np.zeros_like(a["basis"]))),
        "no checksum": index_edit(lambda a: a.pop("checksum")),
    }

    found = [
        Artifact(
            "motion cache entry",
            one("motion", "[0-9a-f]*.npz"),
            load_parsed,
            _same_library,
            (MotionFormatError,),
            motion_edits,
        ),
        Artifact(
            "library cache entry",
            one("motion", "library-*.npz"),
            load_lib,
            _same_library,
            (MotionFormatError,),
            whole_edits,
        ),
        Artifact(
            "graph (cache)",
            one("graph", "graph-*.npz"),
            load_cached_graph,
            _same_graph,
            (GraphFileError,),
            graph_edits,
        ),
        Artifact(
            "graph file (load_graph)",
            one("graph", "graph-*.npz"),
            lambda r: load_graph(sorted((r / "graph").glob("graph-*.npz"))[0]),
            _same_graph,
            (GraphFileError,),
            graph_edits,
        ),
        Artifact(
            "higher layer (cache)",
            one("graph", "layer-*.npz"),
            load_layer,
            _same_layer,
            (LayerFileError,),
            layer_edits,
        ),
        Artifact(
            "bank manifest.json",
            lambda r: r / "bank" / "manifest.json",
            load_bank,
            _same_bank,
            (BankFileError,),
            bank_manifest_edits,
            named=lambda target: target.parent,
        ),
        Artifact(
            "bank.npz",
            lambda r: r / "bank" / "bank.npz",
            load_bank,
            _same_bank,
            (BankFileError,),
            {"a clip's start moved": clip_start_moved},
            named=lambda target: target.parent,
        ),
        Artifact(
            "bank features.npy",
            lambda r: r / "bank" / "features.npy",
            load_bank,
            _same_bank,
            (BankFileError,),
            {"features NaN": nan_features},
        ),
        Artifact(
            "motion arrays (.motion.npz)",
            lambda r: r / "arrays" / "02_01.motion.npz",
            lambda r: read_motion_arrays(r / "arrays" / "02_01.motion.npz"),
            lambda a, b: (
                np.array_equal(a.root_pos, b.root_pos)
                and np.array_equal(a.quats, b.quats)
                and a.fps == b.fps
                and a.skeleton.names == b.skeleton.names
            ),
            (MotionFormatError,),
            {k: v for k, v in motion_edits.items()},
        ),
        Artifact(
            "window index (beside the bank)",
            one("bank", "index-*.npz"),
            load_index,
            _same_index,
            (IndexFileError,),
            index_edits,
        ),
        Artifact(
            "window tables (beside the bank)",
            one("bank", "windows-*-shape.npy"),
            load_tables,
            lambda a, b: all(np.array_equal(x, y) for x, y in zip(a, b, strict=True)),
            (WindowTablesError,),
            {"a value NaN": nan_table},
        ),
        Artifact(
            "window tables manifest",
            one("bank", "windows-*.json"),
            load_tables,
            lambda a, b: all(np.array_equal(x, y) for x, y in zip(a, b, strict=True)),
            (WindowTablesError,),
            {"key changed": lambda p: edit_json(p, lambda d: _set(d, "key", "0" * 64))},
        ),
    ]
    pristine = {
        "motion cache entry": lib,
        "library cache entry": lib,
        "graph (cache)": graph,
        "graph file (load_graph)": graph,
        "higher layer (cache)": layer,
        "bank manifest.json": bank,
        "bank.npz": bank,
        "bank features.npy": bank,
        "motion arrays (.motion.npz)": arrays,
        "window index (beside the bank)": index,
        "window tables (beside the bank)": tables,
        "window tables manifest": tables,
    }
    return found, pristine


def _same_index(a: Any, b: Any) -> bool:
    return (
        a.size == b.size
        and a.nprobe == b.nprobe
        and np.array_equal(a.mean, b.mean)
        and np.array_equal(a.basis, b.basis)
        and np.array_equal(a.index.reconstruct_n(0, a.size), b.index.reconstruct_n(0, b.size))
    )


# --- running a case ------------------------------------------------------------------------


class _Warnings(logging.Handler):
    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.messages: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.messages.append(record.getMessage())


@contextmanager
def _warnings() -> Iterator[_Warnings]:
    handler = _Warnings()
    logging.getLogger().addHandler(handler)
    try:
        yield handler
    finally:
        logging.getLogger().removeHandler(handler)


@dataclass(frozen=True)
class Outcome:
    artifact: str
    case: str
    outcome: str  # same, rebuilt, error, wrong data, traceback
    detail: str = ""


def _settled() -> None:
    """Wait for the background checks of window tables just written (they record the
    tables as checked beside them, ``RACY_NS`` after the write): the pristine folder must
    not change while the cases copy it."""
    for thread in list(_tables.CHECKING):
        thread.join(timeout=60)


def run_case(
    artifact: Artifact,
    pristine_root: Path,
    pristine: Any,
    damage: Callable[[Path], str],
) -> Outcome:
    """Copy the pristine artifacts, damage the artifact's file, load, and classify."""
    # a case's own tables check may still write beside its copy when the copy goes
    with tempfile.TemporaryDirectory(prefix="mimic-fault-", ignore_cleanup_errors=True) as tmp:
        work = Path(tmp) / "w"
        shutil.copytree(pristine_root, work)
        target = artifact.target(work)
        case = damage(target)
        name = str(artifact.named(target))
        with _warnings() as said:
            try:
                result = artifact.load(work)
            except artifact.errors as exc:
                named = name in str(exc)
                return Outcome(
                    artifact.name, case, "error" if named else "traceback", f"{exc}"[:300]
                )
            except Exception as exc:  # exactly what must never happen
                return Outcome(
                    artifact.name, case, "traceback", f"{type(exc).__name__}: {exc}"[:300]
                )
        if not artifact.same(result, pristine):
            return Outcome(artifact.name, case, "wrong data")
        warned = [m for m in said.messages if name in m]
        if warned:
            return Outcome(artifact.name, case, "rebuilt", warned[0][:300])
        return Outcome(artifact.name, case, "same")


def _edit(path: Path, edit: Callable[[Path], object], name: str) -> str:
    edit(path)
    return name


def sweep(
    mocap: Path, flips: int, truncations: int, seed: int = 0, edits: bool = True
) -> list[Outcome]:
    """``flips`` byte flips and ``truncations`` truncations of each artifact, and each of
    its edits; seeded, so a sweep is repeatable."""
    rng = np.random.default_rng(seed)
    out: list[Outcome] = []
    with tempfile.TemporaryDirectory(prefix="mimic-pristine-") as tmp:
        root = Path(tmp)
        found, pristine = artifacts(mocap, root)
        _settled()
        for art in found:
            cases: list[Callable[[Path], str]] = []
            cases += [functools.partial(flip, rng=rng)] * flips
            cases += [functools.partial(truncate, rng=rng)] * truncations
            if edits:
                cases += [functools.partial(_edit, edit=e, name=n) for n, e in art.edits.items()]
            for damage in cases:
                out.append(run_case(art, root, pristine[art.name], damage))
    return out


def table(outcomes: list[Outcome]) -> dict[str, dict[str, int]]:
    """Cases per artifact and outcome."""
    rows: dict[str, dict[str, int]] = {}
    for o in outcomes:
        row = rows.setdefault(o.artifact, {"cases": 0})
        row["cases"] += 1
        row[o.outcome] = row.get(o.outcome, 0) + 1
    return rows
