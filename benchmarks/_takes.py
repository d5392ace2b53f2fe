"""Performers who keep another tempo, stop now and then, or move less or more than the
library's (``bench_accuracy --recordings slow, fast, pauses, small, big``).

A performer rarely keeps the library's tempo: on the shared squat clip each squat takes
about 3 s, the library's about 1.3 s. ``retimed_clip`` plays the take slower or faster.

Real performers pause between repetitions and between actions: on the shared squat clip
she stands still for about two seconds between squats. The labelled exercise takes never
stop, so this makes a take that does: every ``every`` seconds the performer holds still
for ``hold`` seconds, at the frame of the next second where the take moves least (where a
person would rest: a squat's top, a knee raise's end). The held frames carry no action
label (they are no library action, as on the squat clip), and ``holds`` marks them, so
that the benchmark can say what the avatar does while the performer stands still.

People also do an exercise with their own reach: arms that stop short of the head in a
jumping jack, a shallower squat, a wider twist. ``styled_clip`` scales every joint's turn
away from its mean over the take (the root's orientation and path kept, its height moved
so that the lowest foot stays where the take's was).
"""

from __future__ import annotations

import dataclasses

import numpy as np
from numpy.typing import NDArray

from control.graph import joint_jumps
from control.motion import Clip, Contacts, Motion, foot_points, qconj, qexp, qlog, qmul, resample

__all__ = ["held_since", "hold_figures", "paused_clip", "retimed_clip", "styled_clip"]


def retimed_clip(clip: Clip, tempo: float) -> Clip:
    """``clip`` done ``tempo`` times as fast (0.5: half as fast), at its own rate."""
    m = clip.motion
    fast = resample(dataclasses.replace(m, fps=m.fps * tempo), m.fps)
    src = np.clip(np.round(np.arange(fast.n_frames) * tempo).astype(int), 0, m.n_frames - 1)
    motion = dataclasses.replace(fast, source=f"{m.source} (tempo {tempo:g})")
    return _reindexed(clip, motion, src, clip.labels[src])


def styled_clip(clip: Clip, reach: float) -> Clip:
    """``clip`` done with ``reach`` times its movement (0.7: every joint but the root turns
    0.7 times as far from its mean over the take), its lowest foot where the take's is."""
    m = clip.motion
    q = m.quats.copy()
    joints = q[:, 1:]
    ref = joints[0]  # each joint's mean turn: the average of its frames, signs aligned
    aligned = np.where((joints * ref).sum(axis=-1, keepdims=True) < 0, -joints, joints)
    mean = aligned.mean(axis=0)
    mean /= np.linalg.norm(mean, axis=-1, keepdims=True)
    away = qlog(qmul(np.broadcast_to(qconj(mean), joints.shape), joints))
    q[:, 1:] = qmul(np.broadcast_to(mean, joints.shape), qexp(reach * away))
    styled = dataclasses.replace(m, quats=q, source=f"{m.source} (reach {reach:g})")
    lowest = []
    for x in (m, styled):
        ankle, toe = foot_points(x)  # (F, 2, 3) each, y up
        lowest.append(np.minimum(ankle[..., 1], toe[..., 1]).min(axis=1))
    root = m.root_pos.copy()
    root[:, 1] += lowest[0] - lowest[1]
    styled = dataclasses.replace(styled, root_pos=root)
    idx = np.arange(m.n_frames, dtype=np.int64)
    return _reindexed(clip, styled, idx, clip.labels)


def _reindexed(
    clip: Clip, motion: Motion, idx: NDArray[np.int64], labels: NDArray[np.int64]
) -> Clip:
    """``clip`` as ``motion``, each of whose frames shows ``clip``'s frame ``idx``
    (contacts and source frames taken from there), with ``labels``."""
    states = clip.contacts.states[idx]
    contacts = Contacts(states, clip.contacts.ankle_rest, clip.contacts.toe_rest)
    return dataclasses.replace(
        clip, motion=motion, contacts=contacts, labels=labels, source_frames=clip.source_frames[idx]
    )


def paused_clip(
    clip: Clip, every: float = 6.0, hold: float = 2.0, first: float = 3.0
) -> tuple[Clip, NDArray[np.bool_]]:
    """``clip`` with a hold of ``hold`` seconds every ``every`` seconds from ``first``,
    and ``(F,)`` which of the new clip's frames are held copies."""
    m = clip.motion
    fps = m.fps
    move = np.concatenate((joint_jumps(m), [np.inf]))  # each frame's change to the next
    n_hold, look = round(hold * fps), round(fps)
    order: list[int] = []
    held: list[bool] = []
    at = 0
    for t in np.arange(first, m.n_frames / fps - 1.0, every):
        start = round(t * fps)
        rest = start + int(np.argmin(move[start : start + look]))
        order += list(range(at, rest + 1)) + [rest] * n_hold
        held += [False] * (rest + 1 - at) + [True] * n_hold
        at = rest + 1
    order += list(range(at, m.n_frames))
    held += [False] * (m.n_frames - at)
    idx = np.array(order, dtype=np.int64)
    holds = np.array(held, dtype=bool)
    motion = Motion(
        m.skeleton, m.root_pos[idx], m.quats[idx], fps, m.name, f"{m.source} (with pauses)"
    )
    return _reindexed(clip, motion, idx, np.where(holds, -1, clip.labels[idx])), holds


def held_since(holds: NDArray[np.bool_], fps: float, react: float = 0.5) -> NDArray[np.bool_]:
    """Which frames have been held for more than ``react`` seconds."""
    begun = np.zeros(holds.size, dtype=bool)
    run = 0
    for i in range(holds.size):
        run = run + 1 if holds[i] else 0
        begun[i] = run > react * fps
    return begun


def hold_figures(
    begun: NDArray[np.bool_],
    fps: float,
    times: NDArray[np.float64],
    avatar: Motion,
    avatar_start: float,
    jumps_at: NDArray[np.int64],
) -> dict[str, float | int | None]:
    """What the avatar does while the performer holds still (``begun``, at the take's
    ``fps``: ``held_since``'s frames): its jumps a minute and how far its joints turn a
    frame (``joint_jumps``: the largest turn, degrees; beside it the same elsewhere), and
    the decisions counted."""
    n = begun.size
    shown = avatar_start + np.arange(avatar.n_frames) / avatar.fps
    k = np.clip(np.round(shown * fps).astype(int), 0, n - 1)
    still = begun[k] & (shown * fps < n)
    turns = joint_jumps(avatar)  # frame i to i + 1
    in_hold = still[:-1] & still[1:]
    moving = ~begun[k[:-1]] & ~begun[k[1:]]
    jumps = np.asarray(jumps_at, dtype=np.int64)
    jumps = jumps[(jumps >= 0) & (jumps < still.size)]
    seconds = float(in_hold.sum()) / avatar.fps
    d = np.clip(np.round(times * fps).astype(int), 0, n - 1)
    return {
        "seconds": round(seconds, 2),
        "decisions": int(begun[d].sum()),
        "avatar_jumps_per_minute": round(float(still[jumps].sum()) / max(seconds / 60, 1e-9), 1)
        if seconds
        else None,
        "avatar_turn_deg_per_frame": round(float(turns[in_hold].mean()), 2) if seconds else None,
        "avatar_turn_deg_per_frame_elsewhere": round(float(turns[moving].mean()), 2),
    }
