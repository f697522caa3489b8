"""Helpers that several test modules share (tests import nothing from one another's modules)."""

from __future__ import annotations

import contextlib
import math
import os
import re
import resource
import shutil
import subprocess
import sys
import time
import warnings
from pathlib import Path

import numpy as np
import OpenEXR
import pytest
import yaml
from PIL import Image

from hzval.core import conventions as cv
from hzval.io import codecs
from hzval.metrics import compare
from hzval.report import images
from hzval.scene import spec as sc


def interrupt_material(monkeypatch, name: str) -> None:
    """Make a suite stop with Ctrl-C when it reaches material ``name`` (every other one sweeps)."""
    from hzval.commands import suite

    real = suite.sweep_material

    def interrupt(task):
        if task.entry.name == name:
            raise KeyboardInterrupt
        return real(task)

    monkeypatch.setattr(suite, "sweep_material", interrupt)


def exr_layout(path) -> dict[str, str]:
    """``{channel: "HALF" | "FLOAT"}`` of an EXR as stored, and its compression under ``"compression"``."""
    with OpenEXR.File(str(path), separate_channels=True) as f:
        out = {name: ch.type().name for name, ch in f.channels().items()}
        out["compression"] = f.header()["compression"].name
    return out


def png_mode_and_rgb(path) -> tuple[str, np.ndarray]:
    with Image.open(path) as im:
        return im.mode, np.asarray(im.convert("RGB"))


def magma_as_before(values):
    """The FLIP map as the sweep painted it before palettes: matplotlib's magma, 8-bit RGB."""
    from matplotlib import colormaps

    return (colormaps["magma"](np.clip(values, 0, 1))[..., :3] * 255 + 0.5).astype(np.uint8)


def visdiff_as_before(V, F):
    """The visibility-difference map as the sweep painted it before palettes."""
    grey = codecs.unit_to_u8(0.25 + 0.5 * np.clip(V, 0, 1))
    img = np.repeat(grey[..., None], 3, axis=-1)
    lit_v, lit_f = V >= compare.LIT_THRESHOLD, F >= compare.LIT_THRESHOLD
    img[lit_f & ~lit_v] = images.LEAK_RGB
    img[~lit_f & lit_v] = images.FALSE_SHADOW_RGB
    return img


QUAD_P = np.array([[0.0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])


QUAD_UV = np.array([[0.0, 0], [1, 0], [1, 1], [0, 1]])


QUAD_F = np.array([[0, 1, 2], [0, 2, 3]])


def write_obj(path, p, uv, f, normals=True):
    lines = [f"v {x} {y} {z}" for x, y, z in p] + [f"vt {u} {v}" for u, v in uv]
    lines += ["vn 0 0 1"] if normals else []
    fmt = "{0}/{0}/1" if normals else "{0}/{0}"
    lines += ["f " + " ".join(fmt.format(i + 1) for i in tri) for tri in f]
    path.write_text("\n".join(lines) + "\n")
    return str(path)


def write_gltf(path, p, uv, f, normals=None, tangents=None):
    """A glTF 2.0 file written by pygltflib, UVs given in hzval's convention (written as 1 - v)."""
    import pygltflib

    arrays = [
        np.asarray(f, np.uint32).ravel(),
        np.asarray(p, np.float32),
        (np.asarray(uv, np.float64) * [1, -1] + [0, 1]).astype(np.float32),
    ]
    kinds = [("SCALAR", pygltflib.UNSIGNED_INT), ("VEC3", pygltflib.FLOAT), ("VEC2", pygltflib.FLOAT)]
    names = ["POSITION", "TEXCOORD_0"]
    for name, a, kind in (("NORMAL", normals, "VEC3"), ("TANGENT", tangents, "VEC4")):
        if a is not None:
            arrays.append(np.asarray(a, np.float32))
            kinds.append((kind, pygltflib.FLOAT))
            names.append(name)
    blob, views, accessors = b"", [], []
    for i, (a, (kind, ct)) in enumerate(zip(arrays, kinds)):
        views.append(pygltflib.BufferView(buffer=0, byteOffset=len(blob), byteLength=a.nbytes))
        extra = dict(max=a.max(0).tolist(), min=a.min(0).tolist()) if i == 1 else {}
        accessors.append(
            pygltflib.Accessor(
                bufferView=i, componentType=ct, type=kind, count=len(a) if a.ndim > 1 else a.size, **extra
            )
        )
        blob += a.tobytes()
    attrs = pygltflib.Attributes(**{n: i + 1 for i, n in enumerate(names)})
    g = pygltflib.GLTF2(
        scenes=[pygltflib.Scene(nodes=[0])],
        nodes=[pygltflib.Node(mesh=0)],
        meshes=[pygltflib.Mesh(primitives=[pygltflib.Primitive(attributes=attrs, indices=0)])],
        accessors=accessors,
        bufferViews=views,
        buffers=[pygltflib.Buffer(byteLength=len(blob))],
    )
    g.set_binary_blob(blob)
    with warnings.catch_warnings():  # a .gltf gets its blob as a .bin beside it, which pygltflib says
        warnings.simplefilter("ignore")
        g.save(str(path))
    return str(path)


CHROMIUM = "/usr/bin/chromium"


CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


@contextlib.contextmanager
def chromium_page(problems: list[str]):
    """A 1440 x 900 page of headless chromium that records page errors and failed requests in
    ``problems``; the test is skipped where chromium or Playwright is missing."""
    if not os.path.exists(CHROMIUM):
        pytest.skip(f"{CHROMIUM} is missing (apt-get install chromium)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        pytest.skip("the playwright Python package is not importable (pip install playwright)")
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1440, "height": 900})
            page.on("pageerror", lambda e: problems.append(f"page error: {e}"))
            page.on("requestfailed", lambda r: problems.append(f"request failed: {r.url}"))
            yield page
        finally:
            browser.close()


