"""The built-in materials: procedural, exactly tileable height maps with their albedo.

Each material is a module of this package that defines ``MATERIAL``, a
:class:`Material`; :data:`REGISTRY` maps its name to ``"module:attribute"``
and imports it only when it is asked for, as Mitsuba's plugins and
:data:`hzval.techniques.registry.REGISTRY` do. Adding a material is a module and a
line here; nothing else names it (``hzval materials`` lists them, ``hzval
sweep --material NAME`` and ``[material] height = "NAME"`` use them, ``hzval
suite`` runs them all).

The set follows Lengyel's Figure 5.2 - a variety of shapes, because whether a
technique holds depends on the shape of the surface: steep-walled blocks
(bricks), rounded domes (cobblestones), dense small bumps (gravel), a
periodic over-under weave (fabric), flat plates with grooves and small
domes (panels), long grooves with grain (planks), fractal ridges with
nothing outside (ridges, ``open``), and thin tall spikes whose shadows
reach far beyond the horizon bake's radius (spikes, a hard case).

Conventions (docs/ARCHITECTURE.md): ``H[row, col]`` float32 in [0, 1], row 0
at the top; the albedo is linear RGB ``(rows, cols, 3)`` float32 (sRGB
colours decoded by :func:`hzval.core.srgb.decode`), or ``None`` for the
scene's constant albedo. A material's ``depth`` is the world height of
``H = 1`` in image widths, so its features keep their proportions at every
size: feature counts are fixed per period (fewer where a feature would be
narrower than a few texels) and only the finest grain is in texels.
"""

from __future__ import annotations

import functools
import importlib
from dataclasses import dataclass
from typing import Callable

import numpy as np

__all__ = [
    "Material",
    "Generated",
    "REGISTRY",
    "DEFAULT",
    "DEFAULT_SIZE",
    "names",
    "get",
    "is_builtin",
    "generate",
]

#: Side of a built-in material in texels unless a size is asked for.
DEFAULT_SIZE = 512
#: The material every command uses when given none.
DEFAULT = "bricks"

#: name -> "module:attribute" of its :class:`Material`; the order is the listing's.
REGISTRY: dict[str, str] = {
    "bricks": "hzval.materials.bricks:MATERIAL",
    "cobblestones": "hzval.materials.cobblestones:MATERIAL",
    "gravel": "hzval.materials.gravel:MATERIAL",
    "fabric": "hzval.materials.fabric:MATERIAL",
    "panels": "hzval.materials.panels:MATERIAL",
    "planks": "hzval.materials.planks:MATERIAL",
    "ridges": "hzval.materials.ridges:MATERIAL",
    "spikes": "hzval.materials.spikes:MATERIAL",
}


@dataclass(frozen=True)
class Generated:
    """A generated material: height in [0, 1] and linear albedo, both float32 and read-only.

    The height is ``(rows, cols)``, the albedo ``(rows, cols, 3)`` or ``None`` (the scene's constant); both
    are read-only because they are cached.
    """

    height: np.ndarray
    albedo: np.ndarray | None


@dataclass(frozen=True)
class Material:
    """One built-in material.

    ``make(shape, seed)`` returns ``(height, albedo)`` for ``shape = (rows,
    cols)``; equal arguments give equal arrays (on one machine: NumPy's
    vectorised maths may round the last bit differently on another CPU). ``depth`` and
    ``boundary`` are what a scene uses unless it says otherwise.
    """

    name: str
    label: str
    summary: str
    depth: float
    make: Callable[[tuple[int, int], int], tuple[np.ndarray, np.ndarray | None]]
    boundary: str = "wrap"
    min_size: int = 8


def names() -> list[str]:
    """Return the built-in materials' names, in the registry's order."""
    return list(REGISTRY)


def is_builtin(name: str | None) -> bool:
    """Whether ``name`` (a ``[material] height`` value) names a built-in material."""
    return isinstance(name, str) and name in REGISTRY


def get(name: str) -> Material:
    """Return the material registered as ``name``; ``KeyError`` names the known ones."""
    try:
        module, attribute = REGISTRY[name].split(":")
    except KeyError:
        raise KeyError(f"no built-in material {name!r}; choose from {', '.join(REGISTRY)}") from None
    return getattr(importlib.import_module(module), attribute)


@functools.lru_cache(maxsize=2)  # one scene's height and albedo, and one more
def _generate(name: str, shape: tuple[int, int], seed: int) -> Generated:
    height, albedo = get(name).make(shape, seed)
    height = np.ascontiguousarray(height, np.float32)
    height.setflags(write=False)
    if albedo is not None:
        albedo = np.ascontiguousarray(albedo, np.float32)
        albedo.setflags(write=False)
    return Generated(height, albedo)


def generate(name: str, size: int | tuple[int, int] = DEFAULT_SIZE, seed: int = 1) -> Generated:
    """Return material ``name`` at ``size`` (``n`` or ``(rows, cols)``).

    The last few are cached, so the height and the albedo of one scene are generated once.
    """
    shape = (int(size), int(size)) if np.ndim(size) == 0 else tuple(int(s) for s in size)
    m = get(name)
    if min(shape) < m.min_size:
        raise ValueError(
            f"{name}: size must be at least {m.min_size}x{m.min_size} texels, got {shape[1]}x{shape[0]}"
        )
    return _generate(name, shape, int(seed))
