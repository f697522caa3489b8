"""A sweep's frames: each light rendered by the truth and every technique, scored and written.

Each is scored against the truth and written by :func:`render_frames`, with what
:func:`hzval.pipeline.sweep.set_up` builds once before them (:class:`Setup`) and the clocks that time each
stage.
"""

from __future__ import annotations

import contextlib
import dataclasses
import math
import time
from pathlib import Path

import numpy as np

from hzval.bake.maps import BakeParams
from hzval.core import backend, shading, srgb
from hzval.metrics import compare
from hzval.metrics import facing as hzfacing
from hzval.pipeline import records, writing
from hzval.techniques import surface
from hzval.truth import plane as truth

__all__ = [
    "finite",
    "metrics_record",
    "Setup",
    "cpu_time",
    "stage_time",
    "lights",
    "render_frames",
]


def finite(x):
    """JSON has no infinity: a perfect PSNR is written as null."""
    return None if isinstance(x, float) and not math.isfinite(x) else x


def metrics_record(m: compare.FrameMetrics) -> dict:
    """Return a frame's scores as ``metrics.json`` records them (a non-finite number as ``null``)."""
    return {k: finite(v) for k, v in m.as_dict().items()}


@dataclasses.dataclass
class Setup:
    """What :func:`run` builds once before the frames."""

    material: dict
    params: BakeParams
    truth: truth.Truth
    unshadowed: surface.Unshadowed
    techniques: list  # built Technique objects, registry order
    timings: dict
    bake_contents: tuple = ()  # what was baked (hzval.bake.maps.CONTENTS)
    notices: list = dataclasses.field(default_factory=list)  # one-line warnings of the set-up
    estimate: int = 0  # estimated peak memory, bytes
    retained: bool = False  # freed memory kept (budget.RETAIN_BELOW_SHARE, backend.retain_freed_memory)
    perfect: list = dataclasses.field(default_factory=list)  # the techniques at the truth's hits
    base_shadow: object = (
        None  # a model's no-shadows factor: its base mesh's own shadow (perpixel.BaseShadow)
    )
    view: dict = dataclasses.field(default_factory=dict)  # metrics.json's "view" (_view_errors)
    view_maps: dict = dataclasses.field(default_factory=dict)  # its per-pixel maps
    normal: np.ndarray | None = (
        None  # the top view's normal map: which pixels face the light (hzval.metrics.facing)
    )
    albedo_constant: float | None = None  # the linear albedo where it is one grey value (frames.json)
    albedo: np.ndarray | None = None  # the albedo image where it is not one value (written for engines)


@contextlib.contextmanager
def cpu_time(seconds: dict, stage: str):
    """Add the process's CPU time over the block to ``seconds[stage]``.

    The time is every thread's: Dr.Jit's workers and the writers' too. It is ``metrics.json``'s
    ``timings.cpu_s``, beside the stages' wall time.
    """
    c0 = time.process_time()
    try:
        yield
    finally:
        seconds[stage] = seconds.get(stage, 0.0) + time.process_time() - c0


@contextlib.contextmanager
def stage_time(clock: dict, stage: str):
    """Add the block's wall time to ``clock[stage + "_s"]`` and its CPU time to ``clock["cpu_s"][stage]``.

    The CPU time is :func:`cpu_time`'s. This is for a stage that runs in parts, such as each technique's
    render between comparisons.
    """
    t0 = time.perf_counter()
    try:
        with cpu_time(clock["cpu_s"], stage):
            yield
    finally:
        clock[f"{stage}_s"] += time.perf_counter() - t0


def lights(scene) -> list[tuple[float | None, float]]:
    """Return the sweep's lights, ``(elevation, azimuth)`` in degrees.

    They are every azimuth at each elevation of :meth:`hzval.scene.spec.Light.elevations` in turn; the
    elevation is ``None`` where there is one (its frames keep their azimuth's name,
    :func:`hzval.pipeline.records.frame_folder`).
    """
    light = scene.light
    several = len(light.elevations()) > 1
    return [(e if several else None, az) for e in light.elevations() for az in light.azimuths_deg]


