"""The paper's other interfaces on the live page: choice (Lee et al. §5.1) and sketch
(§5.2), with the avatar moving in real time (``mimic play``).

``PlaySession.run`` steps the avatar at the graph's rate on the wall clock and sends its
pose to the page every frame, as ``perform`` does. Whenever the avatar is free (not
performing a choice or a sketch) the page is offered a few actions (``control.choice
.offer``): each a button with a small moving preview of its motion (stick figure, as the
page's camera sees it) and its root's path drawn on the floor. A click makes the avatar
take that action's path. A path drawn on the floor is planned from where the avatar is,
as it is placed there (``SketchTracker`` with ``place``), and taken; the page draws the
root path planned beside the drawn one. Commands arrive from the stage's threads and are
taken by the loop between frames.
"""

from __future__ import annotations

import json
import queue
import time
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from control.avatar import Avatar
from control.choice import Option, offer
from control.clusters import HigherLayer
from control.graph import FrameData, rotate_y
from control.motion import Clip, Motion, forward_kinematics
from control.sketch import SketchSettings, SketchTracker

from ._live import StagePainter
from ._stage import Stage

__all__ = ["PlaySession"]

#: most points a drawn path may have, and the shortest it may be (metres)
MAX_SKETCH_POINTS = 2000
MIN_SKETCH_LENGTH = 0.5
PREVIEW_POSES = 24


