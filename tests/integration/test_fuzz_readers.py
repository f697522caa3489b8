"""Hypothesis fuzzing of the readers of images and of the gates' grammar (issue 53): height maps (PNG,
EXR, ``.npy``), the horizon layers of ``--horizon-map``, ``check``'s references and ``--fail-if``.

Every test starts from data the reader accepts (asserted on the first case), generates values or
bytes around it, and asserts what the reader must answer: the values it was given, to the bit, or
one line of :class:`InputError`, and exactly when. Each also asserts that a share of its cases got
past the reader's checks, so that a test never exercises only its first refusal (the JSON and TOML
readers' fuzzing, in test_faults_fuzz.py, does the same). Examples are derandomised.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra import numpy as hnp
from PIL import Image

from hzval.commands import check, gates
from hzval.core.errors import InputError
from hzval.core.srgb import luminance_weights
from hzval.io import codecs, external, heightmap

SETTINGS = settings(
    max_examples=40, deadline=None, derandomize=True, database=None, suppress_health_check=list(HealthCheck)
)
#: The least share of generated cases each reader must take to its end (module docstring).
ACCEPTED = 0.3

shapes = st.tuples(st.integers(1, 9), st.integers(1, 9))
floats32 = st.floats(width=32, allow_nan=True, allow_infinity=True) | st.sampled_from([0.0, 1.0, -1.0])


def one_line(exc: InputError) -> None:
    assert "\n" not in str(exc) and str(exc), str(exc)


class Tally:
    """How many cases a reader took to its end."""

    def __init__(self):
        self.accepted = self.total = 0

    def __call__(self, ok: bool) -> None:
        self.accepted += bool(ok)
        self.total += 1

    def check(self, least: float = ACCEPTED) -> None:
        assert self.total and self.accepted / self.total >= least, (self.accepted, self.total)


def read(path: Path):
    """``load_height(path)``'s heights, or ``None`` for one line of InputError."""
    try:
        return heightmap.load_height(path).height
    except InputError as exc:
        one_line(exc)
        return None


# --------------------------------------------------------------------------------------------------
# Height maps, from values: every array each format holds, written as the format's own writer does
# --------------------------------------------------------------------------------------------------


@st.composite
def png_images(draw):
    """``(samples, mode)``: 8-bit grey, RGB or RGBA, or 16-bit grey."""
    mode = draw(st.sampled_from(["L", "RGB", "RGBA", "I;16"]))
    rows, cols = draw(shapes)
    dtype = np.uint16 if mode == "I;16" else np.uint8
    planes = {"L": (), "I;16": (), "RGB": (3,), "RGBA": (4,)}[mode]
    return draw(hnp.arrays(dtype, (rows, cols, *planes))), mode


def test_png_heights_are_the_samples_scaled(tmp_path):
    tally = Tally()

    @SETTINGS
    @given(png_images())
    def case(image):
        samples, mode = image
        path = tmp_path / "h.png"
        Image.fromarray(samples).save(path)
        got = read(path)
        tally(got is not None)
        if samples.shape[0] * samples.shape[1] < 2:  # the one refusal these files may get
            assert got is None
            return
        assert got is not None and got.dtype == np.float32 and got.shape == samples.shape[:2]
        scale = 65535.0 if samples.dtype == np.uint16 else 255.0
        want = samples / scale if samples.ndim == 2 else samples[..., :3] / scale @ luminance_weights()
        assert np.allclose(got, want, rtol=0, atol=1e-6) and np.isfinite(got).all()

    case()
    tally.check()


def test_exr_heights_are_taken_as_they_are_or_refused_when_not_finite(tmp_path):
    tally = Tally()

    @SETTINGS
    @given(shapes.flatmap(lambda s: hnp.arrays(np.float32, s, elements=floats32)), st.booleans())
    def case(values, half):
        path = tmp_path / "h.exr"
        with np.errstate(over="ignore"):  # float32 beyond half's range becomes infinite, as a file would
            codecs.write_exr(path, {"Y": values.astype(np.float16) if half else values})
        stored = codecs.read_exr(path)["Y"]
        got = read(path)
        tally(got is not None)
        if values.size < 2 or not np.isfinite(stored).all():
            assert got is None
        else:
            assert got is not None and np.array_equal(got, stored)

    case()
    tally.check()


#: Real dtypes more often than the two a height map cannot be (bool, complex).
npy_dtypes = st.sampled_from(["f2", "f4", "f8", "i1", "u2", "i4", "i8", "f4", "f8", "?", "c8"])


def test_npy_heights_are_float32_values_or_one_line(tmp_path):
    tally = Tally()

    @SETTINGS
    @given(
        npy_dtypes.flatmap(
            lambda d: hnp.arrays(
                np.dtype(d),
                st.sampled_from([(3, 5), (5, 3, 1), (6, 2), (4,), (2, 2, 3), (1, 1)]),
                elements=None if np.dtype(d).kind != "f" else st.floats(width=8 * np.dtype(d).itemsize),
            )
        )
    )
    def case(values):
        path = tmp_path / "h.npy"
        np.save(path, values)
        got = read(path)
        tally(got is not None)
        real = values.dtype.kind in "iuf"
        plane = values.ndim == 2 or (values.ndim == 3 and values.shape[2] == 1)
        with np.errstate(over="ignore"):
            as32 = values.astype(np.float32) if real else None
        if not (real and plane and values.size >= 2 and np.isfinite(as32).all()):
            assert got is None
        else:
            assert got is not None and np.array_equal(got, as32.reshape(got.shape))

    case()
    tally.check()


# --------------------------------------------------------------------------------------------------
# Height maps, from bytes: a valid file with some of its bytes overwritten
# --------------------------------------------------------------------------------------------------


