"""hzval.metrics.flip against NVIDIA's flip-evaluator, and the CIEDE2000 kernel against colour-science.

FLIP: both are float32; they differ by rounding (scipy sums the x-direction
convolutions in float64, FLIP's C++ in float32, and NumPy's ``pow``/``exp``
are not glibc's). Measured (hzval.metrics.flip against flip-evaluator 1.7): the means
agree to 2e-7 on every image here but the hard edge (1.3e-5); per pixel, to
7e-6 on noise, gradients, constant, tiny and non-square images, 3e-4 on the
shaded bricks and 1.5e-3 on the hard edge. The larger ones are in flat
regions near a difference, where the two images' filtered colours agree to
float32 rounding: there FLIP's error is that rounding (``|dLab| ** 0.7``)
raised to ``1 - feature_difference``, in either implementation.

CIEDE2000: float64 both; the kernel agrees with colour-science to 1e-12.
"""

import numpy as np
import pytest

from hzval.core.errors import HzvalError
from hzval.metrics import compare
from hzval.metrics import flip as hzflip

PPD = compare.FLIP_PPD


def contracts_fma(variant) -> bool:
    """Whether the backend may fuse a product and a sum into one rounding (CUDA's ptxas contracts
    ``mul`` and ``add`` into ``fma`` where a product has one use; LLVM keeps Dr.Jit's operations as
    written). There a filter's sum is exact to float32 summation, not to the bit."""
    return variant.startswith("cuda")


def reference_flip(ref, test, ppd=PPD):
    import flip_evaluator

    err, mean, _ = flip_evaluator.evaluate(
        np.ascontiguousarray(ref, np.float32),
        np.ascontiguousarray(test, np.float32),
        "LDR",
        inputsRGB=True,
        applyMagma=False,
        computeMeanError=True,
        parameters={"ppd": float(ppd)},
    )
    err = np.asarray(err)
    return err.reshape(err.shape[:2]), float(mean)


def check(ref, test, max_pixel, ppd=PPD, max_mean=1e-4):
    want_map, want_mean = reference_flip(ref, test, ppd)
    got_map, got_mean = hzflip.flip(ref, test, ppd)
    assert got_map.shape == want_map.shape and got_map.dtype == np.float32
    assert abs(got_mean - want_mean) <= max_mean
    assert float(np.max(np.abs(got_map - want_map))) <= max_pixel
    return got_map, got_mean


rng = np.random.default_rng(7)


def noise(shape):
    return rng.random(tuple(shape) + (3,))


