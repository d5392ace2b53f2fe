"""The options ``mimic perform`` and ``mimic evaluate`` share, and the settings made from
them once, at the command line's edge (``run_settings``): below it, ``prepare`` and the
packages see settings objects, never the parsed arguments."""

from __future__ import annotations

import argparse
import dataclasses
from dataclasses import dataclass

from control.clusters import LayerSettings
from control.graph import GraphOptions
from silhouette_bank import DEFAULT_DESCRIPTOR, DESCRIPTORS
from vision import (
    FILTER_SWITCH,
    FLOOR_ABOVE,
    FLOOR_SECONDS,
    METHODS,
    PERSON_METHODS,
    VISION_COORDS,
    ActionSettings,
    LandingSettings,
    MatchSettings,
    PathSettings,
    PerformSettings,
)

from .args import (
    MOST_SECONDS,
    LibraryChoice,
    add_graph_args,
    add_library_args,
    blend_seconds,
    graph_options,
    library_choice,
    number,
)

__all__ = ["RunSettings", "add_run_args", "run_settings", "silhouette_flag"]


@dataclass(frozen=True)
class RunSettings:
    """What a performance is prepared from (``mimic.run.prepare``).

    Attributes
    ----------
    library : LibraryChoice
        The library folder and which of its clips.
    leave_out : tuple of str
        Shell patterns of clips left out (the performer's own take).
    off_floor : bool
        Keep the clips whose feet leave the floor.
    graph : GraphOptions
        The motion graph's options.
    rebuild : bool
        Rebuild the graph even when the cache has it.
    layer : LayerSettings
        The higher layer's (clusters and trees).
    bank : str or None
        A bank folder built by ``mimic bank build`` (``None``: the cache's).
    descriptor : str
        ``"auto"`` or a descriptor's name.
    variants : bool
        A bank with other bodies and shadows too.
    fallback : bool
        With landmarks, match the person mask where they fail.
    perform : PerformSettings
        The loop's and the matcher's settings.
    start : str or None
        ``CLIP:FRAME`` where the avatar starts (``None``: where the performer is found).
    """

    library: LibraryChoice
    leave_out: tuple[str, ...]
    off_floor: bool
    graph: GraphOptions
    rebuild: bool
    layer: LayerSettings
    bank: str | None
    descriptor: str
    variants: bool
    fallback: bool
    perform: PerformSettings
    start: str | None


def action_settings(args: argparse.Namespace) -> ActionSettings:
    """The ``ActionSettings`` of the vote's arguments: ``--steady``'s or the defaults
    (the filter where the ballots hear landmarks, the counted vote where they hear a
    silhouette alone: ``ActionSettings.switch_for``), with ``--vote-switch``
    and ``--vote-margin``, where given, over either."""
    base = ActionSettings.steady() if args.steady else ActionSettings()
    given = {"margin": args.vote_margin, "switch_chance": args.vote_switch}
    return dataclasses.replace(
        base,
        vote=args.vote,
        strict_share=args.vote_strict,
        weak_fit=args.weak_fit,
        weak_margin=args.weak_margin,
        ballot_jumps=args.ballot_jumps,
        repeat=args.repeat,
        confidence=args.vote_confidence,
        temperature=args.vote_temperature,
        fuse=args.fuse,
        classify=not args.no_classify,
        **{k: v for k, v in given.items() if v is not None},
    )


def run_settings(args: argparse.Namespace) -> RunSettings:
    """The ``RunSettings`` of ``add_run_args``'s arguments; a bad value is said now,
    before minutes of building."""
    match = MatchSettings(
        window=args.window,
        recency=args.recency,
        paths=PathSettings(lookahead=args.lookahead),
        landing=LandingSettings(jumps=not args.no_jumps, min_play=args.hold, lead=args.lead),
        action=action_settings(args),
    )
    # the matcher looks no further ahead than the look-ahead: trees that reach that far
    # (the paper's 15 s trees of a dense graph are truncated, and slow to build)
    bound = max(2.0, args.lookahead + 0.5)
    return RunSettings(
        library=library_choice(args),
        leave_out=tuple(args.leave_out),
        off_floor=args.off_floor,
        graph=graph_options(args),
        rebuild=args.rebuild,
        layer=LayerSettings(k=args.k, bound_seconds=bound),
        bank=args.bank,
        descriptor=args.descriptor,
        variants=args.variants,
        fallback=not args.no_fallback,
        perform=PerformSettings(
            segmentation=args.segmentation,
            learn_frames=args.learn_frames,
            match=match,
            seconds=args.seconds,
            blend=blend_seconds(args, PerformSettings.blend),
        ),
        start=args.start,
    )


