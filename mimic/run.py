"""What ``mimic perform`` and ``mimic evaluate`` share: the library, graph, layer and
bank made from their settings (``prepare``; the options and the settings made from them
are ``mimic.run_args``), and what they say about the source and the avatar's actions."""

from __future__ import annotations

import fnmatch
import json
import math
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from control.clusters import HigherLayer, cached_higher_layer
from control.graph import MotionGraph, cached_graph
from control.motion import Clip
from control.progress import bar, step
from silhouette_bank import (
    DEFAULT_DESCRIPTOR,
    Bank,
    BankSettings,
    StaleBankError,
    cached_bank,
    load_bank,
    robust_settings,
)
from vision import (
    INSTALL,
    ActionSettings,
    MaskFolderSource,
    MatchSettings,
    PerformSettings,
    Source,
    action_runs,
    on_the_floor,
    person_segmentation_available,
)

from .args import load_chosen, start_frame
from .run_args import RunSettings

__all__ = [
    "Prepared",
    "choose_descriptor",
    "prepare",
    "print_actions",
    "voice_bank",
    "warn_own_take",
    "warn_source",
]


def choose_descriptor(name: str, source: Source) -> str:
    """``"auto"`` made concrete for ``source``: ``pose`` where there are colour frames
    (a camera, a colour video) and MediaPipe is installed (it recognised far better than
    any silhouette descriptor: ``benchmarks/bench_recognition.py``), else the bank's
    default silhouette descriptor. A pose descriptor for a silhouette source is an
    error."""
    colour = _gives_colour(source)
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


def _gives_colour(source: Source) -> bool:
    """Whether ``source`` gives colour frames (a camera, a colour video), not silhouettes."""
    return not (isinstance(source, MaskFolderSource) or getattr(source, "silhouette", False))


@dataclass
class Prepared:
    """What a performance runs on, made from a ``RunSettings`` (``prepare``).

    Attributes
    ----------
    descriptor : str
        The descriptor chosen (``"auto"`` made concrete).
    clips : list of Clip
        The graph's clips: the library's, less those left out.
    graph : MotionGraph
    layer : HigherLayer
    bank : Bank
        The bank the performer is matched against.
    bank_built : bool
        Whether the bank was built now (else loaded).
    settings : PerformSettings
    start : int or None
        The graph frame the avatar starts at (``None``: where the performer is found).
    fallback : Bank or None
        With the pose descriptor, the silhouette bank matched where the landmarks fail.
    voice : Bank or None
        With a silhouette descriptor, the pose bank that scores the landmarks read from
        each silhouette (``vision._voice``).
    """

    descriptor: str
    clips: list[Clip]
    graph: MotionGraph
    layer: HigherLayer
    bank: Bank
    bank_built: bool
    settings: PerformSettings
    start: int | None
    fallback: Bank | None = None
    voice: Bank | None = None


def prepare(settings: RunSettings, source: Source) -> Prepared:
    """The library (the clips on the floor unless ``off_floor``), its graph, higher
    layer and bank for ``source``, saying on stderr what was chosen and what was left
    out."""
    chosen = _descriptor_of(settings, source)
    clips = _clips(settings, chosen)
    t0 = time.perf_counter()
    with step("motion graph"):
        pairs = bar("motion graph: frame pairs", "jobs")
        graph, _, _ = cached_graph(clips, settings.graph, rebuild=settings.rebuild, progress=pairs)
    clips = _graph_clips(graph, clips)
    match = settings.perform.match
    _say_unreachable(graph, not match.landing.jumps)
    with step("higher layer (clusters and trees)"):
        fits = bar("higher layer: mixture fits", "fits")
        trees = bar("higher layer: cluster trees", "trees")
        layer, _, layer_built = cached_higher_layer(
            graph, clips, settings.layer, progress=fits, trees=trees
        )
    print(
        f"library: {len(graph.clip_names)} clips, {graph.n_frames} frames "
        f"({int(graph.in_scc.sum())} reachable); graph coords {graph.options.coords}; "
        f"{layer.clustering.k} clusters ({'built' if layer_built else 'cached'}); "
        f"{'cluster trees built on first use (a dense graph); ' if layer.forest.lazy else ''}"
        f"{time.perf_counter() - t0:.1f} s",
        file=sys.stderr,
    )
    descriptor, bank, built = _bank(settings, clips, source, chosen)
    fallback = None
    fuse = settings.perform.match.action.fuse
    if descriptor == "pose" and settings.fallback:
        print(
            f"where the landmarks fail, the silhouette ({DEFAULT_DESCRIPTOR}) is matched "
            "(--no-fallback: no decision there)"
            + (
                "; where limbs are hidden, the landmarks' vote weighs it too (--no-fuse: off)"
                if fuse
                else ""
            ),
            file=sys.stderr,
        )
        fallback, _, _ = cached_bank(
            clips, BankSettings(), progress=bar("silhouette bank (fallback)", "silhouettes")
        )
    voice = _voice(settings, clips, source, bank)
    _say_vote(clips, match, bank.settings.features.kind, voice is not None)
    start = start_frame(graph, settings.start)
    return Prepared(
        descriptor, clips, graph, layer, bank, built, settings.perform, start, fallback, voice
    )


