"""Ground truth for a performance (sidecars, labels CSVs), what the avatar did against it,
and the side-by-side video's mask tape."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest

from tests.vision.conftest import RECORDING
from vision import (
    LabelFileError,
    Truth,
    action_runs,
    agreement,
    brief_actions_per_minute,
    motion_truth,
    plot_timeline,
    switch_delays,
    truth_for,
)
from vision._video import PANE, MaskTape, _frame_decisions, performer_pane


def test_a_recordings_sidecar_is_its_truth() -> None:
    truth = truth_for(RECORDING)
    assert truth is not None and truth.source.endswith(".mkv.json")
    assert truth.label_at(0.5) == "jumpjack" and truth.label_at(6.0) == "twist"
    assert truth.label_at(-1.0) is None and truth.label_at(60.0) is None


def test_a_labels_csv_needs_rows_for_the_video(tmp_path: Path) -> None:
    csv = tmp_path / "l.csv"
    csv.write_text("file,start,end,label\nother.mp4,0,2,Squat\nclip.mp4,1,3,Jog\n")
    truth = truth_for(tmp_path / "clip.mp4", csv)
    assert truth is not None and truth.spans == ((1.0, 3.0, "jog"),)
    with pytest.raises(LabelFileError, match=r"l\.csv: no labelled spans for none\.mp4"):
        truth_for(tmp_path / "none.mp4", csv)
    bad = tmp_path / "v.mkv"
    (tmp_path / "v.mkv.json").write_text("[1, 2]")
    with pytest.raises(LabelFileError, match=r"v\.mkv\.json: not a recording sidecar"):
        truth_for(bad)
    assert truth_for(tmp_path / "plain.mp4") is None


def test_a_recording_of_a_library_take_has_the_takes_cleaned_labels_too(
    mocap: Path, tmp_path: Path
) -> None:
    """Where the performer's motion changes action: the take's cleaned labels at each
    frame's source frame; the label file's boundaries stay the sidecar truth's."""
    truth, moved = truth_for(RECORDING), motion_truth(RECORDING, mocap)
    assert truth is not None and moved is not None and "cleaned labels of 13_29" in moved.source
    assert [s[2] for s in moved.spans] == [s[2] for s in truth.spans]
    shifts = [m[0] - t[0] for m, t in zip(moved.spans[1:], truth.spans[1:], strict=True)]
    assert all(0.05 < abs(x) < 1.0 for x in shifts)  # each boundary moved, by under a second
    side = RECORDING.with_name(RECORDING.name + ".json").read_text()
    for name, text in (
        ("other.mkv", side.replace('"clip": "13_29"', '"clip": "99_99"')),  # another library's
        ("old.mkv", side.replace('"source_frames"', '"frames_then"')),  # names no source
    ):
        (tmp_path / f"{name}.json").write_text(text)
        assert motion_truth(tmp_path / name, mocap) is None
    assert motion_truth(tmp_path / "plain.mp4", mocap) is None
    one_more = side.replace('"source_frames": [', '"source_frames": [0, ')
    (tmp_path / "cut.mkv.json").write_text(one_more)
    with pytest.raises(LabelFileError, match=r"cut\.mkv\.json: \d+ source frames for \d+ labels"):
        motion_truth(tmp_path / "cut.mkv", mocap)


def _decisions(clip, frames, times):
    return [
        {"t": t, "clip": clip.name, "clip_frame": int(f)}
        for t, f in zip(times, frames, strict=True)
    ]


def test_agreement_counts_the_avatars_label_against_the_performers_lagged(setup) -> None:
    lib, _, _ = setup
    clip = lib.clips[0]
    names = [clip.label_at(i) for i in range(clip.motion.n_frames)]
    a = next(i for i, n in enumerate(names) if n == "JumpJack")
    b = next(i for i, n in enumerate(names) if n == "Squat")
    # the avatar does JumpJack for 2 s, then Squat for 2 s; the performer switched at 1.5 s
    times = np.round(np.arange(0.1, 4.0, 0.1), 3)
    frames = [a if t < 2.0 else b for t in times]
    truth = Truth(((0.0, 1.5, "jumpjack"), (1.5, 4.0, "squat")), "test")
    got = agreement(_decisions(clip, frames, times), lib.clips, truth, lags=(0.0, 0.5))
    # at lag 0 the avatar is late by 0.5 s for five decisions; at lag 0.5 it is right
    assert got["by_lag_s"]["0"] == pytest.approx(34 / 39, abs=1e-3)
    assert got["by_lag_s"]["0.5"] == 1.0 and got["best_lag_s"] == 0.5
    assert got["confusion_at_best_lag"] == {"jumpjack": {"jumpjack": 15}, "squat": {"squat": 20}}
    # an action the library lacks is left out with known
    only = agreement(
        _decisions(clip, frames, times), lib.clips, truth, lags=(0.0,), known={"squat"}
    )
    assert only["decisions_by_lag_s"]["0"] == 25


