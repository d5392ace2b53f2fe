"""The argument groups the subcommands share: the library folder, the library and graph
options, the blend and a start frame, and what they make (the options, the graph)."""

from __future__ import annotations

import argparse
import math
import os
import sys
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from control.graph import CONTACT_RULES, COORDS, GraphOptions, MotionGraph, cached_graph
from control.motion import (
    EMBEDDED_LIBRARY,
    Library,
    default_library_path,
    load_library,
)
from control.progress import bar, step

__all__ = [
    "MOST_MOTION_SECONDS",
    "MOST_SECONDS",
    "LibraryChoice",
    "add_graph_args",
    "add_library_args",
    "add_library_dir",
    "blend_seconds",
    "graph_for",
    "graph_options",
    "library_choice",
    "library_dir",
    "library_for",
    "load_chosen",
    "mirror_copies",
    "number",
    "start_frame",
]

#: the longest media time a performance may be told to stop after, seconds (a day)
MOST_SECONDS = 86400.0
#: the longest motion a command may be asked to make, seconds (an hour: 54,000 frames
#: at 15 frames/s; ``graph walk --seconds 1e12`` asked numpy for 109 TiB)
MOST_MOTION_SECONDS = 3600.0


def number(
    kind: type[int] | type[float] = float,
    lo: float | None = None,
    hi: float | None = None,
    *,
    above: bool = False,
    inf: bool = False,
) -> Callable[[str], float]:
    """An argparse ``type`` for a numeric option: a ``kind`` (``int``: a whole number)
    that is finite (``inf``: or infinite, where that means "no limit"), at least ``lo``
    (``above``: more than ``lo``) and at most ``hi``. A value outside is refused by
    argparse with the option's name: ``argument --window: must be a number above 0 and
    at most 10, not 'nan'``. The one check every subcommand's numbers go through."""
    noun = "a whole number" if kind is int else "a number"
    if lo is not None and hi is not None and not above:
        wanted = f"{noun} from {lo:g} to {hi:g}"
    else:
        parts = [f"{'above' if above else 'at least'} {lo:g}"] if lo is not None else []
        parts += [f"at most {hi:g}"] if hi is not None else []
        wanted = " ".join([noun, " and ".join(parts)]).strip()
    wanted += " (or inf: no limit)" if inf else ""

    def parse(text: str) -> float:
        try:
            value = kind(text)
        except (TypeError, ValueError):
            raise argparse.ArgumentTypeError(f"must be {wanted}, not {text!r}") from None
        if inf and value == math.inf:
            return value
        bad = (
            not math.isfinite(value)
            or (lo is not None and (value < lo or (above and value == lo)))
            or (hi is not None and value > hi)
        )
        if bad:
            raise argparse.ArgumentTypeError(f"must be {wanted}, not {text!r}")
        return value

    parse.__name__ = noun  # (argparse names the type in some messages)
    return parse


def add_library_dir(p: argparse.ArgumentParser, positional: bool = True) -> None:
    """The library folder, given as ``--library DIR`` in every subcommand (and, where the
    command takes no other positional list, as its last positional argument too); read
    it with ``library_dir(args)``."""
    where = "default: $MIMIC_MOCAP, else ../shared/mocap, else the embedded library"
    if positional:
        p.add_argument("dir", nargs="?", default=None, help=f"library folder ({where})")
    p.add_argument("--library", default=None, metavar="DIR", help=f"library folder ({where})")


def library_dir(args: argparse.Namespace) -> str | None:
    """The library folder of ``add_library_dir``'s arguments (``None``: the default)."""
    pos, opt = getattr(args, "dir", None), getattr(args, "library", None)
    if pos is not None and opt is not None and Path(pos) != Path(opt):
        raise ValueError(f"two library folders given: {pos} and --library {opt}")
    return opt if opt is not None else pos


#: ``--mirror``'s choices: no mirrored copies, copies of the labelled clips, of every
#: clip, or (``auto``: ``perform``'s and ``bank build``'s default) the labelled clips'
#: where the descriptor is the pose one (``mirror_copies``)
MIRRORS = ("none", "labelled", "all", "auto")


