"""Techniques as plug-ins: the interface every self-shadowing technique implements, and its registry.

A *technique* renders the flat surface's frame for one light from what a
real-time renderer would have (the bake's textures, the height map), and
hzval scores that frame against the truth. The sweep, the comparison, the
report, the regression check, the tradeoff and the command line all loop
over :data:`REGISTRY`; none of them names a technique. Adding one is a
module with a :class:`Technique` subclass and one line here, as Mitsuba
registers its plugins by name and colour-science maps method names to
functions (``colour.DELTA_E_METHODS``). docs/ARCHITECTURE.md, "Adding a
technique", walks through ``pom`` as the example.

The interface
    Class attributes: ``name`` (the registry key, also ``--techniques``),
    ``label`` and ``summary`` (for the report), ``file_stem`` (its files in a
    frame folder: ``<stem>.exr``, ``<stem>_factor.exr``, ``<stem>_flip.png``,
    ...), ``needs`` (effects a scene must declare for the technique to apply:
    every shadowing technique needs ``shadow``), ``not_modelled`` (declarable
    effects it leaves out). :meth:`Technique.build` makes one from a
    :class:`Context`; :meth:`Technique.render` returns a
    :class:`hzval.scene.spec.Frame` whose ``layers["factor"]`` is the pixel mean of
    its shadow factor ``F`` in [0, 1]; ``simulated`` and ``parameters`` go to
    ``metrics.json``. Optional hooks: command-line options
    (:meth:`Technique.add_arguments`, :meth:`Technique.settings_from_args`),
    the images the check guards (:meth:`Technique.check_variants`) and the
    settings the tradeoff measures (:meth:`Technique.tradeoff_variants`,
    :meth:`Technique.storage_bytes`).

The registry maps names to ``"module:Class"`` and imports a technique only
when it is asked for, so this module imports none of them.
"""

from __future__ import annotations

import contextlib
import dataclasses
import importlib
from dataclasses import dataclass, field
from typing import Any, Callable, ClassVar

import numpy as np

from hzval.core.errors import InputError
from hzval.scene import lookup
from hzval.scene.spec import EFFECTS, Frame, Scene

__all__ = [
    "REGISTRY",
    "Technique",
    "Context",
    "Variant",
    "Unavailable",
    "get",
    "names",
    "defaults",
    "select",
    "bake_needs",
]

#: Every technique, by name, in the order the report shows them.
REGISTRY: dict[str, str] = {
    "horizon": "hzval.techniques.horizon:Horizon",
    "terrain": "hzval.techniques.terrain:TerrainShadow",
    "pom": "hzval.techniques.pom:RayMarchShadow",
    "horizon-gl": "hzval.techniques.gl.horizon_gl:HorizonGL",
    "pom-gl": "hzval.techniques.gl.horizon_gl:PomGL",
    "horizon-fit": "hzval.techniques.fitted.horizon_fit:FittedHorizon",
    "horizon-curved": "hzval.techniques.horizon_curved:CurvedHorizon",
    "microshadow-filament": "hzval.techniques.microshadow_filament:MicroshadowFilament",
    "microshadow-hdrp": "hzval.techniques.microshadow_hdrp:MicroshadowHDRP",
    "bent-cone": "hzval.techniques.bent_cone:BentCone",
    "ssbump": "hzval.techniques.ssbump:SSBump",
    "terminator": "hzval.techniques.terminator:Terminator",
    "microshadow-filament-fit": "hzval.techniques.fitted.perpixel_fit:FittedFilament",
    "microshadow-hdrp-fit": "hzval.techniques.fitted.perpixel_fit:FittedHDRP",
    "bent-cone-fit": "hzval.techniques.fitted.perpixel_fit:FittedBentCone",
    "ssbump-fit": "hzval.techniques.fitted.perpixel_fit:FittedSSBump",
}


class Unavailable(Exception):
    """The error :meth:`Technique.build` raises when this machine cannot run the technique.

    An example is no OpenGL context for the GL techniques. The message is one line saying what to install; the
    sweep skips the technique with it and goes on.
    """


