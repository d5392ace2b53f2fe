"""The files a command writes: every one checked before any work, each written to a
temporary file beside its place, and all moved into place together once every one is
written.

Why: an output that names an input (``perform --video in.mkv --out in.mkv``) would
destroy the recording and its ground truth; two outputs that name one file would
overwrite each other; an unwritable place found after a long performance loses it; a
run that fails half way must not leave a new log beside the old BVH. So a clash or an
unwritable place is an error before the first frame that names the option and the path
the user gave; a write that fails replaces nothing, removes its temporary files and says
which file failed and why (a full disk: how much room was left). A run that is stopped
(Ctrl-C) still writes its set: a stop is not a failure.
"""

from __future__ import annotations

import errno
import os
import tempfile
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import TracebackType

from control.artifacts import current_umask, room_left

__all__ = ["Output", "OutputError", "OutputSet", "check_outputs"]


class OutputError(ValueError):
    """An output that cannot be written where it is asked for, said before any work."""


@dataclass(frozen=True)
class Output:
    """A file a command writes: ``option`` names it as the user did (``--out``, or
    ``--out's timing file`` for one that comes with it), ``path`` as given."""

    option: str
    path: Path
    #: a video's codec (a FOURCC, ``"mp4v"``), whose container OpenCV's writer picks by
    #: the file's suffix: checked before any work; ``None``: any name will do
    fourcc: str | None = None

    def said(self) -> str:
        return f"{self.option} {self.path}"


def _identity(path: Path) -> tuple[object, ...]:
    """What makes two names one file: its device and inode where it exists (a hard
    link, a symlink), else its resolved path."""
    try:
        st = path.stat()
    except OSError:
        return ("path", os.path.realpath(path))
    return ("inode", st.st_dev, st.st_ino)


