"""The best horizon map: the eight channels fitted to the truth's visibility with Dr.Jit's AD.

The baked horizon map is one estimate of what eight sines a texel should
hold; the map that minimises mean ``|F - V|`` against the truth is the
representation's floor (what eight directions, linear interpolation between
them and one ``k`` ramp can do), and ``baked - fitted`` is what the bake
loses. :func:`fit` finds it.

Training data
    The truth's visibility ``V`` (:class:`hzval.truth.plane.Truth`, the ``top``
    view, the scene's samples) for each training light: by default hard
    lights at elevations 10, 20, 40 and 60 degrees and azimuths 0 to 345 by
    15 (:data:`TRAINING_LIGHTS`); a soft light's ``V`` is an average of hard
    ones. None is at the default sweep's elevation, 30 degrees, so a sweep
    scores the fit on lights it did not see. :data:`HELD_OUT_LIGHTS` (25
    degrees, azimuths -52.5 to 52.5 by 15) are scored, never trained on.
    The training lights are rendered at :func:`training_spp` samples a pixel
    (a budget of :data:`TRAINING_SAMPLES` a light), the held-out ones at the
    scene's; one truth set-up serves every elevation (:func:`visibility`).

The forward model
    The horizon technique's own kernel (:class:`hzval.techniques.horizon.Horizon`):
    its texture (:class:`hzval.scene.lookup.Filtered`, bilinear, the bake's wrap or
    clamp), its per-light channel weights (``_uniforms``) and its factor
    (:func:`hzval.techniques.horizon.shadow_factor`), at the sweep's own sample
    positions, averaged per pixel as the sweep's ``factor`` layer is. Only
    the texture's tensor is replaced by the differentiable parameters.

The loss
    ``mean sqrt((F - V)^2 + eps^2) - eps`` (Charbonnier, a smoothed L1,
    ``eps =`` :data:`CHARBONNIER_EPS`), over pixels and lights. It is
    ``|F - V|`` to within ``eps`` where it matters, and differentiable where
    ``F = V``: most pixels are fully lit or fully shadowed and exactly
    right, where ``|.|`` has no gradient to speak of and an L2 would weigh
    the few large errors most. The clamp of eq. 5.4 has zero gradient where
    ``F`` is saturated, so a texel that is wrongly saturated (F = 0 where
    the truth is lit) would never move: the factor's clamp is
    straight-through (its gradient is the unclamped ramp's); where it is
    saturated and right, the Charbonnier term's gradient is 0 anyway.

Optimisation
    Adam (:class:`mitsuba.ad.Adam`, Kingma and Ba 2015) on the ``rows x cols x
    8`` sines, clipped to the stored range [0, 1] after every step, from the
    baked map; with ``fit_k`` also on ``log k`` (clipped to [0, log 128]).
    Lights are taken in shuffled batches of :data:`BATCH_LIGHTS` (one Adam
    step each); an *epoch* is a pass over every light. When an epoch improves
    the loss by less than ``tolerance`` (relative), the learning rate is
    halved; the fit has converged at the :data:`HALVINGS`-th such plateau (or
    stops after ``max_epochs``). A pull toward the baked map, ``prior * mean
    |p - p_baked|`` (:data:`PRIOR`), keeps the sines that the training lights
    leave free where the bake put them. Each light's loss is weighted by
    ``1 + lambda``, its multiplier raised after each epoch by its relative
    excess over the baked map's loss (:func:`_reweight`, :data:`CONSTRAIN`):
    dual ascent on "no training light worse than the bake". With ``guard``,
    :func:`hzval.techniques.fitted.guard.guard` gives the bake back to the texels that
    still do worse nearby on some training light.

Storage
    ``float``: the sines as they are. ``u8`` and the block formats
    (:mod:`hzval.io.storage`): quantisation-aware, the forward model samples the
    stored map (``Storage.roundtrip`` of the parameters, recomputed every
    step) and the gradient passes straight through the rounding (Bengio et
    al. 2013's straight-through estimator), so the optimiser moves the
    parameters to the stored values that score best. The result holds what
    the GPU samples: the stored map, decoded.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from hzval.core import backend
from hzval.core import conventions as cv
from hzval.core.errors import InputError
from hzval.io import storage as hz_storage
from hzval.scene import lookup
from hzval.scene import spec as sc
from hzval.techniques import horizon
from hzval.techniques.fitted import guard as fit_guard

__all__ = [
    "TRAINING_LIGHTS",
    "HELD_OUT_LIGHTS",
    "FitResult",
    "parse_lights",
    "fit",
    "write_fit",
    "read_fit",
    "estimate_bytes",
    "check_fits",
    "visibility",
    "mean_error",
    "light_errors",
    "training_spp",
]

#: The default training lights, ``ELEVATIONS@AZIMUTHS`` (:func:`parse_lights`).
TRAINING_LIGHTS = "10,20,40,60@0:345:15"
#: The default held-out lights: scored, never trained on.
HELD_OUT_LIGHTS = "25@-52.5:52.5:15"
#: ``eps`` of the Charbonnier loss (module docstring): a sixteenth of the 16-spp truth's V step.
CHARBONNIER_EPS = 1.0 / 256.0
#: Samples per training light (truth and forward model): a fit's time is its samples' (the truth's
#: shadow rays, the kernel's lanes), so the training lights get ``TRAINING_SAMPLES / pixels`` samples a
#: pixel, at most the scene's and at least 1 (:func:`training_spp`): 16 at 256 x 256, 4 at 512 x 512.
#: 4 stratified samples a pixel still cover a texel's bilinear footprint; the held-out lights are
#: scored at the scene's own samples.
TRAINING_SAMPLES = 1 << 20
#: Lights per Adam step.
BATCH_LIGHTS = 8
#: Adam's learning rate on the sines (and on log k).
LEARNING_RATE = 0.02
#: Relative improvement of an epoch's loss below which the fit counts as converged.
TOLERANCE = 5e-3
MAX_EPOCHS = 60
#: Plateaus (learning rate halved at each) after which the fit has converged.
HALVINGS = 3
#: The largest k that ``fit_k`` may reach (the tradeoff's golden-section search's bound).
MAX_K = 128.0
#: Samples per band of the forward model: bounds the AD graph's memory.
BAND_SAMPLES = 1 << 23
#: Weight of the pull toward the baked map, ``PRIOR * mean |p - p_baked|`` over every sine (0: none).
#: Where the training lights leave a sine free (a horizon between two training elevations), the
#: Charbonnier term's gradient is 0 or tiny and Adam's momentum carries it off; on lights between
#: the training elevations that cost the fit: at the default sweep (elevation 30, 256 x 256), without
#: the pull, fabric's fitted |F - V| was 1.04x the baked map's and ridges' 1.16x; with 0.05 / 0.1
#: fabric's 0.86x / 0.80x (its training error 0.021 / 0.026 instead of 0.0185).
PRIOR = 0.1
#: Memory of a fit (:func:`estimate_bytes`): a base, bytes per pixel and light (V), per sample (uv),
#: per texel (parameters, gradient, Adam's two moments, the stored copy, the bake) and per sample of
#: a band (the AD graph of the forward model).
FIT_BASE_BYTES = 0.4 * 2**30
FIT_BYTES_PER_PIXEL_LIGHT = 4
FIT_BYTES_PER_SAMPLE = 8
FIT_BYTES_PER_TEXEL = 8 * 4 * 8
FIT_BYTES_PER_BAND_SAMPLE = 160
#: The step of the per-light weights (:func:`_reweight`): a light 10 % worse than the bake gains 0.1 x this
#: weight an epoch (0: the plain mean over lights).
CONSTRAIN = 2.0
#: The smallest baked loss a light's excess is relative to (a light the bake gets all but exactly right).
CONSTRAINT_FLOOR = 1e-4
#: Bumped when the fit changes what it finds: a cached fit of another version is made anew.
FIT_VERSION = 2


def parse_lights(spec: str, what: str = "--lights") -> tuple[tuple[float, float], ...]:
    """The training (or held-out) lights of a spec.

    Parameters
    ----------
    spec : str
        ``"E1,E2@AZIMUTHS[;...]"``: each group's elevations (degrees) times its azimuths
        (``START:STOP:STEP`` or a list, :func:`hzval.scene.spec.parse_azimuths`).
    what : str
        The flag the errors name.

    Returns
    -------
    tuple of (float, float)
        ``(elevation_deg, azimuth_deg)`` in order.

    Raises
    ------
    hzval.core.errors.InputError
        For a malformed spec, naming ``what``.
    """
    lights: list[tuple[float, float]] = []
    for group in (g.strip() for g in str(spec).split(";")):
        if not group:
            continue
        if group.count("@") != 1:
            raise InputError(what, f"expected ELEVATIONS@AZIMUTHS (e.g. {TRAINING_LIGHTS}), got {group!r}")
        elev_text, az_text = group.split("@")
        try:
            elevations = [float(e) for e in elev_text.split(",") if e.strip()]
        except ValueError:
            raise InputError(what, f"elevations must be numbers, got {elev_text!r}") from None
        azimuths = sc.parse_azimuths(az_text.strip(), what)
        for e in elevations:
            if not (math.isfinite(e) and 0.0 < e < 90.0):
                raise InputError(what, f"an elevation must lie in (0, 90) degrees, got {e:g}")
        if not azimuths or not elevations:
            raise InputError(what, f"no lights in {group!r}")
        lights += [(e, float(a)) for e in elevations for a in azimuths]
    if not lights:
        raise InputError(what, "name at least one light")
    return tuple(dict.fromkeys(lights))


def training_spp(spp: int, pixels: int) -> int:
    """Samples per pixel of the training lights' truth and forward model.

    Parameters
    ----------
    spp : int
        The scene's samples per pixel.
    pixels : int
        The image's pixels.

    Returns
    -------
    int
        :data:`TRAINING_SAMPLES` over ``pixels``, at most ``spp``, at least 1.
    """
    return max(1, min(int(spp), TRAINING_SAMPLES // max(1, int(pixels))))


def fit_scene(scene) -> "sc.Scene":
    """The scene the fit renders, from a sweep's.

    Shadows only (``V`` and ``F`` are all it compares), a hard light, the ``top`` view with the
    default lookup (a pixel a texel, bilinear), whatever view the sweep has: the fitted map is a
    texture, fitted where a pixel sees its texel.

    Parameters
    ----------
    scene : hzval.scene.spec.Scene
        The sweep's scene.

    Returns
    -------
    hzval.scene.spec.Scene
    """
    from hzval.scene.camera import Camera

    light = dataclasses.replace(scene.light, kind="hard", radius_deg=0.0)
    return dataclasses.replace(
        scene, effects=("shadow",), light=light, camera=Camera(), lookup=lookup.Lookup()
    )


def visibility(scene, height: np.ndarray, lights, bar=None) -> list[np.ndarray]:
    """The truth's visibility of each light, from one set-up.

    One :class:`hzval.truth.plane.Truth`, set up for the lowest elevation of ``lights``, renders them
    all: its mesh's tolerance and wrap margin serve every higher light (a higher ray clears the
    relief sooner; each frame takes the hops its own elevation needs). The tests check that a
    shared set-up's ``V`` is a fresh one's bit for bit.

    Parameters
    ----------
    scene : hzval.scene.spec.Scene
        The fit's scene (:func:`fit_scene`).
    height : numpy.ndarray
        ``(rows, cols)`` the normalised height map.
    lights : sequence of (float, float)
        ``(elevation_deg, azimuth_deg)``.
    bar : tqdm.tqdm, optional
        A progress bar, advanced a light at a time.

    Returns
    -------
    list of numpy.ndarray
        ``(H, W)`` float32 ``V``, one per light, in order.
    """
    from hzval.truth import plane as truth

    base = fit_scene(scene)
    elevations = sorted(dict.fromkeys(e for e, _ in lights))
    if not elevations:
        return []

    def at(e):
        return dataclasses.replace(base, light=dataclasses.replace(base.light, elevation_deg=e))

    t = truth.Truth(at(elevations[0]), height)
    out: dict[tuple[float, float], np.ndarray] = {}
    for e in elevations:
        t.scene = at(e).validate()
        for el, az in lights:
            if el == e:
                out[(el, az)] = t.render(az).layers["visibility"]
                if bar is not None:
                    bar.update(1)
    del t
    return [out[light] for light in lights]


def estimate_bytes(rows: int, cols: int, spp: int, lights: int, scene=None) -> int:
    """The fit's estimated peak memory.

    The truth's ``V`` of every light, beside the larger of the truth's own peak while it renders
    (:func:`hzval.truth.memory.estimate_peak_bytes` of the fit's scene, when ``scene`` is given) and
    the optimisation's (:data:`FIT_BASE_BYTES` and the per-sample, per-texel and per-band terms).

    Parameters
    ----------
    rows, cols : int
        The map's size.
    spp : int
        Samples per pixel.
    lights : int
        Training and held-out lights, each a ``V`` kept.
    scene : hzval.scene.spec.Scene, optional
        The sweep's scene, for the truth's own peak.

    Returns
    -------
    int
        Bytes.
    """
    P = rows * cols
    band = min(P * spp, BAND_SAMPLES)
    optimise = (
        FIT_BASE_BYTES
        + FIT_BYTES_PER_SAMPLE * P * spp
        + FIT_BYTES_PER_TEXEL * P
        + FIT_BYTES_PER_BAND_SAMPLE * band
    )
    render = 0
    if scene is not None:
        from hzval.truth import memory

        render = memory.estimate_peak_bytes(dataclasses.replace(fit_scene(scene), spp=spp), rows, cols)
    return int(FIT_BYTES_PER_PIXEL_LIGHT * P * lights + max(optimise, render))


def check_fits(what: str, rows: int, cols: int, spp: int, lights: int, scene=None) -> int:
    """Refuse, before anything is allocated, a fit that would not fit in memory.

    Parameters
    ----------
    what : str
        The flag or file the refusal names.
    rows, cols, spp, lights, scene
        As :func:`estimate_bytes`.

    Returns
    -------
    int
        The estimate, in bytes, when it fits.

    Raises
    ------
    hzval.core.errors.InputError
        One line (:func:`hzval.core.resources.refuse_over`).
    """
    from hzval.core import resources

    return resources.refuse_over(
        what,
        estimate_bytes(rows, cols, spp, lights, scene),
        f"fitting {cols}x{rows} texels at {spp} spp to {lights} lights",
        "fewer --spp or --lights, or a smaller map",
    )


def light_errors(scene, bake, sines: np.ndarray, lights, V: list[np.ndarray], k: float) -> list[float]:
    """Mean ``|F - V|`` of the horizon technique rendering ``sines``, per light.

    The sweep's own ``visibility_mae`` (:func:`hzval.metrics.compare.visibility_metrics`, every pixel
    seen).

    Parameters
    ----------
    scene : hzval.scene.spec.Scene
        The fit's scene.
    bake : hzval.bake.maps.Bake
        The bake the map belongs to (its normal map and parameters).
    sines : numpy.ndarray
        ``(rows, cols, D)`` horizon sines, as stored (float).
    lights : sequence of (float, float)
        ``(elevation_deg, azimuth_deg)``.
    V : list of numpy.ndarray
        The truth's visibility of each light (:func:`visibility`).
    k : float
        The technique's hardness.

    Returns
    -------
    list of float
    """
    ap = horizon.Horizon(fit_scene(scene), dataclasses.replace(bake, horizon=sines), None, k=k)
    return [
        float(np.mean(np.abs(ap.render(az, elevation_deg=e).layers["factor"].astype(np.float64) - v)))
        for (e, az), v in zip(lights, V)
    ]


def mean_error(scene, bake, sines: np.ndarray, lights, V: list[np.ndarray], k: float) -> float:
    """Mean ``|F - V|`` over ``lights``: the mean of :func:`light_errors`.

    Parameters
    ----------
    scene, bake, sines, lights, V, k
        As :func:`light_errors`.

    Returns
    -------
    float
    """
    return float(np.mean(light_errors(scene, bake, sines, lights, V, k)))


@dataclass
class FitResult:
    """A fitted horizon map and how it was found.

    ``horizon``: ``(rows, cols, D)`` float32 sines as the GPU samples them (the stored map, decoded);
    ``k``: the shadow hardness it was fitted for; ``mae``: mean ``|F - V|`` of the baked and the
    fitted map, each stored the same way, on the ``training`` and ``held_out`` lights;
    ``loss``: the Charbonnier loss per epoch; ``seconds``: wall seconds of the ``truth`` (its renders),
    the ``fit`` and the ``evaluate`` step, and under ``cpu`` the process's CPU seconds of each.
    """

    horizon: np.ndarray
    k: float
    storage: str
    fit_k: bool
    lights: tuple
    held_out: tuple
    mae: dict
    loss: list
    epoch_seconds: list
    epochs: int
    steps: int
    converged: bool
    seconds: dict
    settings: dict = field(default_factory=dict)

    def record(self) -> dict:
        """``fit.json``'s content."""
        m = self.mae
        return {
            "format": "hzval fit 1",
            "k": self.k,
            "fit_k": self.fit_k,
            "storage": self.storage,
            "mae": m,
            "fitted_over_baked": {
                w: (m[w]["fitted"] / m[w]["baked"] if m[w]["baked"] > 0 else None) for w in m
            },
            "loss": {
                "kind": f"Charbonnier sqrt(d^2 + eps^2) - eps, eps = {CHARBONNIER_EPS:g}; "
                "straight-through clamp",
                "per_epoch": self.loss,
                "epoch_seconds": self.epoch_seconds,
            },
            "epochs": self.epochs,
            "steps": self.steps,
            "converged": self.converged,
            "seconds": self.seconds,
            "settings": self.settings,
            "lights": {
                "training": [{"elevation_deg": e, "azimuth_deg": a} for e, a in self.lights],
                "held_out": [{"elevation_deg": e, "azimuth_deg": a} for e, a in self.held_out],
            },
            "conventions": "horizon0/1 as hzval bake writes them: channel c (azimuth 45 c deg, "
            "counterclockwise from +x) in layer c // 4; sines in [0, 1]",
        }


