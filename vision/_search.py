"""The window search, one of ``Matcher``'s collaborators: the library's windows as the
bank sees them, and the searches that compare the performer's last features with them.

Features compared per frame, by the bank's descriptor (``silhouette_bank.Descriptor``):
its shape numbers (Hu moments, grid cells, or landmarks) mapped by ``shape_stats`` (the
bank's learned metric, or the descriptor's standardisation), and the centre's
displacement since the window's first frame, in units of body size (performer: from the
image; bank: the root's image motion accumulated plus the centre relative to the root),
times ``centre_weight``. A silhouette is read as seen and mirrored, landmarks as seen only
(they name the performer's sides; ``Descriptor.variants``); costs in each view are
weighed by which way the performer faces (``facing``, ``vision._facing``).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from control.dtw import ShapeTable, dtw_windows
from control.graph import MotionGraph
from silhouette_bank import Bank

from ._facing import Facing
from ._index import WindowIndex
from ._index_store import cached_window_index
from ._settings import MatchSettings
from ._tables import cached_shape_stats, cached_window_tables
from ._windows import bank_sequences, best_window, performer_queries

__all__ = ["EARLY_WINDOWS", "WindowSearch"]

#: a maker of progress callbacks by label and unit (``control.progress.bar``)
Bars = Callable[[str, str], Callable[[int, int], None]]

#: the most windows times views a half window is searched over by brute force to place
#: the avatar before its first whole window (``WindowSearch.early``: 25 ms for the
#: 54,000 of the default library on the development machine, about 70 ms at the limit)
EARLY_WINDOWS = 150_000

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
Windows = list[tuple[int, int, float]]


class WindowSearch:
    """The windows of ``n`` frames of ``graph``'s clips in every view of ``bank``, with
    ``settings``; ``plays``: whether each graph frame plays on into the next (a window
    never spans a break). With ``anywhere`` (jumps) a window may start at any frame,
    else only inside the graph's component.

    Attributes
    ----------
    to_bank : ndarray
        The bank frame of each graph frame.
    mean, proj : ndarray
        The shape numbers' map (``shape_stats``).
    desc : Descriptor
        What one performer frame is reduced to: the bank's descriptor.
    ring_views : int
        Views of the bank's camera ring (its variants repeat them).
    runs : ndarray
        The run of playback each graph frame belongs to.
    facing : Facing or None
        The performer's facing (silhouettes read both ways), weighing each view's costs.
    """

    def __init__(
        self,
        graph: MotionGraph,
        bank: Bank,
        settings: MatchSettings,
        n: int,
        plays: NDArray[np.bool_],
        anywhere: bool,
    ) -> None:
        self.graph, self.bank, self.settings, self.n = graph, bank, settings, n
        self.plays, self.anywhere = plays, anywhere
        index = {name: i for i, name in enumerate(bank.clip_names)}
        missing = [c for c in graph.clip_names if c not in index]
        if missing:
            raise ValueError(f"the bank lacks clips of the graph: {', '.join(missing)}")
        self.to_bank = np.concatenate(
            [
                np.arange(bank.clip_start[index[c]], bank.clip_start[index[c] + 1])
                for c in graph.clip_names
            ]
        )
        if self.to_bank.size != graph.n_frames:
            raise ValueError("the bank and the graph disagree on clip lengths (rebuild the bank)")
        self.mean, self.proj = cached_shape_stats(bank)
        self.desc = bank.settings.features
        self.ring_views = bank.settings.ring.n_views
        self.runs = np.cumsum(np.concatenate(([0], ~plays[:-1])))
        self.facing: Facing | None = None
        self._tables: tuple[ShapeTable, FloatArray, IntArray] | None = None
        self._key = ""
        self._index: WindowIndex | None = None

    def tables(
        self, progress: Callable[[int, int], None] | None = None
    ) -> tuple[ShapeTable, FloatArray, IntArray]:
        """Every graph frame's standardised shape numbers and accumulated centre (times
        the centre weight) in every view, and the frames a window may start at (with
        ``n`` frames of playback ahead). ``progress(done, total)`` counts the frames of
        tables made (none when they are read)."""
        if self._tables is None:
            shape, centre, self._key = cached_window_tables(
                self.bank,
                self.to_bank,
                self.graph.clip_start,
                self.mean,
                self.proj,
                self.settings.centre_weight,
                progress,
            )
            n = self.graph.n_frames
            ok = np.ones(n, dtype=bool) if self.anywhere else self.graph.in_scc.copy()
            end = np.arange(n) + self.n - 1
            ok &= end < n
            ok[ok] &= self.runs[end[ok]] == self.runs[np.flatnonzero(ok)]
            self._tables = (shape, centre, np.flatnonzero(ok).astype(np.int64))
        return self._tables

    @property
    def key(self) -> str:
        """The tables' key: what the index and the classifier stored beside them name."""
        self.tables()
        return self._key

    @property
    def early(self) -> bool:
        """Whether half a window may place the avatar before the first whole one (by
        brute force): where the library's windows times views are at most
        ``EARLY_WINDOWS``, a search of well under 0.1 s."""
        shape, _, starts = self.tables()
        return starts.size * shape.shape[1] <= EARLY_WINDOWS

    def index(self, progress: Callable[[int, int], None] | None = None) -> WindowIndex:
        """The fast whole-library window search (made on first use; stored in the bank's
        folder, and loaded from there when the tables are the same). ``progress(done,
        total)`` counts the windows as one is made (``WindowIndex``)."""
        if self._index is None:
            shape, centre, starts = self.tables()
            folder = self.bank.path or None
            self._index = cached_window_index(
                shape, centre, starts, self.n, folder, key=self.key, progress=progress
            )
        return self._index

    def open(self, bars: Bars | None = None, label: str = "search") -> WindowIndex:
        """The tables and the index, now (a camera would stall at its first decision),
        each with a progress bar ``bars(label, unit)`` (``control.progress.bar``) while
        it is made."""
        self.tables(bars(f"{label}: window tables", "frames") if bars else None)
        return self.index(bars(f"{label}: window index", "windows") if bars else None)

    def queries(self, performer: FloatArray) -> list[FloatArray] | None:
        """The DTW queries ``(m, F)`` of the performer's last features ``(n, F)``: NaN rows
        (frames without a silhouette or pose) dropped, one query per reading
        (``Descriptor.variants``: as seen, mirrored, ...). ``None`` when fewer than half
        the window's frames are usable."""
        if performer.ndim != 2 or performer.shape[1] != self.desc.size:
            raise ValueError(
                f"performer features must be (n, {self.desc.size}) for the bank's "
                f"{self.desc.name!r} descriptor, got {performer.shape}: compute them with "
                f"silhouette_features(mask, descriptor={self.desc.name!r})"
            )
        now = performer[-self.n :]
        ok = np.isfinite(now).all(axis=1)
        if ok.sum() < max(2, self.n // 2):
            return None
        st = self.settings
        return performer_queries(
            now[ok], self.desc, self.mean, self.proj, st.centre_weight, st.mirror
        )

    def best(
        self,
        queries: list[FloatArray],
        top: int,
        span: int,
        exact: bool,
        actions: IntArray | None = None,
    ) -> Windows:
        """The ``top`` windows ``(start, view, cost)`` nearest ``queries`` (of a
        performer's last ``span`` frames), cheapest first, by the index; with ``exact``,
        or for fewer than ``n`` frames (a window not yet whole, matched against windows
        of its own length: the index holds whole windows), the best one by brute force,
        and with ``actions`` (each graph frame's action) only among ``settled`` windows."""
        st = self.settings
        if exact or span < self.n:
            shape, centre, starts = self.tables()
            if span < self.n and actions is not None:
                starts = self.settled(starts, span, actions)
            return [best_window(queries, shape, centre, starts, span, st.band, st.recency)]
        return self.index().search(queries, st.band, top, recency=st.recency)

    def settled(self, starts: IntArray, span: int, actions: IntArray) -> IntArray:
        """Those of ``starts`` whose window of ``span`` frames ends where the library
        plays on in the same action until a whole window's ``n`` frames are in (all of
        them where none does). A window not yet whole places the avatar at its end, and
        the avatar plays on from there until the first decision: placed at an action's
        last frames, it played on into the next action, and the first decision took it
        back, a brief action the performer never did. (Each of ``starts`` plays on for a
        whole window in its run: ``tables``.)"""
        ok = actions[starts + self.n - 1] == actions[starts + span - 1]
        return starts[ok] if ok.any() else starts

    def ranked(
        self,
        queries: list[FloatArray],
        ranked: list[tuple[IntArray, IntArray, FloatArray]],
        only: NDArray[np.bool_] | None = None,
    ) -> Windows:
        """The index's ``top_windows`` best windows for ``queries`` (among ``only``),
        their short lists added to ``ranked``."""
        st = self.settings
        return self.index().search(
            queries, st.band, st.landing.top_windows, only, ranked, st.recency
        )

    def plain_cost(self, queries: list[FloatArray]) -> Callable[[int, int, int], float] | None:
        """The cost of the window at ``(start, view)`` of the index against
        ``queries[reading]`` by DTW with every frame alike, for the facing's evidence
        (``None`` when the search already weighs them so: ``recency`` 0)."""
        if self.settings.recency == 0:
            return None
        idx, band = self.index(), self.settings.band

        def cost(reading: int, start: int, view: int) -> float:
            s, v = np.array([start], dtype=np.int64), np.array([view], dtype=np.int64)
            q = queries[reading]
            return float(dtw_windows(q, idx.shape, idx.centre, s, v, idx.length, band)[0])

        return cost

    def sequences(self, frames: IntArray) -> FloatArray:
        """DTW features ``(V, n, F)`` of graph ``frames`` in every view."""
        w = self.settings.centre_weight
        return bank_sequences(self.bank, self.to_bank[frames], self.mean, self.proj, w)

    def weighed(self, costs: FloatArray, middle: int) -> FloatArray:
        """Costs ``(readings, V)`` of one window (its middle frame ``middle``) in each
        view, weighed by the performer's ``facing`` when there is one."""
        return costs if self.facing is None else self.facing.weigh_views(costs, middle)

    def playback(self, frame: int) -> IntArray:
        """``frame`` and up to a window of frames playing on from it."""
        out = [frame]
        while len(out) <= self.n and self.plays[out[-1]]:
            out.append(out[-1] + 1)
        return np.array(out, dtype=np.int64)

    def same_run(self, frame: int, target: IntArray) -> NDArray[np.bool_]:
        """Whether ``frame`` plays on to each of ``target`` (or back from it)."""
        return self.runs[np.clip(target, 0, self.graph.n_frames - 1)] == self.runs[frame]
