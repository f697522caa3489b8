"""The built-in brick wall, hzval's default material: procedural and seamlessly tiling.

:func:`bricks` returns a height map ``H[row, col]`` in [0, 1] (row 0 at the
top, docs/ARCHITECTURE.md "Conventions") of bricks laid in running bond: bevelled
brick faces standing proud of recessed mortar joints, each brick with its own
height, tilt, chipped edges and rough face, over a fine grain everywhere. It
lets every hzval command run with no input, and its relief (at
:data:`DEFAULT_DEPTH`) casts long, structured shadows at the ~30 degree light
elevations of the sweep.

The map is exactly periodic with period ``(rows, cols)``: the bond has an
integer number of bricks per course and an even number of courses per
period, and all noise is seeded white noise filtered in the Fourier domain,
which is periodic by construction. It therefore tiles (``boundary="wrap"``)
without a seam.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from hzval.materials import DEFAULT_SIZE, Material
from hzval.materials.noise import periodic_noise, shape_of, smoothstep

__all__ = ["DEFAULT_SIZE", "DEFAULT_DEPTH", "MIN_SIZE", "MATERIAL", "bricks"]

#: Smallest side :func:`bricks` accepts, in texels.
MIN_SIZE = 8
#: Suggested ``depth`` for :func:`bricks`: the world height of ``H = 1`` in
#: units of the image width (docs/ARCHITECTURE.md), i.e. 25.6 texels at 512 texels.
DEFAULT_DEPTH = 0.05

# Height levels of the profile (fractions of the [0, 1] range).
_MORTAR_LEVEL = 0.14  # mean height of the mortar bed
_TOP_LEVEL = 0.82  # mean height of a brick face
_TOP_SPREAD = 0.05  # per-brick height offset, +- (uniform)
_TILT = 0.05  # per-brick tilt: height change across a brick, +-
# Geometry, as fractions of the brick height (in texels).
_MORTAR_FRACTION = 0.03  # width of the mortar joint
_MORTAR_MIN_PX = 1.5  # ... but at least this many texels
_BEVEL_FRACTION = 0.13  # width of the rounded brick edge
# Chips: fracture surface slope (height per brick height of inset), its
# drop per unit of chip noise, and the noise level where chips begin.
_CHIP_SLOPE = 6.0
_CHIP_DEPTH = 0.25
_CHIP_THRESHOLD = 1.0
_MIN_BRICK_PX = 48  # narrowest brick, in texels (fewer bricks on small maps)


def bricks(
    size: int | tuple[int, int] = DEFAULT_SIZE, *, seed: int = 1, bricks_across: int = 4
) -> np.ndarray:
    """Return a seamlessly tiling height map of a brick wall in running bond.

    Parameters
    ----------
    size
        ``n`` for an ``n x n`` map or ``(rows, cols)``; each at least 8.
    seed
        Seed of :func:`numpy.random.default_rng`, the only source of
        randomness: equal ``(size, seed, bricks_across)`` give equal maps.
    bricks_across
        Bricks per course across the width, at least 1. It is lowered where
        bricks would be narrower than 48 texels and raised where a brick
        would be wider than the map is tall. The number of courses follows:
        the even number that keeps bricks closest to 2:1 (width:height).

    Returns
    -------
    numpy.ndarray
        float32, shape ``(rows, cols)``, values in [0, 1], row 0 at the top.
        Mortar lies near 0.1-0.2 and brick faces near 0.7-1.0; use it with
        :data:`DEFAULT_DEPTH`. The map is exactly periodic with period
        ``(rows, cols)``: whole bricks per course, an even number of courses
        (the half-brick offset repeats every two) and Fourier-filtered noise.

    Notes
    -----
    A brick's height is a rounded (quarter-sine) profile of its inset
    distance to the brick boundary, so its edges are bevelled and meet the
    mortar in a joint ``max(1.5 texels, 3%)`` of the brick height wide.
    Chips cut the brick down to a gently sloping fracture surface near its
    edges. Every term is continuous, so the relief has steep bevels but no
    steps or spikes. Units: ``H`` is dimensionless; texel-space lengths scale
    with the brick height, so the look does not depend on the resolution.
    """
    rows, cols = shape_of(size, "bricks", MIN_SIZE)
    if int(bricks_across) < 1:
        raise ValueError(f"bricks: bricks_across must be at least 1, got {bricks_across}")
    rng = np.random.default_rng(seed)
    bond = _bond(rows, cols, int(bricks_across))
    per_brick = _brick_properties(rng, bond.courses * bond.n)  # drawn first, then the noise
    fields = _noise_fields(rng, (rows, cols), bond.brick_h)
    return _relief(bond, per_brick, fields)


@dataclass(frozen=True)
class _Bond:
    """The running bond: bricks per course, courses, brick size, and each texel's place in its brick.

    There are ``n`` bricks per course and ``courses`` courses, the brick size is in texels, and per texel it
    holds its position in its brick (``fu``, ``fv`` in [0, 1)) and the brick's index.
    """

    n: int
    courses: int
    brick_w: float
    brick_h: float
    fu: np.ndarray
    fv: np.ndarray
    brick_id: np.ndarray


def _bond(rows: int, cols: int, bricks_across: int) -> _Bond:
    """Return the running bond: N bricks per course, an even number of courses, bricks ~2:1.

    It gives the brick-space coordinates of texel centres, shifted by a quarter brick and half a course so the
    image edges cut through bricks (the seam is then a real test of tiling, not hidden in a joint).
    """
    f32 = np.float32
    n = max(1, min(bricks_across, cols // _MIN_BRICK_PX))
    n = max(n, -(-cols // rows))  # two courses of half-width bricks fit
    brick_w = cols / n
    courses = max(2, 2 * int(round(rows / (brick_w / 2.0) / 2.0)))
    brick_h = rows / courses
    v = (np.arange(rows) + 0.5) / rows * courses + 0.5  # courses, downwards
    u = (np.arange(cols) + 0.5) / cols * n + 0.25  # bricks, rightwards
    course = np.floor(v).astype(np.int64)
    fv = (v - course).astype(f32)[:, None]  # [0, 1) in the course
    shifted = u[None, :] + 0.5 * (course % 2)[:, None]  # running bond
    column = np.floor(shifted)
    fu = (shifted - column).astype(f32)  # [0, 1) in the brick
    brick_id = ((course % courses)[:, None] * n + column.astype(np.int64) % n).astype(np.intp)  # (rows, cols)
    return _Bond(n, courses, brick_w, brick_h, fu, fv, brick_id)


def _brick_properties(rng, count: int) -> dict[str, np.ndarray]:
    """Per-brick random properties, drawn in a fixed order."""
    f32 = np.float32
    return {
        "top": (_TOP_LEVEL + _TOP_SPREAD * rng.uniform(-1.0, 1.0, count)).astype(f32),
        "tilt_u": (_TILT * rng.uniform(-1.0, 1.0, count)).astype(f32),
        "tilt_v": (0.5 * _TILT * rng.uniform(-1.0, 1.0, count)).astype(f32),
        "bevel_scale": rng.uniform(0.8, 1.25, count).astype(f32),
        "rough_scale": rng.uniform(0.6, 1.4, count).astype(f32),
    }


def _noise_fields(rng, shape: tuple[int, int], brick_h: float) -> dict[str, np.ndarray]:
    """Noise fields, all exactly periodic, drawn in a fixed order.

    Scales are in texels, tied to the brick height so the look does not depend on the resolution.
    """
    s = brick_h / 64.0
    return {
        "chip": periodic_noise(rng, shape, (5.0 * s,), (1.0,)),
        "face": periodic_noise(rng, shape, (12.0 * s, 3.0 * s, 1.0 * s), (1.0, 0.45, 0.2)),
        "pit": periodic_noise(rng, shape, (2.5 * s,), (1.0,)),
        "grain": periodic_noise(rng, shape, (0.6,), (1.0,)),
        "edge": periodic_noise(rng, shape, (10.0 * s,), (1.0,)),
    }


def _inset(bond: _Bond, edge_field: np.ndarray) -> np.ndarray:
    """Return the inset distance (texels) to the brick boundary, less half the mortar joint.

    The boundary has slightly rounded corners; the edge wanders a little along its length.
    """
    f32 = np.float32
    mortar = max(_MORTAR_MIN_PX, _MORTAR_FRACTION * bond.brick_h)
    qx = (f32(0.5) - np.abs(bond.fu - f32(0.5))) * f32(bond.brick_w)
    qy = (f32(0.5) - np.abs(bond.fv - f32(0.5))) * f32(bond.brick_h)
    corner = f32(0.35 * _BEVEL_FRACTION * bond.brick_h)
    inset = np.minimum(qx, qy)
    rounded = corner - np.hypot(np.maximum(corner - qx, 0), np.maximum(corner - qy, 0))
    inset = np.where((qx < corner) & (qy < corner), rounded, inset)
    inset -= f32(0.5 * mortar)
    inset -= f32(0.015 * bond.brick_h) * (f32(0.5) + f32(0.5) * np.tanh(edge_field))
    return inset


def _relief(bond: _Bond, b: dict[str, np.ndarray], fields: dict[str, np.ndarray]) -> np.ndarray:
    """Return the height: mortar, the bevelled brick face, chips, grain (:func:`bricks`, Notes)."""
    f32 = np.float32
    ids, brick_h = bond.brick_id, bond.brick_h
    inset = _inset(bond, fields["edge"])
    # Rounded profile: 0 in the joint, rising as a quarter sine over the bevel.
    bevel = f32(_BEVEL_FRACTION * brick_h) * b["bevel_scale"][ids]
    profile = np.sin(f32(0.5 * np.pi) * np.clip(inset / bevel, 0, 1))
    # Brick face: per-brick height and tilt, rough face, small pits.
    face = b["top"][ids]
    face += b["tilt_u"][ids] * (bond.fu - f32(0.5)) * f32(2.0)
    face += b["tilt_v"][ids] * (bond.fv - f32(0.5)) * f32(2.0)
    face += f32(0.022) * b["rough_scale"][ids] * fields["face"]
    face -= f32(0.04) * smoothstep(1.5, 3.2, fields["pit"])
    mortar_height = f32(_MORTAR_LEVEL) + f32(0.02) * fields["pit"]
    height = mortar_height + profile * (face - mortar_height)
    # Chips: a fracture surface that rises gently from the joint and sinks
    # where the chip field is high; the brick is cut down to it (min), never
    # below the mortar (max). Both are continuous, so chips add no steps.
    fracture = (
        mortar_height
        + f32(_CHIP_SLOPE / brick_h) * inset
        + f32(_CHIP_DEPTH) * (f32(_CHIP_THRESHOLD) - fields["chip"])
        + f32(0.03) * fields["face"]
    )
    height = np.minimum(height, np.maximum(fracture, mortar_height))
    height += f32(0.005) * fields["grain"]
    return np.clip(height, 0.0, 1.0).astype(np.float32)


def _make(shape: tuple[int, int], seed: int):
    return bricks(shape, seed=seed), None


MATERIAL = Material(
    name="bricks",
    label="brick wall",
    summary="bevelled bricks in running bond, proud of recessed mortar: steep walls, long straight joints",
    depth=DEFAULT_DEPTH,
    make=_make,
    min_size=MIN_SIZE,
)
