"""Every memory estimate's figures and formulas: the bake, a sweep, the truth's meshes, a fit.

Each ``*_BYTES*`` constant is fitted to peaks measured on this machine (the benchmark named beside it)
and rounded up; each function adds them up from plain numbers (pixels, samples, triangles), so that
the layers that know a scene (:mod:`hzval.truth.memory`, :mod:`hzval.bake.maps`, ...) all charge the
same figures. :func:`hzval.core.resources.refuse_over` turns an estimate into a refusal.
"""

from __future__ import annotations

from hzval.core import conventions as cv

__all__ = [
    "BAKE_BYTES_PER_TEXEL",
    "BAKE_BYTES_PER_TEXEL_PER_EXTRA_DIRECTION",
    "OCCLUSION_BYTES_PER_TEXEL",
    "PEAK_BASE_BYTES",
    "PEAK_BYTES_PER_PIXEL",
    "PEAK_BYTES_PER_TECHNIQUE_PIXEL",
    "TECHNIQUES_BY_DEFAULT",
    "PEAK_BYTES_PER_TRIANGLE",
    "TRIANGLES_PER_PIXEL_BEFORE_THE_MAP",
    "PEAK_BYTES_PER_SAMPLE",
    "PEAK_BYTES_PER_KEPT_SAMPLE",
    "STATE_BYTES_PER_SAMPLE",
    "PEAK_BYTES_PER_VIEW_SAMPLE",
    "RETAIN_BELOW_SHARE",
    "PEAK_TARGET_BYTES",
    "PEAK_BAND_BYTES_PER_PIXEL",
    "PEAK_BYTES_PER_BAND_TRIANGLE",
    "MAX_FRAME_PIXELS",
    "TRUTH_BYTES_PER_TRIANGLE",
    "MESH_BYTES_PER_TRIANGLE",
    "REFINE_BYTES_PER_TRIANGLE",
    "MODEL_BYTES_PER_SAMPLE",
    "MODEL_BYTES_PER_TRIANGLE",
    "MODEL_BYTES_PER_REFLECTION_SAMPLE",
    "FIT_BASE_BYTES",
    "FIT_BYTES_PER_PIXEL_LIGHT",
    "FIT_BYTES_PER_SAMPLE",
    "FIT_BYTES_PER_TEXEL",
    "FIT_BYTES_PER_BAND_SAMPLE",
    "bake_bytes",
    "sweep_peak_bytes",
    "band_peak_bytes",
    "model_sample_bytes",
    "model_truth_bytes",
    "model_sweep_peak_bytes",
    "mesh_bytes",
    "fit_bytes",
]

# --------------------------------------------------------------------------
# The bake
# --------------------------------------------------------------------------

#: Bytes of memory per texel that a bake needs at its peak (inputs, padded copy, ten kernel outputs,
#: their NumPy copies, normal map, 8-bit encodings), measured with tracemalloc and rounded up, for 8
#: directions.
BAKE_BYTES_PER_TEXEL = 160
#: Bytes per texel that each direction beyond 8 adds (a kernel output, its NumPy copy and stacked
#: channel, its 8-bit encoding: 4 + 4 + 4 + 1, rounded up; an estimate from the 8-direction figure,
#: not measured separately).
BAKE_BYTES_PER_TEXEL_PER_EXTRA_DIRECTION = 16
#: Bytes per texel that the bent normal and the self-shadowed bump map add to a bake at its peak, made
#: two at a time (:func:`hzval.bake.maps.bake`): their six float32 channels and the temporaries of two
#: of them at once (NumPy's allocations traced at 512 x 512: 92 to 105 bytes a texel, as the jobs
#: interleave; 52 made in turn, 140 to 160 four at a time).
OCCLUSION_BYTES_PER_TEXEL = 112


def bake_bytes(rows: int, cols: int, directions: int, pad: int = 0) -> int:
    """Return the peak memory of a bake, in bytes.

    Parameters
    ----------
    rows, cols : int
        The height map's size, texels.
    directions : int
        The horizon map's channels.
    pad : int
        Texels the bake pads each side with (the seed's ``radius - 1``; the exact method pads nothing).

    Examples
    --------
    >>> bake_bytes(1024, 1024, 8) == (160 + 112) * 2**20
    True
    """
    per_texel = (
        BAKE_BYTES_PER_TEXEL
        + OCCLUSION_BYTES_PER_TEXEL
        + BAKE_BYTES_PER_TEXEL_PER_EXTRA_DIRECTION * (directions - cv.CHANNEL_COUNT)
    )
    return per_texel * (rows + 2 * pad) * (cols + 2 * pad)


