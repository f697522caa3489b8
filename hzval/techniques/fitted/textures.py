"""A per-pixel technique's textures fitted to the truth: the floor of its representation.

The horizon fit (:mod:`hzval.techniques.fitted.fit`, docs/fit.md) for every technique whose factor is
a formula of its textures (:class:`hzval.techniques.perpixel.PerPixelFactor`): the micro-shadowing
techniques' AO, bent-cone's bent normal and AO, ssbump's three channels. The forward model is the
technique's own kernel (:class:`hzval.techniques.perpixel.FactorKernel`): its packed texture, filtered
as the sweep filters it, with the fitted planes replaced by differentiable parameters, and its own
:meth:`~hzval.techniques.perpixel.PerPixelFactor.factor`, whose clamps and steps pass the gradient
of their ramps straight through. The training lights, loss, Adam, pull toward the bake and per-light
weights are the horizon fit's (:mod:`hzval.techniques.fitted.model`). Each texture is fitted as it
is stored: quantisation-aware for u8 and the block formats (the stored values forward, the
gradient straight through), and the result is what the GPU samples.

Ranges: an AO or a self-shadowed bump channel lies in [0, 1]; a bent normal is renormalised with
``z >= 0`` after every step.
"""

from __future__ import annotations

import dataclasses
import gc
import time
from dataclasses import dataclass, field

import numpy as np
from typing_extensions import override

from hzval.core import backend
from hzval.core import conventions as cv
from hzval.core.backend import dr, mi
from hzval.core.errors import InputError
from hzval.metrics import facing as hzfacing
from hzval.scene import lookup
from hzval.techniques import perpixel
from hzval.techniques import registry as technique
from hzval.techniques.fitted import fit
from hzval.techniques.fitted import guard as fit_guard
from hzval.techniques.fitted import model as fit_model
from hzval.techniques.fitted import training as fitted_training

__all__ = [
    "PRIOR",
    "SEARCH_STRIDE",
    "TextureFit",
    "TextureModel",
    "fittable",
    "check_fittable",
    "separable",
    "search",
    "facing_errors",
    "fit_textures",
]


def fittable() -> list[str]:
    """Return the registered techniques whose textures can be fitted: per-pixel factors that read textures."""
    out = []
    for name in technique.names():
        cls = technique.get(name)
        if (
            issubclass(cls, perpixel.PerPixelFactor)
            and cls.textures
            and not getattr(cls, "fitted_from", None)
        ):
            out.append(name)
    return out


def check_fittable(name: str, flag: str = "--technique") -> type:
    """Return the class of technique ``name`` if its textures can be fitted, else one line naming ``flag``."""
    if name not in fittable():
        raise InputError(flag, f"cannot fit {name!r}; fittable: horizon, {', '.join(fittable())}")
    return technique.get(name)


@dataclass
class TextureFit:
    """A technique's fitted textures and how they were found.

    ``planes``: by texture name, float32 as the GPU samples them (the storage, decoded); ``mae``:
    mean ``|F - V|`` of the baked and the fitted textures on the ``training`` and ``held_out`` lights,
    and ``per_light`` each light's; the rest as :class:`hzval.techniques.fitted.fit.FitResult`.
    """

    technique: str
    settings: dict
    storage: dict
    planes: dict
    lights: tuple
    held_out: tuple
    mae: dict
    loss: list
    epoch_seconds: list
    epochs: int
    steps: int
    converged: bool
    seconds: dict
    options: dict = field(default_factory=dict)

    def record(self) -> dict:
        """``fit.json``'s content."""
        return {
            "format": "hzval fit 2",
            "technique": self.technique,
            "settings": self.settings,
            "storage": self.storage,
            "textures": sorted(self.planes),
            **fit_model.run_record(self, "straight-through clamps and steps"),
            "options": self.options,
        }


