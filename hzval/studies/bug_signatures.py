"""What each tangent-frame bug looks like on a model with mirrored UVs, for ``hzval models``.

See docs/models.md, "Tangent-bug signatures".

A user whose own engine shows a visibility-difference picture like one of these can name the cause.
Each case is a model with both handedness signs, seen so that both show:

``cube``
    The built-in cube (Figure 5.1; its -x and -z faces mirrored), seen from azimuth 150: the
    mirrored -x face on the left, the unmirrored +y face on the right.
``mirrored-sphere``
    :func:`hzval.geometry.model.mirrored_sphere` (the -y half's UVs the +y half's mirrored), seen from +x:
    the mirror meridian down the middle, the mirrored half on the right.

The truth is traced once per case (it never depends on the bug); the lead technique's ``F`` is
rendered with every bug of :data:`hzval.geometry.tangent_bugs.BUGS`
(:func:`hzval.pipeline.bug_match.bug_factors`:
only the techniques' frames change), at the camera's samples (the flat surface, as an engine without
parallax mapping reads it) and at the truth's own hits (perfect parallax: what the bug does to the
lookup itself, without the parallax error that hides it on a steep relief). The scene's lights are turned to
come from beside the camera
onto the mirrored part (:data:`CASES`). Per case and bug: the mean ``|F - V|`` over the seen pixels
whose samples are all mirrored (``w = -1``) and all unmirrored, per light and over the lights, and
the ratio of the mirrored mean to the correct frames' (``mirrored_ratio``; at the truth's hits
``mirrored_perfect_parallax_ratio``). The picture is ``F - V`` at the light where
the bugs move ``F`` most (the mean over the bugs of ``|F_bug - F_none|``).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from hzval.geometry import model, tangent_bugs
from hzval.pipeline import bug_match
from hzval.report import figures
from hzval.scene import spec as sc
from hzval.truth.model import ModelTruth

__all__ = ["CASES", "measure", "run", "page_context"]

#: Case name -> (built-in shape, the camera's azimuth and the lights' centre azimuth in degrees (the
#: light's convention), uv_scale: the sphere repeats the texture three times a half, about a
#: texture width per radius). The lights come from 90 degrees beside the camera, onto the mirrored
#: part: lights near the camera hide the shadows behind their casters (the camera sees the lit
#: faces), which makes every frame look right.
CASES: dict[str, tuple[str, float, float, float]] = {
    "cube": ("cube", 150.0, 240.0, 1.0),
    "mirrored-sphere": ("mirrored-sphere", 0.0, -90.0, 3.0),
}


def _case_scene(scene, shape: str, view_azimuth: float, light_azimuth: float, uv_scale: float):
    """Return ``scene`` on ``shape`` (bug ``none``) in the models' perspective view from ``view_azimuth``.

    Its lights are turned by ``light_azimuth``.
    """
    mesh = dataclasses.replace(scene.mesh, shape=shape, uv_scale=uv_scale, tangent_bug="none")
    cam = dataclasses.replace(sc.MODEL_CAMERA, azimuth_deg=view_azimuth, resolution=scene.camera.resolution)
    light = dataclasses.replace(
        scene.light, azimuths_deg=tuple(a + light_azimuth for a in scene.light.azimuths_deg)
    )
    effects = tuple(e for e in scene.effects if e != "reflection_occlusion")  # only F and V are compared
    return dataclasses.replace(scene, mesh=mesh, camera=cam, light=light, effects=effects).validate()


def _mean(e: np.ndarray, mask: np.ndarray) -> float | None:
    return float(e[mask].mean()) if mask.any() else None


def measure(
    scene,
    height: np.ndarray,
    lead: str,
    shape: str,
    view_azimuth: float,
    light_azimuth: float,
    uv_scale: float = 1.0,
) -> tuple[dict, dict]:
    """Measure one case, returning ``(record, maps)``.

    ``maps[bug]`` is ``F - V`` ``(H, W)`` (NaN unseen) at the signature light (module docstring).
    """
    sc = _case_scene(scene, shape, view_azimuth, light_azimuth, uv_scale)
    truth = ModelTruth(sc, height, model.load(shape, uv_scale=uv_scale))
    vis = [truth.render(az).layers["visibility"] for az in sc.light.azimuths_deg]
    mirrored, plain = truth.handedness < 0, truth.handedness > 0
    factors = {bug: bug_match.bug_factors(sc, height, truth, bug, lead) for bug in tangent_bugs.NAMES}
    perfect = {
        bug: bug_match.bug_factors(sc, height, truth, bug, lead, at="truth") for bug in tangent_bugs.NAMES
    }
    moved = [
        np.mean([np.abs(factors[b][i] - factors["none"][i])[truth.seen].mean() for b in factors])
        for i in range(len(vis))
    ]
    k = int(np.argmax(moved))
    bugs = {}
    for bug, fs in factors.items():
        err = [np.abs(f - v) for f, v in zip(fs, vis)]
        at_hits = np.mean([np.abs(f - v) for f, v in zip(perfect[bug], vis)], axis=0)
        bugs[bug] = {
            "mirrored": _mean(np.mean(err, axis=0), mirrored),
            "mirrored_perfect_parallax": _mean(at_hits, mirrored),
            "unmirrored": _mean(np.mean(err, axis=0), plain),
            "mirrored_per_light": [_mean(e, mirrored) for e in err],
            "unmirrored_per_light": [_mean(e, plain) for e in err],
        }
    for key in ("mirrored", "mirrored_perfect_parallax"):
        base = bugs["none"][key]
        for rec in bugs.values():
            rec[f"{key}_ratio"] = rec[key] / base if base and rec[key] is not None else None
    maps = {bug: np.where(truth.seen, fs[k] - vis[k], np.nan) for bug, fs in factors.items()}
    record = {
        "shape": shape,
        "uv_scale": uv_scale,
        "view_azimuth_deg": view_azimuth,
        "light_azimuth_deg": light_azimuth,
        "azimuths_deg": list(sc.light.azimuths_deg),
        "elevation_deg": sc.light.elevation_deg,
        "signature_azimuth_deg": sc.light.azimuths_deg[k],
        "mirrored_pixels": int(mirrored.sum()),
        "unmirrored_pixels": int(plain.sum()),
        "bugs": bugs,
    }
    return record, maps


def run(scene, height: np.ndarray, lead: str, out: Path, *, progress: bool = True) -> dict:
    """Measure every case of :data:`CASES` with ``lead`` and write ``out/plots/bugs.png``.

    Return the ``models.json`` ``bugs`` entry ``{technique, cases: {name: record}, figure}``.
    """
    cases, maps = {}, {}
    for name, (shape, az, light_az, uv_scale) in CASES.items():
        if progress:
            print(f"hzval models: tangent bugs on {name}", flush=True)
        cases[name], maps[name] = measure(scene, height, lead, shape, az, light_az, uv_scale)
    names = list(cases)
    figures.plot_signed_maps(
        out / "plots" / "bugs.png",
        [[maps[case][bug] for case in names] for bug in tangent_bugs.NAMES],
        tangent_bugs.NAMES,
        [f"{case}, light {cases[case]['signature_azimuth_deg']:g} deg" for case in names],
        notes=[
            [_mirrored_note(cases[case]["bugs"][bug]["mirrored_ratio"]) for case in names]
            for bug in tangent_bugs.NAMES
        ],
        label=f"{lead} F - V (blue: lit too much)",
    )
    return {"technique": lead, "cases": cases, "figure": "plots/bugs.png"}


def _mirrored_note(ratio: float | None) -> str | None:
    return None if ratio is None else f"mirrored {ratio:.2f}x"


def page_context(bugs: dict) -> dict:
    """Return the study page's section (``models.html.j2``).

    It holds the figure and the mirrored and unmirrored means of every case and bug, formatted.
    """

    def f4(c):
        return "-" if c is None else f"{c:.4f}"

    keys = (
        "mirrored",
        "unmirrored",
        "mirrored_ratio",
        "mirrored_perfect_parallax",
        "mirrored_perfect_parallax_ratio",
    )
    return {
        "technique": bugs["technique"],
        "figure": bugs["figure"],
        "rows": [
            {"case": case, "bug": bug, "cells": [f4(r[k]) for k in keys]}
            for case, rec in bugs["cases"].items()
            for bug, r in rec["bugs"].items()
        ],
    }
