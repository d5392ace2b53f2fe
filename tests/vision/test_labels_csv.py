"""The labels CSV of the real-video benchmark (a user's own labelled footage)."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.conftest import REPO
from vision import LabelFileError
from vision._truth import read_span_labels as read_labels


def test_reads_spans_with_header_and_comments(tmp_path: Path) -> None:
    p = tmp_path / "l.csv"
    p.write_text('# mine\nfile,start,end,label\na.mp4, 0, 2.5, Squat\n\n"b c.mp4",1,3,Jog # x\n')
    assert read_labels(p) == [("a.mp4", 0.0, 2.5, "Squat"), ("b c.mp4", 1.0, 3.0, "Jog")]
    # the committed labels of the shared clips read
    assert {r[0] for r in read_labels(REPO / "benchmarks" / "videos" / "shared_labels.csv")} == {
        "pose_squats.mp4",
        "pose_1.mp4",
    }


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("a.mp4,0,1\n", r"l\.csv:1: expected file,start,end,label"),
        ("a.mp4,0,x,Squat\n", r"l\.csv:1: start and end must be seconds"),
        ("a.mp4,0,1,Squat\na.mp4,3,2,Jog\n", r"l\.csv:2: need 0 <= start < end"),
        ("a.mp4,0,1,\n", r"l\.csv:1: empty label"),
        ("# nothing\n", r"l\.csv: no labelled spans"),
    ],
)
def test_bad_label_files_name_file_and_line(tmp_path: Path, text: str, message: str) -> None:
    p = tmp_path / "l.csv"
    p.write_text(text)
    with pytest.raises(LabelFileError, match=message):
        read_labels(p)
    with pytest.raises(LabelFileError, match="no such file"):
        read_labels(tmp_path / "none.csv")


def test_the_real_video_benchmark_runs_mimic_evaluates_flags() -> None:
    """bench_real_video prepares each video with the command line's own code, its options
    passed on as ``mimic evaluate``'s flags: each must be one that flag sets."""
    from benchmarks.bench_real_video import _run_args
    from control.graph import GraphOptions
    from mimic.cli import build_parser

    flags = _run_args(
        ["13_*"], GraphOptions(sigma_scale=0.5), True, "outline", 2.0, ["--vote", "7"]
    )
    argv = ["evaluate", "v.mp4", "--labels", "l.csv", "--json", "o.json", *flags]
    args = build_parser().parse_args(argv)
    assert (args.clips, args.coords, args.sigma_scale) == (["13_*"], "fixed", 0.5)
    assert (args.variants, args.descriptor, args.recency, args.vote) == (True, "outline", 2.0, 7)