class TextureModel(fit_model.LightBatches):
    """A per-pixel technique whose fitted textures are differentiable parameters (module docstring).

    ``cls`` and ``settings``: the technique and its settings (storage included); the packed
    texture's other planes (the normal map's normal) stay as they are.
    """

    def __init__(self, scene, bake, cls, settings: dict, V_list: list[np.ndarray], lights=()):
        self.scene = fitted_training.fit_scene(scene)
        self.tech = cls(self.scene, bake, None, **settings)
        self.tech.straight_through = True
        self.kernel = self.tech.kernel
        self.kernel.prepare()
        self.level = self.kernel.texture_level()
        self.rows, self.cols = self.kernel.rows, self.kernel.cols
        self.P, self.spp = self.kernel.pixels, self.kernel.spp
        self.constants = self.tech.constants()
        self.names = list(cls.textures)
        self._layout(np.asarray(self.level.tensor(), np.float32))
        # the pixels facing each light: elsewhere the direct term the factor multiplies is 0
        self.setup(
            V_list, [hzfacing.facing_mask(bake.normal, L) for L in _directions(lights)] if V_list else None
        )

    def _layout(self, packed: np.ndarray) -> None:
        """Record where each fitted texture's channels sit in the packed texture.

        Per packed value: whether it is the texture's and which of its parameter's values it is; the rest stay
        ``packed``'s.
        """
        texels, self.C = self.rows * self.cols, packed.shape[-1]
        slots = self.kernel.slots
        self.widths, self._mask, self._index = {}, {}, {}
        for t in self.names:
            s = slots[self.kernel.slot(self.tech, t)]
            w = self.widths[t] = s.stop - s.start
            on = np.zeros((texels, self.C), bool)
            on[:, s] = True
            index = np.zeros((texels, self.C), np.uint32)
            index[:, s] = np.arange(texels, dtype=np.uint32)[:, None] * w + np.arange(w, dtype=np.uint32)
            self._mask[t], self._index[t] = mi.Bool(on.ravel()), mi.UInt32(index.ravel())
        self._constant = mi.Float(lookup.aligned(packed.ravel()))

    def stored(self, t: str, values: np.ndarray) -> np.ndarray:
        """Return what the shader samples of texture ``t``'s ``values`` in the technique's storage.

        ``values`` is ``(rows, cols, channels)``.
        """
        return perpixel.stored(values, self.tech.storage[t], signed=self.tech.texture(t).signed)

    def _packed(self, values: dict):
        """Return the packed texture with ``values`` (by texture; Dr.Jit tensors, gradients kept) in place."""
        out = self._constant
        for t in self.names:
            out = dr.select(
                self._mask[t], dr.gather(mi.Float, values[t].array, self._index[t], self._mask[t]), out
            )
        return mi.TensorXf(out, shape=(self.rows, self.cols, self.C))

    def set_parameters(self, opt) -> None:
        """Upload the optimiser's parameters as stored, with their gradients (straight through)."""
        values = {}
        for t in self.names:
            p = opt[t]
            if self.tech.storage[t] == "float":
                values[t] = p
            else:
                s = self.stored(t, np.asarray(p, np.float32).reshape(self.rows, self.cols, self.widths[t]))
                values[t] = dr.replace_grad(mi.TensorXf(lookup.aligned(s)), p)
        self.level.set_tensor(self._packed(values))

    @override
    def upload(self, values) -> None:
        with dr.suspend_grad():
            self.level.set_tensor(
                self._packed({t: mi.TensorXf(lookup.aligned(_channels(values[t]))) for t in self.names})
            )

    def factor(self, lights, a: int, b: int):
        """Return the pixel means of the technique's ``F``, light-major.

        ``F`` is clamped to [0, 1] straight through.
        """
        L = fit_model.light_vectors(lights)
        li, sample = self.sample_lanes(len(lights), a, b)
        u, v = self.kernel.positions(sample)
        tex = self.kernel.fetch(u, v)
        own = {t: tex[self.kernel.slot(self.tech, t)] for t in self.names}
        n = dr.normalize(mi.Vector3f(*tex[perpixel.NORMAL_SLOT])) if self.tech.reads_normal else None
        Ll = dr.gather(mi.Vector3f, L, li)
        F = self.tech.factor(own, n, Ll, self.constants)
        # the kernel's own clamp and snap to 1 (FactorKernel), straight through
        clamped = dr.clip(F, 0.0, 1.0)
        return self.pixel_mean(perpixel.through(dr.select(clamped >= 1.0 - 2.0**-20, 1.0, clamped), F))


def _directions(lights) -> list:
    return [cv.light_direction(az, e) for e, az in lights]


def facing_errors(model: TextureModel, values: dict, lights, V) -> list[float]:
    """Return each light's mean ``|F - V|`` over the pixels facing it.

    This is the sweep's ``visibility_mae_facing``; 0 where no pixel faces the light.
    """
    out = []
    for e, (el, az) in zip(model.errors(values, lights, V), lights):
        m = hzfacing.facing_mask(model.tech.bake.normal, cv.light_direction(az, el))
        out.append(float(e[m].mean()) if m.any() else 0.0)
    return out


