"""The shipped GLSL on OpenGL (hzval.techniques.gl.horizon_gl, issue 31) against hzval's GPU emulation
(--path gpu).

Both read the same samples of one Context. At texel centres the horizon map
is read exactly, so what is compared is the weight cube map's filtering
(seamless across faces) and the shader's arithmetic; lights sit on every
edge and corner of the cube that the upper hemisphere meets. Mesa's
llvmpipe filters 8-bit textures in 8-bit fixed point by default and in
float with GALLIVM_PERF=no_aos_sampling, which it reads once per process:
the float-path test runs in a subprocess. Tests skip (with the reason) only
where no EGL context can be made.
"""

import json
import math
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from hzval.bake.maps import BakeParams, bake
from hzval.cli import main as cli
from hzval.core.errors import InputError
from hzval.scene import lookup
from hzval.scene import spec as sc
from hzval.techniques import registry as technique
from hzval.techniques.gl import context as gl
from hzval.techniques.horizon import Horizon

try:
    gl.context()
    NO_GL = None
except gl.Unavailable as e:
    NO_GL = str(e)

needs_gl = pytest.mark.skipif(NO_GL is not None, reason=f"no EGL context: {NO_GL}")

#: atan(1 / sqrt 2): the elevation of the cube's upper corners.
CORNER_EL = math.degrees(math.atan(1 / math.sqrt(2)))


def edge_lights() -> list[tuple[float, float]]:
    """Lights on every edge and corner of the cube in the upper hemisphere, and just off them."""
    out = []
    for k in range(4):
        side = 45.0 + 90.0 * k  # vertical edges between side faces
        out += [(side, e) for e in (0.0, 10.0, 30.0, 35.0)]
        out += [(side, CORNER_EL), (side, 35.26), (side + 0.3, 30.0), (side - 0.3, 30.0)]
        mid = 90.0 * k  # edges between a side face and +z
        out += [(mid, 45.0), (mid, 44.9), (mid, 45.1)]
        off = mid + 20.0  # the top edge away from its middle: tan e = cos 20
        out.append((off, math.degrees(math.atan(math.cos(math.radians(20.0))))))
    return out


def texel_centre_context(size: int = 32, height: str = "bricks", boundary: str = "wrap") -> technique.Context:
    scene = sc.override(
        sc.Scene(), height=height, size=size, boundary=boundary, effects="shadow", spp=1
    ).validate()
    hm = sc.load_material_height(scene.material)
    baked = bake(hm.height, BakeParams(depth=scene.material.depth, boundary=boundary).validate())
    rows, cols = hm.height.shape
    r, c = np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij")
    like = lookup.Samples(np.zeros(1, np.float32), np.zeros(1, np.float32), rows, cols, 1)
    points = lookup.from_points((c + 0.5).ravel(), (rows - r - 0.5).ravel(), like, "texel centres")
    return technique.Context(
        scene, hm.height, baked, sc.load_albedo(scene.material, rows, cols), points=points
    )