def add_run_args(p: argparse.ArgumentParser) -> None:
    """The options of a performance that ``perform`` and ``evaluate`` share: the library,
    its graph, the matcher, the segmentation and the descriptor (which sets the library's
    mirrored copies: ``mimic.args.mirror_copies``)."""
    add_library_args(p, mirror="auto")
    p.add_argument(
        "--leave-out",
        action="append",
        default=[],
        metavar="PATTERN",
        help="leave out clips whose name matches (shell pattern, repeatable): the "
        "performer's own take, to measure an unseen performer",
    )
    add_graph_args(p)
    # the vision interface's graph: relative coordinates, so that takes recorded in
    # different places reach each other
    p.set_defaults(coords=VISION_COORDS)
    p.add_argument(
        "--off-floor",
        action="store_true",
        help=f"keep clips whose feet leave the floor (over {FLOOR_ABOVE:g} m for more than "
        f"{FLOOR_SECONDS:g} s: climbing, sitting on things); by default they are left out, "
        "as the avatar would float",
    )
    _add_jump_args(p)
    _add_vision_args(p)
    p.add_argument("--k", type=number(int, 1, 10000), help="number of clusters (default: BIC)")
    p.add_argument("--start", help="avatar starts at CLIP:FRAME")
    p.add_argument("--seed", type=number(int, 0, 2**32 - 1), default=0)


def _add_vision_args(p: argparse.ArgumentParser) -> None:
    """The matcher's window, the segmentation, then the descriptor and its bank
    (``_add_descriptor_args``)."""
    p.add_argument(
        "--seconds",
        type=number(float, 0, MOST_SECONDS, above=True),
        help="stop after this much media time",
    )
    p.add_argument(
        "--window",
        type=number(float, 0, 10, above=True),
        default=MatchSettings.window,
        help="seconds of performer matched",
    )
    p.add_argument(
        "--lookahead",
        type=number(float, 0, 60),
        default=PathSettings.lookahead,
        help="candidate actions within, s",
    )
    p.add_argument(
        "--segmentation",
        choices=("auto", *PERSON_METHODS, *METHODS),
        default="auto",
        help="auto (default): a camera learns the empty scene first (mog2); a video file has "
        "no such plate, so a person segmenter (pose, needs MediaPipe) is used; the pose "
        "descriptor always uses the pose model; the rest are OpenCV background subtractors",
    )
    p.add_argument(
        "--learn-frames",
        type=number(int, 1, 100000),
        default=30,
        help="frames to learn the background",
    )
    _add_descriptor_args(p)


def _add_descriptor_args(p: argparse.ArgumentParser) -> None:
    """The descriptor, its bank, and the silhouette where the landmarks fail."""
    p.add_argument(
        "--variants",
        action="store_true",
        help="match against a bank with other bodies (0.9-1.25 wide) and shadows at the "
        "feet too: more robust to performers who are not the avatar, 8x the bank",
    )
    p.add_argument(
        "--descriptor",
        choices=("auto", *DESCRIPTORS),
        default="auto",
        help="what each frame is reduced to. auto (default): pose (MediaPipe's body "
        "landmarks against the avatar's projected joints) for colour video and cameras "
        "when MediaPipe is installed, else outline (how full each cell of 16x8, 8x4 and "
        "4x2 grids over the silhouette is, and how far it reaches left and right); "
        "multigrid (the cells alone), grid, hu (7 Hu moments): see the README's "
        "recognition figures",
    )
    p.add_argument(
        "--silhouette-video",
        choices=("auto", "yes", "no"),
        default="auto",
        help="whether --video holds binary silhouettes (white on black) rather than "
        "colour footage; auto (default): yes when each of its first 30 frames that is not "
        "all black is black and white only",
    )
    p.add_argument(
        "--bank",
        help="a bank folder built by mimic bank build (any render settings and descriptor; "
        "from the same clips) instead of the cached default bank",
    )
    p.add_argument(
        "--no-fallback",
        action="store_true",
        help="with the pose descriptor, make no decision where the landmarks fail; by "
        "default the pose model's person mask is matched then, against a silhouette bank "
        f"({DEFAULT_DESCRIPTOR}) of the same clips",
    )


def _add_jump_args(p: argparse.ArgumentParser) -> None:
    """The direct jumps' options, and the action vote's (``_add_vote_args``)."""
    p.add_argument(
        "--no-jumps",
        action="store_true",
        help="only the paper's cluster paths (and a relocation through the graph once a "
        "second), no direct blended jumps into the best-matching windows",
    )
    _add_vote_args(p)
    _add_filter_args(p)
    p.add_argument(
        "--recency",
        type=number(float, 0, 1000),
        default=MatchSettings.recency,
        help="the matcher's DTW weighs the performer's last frame 1 + R times the first of "
        "the window, linearly between (default %(default)s; 0: every frame alike)",
    )
    p.add_argument(
        "--lead",
        type=number(float, 0, 0.5),
        default=LandingSettings.lead,
        metavar="SECONDS",
        help="land the avatar this far ahead of the performer's last frame, where a live "
        "performer will be when the avatar is shown (default %(default)s: on bench_accuracy's "
        "runs it helps only where the avatar is shown 0.2 s or more after its frame)",
    )
    p.add_argument(
        "--hold",
        type=number(float, 0, 60),
        default=LandingSettings.min_play,
        metavar="SECONDS",
        help="no jump until the avatar has played this long since its last move (default "
        "%(default)s). Longer is steadier but follows the performer's pose less closely: "
        "on bench_accuracy's runs with landmarks, 0.5 took the actions the avatar shows "
        "for under 0.5 s from 10 to 2 a minute and the pose score from 0.78 to 0.68",
    )
    p.add_argument(
        "--no-classify",
        action="store_true",
        help="each decision votes for its best window's action alone, not settled by the "
        "action classifier learned from the library",
    )


