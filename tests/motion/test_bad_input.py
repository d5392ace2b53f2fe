"""Bad input: one error type, naming the file, the line and the problem; and a fuzz loop."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from control.motion import MotionFormatError, read_amc, read_asf, read_bvh
from tests.conftest import BVH_DIR, amc_path, asf_path
from tests.motion.tiny import TINY_ASF


def _real(clip: str) -> bytes:
    return amc_path(clip).read_bytes()


def _expect(fn, path: Path, line: int | None, words: str) -> MotionFormatError:  # type: ignore[no-untyped-def]
    with pytest.raises(MotionFormatError) as info:
        fn(path)
    err = info.value
    assert err.path == str(path)
    assert err.line == line, str(err)
    assert words in err.problem, str(err)
    assert str(err).startswith(f"{path}:{line}: " if line else f"{path}: ")
    return err


@pytest.fixture(scope="module")
def asf02():  # type: ignore[no-untyped-def]
    return read_asf(asf_path("02_03"))


def _amc_lines(clip: str = "02_03") -> list[bytes]:
    return _real(clip).split(b"\r\n")


def _save(tmp_path: Path, name: str, lines: list[bytes]) -> Path:
    p = tmp_path / name
    p.write_bytes(b"\r\n".join(lines))
    return p


def test_amc_truncated_mid_frame(tmp_path: Path, asf02) -> None:  # type: ignore[no-untyped-def]
    lines = _amc_lines()
    # Line 4 is frame 1; keep frame 1 and the first 5 bone lines of frame 2.
    p = _save(tmp_path, "trunc.amc", lines[: 3 + 30 + 6])
    _expect(lambda q: read_amc(q, asf02), p, 39, "frame 2 (line 34) lacks bone(s)")


def test_amc_truncated_mid_line(tmp_path: Path, asf02) -> None:  # type: ignore[no-untyped-def]
    lines = _amc_lines()
    p = _save(tmp_path, "cut.amc", [*lines[:40], lines[40][:12]])
    _expect(lambda q: read_amc(q, asf02), p, 41, "expects")


def test_amc_garbled_number(tmp_path: Path, asf02) -> None:  # type: ignore[no-untyped-def]
    lines = _amc_lines()
    lines[99] = lines[99].replace(b" ", b" 1x2", 1)[: len(lines[99]) + 1]
    p = _save(tmp_path, "garbled.amc", lines)
    _expect(lambda q: read_amc(q, asf02), p, 100, "is not a number")


def test_amc_wrong_dof_count(tmp_path: Path, asf02) -> None:  # type: ignore[no-untyped-def]
    lines = _amc_lines()
    assert lines[4].startswith(b"root ")
    lines[5] = b"lowerback 1.0 2.0"  # three dofs: rx ry rz
    p = _save(tmp_path, "dof.amc", lines)
    _expect(
        lambda q: read_amc(q, asf02), p, 6, "bone 'lowerback' expects 3 values (rx ry rz), got 2"
    )


def test_amc_nan(tmp_path: Path, asf02) -> None:  # type: ignore[no-untyped-def]
    lines = _amc_lines()
    lines[7] = lines[7].split(b" ")[0] + b" nan 0 0"
    p = _save(tmp_path, "nan.amc", lines)
    _expect(lambda q: read_amc(q, asf02), p, 8, "is not a finite number")


def test_amc_not_utf8(tmp_path: Path, asf02) -> None:  # type: ignore[no-untyped-def]
    lines = _amc_lines()
    lines[20] = lines[20] + b"\xff\xfe"
    p = _save(tmp_path, "latin.amc", lines)
    _expect(lambda q: read_amc(q, asf02), p, 21, "not UTF-8")


def test_empty_files(tmp_path: Path, asf02) -> None:  # type: ignore[no-untyped-def]
    for name, fn in (
        ("e.amc", lambda q: read_amc(q, asf02)),
        ("e.asf", read_asf),
        ("e.bvh", read_bvh),
    ):
        p = tmp_path / name
        p.write_bytes(b"  \r\n")
        _expect(fn, p, None, "empty")


def test_missing_file(tmp_path: Path) -> None:
    _expect(read_bvh, tmp_path / "nope.bvh", None, "cannot read")


def test_mismatched_skeleton_and_motion(tmp_path: Path) -> None:
    tiny = tmp_path / "tiny.asf"
    tiny.write_text(TINY_ASF)
    asf = read_asf(tiny)
    p = tmp_path / "02_03.amc"
    p.write_bytes(_real("02_03"))
    _expect(lambda q: read_amc(q, asf), p, 6, "bone 'lowerback' is not in the skeleton")


def test_asf_problems(tmp_path: Path) -> None:
    cases = [
        (TINY_ASF.replace("    dof rz\n", "    dof rq\n"), "bone dof 'rq'"),
        (TINY_ASF.replace("    a b\n", "    a c\n"), "unknown bone 'c'"),
        (
            TINY_ASF.replace("length 10\n     axis 0 0 90", "length ten\n     axis 0 0 90"),
            "not a number",
        ),
        (TINY_ASF.replace("axis 0 0 90 XYZ", "axis 0 0 90 XXZ"), "not a permutation"),
        (TINY_ASF.split(":hierarchy")[0], "no :hierarchy section"),
    ]
    for k, (text, words) in enumerate(cases):
        p = tmp_path / f"bad{k}.asf"
        p.write_text(text)
        with pytest.raises(MotionFormatError, match=words) as info:
            read_asf(p)
        assert str(p) in str(info.value)


def test_bvh_problems(tmp_path: Path) -> None:
    good = (BVH_DIR / "02_03.bvh").read_bytes().decode()
    lines = good.splitlines()
    motion_at = lines.index("MOTION")
    cases = [
        ("\n".join(lines[:-3]), motion_at + 4, "'Frames: 174' but 171 lines"),
        (
            good.replace(
                "CHANNELS 3 Zrotation Xrotation Yrotation",
                "CHANNELS 3 Zrotation Xrotation Wrotation",
                1,
            ),
            9,
            "unknown channel 'Wrotation'",
        ),
        (good.replace("{", "", 2), 4, "expected '{', got 'OFFSET'"),
        (
            "\n".join(
                [*lines[: motion_at + 3], lines[motion_at + 3] + " 1.0", *lines[motion_at + 4 :]]
            ),
            motion_at + 4,
            "frame 0 has",
        ),
        (
            "\n".join(
                [
                    *lines[: motion_at + 5],
                    "NaN " + lines[motion_at + 5].split(" ", 1)[1],
                    *lines[motion_at + 6 :],
                ]
            ),
            motion_at + 6,
            "not a finite number",
        ),
        (good.replace("Frame Time:", "Frame Tme:"), motion_at + 3, "expected 'Frame Time"),
    ]
    for k, (text, line, words) in enumerate(cases):
        p = tmp_path / f"bad{k}.bvh"
        p.write_text(text)
        _expect(read_bvh, p, line, words)


# --- fuzz ----------------------------------------------------------------------------------

_TOKENS = [
    b"nan",
    b"inf",
    b"-1e999",
    b"1e300",
    b"",
    b"x",
    b"{",
    b"}",
    b"JOINT",
    b"End",
    b"-",
    b"1.2.3",
    b"\xff",
    b"\x00",
    b"9999999999",
    b"\xc2\xb2",
    b":",
    b"#",
    b"root",
    b"begin",
]


def _mutate(data: bytes, rng: np.random.Generator) -> bytes:
    lines = data.split(b"\n")
    kind = int(rng.integers(7))
    i = int(rng.integers(len(lines)))
    if kind == 0:  # delete a line
        del lines[i]
    elif kind == 1:  # duplicate a line
        lines.insert(i, lines[i])
    elif kind == 2:  # truncate at a random byte
        return data[: int(rng.integers(len(data)))]
    elif kind == 3:  # flip bytes
        buf = bytearray(data)
        for _ in range(int(rng.integers(1, 4))):
            buf[int(rng.integers(len(buf)))] = int(rng.integers(256))
        return bytes(buf)
    elif kind == 4:  # replace a token
        words = lines[i].split(b" ")
        words[int(rng.integers(len(words)))] = _TOKENS[int(rng.integers(len(_TOKENS)))]
        lines[i] = b" ".join(words)
    elif kind == 5:  # swap two lines
        j = int(rng.integers(len(lines)))
        lines[i], lines[j] = lines[j], lines[i]
    else:  # insert a junk token line
        lines.insert(i, _TOKENS[int(rng.integers(len(_TOKENS)))])
    return b"\n".join(lines)


@pytest.mark.slow
def test_fuzz_real_files_raise_only_motion_format_error(
    tmp_path: Path, rng: np.random.Generator
) -> None:
    asf_bytes = asf_path("02_03").read_bytes()
    amc_bytes = _real("02_03")
    bvh_bytes = (BVH_DIR / "02_03.bvh").read_bytes()
    good_asf = read_asf(asf_path("02_03"))
    outcomes = {"ok": 0, "error": 0}
    for k in range(450):
        which = k % 3
        p = tmp_path / f"m{k}.{('asf', 'amc', 'bvh')[which]}"
        try:
            if which == 0:
                p.write_bytes(_mutate(asf_bytes, rng))
                asf = read_asf(p)
                read_amc(amc_path("02_03"), asf)
            elif which == 1:
                p.write_bytes(_mutate(amc_bytes, rng))
                read_amc(p, good_asf)
            else:
                p.write_bytes(_mutate(bvh_bytes, rng))
                read_bvh(p)
            outcomes["ok"] += 1
        except MotionFormatError as exc:
            assert exc.path and exc.problem
            outcomes["error"] += 1
        p.unlink()
    # The mutations must exercise both outcomes.
    assert outcomes["ok"] > 20 and outcomes["error"] > 100, outcomes


def test_a_very_deep_chain_writes_and_reads_back(tmp_path: Path) -> None:
    from control.motion import Motion, Skeleton, write_bvh

    n = 1200  # deeper than Python's recursion limit
    sk = Skeleton(
        tuple(f"j{i}" for i in range(n)),
        np.arange(-1, n - 1),
        np.tile([0.0, 0.01, 0.0], (n, 1)),
        (("Xposition", "Yposition", "Zposition", "Zrotation", "Xrotation", "Yrotation"),)
        + (("Zrotation", "Xrotation", "Yrotation"),) * (n - 1),
        np.array([n - 1]),
        np.array([[0.0, 0.01, 0.0]]),
    )
    q = np.zeros((2, n, 4))
    q[..., 0] = 1.0
    m = Motion(sk, np.zeros((2, 3)), q, 30.0, "chain")
    path = tmp_path / "chain.bvh"
    write_bvh(m, path)
    back = read_bvh(path, units="m")
    assert back.skeleton.n_joints == n and back.n_frames == 2


def test_a_walk_in_a_tiny_component_is_a_clear_error(mocap: Path) -> None:
    from control.graph import GraphOptions, build_graph, random_walk
    from control.motion import load_library

    lib = load_library(mocap, clips=["02_03"])
    g = build_graph(lib.clips, GraphOptions(threshold=1e-6, sigma_scale=0.01, similarity=False))
    assert g.in_scc.sum() < 2
    with pytest.raises(ValueError, match="too small to walk in"):
        random_walk(g, 30)


def test_bvh_frames_of_the_wrong_length_are_named_even_when_the_total_fits(
    tmp_path: Path,
) -> None:
    src = (BVH_DIR / "02_03.bvh").read_text().replace("\r\n", "\n").splitlines()
    k = next(i for i, line in enumerate(src) if line.startswith("Frame Time")) + 1
    one, two = src[k + 3].split(), src[k + 4].split()
    src[k + 3] = " ".join(one[:-1])  # a value short
    src[k + 4] = " ".join([*two, "0"])  # a value over: the total still fits
    path = tmp_path / "shift.bvh"
    path.write_text("\n".join(src) + "\n")
    with pytest.raises(MotionFormatError, match=rf"shift\.bvh:{k + 4}"):
        read_bvh(path)


def test_lengths_and_roots_are_checked_after_the_units(tmp_path: Path) -> None:
    p = tmp_path / "huge.asf"
    # 1e8 inches passes the number range, and is 2,540 km after the units
    p.write_text(TINY_ASF.replace("length 10\n", "length 100000000\n", 1))
    with pytest.raises(MotionFormatError, match=r"huge\.asf.*m long after the units"):
        read_asf(p)
    asf02 = read_asf(asf_path("02"))
    amc = _real("02_03").decode().replace("\r\n", "\n").split("\n")
    k = next(i for i, line in enumerate(amc) if line.startswith("root "))
    parts = amc[k].split()
    parts[1] = "3e7"  # x, in ASF units: 3e7 / 0.45 inches is 1,700 km
    amc[k] = " ".join(parts)
    q = tmp_path / "02_03.amc"
    q.write_text("\n".join(amc))
    with pytest.raises(MotionFormatError, match=r"02_03\.amc.*frame 1: the root is"):
        read_amc(q, asf02)
