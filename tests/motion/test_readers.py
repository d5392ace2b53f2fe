"""ASF/AMC and BVH readers and the BVH writer: hand-worked cases and the real CMU data."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from control.motion import (
    MotionFormatError,
    find_role,
    forward_kinematics,
    mirror,
    read_amc,
    read_asf,
    read_bvh,
    resample,
    write_bvh,
)
from tests.conftest import BVH_DIR, MOCAP, REPO, amc_path, asf_path
from tests.motion.tiny import TINY_AMC, TINY_ASF, TINY_BVH

INCH = 0.0254
TAKES = ["02_01", "02_02", "02_03", "02_04", "03_01", "03_02"]


def _write(tmp_path: Path, name: str, text: str, crlf: bool = False) -> Path:
    p = tmp_path / name
    p.write_bytes((text.replace("\n", "\r\n") if crlf else text).encode())
    return p


@pytest.mark.parametrize("crlf", [False, True])
def test_tiny_asf_amc_by_hand(tmp_path: Path, crlf: bool) -> None:
    asf = read_asf(_write(tmp_path, "tiny.asf", TINY_ASF, crlf))
    assert asf.skeleton.names == ("root", "a", "b")
    assert asf.metres_per_unit == pytest.approx(INCH)
    m = read_amc(_write(tmp_path, "tiny_01.amc", TINY_AMC, crlf), asf)
    assert (m.n_frames, m.fps, m.name) == (2, 120.0, "tiny_01")
    pose = forward_kinematics(m)
    L = 10 * INCH
    # Frame 1: a points along +y after its 90 deg turn, b continues it.
    np.testing.assert_allclose(pose.positions[0, 2], [0, L, 0], atol=1e-12)
    np.testing.assert_allclose(pose.end_positions[0, 0], [0, 2 * L, 0], atol=1e-12)
    # Frame 2: b's rx of 90 is, through its axis (z 90), a quarter turn about world y
    # before a's turn: (1,0,0) -> (0,0,-1), unchanged by Rz(90).
    np.testing.assert_allclose(pose.positions[1, 0], [L, 0, 0], atol=1e-12)
    np.testing.assert_allclose(pose.end_positions[1, 0], [L, L, -L], atol=1e-12)


def test_tiny_bvh_by_hand(tmp_path: Path) -> None:
    m = read_bvh(_write(tmp_path, "tiny.bvh", TINY_BVH), units="cm")
    assert m.fps == pytest.approx(30.0, rel=1e-5)
    pose = forward_kinematics(m)
    np.testing.assert_allclose(pose.positions[0, 1], [0, 0.5, 0], atol=1e-12)
    np.testing.assert_allclose(pose.end_positions[0, 0], [0, 0, 0], atol=1e-12)
    # Root Rz(90) then knee Rx(90): the shin (0,-0.5,0) -> Rx -> (0,0,-0.5) -> Rz -> same.
    np.testing.assert_allclose(pose.positions[1, 1], [0.1 + 0.5, 1.0, 0], atol=1e-12)
    np.testing.assert_allclose(pose.end_positions[1, 0], [0.6, 1.0, -0.5], atol=1e-12)


def _readme_frame_counts() -> dict[str, int]:
    counts: dict[str, int] = {}
    for line in (MOCAP / "README.md").read_text().splitlines():
        m = re.match(r"\|\s*(\d\d_\d\d)(?:\.\.(\d\d_\d\d))?\s*\|\s*([\d, ]+)\|", line)
        if not m:
            continue
        first, last, numbers = m.groups()
        values = [int(v) for v in numbers.replace(",", " ").split()]
        if last is None:
            counts[first] = values[0]
        else:
            s, a, b = first[:3], int(first[3:]), int(last[3:])
            for k, v in zip(range(a, b + 1), values, strict=True):
                counts[f"{s}{k:02d}"] = v
    return counts


@pytest.mark.slow
def test_every_amc_loads_with_the_readme_frame_count(mocap: Path) -> None:
    counts = _readme_frame_counts()
    amcs = sorted((mocap / "cmu" / "subjects").rglob("*.amc"))
    assert len(counts) == len(amcs) == 32  # 14_20, a second person, joined the shared data
    for p in amcs:
        m = read_amc(p, read_asf(asf_path(p.stem)))
        assert m.n_frames == counts[p.stem], p.stem
        assert m.skeleton.n_joints == 31


def test_every_bvh_loads(mocap: Path) -> None:
    for p in sorted(BVH_DIR.glob("*.bvh")):
        m = read_bvh(p)
        assert m.fps == pytest.approx(120.0, rel=1e-4)
        assert m.skeleton.n_joints == 43  # the root and 42 joints
        if p.stem in TAKES:  # one extra rest frame before the AMC's first
            amc_frames = _readme_frame_counts()[p.stem]
            assert m.n_frames == amc_frames + 1


ROLES = [
    "left_hip",
    "right_hip",
    "left_knee",
    "right_knee",
    "left_ankle",
    "right_ankle",
    "left_wrist",
    "right_wrist",
    "head",
]


def _joint_tracks(m) -> np.ndarray:  # type: ignore[no-untyped-def]
    pos = forward_kinematics(m).positions
    return pos[:, [find_role(m.skeleton, r) for r in ROLES]]


def _similarity_residual(x: np.ndarray, y: np.ndarray) -> tuple[float, float, float]:
    """Fit x ~ s R y + t over all joints and frames; the residual's time-varying RMS
    (constant per-joint offsets are the skeletons' different joint placement), the scale
    and the rotation angle in degrees."""
    n = min(len(x), len(y))
    xs, ys = x[:n].reshape(-1, 3), y[:n].reshape(-1, 3)
    xc, yc = xs - xs.mean(0), ys - ys.mean(0)
    s = float(np.sqrt((xc**2).sum() / (yc**2).sum()))
    rot, _ = Rotation.align_vectors(xc, yc * s)
    res = (xc - rot.apply(yc * s)).reshape(n, -1, 3)
    var = res - res.mean(axis=0)
    return float(np.sqrt((var**2).sum(-1).mean())), s, float(np.degrees(rot.magnitude()))


def test_asf_amc_and_bvh_agree_on_the_same_takes(mocap: Path) -> None:
    tracks_amc = {c: _joint_tracks(read_amc(amc_path(c), read_asf(asf_path(c)))) for c in TAKES}
    tracks_bvh = {c: _joint_tracks(read_bvh(BVH_DIR / f"{c}.bvh"))[1:] for c in TAKES}
    report = []
    for c in TAKES:
        rms, scale, angle = _similarity_residual(tracks_amc[c], tracks_bvh[c])
        report.append(
            f"{c}: residual {rms * 100:.1f} cm, scale {scale:.3f}, rotation {angle:.1f} deg"
        )
        # Same world frame (conventions agree) and the same person's size up to ~7%.
        assert angle < 3.0 and 0.95 < scale < 1.08, report[-1]
        assert rms < 0.09, report[-1]
        # And the take matches itself better than any other take.
        for other in TAKES:
            if other != c:
                assert _similarity_residual(tracks_amc[c], tracks_bvh[other])[0] > rms, (c, other)
    print("\n".join(report))


def test_bone_lengths_constant_under_fk(mocap: Path) -> None:
    m = read_amc(amc_path("13_29"), read_asf(asf_path("13_29")))
    pos = forward_kinematics(m).positions
    par = m.skeleton.parents
    lengths = np.linalg.norm(pos[:, 1:] - pos[:, par[1:]], axis=-1)
    rest = np.linalg.norm(m.skeleton.offsets[1:], axis=-1)
    np.testing.assert_allclose(lengths, np.broadcast_to(rest, lengths.shape), atol=1e-9)


@pytest.mark.parametrize("clip", ["02_05", "bvh:02_04"])
def test_bvh_write_read_roundtrip(tmp_path: Path, mocap: Path, clip: str) -> None:
    if clip.startswith("bvh:"):
        m = read_bvh(BVH_DIR / f"{clip[4:]}.bvh")
    else:
        m = read_amc(amc_path(clip), read_asf(asf_path(clip)))
    out = tmp_path / "out.bvh"
    write_bvh(m, out)
    back = read_bvh(out)
    assert back.skeleton.names == m.skeleton.names
    assert back.skeleton.same_as(m.skeleton, atol=1e-8)
    assert back.fps == pytest.approx(m.fps, rel=1e-8)
    np.testing.assert_allclose(back.root_pos, m.root_pos, atol=1e-8)
    assert np.min(np.abs(np.sum(back.quats * m.quats, axis=-1))) > 1 - 1e-12
    np.testing.assert_allclose(
        forward_kinematics(back).positions, forward_kinematics(m).positions, atol=1e-7
    )


def test_written_bvh_passes_the_independent_reader(tmp_path: Path, mocap: Path) -> None:
    m = resample(read_amc(amc_path("02_01"), read_asf(asf_path("02_01"))), 30)
    for motion, name in ((m, "a.bvh"), (mirror(m), "b.bvh")):
        write_bvh(motion, tmp_path / name)
        res = subprocess.run(
            [
                sys.executable,
                str(REPO.parent / "shared" / "tools" / "check_bvh.py"),
                str(tmp_path / name),
            ],
            capture_output=True,
            text=True,
            check=False,
        )
        assert res.returncode == 0, res.stderr
        assert f"frames={motion.n_frames} fps=30.0 joints=31" in res.stdout


def test_write_is_atomic(tmp_path: Path, mocap: Path) -> None:
    m = read_amc(amc_path("02_03"), read_asf(asf_path("02_03")))
    out = tmp_path / "keep.bvh"
    out.write_text("previous content")
    with pytest.raises(ValueError):
        write_bvh(m, out, order="XXY")
    assert out.read_text() == "previous content"
    assert [p.name for p in tmp_path.iterdir()] == ["keep.bvh"]


def test_radians_and_other_units(tmp_path: Path) -> None:
    deg = read_amc(
        _write(tmp_path, "d_01.amc", TINY_AMC), read_asf(_write(tmp_path, "d.asf", TINY_ASF))
    )
    rad_asf = TINY_ASF.replace("angle deg", "angle rad").replace(
        "axis 0 0 90 XYZ", "axis 0 0 1.5707963267948966 XYZ"
    )
    rad_amc = TINY_AMC.replace("a 90", "a 1.5707963267948966").replace(
        "b 90", "b 1.5707963267948966"
    )
    rad = read_amc(
        _write(tmp_path, "r_01.amc", rad_amc), read_asf(_write(tmp_path, "r.asf", rad_asf))
    )
    np.testing.assert_allclose(rad.quats, deg.quats, atol=1e-12)
    # :units length 0.5 makes every length twice as long (1 / 0.5 inches a unit).
    half = read_asf(_write(tmp_path, "h.asf", TINY_ASF.replace("length 1.0", "length 0.5")))
    assert half.metres_per_unit == pytest.approx(2 * INCH)


# --- the one-pass AMC scan (control/motion/_amc_scan.py) ----------------------------------


def _tiny_asf(tmp_path: Path):  # type: ignore[no-untyped-def]
    return read_asf(_write(tmp_path, "tiny.asf", TINY_ASF))


def test_the_scan_reads_numbers_as_float_does(tmp_path: Path) -> None:
    """Every way a number is written (Clinger's exact cases, and those handed back to
    float(): long mantissas, powers of ten past 1e22, subnormals), bit for bit."""
    from control.motion._amc_scan import scan_amc

    rng = np.random.default_rng(7)
    values = np.concatenate(
        (rng.normal(0, 100, 300), rng.normal(0, 1e-15, 100), 10.0 ** rng.uniform(-30, 8, 200))
    )
    formats = ["%.6g", "%.17g", "%e", "%.3f", "%.10E", "%+.4f", "%.25f", "%.20e"]
    tokens = [f % v for v in values for f in formats]
    tokens += ["-0", "0.", ".5", "-.25", "1e22", "9007199254740993", "123456789012345678901"]
    tokens += ["4.9e-324", "2.2250738585072014e-308", "1.7976931348623157e308", "+7", "0e0"]
    tokens = [t for t in tokens if abs(float(t)) <= 1e9]  # the readers' plausible range
    body = "".join(f"{i + 1}\nroot 0 0 0 0 0 0\na {t}\nb 0\n" for i, t in enumerate(tokens))
    table = scan_amc(body, _tiny_asf(tmp_path), [0, 1, 2])
    assert table is not None and table.shape == (len(tokens), 8)
    want = np.array([float(t) for t in tokens])
    assert np.array_equal(table[:, 6].view(np.int64), want.view(np.int64))


@pytest.mark.parametrize(
    "body",
    [
        "1\nroot 0 0 0 0 0 0\na 1 2\nb 0\n",  # a number too many
        "1\nroot 0 0 0 0 0 0\na\nb 0\n",  # one too few
        "1\nroot 0 0 0 0 0 0\nab 1\nb 0\n",  # a longer name that begins with a bone's
        "1\nroot 0 0 0 0 0 0\na 1\nb 0\n3\nroot 0 0 0 0 0 0\na 1\nb 0\n",  # frame 3 after 1
        "1\nroot 0 0 0 0 0 0\na nan\nb 0\n",
        "1\nroot 0 0 0 0 0 0\na 1x\nb 0\n",
        "1\nroot 0 0 0 0 0 0\nb 0\na 1\n2\nroot 0 0 0 0 0 0\na 1\nb 0\n",  # order changed
        "1\nroot 0 0 0 0 0 0\n# a comment\na 1\nb 0\n",
    ],
)
def test_the_scan_leaves_anything_irregular_to_the_other_parses(tmp_path: Path, body: str) -> None:
    from control.motion._amc_scan import scan_amc

    assert scan_amc(body, _tiny_asf(tmp_path), [0, 1, 2]) is None


def test_the_scan_is_the_vectorised_parse_on_real_files() -> None:
    """(01_07 and 02_01 hold numbers past 1e-22, handed back to float().)"""
    from control.motion._amc import _amc_fast, _amc_header
    from control.motion._amc_scan import scan_amc
    from control.motion._text import decode, read_bytes

    for clip in ["01_07", "02_01", "13_29"]:
        asf = read_asf(asf_path(clip))
        text = decode(amc_path(clip), read_bytes(amc_path(clip)))
        body = text[_amc_header(text)[1] :]
        moving = [j for j, d in enumerate(asf.dofs) if d]
        got, want = scan_amc(body, asf, moving), _amc_fast(body, asf, moving)
        assert got is not None and want is not None
        assert np.array_equal(got.view(np.int64), want.view(np.int64)), clip


def test_the_line_by_line_parse_goes_on_where_the_scan_stopped() -> None:
    """A real AMC (numbers past 1e-22 in it), strictly regular up to a comment in
    frame 41: the line-by-line parse reads on from there and gives the whole parse's
    table, bit for bit; an error further on names the same line either way."""
    from control.motion._amc import _amc_header, _amc_slow
    from control.motion._amc_scan import scan_amc_prefix
    from control.motion._text import decode, read_bytes

    path = amc_path("02_01")
    asf = read_asf(asf_path("02_01"))
    moving = [j for j, d in enumerate(asf.dofs) if d]
    lines = decode(path, read_bytes(path)).splitlines(keepends=True)
    i = next(k for k, line in enumerate(lines) if line.strip() == "41")
    lines.insert(i + 1, "# a comment\n")
    good = "".join(lines)
    bad = good.replace("\n200\nroot ", "\n200\nroot x")  # a number unreadable
    assert bad != good
    header, start = _amc_header(good)
    for text in (good, bad):
        body = text[start:]
        done, rest = scan_amc_prefix(body, asf, moving)
        assert done.shape[0] == 40 and body[:rest].endswith("\n") and body[rest:].startswith("41")
        if text is good:
            whole = _amc_slow(path, body, header, asf, moving)
            resumed = _amc_slow(path, body, header, asf, moving, done, rest)
            assert np.array_equal(resumed.view(np.int64), whole.view(np.int64))
            continue
        with pytest.raises(MotionFormatError) as e:
            _amc_slow(path, body, header, asf, moving)
        with pytest.raises(MotionFormatError) as again:
            _amc_slow(path, body, header, asf, moving, done, rest)
        where = 1 + text.splitlines().index(next(x for x in text.splitlines() if "root x" in x))
        assert str(again.value) == str(e.value) and f".amc:{where}: " in str(e.value)
