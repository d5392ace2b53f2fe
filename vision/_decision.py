"""What the matcher is told (``MatchSettings``), what the performance loop is told
(``PerformSettings``), and what the matcher answers (``Decision``)."""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

__all__ = ["Decision", "Jump", "MatchSettings", "PerformSettings"]

FloatArray = NDArray[np.float64]
IntArray = NDArray[np.int64]


@dataclass(frozen=True)
class MatchSettings:
    """``window`` seconds of performer compared; candidates reached within ``lookahead``
    seconds; DTW band ``band`` frames; ``centre_weight`` against the shape numbers."""

    window: float = 1.0
    lookahead: float = 1.5
    band: int = 4
    centre_weight: float = 3.0
    max_candidates: int = 64
    locate: bool = True  # start the avatar where the library looks most like the performer
    #: every ``relocate`` seconds (0: never) the whole component is searched too; when its
    #: best window costs less than ``relocate_ratio`` times the best candidate's, the
    #: avatar takes the shortest way there through the graph (at most ``route`` seconds)
    relocate: float = 1.0
    relocate_ratio: float = 0.8
    route: float = 4.0
    #: the temporal prior: a path that plays on in the avatar's clip, without a
    #: transition in its first ``window`` seconds, has its cost multiplied by ``1 - stay``
    #: (0: no prior), so the avatar keeps its action unless another fits clearly better
    stay: float = 0.0
    #: also match the performer mirrored (left and right exchanged), and for landmarks
    #: with left and right labels swapped: the best reading wins. ``None``: the
    #: descriptor's own default (``Descriptor.reads_mirrored``: silhouettes yes, which
    #: cannot tell a pose from its mirror image seen from behind; landmarks no, which
    #: name the performer's sides)
    mirror: bool | None = None
    #: per-frame cost above which a window matches nothing real and no decision is made
    #: (``None``: the descriptor's own threshold, ``Descriptor.reject``)
    reject: float | None = None
    #: motion matching: at every decision the ``top`` best windows of the whole library
    #: (the fast index) are candidates too, as direct blended jumps to the frame after
    #: each window (where the performer is now). A jump's score is its DTW cost times
    #: ``1 + blend_weight * D / (D + D_max)`` (``D``: the graph's distance from the
    #: avatar's frame, ``D_max`` the largest a transition may have); it is taken when
    #: that is below ``jump_ratio`` times the avatar's own cost (always at the end of a
    #: clip). The own cost is that of the library window that plays into the avatar's
    #: frame (``own_from_library``: what the search scores every window by; right after
    #: a jump the frames shown still hold the motion it jumped from), or of the last
    #: ``window`` seconds it has shown. With the vote keeping the action, no margin
    #: (``jump_ratio`` 1, ``blend_weight`` 0) keeps the avatar in step with the
    #: performer: DTW lets an out-of-step window cost nearly what an in-step one does, so
    #: any margin kept it out of step (``benchmarks/HISTORY.md``, "The matcher's settings")
    jumps: bool = True
    top: int = 8
    blend_weight: float = 0.0
    jump_ratio: float = 1.0
    own_from_library: bool = True
    #: no jump until the avatar has played ``hold`` seconds on since its last move (it
    #: would flicker between windows of near cost); at a clip's end it jumps anyway.
    #: Short: the brief stays keep the avatar in step; a longer hold (``mimic perform
    #: --hold``) makes a steadier avatar at the cost of its pose
    hold: float = 0.1
    #: with jumps, when no jump is taken: ``True``, the paper's cluster paths (their
    #: future against the performer's past); ``False`` (default: as accurate on the
    #: folds, and three times faster), the avatar plays on
    cluster_paths: bool = False
    #: with jumps, on a library whose clips are labelled (``Matcher.vote``; each
    #: unlabelled clip counts as an action of its own): the best window of each of the
    #: last ``vote`` decisions votes for its action, and the avatar keeps to the action
    #: most voted for (which changes only when another has more votes; when none of the
    #: best windows shows it, the best that do are searched for), leaving another when
    #: it shows one or will have played on into one within half a window, unless
    #: another fits far better (``vote_margin``) (0: no vote). 15: 1.5 s of decisions
    vote: int = 15
    #: with the vote: windows of another action than the one voted for may be jumped
    #: into too, at ``1 + vote_margin`` times their cost, and the avatar's own motion,
    #: when it shows another action, costs as much more, played on or held still
    #: (``math.inf``: never: the avatar jumps only into the voted action, and leaves
    #: another at once). The library's labels are coarser than its poses: a window of
    #: another action is sometimes far nearer the performer's pose; a margin trades
    #: label agreement for the pose score and flicker (``benchmarks/HISTORY.md``)
    vote_margin: float = 0.2
    #: > 0: the voted action is filtered online by a hidden Markov model over the
    #: library's actions (``ActionVote.filter``) rather than counted over the last
    #: ``vote`` decisions: the chance per decision that the performer changes action,
    #: and the temperature that turns each decision's action scores into evidence
    vote_switch: float = 0.0
    vote_temperature: float = 0.1
    #: with ``vote_switch``: the fewest decision points an action, once voted in, is
    #: kept (1: a plain hidden Markov model)
    vote_min_stay: int = 1
    #: with ``vote_switch``: the voted action changes only to one believed at least this
    #: much (0: to the most believed, whatever its belief)
    vote_confidence: float = 0.0
    #: each decision's vote goes to the action the library's action classifier and the
    #: search's costs agree on (``vision._classify``), not the best window's alone
    classify: bool = True
    #: a jump's target (the frame after its window) moves by up to ``phase`` frames to
    #: where the library's last frames before it are nearest the performer's last 0.2 s
    #: (``vision._windows.phased_targets``; 0: off): DTW places a window's end loosely,
    #: and the avatar then plays out of step (3 frames are compared)
    phase: int = 6
    #: the action vote also reads the performer at these tempos against the library's
    #: (0.6: the performer moves at 0.6 times its speed, so their last ``window / 0.6``
    #: seconds are resampled to a window; ``vision._windows.tempo_readings``); where the
    #: avatar lands stays by the performer as seen. Off by default: it helps slow
    #: performers' labels but costs the pose score, a real squat clip and (silhouettes)
    #: time (``benchmarks/HISTORY.md``)
    tempos: tuple[float, ...] = ()
    #: with jumps, the avatar may hold its frame still (``Matcher.held``) when that
    #: matches a performer standing still better than any jump or playing on
    still: bool = True
    #: for silhouettes read as seen and mirrored: windows that only the performer facing
    #: the other way explains (``vision._facing``: facing the camera by default, then as
    #: the evidence says) cost ``1 + facing`` times as much (0: off), so that the avatar
    #: raises the knee the performer raises, not the other
    facing: float = 0.3
    #: DTW weighs the performer's last frames more than the first of the window
    #: (``control.dtw``'s ``recency``: the last frame ``1 + recency`` times the first,
    #: linearly between, 1 on average; 0: every frame alike), so that the window whose
    #: end fits what the performer does now wins over one whose start fits what they did
    #: a second ago. Off by default: it lifted the pose score on takes of the library's
    #: own performer, and the gain did not carry over to a real one
    #: (``benchmarks/HISTORY.md``)
    recency: float = 0.0

    def __post_init__(self) -> None:
        if not (math.isfinite(self.hold) and self.hold >= 0):
            raise ValueError(f"hold must be a finite number of seconds >= 0, got {self.hold}")
        if not 0.0 <= self.stay < 1.0:
            raise ValueError(f"stay must lie in [0, 1), got {self.stay}")
        if not (self.top >= 1 and self.blend_weight >= 0 and self.jump_ratio > 0):
            raise ValueError("top must be >= 1, blend_weight >= 0 and jump_ratio > 0")
        if self.phase < 0:
            raise ValueError(f"phase must be a number of frames >= 0 (0: off), got {self.phase}")
        if not self.facing >= 0:
            raise ValueError(f"facing must be >= 0 (0: off), got {self.facing}")
        if not (math.isfinite(self.recency) and self.recency >= 0):
            raise ValueError(f"recency must be a finite number >= 0 (0: off), got {self.recency}")
        if not 0.0 <= self.vote_switch < 1.0:
            raise ValueError(f"vote_switch must lie in [0, 1), got {self.vote_switch}")
        if not (self.vote_temperature > 0 and math.isfinite(self.vote_temperature)):
            raise ValueError(f"vote_temperature must be positive, got {self.vote_temperature}")
        if not self.vote_margin >= 0:
            raise ValueError(f"vote_margin must be >= 0 (inf: strict), got {self.vote_margin}")
        if self.vote < 0:
            raise ValueError(f"vote must be a number of decisions >= 0 (0: off), got {self.vote}")
        if self.reject is not None and not self.reject > 0:
            raise ValueError(f"reject must be positive, got {self.reject}")
        object.__setattr__(self, "tempos", tuple(self.tempos))
        if not all(isinstance(t, (int, float)) and 0.25 <= t <= 4.0 for t in self.tempos):
            raise ValueError(f"tempos must be numbers in [0.25, 4], got {self.tempos}")