def _release() -> None:
    """Free the fit's arrays now.

    Many wrap NumPy memory without a copy (the LLVM backend's zero-copy views), whose release is a host
    callback; collected later, inside the symbolic loop of a sweep's next kernel, the callback cannot be
    recorded and Dr.Jit aborts (``enqueue_host_func(): this function cannot be recorded``: four fits in one
    sweep did).
    """
    gc.collect()
    dr.sync_thread()


def _channels(a: np.ndarray) -> np.ndarray:
    a = np.asarray(a, np.float32)
    return a[..., None] if a.ndim == 2 else a


def _project(cls, names):
    """Back into each texture's range after a step: [0, 1], or a unit vector with ``z >= 0``."""

    def project(opt) -> None:
        for t in names:
            if cls.texture(t).signed:
                p = opt[t]
                shape = p.shape
                v = dr.unravel(mi.Vector3f, p.array)
                v.z = dr.maximum(v.z, 1e-3)
                opt[t] = mi.TensorXf(dr.ravel(dr.normalize(v)), shape=shape)
            else:
                fit_model.clip_unit(opt, t)

    return project


#: The pull toward the bake (:data:`hzval.techniques.fitted.fit.PRIOR`): none. A texture fit's
#: factors are steps and clamps whose gradients pass straight through; the horizon fit's pull held
#: bent-cone at its bake (64 x 64, training 0.110 -> 0.108 on ridges), where without it the fit
#: found 0.033 and a lower error at every held-out elevation (25 degrees: 0.0197 -> 0.0145).
PRIOR = 0.0
#: The per-texel search's first pass tries every ``SEARCH_STRIDE``-th of the 256 levels, the second
#: the levels within ``SEARCH_STRIDE - 1`` of each texel's best: 48 passes over the lights, not 256.
SEARCH_STRIDE = 8


def search(
    model: TextureModel, t: str, values: dict, lights, V: list[np.ndarray]
) -> tuple[np.ndarray, float]:
    """Return the best of 256 levels for each texel of the one-channel texture ``t``.

    The other textures are as ``values``.

    Each candidate level is tried at every texel at once and scored by its pixel's ``|F - V|`` over
    the lights, where the pixel faces each, each light weighted by one over its facing pixels (the
    fit's criterion, :func:`facing_errors`); the fit's top view has a pixel a texel, so the score is
    exact where a pixel's samples read its own texel alone, and a close estimate under the bilinear
    filter, which mixes in the neighbours' candidates. A coarse pass (every :data:`SEARCH_STRIDE`-th
    level), then each texel's best's neighbourhood of levels.

    Parameters
    ----------
    model : TextureModel
        The forward model.
    t : str
        The texture searched.
    values : dict
        Every texture's values, as stored; ``t``'s is replaced.
    lights, V
        The training lights and the truth's visibility of each.

    Returns
    -------
    tuple
        ``(levels in [0, 1] (rows, cols) float32, mean |F - V| of the map as stored)``.
    """
    rows, cols = model.rows, model.cols
    masks = model.masks if model.masks is not None else [np.ones((rows, cols), bool)] * len(lights)
    weights = [m / max(int(m.sum()), 1) for m in masks]

    def level_map(index: np.ndarray) -> np.ndarray:
        return model.stored(t, (index.astype(np.float32) / np.float32(255.0))[..., None])[..., 0]

    def cost(values_t: np.ndarray) -> np.ndarray:
        trial = dict(values)
        trial[t] = values_t
        return sum(e * w for e, w in zip(model.errors(trial, lights, V), weights))

    best = np.rint(np.clip(np.asarray(values[t], np.float64), 0.0, 1.0) * 255.0).astype(np.int64)
    best_cost = cost(values[t])

    def consider(index: np.ndarray) -> None:
        c = cost(level_map(index))
        better = c < best_cost
        best[better], best_cost[better] = index[better], c[better]

    for level in [*range(0, 256, SEARCH_STRIDE), 255]:
        consider(np.full((rows, cols), level, np.int64))
    start = best.copy()
    for o in range(-(SEARCH_STRIDE - 1), SEARCH_STRIDE):
        if o != 0:
            consider(np.clip(start + o, 0, 255))
    best = _refine(best, lambda index: cost(level_map(index)), model.tech.bake.params.boundary)
    found = level_map(best)
    trial = dict(values)
    trial[t] = found
    return found, _mean_error(model, trial, lights, V)


#: The offsets of the refinement's candidates from each texel's level (:func:`_refine`).
REFINE_OFFSETS = (-16, -8, -4, -2, -1, 1, 2, 4, 8, 16)
#: Passes of the refinement over the lattices.
REFINE_ROUNDS = 3