def test_what_the_avatar_did_merges_short_runs(setup) -> None:
    lib, _, _ = setup
    clip = lib.clips[0]
    names = [clip.label_at(i) for i in range(clip.motion.n_frames)]
    a = next(i for i, n in enumerate(names) if n == "JumpJack")
    b = next(i for i, n in enumerate(names) if n == "Squat")
    times = np.round(np.arange(0.0, 3.0, 0.1), 3)
    frames = [b if 1.0 <= t < 1.2 else a for t in times]  # a 0.2 s blip of Squat
    runs = action_runs(_decisions(clip, frames, times), lib.clips, min_seconds=0.5)
    assert [r[2] for r in runs] == ["JumpJack"] and runs[0][:2] == (0.0, 2.9)
    runs = action_runs(_decisions(clip, frames, times), lib.clips)
    assert [r[2] for r in runs] == ["JumpJack", "Squat", "JumpJack"]
    # a short first run goes to the one after it
    frames = [b if t < 0.2 else a for t in times]
    runs = action_runs(_decisions(clip, frames, times), lib.clips, min_seconds=0.5)
    assert runs == [(0.0, 2.9, "JumpJack")]


def test_a_brief_action_is_one_the_avatar_shows_under_half_a_second() -> None:
    t = [i / 10 for i in range(17)]
    # 0.2 s of b (brief), 0.6 s of a, 0.5 s of c (not brief), a to the end (cut: not counted)
    labels = ["a"] * 3 + ["b"] * 2 + ["a"] * 6 + ["c"] * 5 + ["a"]
    assert brief_actions_per_minute(labels, t, 60.0) == 1.0
    # every action changed to counts, whether or not the avatar comes back from it
    assert brief_actions_per_minute(["a", "b", "c", "d", "e"], t[:5], 60.0) == 3.0
    # an unlabelled decision (None) is skipped
    assert brief_actions_per_minute(["a", "b", None, "a", "a"], t[:5], 30.0) == 2.0


def test_a_switch_is_followed_when_the_avatar_first_shows_the_new_action() -> None:
    t = [i / 10 for i in range(60)]
    performer = ["a"] * 10 + ["b"] * 20 + [None] * 5 + ["c"] * 10 + ["d"] * 15
    # b taken up 0.8 s after the performer, after a brief third action; c (after an
    # unlabelled stretch) at once; d not within 1 s: missed
    avatar = ["a"] * 15 + ["x"] * 3 + ["b"] * 17 + ["c"] * 25
    got = switch_delays(avatar, performer, t, known={"a", "b", "c", "d"}, within=1.0)
    assert got["each_s"] == [0.8, 0.0] and got["missed"] == 1 and got["switches"] == 3
    assert got["median_s"] == 0.4 and got["mean_s"] == 0.4
    # a switch into an action the library lacks is none the avatar could follow
    got = switch_delays(avatar, performer, t, known={"a", "b"})
    assert got == {"switches": 1, "missed": 0, "median_s": 0.8, "mean_s": 0.8, "each_s": [0.8]}
    # not followed within the limit: missed; cut off by the end before it: not counted
    late = ["a"] * 55 + ["b"] * 5
    assert switch_delays(late, performer, t, known={"b"}, within=4.0)["missed"] == 1
    assert switch_delays(late, performer, t, known={"b"}, within=5.0)["each_s"] == [4.5]
    assert switch_delays(late[:50], performer[:50], t[:50], known={"b"}, within=5.0) == {
        "switches": 0, "missed": 0, "median_s": None, "mean_s": None, "each_s": []
    }  # fmt: skip


def test_the_mask_tape_plays_back_what_was_written(rng: np.random.Generator) -> None:
    with MaskTape() as tape:
        masks = [rng.random((120, 160)) > 0.5 for _ in range(3)]
        for m in masks:
            tape.append(m)
        tape.append(None)
        got = list(tape.frames())
    assert len(got) == 4 and all(g.shape == (PANE[1], PANE[0], 3) for g in got)
    # letterboxed 4x: each mask pixel is a 4x4 block, white or black through the JPEG
    np.testing.assert_array_equal(got[0][::4, ::4, 1] > 127, masks[0])
    assert not got[3].any()
    with MaskTape() as tape:
        tape.append(masks[0])
        tape.reset()
        tape.append(None)
        assert len(tape) == 1 and len(list(tape.frames())) == 1