@dataclass(frozen=True)
class Jump:
    """A direct blended jump: its ``target`` frame, the avatar's ``own_cost`` it beat,
    the pose distance its ``blend`` starts from, and whether it ``leaves`` the avatar's
    action for the one voted for, whatever it costs."""

    target: int
    own_cost: float
    blend: float
    leaves: bool = False


@dataclass(frozen=True, eq=False)
class Decision:
    """The chosen path (``frames``, ``edges`` from the avatar's frame) and the costs."""

    frames: IntArray
    edges: IntArray
    cluster_path: IntArray
    cost: float
    runner_up: float
    view: int
    candidates: int
    latency_ms: float
    #: the avatar's own frame "plays_on" or is "held" (shown again); "" for the paper's
    #: cluster path or a direct jump (``jump``)
    how: str = ""
    jump: Jump | None = None


@dataclass(frozen=True)
class PerformSettings:
    decide_every: float = 0.1
    #: "auto": the pose descriptor's landmarks need the pose model; otherwise a camera
    #: learns a plate (mog2) and footage uses a person segmenter (pose)
    segmentation: str = "auto"
    learn_frames: int = 30
    match: MatchSettings = field(default_factory=MatchSettings)
    seconds: float | None = None  # stop after this much media time (cameras never end)
    #: the avatar's blend interval, seconds (transitions and jumps). 0.5, against the
    #: graph's 1 s: the avatar jumps every few tenths of a second, so a 1 s blend never
    #: ends, and its planted feet slid more and its junctions turned faster
    #: (``benchmarks/HISTORY.md``)
    blend: float = 0.5
    #: run relocation's global search in a thread, its answer taken at a later decision,
    #: so that a live source is never held up by it (it takes tens to hundreds of ms);
    #: None: only for a camera or a paced (``realtime``) file, so that replays stay
    #: deterministic
    background_search: bool | None = None
