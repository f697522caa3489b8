"""What every fit shares: the training lights in batches through a technique's factor, and Adam.

A fit's forward model (:class:`LightBatches`) renders the pixel means of a technique's ``F`` for a
group of lights in one kernel and compares them with the truth's ``V``; :func:`optimise` runs Adam
over its parameters in shuffled batches of lights, with the pull toward the bake and the per-light
weights of docs/fit.md. The horizon fit (:mod:`hzval.techniques.fitted.fit`) and the fit of a
per-pixel technique's textures (:mod:`hzval.techniques.fitted.textures`) are each a subclass and a
start.
"""

from __future__ import annotations

import sys
import time
from typing import Callable

import numpy as np
from tqdm import tqdm

from hzval.core import conventions as cv
from hzval.core.backend import dr, mi
from hzval.scene import lookup
from hzval.techniques.fitted import training as fitted_training

__all__ = [
    "CHARBONNIER_EPS",
    "BATCH_LIGHTS",
    "HALVINGS",
    "CONSTRAINT_FLOOR",
    "LightBatches",
    "light_vectors",
    "optimise",
    "reweight",
    "clip_unit",
    "run_record",
]

#: ``eps`` of the Charbonnier loss (docs/fit.md): a sixteenth of the 16-spp truth's V step.
CHARBONNIER_EPS = 1.0 / 256.0
#: Lights per Adam step.
BATCH_LIGHTS = 8
#: Plateaus (learning rate halved at each) after which a fit has converged.
HALVINGS = 3
#: The smallest baked loss a light's excess is relative to (a light the bake gets all but exactly right).
CONSTRAINT_FLOOR = 1e-4


def light_vectors(lights):
    """``(elevation, azimuth)`` pairs as one :class:`mitsuba.Vector3f` of unit directions toward them."""
    d = np.array([cv.light_direction(az, e) for e, az in lights], np.float32)
    return mi.Vector3f(*(mi.Float(d[:, i].copy()) for i in range(3)))


