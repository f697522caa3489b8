"""OpenGL for the GL techniques: a headless EGL context and the sample pass that runs a shipped shader.

The GL techniques (:mod:`hzval.techniques.gl.horizon_gl`) run the shaders of
``hzval/techniques/gl/shaders/`` on a real OpenGL pipeline: Mesa's llvmpipe on a CPU, the
vendor's driver on a GPU. The context is moderngl's (PyPI ``moderngl``,
with ``glcontext``'s EGL back end), headless, core profile 3.3 or newer,
made once per process and shared; ``HZVAL_GL_DEVICE`` picks an EGL device
by index (glcontext's ``device_index``) on a machine with several.

Where no context can be made (no moderngl, no EGL, no driver), :func:`context`
raises :class:`Unavailable` with one line saying what to install; the
sweep skips the technique and goes on (:class:`hzval.techniques.registry.Unavailable`).

The sample pass (:class:`SamplePass`): one fragment per sample of the
sweep, so that the shader reads its textures exactly where every other
technique of the sweep does (:class:`hzval.scene.lookup.Samples`). Samples are
laid out in bands of :data:`BAND_WIDTH` x at most :data:`BAND_ROWS`
fragments, their ``(u, v)`` in an RG32F texture uploaded once; each frame
draws one full-screen triangle per band into an R32F target and reads back
one float a sample, averaged over each pixel's samples. A per-pixel
footprint texture gives ``textureGrad`` the pixel's derivatives, as a GPU's
2x2 quads would (``hzval.scene.lookup``, ``filter``).

llvmpipe's own settings (Mesa's ``GALLIVM_PERF``, read once per process at
the first context): by default it filters 8-bit textures in 8-bit fixed
point; ``GALLIVM_PERF=no_aos_sampling`` selects its float path
(docs/gpu-pipeline.md).
"""

from __future__ import annotations

import os
from importlib import resources

import numpy as np

from hzval.core import conventions as cv

__all__ = ["Unavailable", "context", "info", "shader_source", "SamplePass", "BAND_WIDTH", "BAND_ROWS"]

#: Fragments per row of a band of samples.
BAND_WIDTH = 4096
#: Rows per band: 4M samples a draw (16 MB of float results).
BAND_ROWS = 1024
#: What to install when no context can be made.
INSTALL = (
    "pip install moderngl (with glcontext) and Mesa's EGL: apt-get install libegl1 libegl-mesa0 "
    "libgl1-mesa-dri"
)

_context = None


class Unavailable(Exception):
    """No OpenGL context can be made here; the message says what to install (one line)."""


def context():
    """Return the process's headless moderngl context (made at the first call), or :class:`Unavailable`."""
    global _context
    if _context is not None:
        return _context
    try:
        # optional: the GL techniques only
        import moderngl
    except ImportError as e:
        raise Unavailable(f"no moderngl ({e}): {INSTALL}") from None
    kwargs = {"standalone": True, "backend": "egl", "require": 330}
    if os.environ.get("HZVAL_GL_DEVICE"):
        kwargs["device_index"] = int(os.environ["HZVAL_GL_DEVICE"])
    try:
        _context = moderngl.create_context(**kwargs)
    except Exception as e:  # glcontext raises plain Exceptions for a missing libEGL or driver
        first = str(e).strip().splitlines()[0] if str(e).strip() else type(e).__name__
        raise Unavailable(f"no OpenGL 3.3 context through EGL ({first}): {INSTALL}") from None
    _context.gc_mode = "auto"  # GL objects are freed with their Python objects
    # filter the cube map across its faces (ARB_seamless_cube_map; core since 3.2, off by default)
    _context.enable_direct(0x884F)  # GL_TEXTURE_CUBE_MAP_SEAMLESS
    return _context


def info() -> dict:
    """Return the context's GL version, renderer and vendor, and Mesa's ``GALLIVM_PERF``.

    The values are for ``metrics.json``.
    """
    c = context().info
    out = {"version": c["GL_VERSION"], "renderer": c["GL_RENDERER"], "vendor": c["GL_VENDOR"]}
    if os.environ.get("GALLIVM_PERF"):
        out["gallivm_perf"] = os.environ["GALLIVM_PERF"]
    return out


def shader_source(name: str) -> str:
    """Return the text of a shader shipped with hzval.

    Parameters
    ----------
    name : str
        Its file name under ``hzval/techniques/gl/shaders/``.

    Returns
    -------
    str
    """
    return resources.files("hzval.techniques.gl").joinpath("shaders", name).read_text()