def test_a_colour_frame_is_shown_with_its_mask_and_landmarks() -> None:
    # a 320x240 frame of flat grey, the person's mask a box in its middle, and the pose
    # model's landmarks: the shoulders seen, the left wrist hidden
    image = np.full((240, 320, 3), 200, np.uint8)
    mask = np.zeros((240, 320), bool)
    mask[60:200, 130:190] = True
    lm = np.zeros((33, 3))
    lm[:, :2] = 0.5
    lm[11] = (0.45, 0.3, 0.9)
    lm[12] = (0.55, 0.3, 0.9)
    lm[15] = (0.3, 0.6, 0.1)
    pane = performer_pane(PANE, mask, image, lm)
    assert pane.shape == (PANE[1], PANE[0], 3)
    # letterboxed 2x: the frame dimmed to half, the mask tinted blue-white
    assert tuple(pane[20, 20]) == (100, 100, 100)
    assert pane[350, 330, 0] > pane[350, 330, 2]  # (BGR) tinted: more blue than red
    shoulder = pane[round(0.3 * 480), round(0.45 * 640)]
    assert tuple(shoulder) == (80, 220, 255)  # a joint seen, in the bones' colour
    wrist = pane[round(0.6 * 480), round(0.3 * 640)]
    assert tuple(wrist) == (150, 150, 150)  # a joint the model could not see, in grey
    # without a frame, the mask alone, white on black, as a silhouette source gives it
    alone = performer_pane(PANE, mask, None, None)
    assert tuple(alone[240, 320]) == (255, 255, 255) and not alone[20, 20].any()
    assert not performer_pane(PANE, None, None, None).any()


def test_a_timeline_is_drawn_with_a_row_for_each(tmp_path: Path) -> None:
    t = [round(0.1 * i, 1) for i in range(100)]
    timeline = {
        "t": t,
        "performer": ["jumpjack"] * 50 + ["twist"] * 50,
        "avatar": [None] * 5 + ["jumpjack"] * 52 + ["twist"] * 43,
    }
    path = tmp_path / "timeline.png"

    def bands() -> int:
        """Runs of coloured rows a third of the way across the plot."""
        img = cv2.imread(str(path))
        assert img is not None and img.shape[1] == 1200
        coloured = (img.max(axis=2).astype(int) - img.min(axis=2)) > 60
        rows = coloured[:, img.shape[1] // 3].astype(int)
        return int((np.diff(rows) == 1).sum() + rows[0])

    plot_timeline(timeline, path, "a title")
    assert bands() == 2  # the performer's actions above, the avatar's below
    assert not list(tmp_path.glob(".*"))  # (written through a temporary file)
    # a recording of a library take: where the motion changes, between the two
    plot_timeline({**timeline, "motion": ["jumpjack"] * 45 + ["twist"] * 55}, path)
    assert bands() == 3


def test_the_video_marks_jumps_and_starts() -> None:
    ds = [
        {"t": 0.5, "cost": 1.0},
        {"t": 1.0, "located": 0.2, "cost": 2.0},
        {"t": 1.1, "cost": 3.0, "jump": 5},
        {"t": 1.2, "decision": None},
    ]
    t0, latest, marks = _frame_decisions(ds, 20, 10.0, mark_s=0.2)
    assert t0 == 1.0
    assert marks[:4] == ["START", "JUMP", "JUMP", ""]
    assert latest[0]["cost"] == 2.0 and latest[5]["cost"] == 3.0  # the last one made


@pytest.mark.slow
def test_mimic_evaluate_writes_agreement_confusion_and_a_plot(
    mocap: Path, tmp_path: Path, capsys
) -> None:
    import json
    import shutil

    import cv2

    from mimic.cli import main

    out, png = tmp_path / "r" / "report.json", tmp_path / "r" / "plot.png"
    argv = ["evaluate", str(RECORDING), str(mocap), "--clips", "13_30", "--k", "12"]
    argv += ["--no-fuse"]  # (what the report holds; the pose model reading each frame is slow)
    assert main([*argv, "--seconds", "6", "--json", str(out), "--png", str(png)]) == 0
    report = json.loads(out.read_text())
    assert report["library"] == ["13_30"] and report["truth"].endswith(".mkv.json")
    assert set(report["agreement_by_lag_s"]) >= {"0", "0.5", "1", "3"}
    best = report["best_at_lag_le_1s"]
    lag = f"{report['best_lag_s']:g}"
    assert best == report["agreement_known_actions_by_lag_s"][lag]
    # the confusion matrix holds every counted decision, its diagonal the agreement
    conf = report["confusion_at_best_lag"]
    n = sum(sum(r.values()) for r in conf.values())
    assert n == report["decisions_known_actions_by_lag_s"][lag]
    assert sum(r.get(a, 0) for a, r in conf.items()) / n == pytest.approx(best, abs=1e-3)
    assert 0 < report["chance"] < 1 and report["latency_ms"]["over_100ms"] == 0
    img = cv2.imread(str(png))
    assert img is not None and img.shape[1] > img.shape[0] > 300
    said = capsys.readouterr().out
    assert "agreement (actions the library has): " in said
    sw = report["switches_per_minute"]
    assert 0 <= sw["avatar_brief_actions_under_0.5s"] <= sw["avatar"]
    assert f"(actions shown under 0.5 s: {sw['avatar_brief_actions_under_0.5s']} a minute)" in said
    # a video without ground truth is a clear error
    bare = tmp_path / "bare.mkv"
    shutil.copy(RECORDING, bare)
    assert main(["evaluate", str(bare), str(mocap), "--clips", "13_30", "--json", str(out)]) == 2
    assert "bare.mkv: no ground truth" in capsys.readouterr().err