@dataclass(frozen=True)
class Variant:
    """A named setting of a technique: keywords for :meth:`Technique.build`, and what to record.

    ``kind`` sorts tradeoff settings (``"technique"``: a setting of the
    technique itself; ``"bake"``: of the bake it reads); ``params`` is what
    ``tradeoff.json`` records of it (``steps`` for pom, ``storage`` for the
    horizon map's textures, ...); ``formerly``: the name its ``hzval check``
    reference had in an earlier release.
    """

    name: str
    settings: dict = field(default_factory=dict)
    params: dict = field(default_factory=dict)
    kind: str = "technique"
    #: A name the variant's check reference had before (read when there is none under ``name``).
    formerly: str | None = None


@dataclass
class Context:
    """What a technique is built from: the scene, the material and its bake.

    ``height``: the normalised height map ``(rows, cols)`` float32;
    ``bake``: its :class:`hzval.bake.maps.Bake`; ``albedo``: linear ``(rows,
    cols, 3)``. :meth:`shared` lets techniques share what they would each
    build (the unshadowed shading of :func:`hzval.techniques.surface.unshadowed`).
    ``points``: where the techniques read their textures, when not where the
    camera's rays meet their plane (:meth:`samples`): the truth's own hit
    points, for the factor at perfect parallax.
    """

    scene: Scene
    height: np.ndarray
    bake: Any
    albedo: np.ndarray
    points: lookup.Samples | None = None
    cache: Any = (
        None  # a folder where a technique may keep what it fits (hzval.techniques.fitted.horizon_fit)
    )
    _shared: dict = field(default_factory=dict, repr=False)

    def samples(self) -> lookup.Samples:
        """Return where every technique of the context reads its textures.

        See :func:`hzval.scene.lookup.samples_for`.
        """
        if self.points is not None:
            return self.points
        return lookup.samples_for(self.scene, *self.height.shape, self.height)

    def shared(self, key: str, make: Callable[[], Any]) -> Any:
        """Return the object stored under ``key``, made by ``make()`` the first time."""
        if key not in self._shared:
            self._shared[key] = make()
        return self._shared[key]