# --------------------------------------------------------------------------
# A sweep on the plane
# --------------------------------------------------------------------------

#: A sweep's peak memory: a base, a cost per pixel (images, comparisons), one per triangle of the
#: truth's mesh (its faces, vertices and Embree's BVH), one per sample for the techniques (the shared
#: uv, terrain's xy, the positions while they are set up) and one per sample the truth keeps between
#: frames (its hits: every sample up to hzval.truth.samples.KEEP_SAMPLES, one band's beyond). Fitted to
#: the peaks measured on this machine (``python benchmarks/bench_production.py``; docs/truth-surface.md,
#: "Cost").
PEAK_BASE_BYTES = 0.3 * 2**30
PEAK_BYTES_PER_PIXEL = 115
#: What each technique adds per pixel at the peak: its frame (image and factor, float32) and what its
#: comparison keeps for the writers, held together until the frame is written. Fitted to the bricks
#: with the eight default techniques against three: 8.16 GiB against 7.35 at 2048 (41 bytes a pixel
#: each), 17.12 GiB against 11.94 at 4096 (65: its frame's comparison and files peak there,
#: ``benchmarks/memory_timeline.py``); the larger, with a margin.
PEAK_BYTES_PER_TECHNIQUE_PIXEL = 70
#: The techniques a sweep runs when none are named (``hzval.techniques.registry.defaults``; a test
#: keeps the two equal): what an estimate made before they are chosen charges.
TECHNIQUES_BY_DEFAULT = 8
#: The mesh's share of the peak, per triangle (hzval.truth.plane.mesh_triangles): the 2048 bricks' peak
#: grew by 2.0 GiB with 26M triangles more (37.5M against bd627d5's 11.5M); Embree holds about 94
#: bytes a triangle once built, 133 while it builds (:data:`TRUTH_BYTES_PER_TRIANGLE`), part of which
#: the peak, later, does not see.
PEAK_BYTES_PER_TRIANGLE = 83
#: Triangles a pixel before the map is known (:func:`sweep_peak_bytes` without the mesh's count): a
#: symmetric tessellation's fewest for a map of twisted cells (four a cell,
#: hzval.geometry.tile.cell_levels), so that the check before the map is generated refuses only what
#: cannot fit; the sweep checks again with the mesh's own count once the map is read.
TRIANGLES_PER_PIXEL_BEFORE_THE_MAP = 4
PEAK_BYTES_PER_SAMPLE = 24
PEAK_BYTES_PER_KEPT_SAMPLE = 52
#: Of a kept sample's bytes, the plane truth's state (:class:`hzval.truth.plane.Truth`): the lifted
#: origin's height (its x and y are the sample positions themselves), the geometric and shading
#: normals and ``A`` (8 float32; the albedo is gathered again by each frame's kernel).
STATE_BYTES_PER_SAMPLE = 32
#: What a view other than ``top`` adds per sample of a band (rays on the host, the hits).
PEAK_BYTES_PER_VIEW_SAMPLE = 64
#: A sweep whose estimated peak is at most this share of the memory available keeps what it frees
#: for its own next allocations until it ends (:func:`hzval.core.backend.retain_freed_memory`; the
#: figures: docs/internals.md); a larger one hands it back, as its peak needs.
RETAIN_BELOW_SHARE = 0.5
#: The most frame pixels (lights x the image's pixels) a sweep renders: 2^31, e.g. 128 lights at
#: 4096 x 4096 or the 361 lights of MAX_LIGHTS at 2400 x 2400. A frame's files take about 17 bytes a
#: pixel (72 MB at 2048 x 2048) and its renders about 0.5 us a pixel here: 2^31 is 36 GB of files and
#: a quarter of an hour to hours of rendering, the most a report is worth waiting for.
MAX_FRAME_PIXELS = 2**31


def _images_bytes(pixels: int, techniques: int) -> int:
    """Return what a sweep's images and comparisons hold per frame at the peak, its techniques' included."""
    return (PEAK_BYTES_PER_PIXEL + PEAK_BYTES_PER_TECHNIQUE_PIXEL * techniques) * pixels


