"""The landmarks the pose model reads from a silhouette, weighed into the silhouette's
ballot where it is unsure (``vision._voice``): a silhouette video of another take (13_29,
``mimic record``'s body and camera), the library 13_30 with a silhouette and a pose bank."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from control.motion import load_library
from vision import (
    FILTER_SWITCH,
    ActionSettings,
    MatchSettings,
    PerformSettings,
    RecordSettings,
    VideoSource,
    record_clip,
)
from vision._perform import Performance
from vision._voice import paint
from vision._vote import UNSURE_LEAD, fused, unsure


def test_a_silhouette_is_painted_dark_on_light_and_softened() -> None:
    mask = np.zeros((240, 320), dtype=bool)
    mask[60:200, 140:180] = True
    img = paint(mask)
    assert img.shape == (240, 320, 3) and img.dtype == np.uint8
    assert img[130, 160].max() < 30 and img[10, 10].min() > 225  # the figure, the ground
    edge = img[130, 138:142, 0]  # (the figure's left edge at column 140)
    assert edge[0] > edge[-1] and 30 < edge[1:3].mean() < 225  # softened, not hard


def test_an_unsure_ballot_lets_a_voice_without_a_fit_weigh_in() -> None:
    # where the best two actions tie the voice weighs alike; where the best leads by
    # UNSURE_LEAD (relatively) or more, not at all
    assert unsure(np.array([2.0, 2.0, 5.0])) == 1.0
    assert unsure(np.array([2.0, 2.0 * (1 + UNSURE_LEAD), 5.0])) == pytest.approx(0.0)
    assert unsure(np.array([2.0, 2.0 * (1 + 2 * UNSURE_LEAD), 5.0])) == 0.0
    assert unsure(np.array([5.0, 2.0, 2.0 * (1 + UNSURE_LEAD / 2)])) == pytest.approx(0.5)
    assert unsure(np.array([1.0])) == 0.0
    # a voice without a fit is weighed by its weight alone, whatever the other's fit
    a, b = np.array([1.0, 2.0, 3.0]), np.array([3.0, 1.0, 2.0])
    assert np.allclose(fused([a, b], [0.1, None], [1.0, 0.5]), (a + 0.5 * b) / 1.5)
    # with both fits, the better fit weighs far more (the landmarks beside the silhouette)
    assert np.allclose(fused([a, b], [0.1, 1.0]), a, atol=1e-6)


@pytest.mark.slow
def test_the_landmarks_read_from_each_silhouette_weigh_into_its_ballot(
    setup: Any, pose_bank: Any, mocap: Path, tmp_path: Path
) -> None:
    lib, layer, silhouettes = setup
    clip = load_library(mocap, fps=15, clips=["13_29"]).clip("13_29")
    video = tmp_path / "13_29.mkv"
    record_clip(clip, video, RecordSettings(azimuth=100.0), 0, 90)  # 6 s from the side
    st = PerformSettings()
    run = Performance(
        VideoSource(video, silhouette=True), layer, silhouettes, lib.clips, st, voice=pose_bank
    )
    assert run.voice is not None and run.matcher.ballot.partner is not None
    # ballots that hear landmarks are filtered, as a camera's are (``switch_for``)
    assert run.matcher.vote.switch == FILTER_SWITCH
    asked: list[Any] = []
    own = run.voice.evidence
    run.voice.evidence = lambda vote: asked.append(got := own(vote)) or got  # type: ignore[method-assign]
    run.matcher.ballot.partner = run.voice.evidence
    r = run.run()
    # the pose model finds a body in most painted silhouettes (from the side, the arms
    # lost in the body now and then), and the log says how often
    read = [d["landmarks_read"] for d in r.decisions if "landmarks_read" in d]
    assert len(read) >= 40 and np.mean(read) >= 0.6, read
    # once a window of them is read, every ballot hears them: a score for every action,
    # no fit (the two descriptors' fits are on scales of their own), a weight of 1
    heard = [a for a in asked if a is not None]
    assert len(heard) >= 0.8 * len(asked) >= 30
    n_actions = int(run.matcher.vote.actions.max()) + 1  # type: ignore[union-attr]
    assert all(a[0].shape == (n_actions,) and a[1] is None and a[2] == 1.0 for a in heard)
    # with the fused ballot off (``--no-fuse``), the silhouette alone; a pose bank for
    # the voice is refused where a silhouette bank is given
    off = PerformSettings(match=MatchSettings(action=ActionSettings(fuse=False)))
    plain = Performance(
        VideoSource(video, silhouette=True), layer, silhouettes, lib.clips, off, voice=pose_bank
    )
    assert plain.voice is None and plain.matcher.ballot.partner is None
    assert plain.matcher.vote.switch == 0.0  # (a silhouette alone: counted)
    with pytest.raises(ValueError, match="needs a pose bank"):
        Performance(
            VideoSource(video, silhouette=True),
            layer,
            silhouettes,
            lib.clips,
            st,
            voice=silhouettes,
        )
