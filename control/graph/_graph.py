"""Building the lower layer (Lee et al. §4.1): distances, eq. 1 likelihoods, Table 1 pruning.

``sigma`` of eq. 1 is set from the data: the median distance between frames ``sigma_dt``
seconds apart (1/15 s by default) in the same clip, i.e. the typical change of pose in one
frame of the paper's 15 frames/s, times ``sigma_scale``. A transition ``i -> j`` has the
likelihood ``exp(-D(i, j-1) / sigma)`` relative to playing on (``i -> i+1``, distance 0,
likelihood 1); the likelihood rule drops transitions below ``threshold``, i.e. with
``D > sigma * ln(1 / threshold)``.
"""

from __future__ import annotations

import hashlib
import json
import logging
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import asdict, dataclass, field
from functools import cached_property
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray

from ..motion import Clip, clips_digest
from ._distance import pair_distances
from ._features import COORDS, FrameFeatures, frame_features
from ._pairs import likely_pairs
from ._prune import CONTACT_RULES, case4, largest_scc, local_maxima

__all__ = [
    "GRAPH_VERSION",
    "GraphOptions",
    "MotionGraph",
    "build_graph",
    "clips_digest",
    "select_clips",
]

log = logging.getLogger(__name__)

#: Bump when the build's output changes for the same inputs and options.
GRAPH_VERSION = 2  # 2: a checksum in the manifest
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class GraphOptions:
    """Settings of a graph build.

    Attributes
    ----------
    coords : ``"fixed"`` (default; the playground), ``"relative"`` or ``"terrain"``.
    contact : ``"loose"`` (default), ``"strict"`` (only at the same contact change) or
        ``"none"``.
    similarity : keep only local maxima; ``None`` means on unless ``contact == "strict"``
        (the paper: not needed with the strict rule).
    nu : weight of the velocity term of eq. 2, in s^2 (velocities are rad/s and m/s).
    sigma_dt : seconds between the frames whose median distance sets sigma.
    sigma_scale : multiplies that median.
    threshold : likelihood threshold (relative to playback, in (0, 1)).
    block : terrain block size in metres.
    origin_x, origin_z : terrain: a block centre on the ground in library coordinates
        (``captured_terrain`` estimates it from the foot contacts); quarter turns are
        about it.
    rise : terrain: block height in metres; transitions' vertical offsets are rounded to
        whole blocks. 0 (default) keeps them continuous.
    case4 : ``"slip"`` (default: keep transitions whose blend a foot's contact spans; the
        foot is held, then slides) or ``"prune"`` (drop them before the SCC step, as the
        paper allows).
    blend : the blend interval (seconds) that ``case4="prune"`` assumes.
    """

    coords: str = "fixed"
    contact: str = "loose"
    similarity: bool | None = None
    nu: float = 0.01
    sigma_dt: float = 1.0 / 15.0
    sigma_scale: float = 1.0
    threshold: float = 0.1
    block: float = 0.5
    origin_x: float = 0.0
    origin_z: float = 0.0
    rise: float = 0.0
    case4: str = "slip"
    blend: float = 1.0

    def __post_init__(self) -> None:
        if self.case4 not in ("slip", "prune"):
            raise ValueError(f"case4 must be 'slip' or 'prune', not {self.case4!r}")
        if self.coords not in COORDS:
            raise ValueError(f"coords must be one of {', '.join(COORDS)}, not {self.coords!r}")
        if self.contact not in CONTACT_RULES:
            raise ValueError(f"contact must be one of {', '.join(CONTACT_RULES)}")
        if not 0.0 < self.threshold < 1.0:
            raise ValueError("threshold must lie in (0, 1)")
        for name in ("nu", "sigma_dt", "sigma_scale", "block", "blend"):
            value = getattr(self, name)
            if not (math.isfinite(value) and (value > 0 or (name == "nu" and value == 0))):
                raise ValueError(f"{name} must be a positive number, not {value!r}")
        for name in ("origin_x", "origin_z", "rise"):
            value = getattr(self, name)
            if not math.isfinite(value) or (name == "rise" and value < 0):
                raise ValueError(f"{name} must be a finite number (rise >= 0), not {value!r}")

    @property
    def use_similarity(self) -> bool:
        return self.contact != "strict" if self.similarity is None else self.similarity

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    def terrain_args(self) -> dict[str, Any]:
        """``pair_distances``' terrain keywords: block, origin and rise."""
        return {"block": self.block, "origin": (self.origin_x, self.origin_z), "rise": self.rise}


