"""What ``mimic perform`` and ``mimic evaluate`` share: their options, the library,
graph, layer and bank made from them (``prepare``), and what they say about the source
and the avatar's actions."""

from __future__ import annotations

import argparse
import fnmatch
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from control.clusters import LayerSettings, cached_higher_layer
from control.graph import cached_graph
from control.progress import bar, step
from silhouette_bank import (
    DEFAULT_DESCRIPTOR,
    DESCRIPTORS,
    BankSettings,
    StaleBankError,
    ensure_bank,
    load_bank,
    robust_settings,
)
from vision import (
    FLOOR_ABOVE,
    FLOOR_SECONDS,
    INSTALL,
    METHODS,
    PERSON_METHODS,
    VISION_COORDS,
    MaskFolderSource,
    MatchSettings,
    PerformSettings,
    action_runs,
    on_the_floor,
    person_segmentation_available,
)

from .args import (
    MOST_SECONDS,
    add_graph_args,
    add_library_args,
    blend_seconds,
    graph_options,
    library_for,
    number,
    start_frame,
)

__all__ = [
    "Prepared",
    "add_run_args",
    "choose_descriptor",
    "prepare",
    "print_actions",
    "silhouette_flag",
    "warn_own_take",
    "warn_source",
]


def add_run_args(p: argparse.ArgumentParser) -> None:
    """The options of a performance that ``perform`` and ``evaluate`` share: the library,
    its graph, the matcher, the segmentation and the descriptor."""
    add_library_args(p)
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
    """The matcher's window, the segmentation, the descriptor and its bank."""
    p.add_argument(
        "--seconds",
        type=number(float, 0, MOST_SECONDS, above=True),
        help="stop after this much media time",
    )
    p.add_argument(
        "--window",
        type=number(float, 0, 10, above=True),
        default=1.0,
        help="seconds of performer matched",
    )
    p.add_argument(
        "--lookahead", type=number(float, 0, 60), default=1.5, help="candidate actions within, s"
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
    """The direct jumps' options, and the action vote's."""
    p.add_argument(
        "--no-jumps",
        action="store_true",
        help="only the paper's cluster paths (and a relocation through the graph once a "
        "second), no direct blended jumps into the best-matching windows",
    )
    p.add_argument(
        "--vote",
        type=number(int, 0, 1000),
        default=MatchSettings.vote,
        help="keep to the action the best windows of the last N decisions voted for (0: off)",
    )
    p.add_argument(
        "--vote-margin",
        type=number(float, 0, 1000, inf=True),
        default=MatchSettings.vote_margin,
        help="with the vote, a window of another action is taken when it fits better even "
        "at 1 + M times its cost, and the avatar's own motion of another action costs as "
        "much more (default %(default)s; inf: only the voted action)",
    )
    p.add_argument(
        "--vote-switch",
        type=number(float, 0, 0.99),
        default=MatchSettings.vote_switch,
        metavar="P",
        help="filter the voted action by a hidden Markov model whose chance of a change "
        "per decision is P, instead of counting votes (default %(default)s: counting)",
    )
    p.add_argument(
        "--vote-confidence",
        type=number(float, 0, 1),
        default=MatchSettings.vote_confidence,
        help="with --vote-switch, change the voted action only to one believed at least "
        "this much (default %(default)s)",
    )
    p.add_argument(
        "--recency",
        type=number(float, 0, 1000),
        default=MatchSettings.recency,
        help="the matcher's DTW weighs the performer's last frame 1 + R times the first of "
        "the window, linearly between (default %(default)s; 0: every frame alike)",
    )
    p.add_argument(
        "--hold",
        type=number(float, 0, 60),
        default=MatchSettings.hold,
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


def choose_descriptor(name: str, source: Any) -> str:
    """``"auto"`` made concrete for ``source``: ``pose`` where there are colour frames
    (a camera, a colour video) and MediaPipe is installed (it recognised far better than
    any silhouette descriptor: ``benchmarks/bench_recognition.py``), else the bank's
    default silhouette descriptor. A pose descriptor for a silhouette source is an
    error."""
    colour = not (isinstance(source, MaskFolderSource) or getattr(source, "silhouette", False))
    if name == "auto":
        return "pose" if colour and person_segmentation_available() else DEFAULT_DESCRIPTOR
    if name == "pose" and not colour:
        raise SystemExit(
            f"mimic perform: {source.name} holds silhouettes, and the pose descriptor needs "
            "colour frames (use --descriptor outline, or auto)"
        )
    if name == "pose" and not person_segmentation_available():
        raise SystemExit(
            f"mimic perform: the pose descriptor needs MediaPipe; install it with: {INSTALL}"
        )
    return name


@dataclass
class Prepared:
    """What a performance runs on, made from ``mimic perform``'s (or ``evaluate``'s)
    arguments."""

    descriptor: str
    clips: list[Any]
    graph: Any
    layer: Any
    bank: Any
    bank_built: bool
    settings: PerformSettings
    start: int | None
    #: with the pose descriptor, the silhouette bank matched where the landmarks fail
    fallback: Any = None


def prepare(args: argparse.Namespace, source: Any) -> Prepared:
    """The library (the clips on the floor unless ``--off-floor``), its graph, higher
    layer and bank for ``source`` with the defaults of the vision interface, saying on
    stderr what was chosen and what was left out."""
    # settings first: a bad one is said before minutes of building
    match = MatchSettings(
        window=args.window,
        lookahead=args.lookahead,
        jumps=not args.no_jumps,
        vote=args.vote,
        vote_margin=args.vote_margin,
        vote_switch=args.vote_switch,
        vote_confidence=args.vote_confidence,
        recency=args.recency,
        hold=args.hold,
        classify=not args.no_classify,
    )
    clips = _clips(args)
    t0 = time.perf_counter()
    with step("motion graph"):
        graph, _, _ = cached_graph(clips, graph_options(args), rebuild=args.rebuild)
    clips = _graph_clips(graph, clips)
    _say_unreachable(graph, args.no_jumps)
    # the matcher looks no further ahead than the look-ahead: trees that reach that far
    # (the paper's 15 s trees of a dense graph are truncated, and slow to build)
    bound = max(2.0, args.lookahead + 0.5)
    with step("higher layer (clusters and trees)"):
        layer, _, layer_built = cached_higher_layer(
            graph, clips, LayerSettings(k=args.k, bound_seconds=bound)
        )
    print(
        f"library: {len(graph.clip_names)} clips, {graph.n_frames} frames "
        f"({int(graph.in_scc.sum())} reachable); graph coords {graph.options.coords}; "
        f"{layer.clustering.k} clusters ({'built' if layer_built else 'cached'}); "
        f"{'cluster trees built on first use (a dense graph); ' if layer.forest.lazy else ''}"
        f"{time.perf_counter() - t0:.1f} s",
        file=sys.stderr,
    )
    descriptor, bank, built = _bank(args, clips, source)
    fallback = None
    if descriptor == "pose" and not args.no_fallback:
        print(
            f"where the landmarks fail, the silhouette ({DEFAULT_DESCRIPTOR}) is matched "
            "(--no-fallback: no decision there)",
            file=sys.stderr,
        )
        fallback, _ = ensure_bank(
            clips, BankSettings(), progress=bar("silhouette bank (fallback)", "renders")
        )
    _say_vote(clips, match)
    settings = PerformSettings(
        segmentation=args.segmentation,
        learn_frames=args.learn_frames,
        match=match,
        seconds=args.seconds,
        blend=blend_seconds(args, PerformSettings.blend),
    )
    return Prepared(
        descriptor,
        clips,
        graph,
        layer,
        bank,
        built,
        settings,
        start_frame(graph, args.start),
        fallback,
    )


def _say_vote(clips: list[Any], match: MatchSettings) -> None:
    """Say on stderr whether the avatar keeps to a voted action, and among which."""
    names = sorted({c.label_names[k] for c in clips for k in set(c.labels[c.labels >= 0])})
    if not (match.jumps and match.vote > 0):
        print("actions: no vote (the avatar jumps to the best windows alone)", file=sys.stderr)
    elif not names:
        print("actions: the library has no action labels: no vote", file=sys.stderr)
    else:
        print(
            f"actions: {len(names)} labelled ({', '.join(names)}); the avatar keeps to the "
            f"one the best windows of the last {match.vote} decisions voted for"
            + (
                f", or another whose window fits better at {1 + match.vote_margin:g} times "
                "its cost (--vote-margin)"
                if math.isfinite(match.vote_margin)
                else ""
            )
            + (
                ", each vote settled by an action classifier learned from the library "
                "(--no-classify: off)"
                if match.classify
                else ""
            )
            + " (--vote 0: off)",
            file=sys.stderr,
        )


def _clips(args: argparse.Namespace) -> list[Any]:
    """The library's clips, less those left out (``--leave-out``) and, unless
    ``--off-floor``, those whose feet leave the floor; said on stderr."""
    library = library_for(args)
    clips = [
        c for c in library.clips if not any(fnmatch.fnmatchcase(c.name, p) for p in args.leave_out)
    ]
    if args.leave_out:
        gone = sorted({c.name for c in library.clips} - {c.name for c in clips})
        print(f"left out as asked: {', '.join(gone) or 'nothing matched'}", file=sys.stderr)
    if not clips:
        raise ValueError(f"{library.root}: --leave-out leaves no clip")
    if not args.off_floor:
        clips, dropped = on_the_floor(clips)
        if dropped:
            print(
                f"left out {len(dropped)} clips whose feet leave the floor (--off-floor "
                f"keeps them): {', '.join(sorted(dropped))}",
                file=sys.stderr,
            )
        if not clips:
            raise SystemExit("mimic perform: every clip leaves the floor (use --off-floor)")
    return clips


def _graph_clips(graph: Any, clips: list[Any]) -> list[Any]:
    """The clips the graph joins (one skeleton: ``control.graph.select_clips``), saying on
    stderr, at every run, which clips of another skeleton it left out: the avatar can
    neither play nor be matched against them, so the bank leaves them out too."""
    kept = set(graph.clip_names)
    other = sorted(c.name for c in clips if c.name not in kept)
    if other:
        print(
            f"left out {len(other)} clip{'s' if len(other) > 1 else ''} of another skeleton "
            "(the graph joins the library's largest group of clips with the same joints): "
            f"{', '.join(other)}",
            file=sys.stderr,
        )
    return list(graph.clips_of(clips))


def _say_unreachable(graph: Any, no_jumps: bool) -> None:
    """Warn about clips mostly outside the graph's connected component."""
    unreachable = [
        f"{name} ({graph.in_scc[a:b].mean():.0%} reachable)"
        for name, a, b in zip(
            graph.clip_names, graph.clip_start[:-1], graph.clip_start[1:], strict=True
        )
        if graph.in_scc[a:b].mean() < 0.5
    ]
    if unreachable and no_jumps:
        print(
            "warning: these clips are mostly outside the graph's connected component, and "
            f"without jumps the avatar cannot reach them: {', '.join(unreachable)}",
            file=sys.stderr,
        )
    elif unreachable:
        print(
            "note: these clips are mostly outside the graph's connected component; the "
            f"avatar reaches them by direct jumps only: {', '.join(unreachable)}",
            file=sys.stderr,
        )


def _bank(args: argparse.Namespace, clips: list[Any], source: Any) -> tuple[str, Any, bool]:
    """The descriptor and the bank: ``--bank``'s (its own settings), else the cache's
    for the chosen descriptor (with ``--variants``, the robust settings)."""
    if args.bank:  # a bank built by mimic bank build, with its own settings
        try:
            bank, built = load_bank(args.bank, clips), False
        except StaleBankError as exc:
            problem = str(exc)[len(exc.path) + 2 :]  # the message without its path
            raise StaleBankError(
                exc.path,
                f"{problem}; perform matches against {len(clips)} clips ({clips[0].name}"
                f"..{clips[-1].name}, the clips off the floor left out unless --off-floor): "
                "build the bank from the same clips",
            ) from None
        descriptor = choose_descriptor(bank.settings.descriptor, source)
        print(f"descriptor: {descriptor} (the bank's, {args.bank})", file=sys.stderr)
        return descriptor, bank, built
    descriptor = choose_descriptor(args.descriptor, source)
    print(f"descriptor: {descriptor}", file=sys.stderr)
    base = BankSettings(descriptor=descriptor)
    if args.variants and descriptor == "pose":
        print("--variants: body variants do not apply to the pose descriptor", file=sys.stderr)
    bank_settings = robust_settings(base) if args.variants and descriptor != "pose" else base
    bank, built = ensure_bank(clips, bank_settings, progress=bar("silhouette bank", "renders"))
    return descriptor, bank, built


def silhouette_flag(args: argparse.Namespace) -> bool | None:
    return {"auto": None, "yes": True, "no": False}[args.silhouette_video]


def warn_source(source: Any) -> None:
    """Say so when a video ended before the frames its header declares."""
    why = source.truncated() if hasattr(source, "truncated") else ""
    if why:
        print(f"warning: {why}", file=sys.stderr)


def warn_own_take(video: str, clips: list[Any]) -> None:
    """Say so when a recording's own take is in the library: then its agreement is not
    that of a performer the library has never seen."""
    side = Path(video).with_name(Path(video).name + ".json")
    try:
        take = json.loads(side.read_text()).get("clip") if side.is_file() else None
    except (OSError, ValueError, AttributeError):
        return
    if take and any(c.name == take for c in clips):
        print(
            f"note: the recording is of {take}, which is in the library: this agreement is "
            f"not that of an unseen performer (--leave-out {take} measures one)"
        )


def print_actions(decisions: list[dict[str, Any]], clips: list[Any], most: int = 10) -> None:
    """What the avatar did: its actions over media time (an unlabelled clip by name)."""
    # from the avatar's start on (before the performer is first matched it idles, and
    # that motion is dropped)
    first = next((i for i, d in enumerate(decisions) if "located" in d), 0)
    runs = action_runs(decisions[first:], clips, min_seconds=0.5)
    if not runs:
        return
    shown = [f"{a:.1f}-{b:.1f} s {name}" for a, b, name in runs[:most]]
    more = f" ... and {len(runs) - most} more" if len(runs) > most else ""
    print("the avatar did: " + ", ".join(shown) + more)