def minified_context(size: int = 32, boundary: str = "wrap") -> technique.Context:
    """The orthographic view from straight above at half the map's resolution (lambda = 1), trilinear."""
    scene = sc.override(
        sc.Scene(),
        size=size,
        boundary=boundary,
        effects="shadow",
        spp=4,
        camera="orthographic",
        view_elevation=90.0,
        resolution=(size // 2, size // 2),
        filter="trilinear",
    ).validate()
    hm = sc.load_material_height(scene.material)
    baked = bake(hm.height, BakeParams(depth=scene.material.depth, boundary=boundary).validate())
    return technique.Context(scene, hm.height, baked, sc.load_albedo(scene.material, size, size))


def differences(ctx: technique.Context, lights, storage: str = "u8") -> tuple[float, float]:
    """(worst mean, worst max) of |F_gpu - F_gl| over the lights' frames."""
    from hzval.techniques.gl.horizon_gl import HorizonGL

    emu, real = Horizon.build(ctx, path="gpu", storage=storage), HorizonGL.build(ctx, storage=storage)
    means, maxes = [0.0], [0.0]
    for az, el in lights:
        d = np.abs(emu.render(az, elevation_deg=el).layers["factor"].astype(np.float64) - real.factor(az, el))
        means.append(float(d.mean()))
        maxes.append(float(d.max()))
    return max(means), max(maxes)


def worst_difference(ctx: technique.Context, lights) -> float:
    """max |F_gpu - F_gl| over the lights' frames."""
    return differences(ctx, lights)[1]


def _float_path_main() -> None:
    """Run in a subprocess with GALLIVM_PERF=no_aos_sampling: prints the worst differences as JSON."""
    lights = [(-45.0, 30.0), (0.0, 30.0), (45.0, 30.0), (45.0, CORNER_EL), (90.0, 45.0)]
    print(
        json.dumps(
            {
                "worst": worst_difference(texel_centre_context(), edge_lights()),
                "trilinear_u8": differences(minified_context(), lights, "u8")[1],
                "trilinear_bc7": differences(minified_context(), lights, "bc7")[1],
                "gl": gl.info(),
            }
        )
    )


@needs_gl
def test_float_sampling_agrees_to_1e_5_on_every_cube_edge_and_corner():
    env = {
        **os.environ,
        "GALLIVM_PERF": "no_aos_sampling",
        "PYTHONPATH": os.pathsep.join([str(Path(__file__).parent), *sys.path]),
    }
    done = subprocess.run(
        [sys.executable, "-c", "import test_horizon_gl as t; t._float_path_main()"],
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    res = json.loads(done.stdout.strip().splitlines()[-1])
    assert res["gl"]["gallivm_perf"] == "no_aos_sampling"
    assert res["worst"] <= 1e-5
    # 2x minified, trilinear: the same 8-bit (and BPTC) mips, read at the same exact level
    assert res["trilinear_u8"] <= 1e-5 and res["trilinear_bc7"] <= 1e-5


@needs_gl
@pytest.mark.parametrize("storage", ["u8", "bc7"])
def test_default_sampling_of_a_minified_trilinear_view_agrees(storage):
    mean, worst = differences(minified_context(), [(0.0, 30.0), (45.0, 30.0), (45.0, CORNER_EL)], storage)
    assert mean <= 0.003 and worst <= 0.03


@needs_gl
def test_bc7_is_uploaded_as_bptc_blocks_at_every_level():
    import ctypes

    from hzval.techniques.gl import horizon_gl as hg

    ctx = minified_context(16)
    tex = hg._horizon_texture(gl.context(), ctx.bake.horizon, "bc7", ctx.scene)
    u, i = ctypes.c_uint, ctypes.c_int
    query = hg._gl_function("glGetTexLevelParameteriv", u, i, u, ctypes.POINTER(i))
    hg._gl_function("glBindTexture", u, u)(0x8C1A, tex.glo)
    value = (i * 1)()
    for level, width in enumerate((16, 8, 4, 2, 1)):
        query(0x8C1A, level, 0x1003, value)  # GL_TEXTURE_INTERNAL_FORMAT
        assert value[0] == 0x8E8C  # GL_COMPRESSED_RGBA_BPTC_UNORM
        query(0x8C1A, level, 0x1000, value)  # GL_TEXTURE_WIDTH
        assert value[0] == width
    tex.release()


@needs_gl
def test_default_sampling_agrees_to_2_255ths_on_every_cube_edge_and_corner():
    assert worst_difference(texel_centre_context(), edge_lights()) <= 2 / 255


@needs_gl
def test_without_seamless_filtering_the_edges_disagree(monkeypatch):
    # the check can fail: the old clamp-to-face filter is far from the real pipeline at the seams
    from hzval.techniques import cubemap

    seamless = cubemap.bilinear
    monkeypatch.setattr(cubemap, "bilinear", lambda c, n, d, seamless_=True: seamless(c, n, d, False))
    assert worst_difference(texel_centre_context(), [(45.0, 30.0), (45.0, 35.0), (0.0, 45.0)]) > 0.02


@needs_gl
@pytest.mark.parametrize("boundary", ["wrap", "open"])
def test_jittered_samples_of_a_sweep_agree(boundary):
    # the sweep's own samples (4 spp, jittered): texels blended bilinearly, also across the open border
    scene = sc.override(sc.Scene(), size=32, boundary=boundary, effects="shadow", spp=4).validate()
    hm = sc.load_material_height(scene.material)
    baked = bake(hm.height, BakeParams(depth=scene.material.depth, boundary=boundary).validate())
    ctx = technique.Context(scene, hm.height, baked, sc.load_albedo(scene.material, 32, 32))
    lights = [(a, 30.0) for a in scene.light.azimuths_deg] + [(45.0, 35.26)]
    from hzval.techniques.gl.horizon_gl import HorizonGL

    emu, real = Horizon.build(ctx, path="gpu"), HorizonGL.build(ctx)
    for az, el in lights:
        d = np.abs(emu.render(az, elevation_deg=el).layers["factor"] - real.factor(az, el))
        assert d.mean() <= 0.002 and d.max() <= 0.02, (az, el)


@needs_gl
def test_the_frame_is_the_unshadowed_shading_times_the_shaders_factor():
    from hzval.techniques.gl.horizon_gl import HorizonGL

    ctx = texel_centre_context(32)
    real = HorizonGL.build(ctx)
    frame = real.render(0.0, elevation_deg=10.0)
    F = frame.layers["factor"]
    assert 0.0 <= F.min() and F.max() <= 1.0 and F.min() < F.max()
    # shadows only: the image is grey E times F
    assert np.allclose(frame.image, F[..., None] * ctx.scene.light.irradiance, atol=1e-6)
    p = real.parameters
    assert p["gl"]["renderer"] and p["gl"]["version"] and p["gl"]["vendor"]
    assert (
        p["shader"] == "hzval/techniques/gl/shaders/horizon_shadow.glsl"
        and p["cube_filter"] == "seamless bilinear"
    )


def test_gl_techniques_are_opt_in():
    scene = sc.Scene()
    chosen = [t.name for t in technique.select(None, scene)]
    assert "horizon-gl" not in chosen and "pom-gl" not in chosen
    assert [t.name for t in technique.select(["horizon-gl", "horizon"], scene)] == ["horizon", "horizon-gl"]


def test_the_shaders_are_package_files():
    for name in ("horizon_shadow.glsl", "pom_shadow.glsl", "samples.frag"):
        text = gl.shader_source(name)
        assert "void main" in text or "float " in text
    assert "horizonShadow(" in gl.shader_source("horizon_shadow.glsl")
    assert "pomShadow(" in gl.shader_source("pom_shadow.glsl")


def test_without_a_context_the_sweep_skips_it_with_one_line(variant, tmp_path, monkeypatch, capsys):
    def no_context():
        raise gl.Unavailable(f"no OpenGL 3.3 context through EGL (test): {gl.INSTALL}")

    monkeypatch.setattr(gl, "context", no_context)
    out = tmp_path / "out"
    assert (
        cli.main(
            [
                "sweep",
                "--size",
                "16",
                "--azimuths",
                "0",
                "--spp",
                "1",
                "--techniques",
                "horizon,horizon-gl",
                "--quiet",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    m = json.loads((out / "metrics.json").read_text())
    assert list(m["techniques"]) == ["horizon"]
    skipped = [w for w in m["warnings"] if w.startswith("horizon-gl: skipped")]
    assert len(skipped) == 1 and "pip install moderngl" in skipped[0] and "\n" not in skipped[0]
    assert "hzval: warning: horizon-gl: skipped" in capsys.readouterr().err
    # nothing else to score: one line, exit 2
    assert (
        cli.main(
            [
                "sweep",
                "--size",
                "16",
                "--azimuths",
                "0",
                "--spp",
                "1",
                "--techniques",
                "horizon-gl",
                "--quiet",
                "--out",
                str(tmp_path / "none"),
            ]
        )
        == 2
    )
    assert "no technique is left" in capsys.readouterr().err


@needs_gl
def test_sweep_records_the_gl_pipeline(variant, tmp_path):
    out = tmp_path / "out"
    assert (
        cli.main(
            [
                "sweep",
                "--size",
                "16",
                "--azimuths",
                "0",
                "--spp",
                "1",
                "--techniques",
                "horizon,horizon-gl",
                "--horizon-path",
                "gpu",
                "--quiet",
                "--out",
                str(out),
            ]
        )
        == 0
    )
    m = json.loads((out / "metrics.json").read_text())
    g = m["techniques"]["horizon-gl"]["parameters"]["gl"]
    assert set(g) >= {"version", "renderer", "vendor"}
    f = m["frames"][0]["techniques"]
    assert abs(f["horizon-gl"]["visibility_mae"] - f["horizon"]["visibility_mae"]) <= 2e-3


def test_square_root_storage_is_refused_before_anything_is_written(variant, tmp_path, capsys):
    bad = tmp_path / "bad"
    assert (
        cli.main(
            [
                "sweep",
                "--size",
                "16",
                "--azimuths",
                "0",
                "--techniques",
                "horizon-gl",
                "--horizon-storage",
                "u8-sqrt",
                "--quiet",
                "--out",
                str(bad),
            ]
        )
        == 2
    )
    err = capsys.readouterr().err.strip()
    assert err.startswith("hzval: error: --horizon-storage") and "\n" not in err and not bad.exists()


@needs_gl
def test_pom_gl_marches_as_pom():
    from hzval.techniques.gl.horizon_gl import PomGL
    from hzval.techniques.pom import RayMarchShadow

    scene = sc.override(sc.Scene(), size=32, effects="shadow", spp=4).validate()
    hm = sc.load_material_height(scene.material)
    baked = bake(hm.height, BakeParams(depth=scene.material.depth).validate())
    ctx = technique.Context(scene, hm.height, baked, sc.load_albedo(scene.material, 32, 32))
    for variant_ in ("hard", "soft"):
        a, b = (
            RayMarchShadow.build(ctx, variant=variant_, steps=16),
            PomGL.build(ctx, variant=variant_, steps=16),
        )
        for az in (-45.0, 0.0, 60.0):
            d = np.abs(a.factor(az, 30.0) - b.factor(az, 30.0))
            assert d.mean() <= 0.002, (variant_, az, d.mean())
    with pytest.raises(InputError, match="steps"):
        PomGL.build(ctx, steps=0)