def _add_vote_args(p: argparse.ArgumentParser) -> None:
    """The action vote's options."""
    p.add_argument(
        "--fuse",
        action=argparse.BooleanOptionalAction,
        default=ActionSettings.fuse,
        help="with landmarks, where the pose model's limbs are of low confidence (a camera "
        "at the side or behind), each decision's vote weighs the silhouette's action "
        "scores too, each descriptor by how well its best window fits; with a silhouette "
        "video, where the silhouette's vote is unsure, it weighs the landmarks the pose "
        "model reads from the silhouette too (--no-fuse: each descriptor alone)",
    )
    p.add_argument(
        "--vote",
        type=number(int, 0, 1000),
        default=ActionSettings.vote,
        help="keep to the action the best windows of the last N decisions voted for (0: off)",
    )
    p.add_argument(
        "--vote-margin",
        type=number(float, 0, 1000, inf=True),
        default=None,
        help="with the vote, a window of another action is taken when it fits better even "
        "at 1 + M times its cost, and the avatar's own motion of another action costs as "
        f"much more (default {ActionSettings.margin:g}, with --steady inf; inf: only the "
        "voted action)",
    )
    p.add_argument(
        "--vote-strict",
        type=number(float, 0, 1),
        default=ActionSettings.strict_share,
        metavar="SHARE",
        help="a decision where at least this share of the last votes went to the voted "
        "action (with the filter: where it is believed at least this much) jumps only into "
        "that action (its own motion and holds keep the margin); 0: off (default %(default)s)",
    )
    p.add_argument(
        "--weak-fit",
        type=number(float, 0.01, 1000, inf=True),
        default=ActionSettings.weak_fit,
        metavar="SHARE",
        help="where the best window's per-frame cost is over SHARE of the reject threshold "
        "(an action the library lacks, a pose model guessing), a window of another action "
        "than the voted one costs 1 + --weak-margin times as much (default %(default)s; "
        "inf: off)",
    )
    p.add_argument(
        "--weak-margin",
        type=number(float, 0, 1000, inf=True),
        default=ActionSettings.weak_margin,
        help="the margin where the best window fits weakly (default %(default)s)",
    )


def _add_filter_args(p: argparse.ArgumentParser) -> None:
    """The filtered vote's options, and ``--steady``, which sets them."""
    steady = ActionSettings.steady()
    p.add_argument(
        "--steady",
        action="store_true",
        help=f"a calmer avatar still: the filtered vote, jumping only into the action it "
        f"believes in (--vote-switch {steady.switch_chance:g} --vote-margin {steady.margin:g}; "
        "either given too wins). It switches action less often, with few brief actions, but "
        "takes a new action up about 0.2 s later and follows the pose less closely",
    )
    p.add_argument(
        "--vote-switch",
        type=number(float, 0, 0.99),
        default=None,
        metavar="P",
        help="filter the voted action by a hidden Markov model whose chance of a change "
        "per decision is P; 0: count the votes instead (default: "
        f"{FILTER_SWITCH:g} with landmarks, a silhouette video's included (the "
        "landmarks read from its silhouettes), 0 with silhouettes alone; with --steady "
        f"{steady.switch_chance:g})",
    )
    p.add_argument(
        "--ballot-jumps",
        action=argparse.BooleanOptionalAction,
        default=ActionSettings.ballot_jumps,
        help="with the filter and a finite --vote-margin, a decision whose ballot names "
        "another action than the voted one may jump into it through the margin before the "
        "filter believes it, and into no third action (default on)",
    )
    p.add_argument(
        "--repeat",
        type=number(float, 0, 0.99),
        default=ActionSettings.repeat,
        metavar="RATIO",
        help="with --ballot-jumps: where your last 0.7 s come within RATIO times the median "
        "distance of a stretch of your own last 3 s (you go on with what you did), a "
        "ballot opens no new action (default %(default)s; 0: off)",
    )
    p.add_argument(
        "--vote-confidence",
        type=number(float, 0, 1),
        default=ActionSettings.confidence,
        help="with the filter, change the voted action only to one believed at least "
        "this much (default %(default)s)",
    )
    p.add_argument(
        "--vote-temperature",
        type=number(float, 0, 100, above=True),
        default=ActionSettings.temperature,
        help="with the filter, what turns each decision's action scores into evidence: "
        "higher weighs one decision less, so a change needs more decisions that agree "
        "(default %(default)s)",
    )


def silhouette_flag(args: argparse.Namespace) -> bool | None:
    """``--silhouette-video`` as the sources take it (``None``: decide by looking)."""
    return {"auto": None, "yes": True, "no": False}[args.silhouette_video]
