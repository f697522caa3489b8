"""The truth's mesh in bands of rows: a mesh too large to hold at once, built a band at a time.

At 4096 x 4096 the bricks' bilinear surface is 187M triangles (10.8 a cell at the default
tolerance), about 21 GiB with Embree's BVH: more than a 16 GiB sweep can hold beside its images.
But in the default top-down orthographic view a sample's rays reach only part of the map:

* its camera ray runs straight down, in its own column;
* a shadow ray toward a light of elevation ``e`` is traced only until it rises above the map's highest
  point (:meth:`hzval.truth.plane.Truth._occluded`: ``t = (top - o.z) / d.z``), so it runs at most
  ``(relief + 4 lift) / tan(e)`` texels horizontally (soft lights: their lowest direction), of which
  ``|sin(azimuth)|`` along y for a hard light (1 for a soft one); ``wrap``'s hops only cut that run
  into pieces, each wrapped back into the tile.

So the samples of a band of pixel rows ``[p0, p1)`` need only the cells whose ``y`` lies within
:func:`reach` of the band: ``up`` texels above it if a light lies toward +y, ``down`` below it if one
lies toward -y (``wrap``: the cells of the tile and its margin whose ``y`` is there modulo the tile,
:func:`cover_runs`). The truth then builds one such band's mesh at a time (:func:`band_pass`: the
whole grid's own cells and levels, so its triangles are the single mesh's, bit for bit), traces the
band's camera rays and every light's shadow rays in it, keeps one bit a sample a light (the
visibility, 34 MB a light at 4096 x 4096 x 16), and frees the mesh before the next band. The frames
then shade from those bits and the shading normals, which need no mesh. Since a shadow ray's answer is
whether it meets *any* triangle within ``[0, maxt]``, and every triangle it could meet is in its band's
mesh, the answers are the single mesh's (``tests/truth/test_bands.py``).

Where a ray could leave every band's cover, the single mesh is used (:func:`why_not`): views other
than ``top`` (camera rays that cross rows), ``ambient``, ``reflection_occlusion`` and
``interreflection`` (rays in every direction, paths that bounce), ``faceted`` shading (which reads the
triangles' normals in every frame) and lights that reach the horizon (shadows without end).
"""

from __future__ import annotations

import math

import numpy as np

from hzval.core import backend
from hzval.core.backend import mi  # Dr.Jit loads at first use, once the LLVM is chosen
from hzval.geometry import tile as mesh

__all__ = [
    "PAD_TEXELS",
    "why_not",
    "reach",
    "cover_runs",
    "group_bands",
    "band_y",
    "band_triangles",
    "band_scene",
    "band_pass",
]

#: Texels added to each side of a band's cover: the cell that holds a sample on the band's edge, the
#: samples moved off edge lines (:func:`hzval.truth.samples.off_edge_lines`, ulps) and float32's rounding.
PAD_TEXELS = 2.0


def why_not(scene) -> str | None:
    """Return why a truth of ``scene`` cannot build its mesh in bands, or ``None`` where it can.

    It cannot where a ray could leave a band's cover (module docstring).
    """
    if scene.camera.kind != "top":
        return f"the {scene.camera.kind} view's camera rays cross rows"
    for effect in ("ambient", "reflection_occlusion", "interreflection"):
        if scene.declares(effect):
            return f"{effect}'s rays leave in every direction"
    if scene.material.shading != "smooth":
        return f"{scene.material.shading} shading reads the triangles' own normals in every frame"
    light = scene.light
    rho = light.radius_deg if light.kind == "soft" else 0.0
    if scene.declares("shadow") and light.elevation_deg - rho <= 0.0 < light.elevation_deg + rho:
        return "a light that reaches the horizon casts shadows of any length"
    return None


def reach(scene, relief: float, lift: float, azimuths) -> tuple[float, float]:
    """Return ``(up, down)``: texels along +y and -y that the rays of a sample may run.

    They are for the lights at ``azimuths`` (degrees), :data:`PAD_TEXELS` included (module docstring).
    ``relief``: the map's highest less its lowest point, texels; ``lift``: the truth's ray lift
    (:attr:`hzval.truth.plane.Truth.lift`).
    """
    pad = PAD_TEXELS
    light = scene.light
    rho = math.radians(light.radius_deg) if light.kind == "soft" else 0.0
    e = math.radians(light.elevation_deg)
    if not scene.declares("shadow") or e + rho <= 0.0:
        return pad, pad  # no shadow rays: the camera's only
    # the traced run: from the lowest origin (z_min + lift) to the top (z_max + 2 lift), widened by a
    # thousandth for float32's rounding of the ray's steps
    run = (relief + 4.0 * lift) / math.tan(e - rho) * 1.001
    up = down = 0.0
    for az in azimuths:
        s = math.sin(math.radians(float(az)))
        if rho == 0.0:
            # a hard light's y share of its horizontal run: sin(azimuth), exactly
            up, down = max(up, run * s), max(down, -run * s)
            continue
        # a soft light's directions: any horizontal heading within rho of the centre's y component
        sy = math.cos(e) * s
        if sy + math.sin(rho) > -1e-9:
            up = run
        if sy - math.sin(rho) < 1e-9:
            down = run
    return up + pad, down + pad