def render_frames(
    out: Path, scene, setup: Setup, scale: float, clock: dict, all_files: bool, bar
) -> list[dict]:
    """Render, compare and write every light of the sweep; return their ``metrics.json`` frames in order.

    The lights come as the progress bar ``bar`` (a ``tqdm`` of :func:`lights`) gives them; each is rendered
    (:func:`_render`), then its techniques rendered and compared one by one, and written (:func:`_finish`).

    One frame at a time, every stage on all cores: the comparison and the truth are both Dr.Jit
    kernels, so overlapping them gains next to nothing and costs memory and clear stage timings.
    """
    frames: list[dict] = []
    for el, az in bar:
        bar.set_postfix_str(f"azimuth {az:+g} deg" + ("" if el is None else f", elevation {el:g}"))
        if el is not None:
            setup.truth.light_at(el)
        # no name holds a frame's renders past its _finish: the next frame's renders would
        # otherwise be made beside them (1.8 GB at 4096 x 4096)
        with cpu_time(clock["cpu_s"], "truth_frames"):
            t_frame = setup.truth.render(az)
        # the techniques' renders as they ran (technique_frames_s): a technique's own frame time
        # (<stem>_s) includes the unshadowed shading it composes its image from, which they share
        with stage_time(clock, "technique_frames"):
            rendered = _render(setup, t_frame, az, el, scale, clock)
        del t_frame
        frames.append(_finish(out, scene, setup, rendered, scale, clock, all_files))
        del rendered
    return frames


@dataclasses.dataclass
class _Rendered:
    """One light's renders, from the truth to each technique's frame once it is compared.

    They are the truth, the unshadowed shading and its direct term, (a view other than ``top``) each
    technique's error at the truth's hit points, and, once :func:`_score_light` has rendered and compared
    them, each technique's frame without its image (kept only for ``--all-files``: the comparison has what the
    report shows of it).
    """

    azimuth_deg: float
    elevation_deg: float | None  # None: the scene's one elevation
    truth: object
    plain: object
    direct: np.ndarray
    perfect: dict
    base: object = None  # a model's no-shadows frame: the base mesh's own shadow alone
    background: np.ndarray | None = None  # a view: the linear colour of the pixels it does not see
    techniques: list = dataclasses.field(default_factory=list)


def _render(setup: Setup, t_frame, az: float, el: float | None, scale: float, clock: dict) -> _Rendered:
    """Return the renders of the light at ``(el, az)`` that every technique's comparison reads.

    They sit beside the truth's ``t_frame``: the unshadowed shading, a model's base shadow, a view's
    perfect-parallax errors (a view's unseen pixels made the background in every image). The techniques' own
    frames are rendered one at a time as they are compared (:func:`_score_light`): holding all of them at once
    was 2 GB at 4096 x 4096 with eight techniques.
    """
    plain, direct = setup.unshadowed.render(az, el)
    clock["plain_s"] += plain.seconds
    base = None if setup.base_shadow is None else setup.base_shadow.render(az, elevation_deg=el)
    mask = t_frame.mask
    perfect, bg = {}, None
    if mask is not None:
        # a view: what no camera ray sees is the background in every image, and left out of the metrics
        bg = (srgb.decode(np.asarray(writing.UNSEEN_DISPLAY)) / scale).astype(np.float32)
        t_frame, plain = _unseen(t_frame, mask, bg), _unseen(plain, mask, bg)
        base = None if base is None else _unseen(base, mask, bg)
        V = t_frame.layers.get("visibility")
        for t in setup.perfect:
            F = t.render(az, elevation_deg=el).layers.get("factor")
            if V is not None and F is not None:
                perfect[t.name] = compare.visibility_metrics(V, F, mask)[0]
    return _Rendered(az, el, t_frame, plain, direct, perfect, base, bg)


