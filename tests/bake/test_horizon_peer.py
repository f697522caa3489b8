"""hzval's horizon bake against an independent peer: the seed loop in C.

``tests/oracles/seed_bake.c`` is FGED2's ``ConstructHorizonMap`` (Lengyel's
algorithm) kept as close to the listing as possible, with only the changes
that hzval's conventions call for (any size, wrap/open, +y up the image,
heights in texel units, averaged ambient terms). It is compiled once per
session; :func:`hzval.bake.horizon.horizon_map` must reproduce it texel for texel up
to float rounding, on odd, tiny, degenerate and power-of-two sizes, both
boundaries and several radii and bin counts. The peer's ``-DHOISTED_TABLE``
variant (its offset table computed once: the benchmark's speed peer) must
reproduce the literal one bit for bit.
"""

from __future__ import annotations

import numpy as np
import pytest

from hzval.bake import horizon as bake_horizon
from hzval.core import conventions as cv
from tests.helpers import GCC, run_peer

#: Largest difference allowed between hzval and the peer (values are in [0, 1]).
TOLERANCE = 2e-6

pytestmark = [
    pytest.mark.gcc,
    pytest.mark.skipif(
        GCC is None, reason="gcc is not installed: cannot compile the seed peer tests/oracles/seed_bake.c"
    ),
]


# (rows, cols, depth, boundary, radius, angles). Dr.Jit compiles one kernel per
# (radius, angles): most cases share (16, 32), a few cover (5, 16) and (16, 64).
CASES = [
    (23, 37, 0.05, "wrap", 16, 32),
    (23, 37, 0.5, "open", 16, 32),
    (37, 23, 0.05, "open", 16, 32),
    (37, 23, 0.5, "wrap", 16, 32),
    (5, 3, 0.5, "wrap", 16, 32),
    (5, 3, 0.05, "open", 16, 32),
    (1, 9, 0.5, "wrap", 16, 32),
    (1, 9, 0.05, "open", 16, 32),
    (9, 1, 0.05, "wrap", 16, 32),
    (9, 1, 0.5, "open", 16, 32),
    (16, 16, 0.05, "wrap", 16, 32),
    (16, 16, 0.5, "open", 16, 32),
    (23, 37, 0.5, "wrap", 5, 16),
    (16, 16, 0.05, "open", 5, 16),
    (5, 3, 0.05, "wrap", 5, 16),
    (37, 23, 0.05, "open", 16, 64),
    (16, 16, 0.5, "wrap", 16, 64),
]


@pytest.mark.parametrize(
    "rows, cols, depth, boundary, radius, angles",
    CASES,
    ids=[f"{r}x{c}-d{d}-{b}-R{R}-N{n}" for r, c, d, b, R, n in CASES],
)
def test_horizon_map_matches_seed_peer(
    variant, seed_peer, tmp_path, rows, cols, depth, boundary, radius, angles
):
    rng = np.random.default_rng(rows * 1000 + cols * 10 + angles + radius)
    height = rng.random((rows, cols), dtype=np.float32)

    peer = run_peer(seed_peer, height, depth, radius, angles, boundary, tmp_path)
    horizon, mean_cos, mean_cos2 = bake_horizon.horizon_map(
        cv.heights_in_texels(height, depth), radius, angles, boundary
    )

    assert horizon.shape == (rows, cols, 8)
    assert mean_cos.shape == mean_cos2.shape == (rows, cols)
    # the comparison means something only if the maps occlude somewhere (a
    # 9x1 map at depth 0.05 is only 0.05 texel high: its sines are small)
    assert peer[..., :8].max() > 0.0 and peer[..., 8].min() < 1.0

    diffs = {
        "horizon sines": float(np.abs(horizon - peer[..., :8]).max()),
        "mean_cos": float(np.abs(mean_cos - peer[..., 8]).max()),
        "mean_cos2": float(np.abs(mean_cos2 - peer[..., 9]).max()),
    }
    where = {}
    for name, ours, theirs in [
        ("horizon sines", horizon, peer[..., :8]),
        ("mean_cos", mean_cos, peer[..., 8]),
        ("mean_cos2", mean_cos2, peer[..., 9]),
    ]:
        idx = np.unravel_index(np.argmax(np.abs(ours - theirs)), ours.shape)
        where[name] = f"at {tuple(int(i) for i in idx)}: hzval {ours[idx]:.7g}, seed {theirs[idx]:.7g}"
    bad = {k: v for k, v in diffs.items() if not v <= TOLERANCE}
    assert not bad, (
        f"hzval.bake.horizon.horizon_map differs from the seed peer by more than {TOLERANCE:g}: "
        + "; ".join(f"{k}: max |diff| {v:.3g} {where[k]}" for k, v in bad.items())
        + f" (all: {diffs})"
    )


