"""A source whose pictures come late (a camera page on a loaded machine, a camera
reconnecting) leaves the performer as last seen for a moment (``vision._frames.HOLD_S``);
only a longer silence is a frame without features, said as ``no picture``."""

from __future__ import annotations

import numpy as np

from tests.vision.conftest import RECORDING
from vision import Frame, PerformSettings, VideoSource, decision_points, perform
from vision._frames import HOLD_S

#: reasons that say the performer was not seen (what a late picture must not cause)
UNSEEN = ("no silhouette", "nobody in view", "no picture")


class _Late:
    """The recording as a loaded machine's camera page delivers it: a picture at every
    ``every``-th read and none at the reads between (the browser camera's when the page's
    next frame is later than it waits), and none at all within ``gap`` (media seconds)."""

    def __init__(self, every: int, gap: tuple[float, float] = (np.inf, np.inf)) -> None:
        self.inner = VideoSource(RECORDING, silhouette=True)
        self.fps, self.name = self.inner.fps, self.inner.name
        self.every, self.gap = every, gap

    def read(self) -> Frame | None:
        f = self.inner.read()
        if f is None:
            return None
        late = f.index % self.every != 0 or self.gap[0] <= f.t < self.gap[1]
        return Frame(f.t, f.index) if late else f

    def close(self) -> None:
        self.inner.close()


def _run(setup, source) -> list[dict]:
    lib, layer, bank = setup
    settings = PerformSettings(seconds=8.0)  # (the silhouette alone: no voice given)
    return perform(source, layer, bank, lib.clips, settings, seed=3).decisions


def test_pictures_that_come_late_are_followed_as_the_last_seen(setup) -> None:
    # a picture every third read (10 a second of the recording's 30): the reads between
    # find none, and the performer is still there
    late = _run(setup, _Late(every=3))
    whole = _run(setup, VideoSource(RECORDING, silhouette=True))
    after = [d for d in late if d["t"] >= 1.0]  # (the first window filled)
    assert after and not [d for d in after if d.get("reason", "").startswith(UNSEEN)]
    made = sum(d["decision"] is not None for d in late)
    assert made >= 0.9 * sum(d["decision"] is not None for d in whole)
    assert decision_points(late)["person_in_view_undecided"] == 0


def test_a_source_silent_for_longer_than_the_hold_gives_no_picture_then_is_followed_again(
    setup,
) -> None:
    gap = (3.0, 5.0)
    got = _run(setup, _Late(every=1, gap=gap))
    # as last seen: matched while the window is still mostly motion (a picture frozen
    # for longer matches no motion of the library: "no match", as a performer standing
    # stock still would)
    held = [d for d in got if gap[0] <= d["t"] <= gap[0] + 0.4]
    assert held and all(d["decision"] is not None for d in held)
    silent = [d for d in got if gap[0] + HOLD_S + 0.1 <= d["t"] < gap[1]]
    assert silent and all(d["decision"] is None for d in silent)
    assert all(d["reason"].startswith("no picture (none for ") for d in silent)
    back = [d for d in got if d["t"] >= gap[1] + 1.0]  # (a window of pictures again)
    assert back and all(d["decision"] is not None for d in back)
    # counted as a point with nobody to see, not as a person left unfollowed
    points = decision_points(got)
    none = [d for d in got if d.get("reason", "").startswith("no picture")]
    assert points["undecided_by_reason"]["no picture"] == len(none) >= len(silent)
    seen = [d for d in got if d["decision"] is None and d not in none]
    seen = [d for d in seen if not d["reason"].startswith("filling buffer")]
    assert points["person_in_view_undecided"] == len(seen)