def _finish(out: Path, scene, setup: Setup, r: _Rendered, scale: float, clock: dict, all_files: bool) -> dict:
    """Compare and write one light's renders; its ``metrics.json`` frame."""
    t_frame, az = r.truth, r.azimuth_deg
    folder = records.frame_folder(az, r.elevation_deg)
    # the truth's files start once its display values are made (a large image's after the
    # techniques), each technique's as soon as it is compared; the frame's end waits for them all
    # (write_s: starting the truth's and the techniques' files, and that wait)
    with writing.FrameWriter(out, folder, scale, t_frame.mask, all_files) as writer:
        compared, floor, none, rel = _score_light(setup, r, scale, clock, writer)
        with stage_time(clock, "write"):
            writer.wait()
    frame = {
        "name": folder,
        "azimuth_deg": az,
        "elevation_deg": t_frame.elevation_deg,
        "truth_s": t_frame.seconds,
    }
    if hasattr(setup.truth, "macro_shadowed"):
        frame["macro_shadowed"] = setup.truth.macro_shadowed(az)  # a model: the base mesh's own shadow
    if floor is not None:
        frame["floor"] = floor
    if none is not None:
        frame["no_shadows"] = none
    per = {t.name: {**metrics_record(m), "seconds": f.seconds, "files": own} for t, f, m, own in compared}
    for name, value in r.perfect.items():
        per[name]["perfect_parallax_mae"] = value
    for t in setup.techniques:
        per[t.name].update(type(t).frame_extras(per))
    _shadow_statistics(scene, setup, r, frame, per)
    if hasattr(setup.truth, "handedness"):
        _handedness_statistics(setup.truth.handedness, r, per)
    frame.update(files=rel, techniques=per)
    return frame


def _score_light(setup: Setup, r: _Rendered, scale: float, clock: dict, writer) -> tuple:
    """Render, compare and start the files of one light's techniques, each in turn.

    This is timed as ``technique_frames`` and ``compare``; ``writer`` is the frame's
    :class:`writing.FrameWriter`. The truth's files are started before them (after them where the truth does
    not keep its samples, a large image). The result is ``(technique, frame, metrics, its files)`` per
    technique, the perfect-shadows floor, the no-shadows baseline and the truth's files. ``r.techniques`` gets
    each technique's frame, its image dropped unless the writer writes every file (``--all-files``).
    """
    t_frame = r.truth
    # an image too large for the truth to keep its samples: hand Dr.Jit's freed buffers back before
    # the comparison, and after each of its steps, whose buffers differ in size and would each stay
    # cached (0.2 GiB of a 4096 sweep's peak); smaller images keep them: re-faulting the pages of
    # every frame's buffers cost 1 s a frame at 2048
    release = backend.release_memory if not setup.truth.keeps else (lambda: None)
    release()
    with stage_time(clock, "compare"):
        ref = compare.Reference(t_frame, scale)

    def truth_files() -> dict:
        with stage_time(clock, "write"):
            return writer.truth_files(t_frame, r.plain, writing.shown(ref.display))

    # the truth's files are written while the techniques are rendered and compared; a large image's
    # are started at the end instead, as before, where the techniques' buffers are freed and the
    # encoders' own do not add to the sweep's peak
    early = truth_files() if setup.truth.keeps else None
    compared = []
    for t in setup.techniques:
        with stage_time(clock, "technique_frames"):
            f = t.render(r.azimuth_deg, elevation_deg=r.elevation_deg)
            f = f if r.background is None else _unseen(f, t_frame.mask, r.background)
        release()
        with stage_time(clock, "compare"):
            metrics, maps = compare.compare(t_frame, f, scale, reference=ref)
            # only what the writers need, as small as it comes: the preview's 8-bit values (an eighth
            # of the float64 display values: 400 MB a technique at 4096 x 4096) and the FLIP map
            kept = {"shown": writing.shown(maps["display"]), "flip": maps["flip"]}
        del maps
        with stage_time(clock, "write"):  # starting its files (the frame's visibility map's truth half once)
            own = writer.technique_files(t.file_stem, f, kept, t_frame.layers.get("visibility"))
        del kept  # the writers hold it until its files are written
        compared.append((t, f if writer.all_files else dataclasses.replace(f, image=None), metrics, own))
        del f
    r.techniques = [(t, f) for t, f, _, _ in compared]
    release()
    V = t_frame.layers.get("visibility")
    with stage_time(clock, "compare"):
        floor = _floor(ref, r.direct, setup.unshadowed.ambient_image, V)
        none = _no_shadows(ref, r.plain if r.base is None else r.base, V, t_frame.mask)
    return compared, floor, none, early if early is not None else truth_files()