def cover_runs(g: mesh.Grid, rows: int, y_lo: float, y_hi: float, wrap: bool) -> list[tuple[int, int]]:
    """Return the runs ``(first, stop)`` of the cell rows of ``g`` that meet ``y_lo <= y <= y_hi``.

    ``g`` is the vertex grid (its rows run toward -y); ``y`` is in texels, beyond the tile for a band near its
    edge. With ``wrap`` they are the cells of the tile and its margin whose ``y`` is in it modulo the tile's
    ``rows``, since hops wrap a ray back into the tile.
    """
    top, bottom = g.y[:-1], g.y[1:]  # cell i spans bottom[i] <= y <= top[i]
    need = np.zeros(top.shape, bool)
    k_max = int(math.ceil((max(abs(y_lo), abs(y_hi)) + g.margin + 1.0) / rows)) + 1 if wrap else 0
    for k in range(-k_max, k_max + 1):
        need |= (bottom + k * rows <= y_hi) & (top + k * rows >= y_lo)
    edges = np.flatnonzero(np.diff(np.concatenate([[0], need.astype(np.int8), [0]])))
    return [(int(a), int(b)) for a, b in zip(edges[0::2], edges[1::2])]


def group_bands(bands: list[tuple[int, int]], cols: int, band_rows: int) -> list[list[int]]:
    """Return the truth's sample bands in consecutive groups of at most ``band_rows`` pixel rows.

    The sample bands are :func:`hzval.truth.samples.bands`: pixel index ranges of whole rows, ``cols`` pixels
    a row. Each group holds at least one band; a group's bands are the bands that share a mesh.
    """
    groups: list[list[int]] = []
    first_row = None
    for i, (first, stop) in enumerate(bands):
        if groups and stop // cols - first_row <= band_rows:
            groups[-1].append(i)
            continue
        groups.append([i])
        first_row = first // cols
    return groups


def band_y(rows: int, H: int, p0: int, p1: int, up: float, down: float) -> tuple[float, float]:
    """Return ``(y_lo, y_hi)``: the texels ``y`` that the samples of pixel rows ``[p0, p1)`` reach.

    The image has ``H`` rows and the map ``rows`` rows; ``up`` and ``down`` are :func:`reach`'s.
    """
    return rows - p1 * rows / H - down, rows - p0 * rows / H + up


def band_triangles(
    g: mesh.Grid,
    levels: np.ndarray,
    rows: int,
    H: int,
    W: int,
    bands,
    band_rows: int,
    up: float,
    down: float,
    wrap: bool,
) -> list[int]:
    """Return the triangles of each band's mesh, counted without building them.

    The bands are :func:`group_bands`'s, their meshes :func:`cover_runs`'s; the counts are what
    :func:`hzval.truth.memory.truth_plan` weighs.
    """
    per_row = np.concatenate([[0], np.cumsum(mesh.row_triangles(levels))])
    counts = []
    for group in group_bands(bands, W, band_rows):
        y_lo, y_hi = band_y(rows, H, bands[group[0]][0] // W, bands[group[-1]][1] // W, up, down)
        counts.append(int(sum(per_row[b] - per_row[a] for a, b in cover_runs(g, rows, y_lo, y_hi, wrap))))
    return counts


def band_scene(g: mesh.Grid, levels: np.ndarray, runs: list[tuple[int, int]]):
    """Return a Mitsuba scene of the cell rows ``runs`` of ``g``.

    It has one mesh a run (:func:`hzval.geometry.tile.piece_mesh`).
    """
    return mi.load_dict(
        {
            "type": "scene",
            **{f"band{k}": mesh.piece_mesh(g, levels, a, b, f"band{k}") for k, (a, b) in enumerate(runs)},
        }
    )


def band_pass(t, azimuths) -> dict[float, list[np.ndarray]]:
    """Return every light's visibility at every sample of the truth ``t``, one mesh band at a time.

    ``t`` is a :class:`hzval.truth.plane.Truth` whose mesh is in bands. The result is ``{azimuth: [bits of
    each sample band]}``, the 0/1 visibility of :meth:`hzval.truth.plane.Truth._visible` packed eight samples
    a byte (``np.packbits``). Each band's mesh is built, its camera rays and the lights' shadow rays traced in
    it, and freed.
    """
    H, W = t.shape
    wrap = t.scene.material.boundary == "wrap"
    up, down = reach(t.scene, t.relief, t.lift, azimuths)
    out: dict[float, list] = {float(az): [None] * len(t.bands) for az in azimuths}
    triangles = largest = 0
    for group in t.mesh_bands:
        y_lo, y_hi = band_y(t.rows, H, t.bands[group[0]][0] // W, t.bands[group[-1]][1] // W, up, down)
        runs = cover_runs(t._grid, t.rows, y_lo, y_hi, wrap)
        t.mi_scene = band_scene(t._grid, t._levels, runs)
        n = sum(int(mesh.row_triangles(t._levels[a:b]).sum()) for a, b in runs)
        triangles, largest = triangles + n, max(largest, n)
        for i in group:
            st = t._camera_samples(*t.bands[i])
            for az in out:
                L, lowest, highest = t.light_directions(az, st)
                vis = np.asarray(t._visible(st.o, st.n, L, lowest, highest), np.float32)
                out[az][i] = np.packbits(vis > 0.5)
            del st
        t.mi_scene = None
        backend.release_memory()
    t.band_triangles_built, t.band_triangles_largest = triangles, largest
    return out
