"""Progress lines on stderr: quiet for quick steps, one finished line in a log."""

from __future__ import annotations

import io
import time

from control.progress import bar, step


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_a_log_gets_one_finished_line_and_quick_work_none() -> None:
    log = io.StringIO()
    update = bar("bank", "shards", stream=log, quiet_s=0.0)
    for k in range(4):
        update(k, 3)
    assert log.getvalue().count("\n") == 1 and "bank [" in log.getvalue()
    assert "3/3 shards" in log.getvalue() and "\r" not in log.getvalue()
    quiet = io.StringIO()
    update = bar("bank", stream=quiet, quiet_s=60.0)
    update(3, 3)
    assert quiet.getvalue() == ""
    with step("graph", stream=quiet, quiet_s=60.0):
        pass
    assert quiet.getvalue() == ""
    with step("graph", stream=log, quiet_s=0.0):
        time.sleep(0.01)
    assert log.getvalue().splitlines()[-1].startswith("graph ... ")


def test_a_terminal_redraws_the_bar_in_place() -> None:
    tty = _Tty()
    update = bar("bank", stream=tty, quiet_s=0.0)
    update(1, 3)
    update(3, 3)
    assert tty.getvalue().count("\r") == 2 and tty.getvalue().endswith("s\n")


def test_a_long_build_is_said_with_its_rate_and_time_left() -> None:
    now = [0.0]
    log = io.StringIO()
    update = bar("bank", "renders", stream=log, quiet_s=1.0, every_s=30.0, clock=lambda: now[0])
    for t, done in ((10.0, 100), (31.0, 310), (40.0, 400), (61.5, 615), (100.0, 1000)):
        now[0] = t
        update(done, 1000)
    lines = log.getvalue().splitlines()
    assert len(lines) == 3  # at 31 s and 61.5 s (30 s apart at most), then finished
    assert lines[0].endswith("310/1000 renders, 10 renders/s, ETA 1:09")
    assert lines[1].endswith("615/1000 renders, 10 renders/s, ETA 0:38")
    assert lines[2].endswith("1000/1000 renders, 10 renders/s, 100.0 s")
    tty, now[0] = _Tty(), 0.0
    update = bar("layer", stream=tty, quiet_s=0.0, clock=lambda: now[0])
    now[0] = 4000.0
    update(1, 3)  # the first work: no rate yet
    assert tty.getvalue().endswith("1/3")
    now[0] = 8000.0
    update(2, 3)  # one more in 4,000 s: 4,000 s left
    assert tty.getvalue().endswith("2/3, 0.00025/s, ETA 1:06:40")


def test_the_time_before_the_first_work_is_not_the_works_rate() -> None:
    """A cluster's start and the features sent to its workers took 30 s before the
    first of 455 jobs; the jobs then came at 1 a second. The first line says no rate
    (it said "ETA 3:48:53"), the next the jobs' own; the finished line the whole."""
    now = [0.0]
    log = io.StringIO()
    update = bar("graph", "jobs", stream=log, quiet_s=1.0, every_s=30.0, clock=lambda: now[0])
    for t, done in ((30.0, 1), (60.0, 31), (485.0, 455)):
        now[0] = t
        update(done, 455)
    lines = log.getvalue().splitlines()
    assert lines[0].endswith("1/455 jobs")
    assert lines[1].endswith("31/455 jobs, 1 jobs/s, ETA 7:04")
    assert lines[2].endswith("455/455 jobs, 0.938 jobs/s, 485.0 s")
