"""The ``mimic`` command line. Subcommands live beside the code they drive."""

from __future__ import annotations

import argparse
import logging
import signal
import sys
import threading
from collections.abc import Sequence

from control.cache_cli import add_cache_command
from control.cli import add_graph_commands, add_library_commands
from control.graph import GraphFileError
from control.motion import MotionFormatError
from silhouette_bank._bank import BankFileError
from silhouette_bank.cli import add_bank_commands
from vision._sources import SourceError
from vision.chain_cli import add_chain_command
from vision.perform_cli import add_perform_commands
from vision.sketch_cli import add_sketch_command

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
    add_bank_commands(sub)
    add_perform_commands(sub)
    add_chain_command(sub)
    add_sketch_command(sub)
    add_cache_command(sub)
    return parser


def _terminate(signum: int, frame: object) -> None:
    """SIGTERM and SIGHUP end a command as Ctrl-C does, through Python, so that files
    being written are removed or finished rather than left half-written (``mimic
    perform`` handles them itself: it writes what was performed)."""
    raise SystemExit(128 + signum)


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
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
