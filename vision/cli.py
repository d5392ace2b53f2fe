"""The ``mimic`` command line. Subcommands live beside the code they drive."""

from __future__ import annotations

import argparse
import logging
import sys
from collections.abc import Sequence

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
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    logging.basicConfig(
        level=logging.INFO if args.verbose else logging.WARNING,
        format="%(levelname)s %(name)s: %(message)s",
    )
    try:
        return int(args.func(args))
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


if __name__ == "__main__":
    sys.exit(main())
