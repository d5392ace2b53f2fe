"""Fault injection over every artifact mimic writes for itself (issue 19): the table of
cases and outcomes.

Usage: python -m benchmarks.bench_faults [LIBRARY_DIR] [--flips N] [--truncations N]
       [--seed S] [--out FILE]

For each artifact (a parsed-motion cache entry, a graph in the cache and given as a file,
a higher layer, a bank's manifest.json, bank.npz and features.npy, the window index and
the window tables (their manifest and a table) beside a bank, a .motion.npz),
``--flips`` single bytes flipped at random, ``--truncations`` random truncations and
every consistent edit in ``tests/faults.py`` (a manifest's fps set to 30, sigma NaN,
clip names swapped, a bank's n_views set to 9, the root moved 1 m, features of NaN,
...). The outcome of each: the same result, a rebuild with a warning naming the file,
or an error naming the file; anything else (a traceback, other data used silently) is a
failure, listed in full.
"""

from __future__ import annotations

import argparse
import logging
import time
from pathlib import Path

from benchmarks._report import machine, save
from control.motion import default_library_path
from tests.faults import GOOD, sweep, table


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("library", nargs="?", default=None)
    ap.add_argument("--flips", type=int, default=200)
    ap.add_argument("--truncations", type=int, default=50)
    ap.add_argument("--seed", type=int, default=2026)
    ap.add_argument("--out", default="benchmarks/results/faults.json")
    args = ap.parse_args()
    # thousands of rebuild warnings: kept from stderr (the table says what they said) but
    # still seen by the sweep, which needs them to tell a rebuild from a silent reuse
    logging.getLogger().addHandler(logging.NullHandler())
    mocap = Path(args.library) if args.library else default_library_path()
    t0 = time.perf_counter()
    outcomes = sweep(mocap, args.flips, args.truncations, args.seed)
    failures = [o for o in outcomes if o.outcome not in GOOD]
    result = {
        "machine": machine(),
        "library": str(mocap),
        "flips": args.flips,
        "truncations": args.truncations,
        "seed": args.seed,
        "seconds": round(time.perf_counter() - t0, 1),
        "table": table(outcomes),
        "cases": len(outcomes),
        "failures": [vars(o) for o in failures],
        "edits": [vars(o) for o in outcomes if not o.case.startswith(("flip", "truncate"))],
    }
    save(result, args.out)
    return 1 if failures else 0


if __name__ == "__main__":
    raise SystemExit(main())