def model_case_scene(n=48, **kw):
    """A small model case: an orthographic view at 60 degrees of an ``n``-texel open tile, 4 spp."""
    base = dict(
        size=n,
        depth=0.08,
        spp=4,
        azimuths="-45,30",
        boundary="open",
        camera="orthographic",
        view_elevation=60,
        view_azimuth=-90,
        resolution=(n, n),
    )
    base.update(kw)
    return sc.override(sc.Scene(), **base)


def material_height(scene):
    """The height map of ``scene``'s material."""
    return sc.load_material_height(scene.material).height


def make_scene(
    shape,
    depth,
    boundary="open",
    *,
    effects=("shadow",),
    elevation=30.0,
    kind="hard",
    radius=0.0,
    spp=16,
    seed=0,
    irradiance=1.0,
    albedo=0.5,
    supersampling=1,
    depth_ir=2,
    shading="smooth",
):
    return sc.Scene(
        name="test",
        material=sc.MaterialSpec(
            height="test", size=shape[1], depth=depth, boundary=boundary, albedo=albedo, shading=shading
        ),
        camera=sc.Camera(supersampling=supersampling),
        light=sc.Light(kind=kind, radius_deg=radius, elevation_deg=elevation, irradiance=irradiance),
        effects=tuple(effects),
        interreflection_depth=depth_ir,
        spp=spp,
        seed=seed,
    ).validate()


def column_wall(rows, cols, col):
    h = np.zeros((rows, cols), np.float32)
    h[:, col] = 1.0
    return h


def row_wall(rows, cols, row):
    h = np.zeros((rows, cols), np.float32)
    h[row, :] = 1.0
    return h


WALL_H = 4.0  # texels: H = 1 at depth 4 / 40 on a 40-wide map


WALL_AT = 20


def wall_shadow_extents(column, row, azimuth):
    """Shadow extents across a column wall and a row wall at ``WALL_AT`` (40x40), lit from ``azimuth``.

    ``column()`` and ``row()`` give the lit fraction (``V`` or ``F``, 1 = lit)
    of the two walls. Checks the side each shadow falls on (light from +x:
    toward -x; from +y, up the image: toward larger rows) and that the other
    side is fully lit; returns ``[(texels across the wall, |cos| or |sin| of
    the azimuth)]`` for each wall the light is not parallel to.
    """
    phi = math.radians(azimuth)
    top = WALL_AT + 0.5
    cx, cy = math.cos(phi), math.sin(phi)
    out = []
    if abs(cx) > 0.1:
        lit = column()
        middle = lit[8:-2] if cy > 0 else lit[2:-8]  # rows whose casters are inside the map
        x = np.arange(40) + 0.5
        centroid = ((1.0 - middle).sum(axis=0) * x).sum() / (1.0 - middle).sum()
        assert (centroid < top) if cx > 0 else (centroid > top)
        assert np.all((lit[:, WALL_AT + 1 :] if cx > 0 else lit[:, :WALL_AT]) == 1.0)
        out.append(((1.0 - middle).sum(axis=1).mean(), abs(cx)))
    if abs(cy) > 0.1:
        lit = row()
        middle = lit[:, 2:-8] if cx > 0 else lit[:, 8:-2]
        r = np.arange(40) + 0.5
        centroid = ((1.0 - middle).sum(axis=1) * r).sum() / (1.0 - middle).sum()
        assert (centroid > top) if cy > 0 else (centroid < top)
        assert np.all((lit[:WALL_AT] if cy > 0 else lit[WALL_AT + 1 :]) == 1.0)
        out.append(((1.0 - middle).sum(axis=0).mean(), abs(cy)))
    assert out
    return out