def _band_texture(ctx, values: np.ndarray, components: int):
    """Return a float32 texture holding ``values`` ``(n, components)`` row by row.

    It has ``components`` per texel, is :data:`BAND_WIDTH` wide (the last row padded) and is read with
    ``texelFetch``.
    """
    n = values.shape[0]
    width = min(BAND_WIDTH, max(n, 1))
    rows = -(-n // width)
    data = np.zeros((rows * width, components), np.float32)
    data[:n] = values
    tex = ctx.texture((width, rows), components, data.tobytes(), dtype="f4")
    tex.filter = (0x2600, 0x2600)  # GL_NEAREST: texelFetch ignores it; completeness needs one level
    return tex, width


class SamplePass:
    """Runs ``samples.frag`` with a shadow function over every sample of a sweep's image.

    ``library``: the shader file(s) defining the function (e.g. ``horizon_shadow.glsl``);
    ``define``: ``"HORIZON"`` or ``"POM"``; ``samples``: the sweep's :class:`hzval.scene.lookup.Samples`.
    :meth:`run` binds the caller's textures and uniforms and returns the pixel means ``(H, W)``.
    """

    def __init__(self, library: str, define: str, samples, shape: tuple[int, int]):

        ctx = self.ctx = context()
        source = "\n".join(
            ["#version 330 core", f"#define {define}", shader_source(library), shader_source("samples.frag")]
        )
        self.program = ctx.program(vertex_shader=_VERTEX, fragment_shader=source)
        self.vao = ctx.vertex_array(self.program, [])
        self.shape, self.spp = shape, int(samples.spp)
        u, v = cv.tangent_to_uv(samples.x, samples.y, samples.rows, samples.cols)
        uv = np.stack([np.asarray(u, np.float32), np.asarray(v, np.float32)], axis=-1)
        self.count = uv.shape[0]
        self.bands = []  # (first sample, texture, rows, target)
        per_band = BAND_WIDTH * BAND_ROWS
        for first in range(0, self.count, per_band):
            tex, width = _band_texture(ctx, uv[first : first + per_band], 2)
            fbo = ctx.framebuffer(color_attachments=[ctx.texture(tex.size, 1, dtype="f4")])
            self.bands.append((first, tex, width, fbo))
        self.footprints, self.footprint_width = self._footprints(samples)

    def _footprints(self, samples):
        """Return the per-pixel footprints ``(du/dcol, dv/dcol, du/drow, dv/drow)``.

        Texels are turned to texture coordinates (``u = x / cols``, ``v = (rows - y) / rows``); zeros (level
        0) without footprints.
        """
        fp = samples.footprint
        if fp is None:
            values = np.zeros((1, 4), np.float32)
        else:
            fp = np.nan_to_num(np.asarray(fp, np.float64), nan=1.0)
            scale = np.array([1.0 / samples.cols, -1.0 / samples.rows] * 2)
            values = (fp * scale).astype(np.float32)
        return _band_texture(self.ctx, values, 4)

    def set(self, **uniforms) -> None:
        """Set the program's uniforms that it uses (names of ``samples.frag``)."""
        for name, value in uniforms.items():
            if name in self.program:
                self.program[name].value = value

    def run(self, textures: dict) -> np.ndarray:
        """Return the pixel means of the pass's output, float32 ``shape``.

        ``textures`` maps sampler uniform names to moderngl textures (the sample and footprint textures are
        bound here).
        """
        units = {"samplePositions": None, "pixelFootprints": self.footprints, **textures}
        for unit, name in enumerate(units):
            if name in self.program:
                self.program[name].value = unit
        self.set(samplesPerPixel=self.spp, footprintWidth=self.footprint_width)
        out = np.empty(self.count, np.float32)
        for first, tex, width, fbo in self.bands:
            for unit, t in enumerate(units.values()):
                (tex if t is None else t).use(unit)
            self.set(firstSample=first, bandWidth=width)
            fbo.use()
            fbo.viewport = (0, 0, *fbo.size)
            self.vao.render(mode=self.ctx.TRIANGLES, vertices=3)
            n = min(self.count - first, width * fbo.size[1])
            band = np.frombuffer(fbo.read(components=1, dtype="f4"), np.float32)
            out[first : first + n] = band[:n]
        per_pixel = out.reshape(-1, self.spp).mean(axis=1, dtype=np.float64) if self.spp > 1 else out
        return np.asarray(per_pixel, np.float32).reshape(self.shape)

    def release(self) -> None:
        """Free the pass's GL objects."""
        for _, tex, _, fbo in self.bands:
            tex.release()
            for a in fbo.color_attachments:
                a.release()
            fbo.release()
        self.footprints.release()
        self.vao.release()
        self.program.release()
        self.bands = []


# one triangle covering the viewport: no vertex buffer
_VERTEX = """#version 330 core
void main() {
    vec2 p = vec2(float((gl_VertexID & 1) << 2) - 1.0, float((gl_VertexID & 2) << 1) - 1.0);
    gl_Position = vec4(p, 0.0, 1.0);
}
"""