def add_library_args(p: argparse.ArgumentParser, mirror: str = "none") -> None:
    """The library folder, ``--clips``, ``--fps`` and ``--mirror`` (whose default is
    ``mirror``)."""
    add_library_dir(p)
    p.add_argument(
        "--clips",
        action="append",
        metavar="PATTERN",
        help="only clips whose name matches (shell pattern, repeatable): --clips '01_*'",
    )
    p.add_argument(
        "--fps",
        type=number(float, 0, 240, above=True),
        default=15.0,
        help="library frame rate (default 15)",
    )
    p.add_argument(
        "--mirror",
        nargs="?",
        const="all",
        default=mirror,
        choices=MIRRORS if mirror == "auto" else MIRRORS[:3],
        help="add left/right mirrored copies of the clips: labelled (those with labels), "
        + (
            "all (--mirror alone), none, or auto (the labelled clips' where landmarks are matched)"
            if mirror == "auto"
            else "all (--mirror alone) or none"
        )
        + f" (default {mirror})",
    )


def add_graph_args(p: argparse.ArgumentParser) -> None:
    """The graph options (``GraphOptions``) and ``--blend``, ``--rebuild``."""
    d = GraphOptions()
    p.add_argument(
        "--coords", choices=COORDS, default=d.coords, help="root coordinates (default fixed)"
    )
    p.add_argument(
        "--contact",
        choices=CONTACT_RULES,
        default=d.contact,
        help="contact pruning rule (default loose)",
    )
    sim = p.add_mutually_exclusive_group()
    sim.add_argument(
        "--similarity",
        dest="similarity",
        action="store_true",
        default=None,
        help="keep only local maxima (default: on unless --contact strict)",
    )
    sim.add_argument("--no-similarity", dest="similarity", action="store_false")
    p.add_argument(
        "--threshold",
        type=number(float, 0, 1000),
        default=d.threshold,
        help=f"likelihood threshold relative to playing on (default {d.threshold})",
    )
    p.add_argument(
        "--sigma-scale",
        type=number(float, 0, 1000, above=True),
        default=d.sigma_scale,
        help="sigma = this x the median distance between frames 1/15 s apart",
    )
    p.add_argument(
        "--nu",
        type=number(float, 0, 1000),
        default=d.nu,
        help=f"velocity weight, s^2 (default {d.nu})",
    )
    p.add_argument(
        "--block",
        type=number(float, 0, 1000, above=True),
        default=d.block,
        help="terrain block size, metres",
    )
    p.add_argument(
        "--case4",
        choices=("slip", "prune"),
        default=d.case4,
        help="transitions whose blend a foot contact spans: keep and let the foot slip "
        "(default) or prune them",
    )
    p.add_argument(
        "--blend",
        type=number(float, 0, 10, above=True),
        default=None,
        help=f"blend interval b, seconds, of the avatar's transitions and jumps (default "
        f"{d.blend:g}; perform 0.5; sketch on block terrain 0.3); with --case4 prune also "
        "the interval the pruning assumes",
    )
    p.add_argument("--rebuild", action="store_true", help="ignore a cached graph")


def add_offer_args(p: argparse.ArgumentParser, most: int) -> None:
    """The choice interface's ``--k``, ``--options`` (at most ``most``) and
    ``--lookahead`` (``mimic choose``, ``mimic play``)."""
    p.add_argument(
        "--k", type=number(int, 1, 10000), help="number of clusters (default: chosen by BIC)"
    )
    p.add_argument(
        "--options", type=number(int, 1, most), default=4, help="actions offered (default 4)"
    )
    p.add_argument(
        "--lookahead",
        type=number(float, 0, 3600),
        default=6.0,
        help="offer clusters reached within this many seconds (0: the whole tree)",
    )


def graph_options(args: argparse.Namespace) -> GraphOptions:
    """The ``GraphOptions`` of ``add_graph_args``'s arguments."""
    return GraphOptions(
        coords=args.coords,
        contact=args.contact,
        similarity=args.similarity,
        nu=args.nu,
        sigma_scale=args.sigma_scale,
        threshold=args.threshold,
        block=args.block,
        case4=args.case4,
        # only pruning reads the blend: elsewhere it must not change the graph's cache key
        blend=blend_seconds(args) if args.case4 == "prune" else GraphOptions().blend,
    )


