"""A lead (``LandingSettings.lead``): the avatar lands that far ahead of the performer's
last frame, where a live performer will be when the avatar is shown."""

from __future__ import annotations

import numpy as np
import pytest

from control.avatar import JumpCosts
from mimic.cli import main
from tests.vision.conftest import RECORDING
from vision import LandingSettings, Matcher, MatchSettings, PerformSettings, perform
from vision._sources import VideoSource


def test_a_lead_lands_a_jump_that_far_ahead_and_reads_the_own_cost_that_far_behind(
    setup,
) -> None:
    lib, layer, bank = setup
    plain = Matcher(layer, bank, MatchSettings(landing=LandingSettings(phase_frames=0)))
    ahead = Matcher(layer, bank, MatchSettings(landing=LandingSettings(phase_frames=0, lead=0.2)))
    assert plain.lander.lead == 0 and ahead.lander.lead == 3  # 0.2 s at 15 frames/s
    j = 200  # the performer does the window that ends at frame j, seen from view 3
    window = np.arange(j - plain.n + 1, j + 1)
    performer = bank.features[plain.windows.to_bank[window], 3].astype(np.float64)
    queries = plain.queries(performer)
    assert queries is not None
    st = plain.settings
    got = plain.windows.index().search(queries, st.band, st.landing.top_windows, recency=st.recency)
    costs = JumpCosts(layer.graph, lib.clips, anywhere=True)
    before, _, _ = plain.lander.targets(40, got, costs, queries)
    after, _, _ = ahead.lander.targets(40, got, costs, queries)
    # each target played on by 3 frames, as far as its clip plays on
    assert np.array_equal(after, plain.lander.ahead(before, 3))
    assert (after == before + 3).mean() > 0.5 and (after >= before).all()
    # the avatar, 3 frames ahead, is costed by the window the performer is at
    shown = np.arange(j + 3 - 30, j + 4)
    assert np.array_equal(ahead.lander.own_frames(j + 3, shown), plain.lander.own_frames(j, shown))
    assert np.array_equal(
        Matcher(
            layer, bank, MatchSettings(landing=LandingSettings(own_from_library=False, lead=0.2))
        ).lander.own_frames(j + 3, shown),
        shown[:-3],
    )
    # a clip's end is as far as a lead goes, and its first frame as far back
    end = int(np.flatnonzero(~plain.lander.plays)[0])  # a frame that plays on into none
    assert ahead.lander.ahead(np.array([end - 1]))[0] == end
    assert ahead.lander.behind(1) == 0 and ahead.lander.behind(10) == 7


def test_with_a_lead_the_avatar_is_placed_and_lands_that_far_ahead(setup) -> None:
    lib, layer, bank = setup

    def run(lead: float) -> list[dict]:
        settings = PerformSettings(
            seconds=4.0, match=MatchSettings(landing=LandingSettings(lead=lead))
        )
        source = VideoSource(RECORDING, silhouette=True)
        return perform(source, layer, bank, lib.clips, settings).decisions

    plain, ahead = run(0.0), run(0.2)
    placed = [next(d for d in r if "located" in d)["frame"] for r in (plain, ahead)]
    assert placed[1] == placed[0] + 3
    # the performer is the same: most decisions the same, the avatar 3 frames on
    same = [
        (a["frame"] - p["frame"], "jump" in a)
        for p, a in zip(plain, ahead, strict=True)
        if p["decision"] is not None and ("jump" in p) == ("jump" in a)
    ]
    assert len(same) > 0.6 * len(plain)
    assert np.median([d for d, _ in same]) == 3


@pytest.mark.parametrize("bad", [-0.1, 0.6, float("nan"), float("inf")])
def test_a_bad_lead_is_refused(bad: float) -> None:
    with pytest.raises(ValueError, match="lead must be"):
        LandingSettings(lead=bad)


def test_the_command_line_refuses_a_lead_past_half_a_second(capsys) -> None:
    assert main(["perform", "--lead", "0.6", "--video", str(RECORDING)]) != 0
    assert "argument --lead: must be a number from 0 to 0.5, not '0.6'" in capsys.readouterr().err
