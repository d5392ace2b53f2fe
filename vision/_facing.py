"""Which way the performer faces the camera, for silhouettes (which cannot tell).

A silhouette cannot tell a pose seen from the front from its mirror image seen from
behind, so the matcher reads the performer as seen and mirrored, and each reading finds
its window among all the ring's views: of a performer raising the left knee, the left
knee seen from the front (as seen) or from behind (mirrored), but just as well the right
knee seen from behind (as seen) or from the front (mirrored). Label agreement does not
care; the performer does, who sees the avatar raise the other knee. On
``bench_accuracy``'s silhouette runs its pose was nearer the performer's mirror image
than the performer's own at a fifth to a third of the decisions.

The two hypotheses are the performer facing the camera (the readings as seen in views
from the avatar's front, mirrored in views from its back) and facing away (the
others). ``Facing`` weighs windows against the one the evidence favours: a window that
only the other explains costs ``1 + penalty`` times as much. The evidence is how much
cheaper the best window each hypothesis explains is, on a log scale (at most ``STEP`` a
decision), summed over the decisions with a memory of about ``MEMORY_S`` seconds;
before any, the performer faces the camera, as in front of a webcam. Perspective makes
the true hypothesis the cheaper one at about two thirds of a take's windows
(``bench_accuracy``'s cameras from the front, above and behind: the sum settled on the
right side in every one). Neither hypothesis is weighed in views within ``MARGIN``
degrees of the avatar's side (seen from the side a pose and its mirror image look alike,
and the performer's heading wanders across the side: in a ``/tmp`` harness of
``bench_recognition``'s search, 3 takes x 11 recordings, weighing side views too made
those from the side worse; ``MARGIN`` 0, 15 and 30 gave the avatar's own-side pose error
0.456-0.49 against 0.568 unweighed, the label the same within 0.005), nor in windows
that show no side (``clip_sides``: a squat is its own mirror image, and weighing its
views only cost the shared real squat clip, filmed by another camera than the bank's,
4 of its 39 decisions, 0.641 -> 0.538 with silhouettes, the selfie model's masks; with sides
only, 0.641).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from scipy.ndimage import maximum_filter1d

from control.clusters import orientation_distance
from control.graph import weighted_joints
from control.motion import Clip, mirrored_rotations
from silhouette_bank import joint_points

log = logging.getLogger(__name__)

__all__ = ["MARGIN", "MEMORY_S", "SIDED", "STEP", "Facing", "clip_headings", "clip_sides"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]
Ranked = list[tuple[IntArray, IntArray, FloatArray]]

#: degrees either side of the avatar's side within which a view is neither front nor back
MARGIN = 15.0
#: seconds over which the evidence is remembered (a performer may turn round)
MEMORY_S = 30.0
#: the most one decision adds to the evidence (a cost ratio of about 1.05)
STEP = 0.05
#: a window shows a side when, at some frame, its pose is this far from its own mirror
#: image (the sum over the weighted joints of squared half-angles, as ``bench_accuracy``'s
#: pose error): the exercise takes' knee raises, toe touches and twists (median 0.3-2.3),
#: not their squats, jumping jacks and arm circles (90th percentile 0.14-0.35)
SIDED = 0.4


def clip_headings(clips: Sequence[Clip]) -> FloatArray:
    """The heading (radians about +Y from +Z) of every frame of ``clips``, one after
    another: the direction the hips face (perpendicular to the right-to-left hip line,
    horizontal). A ``ValueError`` names a skeleton without hips."""
    out = []
    for clip in clips:
        p = joint_points(clip.motion)
        left = p[:, 6] - p[:, 7]  # right hip to left hip
        # forward = left x up: (lx, ly, lz) x (0, 1, 0) = (-lz, 0, lx)
        out.append(np.arctan2(-left[:, 2], left[:, 0]))
    return np.concatenate(out) if out else np.zeros(0)


def clip_sides(clips: Sequence[Clip], length: int) -> NDArray[np.bool_]:
    """Whether the ``length`` frames around each frame of ``clips`` (one after another)
    show a side: a pose at least ``SIDED`` from its mirror image. A ``KeyError`` names a
    limb the skeleton lacks."""
    out = []
    for clip in clips:
        joints = weighted_joints(clip.motion.skeleton)
        other = mirrored_rotations(clip.motion, joints)
        d = np.sum(orientation_distance(other, clip.motion.quats[:, joints]) ** 2, axis=-1)
        out.append(maximum_filter1d(d, size=max(1, length), mode="nearest") >= SIDED)
    return np.concatenate(out) if out else np.zeros(0, dtype=bool)


class Facing:
    """The performer's facing, for a matcher that reads silhouettes both ways.

    ``zone[f, v]``: +1 where ring view ``v`` sees the avatar at frame ``f`` from the front
    (more than ``MARGIN`` degrees from its side), -1 from behind, 0 from the side or where
    the window around ``f`` shows no side (``sided``: a squat looks the same mirrored, so
    either facing explains it)."""

    def __init__(
        self,
        headings: FloatArray,
        azimuths: FloatArray,
        half: int,
        penalty: float,
        memory: float = 0.99,
        margin: float = MARGIN,
        sided: NDArray[np.bool_] | None = None,
    ) -> None:
        c = np.cos(np.asarray(azimuths)[None, :] - np.asarray(headings)[:, None])
        edge = math.sin(math.radians(margin))
        self.zone = np.where(c > edge, 1, np.where(c < -edge, -1, 0)).astype(np.int8)
        if sided is not None:
            self.zone[~np.asarray(sided, dtype=bool)] = 0
        self.ring_views = self.zone.shape[1]
        self.half = half  # a window is seen as at its middle frame
        self.penalty = penalty
        self.memory = memory
        #: the evidence so far: > 0 the performer faces the camera, < 0 away
        self.evidence = 0.0

    @property
    def toward(self) -> bool:
        """Whether the performer is taken to face the camera (the default)."""
        return self.evidence >= 0.0

    def _zones(self, frames: IntArray, views: IntArray) -> NDArray[np.int8]:
        last = self.zone.shape[0] - 1
        return self.zone[np.minimum(frames, last), np.asarray(views) % self.ring_views]

    @staticmethod
    def _unexplained(reading: int, zones: NDArray[np.int8], toward: bool) -> NDArray[np.bool_]:
        """Which windows of ``reading`` (even: as seen, odd: mirrored) the hypothesis
        ``toward`` does not explain."""
        front = 1 if toward else -1
        return zones == (-front if reading % 2 == 0 else front)

    def weigh(
        self,
        ranked: Ranked,
        observe: bool = True,
        recost: Callable[[int, int, int], float] | None = None,
    ) -> Ranked:
        """The short lists ``ranked`` (one per reading, in ``Descriptor.variants``'
        order: as seen, mirrored, ...) with the windows the favoured hypothesis does not
        explain costing ``1 + penalty`` times as much; with ``observe``, their costs then
        add to the evidence: each hypothesis's best window's, or ``recost(reading, start,
        view)`` of it (the matcher's: DTW with every frame alike, ``MatchSettings.recency``
        0, the evidence over the whole window)."""
        best = {True: math.inf, False: math.inf}
        at: dict[bool, tuple[int, int, int]] = {}
        toward, out = self.toward, []
        for r, (s, v, c) in enumerate(ranked):
            z = self._zones(s + self.half, v)
            masks = {hyp: self._unexplained(r, z, hyp) for hyp in (True, False)}
            for hyp, m in masks.items():
                if m.any():
                    k = int(np.flatnonzero(m)[np.argmin(c[m])])
                    if c[k] < best[hyp]:
                        best[hyp], at[hyp] = float(c[k]), (r, int(s[k]), int(v[k]))
            out.append((s, v, np.where(masks[toward], c * (1 + self.penalty), c)))
        if observe and recost is not None and len(at) == 2:
            best = {hyp: recost(*at[hyp]) for hyp in (True, False)}
        if observe and 0.0 < best[False] < math.inf and 0.0 < best[True] < math.inf:
            # facing the camera explains its windows better when those it does not
            # explain cost more; by at most ``STEP`` a decision (a run of windows of
            # another action, seen from where it turns, outweighed seconds of evidence)
            e = math.log(best[True] / best[False])
            self.evidence = self.memory * self.evidence + min(max(e, -STEP), STEP)
        return out

    def weigh_views(self, costs: FloatArray, frame: int) -> FloatArray:
        """Costs ``(readings, V)`` of one window whose middle is ``frame``, seen from
        each of the bank's views, weighed as ``weigh`` does (without observing)."""
        out = np.array(costs, dtype=np.float64, copy=True)
        views = np.arange(out.shape[1])
        z = self._zones(np.full(views.size, frame, dtype=np.int64), views)
        for r in range(out.shape[0]):
            out[r, self._unexplained(r, z, self.toward)] *= 1 + self.penalty
        return out

    @classmethod
    def of(cls, clips: Sequence[Clip], matcher: Any, period: float) -> Facing | None:
        """The facing for ``matcher`` (a ``Matcher`` of the graph made of ``clips``, one
        decision every ``period`` seconds): ``None`` unless it reads silhouettes as seen
        and mirrored with ``settings.facing`` on, or when the clips' skeleton has no
        hips (a warning says so). ``ValueError`` when the clips' frames are not the
        graph's (pass ``graph.clips_of(clips)``)."""
        st = matcher.settings
        both = st.mirror if st.mirror is not None else matcher.desc.reads_mirrored
        if matcher.desc.kind != "silhouette" or not both or st.facing <= 0:
            return None
        try:
            headings, sided = clip_headings(clips), clip_sides(clips, matcher.n)
        except (KeyError, ValueError) as exc:
            log.warning("the performer's facing is not weighed: %s", exc)
            return None
        if headings.size != matcher.graph.n_frames:
            raise ValueError(
                f"{headings.size} frames of clips against the graph's {matcher.graph.n_frames}"
            )
        ring = matcher.bank.settings.ring
        memory = math.exp(-period / MEMORY_S)
        return cls(headings, ring.azimuths(), matcher.n // 2, st.facing, memory, sided=sided)