def _voice(settings: RunSettings, clips: list[Clip], source: Source, bank: Bank) -> Bank | None:
    """``voice_bank`` for a run on ``bank`` of ``source``, said on stderr."""
    if bank.settings.features.kind != "silhouette" or _gives_colour(source):
        return None  # (colour frames: the pose descriptor reads them itself)
    progress = bar("pose bank (voice)", "poses")
    voice = voice_bank(clips, settings.perform.match, progress)
    if voice is not None:
        print(
            "the silhouette's vote also weighs the landmarks the pose model reads from each "
            "silhouette (--no-fuse: the silhouette alone)",
            file=sys.stderr,
        )
    return voice


def voice_bank(
    clips: list[Clip], match: MatchSettings, progress: Callable[[int, int], None] | None = None
) -> Bank | None:
    """For a silhouette bank's run on a source of silhouettes with ``match``, the pose
    bank of ``clips`` that scores the landmarks the pose model reads from each silhouette
    (``vision._voice``); ``None`` without the fused ballot (``--no-fuse``) or MediaPipe."""
    if not match.action.fuse or not person_segmentation_available():
        return None
    return cached_bank(clips, BankSettings(descriptor="pose"), progress=progress)[0]


def _say_vote(clips: list[Clip], match: MatchSettings, kind: str, voice: bool) -> None:
    """Say on stderr whether the avatar keeps to a voted action, and among which (for a
    matcher of descriptor ``kind``; ``voice``: with the landmarks read from its
    silhouettes)."""
    names = sorted({c.label_names[k] for c in clips for k in set(c.labels[c.labels >= 0])})
    if not (match.landing.jumps and match.action.vote > 0):
        print("actions: no vote (the avatar jumps to the best windows alone)", file=sys.stderr)
    elif not names:
        print("actions: the library has no action labels: no vote", file=sys.stderr)
    else:
        print(
            f"actions: {len(names)} labelled ({', '.join(names)}); the avatar keeps to the "
            + _vote_phrase(match.action, kind, voice)
            + " (--vote 0: off)",
            file=sys.stderr,
        )


def _vote_phrase(a: ActionSettings, kind: str, voice: bool) -> str:
    """How the voted action is chosen (for a matcher of descriptor ``kind``, ``voice``:
    with the landmarks read from its silhouettes) and what else the avatar may jump
    into, in words."""
    switch = a.switch_for(kind, voice)
    if switch > 0:
        how = (
            f"one a hidden Markov filter of the last decisions believes in (a change "
            f"{switch:g} a decision, taken up at a belief of {a.confidence:g}; --vote-switch)"
        )
    else:
        how = f"one the best windows of the last {a.vote} decisions voted for"
    if math.isfinite(a.margin):
        other = "the one its latest ballot names" if switch > 0 and a.ballot_jumps else "another"
        if switch > 0 and a.ballot_jumps and a.repeat > 0:
            other += " (none while you go on with what you did: --repeat)"
        how += f", or {other} where its window fits better at {1 + a.margin:g} times its cost"
        if math.isfinite(a.weak_fit):
            weak = 1 + max(a.margin, a.weak_margin)
            how += f" ({weak:g} times where the best fits weakly, --weak-fit)"
        how += " (--vote-margin)"
    if a.classify:
        how += ", each vote settled by an action classifier learned from the library"
        how += " (--no-classify: off)"
    return how


def _descriptor_of(settings: RunSettings, source: Source) -> str:
    """The descriptor ``_bank`` will match with: ``--bank``'s (as its manifest says; a
    bank that cannot be read says so there), else the one chosen for ``source``."""
    if not settings.bank:
        return choose_descriptor(settings.descriptor, source)
    try:
        manifest = json.loads((Path(settings.bank) / "manifest.json").read_text("utf-8"))
        return str(manifest["settings"]["descriptor"])
    except (OSError, ValueError, KeyError, TypeError):
        return ""


