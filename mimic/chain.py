"""``mimic chain``: named actions in order, with synthesized transitions (Peng et al.)."""

from __future__ import annotations

import argparse
import time

import numpy as np

from control.motion import load_library, write_bvh
from control.progress import step
from control.transition import Chainer
from silhouette_bank import MP4_FOURCC

from .args import add_library_dir, library_dir, number
from .outputs import check_outputs

__all__ = ["add_chain_command"]


def add_chain_command(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "chain",
        help="play named actions in order with synthesized transitions, write BVH",
        description="ACTION is CLIP, CLIP:FROM-TO (seconds) or label:NAME (from labels/*.csv), "
        "or a parametric action REF@[EFFECTOR=]X,Y,Z: the library's examples of the action "
        "REF (found by DTW) blended so that EFFECTOR (a joint role, default right_wrist at "
        "the action's apex; root: where the action ends on the floor, Y ignored) reaches "
        "X,Y,Z metres in the avatar's frame where the action begins (x left, y up, z "
        "forward), e.g. 02_05:6.67-7.6@0.45,1.3,0.55; REF@turn=DEGREES turns the avatar "
        "by DEGREES (left when positive) by the action's end. Transitions follow candidate "
        "paths of the cluster transition graph, or a Bezier interpolation when no path "
        "exists.",
    )
    p.add_argument("actions", nargs="+", metavar="ACTION")
    add_library_dir(p, positional=False)  # ACTION... takes the positionals
    p.add_argument("--clips", action="append", metavar="PATTERN", help="only these clips")
    p.add_argument("--fps", type=number(float, 0, 240, above=True), default=15.0)
    p.add_argument(
        "--cluster-sigmas",
        type=number(float, 0, 1000, above=True),
        default=10.0,
        help="cluster radius of the two-pass clustering, in sigmas (sketch's --radius is "
        "metres: another thing)",
    )
    p.add_argument(
        "--blend",
        type=number(float, 0, 10, above=True),
        default=0.5,
        help="junction blend, seconds",
    )
    p.add_argument("--seed", type=number(int, 0, 2**32 - 1), default=0)
    p.add_argument("--undirected", action="store_true", help="also play transition clips backwards")
    p.add_argument(
        "--fallback",
        choices=("bezier", "linear"),
        default="bezier",
        help="interpolation where no path exists (default bezier)",
    )
    p.add_argument(
        "--example-cost",
        type=number(float, 0, 100, above=True),
        default=0.5,
        help="a parametric action's examples: at most this share of the library's "
        "background DTW cost (default 0.5)",
    )
    p.add_argument("--out", required=True, help="BVH file to write")
    p.add_argument("--video", help="also an MP4 of the avatar (shaded, camera following)")
    p.set_defaults(func=_chain)


def _chain(args: argparse.Namespace) -> int:
    outputs = check_outputs(args, ["--out", "--video"], videos={"--video": MP4_FOURCC})
    library = load_library(library_dir(args), fps=args.fps, clips=args.clips)
    t0 = time.perf_counter()
    with step("action clusters and transitions (two-pass clustering)"):
        chainer = Chainer(
            library.clips,
            radius=args.cluster_sigmas,
            blend=args.blend,
            seed=args.seed,
            fallback=args.fallback,
            directed=not args.undirected,
            example_cost=args.example_cost,
        )
    t1 = time.perf_counter()
    result = chainer.chain(args.actions)
    t2 = time.perf_counter()
    with outputs:  # the BVH and its video replaced together, or neither
        out, video = outputs.find("--out"), outputs.find("--video")
        assert out is not None
        outputs.write(out, lambda p: write_bvh(result.motion, p))
        if video is not None:
            from silhouette_bank import render_motion_video

            outputs.write(video, lambda p: render_motion_video(result.motion, p))
        outputs.commit()
    pieces = ", ".join(f"{name}@{start / chainer.fps:.1f}s" for name, start in result.pieces)
    print(
        f"wrote {args.out}: {result.motion.n_frames / chainer.fps:.1f} s ({pieces}); "
        f"{chainer.clusters.k} clusters, preprocess {t1 - t0:.2f} s, synthesis "
        f"{(t2 - t1) / result.motion.n_frames * 1e3:.3f} ms per frame"
    )
    for name, blend in result.blends:
        used = int(np.sum(blend.weights > 0.01))
        note = " (the target was outside the examples' reach: clamped into their hull)"
        if "@turn=" in name:
            got = f"turned {blend.reached[0]:.1f} degrees, asked {blend.target[0]:.1f}"
        else:
            off = float(np.linalg.norm(blend.reached - blend.target)) * 100
            got = (
                f"the effector at ({', '.join(f'{x:.2f}' for x in blend.reached)}), {off:.1f} "
                f"cm from ({', '.join(f'{x:.2f}' for x in blend.target)})"
            )
        print(
            f"{name}: a blend of {used} of {blend.weights.size} examples; {got}"
            + (note if blend.clamped else "")
        )
    return 0
