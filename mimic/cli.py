"""The ``mimic`` command line: the parser, the error handling and the signals; one module
of this package per subcommand."""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading
from collections.abc import Sequence

from control.graph import GraphFileError
from control.jobs import ClusterError
from control.motion import MotionFormatError
from silhouette_bank import BankFileError
from vision import SourceError

from .bank import add_bank_commands
from .cache import add_cache_command
from .chain import add_chain_command
from .choose import add_choose_command
from .evaluate import add_evaluate_command
from .graph import add_graph_commands
from .library import add_library_commands
from .perform import add_perform_command
from .play import add_play_command
from .record import add_record_command
from .sketch import add_sketch_command
from .vendor import add_vendor_command

__all__ = ["build_parser", "main"]


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="mimic",
        description="An avatar animated with real motion capture that follows a performer.",
    )
    parser.add_argument("-v", "--verbose", action="store_true", help="log progress")
    sub = parser.add_subparsers(dest="command", required=True)
    add_library_commands(sub)
    add_graph_commands(sub)
    add_choose_command(sub)
    add_bank_commands(sub)
    add_perform_command(sub)
    add_play_command(sub)
    add_evaluate_command(sub)
    add_record_command(sub)
    add_chain_command(sub)
    add_sketch_command(sub)
    add_cache_command(sub)
    add_vendor_command(sub)
    return parser


def _terminate(signum: int, frame: object) -> None:
    """SIGTERM and SIGHUP end a command as Ctrl-C does, through Python, so that files
    being written are removed or finished rather than left half-written (``mimic
    perform`` handles them itself: it writes what was performed)."""
    raise SystemExit(128 + signum)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    try:  # a bad option is said by argparse (naming it), and is exit status 2
        args = parser.parse_args(argv)
    except SystemExit as exc:
        return exc.code if isinstance(exc.code, int) else 2
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    old: dict[int, object] = {}
    if threading.current_thread() is threading.main_thread():
        for name in ("SIGTERM", "SIGHUP"):
            if hasattr(signal, name):
                sig = getattr(signal, name)
                old[sig] = signal.signal(sig, _terminate)
    try:
        return int(args.func(args))
    except KeyboardInterrupt:
        print("mimic: interrupted", file=sys.stderr)
        return 130
    except (
        MotionFormatError,
        GraphFileError,
        BankFileError,
        ClusterError,
        SourceError,
        FileNotFoundError,
        KeyError,
        ValueError,
        OSError,
        ImportError,  # an optional dependency that is not installed (the message says how)
    ) as exc:
        print(f"mimic: error: {exc}", file=sys.stderr)
        return 2
    finally:
        for sig, handler in old.items():
            signal.signal(sig, handler)  # type: ignore[arg-type]


if __name__ == "__main__":
    sys.exit(main())