def sweep_peak_bytes(
    pixels: int, samples: int, kept: int, triangles: int, techniques: int, view: bool = False
) -> int:
    """Return the peak resident memory of a sweep on the plane, in bytes.

    Parameters
    ----------
    pixels : int
        The image's pixels.
    samples : int
        Its samples (pixels times samples per pixel).
    kept : int
        The samples whose camera hits the truth keeps between frames (all, or one band's).
    triangles : int
        The truth's mesh's (0 for a mesh in bands: :func:`band_peak_bytes` charges those).
    techniques : int
        How many the sweep runs.
    view : bool
        Whether the camera is other than ``top``: a band's rays in float64 on the host, the truth's
        hits and the techniques built twice.
    """
    extra = PEAK_BYTES_PER_VIEW_SAMPLE * kept + PEAK_BYTES_PER_SAMPLE * samples if view else 0
    return int(
        PEAK_BASE_BYTES
        + _images_bytes(pixels, techniques)
        + PEAK_BYTES_PER_TRIANGLE * triangles
        + PEAK_BYTES_PER_SAMPLE * samples
        + PEAK_BYTES_PER_KEPT_SAMPLE * kept
        + extra
    )


# --------------------------------------------------------------------------
# The truth's mesh in bands
# --------------------------------------------------------------------------

#: The peak a sweep aims to stay within (a 4096 x 4096 sweep within 16 GiB): past it, or past the
#: memory available, the truth builds its mesh in bands (:func:`hzval.truth.memory.truth_plan`).
PEAK_TARGET_BYTES = 16 * 2**30
#: The truth's peak while it builds its mesh in bands (:mod:`hzval.truth.bands`), before the techniques
#: are built: a base, the bake and the albedo per pixel, a band's triangles while Embree builds them
#: (their positions and faces, Embree's BVH and its build's own buffers; a band's samples come after,
#: once those are freed) and the visibility bits (one a sample a light). Fitted to the 4096 bricks
#: (docs/truth-surface.md, "Cost": 2.37 GiB before the first band, 11.57 GiB at its build's peak with
#: 75M triangles; 11.93 GiB with 79M and 16.26 GiB with one band of 111M, 134 bytes a triangle:
#: the larger, with a margin, so that a band whose build would pass the target is not chosen).
PEAK_BAND_BYTES_PER_PIXEL = 130
PEAK_BYTES_PER_BAND_TRIANGLE = 135


def band_peak_bytes(texels: int, band_triangles: int, bits: float) -> int:
    """Return the peak of the truth's phase in bands, in bytes.

    ``texels``: the height map's; ``band_triangles``: the largest band's; ``bits``: the visibility
    bits' bytes (one bit a sample a light).
    """
    return int(
        PEAK_BASE_BYTES
        + PEAK_BAND_BYTES_PER_PIXEL * texels
        + PEAK_BYTES_PER_BAND_TRIANGLE * band_triangles
        + bits
    )


# --------------------------------------------------------------------------
# Meshes
# --------------------------------------------------------------------------

#: Resident bytes per triangle of the truth's mesh on the plane: its faces, its share of the vertices
#: and Embree's BVH (at 2048 x 2048 with a margin of 178: 4.42 GiB against 1.59 GiB for 33.9M
#: triangles against 11.3M, 134 bytes a triangle more).
TRUTH_BYTES_PER_TRIANGLE = 140
#: Peak bytes per triangle while :func:`hzval.geometry.tile.displaced_mesh` builds a mesh with vertex
#: normals and texture coordinates and it is written (``benchmarks/bench_mesh_memory.py``: 112-134
#: measured on the bricks, half a vertex a triangle), with a margin.
MESH_BYTES_PER_TRIANGLE = 160
#: Bytes per refined triangle of a model to budget: :func:`hzval.geometry.displace.refine` and
#: :func:`hzval.geometry.displace.displace` peak at 330-390 bytes a triangle over their start (a
#: 20k-triangle torus and model, the plane, 512^2 and 1024^2, benchmarks/bench_meshes.py) and keep
#: 130-250 (the refined arrays and the displaced positions), to which Mitsuba's mesh and Embree's BVH
#: add 140 (:data:`TRUTH_BYTES_PER_TRIANGLE`).
REFINE_BYTES_PER_TRIANGLE = 420
#: Bytes a sample of the truth on a model keeps between frames (hit, normals, frame, uv, base point,
#: triangle: 23 floats) and what the techniques keep of it (their frames, texel positions).
MODEL_BYTES_PER_SAMPLE = 4 * 23 + 4 * 14
#: A displaced triangle of a model with its BVH.
MODEL_BYTES_PER_TRIANGLE = 120
#: What ``reflection_occlusion`` adds a sample: its lobe's ray while it is traced (origin, direction,
#: weight, masks: about 40 bytes, beside the kept hits) and ``R`` with its variance, kept between frames
#: (8 bytes a pixel, counted a sample). Measured at 384 x 384 px, 8 spp on the sphere: the peak did not
#: rise (583 MiB against 590 without): the lobe's rays fit under the camera rays' peak (docs/meshes.md).
MODEL_BYTES_PER_REFLECTION_SAMPLE = 48