@dataclass(frozen=True, eq=False)
class MotionGraph:
    """The pruned lower layer: transitions between the frames of ``clip_names``.

    Frames are numbered end to end over the clips (``clip_start``). Transition ``e`` goes
    from frame ``src[e]`` to frame ``dst[e]`` (so ``dst[e] - 1`` resembles ``src[e]``), with
    distance ``dist[e]`` and the alignment ``align[e] = (yaw, dx, dy, dz)`` that places the
    target's motion onto the source's (identity for fixed coordinates). Only frames with
    ``in_scc`` may be visited; every such frame has an exit inside the component.
    Transitions are sorted by ``src``; ``indptr`` indexes them (CSR).
    """

    options: GraphOptions
    clip_names: tuple[str, ...]
    clip_start: IntArray
    fps: float
    sigma: float
    src: IntArray
    dst: IntArray
    dist: NDArray[np.float32]
    align: NDArray[np.float32]
    in_scc: NDArray[np.bool_]
    library_digest: str
    report: dict[str, Any] = field(default_factory=dict)

    @property
    def n_frames(self) -> int:
        return int(self.clip_start[-1])

    @property
    def n_edges(self) -> int:
        return int(self.src.size)

    @cached_property
    def indptr(self) -> IntArray:
        """(n + 1,) CSR row pointers of the transitions (computed once)."""
        return np.searchsorted(self.src, np.arange(self.n_frames + 1)).astype(np.int64)

    def locate(self, frame: int) -> tuple[str, int]:
        """``(clip name, frame in clip)`` of a graph frame."""
        c = int(np.searchsorted(self.clip_start, frame, side="right")) - 1
        if not 0 <= frame < self.n_frames:
            raise IndexError(f"frame {frame} out of range 0..{self.n_frames - 1}")
        return self.clip_names[c], int(frame - self.clip_start[c])

    def frame_of(self, clip: str, frame: int) -> int:
        """Graph frame of ``frame`` of ``clip``."""
        if clip not in self.clip_names:
            raise ValueError(f"the graph has no clip {clip!r}")
        c = self.clip_names.index(clip)
        size = int(self.clip_start[c + 1] - self.clip_start[c])
        if not 0 <= frame < size:
            raise ValueError(f"clip {clip} has no frame {frame} (it has {size} frames)")
        return int(self.clip_start[c] + frame)

    def likelihood(self) -> NDArray[np.float64]:
        """``exp(-dist / sigma)`` per transition (eq. 1, unnormalised; playback is 1)."""
        return np.exp(-self.dist.astype(np.float64) / self.sigma)

    def plays_on(self) -> NDArray[np.bool_]:
        """(n,) True where ``f -> f + 1`` is allowed (same clip, both in the component)."""
        ok = np.zeros(self.n_frames, dtype=bool)
        ok[:-1] = self.in_scc[:-1] & self.in_scc[1:]
        ok[self.clip_start[1:] - 1] = False
        return ok

    def playback_runs(self) -> IntArray:
        """(n,) a number per frame, the same for frames that play on into one another:
        ``f`` plays on to ``g > f`` without a transition when their numbers are equal."""
        return np.cumsum(np.concatenate(([0], ~self.plays_on()[:-1])))

    def route(
        self,
        frame: int,
        target: int,
        max_steps: int,
        plays: NDArray[np.bool_] | None = None,
    ) -> tuple[IntArray, IntArray] | None:
        """The shortest way ``(frames, edges)`` from ``frame`` to ``target`` through the
        component (playing on where ``plays``, default ``plays_on()``, and transitions;
        one frame per step, breadth first), at most ``max_steps`` steps, or ``None``.
        ``edges[i]`` leads into ``frames[i + 1]`` (-1: playing on)."""
        plays = self.plays_on() if plays is None else plays
        prev: dict[int, tuple[int, int]] = {frame: (-1, -1)}
        layer = [frame]
        depth = 0
        indptr = self.indptr
        while target not in prev and layer and depth < max_steps:
            depth += 1
            nxt = []
            for u in layer:
                steps = [(u + 1, -1)] if plays[u] else []
                steps += [(int(self.dst[e]), e) for e in range(indptr[u], indptr[u + 1])]
                for v, e in steps:
                    if v not in prev and self.in_scc[v]:
                        prev[v] = (u, e)
                        nxt.append(v)
            layer = nxt
        if target not in prev:
            return None
        frames, edges = [target], []
        while prev[frames[-1]][0] >= 0:
            u, e = prev[frames[-1]]
            edges.append(e)
            frames.append(u)
        return np.array(frames[::-1], dtype=np.int64), np.array(edges[::-1], dtype=np.int64)

    def clips_of(self, clips: Sequence[Clip]) -> list[Clip]:
        """The graph's clips, in its order, from a library's ``clips`` (``KeyError``
        naming those the library lacks)."""
        by_name = {c.name: c for c in clips}
        missing = [n for n in self.clip_names if n not in by_name]
        if missing:
            raise KeyError(f"the graph needs clips the library lacks: {', '.join(missing)}")
        return [by_name[n] for n in self.clip_names]


