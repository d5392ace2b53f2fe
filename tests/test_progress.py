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
