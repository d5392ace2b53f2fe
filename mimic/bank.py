"""``mimic bank ...``: build, inspect and look at the silhouette bank."""

from __future__ import annotations

import argparse
import json
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from control.jobs import cluster_address
from control.motion import Library
from control.progress import bar
from silhouette_bank import (
    DEFAULT_DESCRIPTOR,
    DESCRIPTORS,
    BankSettings,
    BodyShape,
    CameraRing,
    cached_bank,
    capsule_body,
    ensure_bank,
    load_bank,
    motion_silhouettes,
)

from .args import add_library_args, library_choice, load_chosen, number

__all__ = ["add_bank_args", "add_bank_commands", "bank_settings", "contact_sheet"]


def add_bank_args(p: argparse.ArgumentParser) -> None:
    """The library (with ``mimic perform``'s mirrored copies for a pose bank, so that a
    bank built here is the one it matches against), ``--bank`` and the bank's settings
    (camera ring, body, renderer, descriptor)."""
    add_library_args(p, mirror="auto")
    d = CameraRing()
    p.add_argument("--bank", help="bank folder (default: the cache, by content hash)")
    p.add_argument(
        "--width", type=number(int, 16, 4096), default=d.width, help="image width, pixels"
    )
    p.add_argument(
        "--height", type=number(int, 16, 4096), default=d.height_px, help="image height, pixels"
    )
    p.add_argument(
        "--views", type=number(int, 1, 360), default=d.n_views, help="cameras on the ring"
    )
    p.add_argument(
        "--distance",
        type=number(float, 0, 1000, above=True),
        default=d.distance,
        help="camera distance, m",
    )
    p.add_argument(
        "--camera-height", type=number(float, -100, 100), default=d.height, help="camera height, m"
    )
    p.add_argument(
        "--target-height",
        type=number(float, -100, 100),
        default=d.target_height,
        help="look-at height, m",
    )
    p.add_argument(
        "--fov",
        type=number(float, 0, 179, above=True),
        default=d.fov_y,
        help="vertical field of view, degrees",
    )
    p.add_argument(
        "--body-width",
        type=number(float, 0, 10, above=True),
        default=1.0,
        help="radius scale of the body",
    )
    p.add_argument(
        "--body-height",
        type=number(float, 0, 10, above=True),
        default=1.0,
        help="height scale of the body",
    )
    p.add_argument(
        "--renderer",
        choices=("raster", "gl"),
        default="raster",
        help="numba capsule rasterizer (default) or pyrender",
    )
    p.add_argument(
        "--descriptor",
        choices=DESCRIPTORS,
        default=DEFAULT_DESCRIPTOR,
        help="outline (default: the multigrid's cells and how far the silhouette reaches "
        "left and right in 16 row bands), multigrid (16x8, 8x4 and 4x2 grids of cells over "
        "the silhouette), grid (8x4 cells), hu (7 Hu moments) or pose (the joints "
        "projected, for landmark matching)",
    )


def bank_settings(args: argparse.Namespace) -> BankSettings:
    ring = CameraRing(
        n_views=args.views,
        distance=args.distance,
        height=args.camera_height,
        target_height=args.target_height,
        fov_y=args.fov,
        width=args.width,
        height_px=args.height,
    )
    return BankSettings(
        ring,
        BodyShape(args.body_width, args.body_height),
        args.renderer,
        descriptor=args.descriptor,
    )