def blend_seconds(args: argparse.Namespace, default: float | None = None) -> float:
    """``--blend``, else ``default``, else the graph options' default (1 s)."""
    if args.blend is not None:
        if not (args.blend > 0 and np.isfinite(args.blend)):
            raise ValueError(f"--blend must be positive seconds, not {args.blend}")
        return float(args.blend)
    return GraphOptions().blend if default is None else default


@dataclass(frozen=True)
class LibraryChoice:
    """Which library: its ``folder`` (``None``: the default), the frame rate ``fps`` it
    is read at, which clips' mirrored copies are added (``mirror``: one of ``MIRRORS``),
    and which ``clips``
    (shell patterns; ``None``: every clip)."""

    folder: str | None
    fps: float
    mirror: str
    clips: tuple[str, ...] | None


def library_choice(args: argparse.Namespace) -> LibraryChoice:
    """The ``LibraryChoice`` of ``add_library_args``'s arguments."""
    if args.fps is None or args.fps <= 0:
        raise ValueError("--fps must be positive")
    clips = tuple(args.clips) if args.clips else None
    return LibraryChoice(library_dir(args), float(args.fps), args.mirror, clips)


def mirror_copies(mirror: str, descriptor: str = "") -> bool | str:
    """``load_library``'s ``mirror`` for ``--mirror``'s value (one of ``MIRRORS``) with a
    bank of ``descriptor``. ``auto`` is the labelled clips' copies for landmarks (a
    performer may lead with the other arm or leg, and a pose model reading someone from
    behind takes their left for their right) and none otherwise: silhouettes already read
    the performer as seen and mirrored, and a mirrored library lets the avatar do the
    mirror image of their pose."""
    if mirror == "auto":
        mirror = "labelled" if descriptor == "pose" else "none"
    return {"none": False, "all": True}.get(mirror, mirror)


def load_chosen(choice: LibraryChoice, descriptor: str = "") -> Library:
    """The library ``choice`` names, for a bank of ``descriptor`` (``mirror_copies``),
    saying on stderr when it is the embedded one."""
    unset = choice.folder is None and not os.environ.get("MIMIC_MOCAP")
    if unset and default_library_path() == EMBEDDED_LIBRARY:  # (nothing else found)
        print(
            f"motion library: the embedded default library ({EMBEDDED_LIBRARY}): no "
            "$MIMIC_MOCAP and no ../shared/mocap (pass a folder for your own mocap)",
            file=sys.stderr,
        )
    clips = list(choice.clips) if choice.clips else None
    with step("motion library"):
        mirror = mirror_copies(choice.mirror, descriptor)
        return load_library(choice.folder, fps=choice.fps, mirror=mirror, clips=clips)


def library_for(args: argparse.Namespace) -> Library:
    """The library of ``add_library_args``'s arguments."""
    return load_chosen(library_choice(args))


def graph_for(
    args: argparse.Namespace,
    library: Library | None = None,
    options: GraphOptions | None = None,
) -> tuple[Library, MotionGraph, Path, bool]:
    """The library (``library_for``, unless given) and its cached graph with ``options``
    (``graph_options(args)``, unless given): ``(library, graph, cache path, built)``."""
    options = options or graph_options(args)
    library = library or library_for(args)
    with step("motion graph"):
        graph, path, built = cached_graph(
            library.clips,
            options,
            rebuild=args.rebuild,
            cluster=getattr(args, "cluster", None),
            progress=bar("motion graph: frame pairs", "jobs"),
        )
    return library, graph, path, built


def start_frame(graph: MotionGraph, text: str | None) -> int | None:
    """The graph frame of a ``--start CLIP:FRAME`` argument (``None`` when not given)."""
    if not text:
        return None
    clip, _, frame = text.rpartition(":")
    if not clip or not frame.isdigit():
        raise ValueError(f"--start must be CLIP:FRAME, not {text!r}")
    return graph.frame_of(clip, int(frame))