#: The repository's root.
ROOT = Path(__file__).resolve().parents[1]


def hzval(*argv, limit_gib: float | None = 4.0, timeout: float = 60, cwd=None):
    """``python -m hzval ARGV`` in a process of its own, its address space limited to ``limit_gib``
    (LLVM reserves a few GiB of address space of its own); ``(rc, stderr, seconds)``."""

    def limit():
        if limit_gib:
            size = int(limit_gib * 2**30)
            resource.setrlimit(resource.RLIMIT_AS, (size, size))

    env = {**os.environ, "PYTHONPATH": str(ROOT), "HZVAL_VARIANT": "llvm_ad_rgb"}
    t0 = time.perf_counter()
    p = subprocess.run(
        [sys.executable, "-m", "hzval", *map(str, argv)],
        capture_output=True,
        text=True,
        timeout=timeout,
        preexec_fn=limit,
        env=env,
        cwd=cwd,
    )
    return p.returncode, p.stderr.strip(), time.perf_counter() - t0


def one_line(err: str, *needles: str) -> None:
    """An error of the command line: one line, ``hzval: error:``, no traceback, naming each needle."""
    err = err.strip()
    assert err.startswith("hzval: error:") and "\n" not in err and "Traceback" not in err, err
    for n in needles:
        assert n in err, (n, err)


def hemisphere_directions(D: int, elevations: int = 4000):
    """Unit directions of a dense midpoint rule over the upper hemisphere, per horizon azimuth:
    ``(phi_k, t_j)`` and their weights ``cos t dt dphi``."""
    t = (np.arange(elevations) + 0.5) * (math.pi / 2) / elevations
    out = []
    for k in range(D):
        phi = math.radians(cv.channel_azimuth_deg(k, D))
        w = np.stack([np.cos(t) * math.cos(phi), np.cos(t) * math.sin(phi), np.sin(t)], axis=-1)
        out.append((w, np.cos(t) * (math.pi / 2) / elevations * (2 * math.pi / D)))
    return t, out


def dense_bent_normal(s: np.ndarray) -> np.ndarray:
    """The cosine-weighted bent normal of horizon sines ``s``, by a dense quadrature (the reference)."""
    t, dirs = hemisphere_directions(len(s))
    acc = np.zeros(3)
    for (w, dw), sk in zip(dirs, s):
        open_ = t > math.asin(min(max(sk, 0.0), 1.0))
        acc += ((w[:, 2] * dw)[:, None] * w)[open_].sum(axis=0)  # cosine-weighted, about +z
    return acc / np.linalg.norm(acc)


#: The CI recipe docs/ci.md gives.
RECIPE = ROOT / "docs" / "ci.md"


def recipe_steps() -> list[dict]:
    """The steps of the recipe's one job (the first ```yaml block of docs/ci.md)."""
    block = re.search(r"```yaml\n(.*?)```", RECIPE.read_text(encoding="utf-8"), re.S).group(1)
    jobs = yaml.safe_load(block)["jobs"]
    (job,) = jobs.values()
    return job["steps"]


GCC = shutil.which("gcc")


SOURCE = ROOT / "tests" / "oracles" / "seed_bake.c"


def run_peer(
    exe: Path, height: np.ndarray, depth: float, radius: int, angles: int, boundary: str, workdir: Path
) -> np.ndarray:
    """The peer's ``(rows, cols, 10)`` output: 8 channel sines, mean_cos, mean_cos2."""
    rows, cols = height.shape
    src, dst = workdir / "height.f32", workdir / "peer.f32"
    np.ascontiguousarray(height, dtype="<f4").tofile(src)
    cmd = [
        str(exe),
        str(src),
        str(rows),
        str(cols),
        repr(float(depth)),
        str(radius),
        str(angles),
        boundary,
        str(dst),
    ]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    assert proc.returncode == 0, f"{' '.join(cmd)} failed:\n{proc.stderr}"
    return np.fromfile(dst, dtype="<f4").reshape(rows, cols, 10)