def add_bank_commands(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    bank = sub.add_parser("bank", help="the silhouette bank (every frame from 18 views)")
    bsub = bank.add_subparsers(dest="bank_command", required=True)
    build = bsub.add_parser(
        "build",
        help="render every library frame from every view and store the features",
        description="Built in shards (parallel, resumable); a stale bank is rebuilt.",
    )
    add_bank_args(build)
    build.add_argument(
        "--workers", type=number(int, 1, 1024), default=None, help="processes (default: cores)"
    )
    build.add_argument(
        "--shard-frames", type=number(int, 1, 10**8), default=1000, help="frames per shard"
    )
    build.add_argument(
        "--cluster",
        default=None,
        help="render on a Dask cluster: a scheduler's address (tcp://host:8786) or local:N "
        "(N worker processes here); default $MIMIC_CLUSTER, else this machine's --workers",
    )
    build.set_defaults(func=_build)
    info = bsub.add_parser("info", help="what a bank holds and how it was made")
    info.add_argument("folder", help="bank folder")
    info.add_argument("--json", action="store_true")
    info.set_defaults(func=_info)
    show = bsub.add_parser("show", help="a PNG contact sheet of one frame's silhouettes")
    show.add_argument("frame", help="CLIP:FRAME (library frame at --fps)")
    add_bank_args(show)
    show.add_argument("--out", required=True, help="PNG to write")
    show.set_defaults(func=_show)


def _library(args: argparse.Namespace) -> Library:
    """The library of the bank's arguments (``--mirror auto``: ``perform``'s for the
    bank's descriptor)."""
    return load_chosen(library_choice(args), args.descriptor)


def _build(args: argparse.Namespace) -> int:
    cluster_address(args.cluster)  # a bad address is said before the library loads
    library = _library(args)
    settings = bank_settings(args)
    options = {
        "shard_frames": args.shard_frames,
        "workers": args.workers,
        "progress": bar("silhouette bank", "silhouettes", quiet_s=0.0),
        "cluster": args.cluster,
    }
    if args.bank:  # a folder of the user's
        bank, built = ensure_bank(library.clips, settings, args.bank, **options)
    else:
        bank, _, built = cached_bank(library.clips, settings, **options)
    how = "built" if built else "up to date"
    print(
        f"bank {bank.path} ({how}): {bank.n_frames} frames x {settings.ring.n_views} views, "
        f"{settings.ring.width}x{settings.ring.height_px}, renderer {settings.renderer}"
    )
    return 0


def _info(args: argparse.Namespace) -> int:
    path = Path(args.folder)
    manifest: dict[str, Any] = (
        json.loads((path / "manifest.json").read_text())
        if (path / "manifest.json").is_file()
        else {}
    )
    if not manifest:
        raise FileNotFoundError(f"no bank at {path} (no manifest.json)")
    bank = load_bank(path)
    f = bank.features
    summary: dict[str, Any] = {
        "folder": str(path),
        "frames": bank.n_frames,
        "views": int(f.shape[1]),
        "clips": len(bank.clip_names),
        "settings": bank.settings.to_dict(),
        "library_digest": bank.library_digest[:16],
        "empty_silhouettes": int(np.isnan(f[..., 0]).sum()),
        "built": manifest.get("built"),
        "bytes": sum(p.stat().st_size for p in path.iterdir() if p.is_file()),
    }
    if args.json:
        print(json.dumps(summary, indent=2))
        return 0
    ring = summary["settings"]["ring"]
    print(
        f"bank {path}: {summary['frames']} frames of {summary['clips']} clips x "
        f"{summary['views']} views, {ring['width']}x{ring['height_px']}, camera "
        f"{ring['distance']} m away at {ring['height']} m, fov {ring['fov_y']} deg, body "
        f"{summary['settings']['body']}, renderer {summary['settings']['renderer']}; "
        f"{summary['empty_silhouettes']} empty silhouettes; {summary['bytes'] / 1e6:.1f} MB"
    )
    return 0


def contact_sheet(masks: np.ndarray, cols: int = 6) -> np.ndarray:
    """Masks ``(V, H, W)`` tiled into one image (white silhouettes, grey borders)."""
    v, h, w = masks.shape
    rows = (v + cols - 1) // cols
    sheet = np.full((rows * (h + 2), cols * (w + 2)), 64, dtype=np.uint8)
    for i in range(v):
        r, c = divmod(i, cols)
        sheet[r * (h + 2) + 1 : r * (h + 2) + 1 + h, c * (w + 2) + 1 : c * (w + 2) + 1 + w] = (
            masks[i] * 255
        )
    return sheet


def _show(args: argparse.Namespace) -> int:
    library = _library(args)
    settings = bank_settings(args)
    clip_name, _, frame = args.frame.rpartition(":")
    if not clip_name or not frame.isdigit():
        raise ValueError(f"FRAME must be CLIP:FRAME, not {args.frame!r}")
    clip = library.clip(clip_name)
    f = int(frame)
    if not 0 <= f < clip.motion.n_frames:
        raise ValueError(f"clip {clip_name} has no frame {f} (it has {clip.motion.n_frames})")
    body = capsule_body(clip.motion.skeleton, settings.body)
    if settings.renderer == "gl":
        from silhouette_bank import GLRenderer, gl_silhouettes

        with GLRenderer(settings.ring) as gl:
            masks = gl_silhouettes(gl, clip.motion, body, settings.ring, np.array([f]))[0]
    else:
        masks = motion_silhouettes(clip.motion, body, settings.ring, np.array([f]))[0]
    sheet = contact_sheet(masks)
    out = Path(args.out)
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp.png")
    if not cv2.imwrite(str(tmp), sheet):
        raise OSError(f"could not write {out}")
    tmp.replace(out)
    print(f"wrote {out}: {clip_name} frame {f}, {masks.shape[0]} views")
    return 0