def mesh_bytes(triangles: int, also: float = 0) -> float:
    """Return the peak of building and writing a tile's displaced mesh, and ``also`` bytes beside it."""
    return also + MESH_BYTES_PER_TRIANGLE * triangles


def model_sample_bytes(reflection: bool) -> int:
    """Return the bytes a sample of the truth on a model takes at its peak.

    Its kept hit and frame (:data:`MODEL_BYTES_PER_SAMPLE`) and, with ``reflection`` (the scene
    declares ``reflection_occlusion``), the lobe's rays (:data:`MODEL_BYTES_PER_REFLECTION_SAMPLE`).
    """
    return MODEL_BYTES_PER_SAMPLE + (MODEL_BYTES_PER_REFLECTION_SAMPLE if reflection else 0)


def model_truth_bytes(refined_bytes: int, triangles: int, samples: int, reflection: bool) -> int:
    """Return the truth's memory on a model: the refined mesh, its displaced triangles and its samples.

    ``refined_bytes`` and ``triangles`` are :func:`hzval.geometry.displace.estimate`'s.
    """
    return refined_bytes + MODEL_BYTES_PER_TRIANGLE * triangles + model_sample_bytes(reflection) * samples


def model_sweep_peak_bytes(
    refined_bytes: int, triangles: int, samples: int, reflection: bool, pixels: int, techniques: int
) -> int:
    """Return the peak of a sweep on a model: :func:`model_truth_bytes`, the images and the techniques'."""
    truth = model_truth_bytes(refined_bytes, triangles, samples, reflection)
    return int(PEAK_BASE_BYTES + truth + _images_bytes(pixels, techniques))


# --------------------------------------------------------------------------
# A fit
# --------------------------------------------------------------------------

#: Memory of a fit (:func:`fit_bytes`): a base, bytes per pixel and light (V), per sample (uv), per
#: texel (parameters, gradient, Adam's two moments, the stored copy, the bake) and per sample of a band
#: (the AD graph of the forward model).
FIT_BASE_BYTES = 0.4 * 2**30
FIT_BYTES_PER_PIXEL_LIGHT = 4
FIT_BYTES_PER_SAMPLE = 8
FIT_BYTES_PER_TEXEL = 8 * 4 * 8
FIT_BYTES_PER_BAND_SAMPLE = 160


def fit_bytes(pixels: int, spp: int, lights: int, band_samples: int, render: int = 0) -> int:
    """Return a fit's estimated peak memory, in bytes.

    The truth's ``V`` of every light, beside the larger of the truth's own peak while it renders and the
    optimisation's.

    Parameters
    ----------
    pixels : int
        The map's texels (the fit renders a pixel a texel).
    spp : int
        Samples per pixel.
    lights : int
        Training and held-out lights, each a ``V`` kept.
    band_samples : int
        The samples of one band of the forward model.
    render : int
        The truth's own peak while it renders (:func:`sweep_peak_bytes` of the fit's scene), bytes.
    """
    optimise = (
        FIT_BASE_BYTES
        + FIT_BYTES_PER_SAMPLE * pixels * spp
        + FIT_BYTES_PER_TEXEL * pixels
        + FIT_BYTES_PER_BAND_SAMPLE * band_samples
    )
    return int(FIT_BYTES_PER_PIXEL_LIGHT * pixels * lights + max(optimise, render))