def _shadow_statistics(scene, setup: Setup, r: _Rendered, frame: dict, per: dict) -> None:
    """Record the truth's shadowed and attached fractions and each technique's visibility metrics.

    The fractions go into ``frame["truth"]``; the metrics are over the pixels that face the light
    (:mod:`hzval.metrics.facing`).
    """
    V = r.truth.layers.get("visibility")
    if V is None:
        return
    facing = None
    if setup.normal is not None:
        facing = hzfacing.facing_mask(
            setup.normal,
            scene.light.direction(r.azimuth_deg, frame["elevation_deg"]),
            scene.camera.supersampling,
        )
    frame["truth"] = hzfacing.truth_statistics(V, facing, scene.spp, r.truth.mask)
    if facing is None:
        return
    for t, f in r.techniques:
        F = f.layers.get("factor")
        if F is not None:
            per[t.name].update(hzfacing.facing_metrics(V, F, facing, r.truth.mask))
    if "no_shadows" in frame:
        F = np.ones_like(V) if r.base is None else r.base.layers["factor"]
        frame["no_shadows"].update(hzfacing.facing_metrics(V, F, facing, r.truth.mask))


def _handedness_statistics(sign: np.ndarray, r: _Rendered, per: dict) -> None:
    """Record each technique's |F - V| over mirrored and unmirrored pixels on a model with mirrored UVs.

    ``visibility_mae_mirrored`` is over the pixels whose UVs are mirrored and ``visibility_mae_unmirrored``
    over those as drawn: where a tangent bug of the handedness would show
    (:mod:`hzval.geometry.tangent_bugs`).
    """
    V = r.truth.layers.get("visibility")
    if V is None or not (sign < 0).any():
        return
    for t, f in r.techniques:
        F = f.layers.get("factor")
        if F is not None:
            for key, mask in (("visibility_mae_mirrored", sign < 0), ("visibility_mae_unmirrored", sign > 0)):
                per[t.name][key] = float(compare.visibility_metrics(V, F, mask)[0]) if mask.any() else None


def _unseen(frame, mask: np.ndarray, background: np.ndarray):
    """``frame`` with ``background`` (linear) where ``mask`` is false and its layers 0 there."""
    image = np.where(mask[..., None], frame.image, background).astype(np.float32)
    layers = {k: np.where(mask, v, 0.0).astype(np.float32) for k, v in frame.layers.items()}
    return dataclasses.replace(frame, image=image, layers=layers, mask=mask)


def _floor(ref: compare.Reference, direct: np.ndarray, ambient: np.ndarray | None, V: np.ndarray | None):
    """Return the perfect-shadows floor of a frame, scored against the truth.

    It is the techniques' unshadowed shading times the truth's own visibility, ``direct * V + ambient``,
    scored with ``compare.IMAGE_METRICS``.

    No technique can score better than its shadows being exactly right, so
    this is the part of every image score that is not the shadows' (the
    shading's difference from the truth's, and the truth's noise); ``None``
    without ``shadow``.
    """
    if V is None:
        return None
    scores, _ = compare.image_metrics(ref, shading.compose(direct, V, ambient))
    return {k: finite(v) for k, v in scores.items()}


def _no_shadows(ref: compare.Reference, none, V: np.ndarray | None, mask) -> dict | None:
    """Return the baseline of a frame, no technique's shadows: its image scores and ``|F - V|``.

    The baseline is ``F = 1``: the unshadowed shading, the report's normal mapping only; on a model ``F`` is
    the base mesh's own shadow, which every technique's factor holds too. A technique worse than it at some
    light elevation does harm there. ``none``: its frame; ``None`` without ``shadow``.
    """
    if V is None:
        return None
    scores, _ = compare.image_metrics(ref, none.image)
    F = none.layers.get("factor", np.ones_like(V))
    mae, leaks, false_shadows = compare.visibility_metrics(V, F, mask)
    return {k: finite(v) for k, v in scores.items()} | {
        "visibility_mae": mae,
        "leak_fraction": leaks,
        "false_shadow_fraction": false_shadows,
    }
