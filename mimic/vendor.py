"""``mimic vendor-three``: refresh the live page's vendored three.js from the npm
registry (maintainers; the page never reaches the network)."""

from __future__ import annotations

import argparse

from vision import THREE_VERSION, vendor_three

__all__ = ["add_vendor_command"]


def add_vendor_command(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    p = sub.add_parser(
        "vendor-three",
        help="refresh the live page's three.js from the npm registry (maintainers)",
        description="Fetch three.js from registry.npmjs.org (its tarball checked against the "
        "registry's sha512) and write its minified module and LICENSE into vision/static.",
    )
    p.add_argument(
        "--version", default=THREE_VERSION, help=f"three's version (default {THREE_VERSION})"
    )
    p.set_defaults(func=_vendor)


def _vendor(args: argparse.Namespace) -> int:
    for path, size in vendor_three(args.version):
        print(f"wrote {path} ({size} bytes)")
    return 0