def select_clips(clips: Sequence[Clip]) -> tuple[list[Clip], list[str]]:
    """The clips the graph can join: the largest group (by frames) sharing joint names.

    Joint angles are only comparable between skeletons with the same joints; the rest
    are returned by name so that the caller can say they were left out.
    """
    groups: dict[tuple[str, ...], list[Clip]] = {}
    for c in clips:
        groups.setdefault(c.motion.skeleton.names, []).append(c)
    best = max(groups.values(), key=lambda g: sum(c.motion.n_frames for c in g))
    excluded = [c.name for c in clips if c not in best]
    return best, excluded


def graph_sigma(feat: FrameFeatures, fps: float, options: GraphOptions) -> float:
    """The distance scale sigma of eq. 1: ``options.sigma_scale`` times the median
    distance between frames ``options.sigma_dt`` apart within a clip."""
    step = max(1, round(options.sigma_dt * fps))
    f = np.arange(feat.n - step)
    clip = np.searchsorted(feat.clip_start, np.arange(feat.n), side="right")
    f = f[clip[f] == clip[f + step]]
    if f.size == 0:
        raise ValueError("clips too short to measure sigma (need more than one frame)")
    d, _ = pair_distances(feat, f, f + step, options.nu, **options.terrain_args())
    sigma = float(np.median(d)) * options.sigma_scale
    if not sigma > 0:
        raise ValueError("all frames identical: cannot set sigma")
    return sigma


def _prune_rules(
    feat: FrameFeatures,
    options: GraphOptions,
    fps: float,
    a: IntArray,
    b: IntArray,
    d: NDArray[np.float64],
    align: NDArray[np.float32],
) -> tuple[tuple[Any, Any, Any, Any], int | None, int | None]:
    """The similarity rule (local maxima) and case 4 when the options ask for them: the
    transitions left, and how many after each (``None`` for a rule not applied)."""
    n_similar: int | None = None
    if options.use_similarity:
        keep = local_maxima(a, b, d, feat.clip_start)
        a, b, d, align = a[keep], b[keep], d[keep], align[keep]
        n_similar = int(a.size)
    n_case4: int | None = None
    if options.case4 == "prune":
        drop = case4(feat.states, feat.clip_start, a, b + 1, max(1, round(options.blend * fps)))
        a, b, d, align = a[~drop], b[~drop], d[~drop], align[~drop]
        n_case4 = int(a.size)
    return (a, b, d, align), n_similar, n_case4


def _one_rate(clips: Sequence[Clip]) -> float:
    rates = {c.motion.fps for c in clips}
    if len(rates) != 1:
        raise ValueError(f"clips must share one frame rate, got {sorted(rates)}")
    return rates.pop()


def _chosen(clips: Sequence[Clip]) -> tuple[list[Clip], list[str], float]:
    """The clips a graph is built of (those with the first clip's joints; the names of
    the others, left out with a warning) and their one frame rate."""
    chosen, excluded = select_clips(list(clips))
    fps = _one_rate(chosen)
    if excluded:
        log.warning("left out %d clips with other joints: %s", len(excluded), ", ".join(excluded))
    return chosen, excluded, fps


def _in_largest_component(
    feat: FrameFeatures, a: IntArray, b: IntArray, d: NDArray[np.float64], align: NDArray[Any]
) -> tuple[tuple[Any, Any, Any, Any], NDArray[np.bool_], int]:
    """The transitions ``a`` to ``b + 1`` (distance ``d``, alignment ``align``) within
    the largest strongly connected component, ordered by source then target; which
    frames the component holds; how many components there are."""
    in_scc, n_comp = largest_scc(feat.n, a, b + 1, feat.clip_start)
    keep = in_scc[a] & in_scc[b + 1]
    a, b, d, align = a[keep], b[keep], d[keep], align[keep]
    order = np.lexsort((b, a))
    return (a[order], b[order], d[order], align[order]), in_scc, n_comp