def valid_file(tmp_path: Path, kind: str) -> bytes:
    values = np.random.default_rng(5).random((6, 7)).astype(np.float32)
    path = tmp_path / f"seed.{kind}"
    if kind == "exr":
        codecs.write_exr(path, {"Y": values}, compression="none")
    elif kind == "npy":
        np.save(path, values)
    else:
        Image.fromarray((values * 65535).astype(np.uint16)).save(path)
    assert read(path) is not None  # the seed is accepted
    return path.read_bytes()


@pytest.mark.parametrize("kind, least", [("exr", ACCEPTED), ("npy", ACCEPTED), ("png", 0.0)])
def test_a_height_map_with_bytes_overwritten_is_read_whole_or_refused_in_one_line(tmp_path, kind, least):
    """EXR (uncompressed) and ``.npy`` keep their pixels in their second half: bytes overwritten
    there are new heights, refused only where not finite. A PNG's pixels are deflated and check-
    summed, so most of its cases are refused: no share is asserted there."""
    seed = valid_file(tmp_path, kind)
    tally = Tally()
    half = len(seed) // 2 if kind != "png" else 8

    @SETTINGS
    @given(st.lists(st.tuples(st.integers(half, len(seed) - 1), st.integers(0, 255)), min_size=1, max_size=6))
    def case(edits):
        data = bytearray(seed)
        for at, byte in edits:
            data[at] = byte
        path = tmp_path / f"h.{kind}"
        path.write_bytes(bytes(data))
        got = read(path)
        tally(got is not None)
        if got is not None:
            assert got.dtype == np.float32 and got.shape == (6, 7) and np.isfinite(got).all()

    case()
    tally.check(least)


def test_a_missing_exr_is_named_missing(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        codecs.read_exr(tmp_path / "none.exr")


# --------------------------------------------------------------------------------------------------
# --horizon-map layers, check's references, --fail-if
# --------------------------------------------------------------------------------------------------


def test_horizon_layers_are_taken_when_finite_and_in_range(tmp_path):
    tally = Tally()
    enc = external.Encoding(channels=8)

    @SETTINGS
    @given(
        hnp.arrays(np.float32, (4, 5, 8), elements=st.floats(-1.0, 1.0, width=32) | floats32),
    )
    def case(values):
        paths = [tmp_path / "h0.exr", tmp_path / "h1.exr"]
        for i, p in enumerate(paths):
            codecs.write_exr(p, {"RGBA": values[..., 4 * i : 4 * i + 4]})
        try:
            got = external.check_layers(external.read_layers(paths), enc, paths)
        except InputError as exc:
            one_line(exc)
            got = None
        tally(got is not None)
        ok = np.isfinite(values).all() and values.min() >= -1 - 1e-6 and values.max() <= 1 + 1e-6
        assert (got is not None) == bool(ok)
        if ok:
            assert np.array_equal(got, values)

    case()
    tally.check()


@given(
    hnp.arrays(np.float32, (8, 8), elements=st.floats(0.0, 1.0, width=32)),
    st.lists(
        st.tuples(st.integers(0, 7), st.integers(0, 7), floats32 | st.floats(-1e-3, 1e-3)),
        max_size=4,
    ),
)
@SETTINGS
def test_a_technique_reference_passes_only_when_every_pixel_is_finite_and_within_tolerance(new, edits):
    """``check``'s test of a technique's image against its reference: exactly what its tiers say."""
    ref = new.copy()
    for r, c, v in edits:
        ref[r, c] = new[r, c] + v if abs(v) <= 1e-3 else v
    tiers = check.DEFAULT_TIERS["technique"]
    channels = lambda f: {"R": f, "G": f, "B": f, "F": f}  # noqa: E731
    status, reasons, _, _ = check.compare_image(channels(new), channels(ref), "horizon", tiers, 1.0, 16)
    diff = np.abs(new.astype(np.float64) - ref.astype(np.float64))
    should_pass = bool(np.isfinite(ref).all() and diff.max() <= tiers.fail)
    assert (status == "pass") == should_pass, (status, reasons)


operands = st.sampled_from(gates.known_names(["horizon", "pom", "engine"])).flatmap(
    lambda n: st.sampled_from([n, f"mean({n})", f"max({n})", f"min({n})"])
)
numbers = st.floats(allow_nan=False, allow_infinity=False, width=32).map(lambda x: f"{x:g}")


def test_every_condition_of_the_grammar_parses_and_names_what_it_reads():
    tally = Tally()

    @SETTINGS
    @given(operands, st.sampled_from([">", ">=", "<", "<="]), operands | numbers, st.text(" ", max_size=2))
    def case(left, op, right, pad):
        cond = gates.parse(f"{pad}{left}{pad}{op}{pad}{right}{pad}")
        gates.check_names([cond], ["horizon", "pom", "engine"])
        tally(True)
        assert cond.op == op and cond.left.text() == left
        if cond.right.path is None:
            assert math.isclose(cond.right.number, float(right))
        else:
            assert cond.right.text() == right

    case()
    tally.check(1.0)


def test_any_text_is_a_condition_or_one_line():
    tally = Tally()
    alphabet = st.sampled_from(list("horizn.flipmea_()<>=0123456789.eE+- \t"))

    @SETTINGS
    @given(
        st.text(alphabet, max_size=40)
        | (operands.map(lambda o: o + ">") | st.just("")).flatmap(
            lambda head: (numbers | st.text(alphabet, max_size=12)).map(lambda tail: head + tail)
        )
    )
    def case(text):
        try:
            cond = gates.parse(text)
            gates.check_names([cond], ["horizon"])
        except InputError as exc:
            one_line(exc)
            tally(False)
        else:
            tally(True)

    case()
    tally.check(0.05)