class LightBatches:
    """A technique's pixel-mean ``F`` over groups of lights, and its loss against the truth's ``V``.

    Lane ``i`` of a group's kernel is sample ``i % n`` of light ``i // n``; a group holds at most
    :data:`hzval.techniques.fitted.training.BAND_SAMPLES` lanes (one light in pixel bands beyond
    that), which bounds the AD graph's memory. A subclass sets ``rows``, ``cols``, ``P`` (pixels) and
    ``spp`` before calling :meth:`setup`, and gives :meth:`factor` and :meth:`upload`.
    """

    def setup(self, V_list: list[np.ndarray], masks: list[np.ndarray] | None = None) -> None:
        """Set up the groups, bands and the truth's ``V`` of every light, one copy, light-major.

        ``masks``: per light, the pixels the loss counts (``None``: all).
        """
        self.group = max(1, fitted_training.BAND_SAMPLES // (self.P * self.spp))
        band = max(1, fitted_training.BAND_SAMPLES // self.spp)
        self.bands = [(a, min(self.P, a + band)) for a in range(0, self.P, band)]
        V = lookup.aligned_empty(len(V_list) * self.P)
        for i, v in enumerate(V_list):  # one copy, not a stack and then an aligned copy
            V[i * self.P : (i + 1) * self.P] = np.asarray(v, np.float32).ravel()
        self.V = mi.Float(V)
        self.masks, self.W = masks, None
        if masks is not None:
            W = lookup.aligned_empty(len(masks) * self.P)
            for i, m in enumerate(masks):
                W[i * self.P : (i + 1) * self.P] = np.asarray(m, np.float32).ravel()
            self.W = mi.Float(W)

    def factor(self, lights, a: int, b: int):
        """Return the pixel means of ``F`` over pixels ``a..b`` of each of ``lights``, light-major."""
        raise NotImplementedError

    def upload(self, values) -> None:
        """Make ``values`` (NumPy, as stored) what :meth:`factor` reads, without gradients."""
        raise NotImplementedError

    def sample_lanes(self, count: int, a: int, b: int):
        """``(light index, sample index)`` of the lanes of ``count`` lights over pixels ``a..b``."""
        n = (b - a) * self.spp
        lane = dr.arange(mi.UInt32, count * n)
        li = lane // n
        return li, lane - li * n + a * self.spp

    def pixel_mean(self, F):
        """Return the mean of ``F`` over each pixel's consecutive samples."""
        return dr.block_sum(F, self.spp) * (1.0 / self.spp) if self.spp > 1 else F

    def errors(self, values, lights, V_list):
        """Return ``|F - V|`` ``(rows, cols)`` float32 of ``values`` as stored, per light of ``lights``.

        ``V`` is the one the lights were given in; the errors are computed without gradients.
        """
        with dr.suspend_grad():
            self.upload(values)
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

    def light_losses(self, values, lights, V_list) -> np.ndarray:
        """Return the Charbonnier loss of each light (its pixels' mean) of ``values`` as stored."""
        eps = CHARBONNIER_EPS
        masks = self.masks if self.masks is not None else [1.0] * len(lights)
        return np.array(
            [
                float(np.mean((np.sqrt(e.astype(np.float64) ** 2 + eps**2) - eps) * m))
                for e, m in zip(self.errors(values, lights, V_list), masks)
            ]
        )

    def backward(self, indices, lights, scale: float, weights=None, per_light=None) -> float:
        """Accumulate ``scale *`` the gradient of the summed loss of lights ``indices``.

        ``indices`` index into ``lights`` and the V they were given in; each light's loss is multiplied by
        ``weights[i]`` if given. Return the unweighted loss (a float) and put each light's into
        ``per_light[i]`` if given.
        """
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
                if self.W is not None:
                    pixel = pixel * dr.gather(mi.Float, self.W, at)
                dr.eval(pixel)
                sums = np.asarray(dr.block_sum(dr.detach(pixel), m), np.float64)  # one per light of the group
                if per_light is not None:
                    per_light[group] += sums
                if weights is not None:
                    pixel = pixel * dr.gather(mi.Float, mi.Float(np.asarray(weights, np.float32)[group]), li)
                dr.backward(dr.sum(pixel) * scale)
                total += float(sums.sum())
        return total


def reweight(weights: np.ndarray, losses: np.ndarray, baked: np.ndarray, step: float) -> np.ndarray:
    """Return the per-light weights ``1 + lambda`` after an epoch.

    Each light's multiplier ``lambda`` is raised by ``step`` times its relative excess over the baked loss
    (clipped to [-1, 1]; its floor :data:`CONSTRAINT_FLOOR`) and kept >= 0 (dual ascent on "no training light
    worse than the bake").

    Examples
    --------
    >>> import numpy as np
    >>> [float(w) for w in reweight(np.ones(2), np.array([0.11, 0.09]), np.array([0.1, 0.1]), 2.0)]
    [1.2000000476837158, 1.0]
    """
    excess = np.clip((losses - baked) / np.maximum(baked, CONSTRAINT_FLOOR), -1.0, 1.0)
    return (1.0 + np.maximum(0.0, weights - 1.0 + step * excess)).astype(np.float32)


def optimise(
    model: LightBatches,
    start: dict,
    lights,
    *,
    set_parameters: Callable,
    project: Callable,
    baked_losses: np.ndarray | None,
    extra: dict | None = None,
    tolerance: float,
    max_epochs: int,
    lr: float,
    prior: float,
    constrain: float,
    seed: int,
    progress: bool,
):
    """Adam (:class:`mitsuba.ad.Adam`) over ``start``'s tensors from their values (docs/fit.md).

    Parameters
    ----------
    model : LightBatches
        The forward model and its truth.
    start : dict of str to mitsuba.TensorXf
        The parameters' start, which the pull ``prior * mean |p - start|`` of each holds to.
    lights : sequence of (float, float)
        The training lights.
    set_parameters : callable
        ``set_parameters(opt)``: upload the optimiser's parameters into the model.
    project : callable
        ``project(opt)``: back into the stored range after every step.
    baked_losses : numpy.ndarray or None
        Each light's loss of the bake (:meth:`LightBatches.light_losses`): the per-light weights'
        reference (``None`` with ``constrain`` 0).
    extra : dict, optional
        Further parameters, not pulled (the horizon fit's ``log k``).
    tolerance, max_epochs, lr, prior, constrain : float, int, float, float, float
        When to stop, the step, the pull and the per-light weights' step (0: the plain mean).
    seed : int
        The shuffles' seed.
    progress : bool
        Show a progress bar.

    Returns
    -------
    tuple
        ``(opt, loss per epoch, seconds per epoch, steps, converged)``.
    """
    opt = mi.ad.Adam(lr=lr)
    for key, value in start.items():
        opt[key] = type(value)(value)
    for key, value in (extra or {}).items():
        opt[key] = value
    rng = np.random.default_rng(seed)
    norm = 1.0 / (model.P * len(lights))
    curve, times, steps, calm, converged = [], [], 0, 0, False
    weights = np.ones(len(lights), np.float32) if constrain > 0 else None
    bar = tqdm(
        range(max_epochs), desc="fit", unit="epoch", disable=not progress, file=sys.stderr, leave=False
    )
    for _ in bar:
        t0, total, per = time.perf_counter(), 0.0, np.zeros(len(lights))
        order = rng.permutation(len(lights))
        for first in range(0, len(order), BATCH_LIGHTS):
            batch = order[first : first + BATCH_LIGHTS]
            set_parameters(opt)
            total += model.backward(batch, lights, norm, weights, per) * norm
            for key, value in start.items() if prior > 0 else ():
                # where the training lights leave a parameter free, it stays the bake's (docs/fit.md)
                pull = prior * dr.mean(dr.abs(opt[key].array - value.array), axis=None)
                dr.backward(pull)
                total += float(np.asarray(dr.detach(pull)).ravel()[0]) * len(batch) / len(lights)
            opt.step()
            project(opt)
            steps += 1
        if weights is not None:
            weights = reweight(weights, per / model.P, baked_losses, constrain)
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
    return opt, curve, times, steps, converged


def clip_unit(opt, key: str) -> None:
    """Keep ``opt[key]`` in [0, 1]."""
    opt[key] = dr.clip(opt[key], 0.0, 1.0)


def run_record(result, through: str) -> dict:
    """Return what every ``fit.json`` records of a fit's run.

    That is the errors before and after and their ratio, the loss per epoch (``through``: what its gradient
    passes straight through), the epochs, steps, seconds and lights of ``result`` (a fit's result dataclass).
    """
    m = result.mae
    return {
        "mae": m,
        "fitted_over_baked": {w: (m[w]["fitted"] / m[w]["baked"] if m[w]["baked"] > 0 else None) for w in m},
        "loss": {
            "kind": f"Charbonnier sqrt(d^2 + eps^2) - eps, eps = {CHARBONNIER_EPS:g}; {through}",
            "per_epoch": result.loss,
            "epoch_seconds": result.epoch_seconds,
        },
        "epochs": result.epochs,
        "steps": result.steps,
        "converged": result.converged,
        "seconds": result.seconds,
        "lights": {
            "training": [{"elevation_deg": e, "azimuth_deg": a} for e, a in result.lights],
            "held_out": [{"elevation_deg": e, "azimuth_deg": a} for e, a in result.held_out],
        },
    }