def bricks_renders():
    """The built-in bricks' heights, Lambert-shaded under two lights and with a darkened patch
    (a shadow), as display values."""
    from hzval import materials

    h = materials.generate("bricks", 96, 0).height.astype(np.float64)
    gy, gx = np.gradient(h * 8.0)
    n = np.stack([-gx, gy, np.ones_like(gx)], axis=-1)
    n /= np.linalg.norm(n, axis=-1, keepdims=True)

    def shade(az, el=30.0):
        az, el = np.radians(az), np.radians(el)
        light = np.array([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        return np.clip(n @ light, 0, None)[..., None] * np.array([0.62, 0.36, 0.27])

    a, b = shade(0.0), shade(20.0)
    shadowed = a.copy()
    shadowed[30:60, 20:50] *= 0.3
    grainy = a * (1 + 0.05 * rng.standard_normal(a.shape))
    return [compare.display(x, 1.5) for x in (a, b, shadowed, grainy)]


# -- FLIP ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("shape", [(64, 64), (100, 37), (37, 150)])
def test_noise(shape):
    check(noise(shape), noise(shape), max_pixel=2e-5)


def test_noise_small_difference():
    a = noise((96, 80))
    check(a, np.clip(a + 0.02 * rng.standard_normal(a.shape), 0, 1), max_pixel=2e-5)


def test_smooth_gradients():
    x = np.linspace(0, 1, 120)
    g = np.stack(np.broadcast_arrays(x[None, :], x[:90, None], 0.5), axis=-1)
    check(g, g[::-1], max_pixel=2e-5)
    check(g, np.clip(g * 0.9 + 0.05, 0, 1), max_pixel=2e-5)


@pytest.mark.parametrize("axis", [0, 1])
def test_hard_edge(axis):
    e = np.zeros((80, 120, 3))
    e[:, 60:] = 1.0
    e = e if axis == 1 else e.transpose(1, 0, 2)
    check(e, np.roll(e, 2, axis=axis), max_pixel=5e-3, max_mean=1e-4)
    c = np.zeros((80, 120, 3))
    c[:, 60:] = (0.8, 0.2, 0.1)
    c = c if axis == 1 else c.transpose(1, 0, 2)
    check(c, np.roll(c, 3, axis=axis), max_pixel=2e-5)


def test_constant_images():
    c = np.full((50, 40, 3), 0.3)
    m, mean = check(c, c, max_pixel=0.0, max_mean=0.0)
    assert mean == 0 and not m.any()
    check(c, c + 0.1, max_pixel=2e-5)
    check(np.zeros((8, 8, 3)), np.ones((8, 8, 3)), max_pixel=2e-5)


@pytest.mark.parametrize("shape", [(1, 1), (2, 3), (5, 40), (40, 5), (1, 7)])
def test_tiny_images(shape):
    """Smaller than the filters (radius 10 and 9 at 67 ppd): both clamp to the edge, so a 1 x 1
    image is a constant one; flip-evaluator accepts them all."""
    check(noise(shape), noise(shape), max_pixel=2e-5)


def test_out_of_range_and_nan_inputs_are_clamped_as_flip_does():
    a, b = noise((20, 30)) * 1.4 - 0.2, noise((20, 30))
    a[3, 4] = np.nan
    check(a, b, max_pixel=2e-5)


@pytest.mark.parametrize("ppd", [20.0, 150.0])
def test_other_viewing_distances(ppd):
    check(noise((60, 70)), noise((60, 70)), ppd=ppd, max_pixel=2e-5)


def test_rendered_images():
    a, b, shadowed, grainy = bricks_renders()
    check(a, b, max_pixel=1e-3)
    check(a, shadowed, max_pixel=1e-3)
    check(a, grainy, max_pixel=1e-3)


def test_reference_reused_for_several_tests_is_the_same_as_fresh():
    a, *tests = bricks_renders()
    ref = hzflip.FlipReference(a, PPD)
    for t in tests + [noise(a.shape[:2])]:
        m, mean = hzflip.flip_error(ref, t)
        m1, mean1 = hzflip.flip(a, t, PPD)
        np.testing.assert_array_equal(m, m1)
        assert mean == mean1


def test_kernels_replayed_for_a_shape_are_the_traced_ones():
    """FLIP's kernels are recorded once per image shape and replayed (``FROZEN_SHAPES`` of them kept):
    shapes interleaved, more of them than are kept, and new images of a shape seen before give the
    same maps as the first call of each, which traced them."""
    shapes = [(8 + 3 * i, 20 - i) for i in range(hzflip.FROZEN_SHAPES + 2)]
    images = {s: (noise(s), noise(s)) for s in shapes}
    first = {s: hzflip.flip(*images[s], PPD)[0] for s in shapes}
    for s in reversed(shapes):
        np.testing.assert_array_equal(hzflip.flip(*images[s], PPD)[0], first[s])
    for s in shapes[:3]:
        a, b = noise(s), noise(s)
        want, _ = reference_flip(a, b)
        assert float(np.max(np.abs(hzflip.flip(a, b, PPD)[0] - want))) <= 2e-5


def test_a_crop_away_from_its_border_is_the_whole_images(variant):
    """Each pixel reads its neighbours within the filters' radii (x, then y), clamped at the image's
    border: a crop's pixels farther than that from the crop's border are the whole image's, bit for
    bit, whatever the sizes (one kernel serves every size). Where the backend contracts FMAs, a
    pixel's place in its block decides which products fuse: there they agree to float32 rounding."""
    a, b = noise((90, 130)), noise((90, 130))
    whole, _ = hzflip.flip(a, b, PPD)
    f = hzflip.filters(PPD)
    m = 2 * max(f.spatial_radius, f.feature_radius)
    crop = (slice(7, 83), slice(20, 111))
    part, _ = hzflip.flip(a[crop], b[crop], PPD)
    if contracts_fma(variant):
        np.testing.assert_allclose(part[m:-m, m:-m], whole[crop][m:-m, m:-m], rtol=0, atol=1e-6)
    else:
        np.testing.assert_array_equal(part[m:-m, m:-m], whole[crop][m:-m, m:-m])
    assert not np.array_equal(part[:2], whole[crop][:2])  # the border itself differs: clamped


def numpy_separable_filter(plane, along_x, along_y):
    """FLIP's two passes written plainly in NumPy float32: one tap at a time over the plane with its
    edges repeated, summed in FLIP's tap order."""

    def correlate(p, weights, axis):
        r = (len(weights) - 1) // 2
        n = p.shape[axis]
        padded = np.pad(p, [(r, r) if a == axis else (0, 0) for a in range(2)], mode="edge")
        acc = None
        for i, wi in enumerate(weights):
            term = (padded[i : i + n] if axis == 0 else padded[:, i : i + n]) * np.float32(wi)
            acc = term if acc is None else acc + term
        return acc

    return correlate(correlate(plane.astype(np.float32), along_x, 1), along_y, 0)


@pytest.mark.parametrize("shape", [(1, 1), (3, 17), (9, 8), (16, 24), (37, 50), (64, 9)])
@pytest.mark.parametrize("ppd", [PPD, 20.0, 150.0])
def test_blocked_passes_are_the_plain_passes_bit_for_bit(variant, shape, ppd):
    """The passes compute BLOCK pixels a lane from inputs read once; each pixel's sums are still
    FLIP's, tap by tap in float32: they equal a plain NumPy float32 evaluation exactly, on sizes
    that are not whole blocks or are smaller than the filters, for every filter of FLIP's and for
    radii of one to three packets (150 ppd: 21 and 19 pixels). Where the backend contracts FMAs
    they agree within float32 summation's bound, ``(n_x + n_y) eps`` times the sum of
    ``|w_x| |w_y| |plane|`` over the taps (Higham, *Accuracy and Stability of Numerical
    Algorithms*, 2002, eq. 4.4)."""
    f = hzflip.filters(ppd)
    plane = (100.0 * noise(shape)[..., 0] - 16.0).astype(np.float32)
    for along_x, along_y in ((f.y, f.y), (f.cz1, f.cz2), (f.dg, f.g), (f.g, f.ddg), (f.g, f.y)):
        got = hzflip.separable_filter(plane, along_x, along_y)
        want = numpy_separable_filter(plane, along_x, along_y)
        if not contracts_fma(variant):
            np.testing.assert_array_equal(got, want)
            continue
        magnitude = numpy_separable_filter(np.abs(plane), np.abs(along_x), np.abs(along_y))
        bound = (len(along_x) + len(along_y)) * np.finfo(np.float32).eps * magnitude.astype(np.float64)
        assert np.all(np.abs(got.astype(np.float64) - want) <= bound)


def test_separable_filter_refuses_what_it_cannot_filter():
    with pytest.raises(ValueError):
        hzflip.separable_filter(np.zeros((4, 4, 3)), np.ones(3), np.ones(3))
    with pytest.raises(ValueError):
        hzflip.separable_filter(np.zeros((4, 4)), np.ones(2), np.ones(3))


def test_mean_is_flips_float32_running_sum():
    m = np.random.default_rng(0).random((300, 301)).astype(np.float32)
    total = np.float32(0)
    for v in m.ravel():
        total = np.float32(total + v)
    assert hzflip.mean_error(m) == float(total / np.float32(m.size))


def test_filters_are_flips():
    f = hzflip.filters(PPD)
    assert f.spatial_radius == 10 and f.feature_radius == 9  # at 67 ppd
    for w in (f.y, f.cx, f.g):
        assert w.sum() == pytest.approx(1.0, abs=1e-6)
    assert np.hypot(f.cz1.sum(), f.cz2.sum()) == pytest.approx(1.0, abs=1e-6)
    for w in (f.dg, f.ddg):
        assert w[w > 0].sum() == pytest.approx(1.0, abs=1e-6) and w[w < 0].sum() == pytest.approx(
            -1.0, abs=1e-6
        )
    assert f.cmax == pytest.approx(41.0, abs=1.0)


def test_bad_input_is_an_error():
    with pytest.raises(ValueError):
        hzflip.flip(np.zeros((4, 4, 3)), np.zeros((5, 4, 3)))
    with pytest.raises(ValueError):
        hzflip.flip(np.zeros((4, 4)), np.zeros((4, 4)))
    with pytest.raises(HzvalError):
        compare.flip(np.zeros((4, 4, 3)), np.zeros((4, 5, 3)))


def test_compare_uses_it():
    a, b, *_ = bricks_renders()
    m, mean = compare.flip(a, b)
    m0, mean0 = compare.flip_evaluator_flip(a, b)
    assert abs(mean - mean0) < 1e-6 and np.max(np.abs(m - m0)) < 1e-3


# -- CIEDE2000 -------------------------------------------------------------------------------------


def colour_lab(rgb):
    import colour

    return colour.XYZ_to_Lab(colour.sRGB_to_XYZ(np.asarray(rgb, np.float64), apply_cctf_decoding=True))


def colour_de(a, b):
    import colour

    return colour.delta_E(colour_lab(a), colour_lab(b), method="CIE 2000")


def grey_against_colour():
    """Grey and near-grey pixels (a, b within 1e-2 of 0: their hue is rounding) against saturated ones,
    and pairs of opposite hue (the CIEDE2000 mean hue's branch at |dh| = 180 degrees)."""
    g = np.linspace(0, 1, 64)
    grey = np.stack([g, g, g], axis=-1)[None].repeat(8, axis=0)
    sat = noise((8, 64)) ** 3
    opposite = np.concatenate(
        [np.stack([g, 1 - g, 0.5 + 0 * g], -1)[None], np.stack([1 - g, g, 0.5 + 0 * g], -1)[None]]
    )
    return np.concatenate([grey, grey, opposite[:1]]), np.concatenate(
        [sat, grey[::-1, ::-1] * 0.5 + 0.25, opposite[1:]]
    )


@pytest.mark.parametrize("case", ["noise", "renders", "grey", "tiny", "row"])
def test_delta_e2000_against_colour_science(case):
    if case == "noise":
        pairs = [(noise((128, 96)), noise((128, 96)))]
    elif case == "renders":
        a, *rest = bricks_renders()
        pairs = [(a, t) for t in rest]
    elif case == "grey":
        pairs = [grey_against_colour()]
    elif case == "tiny":
        pairs = [(noise((1, 1)), noise((1, 1))), (noise((2, 3)), noise((2, 3)))]
    else:
        pairs = [(noise((1, 257)), noise((1, 257)))]
    for a, b in pairs:
        want = colour_de(a, b)
        got = compare.delta_e2000(a, b)
        assert got.shape == a.shape[:2] and got.dtype == np.float64
        assert float(np.max(np.abs(got - want))) < 1e-9
        np.testing.assert_allclose(compare.lab(a), colour_lab(a), rtol=0, atol=1e-9)


def test_delta_e2000_with_the_reference_lab_given():
    a, b, c = noise((40, 50)), noise((40, 50)), noise((40, 50))
    lab = compare.LabImage(a)
    fresh = compare.delta_e2000(a, b)
    np.testing.assert_array_equal(compare.delta_e2000(a, b, reference_lab=lab), fresh)
    np.testing.assert_allclose(
        compare.delta_e2000(a, b, reference_lab=colour_lab(a)), fresh, rtol=0, atol=1e-9
    )
    np.testing.assert_array_equal(
        compare.delta_e2000(a, c, reference_lab=lab), compare.delta_e2000(a, c)
    )  # reused
    np.testing.assert_allclose(lab.numpy(), colour_lab(a), rtol=0, atol=1e-9)


def test_delta_e2000_known_values():
    black, white = np.zeros((2, 2, 3)), np.ones((2, 2, 3))
    assert np.all(compare.delta_e2000(black, black) == 0)
    np.testing.assert_allclose(compare.delta_e2000(white, black), 100.0, atol=0.01)
    with pytest.raises(HzvalError):
        compare.delta_e2000(black, np.zeros((2, 3, 3)))


def test_delta_e2000_colour_is_colour_science():
    a, b = noise((30, 20)), noise((30, 20))
    np.testing.assert_array_equal(compare.delta_e2000_colour(a, b), colour_de(a, b))
