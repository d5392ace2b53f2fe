"""``mimic cache``: what the cache holds, and clearing it (``control.artifacts``)."""

from __future__ import annotations

import argparse
import time

from control.artifacts import (
    CACHE_KINDS,
    bound_cache,
    cache_entries,
    cache_limit,
    cache_root,
    clear_cache,
)

__all__ = ["add_cache_command"]

from .args import number


def add_cache_command(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    cache = sub.add_parser(
        "cache",
        help="show or clear the cache (parsed motion, graphs, layers, banks)",
        description=(
            "The cache is $MIMIC_CACHE, else $XDG_CACHE_HOME/mimic, else ~/.cache/mimic. "
            "After each new entry the least recently used ones are removed until it holds "
            "at most $MIMIC_CACHE_MAX_GB gigabytes (default 8). Everything in it is rebuilt "
            "when needed, so clearing it only costs time."
        ),
    )
    cache_sub = cache.add_subparsers(dest="cache_command")
    cache.set_defaults(func=_info)
    info = cache_sub.add_parser("info", help="where the cache is and what it holds (default)")
    info.set_defaults(func=_info)
    clear = cache_sub.add_parser("clear", help="remove entries (all of them by default)")
    clear.add_argument(
        "--kind",
        action="append",
        choices=CACHE_KINDS,
        help="only entries of this kind (repeat for several)",
    )
    clear.add_argument(
        "--older-than",
        type=number(float, 0, 36500),
        default=0.0,
        metavar="DAYS",
        help="only entries not used for this many days",
    )
    clear.set_defaults(func=_clear)
    trim = cache_sub.add_parser(
        "trim", help="remove the least recently used entries down to the size limit now"
    )
    trim.set_defaults(func=_trim)


def _mb(n: int) -> str:
    return f"{n / 1e6:,.1f} MB"


def _info(args: argparse.Namespace) -> int:
    root = cache_root()
    entries = cache_entries(root)
    print(f"cache: {root}  (limit {cache_limit() / 1e9:g} GB, $MIMIC_CACHE_MAX_GB)")
    now = time.time()
    for kind in CACHE_KINDS:
        mine = [e for e in entries if e.kind == kind]
        if mine:
            age = (now - mine[0].used) / 86400.0
            print(
                f"  {kind:<7} {len(mine):>5} entries  {_mb(sum(e.bytes for e in mine)):>12}"
                f"  least recently used {age:.1f} days ago"
            )
        else:
            print(f"  {kind:<7}     0 entries")
    print(f"  total   {len(entries):>5} entries  {_mb(sum(e.bytes for e in entries)):>12}")
    return 0


def _clear(args: argparse.Namespace) -> int:
    if args.older_than < 0:
        raise ValueError(f"--older-than {args.older_than}: a number of days, 0 or more")
    removed = clear_cache(args.kind or CACHE_KINDS, args.older_than)
    print(
        f"removed {len(removed)} entries, {_mb(sum(e.bytes for e in removed))}, from {cache_root()}"
    )
    return 0


def _trim(args: argparse.Namespace) -> int:
    removed = bound_cache()
    print(
        f"removed {len(removed)} entries, {_mb(sum(e.bytes for e in removed))}: "
        f"the cache holds at most {cache_limit() / 1e9:g} GB"
    )
    return 0
