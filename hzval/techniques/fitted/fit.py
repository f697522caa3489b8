"""The best horizon map: the eight channels fitted to the truth's visibility with Dr.Jit's AD.

The baked horizon map is one estimate of what eight sines a texel should
hold; the map that minimises mean ``|F - V|`` against the truth is the
representation's floor (what eight directions, linear interpolation between
them and one ``k`` ramp can do), and ``baked - fitted`` is what the bake
loses. :func:`fit` finds it.

The design in full: docs/internals.md, "hzval.techniques.fitted.fit".
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from dataclasses import dataclass, field

import numpy as np
from tqdm import tqdm

from hzval.core import backend
from hzval.core.backend import dr, mi
from hzval.core.errors import InputError
from hzval.io import storage as hz_storage
from hzval.scene import lookup
from hzval.techniques import horizon
from hzval.techniques.fitted import guard as fit_guard
from hzval.techniques.fitted import model as fit_model
from hzval.techniques.fitted import training as fitted_training

__all__ = [
    "CHARBONNIER_EPS",
    "BATCH_LIGHTS",
    "LEARNING_RATE",
    "TOLERANCE",
    "MAX_EPOCHS",
    "HALVINGS",
    "MAX_K",
    "PRIOR",
    "CONSTRAIN",
    "CONSTRAINT_FLOOR",
    "FitResult",
    "fit",
    "guarded",
    "truths",
]
#: ``eps`` of the Charbonnier loss (module docstring).
CHARBONNIER_EPS = fit_model.CHARBONNIER_EPS
#: Lights per Adam step.
BATCH_LIGHTS = fit_model.BATCH_LIGHTS
#: Adam's learning rate on the sines (and on log k).
LEARNING_RATE = 0.02
#: Relative improvement of an epoch's loss below which the fit counts as converged.
TOLERANCE = 5e-3
MAX_EPOCHS = 60
#: Plateaus (learning rate halved at each) after which the fit has converged.
HALVINGS = fit_model.HALVINGS
#: The largest k that ``fit_k`` may reach (the tradeoff's golden-section search's bound).
MAX_K = 128.0
#: Weight of the pull toward the baked map, ``PRIOR * mean |p - p_baked|`` over every sine (0: none).
#: Where the training lights leave a sine free (a horizon between two training elevations), the
#: Charbonnier term's gradient is 0 or tiny and Adam's momentum carries it off; on lights between
#: the training elevations that cost the fit: at the default sweep (elevation 30, 256 x 256), without
#: the pull, fabric's fitted |F - V| was 1.04x the baked map's and ridges' 1.16x; with 0.05 / 0.1
#: fabric's 0.86x / 0.80x (its training error 0.021 / 0.026 instead of 0.0185).
PRIOR = 0.1
#: The step of the per-light weights (:func:`hzval.techniques.fitted.model.reweight`): a light 10 %
#: worse than the bake gains 0.1 x this
#: weight an epoch (0: the plain mean over lights).
CONSTRAIN = 2.0
#: The smallest baked loss a light's excess is relative to (a light the bake gets all but exactly right).
CONSTRAINT_FLOOR = fit_model.CONSTRAINT_FLOOR


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
        return {
            "format": "hzval fit 1",
            "k": self.k,
            "fit_k": self.fit_k,
            "storage": self.storage,
            **fit_model.run_record(self, "straight-through clamp"),
            "settings": self.settings,
            "conventions": "horizon0/1 as hzval bake writes them: channel c (azimuth 45 c deg, "
            "counterclockwise from +x) in layer c // 4; sines in [0, 1]",
        }


class _Model(fit_model.LightBatches):
    """The horizon technique with its horizon texture replaced by differentiable parameters.

    It is a :class:`hzval.techniques.fitted.model.LightBatches`: the lights' channel weights are the
    technique's own, ``_channel_weights``, of each light's direction.
    """

    def __init__(self, scene, bake, k: float, storage: str, V_list: list[np.ndarray]):
        self.scene = fitted_training.fit_scene(scene)
        self.ap = horizon.Horizon(self.scene, bake, None, k=k)
        if set(self.ap._slots) != {horizon.HORIZON_SLOT}:
            raise AssertionError("the fit's technique must hold the horizon channels alone")
        self.texture = self.ap._texture.levels[0]
        self.storage = hz_storage.get(storage)
        self.rows, self.cols = self.ap.rows, self.ap.cols
        self.P, self.spp = self.ap.pixels, self.ap.spp
        self.k = self.ap._k
        self.setup(V_list)

    def set_parameters(self, p, logk=None) -> None:
        """Upload the parameters: the stored map's values, with the parameters' gradient."""
        if self.storage.name == "float":
            value = p
        else:
            stored = self.storage.roundtrip(np.asarray(p, np.float32).reshape(self.rows, self.cols, -1))
            value = dr.replace_grad(mi.TensorXf(lookup.aligned(stored)), p)
        self.texture.set_tensor(value)
        self.k = dr.exp(logk) if logk is not None else self.ap._k

    def upload(self, values) -> None:
        self.texture.set_tensor(mi.TensorXf(lookup.aligned(np.asarray(values, np.float32))))

    def factor(self, lights, a: int, b: int):
        """Return the pixel means of F, light-major, of ``lights`` over pixels ``a..b``.

        The clamp is straight-through.
        """
        L = fit_model.light_vectors(lights)
        w = self.ap._channel_weights(L)
        li, sample = self.sample_lanes(len(lights), a, b)
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
        return self.pixel_mean(F)


def fit(
    height: np.ndarray,
    bake,
    scene,
    *,
    lights=fitted_training.TRAINING_LIGHTS,
    held_out=fitted_training.HELD_OUT_LIGHTS,
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
    """Fit a bake's horizon map to the truth by Dr.Jit's automatic differentiation.

    The differentiation runs through the horizon technique's own lookup and factor (module docstring;
    docs/fit.md).

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
    lights = fitted_training.parse_lights(lights) if isinstance(lights, str) else tuple(lights)
    if isinstance(held_out, str):
        held_out = fitted_training.parse_lights(held_out, "held_out") if held_out.strip() else ()
    held_out = tuple(held_out)
    stored = hz_storage.get(storage)
    if not (math.isfinite(k) and k > 0):
        raise InputError("--k", f"must be a positive number, got {k}")
    rows, cols = height.shape
    # the guard holds the bake's |F - V| per pixel and training light beside V: as much again
    fitted_training.check_fits(
        "HEIGHT", rows, cols, scene.spp, len(lights) * (2 if guard is not None else 1) + len(held_out), scene
    )
    train = dataclasses.replace(
        scene, spp=min(scene.spp, int(train_spp or fitted_training.training_spp(scene.spp, rows * cols)))
    )
    t0, c0 = time.perf_counter(), time.process_time()
    V_train, V_held = truths(train, scene, height, lights, held_out, progress)
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
                fitted_training.light_errors(s, bake, baked_stored, ls, V, k),
                fitted_training.light_errors(s, bake, fitted, ls, V, k_fit),
            )
            mae[name] = {
                "baked": float(np.mean(before)),
                "fitted": float(np.mean(after)),
                "lights_worse": int(sum(a > b for a, b in zip(after, before))),
                "per_light": [
                    {"elevation_deg": e, "azimuth_deg": az, "baked": b, "fitted": a}
                    for (e, az), b, a in zip(ls, before, after)
                ],
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
    """Return the optimiser's map guarded against the baked map, on the training lights.

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
        model.k = k if baked else k_fit  # read as the generator runs, which is before the next call
        return model.errors(sines, lights, V)

    return fit_guard.guard(
        stored.roundtrip(bake.horizon),
        fitted,
        errors,
        bake.params.boundary,
        cell=4 if blocks else 1,
        tolerance=tolerance,
        finish=stored.roundtrip if blocks else None,
    )


def truths(train, scene, height, lights, held_out, progress: bool):
    """Return the truth's V for the training lights and the held-out ones, with a progress bar.

    The training lights' V is at ``train``'s samples, the held-out ones' at ``scene``'s.
    """
    with tqdm(
        total=len(lights) + len(held_out),
        desc="truth",
        unit="light",
        disable=not progress,
        file=sys.stderr,
        leave=False,
    ) as bar:
        return fitted_training.visibility(train, height, lights, bar), fitted_training.visibility(
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
    """Run Adam from the baked map (module docstring).

    Return ``(stored sines, k, loss and seconds per epoch, steps, converged)``. ``constrain``: the step of the
    per-light weights (:func:`hzval.techniques.fitted.model.reweight`; 0: none).
    """
    model = _Model(scene, bake, k, storage, V_list)
    stored = hz_storage.get(storage)
    baked = None
    if constrain > 0:
        model.k = k
        baked = model.light_losses(stored.roundtrip(bake.horizon), lights, V_list)

    def project(opt) -> None:
        fit_model.clip_unit(opt, "h")
        if fit_k:
            opt["logk"] = dr.clip(opt["logk"], 0.0, math.log(MAX_K))

    opt, curve, times, steps, converged = fit_model.optimise(
        model,
        {"h": mi.TensorXf(lookup.aligned(np.clip(bake.horizon, 0.0, 1.0)))},
        lights,
        set_parameters=lambda opt: model.set_parameters(opt["h"], opt["logk"] if fit_k else None),
        project=project,
        baked_losses=baked,
        extra={"logk": mi.Float(math.log(k))} if fit_k else None,
        tolerance=tolerance,
        max_epochs=max_epochs,
        lr=lr,
        prior=prior,
        constrain=constrain,
        seed=scene.seed,
        progress=progress,
    )
    h = np.asarray(opt["h"], np.float32).reshape(model.rows, model.cols, -1)
    k_fit = float(np.exp(np.asarray(opt["logk"])[0])) if fit_k else float(k)
    return stored.roundtrip(h), k_fit, curve, times, steps, converged
