"""The four pruning rules of Lee et al. Table 1 as functions on frame pairs.

A transition from frame ``i`` to frame ``j`` is judged on the pair ``(a, b) = (i, j - 1)``:
the avatar leaves ``a`` and carries on from ``b + 1``. Pairs are arrays ``a, b``; the
playback edge ``a -> a + 1`` is the diagonal ``a == b``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import NDArray
from scipy.sparse import csr_matrix
from scipy.sparse.csgraph import connected_components

__all__ = [
    "CONTACT_RULES",
    "case4",
    "contact_groups",
    "largest_scc",
    "local_maxima",
]

CONTACT_RULES = ("loose", "strict", "none")
IntArray = NDArray[np.int64]
BoolArray = NDArray[np.bool_]


def _clip_ids(clip_start: IntArray) -> IntArray:
    n = int(clip_start[-1])
    return np.repeat(np.arange(clip_start.size - 1), np.diff(clip_start))[:n]


def contact_groups(
    states: BoolArray, clip_start: IntArray, rule: str
) -> list[tuple[IntArray, IntArray]]:
    """Frames grouped so that a pair passes the contact rule iff both lie in one group.

    Returns a list of ``(rows, cols)``: pairs ``(a, b)`` with ``a`` in ``rows`` and ``b`` in
    ``cols`` of the same group (and ``a != b``) are the pairs the rule allows.

    - ``loose``: contact states of ``a`` and ``b`` agree, and those of ``a + 1`` and
      ``b + 1`` agree. A clip's last frame has no ``a + 1``; it is compared as if its
      state held (so a transition can leave it).
    - ``strict``: as loose, and the contact state changes from ``a`` to ``a + 1`` (so the
      same change happens at ``b`` to ``b + 1``).
    - ``none``: every pair.

    ``b`` is never the last frame of its clip (``b + 1`` must exist).
    """
    if rule not in CONTACT_RULES:
        raise ValueError(f"contact rule must be one of {', '.join(CONTACT_RULES)}, not {rule!r}")
    n = int(clip_start[-1])
    last = np.zeros(n, dtype=bool)
    last[clip_start[1:] - 1] = True
    code_now = states[:, 0].astype(np.int64) + 2 * states[:, 1]
    code_next = np.where(last, code_now, np.roll(code_now, -1))
    code = code_now + 4 * code_next
    everything = np.arange(n, dtype=np.int64)
    if rule == "none":
        return [(everything, everything[~last])]
    changes = code_now != code_next
    groups = []
    for c in np.unique(code):
        in_c = code == c
        if rule == "strict":
            in_c &= changes
        rows = everything[in_c]
        cols = everything[in_c & ~last]
        if rows.size and cols.size:
            groups.append((rows, cols))
    return groups


def local_maxima(
    a: IntArray, b: IntArray, d: NDArray[np.float64], clip_start: IntArray
) -> BoolArray:
    """Keep a pair only where its likelihood is a local maximum of the transition matrix.

    A pair survives when no present pair among its 8 neighbours ``(a +- 1, b +- 1)`` (in
    the same clips as ``a`` and ``b``) has a smaller distance. Absent pairs have
    probability 0 and do not count; the diagonal (playback, distance 0) is always present.
    """
    n = int(clip_start[-1])
    if a.size == 0:
        return np.zeros(0, dtype=bool)
    clip = _clip_ids(clip_start)
    keys = a * n + b
    order = np.argsort(keys)
    keys = keys[order]
    d_sorted = d[order]
    del order
    keep = np.ones(a.size, dtype=bool)
    # the neighbours are looked up a chunk of pairs at a time: a dozen temporaries the
    # size of the chunk, not of every pair (gigabytes at 500,000 frames)
    for c0 in range(0, a.size, _CHUNK):
        ca, cb, cd = a[c0 : c0 + _CHUNK], b[c0 : c0 + _CHUNK], d[c0 : c0 + _CHUNK]
        ck = keep[c0 : c0 + _CHUNK]  # (a view: written through)
        for da in (-1, 0, 1):
            for db in (-1, 0, 1):
                if da == 0 and db == 0:
                    continue
                na, nb = ca + da, cb + db
                ok = (na >= 0) & (na < n) & (nb >= 0) & (nb < n)
                na_c, nb_c = np.clip(na, 0, n - 1), np.clip(nb, 0, n - 1)
                ok &= (clip[na_c] == clip[ca]) & (clip[nb_c] == clip[cb])
                diagonal = ok & (na == nb)
                ck &= ~(diagonal & (cd > 0.0))
                key = na_c * n + nb_c
                pos = np.minimum(np.searchsorted(keys, key), keys.size - 1)
                found = ok & ~diagonal & (keys[pos] == key)
                ck &= ~(found & (d_sorted[pos] < cd))
    return keep


#: pairs whose neighbours ``local_maxima`` looks up at a time
_CHUNK = 1 << 22


def largest_scc(
    n: int, src: IntArray, dst: IntArray, clip_start: IntArray
) -> tuple[BoolArray, int]:
    """Frames of the largest strongly connected component of the frame graph.

    The graph has an edge for every transition ``src -> dst`` and for playback
    ``f -> f + 1`` inside each clip. Uses scipy's Tarjan-style strong components.

    Returns
    -------
    in_scc : (n,) bool.
    n_components : the number of strongly connected components.
    """
    last = np.zeros(n, dtype=bool)
    last[clip_start[1:] - 1] = True
    play = np.flatnonzero(~last)
    s = np.concatenate((play, src))
    t = np.concatenate((play + 1, dst))
    graph = csr_matrix((np.ones(s.size, dtype=np.int8), (s, t)), shape=(n, n))
    n_comp, labels = connected_components(graph, directed=True, connection="strong")
    sizes = np.bincount(labels, minlength=n_comp)
    return labels == int(np.argmax(sizes)), int(n_comp)


def _run_ends(col: BoolArray, clip_start: IntArray) -> IntArray:
    """(n,) last frame of the contact run holding each frame (runs stop at clip ends);
    -1 where the foot is not in contact."""
    n = col.size
    last = np.zeros(n, dtype=bool)
    last[clip_start[1:] - 1] = True
    first = np.zeros(n, dtype=bool)
    first[clip_start[:-1]] = True
    prev = np.concatenate(([False], col[:-1]))
    nxt = np.concatenate((col[1:], [False]))
    starts = col & (~prev | first)
    ends = np.flatnonzero(col & (~nxt | last))
    run = np.cumsum(starts) - 1
    return np.where(col, ends[np.maximum(run, 0)] if ends.size else -1, -1)


def case4(
    states: BoolArray, clip_start: IntArray, src: IntArray, dst: IntArray, b: int
) -> BoolArray:
    """Transitions in Lee et al.'s case 4: a foot's contact spans a whole blend interval.

    For ``i -> j`` with blend length ``b`` frames: some foot is in contact at ``i`` and
    stays so at least until ``i + b`` in the source clip, or is in contact at ``j`` and
    stays so until ``j + b - 1``. Such a blend cannot keep the foot planted at both ends
    (the paper lets it slip or drops the transition).
    """
    out = np.zeros(src.size, dtype=bool)
    for foot in range(states.shape[1]):
        col = states[:, foot]
        end = _run_ends(col, clip_start)
        out |= (col[src] & (end[src] >= src + b)) | (col[dst] & (end[dst] >= dst + b - 1))
    return out
