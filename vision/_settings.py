"""What the matcher is told, one small object per concern.

``MatchSettings`` holds what every decision uses (the performer's window, DTW, the
readings of the performer) and three concerns, each its own object:

- ``PathSettings``: Lee et al.'s candidate paths through the cluster forest, where the
  avatar starts, and relocation by a search of the whole component;
- ``LandingSettings``: motion matching's direct blended jumps, where they land, and
  holding the avatar still;
- ``ActionSettings``: which action the avatar keeps to (the vote over the last
  decisions, or the online filter).

The command line keeps its flags (``--vote``, ``--hold``, ...); ``mimic`` turns them into
these objects once, at its edge.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = [
    "FILTER_SWITCH",
    "ActionSettings",
    "LandingSettings",
    "MatchSettings",
    "PathSettings",
    "PerformSettings",
]


@dataclass(frozen=True)
class PathSettings:
    """Lee et al.'s candidate paths, the avatar's start and relocation.

    Attributes
    ----------
    lookahead : float
        Seconds ahead of the avatar's frame that a candidate path reaches.
    max_candidates : int
        At most this many candidate paths are compared per decision.
    start_at_best : bool
        Start the avatar where the library looks most like the performer (else at the
        run's start frame).
    relocate_every : float
        Every so many seconds (0: never) the whole component is searched too.
    relocate_ratio : float
        A relocation is taken when the component's best window costs less than this
        times the best candidate's.
    route_seconds : float
        The longest way through the graph a relocation may take.
    keep_clip_bonus : float
        A temporal prior in [0, 1): a path that plays on in the avatar's clip, without a
        transition in its first window, has its cost multiplied by ``1 - keep_clip_bonus``,
        so the avatar keeps its action unless another fits clearly better (0: none).
    after_no_jump : bool
        With jumps on, when no jump is taken: ``True``, the paper's cluster paths (their
        future against the performer's past); ``False`` (as accurate on the folds and
        three times faster), the avatar plays on.
    """

    lookahead: float = 1.5
    max_candidates: int = 64
    start_at_best: bool = True
    relocate_every: float = 1.0
    relocate_ratio: float = 0.8
    route_seconds: float = 4.0
    keep_clip_bonus: float = 0.0
    after_no_jump: bool = False

    def __post_init__(self) -> None:
        if not 0.0 <= self.keep_clip_bonus < 1.0:
            raise ValueError(f"keep_clip_bonus must lie in [0, 1), got {self.keep_clip_bonus}")


@dataclass(frozen=True)
class LandingSettings:
    """Motion matching's direct blended jumps: when one is taken and where it lands.

    At every decision the ``top_windows`` best windows of the whole library (the fast
    index) are candidates, each as a jump to the frame after its window (where the
    performer is now). A jump's score is its DTW cost times ``1 + blend_weight * D / (D +
    D_max)`` (``D``: the graph's distance from the avatar's frame, ``D_max`` the largest
    a transition may have); it is taken when that is below ``jump_ratio`` times the
    avatar's own cost (always at the end of a clip). With the action decision keeping
    the action, no margin (``jump_ratio`` 1, ``blend_weight`` 0) keeps the avatar in step
    with the performer: DTW lets an out-of-step window cost nearly what an in-step one
    does, so any margin keeps it out of step.

    Attributes
    ----------
    jumps : bool
        Direct jumps at all (else only the paper's cluster paths and relocation).
    top_windows : int
        The library's best windows that are candidate jumps.
    blend_weight : float
        How much a far jump (a long blend) costs more, at most (0: nothing).
    jump_ratio : float
        A jump must score below this times the avatar's own cost.
    own_from_library : bool
        The avatar's own cost is that of the library window that plays into its frame
        (what the search scores every window by; right after a jump the frames shown
        still hold the motion it jumped from); else of the last window it has shown.
    min_play : float
        Seconds the avatar plays on after a move before it may jump again (it would
        flicker between windows of near cost); at a clip's end it jumps anyway. Longer
        makes a steadier avatar at the cost of its pose.
    phase_frames : int
        A jump's target moves by up to this many frames to where the library's last
        frames before it are nearest the performer's last 0.2 s (0: off): DTW places a
        window's end loosely, and the avatar then plays out of step.
    hold_still : bool
        The avatar may hold its frame still when that matches a performer standing still
        better than any jump or playing on.
    hold_back : int
        With ``hold_still``, where a jump is chosen: the avatar may instead land on one of
        this many frames that play into the jump's target and hold it, where that
        matches a performer standing still better (0: only its own frame is held).
    hold_keep : float
        With ``hold_still``, what a frame the avatar holds already costs, as a share of
        its cost, when it is weighed against a jump or another frame to hold (1: as
        much), where it fits the performer well (not over ``action.weak_fit``). A
        performer's stillness, read with a pose model's or a segmentation's noise, fits
        many near-alike frames about as well: at 1 the avatar went on hopping from one
        held frame to another about twice a second while the performer stood still.
        Where the held frame fits weakly (a pose model guessing from behind, an action
        the library lacks) it would only keep the avatar in the wrong pose
        (``benchmarks/HISTORY.md``, "Holds").
    lead : float
        Seconds ahead of the performer's last frame a jump lands (at most 0.5), where
        the performer will be when a live avatar is shown (the pose model, the page's
        round trip). It plays the matched clip on, which foresees the performer's
        tempo no better than the present does: measured, it helps only a viewer who
        sees the avatar 0.2 s or more after the frame it answers.
    """

    jumps: bool = True
    top_windows: int = 8
    blend_weight: float = 0.0
    jump_ratio: float = 1.0
    own_from_library: bool = True
    min_play: float = 0.1
    phase_frames: int = 6
    hold_still: bool = True
    hold_back: int = 6
    hold_keep: float = 0.8
    lead: float = 0.0

    def __post_init__(self) -> None:
        if not 0 <= self.lead <= 0.5:  # (further ahead is a guess, not a phase)
            raise ValueError(f"lead must be from 0 to 0.5 seconds, got {self.lead}")
        if not (math.isfinite(self.min_play) and self.min_play >= 0):
            raise ValueError(
                f"min_play must be a finite number of seconds >= 0, got {self.min_play}"
            )
        if not (self.top_windows >= 1 and self.blend_weight >= 0 and self.jump_ratio > 0):
            raise ValueError("top_windows must be >= 1, blend_weight >= 0 and jump_ratio > 0")
        if not 0 < self.hold_keep <= 1:
            raise ValueError(f"hold_keep must lie in (0, 1], got {self.hold_keep}")
        if self.hold_back < 0:
            raise ValueError(f"hold_back must be >= 0 (0: off), got {self.hold_back}")
        if self.phase_frames < 0:
            raise ValueError(f"phase_frames must be >= 0 (0: off), got {self.phase_frames}")


#: the filtered vote's chance of a change per decision, by default with landmarks
#: (``ActionSettings.switch_for``)
FILTER_SWITCH = 0.02


@dataclass(frozen=True)
class ActionSettings:
    """Which action the avatar keeps to, on a library whose clips are labelled (each
    unlabelled clip counts as an action of its own), with jumps on.

    Attributes
    ----------
    vote : int
        The best window of each of the last ``vote`` decisions votes for its action, and
        the avatar keeps to the action most voted for (0: no vote; 15: 1.5 s of
        decisions). It leaves another action when it shows one or will have played on
        into one within half a window, unless another fits far better (``margin``).
        With the filter (``switch_chance``) every decision weighs in and this only turns
        the vote on (> 0).
    margin : float
        Windows of another action than the voted one may be jumped into at ``1 + margin``
        times their cost, and the avatar's own motion, when it shows another action,
        costs as much more (``math.inf``: the avatar jumps only into the voted action).
        The library's labels are coarser than its poses: a window of another action is
        sometimes far nearer the performer's pose; a margin trades label agreement for
        the pose score and flicker.
    switch_chance : float or None
        > 0: the voted action is filtered online by a hidden Markov model over the
        actions (``ActionVote.filter``) rather than counted: the chance per decision
        that the performer changes action (0: the counted vote). ``None``: by what the
        ballots hear (``switch_for``): the filter (0.02) where they hear landmarks (the
        pose descriptor, or a silhouette's with the landmarks read from it:
        ``vision._voice``), whose ballots it follows steadier and as soon, with
        ``ballot_jumps``; the counted vote for a silhouette's alone, whose ballots are
        less sure and which the filter follows late (``benchmarks/HISTORY.md``, "Ballot
        jumps" and "Steadiness").
    temperature : float
        With the filter: what turns each decision's action scores into evidence.
    min_points : int
        With the filter: the fewest decision points an action, once voted in, is kept
        (1: a plain hidden Markov model).
    confidence : float
        With the filter: the voted action changes only to one believed at least this
        much (0: to the most believed).
    classify : bool
        Each decision votes for the action the library's action classifier and the
        search's costs agree on (``vision._classify``), not the best window's alone.
    strict_share : float
        Where at least this share of the last ``vote`` decisions voted for the voted
        action (with the filter: where it is believed at least this much), that decision
        jumps only into the voted action, and the avatar playing on out of it jumps
        before it does; where the vote is split, the margin lets a jump take a nearer
        pose of another action (0: off). The avatar's own motion of another action, and
        its holds, keep the margin: a performer standing still is still mirrored by a
        held frame of whatever action. 0.9 is steadier than off on every fold at about
        the same pose score; from the side and from behind it agrees a little less
        (``benchmarks/HISTORY.md``, "Steadiness").
    weak_fit : float
        A decision whose best window's per-frame cost is over this share of the
        descriptor's reject threshold fits weakly: the performer does something the
        library lacks, or the pose model guesses (from behind it misplaces wrists and
        ankles by a fifth of the body), and the pose then says less of the action than
        the vote over the last decisions does. There windows of another action than the
        voted one cost ``1 + weak_margin`` times as much (where that is more than
        ``margin``); the avatar's own motion keeps ``margin``. The actions a performer
        does fit at about a quarter of the threshold, what the library lacks at about
        half (``benchmarks/HISTORY.md``, "Weak fits"). ``inf``: off.
    weak_margin : float
        The margin where the best window fits weakly (``weak_fit``).
    ballot_jumps : bool
        With the filter and a finite ``margin``: where a decision's ballot names another
        action than the voted one, that decision may jump into a window of it through
        the margin (windows of any third action stay shut), before the filter believes
        it. The filter takes a change up once the evidence of several decisions outweighs
        its cost; the performer's pose often shows the new action a decision or two
        before that (a squat begins), and a window of it then fits far better than any
        of the voted action.
    ballot_keep : int
        With ``ballot_jumps``: an avatar showing another action than the voted one that
        a ballot of the last ``ballot_keep`` decision points named (a skipped point
        counts) plays on in it at its own cost, without the margin, while it will still
        show it half a window on (0: off). Without it, the next decision whose ballot
        names the voted action again pushes the avatar straight back out of an action it
        has just jumped into, and the next ballot for that action takes it back in: the
        action is shown for a tenth of a second, twice (``benchmarks/HISTORY.md``,
        "Ballot jumps").
    repeat : float
        With ``ballot_jumps``: where the performer's last 0.7 s come within ``repeat``
        times the median distance of a stretch of their own last 3 s
        (``vision._repeat.repeated``), the performer does again what they did a moment
        ago, and a ballot's new action stays shut: the decision may jump into the voted
        action, the one the avatar shows, or the one voted when the performer did this
        before (a second squat after a pause the vote took for standing), as a ballot
        for none had asked (0: off). The avatar's wrong switches on our takes were
        ballot jumps into an action the performer was not doing, each undone a moment
        later, and most came while the performer repeated themselves; the right ones
        come while the performer does something new (``benchmarks/HISTORY.md``,
        "Repeats").
    fuse : bool
        With landmarks and the silhouette beside them (``vision._fallback``): where the
        pose model's limbs are of low confidence, each decision's ballot weighs both
        descriptors' action scores, each by how well its best window fits
        (``vision._vote.fused``) and the silhouette more the more limbs are hidden
        (``SilhouetteFallback.evidence``). From the side the pose model places the far
        arm and leg by guess, and the silhouette still shows them; with every limb seen
        (a performer facing the camera) the landmarks decide alone, as without it, and
        no silhouette search is made. On by default: a camera at the side or at three
        quarters behind is followed much better, a performer facing it as before
        (``benchmarks/HISTORY.md``, "Both descriptors").
    tempos : tuple of float
        The vote also reads the performer at these tempos against the library's (0.6:
        the performer moves at 0.6 times its speed, so their last ``window / 0.6``
        seconds are resampled to a window); where the avatar lands stays by the
        performer as seen. Empty by default: it helps slow performers' labels but costs
        the pose score and time.
    """

    vote: int = 15
    margin: float = 0.2
    switch_chance: float | None = None
    temperature: float = 0.2
    min_points: int = 1
    confidence: float = 0.9
    classify: bool = True
    strict_share: float = 0.9
    weak_fit: float = 0.35
    weak_margin: float = 1.0
    ballot_jumps: bool = True
    ballot_keep: int = 5
    repeat: float = 0.6
    fuse: bool = True
    tempos: tuple[float, ...] = ()

    @classmethod
    def steady(cls) -> ActionSettings:
        """The filter alone (``mimic perform --steady``): the voted action filtered by a
        hidden Markov model (a change 0.02 a decision, at the defaults' ``temperature``
        and ``confidence``), and jumps only into it, whatever the descriptor.
        Calmer than the defaults (on our simulated takes with landmarks 15.6 action
        switches a minute against 16.9, 0.8 brief against 1.5; on MediaPipe's renders
        of another person 20.5 against 25.5), but it takes a change up about 0.2 s
        later, follows the pose less closely and makes two of the real squat clip's 39
        labelled decisions wrong that the defaults make right, so it is an option
        (``benchmarks/HISTORY.md``, "Steadiness" and "Ballot jumps")."""
        return cls(switch_chance=FILTER_SWITCH, margin=math.inf)

    def switch_for(self, descriptor: str, voice: bool = False) -> float:
        """``switch_chance`` for a matcher of ``descriptor`` (a ``Descriptor.kind``),
        ``voice``: with the landmarks read from its silhouettes beside it
        (``vision._voice``). As set, or by default ``FILTER_SWITCH`` where the ballots
        hear landmarks and 0 (counted) where they hear a silhouette alone."""
        if self.switch_chance is not None:
            return self.switch_chance
        return FILTER_SWITCH if descriptor == "pose" or voice else 0.0

    def __post_init__(self) -> None:
        if self.vote < 0:
            raise ValueError(f"vote must be a number of decisions >= 0 (0: off), got {self.vote}")
        if self.ballot_keep < 0:
            raise ValueError(f"ballot_keep must be >= 0 (0: off), got {self.ballot_keep}")
        if not (0.0 <= self.repeat < 1.0):
            raise ValueError(f"repeat must lie in [0, 1) (0: off), got {self.repeat}")
        if not self.margin >= 0:
            raise ValueError(f"margin must be >= 0 (inf: strict), got {self.margin}")
        if not (self.switch_chance is None or 0.0 <= self.switch_chance < 1.0):
            raise ValueError(f"switch_chance must lie in [0, 1), got {self.switch_chance}")
        if not 0.0 <= self.strict_share <= 1.0:
            raise ValueError(f"strict_share must lie in [0, 1], got {self.strict_share}")
        if not (self.weak_fit > 0 and self.weak_margin >= 0):
            raise ValueError(
                f"weak_fit must be > 0 (inf: off) and weak_margin >= 0, got "
                f"{self.weak_fit} and {self.weak_margin}"
            )
        if not (self.temperature > 0 and math.isfinite(self.temperature)):
            raise ValueError(f"temperature must be positive, got {self.temperature}")
        object.__setattr__(self, "tempos", tuple(self.tempos))
        if not all(isinstance(t, (int, float)) and 0.25 <= t <= 4.0 for t in self.tempos):
            raise ValueError(f"tempos must be numbers in [0.25, 4], got {self.tempos}")


@dataclass(frozen=True)
class MatchSettings:
    """What the matcher is told: what every decision uses, then one object per concern.

    Attributes
    ----------
    window : float
        Seconds of the performer compared with the library's windows.
    band : int
        The DTW band, in frames.
    centre_weight : float
        The silhouette's (or mid-hip's) place against the shape numbers.
    mirror : bool or None
        Also match the performer mirrored (and, for landmarks, with left and right
        labels swapped): the best reading wins. ``None``: the descriptor's own default
        (``Descriptor.reads_mirrored``: silhouettes yes, which cannot tell a pose from
        its mirror image seen from behind; landmarks no, which name the sides).
    reject : float or None
        Per-frame cost above which a window matches nothing real and no decision is
        made (``None``: the descriptor's own, ``Descriptor.reject``).
    facing : float
        For silhouettes read as seen and mirrored: windows that only the performer
        facing the other way explains cost ``1 + facing`` times as much (0: off), so the
        avatar raises the knee the performer raises, not the other.
    recency : float
        DTW weighs the performer's last frames more than the window's first (the last
        ``1 + recency`` times the first, linearly between, 1 on average; 0: alike).
        Off by default: its gain on the library's own performer did not carry over.
    paths : PathSettings
        Lee et al.'s candidate paths, the start and relocation.
    landing : LandingSettings
        Direct jumps and where they land.
    action : ActionSettings
        Which action the avatar keeps to.
    """

    window: float = 1.0
    band: int = 4
    centre_weight: float = 3.0
    mirror: bool | None = None
    reject: float | None = None
    facing: float = 0.3
    recency: float = 0.0
    paths: PathSettings = field(default_factory=PathSettings)
    landing: LandingSettings = field(default_factory=LandingSettings)
    action: ActionSettings = field(default_factory=ActionSettings)

    def __post_init__(self) -> None:
        if not self.facing >= 0:
            raise ValueError(f"facing must be >= 0 (0: off), got {self.facing}")
        if not (math.isfinite(self.recency) and self.recency >= 0):
            raise ValueError(f"recency must be a finite number >= 0 (0: off), got {self.recency}")
        if self.reject is not None and not self.reject > 0:
            raise ValueError(f"reject must be positive, got {self.reject}")


@dataclass(frozen=True)
class PerformSettings:
    """What the performance loop is told.

    Attributes
    ----------
    decide_every : float
        Seconds of media time between decision points.
    segmentation : str
        How a frame becomes a silhouette: ``"auto"`` (the pose descriptor's landmarks
        need the pose model; otherwise a camera learns a plate, ``mog2``, and footage
        uses a person segmenter, ``pose``), or one of those by name.
    learn_frames : int
        Frames a plate-learning segmenter watches before the performer steps in.
    match : MatchSettings
        What the matcher is told.
    seconds : float or None
        Stop after this much media time (cameras never end); ``None``: at the source's
        end.
    blend : float
        The avatar's blend interval in seconds (transitions and jumps): shorter than
        the graph's 1 s, as the avatar jumps every few tenths of a second, and a blend
        that never ends slides planted feet and turns junctions faster.
    background_search : bool or None
        Run relocation's global search in a thread, its answer taken at a later
        decision, so a live source is never held up by it; ``None``: only for a camera
        or a paced (``realtime``) file, so that replays stay deterministic.
    """

    decide_every: float = 0.1
    segmentation: str = "auto"
    learn_frames: int = 30
    match: MatchSettings = field(default_factory=MatchSettings)
    seconds: float | None = None
    blend: float = 0.5
    background_search: bool | None = None