class Technique:
    """Base class of the techniques (module docstring). Subclasses set the class attributes."""

    name: ClassVar[str]
    label: ClassVar[str]
    summary: ClassVar[str] = ""
    file_stem: ClassVar[str]
    needs: ClassVar[tuple[str, ...]] = ("shadow",)
    not_modelled: ClassVar[tuple[str, ...]] = ("interreflection",)
    #: Whether a sweep without ``--techniques`` renders it (the GL techniques are opt-in).
    by_default: ClassVar[bool] = True
    #: Whether its factor turns with the tile: mirrored, turned a quarter or transposed with its light,
    #: the map gives the turned factor. False for a technique whose textures hold a basis that is not
    #: the square's (ssbump's three vectors are symmetric only about the tangent's x axis).
    square_symmetric: ClassVar[bool] = True
    #: Why the technique does not render on a model (``[mesh]``, :mod:`hzval.truth.model`), in one
    #: line; empty: it does, reading each sample's own tangent frame (:class:`hzval.scene.lookup.Samples`).
    not_on_models: ClassVar[str] = ""

    simulated: tuple[str, ...] = ()
    #: The command-line flag of each :meth:`build` setting (``{"steps": "--pom-steps"}``), which an
    #: error about that setting names (:func:`flag_errors`).
    flags: ClassVar[dict[str, str]] = {}
    #: One-line warnings the sweep prints and the report shows (e.g. a suspicious external bake).
    warnings: tuple[str, ...] = ()
    #: Entries the technique adds to the top level of ``metrics.json`` (e.g. ``external_bake``).
    extras: dict = {}
    #: The parts that a frame's ``split`` (:meth:`frame_extras`) divides an error into, ``(key, label)``
    #: from the bottom up as the report stacks them (``metrics.json``'s ``techniques.NAME.split_parts``);
    #: none by default.
    split_parts: ClassVar[tuple[tuple[str, str], ...]] = ()
    #: The technique whose textures this one fits to the truth (``horizon-fit``'s is ``horizon``):
    #: its scores are that technique's floor (:func:`hzval.report.ranking.floors`); ``None``: none.
    fit_of: ClassVar[str | None] = None
    #: Flags of the command line that give it inputs rather than settings (``--horizon-map``).
    input_flags: ClassVar[tuple[str, ...]] = ()

    @classmethod
    def applies(cls, scene: Scene) -> bool:
        """Whether the technique has something to render for ``scene``."""
        return all(scene.declares(e) for e in cls.needs)

    @classmethod
    def simulates(cls, scene: Scene) -> tuple[str, ...]:
        """Return the declared effects less those the technique does not model.

        They are in :data:`hzval.scene.spec.EFFECTS` order.
        """
        return tuple(e for e in EFFECTS if scene.declares(e) and e not in cls.not_modelled)

    @classmethod
    def bake_needs(cls, scene: Scene) -> frozenset[str]:
        """Return what the technique reads for ``scene``.

        These are names of :data:`hzval.bake.maps.CONTENTS` (``normal``, ``horizon_map``, ``ambient``) and
        ``height`` (the height map itself). A sweep bakes only what its techniques need; by default
        everything.
        """
        return frozenset({"normal", "horizon_map", "ambient", "height"})

    @classmethod
    def build(cls, ctx: Context, **settings) -> "Technique":
        """Build the technique on ``ctx`` with its ``settings`` (each subclass's own)."""
        raise NotImplementedError

    def render(self, azimuth_deg: float, *, elevation_deg: float | None = None) -> Frame:
        """Render the frame of the light at ``azimuth_deg`` (and ``elevation_deg``, default the scene's)."""
        raise NotImplementedError

    @property
    def parameters(self) -> dict:
        """Its settings, for ``metrics.json``."""
        return {}

    # -- optional hooks --------------------------------------------------------

    @classmethod
    def add_arguments(cls, parser) -> None:
        """Add the technique's own ``hzval sweep`` options to an argparse parser."""

    @classmethod
    def settings_from_args(cls, args) -> dict:
        """Return the :meth:`build` keywords of the options :meth:`add_arguments` added."""
        return {}

    @classmethod
    def check_settings(cls, bake_params, settings: dict) -> None:
        """Refuse settings that cannot work with this bake, before anything is written.

        A refusal raises :class:`hzval.core.errors.InputError`.
        """

    @classmethod
    def check_variants(cls) -> list[Variant]:
        """Return the images ``hzval check`` guards: one reference per variant, named after it."""
        return [Variant(cls.file_stem)]

    @classmethod
    def tradeoff_variants(cls) -> list[Variant]:
        """Return the settings ``hzval tradeoff`` measures; by default the technique as built."""
        return [Variant(cls.label)]

    @classmethod
    def fit(cls, ctx: Context, settings: dict, visibility: list, azimuths) -> dict:
        """Return ``settings`` with any value the technique fits to a converged truth filled in.

        ``visibility`` is the truth's V per azimuth. By default ``settings`` is returned unchanged.
        """
        return settings

    def storage_bytes(self) -> int:
        """Texture memory the technique reads at run time, bytes."""
        return 0

    @classmethod
    def frame_extras(cls, scores: dict) -> dict:
        """Return the entries the technique adds to its own record of a frame.

        The record is ``frames[i].techniques.NAME``; the entries come from every technique's scores of that
        frame, ``{name: metrics}`` (e.g. how its error splits against another's). By default there are none.
        """
        return {}


def names() -> list[str]:
    """Return the registered technique names, in registry order."""
    return list(REGISTRY)


