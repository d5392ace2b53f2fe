"""Every numeric option of every subcommand goes through one validator
(``mimic.args.number``): NaN, a value out of range and a number too large to mean
anything are refused by argparse, naming the option, before any work."""

from __future__ import annotations

import argparse
import dataclasses
import math
from collections.abc import Iterator
from pathlib import Path

import pytest

from mimic.args import number
from mimic.cli import build_parser, main
from mimic.run_args import action_settings
from vision import ActionSettings


def _actions(
    parser: argparse.ArgumentParser, path: str = "mimic"
) -> Iterator[tuple[str, argparse.Action]]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for name, sub in action.choices.items():
                yield from _actions(sub, f"{path} {name}")
        else:
            yield path, action


def test_every_numeric_option_is_checked_by_the_one_validator() -> None:
    numeric = [(cmd, a) for cmd, a in _actions(build_parser()) if a.type is not None]
    assert len(numeric) > 50  # (the test sees the options)
    for cmd, action in numeric:
        where = f"{cmd} {action.option_strings}"
        assert action.type not in (int, float), f"{where}: a bare {action.type.__name__}"
        check = action.type
        assert callable(check)
        try:
            limitless = check("inf") == float("inf")  # "inf: no limit" (--vote-margin)
        except argparse.ArgumentTypeError:
            limitless = False
        for bad in ("nan", "-nan", "-inf", "x", "", *(() if limitless else ("1e400",))):
            with pytest.raises(argparse.ArgumentTypeError, match="must be"):
                check(bad)
        if not limitless:
            with pytest.raises(argparse.ArgumentTypeError):
                check("1e12")  # no count, size or duration of mimic's means that much
        if action.default is not None and not isinstance(action.default, str):
            assert check(repr(action.default)) == action.default, where  # defaults pass


def test_the_validator_says_what_it_wants() -> None:
    port = number(int, 0, 65535)
    assert port("8765") == 8765
    with pytest.raises(
        argparse.ArgumentTypeError, match="a whole number from 0 to 65535, not '70000'"
    ):
        port("70000")
    with pytest.raises(argparse.ArgumentTypeError, match="whole number"):
        port("80.5")
    window = number(float, 0, 10, above=True)
    with pytest.raises(argparse.ArgumentTypeError, match="above 0 and at most 10, not '0'"):
        window("0")
    margin = number(float, 0, 1000, inf=True)
    assert margin("inf") == float("inf")
    with pytest.raises(argparse.ArgumentTypeError, match=r"\(or inf: no limit\)"):
        margin("-inf")


@pytest.mark.parametrize(
    ("argv", "option"),
    [
        (["perform", "--video", "v.mkv", "--live-port", "70000"], "--live-port"),
        (["perform", "--video", "v.mkv", "--live-port", "-5"], "--live-port"),
        (["perform", "--video", "v.mkv", "--seconds", "nan"], "--seconds"),
        (["perform", "--video", "v.mkv", "--seconds", "-1"], "--seconds"),
        (["perform", "--video", "v.mkv", "--window", "0"], "--window"),
        (["perform", "--video", "v.mkv", "--window", "nan"], "--window"),
        (["perform", "--video", "v.mkv", "--lookahead", "-1"], "--lookahead"),
        (["graph", "walk", "--seconds", "inf", "--out", "w.bvh"], "--seconds"),
        (["graph", "walk", "--seconds", "1e12", "--out", "w.bvh"], "--seconds"),
    ],
)
def test_the_issue_s_values_are_refused_by_name(
    argv: list[str], option: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"argument {option}: must be" in err and "Traceback" not in err


def test_steady_sets_the_filtered_vote_and_a_flag_given_too_wins() -> None:
    """``--steady`` is the filtered vote's four flags in one; without it the vote is
    counted, as the defaults say; any of the four given beside it wins."""
    parse = build_parser().parse_args
    video = ["perform", "--video", "v.mkv"]
    assert action_settings(parse(video)) == ActionSettings()
    steady = action_settings(parse([*video, "--steady"]))
    assert steady == ActionSettings.steady()
    assert steady.switch_chance > 0 and math.isinf(steady.margin)  # filtered, strict
    mine = action_settings(parse([*video, "--steady", "--vote-temperature", "0.3"]))
    assert mine == dataclasses.replace(ActionSettings.steady(), temperature=0.3)
    # the same settings as the four flags spelt out, and the other vote flags still apply
    spelt = ["--vote-switch", "0.02", "--vote-confidence", "0.9", "--vote-margin", "inf"]
    spelt += ["--vote-temperature", "0.2", "--vote", "9"]
    assert action_settings(parse([*video, *spelt])) == dataclasses.replace(steady, vote=9)


def test_perform_reads_the_labelled_clips_mirrored_for_landmarks_and_a_left_out_clips_copy_goes(
    mocap: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from mimic.run import _clips
    from mimic.run_args import run_settings

    def clips(*argv: str, descriptor: str = "pose") -> list[str]:
        args = build_parser().parse_args(["perform", "--video", "x.mp4", str(mocap), *argv])
        settings = run_settings(args)
        return [c.name for c in _clips(settings, descriptor)]

    pick = ["--clips", "13_3*", "--clips", "02_01"]  # two labelled takes and a walk
    assert clips(*pick) == ["02_01", "13_30", "13_30_mirror", "13_31", "13_31_mirror"]
    # silhouettes read the performer mirrored already: the library as it is
    assert clips(*pick, descriptor="outline") == ["02_01", "13_30", "13_31"]
    assert clips(*pick, "--mirror", "none") == ["02_01", "13_30", "13_31"]
    assert clips(*pick, "--mirror", descriptor="outline") == [  # every clip, as elsewhere
        "02_01", "02_01_mirror", "13_30", "13_30_mirror", "13_31", "13_31_mirror"
    ]  # fmt: skip
    # a left-out take takes its mirror image with it: the same performer
    assert clips(*pick, "--leave-out", "13_30") == ["02_01", "13_31", "13_31_mirror"]
    assert "left out as asked: 13_30, 13_30_mirror" in capsys.readouterr().err
    # the other commands' library as it was; auto is perform's and bank build's alone
    assert build_parser().parse_args(["graph", "build", str(mocap)]).mirror == "none"
    with pytest.raises(SystemExit):
        build_parser().parse_args(["graph", "build", str(mocap), "--mirror", "auto"])
    assert "invalid choice: 'auto'" in capsys.readouterr().err
