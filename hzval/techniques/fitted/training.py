"""What a fit trains on and what it costs.

That is its lights (:func:`parse_lights`), its samples, its scene (shadows only, the top view), the truth's
visibility of every light from one set-up, the errors of a map on them, and the memory it needs
(:func:`estimate_bytes`, :func:`check_fits`).
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from hzval.core import budget, resources
from hzval.core.errors import InputError
from hzval.scene import lookup
from hzval.scene import spec as sc
from hzval.scene.camera import Camera
from hzval.techniques import horizon
from hzval.truth import memory
from hzval.truth import plane as truth

__all__ = [
    "check_held_out",
    "TRAINING_LIGHTS",
    "HELD_OUT_LIGHTS",
    "TRAINING_SAMPLES",
    "BAND_SAMPLES",
    "parse_lights",
    "training_spp",
    "fit_scene",
    "visibility",
    "estimate_bytes",
    "check_fits",
    "light_errors",
    "mean_error",
]

#: The default training lights, ``ELEVATIONS@AZIMUTHS`` (:func:`parse_lights`).
TRAINING_LIGHTS = "10,20,40,60@0:345:15"
#: The default held-out lights: scored, never trained on.
HELD_OUT_LIGHTS = "25@-52.5:52.5:15"
#: Samples per training light (truth and forward model): a fit's time is its samples' (the truth's
#: shadow rays, the kernel's lanes), so the training lights get ``TRAINING_SAMPLES / pixels`` samples a
#: pixel, at most the scene's and at least 1 (:func:`training_spp`): 16 at 256 x 256, 4 at 512 x 512.
#: 4 stratified samples a pixel still cover a texel's bilinear footprint; the held-out lights are
#: scored at the scene's own samples.
TRAINING_SAMPLES = 1 << 20
#: Samples per band of the forward model: bounds the AD graph's memory.
BAND_SAMPLES = 1 << 23


def check_held_out(lights, held_out) -> None:
    """Refuse held-out lights that are training lights too (an azimuth taken modulo 360).

    Their score would be the training score under the held-out name. The error is one line naming
    ``--held-out``.

    Examples
    --------
    >>> check_held_out(((30.0, 0.0),), ((30.0, 15.0),))
    >>> check_held_out(((30.0, 0.0),), ((30.0, 360.0),))
    Traceback (most recent call last):
    ...
    hzval.core.errors.InputError: --held-out: 1 of its 1 lights are training lights too (30@360): a held-out score comes from lights the fit did not see
    """  # noqa: E501

    def key(light):
        return (round(float(light[0]), 9), round(float(light[1]) % 360.0, 9))

    seen = {key(light) for light in lights}
    both = [light for light in held_out if key(light) in seen]
    if both:
        shown = ", ".join(f"{e:g}@{a:g}" for e, a in both[:4]) + (" ..." if len(both) > 4 else "")
        raise InputError(
            "--held-out",
            f"{len(both)} of its {len(held_out)} lights are training lights too ({shown}): a held-out "
            "score comes from lights the fit did not see",
        )


def parse_lights(spec: str, what: str = "--lights") -> tuple[tuple[float, float], ...]:
    """Return the training (or held-out) lights of a spec.

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
    """Return the samples per pixel of the training lights' truth and forward model.

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
    """Return the scene the fit renders, from a sweep's.

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
    light = dataclasses.replace(scene.light, kind="hard", radius_deg=0.0)
    return dataclasses.replace(
        scene, effects=("shadow",), light=light, camera=Camera(), lookup=lookup.Lookup()
    )


def visibility(scene, height: np.ndarray, lights, bar=None) -> list[np.ndarray]:
    """Return the truth's visibility of each light, from one set-up.

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
    """Return the fit's estimated peak memory.

    The truth's ``V`` of every light, beside the larger of the truth's own peak while it renders
    (:func:`hzval.truth.memory.estimate_peak_bytes` of the fit's scene, when ``scene`` is given) and
    the optimisation's (:func:`hzval.core.budget.fit_bytes`).

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
    render = 0
    if scene is not None:
        render = memory.estimate_peak_bytes(dataclasses.replace(fit_scene(scene), spp=spp), rows, cols)
    return budget.fit_bytes(P, spp, lights, band, render)


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
