"""Parametric actions (issue 22, Peng et al. §6): how close a blend gets to its target.

Usage: python -m benchmarks.bench_parametric [LIBRARY_DIR] [--targets 60] [--out FILE]

On the default library, for each hand-picked reference (a strike of 02_05, the right
wrist at its apex; a forward jump of 01_01, where the root lands; a turning step of the
walk 03_04, the angle turned): the examples found, and over ``--targets`` random targets
inside their hull (a random convex mix of three examples' parameters, seed 0) the
effector's distance from the target at the key frame (cm; degrees for the turn) for the
default solve, the voxels, plain inverse-distance weights and the nearest single
example; at the examples' own parameters; the time of a request (the blend of every
frame, its contacts planted) against the paper's 0.561 s for 233 frames; the blends'
foot slide and largest per-frame joint change against the raw examples'; and a picture
of the avatar's three strikes chained, each at its apex with its target.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import Any

import numpy as np

from benchmarks._report import machine, save
from control.graph import foot_slide, joint_jumps
from control.motion import Motion, default_library_path, detect_contacts, load_library
from control.transition import Chainer, ParametricAction

REFERENCES = (
    ("strike", "02_05:6.67-7.6", "right_wrist", "apex"),
    ("jump", "01_01:3.2-4.3", "root", "end"),
    ("turn", "03_04:7.8-8.8", "turn", "end"),  # a turning step of a walk: degrees
)
HERE = Path(__file__).resolve().parent


def _cm(x: list[float], scale: float = 100.0) -> dict[str, float]:
    a = np.asarray(x) * scale
    return {"mean": round(float(a.mean()), 2), "p90": round(float(np.percentile(a, 90)), 2),
            "max": round(float(a.max()), 2)}  # fmt: skip


def _quality(motions: list[Motion]) -> dict[str, float]:
    slide = np.concatenate([foot_slide(m, detect_contacts(m).states) for m in motions])
    jumps = np.concatenate([joint_jumps(m) for m in motions])
    return {
        "foot_slide_m_per_s": round(float(slide.mean()), 4) if slide.size else 0.0,
        "largest_joint_jump_deg": round(float(jumps.max()), 2),
        "joint_jump_p99_deg": round(float(np.percentile(jumps, 99)), 2),
    }


def _one(ch: Chainer, spec: str, effector: str, key: str, n: int) -> dict[str, Any]:
    ref = ch.action(spec)
    t0 = time.perf_counter()
    model = ParametricAction(
        ch.feat, ch.root, ch.quats, ch.skeleton, ch.fps, (ref.start, ref.stop), effector, key
    )
    built = time.perf_counter() - t0
    names = [c.name for c in ch.clips]
    where = np.searchsorted(ch.feat.clip_start, [e.start for e in model.examples], "right") - 1
    rng = np.random.default_rng(0)
    errs: dict[str, list[float]] = {
        "solve": [],
        "voxels": [],
        "inverse_distance": [],
        "nearest": [],
    }
    times: dict[str, list[float]] = {"solve": [], "voxels": []}
    blends = []
    for _ in range(n):
        pick = rng.choice(len(model.params), 3, replace=False)
        target = rng.dirichlet(np.ones(3)) @ model.params[pick]
        for how in ("solve", "voxels"):
            t = time.perf_counter()
            got = model.request(target, voxels=how == "voxels")
            times[how].append(time.perf_counter() - t)
            errs[how].append(float(np.linalg.norm(got.reached - target)))
            if how == "solve":
                blends.append(got.motion)
        d2 = np.sum((model.params - target) ** 2, axis=1)
        errs["inverse_distance"].append(
            float(np.linalg.norm(model.reached((1 / d2) / np.sum(1 / d2)) - target))
        )
        errs["nearest"].append(float(np.sqrt(d2.min())))
    own = [float(np.linalg.norm(model.request(p).reached - p)) for p in model.params]
    raw = [Motion(ch.skeleton, r, q, ch.fps) for r, q in zip(model.roots, model.quats, strict=True)]
    frames = model.roots.shape[1]
    unit, scale = ("deg", 1.0) if effector == "turn" else ("cm", 100.0)
    return {
        "reference": spec,
        "effector": effector,
        "key_frame": model.key,
        "frames": frames,
        "examples": [
            {
                "clip": names[c],
                "from_s": round((e.start - ch.feat.clip_start[c]) / ch.fps, 2),
                "cost": round(e.cost, 3),
            }
            for e, c in zip(model.examples, where, strict=True)
        ],
        "model_seconds": round(built, 3),
        "targets_inside_hull": n,
        # (a turn's parameter is in degrees, not metres)
        f"error_{unit}": {k: _cm(v, scale) for k, v in errs.items()},
        f"error_{unit}_at_own_parameters_max": round(max(own) * scale, 6),
        "request_ms": {
            k: {
                "p50": round(float(np.median(v)) * 1e3, 2),
                "p99": round(float(np.percentile(v, 99)) * 1e3, 2),
            }
            for k, v in times.items()
        },
        "request_ms_per_frame_p50": round(float(np.median(times["solve"])) * 1e3 / frames, 3),
        "blends": _quality(blends),
        "raw_examples": _quality(raw),
    }


def _picture(ch: Chainer, out: Path) -> dict[str, Any]:
    """The three strikes chained: the chain's frame at each blend's apex, with the target
    (red: the action frame's target placed where the chain put the blend) and the wrist
    (green), seen from the avatar's right."""
    import cv2

    from control.graph import rotate_y, yaw_of
    from control.motion import forward_kinematics, role_point
    from silhouette_bank import CameraRing, shaded_frames

    targets = [(0.45, 1.3, 0.55), (0.3, 1.55, 0.45), (0.55, 1.0, 0.6)]
    acts = [ch.action(f"{REFERENCES[0][1]}@{t[0]},{t[1]},{t[2]}") for t in targets]
    result = ch.chain(acts)
    assert result.played is not None
    model = next(m for k, m in ch._models.items() if k[2] == "right_wrist")
    k = model.key
    kind, j = role_point(ch.skeleton, "right_wrist")
    pose = forward_kinematics(result.motion)
    wrist = (pose.positions if kind == "joint" else pose.end_positions)[:, j]
    ring = CameraRing(n_views=4, width=320, height_px=240, distance=3.0)
    tiles, report = [], []
    for act in acts:
        assert act.blend is not None
        hit = np.flatnonzero(result.played == act.start + k)
        if hit.size == 0:
            report.append({"target": act.blend.target.tolist(), "apex_played": False})
            continue
        f = int(hit[0])
        b = act.blend.motion
        turn = float(yaw_of(result.motion.quats[f, 0])) - float(yaw_of(b.quats[k, 0]))
        target = result.motion.root_pos[f] + rotate_y(act.blend.target - b.root_pos[k], turn)
        frame = Motion(
            ch.skeleton, result.motion.root_pos[f : f + 1], result.motion.quats[f : f + 1], ch.fps
        )
        img = next(shaded_frames(frame, ring, 3)).copy()
        cam = ring.poses(frame.root_pos)[0, 3]
        for p, colour in ((target, (0, 0, 255)), (wrist[f], (0, 255, 0))):
            x, y = np.rint(ring.project(ring.to_camera(np.asarray(p)[None], cam))[0]).astype(int)
            cv2.circle(img, (int(x), int(y)), 5, colour, 2)
        tiles.append(img)
        report.append(
            {
                "target": [round(float(v), 3) for v in act.blend.target],
                "blend_reached_cm": round(
                    float(np.linalg.norm(act.blend.reached - act.blend.target)) * 100, 2
                ),
                "chain_reached_cm": round(float(np.linalg.norm(wrist[f] - target)) * 100, 2),
                "apex_at_s": round(f / ch.fps, 2),
            }
        )
    cv2.imwrite(str(out), np.concatenate(tiles, axis=1))
    return {"picture": str(out.relative_to(HERE.parent)), "strikes": report}


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("root", nargs="?", default=str(default_library_path()))
    ap.add_argument("--targets", type=int, default=60)
    ap.add_argument("--out", default="benchmarks/results/parametric.json")
    args = ap.parse_args()
    lib = load_library(args.root)
    ch = Chainer(lib.clips)
    result: dict[str, Any] = {"machine": machine(), "date": time.strftime("%Y-%m-%d")}
    result["library_frames"] = ch.n_library
    for name, spec, effector, key in REFERENCES:
        result[name] = _one(ch, spec, effector, key, args.targets)
        err = result[name].get("error_cm", result[name].get("error_deg"))
        print(name, err, result[name]["request_ms"], flush=True)
    result["three_strikes"] = _picture(ch, HERE / "results" / "parametric_strikes.png")
    save(result, args.out)


if __name__ == "__main__":
    main()