def _transitions(
    feat: FrameFeatures,
    options: GraphOptions,
    fps: float,
    dmax: float,
    cluster: str | None,
    work: Path | None,
    jobs: Callable[[int, int], None] | None,
    progress: Callable[[str], None] | None,
) -> tuple[tuple[Any, Any, Any, Any], NDArray[np.bool_], dict[str, Any], list[float]]:
    """The transitions ``(a, b, d, align)`` of ``build_graph``: the likely pairs
    (``likely_pairs``), pruned as the options ask, within the largest strongly connected
    component; which frames the component holds; the counts left after each step; and
    when the search, the pruning and the component were done."""
    (a, b, d, align), counts = likely_pairs(feat, options, dmax, cluster, work, jobs)
    n_likely = a.size
    t_search = time.perf_counter()  # (the search's jobs, and a resumed build's parts read)
    if progress:
        progress(f"{n_likely} transitions under the likelihood threshold")
    (a, b, d, align), n_similar, n_case4 = _prune_rules(feat, options, fps, a, b, d, align)
    t_prune = time.perf_counter()
    (a, b, d, align), in_scc, n_comp = _in_largest_component(feat, a, b, d, align)
    counted = {
        **{k: counts[k] for k in ("contact", "candidates", "jobs")},
        "resumed_jobs": counts["resumed"],
        "likelihood": int(n_likely),
        "similarity": n_similar,
        "case4": n_case4,
        "scc": int(a.size),
        "scc_frames": int(in_scc.sum()),
        "components": n_comp,
    }
    return (a, b, d, align), in_scc, counted, [t_search, t_prune, time.perf_counter()]


def build_graph(
    clips: Sequence[Clip],
    options: GraphOptions | None = None,
    progress: Callable[[str], None] | None = None,
    cluster: str | None = None,
    work: str | Path | None = None,
    jobs: Callable[[int, int], None] | None = None,
) -> MotionGraph:
    """Build the pruned motion graph of ``clips`` (one frame rate).

    The search for likely pairs (the lower bound and the exact distances, most of the
    time) runs in jobs of blocks of rows (``likely_pairs``), on a Dask cluster when
    ``cluster`` (or ``$MIMIC_CLUSTER``, ``control.jobs``) names one; the graph is the
    local build's, array for array. With ``work`` (a folder) each finished job is kept
    there, so that a build stopped midway resumes where it was; ``jobs(done, total)``
    counts them (a progress bar).

    The report (``graph.report``) has the Table 1 counts: ``frames``, ``possible``
    (frames squared), then transitions left after ``contact``, ``likelihood``,
    ``similarity`` (``None`` when the rule is off), ``case4`` (``None`` unless
    ``options.case4 == "prune"``) and ``scc``, with timings.
    """
    options = options or GraphOptions()
    t0 = time.perf_counter()
    chosen, excluded, fps = _chosen(clips)
    feat = frame_features(chosen, options.coords)
    n = feat.n
    sigma = graph_sigma(feat, fps, options)
    dmax = sigma * math.log(1.0 / options.threshold)
    t_feat = time.perf_counter()

    where = Path(work) if work is not None else None
    (a, b, d, align), in_scc, counted, marks = _transitions(
        feat, options, fps, dmax, cluster, where, jobs, progress
    )
    report: dict[str, Any] = {
        "clips": len(chosen),
        "excluded_clips": excluded,
        "fps": fps,
        "frames": n,
        "possible": n * n,
        **counted,
        "sigma": sigma,
        "max_distance": dmax,
        "seconds": _seconds(t0, t_feat, *marks),
    }
    return MotionGraph(
        options=options,
        clip_names=tuple(c.name for c in chosen),
        clip_start=feat.clip_start,
        fps=float(fps),
        sigma=sigma,
        src=a,
        dst=b + 1,
        dist=d.astype(np.float32),
        align=align.astype(np.float32),
        in_scc=in_scc,
        library_digest=clips_digest(chosen),
        report=report,
    )


def _seconds(*marks: float) -> dict[str, float]:
    """The seconds of each part of a build between its ``marks`` (the start, then the
    ends of the features, the search, the pruning and the component), and the total."""
    parts = ("features", "search", "prune", "scc")
    out = {k: round(b - a, 3) for k, a, b in zip(parts, marks[:-1], marks[1:], strict=True)}
    out["total"] = round(marks[-1] - marks[0], 3)
    return out


def options_key(options: GraphOptions, digest: str) -> str:
    """Content hash naming a graph artifact: the version, the clips' digest, the options."""
    text = json.dumps(
        {"version": GRAPH_VERSION, "library": digest, "options": options.to_dict()},
        sort_keys=True,
    )
    return hashlib.sha256(text.encode()).hexdigest()[:24]