def defaults() -> list[str]:
    """Return the names a sweep renders when none are asked for.

    They are the registry less the techniques that are not on by default (:attr:`Technique.by_default`).
    """
    return [n for n in REGISTRY if get(n).by_default]


def get(name: str) -> type[Technique]:
    """Return the technique class registered under a name.

    Parameters
    ----------
    name : str

    Returns
    -------
    type[Technique]

    Raises
    ------
    hzval.core.errors.InputError
        For an unknown name, with the known ones.
    """
    try:
        module, cls = REGISTRY[name].split(":")
    except KeyError:
        raise InputError(
            "--techniques", f"unknown technique {name!r}; choose from {', '.join(REGISTRY)}"
        ) from None
    return getattr(importlib.import_module(module), cls)


def select(requested: list[str] | None, scene: Scene, *, exclude=()) -> list[type[Technique]]:
    """Return the techniques to render for a scene.

    Parameters
    ----------
    requested : list of str or None
        Names (rendered in registry order), or ``None`` for every one that applies and is on by
        default (:attr:`Technique.by_default`).
    scene : hzval.scene.spec.Scene
    exclude : collection of str
        Names to leave out.

    Returns
    -------
    list of type[Technique]

    Raises
    ------
    hzval.core.errors.InputError
        For a requested technique that does not apply (``pom`` without ``shadow``): never dropped
        silently.
    """
    if requested is None:
        chosen = [
            t for t in (get(n) for n in REGISTRY if n not in exclude) if t.by_default and t.applies(scene)
        ]
        if not chosen:
            raise InputError(
                "--techniques",
                "no technique is left to score: every one is left out or needs "
                "effects the scene does not declare",
            )
        return chosen
    wanted = list(dict.fromkeys(requested))
    if not wanted:
        raise InputError("--techniques", "name at least one technique")
    classes = [get(n) for n in wanted]  # unknown names fail here
    for t in classes:
        if not t.applies(scene):
            raise InputError("--techniques", f"{t.name} needs the scene to declare {', '.join(t.needs)}")
    order = list(REGISTRY)
    chosen = sorted((t for t in classes if t.name not in exclude), key=lambda t: order.index(t.name))
    if not chosen:
        raise InputError(
            "--techniques",
            f"no technique is left to score: {', '.join(wanted)} "
            f"{'is' if len(wanted) == 1 else 'are'} left out too (--no-{wanted[0]})",
        )
    return chosen


def replace_effects(scene: Scene, effects) -> Scene:
    """Return the scene with another effect list (for the shading a technique builds on).

    Parameters
    ----------
    scene : hzval.scene.spec.Scene
    effects : sequence of str

    Returns
    -------
    hzval.scene.spec.Scene
    """
    return dataclasses.replace(scene, effects=tuple(effects))


def bake_needs(techniques, scene: Scene) -> frozenset[str]:
    """Return what a sweep must bake for its techniques.

    Parameters
    ----------
    techniques : iterable of type[Technique]
    scene : hzval.scene.spec.Scene

    Returns
    -------
    frozenset of str
        Their :meth:`Technique.bake_needs`, and the normal map (and, where ``ambient`` is declared, the
        ambient map) that the unshadowed shading reads (:class:`hzval.techniques.surface.Unshadowed`).
    """
    needs = {"normal"} | ({"ambient"} if scene.declares("ambient") else set())
    for t in techniques:
        needs |= t.bake_needs(scene)
    return frozenset(needs)


@contextlib.contextmanager
def flag_errors(cls: type[Technique], typed: dict[str, str] | None = None):
    """Yield a context in which errors about a technique's settings name its command-line flag.

    Parameters
    ----------
    cls : type[Technique]
        The technique (:attr:`Technique.flags` maps settings to flags).
    typed : dict of str to str, optional
        Canonical flag to the spelling the user typed (an alias), so the error names what was typed.
    """
    try:
        yield
    except InputError as exc:
        flag = cls.flags.get(exc.what)
        if flag is None:
            raise
        raise InputError((typed or {}).get(flag, flag), exc.problem) from None