class OutputSet:
    """The outputs of one run (``outputs``, ``None`` paths left out), checked against
    each other and against its ``inputs`` (``(what, path)``: the files and folders it
    reads, sidecars included) when made: raises ``OutputError`` naming both options of
    a clash, or the option of a place that cannot be written.

    ``write(output, fn)`` has ``fn`` write the output's temporary file; ``commit()``
    moves every written one into place (and returns them); ``discard()`` (also on
    leaving a ``with`` by an exception) removes the temporary files and replaces
    nothing."""

    def __init__(
        self,
        outputs: Sequence[Output | None],
        inputs: Sequence[tuple[str, str | Path | None]] = (),
    ) -> None:
        self.outputs = [
            Output(o.option, Path(o.path).expanduser(), o.fourcc) for o in outputs if o is not None
        ]
        self._staged: dict[Output, Path] = {}
        self._written: list[Output] = []
        read: dict[tuple[object, ...], str] = {}
        for what, path in inputs:
            if path is not None:
                read.setdefault(_identity(Path(path).expanduser()), f"{what} {path}")
        written: dict[tuple[object, ...], str] = {}
        for out in self.outputs:  # (clashes first: a refused run makes no folder)
            key = _identity(out.path)
            if key in read:
                raise OutputError(
                    f"{out.said()}: the same file as {read[key]}, which this run reads "
                    "(an output never replaces an input)"
                )
            if key in written:
                raise OutputError(
                    f"{out.said()}: the same file as {written[key]} (two outputs cannot "
                    "share a file)"
                )
            written[key] = out.said()
        for out in self.outputs:
            self._check_place(out)

    @staticmethod
    def _check_place(out: Output) -> None:
        path = out.path
        if path.is_dir():
            raise OutputError(f"{out.said()}: is a folder, not a file")
        if path.exists() and not path.is_file():
            raise OutputError(f"{out.said()}: is not a regular file (a device or a pipe)")
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(
                f"{out.said()}: cannot make its folder {path.parent} ({exc.strerror or exc})"
            ) from None
        # the one reliable test of a place: writing there (a read-only mount, /proc); and
        # of a video's name: its writer opening a file named so
        try:
            fd, probe = tempfile.mkstemp(
                prefix=f".{path.name}.", suffix=f".probe{path.suffix}", dir=path.parent
            )
            os.close(fd)
        except OSError as exc:
            raise OutputError(
                f"{out.said()}: cannot write in {path.parent} ({exc.strerror or exc})"
            ) from None
        try:
            video_ok = out.fourcc is None or _video_opens(probe, out.fourcc)
        finally:
            Path(probe).unlink(missing_ok=True)  # (a failed video writer may remove it)
        if not video_ok:
            named = f"ending {path.suffix!r}" if path.suffix else "without a suffix"
            raise OutputError(
                f"{out.said()}: a video in {out.fourcc} cannot be written to a file {named} "
                "(its suffix picks the container); name it .mp4, .mkv or .avi"
            )

    def find(self, option: str) -> Output | None:
        return next((o for o in self.outputs if o.option == option), None)

    def stage(self, out: Output) -> Path:
        """A new temporary file of ``out``'s, beside it, with its suffix (a video
        writer picks its format by it)."""
        if out not in self._staged:
            fd, name = tempfile.mkstemp(
                prefix=f".{out.path.name}.", suffix=f".tmp{out.path.suffix}", dir=out.path.parent
            )
            os.close(fd)
            os.chmod(name, 0o666 & ~current_umask())  # as open() would make it
            self._staged[out] = Path(name)
        return self._staged[out]

    def write(self, out: Output, fn: Callable[[Path], object]) -> None:
        """``fn(temporary path)`` writes ``out``; an ``OSError`` of it is said as
        ``out``'s (the option and path given, a full disk's room left)."""
        tmp = self.stage(out)
        try:
            fn(tmp)
        except OSError as exc:
            raise OSError(self._failed(out, exc)) from None
        self._written.append(out)

    def _failed(self, out: Output, exc: OSError) -> str:
        if exc.errno in (errno.ENOSPC, errno.EDQUOT):
            return (
                f"{out.said()}: the disk is full: it needs more room than the "
                f"{room_left(out.path.parent)} left in {out.path.parent}; nothing was replaced"
            )
        why = exc.strerror or str(exc)
        return f"{out.said()}: could not be written ({why}); nothing was replaced"

    def commit(self) -> list[Output]:
        """Every written output moved into place (renames in their own folders, which
        need no room); their temporary files of any not written removed."""
        for out in self._written:
            os.replace(self._staged.pop(out), out.path)
        done, self._written = self._written, []
        self.discard()
        return done

    def discard(self) -> None:
        for tmp in self._staged.values():
            tmp.unlink(missing_ok=True)
        self._staged.clear()
        self._written = []

    def __enter__(self) -> OutputSet:
        return self

    def __exit__(
        self,
        kind: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.discard()  # (after a commit there is nothing left to remove)


def _video_opens(probe: str, fourcc: str) -> bool:
    """Whether OpenCV's video writer opens the file ``probe`` (its suffix picks the
    container) for the codec ``fourcc``."""
    import cv2

    logs = cv2.utils.logging
    level = logs.getLogLevel()
    logs.setLogLevel(logs.LOG_LEVEL_SILENT)  # (its reasons are OpenCV's, not the user's)
    try:
        writer = cv2.VideoWriter(probe, cv2.VideoWriter.fourcc(*fourcc), 10.0, (16, 16))
        opened = bool(writer.isOpened())
        writer.release()
    finally:
        logs.setLogLevel(level)
    return opened


def check_outputs(
    args: object,
    options: Sequence[str],
    inputs: Sequence[str] = (),
    also: Sequence[tuple[str, str]] = (),
    videos: Mapping[str, str] | None = None,
) -> OutputSet:
    """The outputs named by ``args``' ``options`` (``"--out"``: ``args.out``; unset
    ones left out) and ``also`` (``(what, path)``: a file one of them brings, such as a
    recording's sidecar), checked against each other and the inputs named by ``inputs``,
    before a command does any work (``OutputError``). The commands that write one file,
    or files that need not agree, write each atomically themselves; the set is returned
    for those that replace theirs together. ``videos`` maps the options that name a
    video to its codec (``Output.fourcc``)."""

    def value(option: str) -> str | None:
        got = getattr(args, option.lstrip("-").replace("-", "_"), None)
        return str(got) if got is not None else None

    codecs = videos or {}
    outs = [Output(o, Path(v), codecs.get(o)) for o in options if (v := value(o)) is not None]
    outs += [Output(what, Path(path)) for what, path in also]
    return OutputSet(outs, [(o, value(o)) for o in inputs])