class PlaySession:
    """The avatar steered from the page (module docstring)."""

    def __init__(
        self,
        stage: Stage,
        clips: Sequence[Clip],
        layer: HigherLayer,
        start: int | None = None,
        seed: int = 0,
        options: int = 4,
        lookahead: float = 6.0,
    ) -> None:
        self.stage, self.layer, self.graph = stage, layer, layer.graph
        self.clips = layer.graph.clips_of(clips)
        self.data = FrameData(self.graph, self.clips)
        self.avatar = Avatar(self.graph, self.clips, start=start, seed=seed)
        self.painter = StagePainter(stage, self.clips, self.graph)
        self.n_options, self.lookahead = options, lookahead
        self.offered: list[Option] = []
        self.offer_id = 0
        self._offered_at = -1.0
        self._inbox: queue.Queue[dict[str, Any]] = queue.Queue()
        #: what was done: {"kind": "choice"|"sketch", "t": seconds, ...} per command taken
        self.performed: list[dict[str, Any]] = []
        stage.on_command = self.command
        skeleton = self.clips[0].motion.skeleton
        self._bones = [[int(p), j] for j, p in enumerate(skeleton.parents) if p >= 0]

    # --- from the page (the stage's threads) ---------------------------------------------

    def command(self, message: dict[str, Any]) -> str:
        """Check a page's command and queue it for the loop; what is wrong ("" if none)."""
        kind = message.get("type")
        if kind == "choose":
            option, offer_id = message.get("option"), message.get("offer")
            if not isinstance(option, int) or not isinstance(offer_id, int):
                return "choose: 'option' and 'offer' must be whole numbers"
        elif kind == "sketch":
            points = message.get("points")
            try:
                xz = np.asarray(points, dtype=np.float64)
            except (TypeError, ValueError):
                return "sketch: 'points' must be a list of [x, z] pairs"
            if xz.ndim != 2 or xz.shape[1] != 2 or not 2 <= len(xz) <= MAX_SKETCH_POINTS:
                return f"sketch: 'points' must hold 2 to {MAX_SKETCH_POINTS} [x, z] pairs"
            if not np.isfinite(xz).all() or np.abs(xz).max() > 1000:
                return "sketch: the points must be finite, within 1000 m"
            if np.linalg.norm(np.diff(xz, axis=0), axis=1).sum() < MIN_SKETCH_LENGTH:
                return f"sketch: a path under {MIN_SKETCH_LENGTH:g} m is too short to follow"
            message = {"type": "sketch", "points": xz}
        else:
            return f"unknown command {kind!r}"
        self._inbox.put(message)
        return ""

    # --- the loop ---------------------------------------------------------------------------

    def run(self, seconds: float, stop: Callable[[], str] | None = None) -> str:
        """Move the avatar for ``seconds`` of wall time, or until ``stop()`` says why."""
        fps = self.graph.fps
        t0 = time.monotonic()
        n = 0
        while n / fps < seconds:
            if stop is not None and (why := stop()):
                return why
            while not self._inbox.empty():
                self._take(self._inbox.get())
            t = n / fps
            if not self.avatar.busy and (not self.offered or t - self._offered_at >= 0.5):
                self._offer(t)
            self.avatar.step()
            n += 1
            self.painter.on_frame(t, None, self.avatar, picture=None)
            delay = t0 + n / fps - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        return ""

    def _offer(self, t: float) -> None:
        lookahead = (0.0, self.lookahead) if self.lookahead > 0 else None
        was = [o.cluster for o in self.offered]
        self.offered = offer(self.layer, self.avatar, self.data, self.n_options, lookahead)
        self._offered_at = t
        if self.offered and [o.cluster for o in self.offered] == was:
            return  # the same actions: the page's buttons (and their previews) stay
        self.offer_id += 1
        items = [self._describe(o) for o in self.offered]
        self.stage.publish_extra(
            "options", json.dumps({"type": "options", "id": self.offer_id, "options": items})
        )

    def _describe(self, o: Option) -> dict[str, Any]:
        """An option as the page shows it: its action's name, length, a preview of its
        motion (joint positions seen from the page's camera, x and height) and its root's
        path on the floor."""
        end = int(o.frames[-1])
        name, f = self.graph.locate(end)
        label = next((c.label_at(f) for c in self.clips if c.name == name), None)
        pick = np.unique(np.linspace(0, o.frames.size - 1, PREVIEW_POSES).round().astype(int))
        frames = o.frames[pick]
        skeleton = self.clips[0].motion.skeleton
        motion = Motion(skeleton, self.data.root[frames], self.data.quats[frames], self.graph.fps)
        pos = forward_kinematics(motion).positions
        pos[..., 0] -= pos[:, :1, 0]  # each pose about its own root, seen from the front
        return {
            "label": f"{label or name} ({o.seconds:.1f} s)",
            "preview": {"bones": self._bones, "poses": np.round(pos[..., :2], 3).tolist()},
            "path": np.round(o.root_path[:: max(1, len(o.root_path) // 40), [0, 2]], 3).tolist(),
        }

    def _take(self, message: dict[str, Any]) -> None:
        if message["type"] == "choose":
            k, offer_id = message["option"], message["offer"]
            if offer_id != self.offer_id or not 0 <= k < len(self.offered):
                self.stage.broadcast("that offer has gone (the avatar moved on): choose again")
                return
            # the avatar has played on since the offer: the way from where it is now to
            # the cluster clicked (Lee et al. offer from the current frame, and so do we)
            cluster = self.offered[k].cluster
            lookahead = (0.0, self.lookahead) if self.lookahead > 0 else None
            now = offer(self.layer, self.avatar, self.data, 64, lookahead)
            o = next((x for x in now if x.cluster == cluster), None)
            if o is None:
                self.stage.broadcast("that action is out of reach from here now: choose again")
                self.offered = []
                return
            self.avatar.take(o.frames, o.edges)
            self.performed.append({"kind": "choice", "cluster": int(o.cluster), "s": o.seconds})
            self.offered = []
            self.stage.publish_extra("options", json.dumps({"type": "options", "id": -1}))
            return
        self._sketch(message["points"])

    def _sketch(self, points: np.ndarray) -> None:
        avatar = self.avatar
        yaw, trans = avatar.root_transform()
        here = rotate_y(self.data.root[avatar.frame], float(yaw)) + trans
        start = avatar.frame
        if not self.graph.in_scc[start]:
            self.stage.broadcast("the avatar is outside the graph's component: sketch again soon")
            return
        sketch = np.vstack(([[float(here[0]), float(here[2])]], points))
        t0 = time.perf_counter()
        tracker = SketchTracker(
            self.graph,
            self.clips,
            sketch,
            settings=SketchSettings(),
            start=start,
            place=(yaw, trans),
        )
        length = float(np.linalg.norm(np.diff(sketch, axis=0), axis=1).sum())
        tracker.run(max_seconds=min(120.0, 5.0 + 2.0 * length))
        if len(tracker.frames) < 2:
            self.stage.broadcast("no way along that path was found: draw another")
            return
        edges = np.full(len(tracker.frames) - 1, -1, dtype=np.int64)
        edges[np.array(tracker.jumps, dtype=np.int64) - 1] = tracker.edges
        avatar.take(tracker.frames, edges)
        summary = tracker.summary(time.perf_counter() - t0)
        self.performed.append({"kind": "sketch", **summary})
        self.offered = []
        self.stage.publish_extra(
            "plan",
            json.dumps(
                {
                    "type": "plan",
                    "path": np.round(tracker.root_path()[::4], 3).tolist(),
                    "followed": summary["followed"],
                }
            ),
        )
