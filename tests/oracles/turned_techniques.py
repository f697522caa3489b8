"""A map turned (mirrored, rotated by 90 or 180 degrees, transposed) and each sample at its turned
position: the truth's V and every default technique's factor, in the as-is map's pixel order.

A turned map lit from the turned light is the same surface turned, so every image must equal the as-is
map's to rounding (tests/truth/test_plane_surface.py). studies/turned_techniques.py prints the
comparison and the noise of whole sweeps beside it.
"""

from __future__ import annotations

import numpy as np

#: (name, the map turned, the light's azimuth turned, where a tangent-space point (x, y) of a rows x
#: cols tile goes): x runs along the columns and y up the rows, so np.rot90 turns counterclockwise.
TURNS = (
    ("mirror", lambda h: h[:, ::-1], lambda a: 180.0 - a, lambda x, y, r, c: (c - x, y)),
    ("rot90", lambda h: np.rot90(h), lambda a: a + 90.0, lambda x, y, r, c: (r - y, x)),
    ("rot180", lambda h: np.rot90(h, 2), lambda a: a + 180.0, lambda x, y, r, c: (c - x, r - y)),
    ("transpose", lambda h: h.T, lambda a: -90.0 - a, lambda x, y, r, c: (r - y, c - x)),
)
AS_IS = ("as-is", lambda h: h, lambda a: a, lambda x, y, r, c: (x, y))


def crop():
    from hzval import materials

    return np.ascontiguousarray(materials.generate("bricks", 192, seed=6).height[10:138, 20:148])


def turned_frames(h, boundary: str, azimuth: float, spp: int, turn=AS_IS, depth: float = 0.05) -> dict:
    """``{"V": truth's visibility, technique: factor}`` of ``h`` turned by ``turn`` (a :data:`TURNS`
    entry), lit from the turned light, each sample at the turned position of the as-is map's sample
    (:func:`hzval.scene.camera.sample_positions`, seed 1); each image in the as-is map's pixel order."""
    from hzval.bake import maps as bake
    from hzval.scene import lookup
    from hzval.scene import spec as sc
    from hzval.scene.camera import sample_positions
    from hzval.techniques import registry as technique
    from hzval.truth.plane import Truth

    _, f, az, point = turn
    rows, cols = h.shape
    ht = np.ascontiguousarray(f(h))
    perm = f(np.arange(rows * cols).reshape(rows, cols)).ravel()  # turned pixel -> as-is pixel
    light = az(azimuth) % 360.0
    scene = sc.override(
        sc.Scene(),
        depth=depth,
        boundary=boundary,
        elevation=30.0,
        spp=spp,
        effects="shadow",
        azimuths=str(light),
    ).validate()
    x, y = (
        np.asarray(a, np.float64).reshape(rows * cols, spp)[perm]
        for a in sample_positions(rows, cols, scene.camera, spp, 1)
    )
    x, y = point(x, y, rows, cols)
    x, y = x.astype(np.float32).ravel(), y.astype(np.float32).ravel()
    out = {"V": Truth(scene, ht, positions=(x, y)).render(light).layers["visibility"]}
    baked = bake.bake(ht, bake.BakeParams(depth=depth, boundary=boundary).validate())
    like = lookup.Samples(np.zeros(1, np.float32), np.zeros(1, np.float32), *ht.shape, spp)
    ctx = technique.Context(scene, ht, baked, None, points=lookup.from_points(x, y, like))
    for t in technique.select(None, scene):
        if t.square_symmetric:  # ssbump's basis turns with nothing but a mirror in y (its own test)
            out[t.name] = t.build(ctx).render(light).layers["factor"]
    inverse = np.empty_like(perm)
    inverse[perm] = np.arange(perm.size)
    return {k: v.ravel()[inverse] for k, v in out.items()}