class _Model:
    """The horizon technique with its horizon texture replaced by differentiable parameters.

    One kernel (a forward and a backward pass) covers a *group* of lights: lane ``i`` is sample
    ``i % n`` of light ``i // n`` of the group, its channel weights the technique's own
    (``_channel_weights``) of that light's direction; a group holds at most :data:`BAND_SAMPLES`
    lanes (one light in pixel bands beyond that), which bounds the AD graph's memory.
    """

    def __init__(self, scene, bake, k: float, storage: str, V_list: list[np.ndarray]):
        import drjit as dr
        import mitsuba as mi

        self.scene = fit_scene(scene)
        self.ap = horizon.Horizon(self.scene, bake, None, k=k)
        if set(self.ap._slots) != {horizon.HORIZON_SLOT}:
            raise AssertionError("the fit's technique must hold the horizon channels alone")
        self.texture = self.ap._texture.levels[0]
        self.storage = hz_storage.get(storage)
        self.rows, self.cols = self.ap.rows, self.ap.cols
        self.P, self.spp = self.ap.pixels, self.ap.spp
        self.group = max(1, BAND_SAMPLES // (self.P * self.spp))
        band = max(1, BAND_SAMPLES // self.spp)
        self.bands = [(a, min(self.P, a + band)) for a in range(0, self.P, band)]
        V = lookup.aligned_empty(len(V_list) * self.P)
        for i, v in enumerate(V_list):  # one copy, not a stack and then an aligned copy
            V[i * self.P : (i + 1) * self.P] = np.asarray(v, np.float32).ravel()
        self.V = mi.Float(V)
        self._mi, self._dr = mi, dr

    def set_parameters(self, p, logk=None) -> None:
        """Upload the parameters: the stored map's values, with the parameters' gradient."""
        dr, mi = self._dr, self._mi
        if self.storage.name == "float":
            value = p
        else:
            stored = self.storage.roundtrip(np.asarray(p, np.float32).reshape(self.rows, self.cols, -1))
            value = dr.replace_grad(mi.TensorXf(lookup.aligned(stored)), p)
        self.texture.set_tensor(value)
        self.k = dr.exp(logk) if logk is not None else self.ap._k

    def factor(self, lights, a: int, b: int):
        """The pixel means of F, light-major, of ``lights`` over pixels ``a..b`` (straight-through clamp)."""
        dr, mi = self._dr, self._mi
        d = np.array([cv.light_direction(az, e) for e, az in lights], np.float32)
        L = mi.Vector3f(*(mi.Float(d[:, i].copy()) for i in range(3)))
        w = self.ap._channel_weights(L)
        n = (b - a) * self.spp
        lane = dr.arange(mi.UInt32, len(lights) * n)
        li = lane // n
        sample = lane - li * n + a * self.spp
        if self.spp == 1:
            u, v = dr.gather(mi.Float, self.ap._u, sample), dr.gather(mi.Float, self.ap._v, sample)
        else:
            uv = dr.gather(mi.Point2f, self.ap._uv, sample)
            u, v = uv.x, uv.y
        h = self.ap._fetch(u, v)[horizon.HORIZON_SLOT]
        F, _ = horizon.shadow_factor(
            h,
            [dr.gather(mi.Float, c, li) for c in w],
            dr.gather(mi.Float, L.z, li),
            self.k,
            straight_through=True,
        )
        return dr.block_sum(F, self.spp) * (1.0 / self.spp) if self.spp > 1 else F

    def errors(self, sines: np.ndarray, k: float, lights, V_list):
        """``|F - V|`` (rows, cols) float32 per light of ``lights`` (and the V they were given in) of
        ``sines`` as stored, at shadow hardness ``k``, without gradients
        (:mod:`hzval.techniques.fitted.guard`)."""
        dr, mi = self._dr, self._mi
        with dr.suspend_grad():
            self.texture.set_tensor(mi.TensorXf(lookup.aligned(np.asarray(sines, np.float32))))
            self.k = k
            for first in range(0, len(lights), self.group):
                group = lights[first : first + self.group]
                F = np.concatenate(
                    [
                        np.asarray(self.factor(group, a, b), np.float32).reshape(len(group), b - a)
                        for a, b in self.bands
                    ],
                    axis=1,
                )
                for i, f in enumerate(F):
                    yield np.abs(f.reshape(self.rows, self.cols) - V_list[first + i])

    def backward(self, indices, lights, scale: float, weights=None, per_light=None) -> float:
        """Accumulate ``scale *`` the gradient of the summed loss of lights ``indices`` (into ``lights``
        and the V they were given in), each light's loss times ``weights[i]`` if given; return the
        unweighted loss (a float) and put each light's into ``per_light[i]`` if given."""
        dr, mi = self._dr, self._mi
        total = 0.0
        for first in range(0, len(indices), self.group):
            group = [int(i) for i in indices[first : first + self.group]]
            for a, b in self.bands:
                F = self.factor([lights[i] for i in group], a, b)
                m = b - a
                lane = dr.arange(mi.UInt32, len(group) * m)
                li = lane // m
                at = dr.gather(mi.UInt32, mi.UInt32(np.array(group, np.uint32)), li) * self.P + (
                    lane - li * m + a
                )
                diff = F - dr.gather(mi.Float, self.V, at)
                pixel = dr.sqrt(dr.fma(diff, diff, CHARBONNIER_EPS**2)) - CHARBONNIER_EPS
                dr.eval(pixel)
                sums = np.asarray(dr.block_sum(dr.detach(pixel), m), np.float64)  # one per light of the group
                if per_light is not None:
                    per_light[group] += sums
                if weights is not None:
                    pixel = pixel * dr.gather(mi.Float, mi.Float(np.asarray(weights, np.float32)[group]), li)
                dr.backward(dr.sum(pixel) * scale)
                total += float(sums.sum())
        return total


def fit(
    height: np.ndarray,
    bake,
    scene,
    *,
    lights=TRAINING_LIGHTS,
    held_out=HELD_OUT_LIGHTS,
    fit_k: bool = False,
    storage: str = "float",
    k: float = horizon.DEFAULT_K,
    tolerance: float = TOLERANCE,
    max_epochs: int = MAX_EPOCHS,
    learning_rate: float = LEARNING_RATE,
    prior: float = PRIOR,
    guard: float | None = None,
    train_spp: int | None = None,
    constrain: float = CONSTRAIN,
    progress: bool = True,
) -> FitResult:
    """Fit a bake's horizon map to the truth, by Dr.Jit's automatic differentiation through the
    horizon technique's own lookup and factor (module docstring; docs/fit.md).

    Parameters
    ----------
    height : numpy.ndarray
        ``(rows, cols)`` the normalised height map.
    bake : hzval.bake.maps.Bake
        The bake whose map the fit starts from.
    scene : hzval.scene.spec.Scene
        The sweep's scene (:func:`fit_scene` makes the fit's).
    lights, held_out : str or sequence of (float, float)
        Training and scored-only lights: specs (:func:`parse_lights`) or ``(elevation, azimuth)``.
    fit_k : bool
        Fit the hardness too.
    storage : str
        How the map is stored (:mod:`hzval.io.storage`); the fit is quantisation-aware for all but float.
    k : float
        The technique's hardness (the start with ``fit_k``).
    tolerance, max_epochs, learning_rate, prior : float, int, float, float
        When to stop, the Adam step, and the pull toward the baked map.
    guard : float, optional
        The tolerance of :func:`hzval.techniques.fitted.guard.guard` (``None``: the optimiser's map
        as it is).
    train_spp : int, optional
        Samples per pixel of the training lights (``None``: :func:`training_spp`); held-out lights are
        scored at the scene's own.
    constrain : float
        The step of the per-light weights (0: the plain mean).
    progress : bool
        Show progress bars.

    Returns
    -------
    FitResult
        The fitted sines, ``k``, the errors per light before and after, epochs and times.
    """
    backend.variant()
    lights = parse_lights(lights) if isinstance(lights, str) else tuple(lights)
    if isinstance(held_out, str):
        held_out = parse_lights(held_out, "held_out") if held_out.strip() else ()
    held_out = tuple(held_out)
    stored = hz_storage.get(storage)
    if not (math.isfinite(k) and k > 0):
        raise InputError("--k", f"must be a positive number, got {k}")
    rows, cols = height.shape
    # the guard holds the bake's |F - V| per pixel and training light beside V: as much again
    check_fits(
        "HEIGHT", rows, cols, scene.spp, len(lights) * (2 if guard is not None else 1) + len(held_out), scene
    )
    train = dataclasses.replace(
        scene, spp=min(scene.spp, int(train_spp or training_spp(scene.spp, rows * cols)))
    )
    t0, c0 = time.perf_counter(), time.process_time()
    V_train, V_held = _truth(train, scene, height, lights, held_out, progress)
    t_truth, c_truth = time.perf_counter() - t0, time.process_time() - c0

    t0, c0 = time.perf_counter(), time.process_time()
    fitted, k_fit, curve, times, steps, converged = _optimise(
        train,
        bake,
        V_train,
        lights,
        k,
        fit_k,
        storage,
        tolerance,
        max_epochs,
        learning_rate,
        progress,
        prior,
        constrain,
    )
    guard_record = None
    if guard is not None:
        fitted, guard_record = guarded(train, bake, stored, V_train, lights, fitted, k, k_fit, guard)
    t_fit, c_fit = time.perf_counter() - t0, time.process_time() - c0
    baked_stored = stored.roundtrip(bake.horizon)
    mae = {}
    for name, s, ls, V in (("training", train, lights, V_train), ("held_out", scene, held_out, V_held)):
        if ls:
            before, after = (
                light_errors(s, bake, baked_stored, ls, V, k),
                light_errors(s, bake, fitted, ls, V, k_fit),
            )
            mae[name] = {
                "baked": float(np.mean(before)),
                "fitted": float(np.mean(after)),
                "lights_worse": int(sum(a > b for a, b in zip(after, before))),
            }
    settings = {
        "tolerance": tolerance,
        "max_epochs": max_epochs,
        "learning_rate": learning_rate,
        "prior": prior,
        "constrain": constrain,
        "batch_lights": BATCH_LIGHTS,
        "spp": scene.spp,
        "train_spp": train.spp,
        "seed": scene.seed,
        "guard": guard_record,
        "k_baked": k,
        "optimiser": "Adam (mitsuba.ad.Adam)",
    }
    return FitResult(
        fitted,
        k_fit,
        storage,
        fit_k,
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
            # the process's CPU seconds (user + sys, every thread): on a shared machine the wall
            # time is what the load allowed, this what the stage cost
            "cpu": {"truth": c_truth, "fit": c_fit, "evaluate": time.process_time() - c0 - c_fit},
        },
        settings,
    )


def guarded(scene, bake, stored, V, lights, fitted, k: float, k_fit: float, tolerance: float):
    """The optimiser's map guarded against the baked map, on the training lights.

    :func:`hzval.techniques.fitted.guard.guard` through the fit's forward model, both maps stored
    alike; a block storage format guards whole blocks.

    Parameters
    ----------
    scene : hzval.scene.spec.Scene
        The fit's scene.
    bake : hzval.bake.maps.Bake
        The bake.
    stored : callable
        The storage's round trip of a map.
    V : list of numpy.ndarray
        The truth's visibility of each training light.
    lights : sequence of (float, float)
        The training lights.
    fitted : numpy.ndarray
        ``(rows, cols, D)`` the optimiser's sines.
    k, k_fit : float
        The baked map's hardness and the fitted one's.
    tolerance : float
        The regression a texel may show before it reverts.

    Returns
    -------
    tuple
        ``(sines, record)`` as :func:`hzval.techniques.fitted.guard.guard`.
    """
    model = _Model(scene, bake, k, "float", [])
    blocks = bool(stored.block_bytes)

    def errors(sines, baked):
        return model.errors(sines, k if baked else k_fit, lights, V)

    return fit_guard.guard(
        stored.roundtrip(bake.horizon),
        fitted,
        errors,
        bake.params.boundary,
        cell=4 if blocks else 1,
        tolerance=tolerance,
        finish=stored.roundtrip if blocks else None,
    )


def _truth(train, scene, height, lights, held_out, progress: bool):
    """The truth's V for the training lights (at ``train``'s samples) and the held-out ones (``scene``'s),
    with a progress bar."""
    import sys

    from tqdm import tqdm

    with tqdm(
        total=len(lights) + len(held_out),
        desc="truth",
        unit="light",
        disable=not progress,
        file=sys.stderr,
        leave=False,
    ) as bar:
        return visibility(train, height, lights, bar), visibility(
            scene, height, held_out, bar
        ) if held_out else []


def _optimise(
    scene,
    bake,
    V_list,
    lights,
    k: float,
    fit_k: bool,
    storage: str,
    tolerance: float,
    max_epochs: int,
    lr: float,
    progress: bool,
    prior: float = 0.0,
    constrain: float = 0.0,
):
    """Adam from the baked map (module docstring); ``(stored sines, k, loss and seconds per epoch, steps,
    converged)``. ``constrain``: the step of the per-light weights (:func:`_reweight`; 0: none)."""
    import sys

    import drjit as dr
    import mitsuba as mi
    from tqdm import tqdm

    model = _Model(scene, bake, k, storage, V_list)
    opt = mi.ad.Adam(lr=lr)
    start = mi.TensorXf(lookup.aligned(np.clip(bake.horizon, 0.0, 1.0)))
    opt["h"] = mi.TensorXf(start)
    if fit_k:
        opt["logk"] = mi.Float(math.log(k))
    rng = np.random.default_rng(scene.seed)
    norm = 1.0 / (model.P * len(lights))
    curve, times, steps, calm, converged = [], [], 0, 0, False
    weights = np.ones(len(lights), np.float32) if constrain > 0 else None
    if weights is not None:
        baked = _light_losses(model, hz_storage.get(storage).roundtrip(bake.horizon), k, lights, V_list)
    bar = tqdm(
        range(max_epochs), desc="fit", unit="epoch", disable=not progress, file=sys.stderr, leave=False
    )
    for _ in bar:
        t0, total, per = time.perf_counter(), 0.0, np.zeros(len(lights))
        order = rng.permutation(len(lights))
        for first in range(0, len(order), BATCH_LIGHTS):
            model.set_parameters(opt["h"], opt["logk"] if fit_k else None)
            total += model.backward(order[first : first + BATCH_LIGHTS], lights, norm, weights, per) * norm
            if prior > 0:
                # where the training lights leave a sine free, it stays the bake's (docs/fit.md, "Limits")
                pull = prior * dr.mean(dr.abs(opt["h"].array - start.array), axis=None)
                dr.backward(pull)
                total += (
                    float(np.asarray(dr.detach(pull)).ravel()[0])
                    * len(order[first : first + BATCH_LIGHTS])
                    / len(lights)
                )
            opt.step()
            opt["h"] = dr.clip(opt["h"], 0.0, 1.0)
            if fit_k:
                opt["logk"] = dr.clip(opt["logk"], 0.0, math.log(MAX_K))
            steps += 1
        if weights is not None:
            weights = _reweight(weights, per / model.P, baked, constrain)
        curve.append(total)
        times.append(time.perf_counter() - t0)
        bar.set_postfix_str(f"loss {total:.5f}")
        if len(curve) > 1 and curve[-2] - total <= tolerance * total:
            # a plateau: halve the step; converged after HALVINGS of them
            calm += 1
            if calm >= HALVINGS:
                converged = True
                break
            opt.set_learning_rate(lr * 0.5**calm)
    bar.close()
    h = np.asarray(opt["h"], np.float32).reshape(model.rows, model.cols, -1)
    k_fit = float(np.exp(np.asarray(opt["logk"])[0])) if fit_k else float(k)
    return hz_storage.get(storage).roundtrip(h), k_fit, curve, times, steps, converged


def _light_losses(model: _Model, sines: np.ndarray, k: float, lights, V_list) -> np.ndarray:
    """The Charbonnier loss of each light (its pixels' mean) of ``sines`` as stored."""
    eps = CHARBONNIER_EPS
    return np.array(
        [
            float(np.mean(np.sqrt(e.astype(np.float64) ** 2 + eps**2) - eps))
            for e in model.errors(sines, k, lights, V_list)
        ]
    )


def _reweight(weights: np.ndarray, losses: np.ndarray, baked: np.ndarray, step: float) -> np.ndarray:
    """The per-light weights after an epoch: ``1 + lambda``, each light's multiplier ``lambda`` raised by
    ``step`` times its relative excess over the baked map's loss (clipped to [-1, 1]; its floor
    :data:`CONSTRAINT_FLOOR`) and kept >= 0 (dual ascent on "no training light worse than the bake")."""
    excess = np.clip((losses - baked) / np.maximum(baked, CONSTRAINT_FLOOR), -1.0, 1.0)
    return (1.0 + np.maximum(0.0, weights - 1.0 + step * excess)).astype(np.float32)


def write_fit(result: FitResult, out: str | Path, *, input_info: dict) -> list[Path]:
    """Write a fit, all or nothing: ``horizon0.exr``, ``horizon1.exr`` (and 8-bit PNGs) in
    :func:`hzval.bake.maps.write_bake`'s layout, and ``fit.json``.

    Parameters
    ----------
    result : FitResult
        The fit.
    out : str or path-like
        The folder.
    input_info : dict
        What ``fit.json`` records of the input (the material, the bake, the cache key).

    Returns
    -------
    list of pathlib.Path
        The files written.
    """
    from hzval.io import files

    layers = [
        result.horizon[..., c : c + cv.CHANNELS_PER_LAYER]
        for c in range(0, result.horizon.shape[-1], cv.CHANNELS_PER_LAYER)
    ]
    with files.Staging(out) as stage:
        for i, layer in enumerate(layers):
            files.write_exr(stage.path(f"horizon{i}.exr"), {"RGBA": layer}, atomic=False, compression="none")
            files.write_png(stage.path(f"horizon{i}.png"), files.unit_to_u8(layer), atomic=False)
        digests = {
            p.relative_to(stage.dir).as_posix(): files.file_digest(p)
            for p in sorted(stage.dir.rglob("*"))
            if p.is_file()
        }
        files.write_json(
            stage.path("fit.json"),
            {"input": input_info, **result.record(), "versions": backend.versions(), "files": digests},
            atomic=False,
        )
        return stage.commit()


def read_fit(folder: str | Path) -> tuple[np.ndarray, dict]:
    """A fit written by :func:`write_fit`.

    Parameters
    ----------
    folder : str or path-like
        Its folder.

    Returns
    -------
    sines : numpy.ndarray
        ``(rows, cols, D)`` float32, from the EXRs.
    record : dict
        ``fit.json``.

    Raises
    ------
    hzval.core.errors.InputError
        For a missing or malformed ``fit.json``.
    """
    from hzval.io import documents, files

    folder = Path(folder)
    record = documents.read_json(folder / "fit.json")
    layers = [
        files.read_exr(folder / f"horizon{i}.exr")
        for i in range(len([n for n in record["files"] if n.endswith(".exr")]))
    ]
    return np.stack([layer[c] for layer in layers for c in "RGBA"], axis=-1), record


def cache_key(height: np.ndarray, bake, scene, settings: dict) -> str:
    """The digest a cached fit is reused by.

    Parameters
    ----------
    height : numpy.ndarray
        The normalised height map.
    bake : hzval.bake.maps.Bake
        Its bake (its parameters).
    scene : hzval.scene.spec.Scene
        The scene (its samples, lookup and supersampling).
    settings : dict
        The fit's own settings.

    Returns
    -------
    str
        A SHA-256 hex digest of all of them and :data:`FIT_VERSION`.
    """
    h = hashlib.sha256(np.ascontiguousarray(height, np.float32).tobytes())
    meta = {
        "bake": bake.params.record(),
        "spp": scene.spp,
        "seed": scene.seed,
        "lookup": repr(scene.lookup),
        "supersampling": scene.camera.supersampling,
        "fit": settings,
        "version": FIT_VERSION,
    }
    h.update(json.dumps(meta, sort_keys=True, default=str).encode())
    return h.hexdigest()


def cached_fit(
    height: np.ndarray, bake, scene, folder: str | Path | None, *, progress: bool = False, **settings
) -> tuple[FitResult | None, np.ndarray, dict, bool]:
    """The fit in ``folder`` when its key and file digests match, else a new one written there.

    Parameters
    ----------
    height, bake, scene
        As :func:`fit`.
    folder : str or path-like or None
        The cache's folder (``None``: fit and keep nothing). A missing, damaged or hand-edited cache is
        fitted anew; nothing outside the folder is read.
    progress : bool
        Show progress bars.
    **settings
        :func:`fit`'s keywords.

    Returns
    -------
    tuple
        ``(result or None, sines, record, cached)``: ``result`` is ``None`` for a cached fit.
    """
    from hzval.io import documents, files, paths

    key = cache_key(height, bake, scene, settings)
    if folder is not None:
        folder = Path(folder)
        try:  # a missing, damaged or hand-edited cache is fitted anew; nothing outside it is read
            record = documents.read_json(folder / "fit.json")
            if record["input"]["key"] == key and all(
                files.file_digest(paths.inside(folder, n, folder / "fit.json", "files")) == d
                for n, d in record["files"].items()
            ):
                sines, record = read_fit(folder)
                return None, sines, record, True
        except (InputError, OSError, ValueError, KeyError, TypeError, AttributeError):
            pass
    result = fit(height, bake, scene, progress=progress, **settings)
    record = result.record()
    if folder is not None:
        write_fit(result, folder, input_info={"key": key})
    return result, result.horizon, record, False
