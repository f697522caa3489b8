"""A NumPy reference of OpenGL's seamless cube-map filtering, built differently from hzval.techniques.cubemap.

Each face is padded by one texel all round; a border texel is the texel of
another face whose centre direction is nearest in angle to the border
texel's own (extended) centre direction, found by brute force over every
texel of the cube; a corner of the padding is the mean of its three
neighbours there (the spec's recommendation). A lookup is then plain
bilinear filtering of the padded face (OpenGL 4.6, 8.13.1 and 8.14.2).
"""

import functools

import numpy as np

from hzval.core import cube as cube_layout


@functools.lru_cache(maxsize=4)
def padded_faces(cube_bytes: bytes, n: int) -> np.ndarray:
    """``(6, n + 2, n + 2, 4)`` float64: every face with its one-texel border from its neighbours."""
    cube = np.frombuffer(cube_bytes, np.float64).reshape(6, n, n, 4)
    centres = cube_layout.cube_texel_directions(n).reshape(-1, 3)
    centres = centres / np.linalg.norm(centres, axis=-1, keepdims=True)
    flat = cube.reshape(-1, 4)
    c = (np.arange(-1, n + 1) + 0.5) / n * 2.0 - 1.0
    tc, sc = np.meshgrid(c, c, indexing="ij")
    one = np.ones_like(sc)
    axes = [
        (one, -tc, -sc),
        (-one, -tc, sc),
        (sc, one, tc),
        (sc, -one, -tc),
        (sc, -tc, one),
        (-sc, -tc, -one),
    ]
    out = np.zeros((6, n + 2, n + 2, 4))
    for f, (x, y, z) in enumerate(axes):
        d = np.stack([x, y, z], axis=-1).reshape(-1, 3)
        d /= np.linalg.norm(d, axis=-1, keepdims=True)
        nearest = np.argmax(d @ centres.T, axis=1)
        out[f] = flat[nearest].reshape(n + 2, n + 2, 4)
        out[f, 1:-1, 1:-1] = cube[f]
        for r, cc, dr, dc in ((0, 0, 1, 1), (0, -1, 1, -1), (-1, 0, -1, 1), (-1, -1, -1, -1)):
            out[f, r, cc] = (out[f, r + dr, cc] + out[f, r, cc + dc] + out[f, r + dr, cc + dc]) / 3.0
    return out


def seamless_bilinear(cube: np.ndarray, d) -> np.ndarray:
    """The seamlessly filtered texel ``(4,)`` of ``cube`` ``(6, n, n, 4)`` toward the direction ``d``."""
    n = cube.shape[1]
    pad = padded_faces(np.ascontiguousarray(cube, np.float64).tobytes(), n)
    face, s, t = cube_layout.cube_lookup(np.asarray(d, np.float64))
    u, v = float(s) * n - 0.5 + 1.0, float(t) * n - 0.5 + 1.0  # in the padded face
    i, j = min(int(np.floor(u)), n), min(int(np.floor(v)), n)
    a, b = u - i, v - j
    p = pad[int(face)]
    return (1 - b) * ((1 - a) * p[j, i] + a * p[j, i + 1]) + b * ((1 - a) * p[j + 1, i] + a * p[j + 1, i + 1])
