"""The bank's cache front door, the same as the graph's and the higher layer's
(``control.graph.cached_graph``, ``control.clusters.cached_higher_layer``): one call
shape, ``(artifact, path, built)`` back, and ``control.artifacts.cached_entry``'s locking
(of two processes asking at once, one builds and the other waits and loads its bank).

A bank is a folder, not a file: its entry is ``<cache>/<key>/`` and its ``manifest.json``
says whether it is complete. An interrupted build resumes from the shards it wrote.
"""

from __future__ import annotations

import logging
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from control.artifacts import LOCK_NAME, bound_cache, cached_entry, touch
from control.motion import Clip, clips_digest

from ._bank import Bank, BankFileError, bank_cache_dir, bank_key, build_bank, load_bank
from ._settings import BankSettings

__all__ = ["cached_bank", "ensure_bank"]

log = logging.getLogger(__name__)


def _load(folder: Path, clips: Sequence[Clip], settings: BankSettings) -> Bank | None:
    """The bank in ``folder`` when it is complete and of ``clips`` and ``settings``,
    else ``None`` (a damaged one said with a warning; an incomplete one resumes
    quietly)."""
    try:
        bank = load_bank(folder, clips, settings)
    except FileNotFoundError:
        return None
    except BankFileError as exc:
        if "incomplete" not in exc.problem:
            log.warning("rebuilding the bank: %s", exc)
        return None
    touch(folder)
    return bank


def _clear(folder: Path) -> None:
    """Every file of the bank in ``folder`` removed (its lock kept: it is held)."""
    for f in folder.iterdir():
        if f.is_file() and f.name != LOCK_NAME:
            f.unlink()


def ensure_bank(
    clips: Sequence[Clip],
    settings: BankSettings,
    folder: str | Path,
    rebuild: bool = False,
    **build_options: Any,
) -> tuple[Bank, bool]:
    """The bank of ``clips`` with ``settings`` in ``folder`` (one of the user's, or the
    cache's entry): loaded when complete and fresh, else (re)built there, resuming what an
    interrupted build wrote; ``rebuild``: built from nothing whatever is there.
    ``build_options`` go to ``build_bank``. Returns ``(bank, built)``."""
    folder = Path(folder)

    def make() -> Bank:
        if rebuild and folder.is_dir():
            _clear(folder)
        return build_bank(clips, settings, folder, **build_options)

    return cached_entry(
        folder / "manifest.json", lambda: _load(folder, clips, settings), make, rebuild
    )


def cached_bank(
    clips: Sequence[Clip],
    settings: BankSettings | None = None,
    cache_dir: str | Path | None = None,
    rebuild: bool = False,
    cluster: str | None = None,
    **build_options: Any,
) -> tuple[Bank, Path, bool]:
    """The bank of ``clips`` with ``settings`` (default ``BankSettings()``) from the
    cache (``bank_cache_dir()``, or ``cache_dir``), built and stored when missing, stale
    or unreadable (rendered on ``cluster`` where one is named; ``build_options``: as
    ``build_bank`` takes them). Returns ``(bank, folder, built)``."""
    settings = settings or BankSettings()
    root = Path(cache_dir) if cache_dir is not None else bank_cache_dir()
    folder = root / bank_key(clips_digest(clips), settings)
    bank, built = ensure_bank(clips, settings, folder, rebuild, cluster=cluster, **build_options)
    if built and cache_dir is None:
        bound_cache(keep=[folder])
    return bank, folder, built
