"""Silhouette features: hand-worked shapes, skimage's Hu moments, invariances, and the
batch of masks against the masks one by one."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from skimage.measure import moments_central, moments_hu, moments_normalized

from silhouette_bank import (
    DESCRIPTORS,
    Descriptor,
    GridDescriptor,
    OutlineDescriptor,
    get_descriptor,
    outline_extents,
    silhouette_features,
)
from silhouette_bank._descriptor import THIGH_RATIO, grid_cells, hu_log, mask_extents
from silhouette_bank._features import feature_size

GRID_ROWS, GRID_COLS = 8, 4


def _hu(mask: np.ndarray, origin: tuple[float, float] = (0.0, 0.0)) -> np.ndarray:
    return silhouette_features(mask, origin, "hu")


def _figure(h: int = 120, w: int = 160) -> np.ndarray:
    """A crude person: a torso rectangle, a head disc, two legs, one raised arm."""
    m = np.zeros((h, w), dtype=np.uint8)
    m[30:70, 70:90] = 1
    cv2.circle(m, (80, 20), 9, 1, -1)
    m[70:110, 71:78] = 1
    m[70:110, 82:89] = 1
    cv2.line(m, (90, 35), (115, 10), 1, 4)
    return m


def test_square_by_hand() -> None:
    m = np.zeros((20, 30), dtype=np.uint8)
    m[5:15, 10:20] = 1  # 10 x 10 square, centre (14.5, 9.5)
    f = _hu(m, origin=(0.0, 0.0))
    assert f[7] == pytest.approx(14.5 / 10) and f[8] == pytest.approx(-9.5 / 10)
    # a square's first Hu moment: (mu20 + mu02) / m00^2 = 2 (n^4 / 12) / n^4 = 1/6
    # (discrete pixels: n^2 - 1 instead of n^2 in mu20)
    h1 = 2 * (10**2 * (10**2 - 1) / 12) / 100**2
    assert f[0] == pytest.approx(np.log10(1 + h1 / 1e-7), rel=1e-12)


def test_log_scale_is_continuous_through_zero() -> None:
    h = np.array([-1e-6, -1e-9, 0.0, 1e-9, 1e-6, 0.2])
    y = hu_log(np.tile(h[:, None], (1, 7)))[:, 0]
    assert np.all(np.diff(y) > 0) and y[2] == 0.0
    assert abs(y[1]) < 0.01 and abs(y[3]) < 0.01  # tiny values of either sign are near 0
    assert y[5] == pytest.approx(np.log10(0.2) + 7, abs=1e-6)


def test_hu_moments_match_skimage() -> None:
    m = _figure().astype(float)
    mu = moments_central(m)
    ref = moments_hu(moments_normalized(mu, 3))
    ours = cv2.HuMoments(cv2.moments(_figure(), binaryImage=True)).ravel()
    # skimage mirrors the sign of the 7th moment (its y axis); magnitudes agree
    np.testing.assert_allclose(ours[:6], ref[:6], rtol=1e-6)
    np.testing.assert_allclose(abs(ours[6]), abs(ref[6]), rtol=1e-6)
    np.testing.assert_allclose(_hu(_figure())[:6], hu_log(ref)[:6], rtol=1e-9)


def test_unchanged_by_translation_and_nearly_by_scale() -> None:
    m = _figure()
    f = _hu(m, origin=(80.0, 60.0))
    shifted = np.roll(np.roll(m, 13, axis=1), -7, axis=0)
    g = _hu(shifted, origin=(93.0, 53.0))
    np.testing.assert_allclose(g, f, atol=1e-12)
    big = cv2.resize(m, (320, 240), interpolation=cv2.INTER_NEAREST)
    b = _hu(big, origin=(160.0 - 0.5, 120.0 - 0.5))
    # scale: the same to within the pixel grid's error
    np.testing.assert_allclose(b[:4], f[:4], atol=0.05)
    np.testing.assert_allclose(b[7:], f[7:], atol=0.02)


def test_empty_and_bad_masks() -> None:
    assert np.isnan(silhouette_features(np.zeros((10, 10), dtype=bool))).all()
    with pytest.raises(ValueError, match="2-D"):
        silhouette_features(np.zeros((2, 3, 4)))
    with pytest.raises(TypeError, match="defines no shape numbers"):  # a descriptor half made
        Descriptor("half", 3).from_mask(_figure())
    f = _hu(_figure().astype(bool))
    np.testing.assert_allclose(f, _hu(_figure() * 255))


def test_grid_by_hand_and_against_block_means() -> None:
    m = np.zeros((40, 60), dtype=np.uint8)
    m[4:36, 22:38] = 1  # 32 rows x 16 columns, centred on column 29.5: every cell full
    f = silhouette_features(m, descriptor="grid")
    assert f.shape == (feature_size("grid"),) == (GRID_ROWS * GRID_COLS + 2,)
    np.testing.assert_allclose(f[:-2], 1.0)
    # the centre is the same as with Hu moments
    np.testing.assert_allclose(f[-2:], _hu(m)[-2:])
    # a figure 2 x 8 rows tall: each cell is the mean of a 2 x 2 pixel block
    fig = np.zeros((30, 40), dtype=np.uint8)
    rng = np.random.default_rng(3)
    fig[5:21, 16:24] = rng.random((16, 8)) < 0.6
    fig[5, 16:24] = 1  # the top and bottom rows are set, so the span is 16 rows
    fig[20, 16:24] = 1
    cells = grid_cells(fig, 5, 21, 19.5, 8, 4)  # columns 16..23 about their middle
    blocks = fig[5:21, 16:24].reshape(8, 2, 4, 2).mean(axis=(1, 3)).ravel()
    np.testing.assert_allclose(cells, blocks, atol=1e-6)


def test_grid_ignores_position_and_nearly_scale_and_clips_at_the_border() -> None:
    m = _figure()
    f = silhouette_features(m, descriptor="grid")
    assert np.all((f[:-2] >= 0) & (f[:-2] <= 1)) and f[:-2].max() > 0.5
    shifted = np.roll(np.roll(m, 13, axis=1), -7, axis=0)
    np.testing.assert_allclose(silhouette_features(shifted, descriptor="grid")[:-2], f[:-2])
    big = cv2.resize(m, (320, 240), interpolation=cv2.INTER_NEAREST)
    np.testing.assert_allclose(silhouette_features(big, descriptor="grid")[:-2], f[:-2], atol=0.1)
    # the figure cut by the image's left edge: the cells beyond it are empty, as if the
    # image went on with background
    cut = np.ascontiguousarray(m[:, 75:])
    g = silhouette_features(cut, descriptor="grid")[:-2]
    padded = np.pad(cut, ((0, 0), (100, 0)))
    ys, xs = np.nonzero(cut)
    ref = grid_cells(padded, ys.min(), ys.max() + 1, xs.mean() + 100, GRID_ROWS, GRID_COLS)
    assert g[0] == 0 and np.isfinite(g).all()
    np.testing.assert_allclose(g, ref, atol=1e-6)
    assert np.isnan(silhouette_features(np.zeros((9, 9), np.uint8), descriptor="grid")).all()
    with pytest.raises(
        ValueError, match="descriptor must be one of hu, grid, multigrid, outline, pose"
    ):
        silhouette_features(m, descriptor="zernike")


@pytest.mark.parametrize("name", ["hu", "grid", "multigrid", "outline"])
def test_a_descriptor_owns_its_layout_and_mirrors_the_image(name: str) -> None:
    desc = get_descriptor(name)
    m = _figure()
    f = silhouette_features(m, (80.0, 60.0), name)
    assert f.shape == (desc.size,) == (feature_size(name),) and desc.kind == "silhouette"
    np.testing.assert_array_equal(desc.shape(f), f[: desc.n_shape])
    np.testing.assert_array_equal(desc.centre(f), f[desc.n_shape :])
    # the mirrored image's vector is the vector mirrored (the grid's columns about the
    # centroid are rounded to pixels, so cells agree to a pixel column's worth)
    flipped = np.ascontiguousarray(m[:, ::-1])
    g = silhouette_features(flipped, (159 - 80.0, 60.0), name)  # pixel x -> 159 - x
    np.testing.assert_allclose(desc.mirror(f), g, atol=0.2 if name != "hu" else 1e-6)
    assert np.mean(np.abs(desc.mirror(f) - g)) < 0.03
    np.testing.assert_allclose(desc.mirror(desc.mirror(f)), f)
    # a standardiser from rows: Hu each by its spread, cells by one scale
    rows = np.random.default_rng(0).random((50, desc.n_shape))
    mean, scale = desc.standardiser(rows)
    assert mean.shape == scale.shape == (desc.n_shape,)
    total = float(np.sum(((rows - mean) / scale).var(axis=0)))
    assert total == pytest.approx(7.0)
    assert (np.unique(scale).size == 1) == (name != "hu")


def test_multigrid_is_the_grids_concatenated() -> None:
    m = _figure()
    f = silhouette_features(m, descriptor="multigrid")
    desc = get_descriptor("multigrid")
    rows = np.flatnonzero(m.any(axis=1))
    xs = np.nonzero(m)[1]
    parts = [grid_cells(m, rows[0], rows[-1] + 1, xs.mean(), r, c) for r, c in desc.levels]
    np.testing.assert_allclose(desc.shape(f), np.concatenate(parts))
    np.testing.assert_allclose(desc.centre(f), silhouette_features(m, descriptor="grid")[-2:])


def test_the_outline_sees_arms_the_grids_do_not_reach() -> None:
    """Arms held out to the side, longer or shorter, beyond the grids' box (half the
    silhouette's height around its centroid): the cells are the same, the outline is not."""

    def t_pose(reach: int) -> np.ndarray:
        m = np.zeros((120, 200), dtype=np.uint8)
        m[20:60, 92:108] = 1  # torso
        m[60:100, 93:99] = m[60:100, 101:107] = 1  # legs
        cv2.circle(m, (100, 12), 7, 1, -1)  # head
        m[24:28, 100 - reach : 100 + reach] = 1  # arms
        return m

    desc = get_descriptor("outline")
    assert isinstance(desc, OutlineDescriptor) and desc.kind == "silhouette"
    wide, wider = desc.from_mask(t_pose(60)), desc.from_mask(t_pose(80))  # height 95
    k = desc.grid.n_shape
    # both reach out of the grids' box (the centroids differ by a hair: so do the cells)
    np.testing.assert_allclose(wide[:k], wider[:k], atol=0.01)
    arms = 2 * ((24 - 5) * desc.bands // 95)  # the band of the arms' rows (top at row 5)
    assert wider[k + arms] == pytest.approx(wide[k + arms] - 20 / 95, abs=0.002)
    assert wider[k + arms + 1] == pytest.approx(wide[k + arms + 1] + 20 / 95, abs=0.002)
    assert wide[k + arms + 1] == pytest.approx((160.5 - 100.0) / 95, abs=0.02)
    # the legs' bands reach no further than the legs; the outline is the numpy one
    assert np.all(np.abs(wide[k + 2 * desc.bands - 2 : desc.n_shape]) < 0.1)
    masks = np.stack([t_pose(60), t_pose(80), np.zeros((120, 200), np.uint8)])
    ext = mask_extents(masks)
    got = outline_extents(masks, desc.bands)
    for i in range(2):
        cx = ext[i, 1] / ext[i, 0]
        want = _outline_by_hand(masks[i], int(ext[i, 3]), int(ext[i, 4]), cx, desc.bands)
        assert got[i].tobytes() == want.tobytes()
    assert np.isnan(got[2]).all()


def test_pose_descriptor_normalises_position_scale_and_swaps_sides() -> None:
    desc = get_descriptor("pose")
    assert "pose" in DESCRIPTORS and desc.kind == "pose" and desc.size == 26
    # a T-pose by hand: shoulders 1 above the hips (torso length 1), y down in pixels
    arms = [[-0.5, -1], [0.5, -1], [-1, -1], [1, -1], [-1.5, -1], [1.5, -1]]
    legs = [[-0.3, 0], [0.3, 0], [-0.3, 0.6], [0.3, 0.6], [-0.3, 1.2], [0.3, 1.2]]
    pts = np.array([*arms, *legs], dtype=float)
    f = desc.from_points(pts)
    np.testing.assert_allclose(f[:2], [-0.5, 1.0])  # left shoulder: y up
    np.testing.assert_allclose(f[-4:-2], [0.3, -1.2])  # right ankle
    np.testing.assert_allclose(f[-2:], [0.0, 0.0])
    # moved and scaled in the image: the same shape, the centre in torso lengths
    g = desc.from_points(pts * 40 + [100, 50], (0.0, 0.0))
    np.testing.assert_allclose(g[:24], f[:24], atol=1e-12)
    np.testing.assert_allclose(g[-2:], [100 / 40, -50 / 40])
    swapped = desc.swap(f)
    np.testing.assert_allclose(swapped[:2], f[2:4] * 0 + [0.5, 1.0])
    np.testing.assert_allclose(desc.swap(swapped), f)
    # mirroring the image negates x, and what was the left arm is seen as a right arm
    sides = [1, 0, 3, 2, 5, 4, 7, 6, 9, 8, 11, 10]
    np.testing.assert_allclose(desc.mirror(f), desc.from_points((pts * [-1, 1])[sides]))
    # landmarks name the sides: read as seen only, unless told to try the other readings
    assert len(desc.variants(f)) == 1 and len(desc.variants(f, mirror=True)) == 4
    assert len(desc.variants(f, mirror=False)) == 1
    # a window whose frames show both sides (the shoulders and hips in one left-right
    # order, then the other) is also read with every frame showing one side, then the
    # other; a frame side on (its shoulders and hips nearer than side_margin) stays
    side_on = desc.from_points(pts * [0.05, 1])
    window = np.stack([f, swapped, side_on, swapped])
    reads = desc.variants(window)
    assert len(reads) == 3 and reads[0] is window
    one_sided = {
        np.stack([swapped, swapped, side_on, swapped]).tobytes(),
        np.stack([f, f, side_on, f]).tobytes(),
    }
    assert {reads[1].tobytes(), reads[2].tobytes()} == one_sided
    assert len(desc.variants(np.stack([f, side_on, f]))) == 1  # one side throughout
    assert len(desc.variants(np.stack([f, desc.swap(side_on)]))) == 1
    assert len(desc.variants(window, mirror=True)) == 6
    # bent over towards the camera, the torso is short in the image: the legs say how
    # long it is (a thigh is THIGH_RATIO torsos long)
    bent = pts.copy()
    bent[:6, 1] = -0.2
    thigh = 0.6 / THIGH_RATIO
    np.testing.assert_allclose(desc.from_points(bent)[:2], [-0.5 / thigh, 0.2 / thigh])
    # a degenerate torso has no vector; masks are not its input
    assert np.isnan(desc.from_points(np.zeros((12, 2)))).all()
    with pytest.raises(ValueError, match="landmarks, not masks"):
        silhouette_features(_figure(), descriptor="pose")


def _masks(rng: np.random.Generator) -> list[np.ndarray]:
    """Figures moved and cut at the image's edges, blobs, one pixel, an empty mask."""
    out = [np.roll(_figure(), (dy, dx), axis=(0, 1)) for dy, dx in ((0, 0), (9, -70), (-25, 71))]
    for _ in range(5):
        m = np.zeros((120, 160), dtype=np.uint8)
        for _ in range(3):
            centre = (int(rng.integers(0, 160)), int(rng.integers(0, 120)))
            axes = (int(rng.integers(1, 40)), int(rng.integers(1, 50)))
            cv2.ellipse(m, centre, axes, float(rng.uniform(0, 180)), 0, 360, 1, -1)
        out.append(m)
    dot = np.zeros((120, 160), dtype=np.uint8)
    dot[119, 0] = 1
    return [*out, dot, np.zeros((120, 160), dtype=np.uint8)]


def test_mask_extents_are_cv2s_moments_and_rows() -> None:
    masks = np.stack(_masks(np.random.default_rng(3)))
    ext = mask_extents(masks)
    for m, (m00, m10, m01, top, bottom) in zip(masks, ext, strict=True):
        mom = cv2.moments(m, binaryImage=True)
        assert (m00, m10, m01) == (mom["m00"], mom["m10"], mom["m01"])
        rows = np.flatnonzero(m.any(axis=1))
        assert (top, bottom) == ((rows[0], rows[-1] + 1) if rows.size else (-1, -1))
    # any nonzero value is silhouette, in any dtype
    np.testing.assert_array_equal(mask_extents(masks * 255), ext)
    np.testing.assert_array_equal(mask_extents(masks.astype(bool)), ext)
    np.testing.assert_array_equal(mask_extents(masks.astype(np.float32) * 0.5), ext)
    with pytest.raises(ValueError, match=r"\(N, H, W\)"):
        mask_extents(masks[0])


def _outline_by_hand(mask: np.ndarray, top: int, bottom: int, cx: float, bands: int) -> np.ndarray:
    """Each row band's leftmost and rightmost pixel edges from ``np.nonzero``."""
    h = bottom - top
    out = np.zeros(2 * bands)
    ys, xs = np.nonzero(mask)
    for b in range(bands):
        a, e = top + (b * h) // bands, top + max(((b + 1) * h) // bands, (b * h) // bands + 1)
        inside = xs[(ys >= a) & (ys < e)]
        if inside.size:
            out[2 * b] = (inside.min() - 0.5 - cx) / h
            out[2 * b + 1] = (inside.max() + 0.5 - cx) / h
    return out


def _one_by_one(mask: np.ndarray, origin: tuple[float, float], name: str) -> np.ndarray:
    """The vector of one mask written out with cv2's moments, as the bank had it."""
    desc = get_descriptor(name)
    out = np.full(desc.size, np.nan)
    mom = cv2.moments(mask, binaryImage=True)
    if mom["m00"] == 0:
        return out
    rows = np.flatnonzero(mask.any(axis=1))
    top, bottom = int(rows[0]), int(rows[-1]) + 1
    cx, cy = mom["m10"] / mom["m00"], mom["m01"] / mom["m00"]
    if name == "hu":
        out[:7] = hu_log(cv2.HuMoments(mom).ravel())
    elif isinstance(desc, OutlineDescriptor):
        k = desc.grid.n_shape
        levels = desc.grid.levels
        out[:k] = np.concatenate([grid_cells(mask, top, bottom, cx, r, c) for r, c in levels])
        out[k:-2] = _outline_by_hand(mask, top, bottom, cx, desc.bands)
    else:
        assert isinstance(desc, GridDescriptor)
        out[:-2] = np.concatenate([grid_cells(mask, top, bottom, cx, r, c) for r, c in desc.levels])
    out[-2] = (cx - origin[0]) / (bottom - top)
    out[-1] = -(cy - origin[1]) / (bottom - top)
    return out


@pytest.mark.parametrize("name", ["hu", "grid", "multigrid", "outline"])
def test_a_batch_of_masks_is_each_mask_bit_for_bit(name: str) -> None:
    masks = np.stack(_masks(np.random.default_rng(4)))
    origins = np.random.default_rng(5).uniform(0, 160, size=(len(masks), 2))
    got = get_descriptor(name).from_masks(masks, origins)
    for m, o, g in zip(masks, origins, got, strict=True):
        want = _one_by_one(m, (float(o[0]), float(o[1])), name)
        assert want.tobytes() == g.tobytes()
        assert silhouette_features(m, (float(o[0]), float(o[1])), name).tobytes() == g.tobytes()
    with pytest.raises(ValueError, match="body landmarks"):
        get_descriptor("pose").from_masks(masks)