def _clips(settings: RunSettings, descriptor: str) -> list[Clip]:
    """The library's clips for a bank of ``descriptor`` (its mirrored copies:
    ``mimic.args.mirror_copies``), less those left out (``--leave-out``: a clip left out
    takes its mirrored copy with it, which is the same performer) and, unless
    ``--off-floor``, those whose feet leave the floor; said on stderr."""
    library = load_chosen(settings.library, descriptor)
    out = settings.leave_out

    def left_out(c: Clip) -> bool:
        names = (c.name, c.name.removesuffix("_mirror")) if c.mirrored else (c.name,)
        return any(fnmatch.fnmatchcase(n, p) for n in names for p in out)

    clips = [c for c in library.clips if not left_out(c)]
    if out:
        gone = sorted({c.name for c in library.clips} - {c.name for c in clips})
        print(f"left out as asked: {', '.join(gone) or 'nothing matched'}", file=sys.stderr)
    if not clips:
        raise ValueError(f"{library.root}: --leave-out leaves no clip")
    if not settings.off_floor:
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


def _graph_clips(graph: MotionGraph, clips: list[Clip]) -> list[Clip]:
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


def _say_unreachable(graph: MotionGraph, no_jumps: bool, most: int = 8) -> None:
    """Warn about clips mostly outside the graph's connected component (``most`` of them
    named: a large library's would fill the screen)."""
    unreachable = [
        f"{name} ({graph.in_scc[a:b].mean():.0%} reachable)"
        for name, a, b in zip(
            graph.clip_names, graph.clip_start[:-1], graph.clip_start[1:], strict=True
        )
        if graph.in_scc[a:b].mean() < 0.5
    ]
    if not unreachable:
        return
    named = ", ".join(unreachable[:most])
    if len(unreachable) > most:
        named += f" ... and {len(unreachable) - most} more"
    some = f"{len(unreachable)} of {len(graph.clip_names)} clips are"
    if no_jumps:
        print(
            f"warning: {some} mostly outside the graph's connected component, and without "
            f"jumps the avatar cannot reach them: {named}",
            file=sys.stderr,
        )
    else:
        print(
            f"note: {some} mostly outside the graph's connected component; the avatar "
            f"reaches them by direct jumps only: {named}",
            file=sys.stderr,
        )


def _bank(
    settings: RunSettings, clips: list[Clip], source: Source, chosen: str
) -> tuple[str, Bank, bool]:
    """The descriptor and the bank: ``--bank``'s (its own settings), else the cache's
    for the ``chosen`` descriptor (``_descriptor_of``; with ``--variants``, the robust
    settings)."""
    if settings.bank:  # a bank built by mimic bank build, with its own settings
        try:
            bank, built = load_bank(settings.bank, clips), False
        except StaleBankError as exc:
            problem = str(exc)[len(exc.path) + 2 :]  # the message without its path
            raise StaleBankError(
                exc.path,
                f"{problem}; perform matches against {len(clips)} clips ({clips[0].name}"
                f"..{clips[-1].name}, the clips off the floor left out unless --off-floor): "
                "build the bank from the same clips",
            ) from None
        descriptor = choose_descriptor(bank.settings.descriptor, source)
        print(f"descriptor: {descriptor} (the bank's, {settings.bank})", file=sys.stderr)
        return descriptor, bank, built
    descriptor = chosen
    print(f"descriptor: {descriptor}", file=sys.stderr)
    base = BankSettings(descriptor=descriptor)
    if settings.variants and descriptor == "pose":
        print("--variants: body variants do not apply to the pose descriptor", file=sys.stderr)
    bank_settings = robust_settings(base) if settings.variants and descriptor != "pose" else base
    rendered = bar("silhouette bank", "silhouettes")
    bank, _, built = cached_bank(clips, bank_settings, progress=rendered)
    return descriptor, bank, built


def warn_source(source: Source) -> None:
    """Say so when a video ended before the frames its header declares."""
    why = source.truncated() if hasattr(source, "truncated") else ""
    if why:
        print(f"warning: {why}", file=sys.stderr)


def warn_own_take(video: str, clips: list[Clip]) -> None:
    """Say so when a recording's own take is in the library: then its agreement is not
    that of a performer the library has never seen."""
    side = Path(video).with_name(Path(video).name + ".json")
    try:
        take = json.loads(side.read_text()).get("clip") if side.is_file() else None
    except (OSError, ValueError, AttributeError):
        return
    if take and any(c.name in (take, f"{take}_mirror") for c in clips):
        print(
            f"note: the recording is of {take}, which is in the library: this agreement is "
            f"not that of an unseen performer (--leave-out {take} measures one)"
        )


def print_actions(decisions: list[dict[str, Any]], clips: list[Clip], most: int = 10) -> None:
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