@pytest.mark.parametrize("radius, angles", [(16, 32), (5, 16), (16, 64), (3, 48), (24, 128)])
def test_offset_table_matches_libm(radius, angles):
    """Every offset of :func:`hzval.bake.horizon.horizon_table` covers the seed's bins.

    The random maps above exercise an offset only where it sets a maximum;
    this checks all of them, with the C library functions that the peer calls
    (``atan2f``, ``atanf``, ``sqrtf``, ``floorf``, ``ceilf`` through ctypes)
    and float32 arithmetic in between, as in ``seed_bake.c``.
    """
    import ctypes
    import ctypes.util

    libm = ctypes.CDLL(ctypes.util.find_library("m") or "libm.so.6")
    f32 = np.float32
    for name, nargs in [("atan2f", 2), ("atanf", 1), ("sqrtf", 1), ("floorf", 1), ("ceilf", 1)]:
        fn = getattr(libm, name)
        fn.restype, fn.argtypes = ctypes.c_float, [ctypes.c_float] * nargs
    k_index = f32(angles) / f32(6.2831855)

    ours = {off: g.bins for g in bake_horizon.horizon_table(radius, angles) for off in g.offsets}
    expected = {}
    for j in range(-radius + 1, radius):
        for i in range(-radius + 1, radius):
            r2 = i * i + j * j
            if r2 == 0 or r2 >= radius * radius:
                continue
            direction = f32(libm.atan2f(j, i))
            delta = f32(libm.atanf(f32(0.7071) / f32(libm.sqrtf(r2))))
            lo = int(libm.floorf((direction - delta) * k_index))
            hi = int(libm.ceilf((direction + delta) * k_index))
            expected[(i, j)] = tuple(sorted({n % angles for n in range(lo, hi + 1)}))
    wrong = {off: (ours.get(off), bins) for off, bins in expected.items() if ours.get(off) != bins}
    assert set(ours) == set(expected), "hzval's table and the seed's loop visit different offsets"
    assert not wrong, (
        f"{len(wrong)} offsets cover other bins than the seed's (hzval, seed): "
        f"{dict(list(wrong.items())[:5])}"
    )


# (rows, cols, depth, boundary, radius, angles): odd sizes, both boundaries, and
# a radius larger than the map and a bin count that is not a power of two.
HOISTED_CASES = [
    (129, 257, 0.05, "wrap", 16, 32),
    (129, 257, 0.05, "open", 16, 32),
    (23, 37, 0.5, "wrap", 5, 48),
    (5, 3, 0.5, "open", 16, 64),
]


@pytest.mark.parametrize(
    "rows, cols, depth, boundary, radius, angles",
    HOISTED_CASES,
    ids=[f"{r}x{c}-d{d}-{b}-R{R}-N{n}" for r, c, d, b, R, n in HOISTED_CASES],
)
def test_hoisted_table_variant_is_bit_identical(
    seed_peer, seed_peer_hoisted, tmp_path, rows, cols, depth, boundary, radius, angles
):
    """seed_bake.c -DHOISTED_TABLE (the benchmark's speed peer) computes the
    literal seed loop's output bit for bit: only where the offset table is
    computed changes, not a single float operation."""
    rng = np.random.default_rng(rows * 7 + cols + radius * 3 + angles)
    height = rng.random((rows, cols), dtype=np.float32)
    (tmp_path / "literal").mkdir()
    (tmp_path / "hoisted").mkdir()
    literal = run_peer(seed_peer, height, depth, radius, angles, boundary, tmp_path / "literal")
    hoisted = run_peer(seed_peer_hoisted, height, depth, radius, angles, boundary, tmp_path / "hoisted")
    assert literal[..., :8].max() > 0.0  # something is occluded: the comparison means something
    differ = literal.view(np.uint32) != hoisted.view(np.uint32)
    assert not differ.any(), (
        f"{int(differ.sum())} of {differ.size} floats differ, first at "
        f"{tuple(int(i) for i in np.argwhere(differ)[0])}"
    )
