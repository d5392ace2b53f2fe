"""Feeding the live page (``vision._stage.Stage``) from the performance loop.

``StagePainter.on_frame`` sends, every frame, the avatar's pose: the root's position and
every joint's rotation (w, x, y, z) of the library skeleton, placed in the avatar's
world. The pose is the library frame the avatar is on (the BVH also blends across a
jump; the page smooths by interpolating between poses at its own frame rate). At most
``fps`` times a second it sends the performer's picture as the side-by-side video draws
it (``vision._video.performer_pane``: the colour frame with the person mask and the
landmarks over it, or the mask in white). ``on_decision`` sends the state: the avatar's
action, what the performer is taken to do (their labelled action when the run has
labels, else the action the vote settled on), the match cost and decision latency.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from control.graph import root_scales, rotate_y
from control.motion import Clip

from ._stage import Stage
from ._truth import Truth
from ._video import performer_pane

__all__ = ["StagePainter", "skeleton_message"]


def skeleton_message(clip: Clip) -> dict[str, Any]:
    """The skeleton as the page builds it: joint names, parents, rest offsets (metres)
    and end sites."""
    sk = clip.motion.skeleton
    return {
        "names": list(sk.names),
        "parents": [int(p) for p in sk.parents],
        "offsets": np.round(sk.offsets, 4).tolist(),
        "end_parents": [int(p) for p in sk.end_parents],
        "end_offsets": np.round(sk.end_offsets, 4).tolist(),
    }


class StagePainter:
    """The loop's ``on_frame`` and ``on_decision`` for a ``Stage`` (module docstring)."""

    PANE = (480, 360)

    def __init__(
        self,
        stage: Stage,
        clips: Sequence[Clip],
        graph: Any,
        truth: Truth | None = None,
        fps: float = 15.0,
    ) -> None:
        self.stage = stage
        self.graph = graph
        chosen = graph.clips_of(clips)
        self.by_name = {c.name: c for c in chosen}
        self.scale = dict(zip((c.name for c in chosen), root_scales(chosen), strict=True))
        self.truth = truth
        self._period = 1.0 / fps
        self._last = -1.0
        stage.set_skeleton(skeleton_message(chosen[0]))

    def pose(self, t: float, avatar: Any) -> dict[str, Any]:
        """The avatar's pose now, placed in its world, and its action."""
        name, f = self.graph.locate(avatar.frame)
        clip = self.by_name[name]
        yaw, trans = avatar.root_transform()
        root = rotate_y(clip.motion.root_pos[f] * self.scale[name], float(yaw)) + trans
        q = np.array(clip.motion.quats[f], dtype=np.float64)
        w, y = np.cos(yaw / 2.0), np.sin(yaw / 2.0)  # the root turned by yaw about +Y
        a = q[0].copy()
        q[0] = (w * a[0] - y * a[2], w * a[1] + y * a[3], w * a[2] + y * a[0], w * a[3] - y * a[1])
        camera = self.stage.camera
        return {
            "t": round(float(t), 3),
            "root": np.round(root, 4).tolist(),
            "q": np.round(q, 4).tolist(),
            "ts": camera.last_stamp if camera is not None else None,
            "action": clip.label_at(f) or name,
        }

    def on_frame(
        self,
        t: float,
        mask: NDArray[np.bool_] | None,
        avatar: Any,
        picture: tuple[Any, Any] | None = (None, None),
    ) -> None:
        """The pose now; the performer's picture when it is time (none without a
        ``picture``: a run without a performer)."""
        self.stage.publish_pose(self.pose(t, avatar))
        if picture is None or t - self._last < self._period - 1e-9:
            return
        self._last = t
        pane = performer_pane(self.PANE, mask, *picture)
        ok, buf = cv2.imencode(".jpg", pane, [cv2.IMWRITE_JPEG_QUALITY, 80])
        if ok:
            self.stage.publish_picture(buf.tobytes())

    def on_decision(self, entry: dict[str, Any]) -> None:
        clip = self.by_name.get(entry.get("clip", ""))
        action = clip.label_at(int(entry["clip_frame"])) if clip is not None else None
        performer = (
            self.truth.label_at(float(entry["t"])) if self.truth is not None else entry.get("voted")
        )
        made = entry.get("decision") is not None
        self.stage.set_state(
            t=entry["t"],
            action=action or entry.get("clip"),
            performer=performer,
            performer_from="labels" if self.truth is not None else "vote",
            cost=entry.get("cost") if made else None,
            latency_ms=entry.get("latency_ms") if made else None,
            why=None if made else entry.get("reason"),
            by=entry.get("by"),
            clip=entry.get("clip"),
            clip_frame=entry.get("clip_frame"),
        )
