"""Metrics against cases whose values are known."""

import math

import numpy as np
import pytest

from hzval.core import srgb
from hzval.core.errors import HzvalError
from hzval.io import codecs
from hzval.metrics import compare
from hzval.scene.spec import Frame


def frame(img, **layers):
    return Frame(0.0, 30.0, np.asarray(img, np.float32), layers)


def test_visibility_metrics_count_leaks_and_false_shadows():
    V = np.array([[1, 1, 0, 0]], np.float32)
    F = np.array([[1, 0.2, 0.9, 0]], np.float32)  # one false shadow, one leak
    mae, leak, false_shadow = compare.visibility_metrics(V, F)
    assert mae == pytest.approx((0 + 0.8 + 0.9 + 0) / 4)
    assert leak == 0.25 and false_shadow == 0.25


def test_identical_frames_have_no_error():
    img = np.random.default_rng(0).random((16, 16, 3)) * 0.5
    m, maps = compare.compare(frame(img, visibility=img[..., 0]), frame(img, factor=img[..., 0]), 1.0)
    assert m.visibility_mae == 0 and m.rmse == 0 and m.flip_mean == 0 and m.delta_e2000_mean == 0
    assert m.psnr_db == math.inf


def test_black_against_white():
    black, white = np.zeros((8, 8, 3)), np.ones((8, 8, 3))
    m, maps = compare.compare(frame(white), frame(black), 1.0)
    assert m.rmse == pytest.approx(1.0) and m.psnr_db == pytest.approx(0.0)
    assert m.delta_e2000_mean == pytest.approx(100.0, abs=0.01)  # L* 100 -> 0
    assert m.flip_mean > 0.5 and m.visibility_mae is None


def test_psnr_of_a_constant_offset():
    a = np.full((8, 8, 3), 0.5)
    m, _ = compare.compare(frame(a), frame(a + 0.1), 1.0)
    assert m.psnr_db == pytest.approx(20.0)


def test_display_encodes_srgb_after_exposure():
    d = compare.display(np.array([[0.5 / math.pi]]), math.pi)
    assert d.shape == (1, 1, 3) and d[0, 0, 0] == pytest.approx(0.7353569, abs=1e-6)


@pytest.mark.parametrize("dtype", [np.float32, np.float64])
def test_display_is_colour_sciences_encoding_of_the_exposed_values(dtype):
    """The Dr.Jit kernel against colour-science's sRGB encoding, on values below 0, on both sides
    of the linear segment's end (0.0031308) and above 1 once exposed; grey (H, W) images too."""
    rng = np.random.default_rng(5)
    a = (rng.random((37, 23, 3)) * 1.2 - 0.1).astype(dtype)
    a[0, :3, 0] = (0.0031308 / 0.7, 0.0, 1.0 / 0.7)
    want = srgb.encode(np.clip(np.asarray(a, np.float64) * 0.7, 0, 1))
    got = compare.display(a, 0.7)
    assert got.shape == a.shape and got.dtype == np.float64
    assert np.max(np.abs(got - want)) <= 4e-16
    grey = compare.display(a[..., 1], 0.7)
    assert (
        grey.shape == a.shape
        and np.array_equal(grey[..., 0], got[..., 1])
        and np.array_equal(grey[..., 2], got[..., 1])
    )


def test_flip_refusal_is_an_error_not_an_exit():
    with pytest.raises(HzvalError):
        compare.flip(np.zeros((4, 4, 3)), np.zeros((5, 4, 3)))


def test_colour_science_in_row_blocks_is_bit_for_bit_one_call(monkeypatch):
    import colour

    rng = np.random.default_rng(3)
    a, b = rng.random((2, 3 * compare.PARALLEL_MIN_ROWS + 5, 40, 3))
    from hzval.core import backend

    monkeypatch.setattr(backend, "host_cores", lambda: 3)  # three blocks, on three threads

    def lab(x):
        return colour.XYZ_to_Lab(colour.sRGB_to_XYZ(x, apply_cctf_decoding=True))

    np.testing.assert_array_equal(
        compare.delta_e2000_colour(a, b), colour.delta_E(lab(a), lab(b), method="CIE 2000")
    )


def test_image_metrics_match_flip_evaluator_and_colour_science():
    """The sweep's FLIP (hzval.metrics.flip) and CIEDE2000 (the Dr.Jit kernel) against the packages they
    replaced, through a Reference reused for two images (tests/metrics/test_flip.py checks them in depth)."""
    rng = np.random.default_rng(5)
    truth = rng.random((40, 70, 3)) * 0.4
    ref = compare.Reference(frame(truth), 1.2)
    for img in (truth * 0.8, np.clip(truth + 0.05 * rng.standard_normal(truth.shape), 0, None)):
        scores, maps = compare.image_metrics(ref, img)
        want_map, want_mean = compare.flip_evaluator_flip(ref.display, maps["display"])
        assert abs(scores["flip_mean"] - want_mean) < 1e-6
        assert np.max(np.abs(maps["flip"] - want_map)) < 1e-4
        de = compare.delta_e2000_colour(ref.display, maps["display"])
        assert np.max(np.abs(maps["delta_e"] - de)) < 1e-9
        assert scores["delta_e2000_mean"] == pytest.approx(float(np.mean(de)), abs=1e-9)


@pytest.mark.parametrize("shape", [(1, 1), (37, 50), (64, 9)])
def test_a_grey_image_scores_the_same_through_its_one_channel(variant, shape, monkeypatch):
    """A grey image's colour is converted once, not three times (CIELAB, CIEDE2000 and FLIP): every
    value is the same bit for bit as through the three channels, and an image that is grey but for
    one pixel is not taken for grey."""
    from hzval.metrics import flip as hzflip

    rng = np.random.default_rng(sum(shape))
    grey = lambda a: np.repeat(a[..., None], 3, axis=-1)  # noqa: E731
    ref = grey(rng.random(shape).astype(np.float32))
    test = grey(np.clip(ref[..., 0] + 0.2 * rng.standard_normal(shape), 0, 1.2).astype(np.float32))
    same = lambda a, b: np.ascontiguousarray(a).tobytes() == np.ascontiguousarray(b).tobytes()  # noqa: E731
    r_disp, t_disp = compare.display(ref, 0.9), compare.display(test, 0.9)
    assert same(compare.LabImage(r_disp, grey=True).numpy(), compare.LabImage(r_disp, grey=False).numpy())
    assert same(
        compare.delta_e2000(r_disp, t_disp, grey=True), compare.delta_e2000(r_disp, t_disp, grey=False)
    )
    both = [hzflip.flip_error(hzflip.FlipReference(r_disp, grey=g), t_disp, grey=g)[0] for g in (True, False)]
    assert same(*both)
    ref_frame = Frame(0.0, 30.0, ref, {})
    scores = compare.image_metrics(compare.Reference(ref_frame, 0.9), test)[0]
    with monkeypatch.context() as m:  # every image taken for colour: the three-channel path
        m.setattr(codecs, "is_grey", lambda a: False)
        assert scores == compare.image_metrics(compare.Reference(ref_frame, 0.9), test)[0]
    if ref.size > 3:
        test[0, 0, 1] += 0.25
        assert not codecs.is_grey(test)
        assert not same(compare.display(test, 0.9)[..., 1], compare.display(test, 0.9)[..., 0])