def _refine(best: np.ndarray, cost, boundary: str) -> np.ndarray:
    """Refine the levels by coordinate descent, the neighbours' levels as they are.

    The filter makes a texel's level reach the 3 x 3 pixels about it, so texels 3 apart (9 interleaved
    lattices) can move at once and each move's cost is exactly the change over its own neighbourhood. Every
    lattice tries :data:`REFINE_OFFSETS`; a texel keeps a move that lowers its neighbourhood's cost. The
    levels are kept only where the whole map's cost falls (a wrapped side not a multiple of 3 puts two lattice
    texels closer across the seam).
    """
    current = cost(best)
    out = best.copy()
    rows, cols = best.shape
    r, c = np.indices((rows, cols))
    for lattice in [*range(9)] * REFINE_ROUNDS:
        on = (r % 3 == lattice // 3) & (c % 3 == lattice % 3)
        here = fit_guard.neighbourhood_sum(current, boundary)
        for o in REFINE_OFFSETS:
            trial = out.copy()
            trial[on] = np.clip(out[on] + o, 0, 255)
            after = cost(trial)
            gain = on & (fit_guard.neighbourhood_sum(after, boundary) < here)
            if gain.any():
                out[gain] = trial[gain]
                # the pixels a moved texel reaches took their cost from the trial: the other moves
                # of the trial reach other pixels
                moved = fit_guard.neighbourhood_sum(gain.astype(np.float64), boundary) > 0
                current = np.where(moved, after, current)
                here = fit_guard.neighbourhood_sum(current, boundary)
    return out if cost(out).sum() < cost(best).sum() else best


def _mean_error(model: TextureModel, values: dict, lights, V) -> float:
    """Mean ``|F - V|`` over the lights and the pixels facing each (the fit's criterion)."""
    return float(np.mean(facing_errors(model, values, lights, V)))


def separable(model: TextureModel) -> bool:
    """Return whether the technique reads one one-channel texture (the micro-shadowing techniques' AO).

    Its factor at a sample is then a function of that texel's value alone (and the normal map's), and the loss
    separates per texel up to the filter (:func:`search`).
    """
    return len(model.names) == 1 and model.widths[model.names[0]] == 1


def _fit(model: TextureModel, cls, baked: dict, lights, V, adam: dict):
    """Return the textures that do best on the training lights.

    One one-channel texture is searched per texel (:func:`search`); several textures, or one of several
    channels, are fitted by Adam from the bake (:func:`hzval.techniques.fitted.model.optimise`) with the
    horizon fit's per-light weights. A search over one texture of several would trade the lights between the
    training elevations away (bent-cone's AO alone: ridges at 25 degrees 0.0215 -> 0.0241 over pixels facing
    the light). The result is kept only where it lowers the training error, so it is never worse there than
    the bake.

    Returns ``(textures as stored, loss per epoch, seconds per epoch, steps, converged, steps taken)``.
    """
    values, current, how = dict(baked), _mean_error(model, baked, lights, V), []
    curve, times, steps, converged = [], [], 0, True
    if separable(model):
        (t,) = cls.textures
        found, error = search(model, t, values, lights, V)
        trial = {**values, t: found}
        if error < current:
            values, current = trial, error
            how.append(f"per-texel search of {t}")
        return values, curve, times, steps, converged, how or ["none: the bake did best"]
    opt, curve, times, steps, converged = fit_model.optimise(
        model,
        {t: mi.TensorXf(lookup.aligned(_channels(values[t]))) for t in cls.textures},
        lights,
        set_parameters=model.set_parameters,
        project=_project(cls, cls.textures),
        baked_losses=model.light_losses(baked, lights, V) if adam["constrain"] > 0 else None,
        **adam,
    )
    moved = {}
    for t in cls.textures:
        a = model.stored(t, np.asarray(opt[t], np.float32).reshape(model.rows, model.cols, -1))
        moved[t] = a[..., 0] if a.shape[-1] == 1 else a  # the bake's shape
    if _mean_error(model, moved, lights, V) < current:
        values = moved
        how.append("Adam over " + ", ".join(cls.textures))
    return values, curve, times, steps, converged, how or ["none: the bake did best"]


def fit_textures(
    height: np.ndarray,
    bake,
    scene,
    name: str,
    *,
    settings: dict | None = None,
    lights=fitted_training.TRAINING_LIGHTS,
    held_out=fitted_training.HELD_OUT_LIGHTS,
    tolerance: float = fit.TOLERANCE,
    max_epochs: int = fit.MAX_EPOCHS,
    learning_rate: float = fit.LEARNING_RATE,
    prior: float = PRIOR,
    train_spp: int | None = None,
    constrain: float = fit.CONSTRAIN,
    progress: bool = True,
) -> TextureFit:
    """Fit a per-pixel technique's textures to the truth (module docstring; docs/fit.md).

    Parameters
    ----------
    height : numpy.ndarray
        ``(rows, cols)`` the normalised height map.
    bake : hzval.bake.maps.Bake
        The bake whose textures the fit starts from (with its directional occlusion).
    scene : hzval.scene.spec.Scene
        The sweep's scene (:func:`hzval.techniques.fitted.training.fit_scene` makes the fit's).
    name : str
        The technique (:func:`fittable`).
    settings : dict, optional
        Its settings, as its ``build`` takes them (``storage``: ``{texture: format}``, a variant).
    lights, held_out, tolerance, max_epochs, learning_rate, prior, train_spp, constrain, progress
        As :func:`hzval.techniques.fitted.fit.fit`.

    Returns
    -------
    TextureFit
    """
    backend.variant()
    cls = check_fittable(name)
    settings = dict(settings or {})
    cls.check_settings(bake.params, settings)
    lights = fitted_training.parse_lights(lights) if isinstance(lights, str) else tuple(lights)
    if isinstance(held_out, str):
        held_out = fitted_training.parse_lights(held_out, "held_out") if held_out.strip() else ()
    held_out = tuple(held_out)
    rows, cols = height.shape
    fitted_training.check_fits("HEIGHT", rows, cols, scene.spp, len(lights) + len(held_out), scene)
    train = dataclasses.replace(
        scene, spp=min(scene.spp, int(train_spp or fitted_training.training_spp(scene.spp, rows * cols)))
    )
    t0, c0 = time.perf_counter(), time.process_time()
    V_train, V_held = fit.truths(train, scene, height, lights, held_out, progress)
    t_truth, c_truth = time.perf_counter() - t0, time.process_time() - c0

    t0, c0 = time.perf_counter(), time.process_time()
    model = TextureModel(train, bake, cls, settings, V_train, lights)
    baked = {t: model.tech.stored_plane(t) for t in cls.textures}
    adam = {
        "tolerance": tolerance,
        "max_epochs": max_epochs,
        "lr": learning_rate,
        "prior": prior,
        "constrain": constrain,
        "seed": scene.seed,
        "progress": progress,
    }
    fitted, curve, times, steps, converged, how = _fit(model, cls, baked, lights, V_train, adam)
    t_fit, c_fit = time.perf_counter() - t0, time.process_time() - c0
    mae = {}
    for what, s, ls, V in (("training", train, lights, V_train), ("held_out", scene, held_out, V_held)):
        if ls:
            m = model if s is train else TextureModel(s, bake, cls, settings, [])
            before, after = facing_errors(m, baked, ls, V), facing_errors(m, fitted, ls, V)
            whole = [[float(np.mean(e)) for e in m.errors(x, ls, V)] for x in (baked, fitted)]
            mae[what] = {
                "baked": float(np.mean(before)),
                "fitted": float(np.mean(after)),
                "lights_worse": int(sum(a > b for a, b in zip(after, before))),
                "whole_image": {"baked": float(np.mean(whole[0])), "fitted": float(np.mean(whole[1]))},
                "per_light": [
                    {"elevation_deg": e, "azimuth_deg": az, "baked": b, "fitted": a}
                    for (e, az), b, a in zip(ls, before, after)
                ],
            }
    used, stores = dict(model.tech.settings), dict(model.tech.storage)
    del model, m
    _release()
    return TextureFit(
        name,
        used,
        stores,
        fitted,
        lights,
        held_out,
        mae,
        curve,
        times,
        len(curve),
        steps,
        converged,
        {
            "truth": t_truth,
            "fit": t_fit,
            "evaluate": time.perf_counter() - t0 - t_fit,
            "cpu": {"truth": c_truth, "fit": c_fit, "evaluate": time.process_time() - c0 - c_fit},
        },
        {
            "tolerance": tolerance,
            "max_epochs": max_epochs,
            "learning_rate": learning_rate,
            "prior": prior,
            "constrain": constrain,
            "batch_lights": fit_model.BATCH_LIGHTS,
            "spp": scene.spp,
            "train_spp": train.spp,
            "seed": scene.seed,
            "optimiser": "per-texel search of one-channel textures, then Adam (mitsuba.ad.Adam)",
            "steps": how,
        },
    )
