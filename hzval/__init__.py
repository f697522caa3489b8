"""hzval: a physically based validation harness for horizon mapping.

The package is laid out by role, one subpackage per layer; a layer imports only the layers below
it (docs/ARCHITECTURE.md draws them; ``tests/test_structure.py`` enforces the order):

``cli``         the ``hzval`` command: flags in, one module per command
``commands``    check, gates, tradeoff, suite, views, score, export
``studies``     what models cost, the curvature band, seam shares, tangent-bug signatures
``pipeline``    the sweep: truth and techniques over the lights, compared, written, reported
``report``      HTML pages, plots, difference maps, templates
``techniques``  the self-shadowing plug-ins and their registry (horizon, terrain, pom, fitted, gl)
``truth``       Mitsuba traces the displaced surface: plane, bands, model
``metrics``     |F - V|, FLIP, CIEDE2000, RMSE, light-facing scores
``bake``        height map -> normal, horizon and ambient maps
``scene``       the scene description, the camera, where techniques read their textures
``geometry``    the tile mesh, models, tangent frames, the displaced model
``io``          files, height maps, external horizon maps, storage formats
``materials``   the built-in procedural materials (a registry: bricks, cobblestones, ...)
``core``        conventions, shading, backend, errors, interrupts, strict TOML, memory figures

Each subpackage's ``__init__`` says what it holds and re-exports its modules' public names
(``from hzval.truth import Truth``) at their first use.

A script calls :func:`init` to choose the LLVM library and the Mitsuba variant before it imports
hzval's rendering modules; the ``hzval`` command chooses the LLVM first thing in
:func:`hzval.cli.main.main`. Importing the package changes nothing in the environment.
"""

from importlib.metadata import PackageNotFoundError
from importlib.metadata import version as _version

try:
    __version__ = _version("hzval")  # the installed package's, i.e. pyproject.toml's
except PackageNotFoundError:  # run from a source tree that was never installed
    __version__ = "0+unknown"


def init(variant: str | None = None) -> str:
    """Choose the LLVM library Dr.Jit's CPU backend loads and the Mitsuba variant hzval renders with.

    The choice is made once (:func:`hzval.core.backend.prefer_working_llvm`,
    :func:`hzval.core.backend.variant`), and the variant is returned. Call it before anything imports Dr.Jit:
    Dr.Jit reads ``DRJIT_LIBLLVM_PATH`` when it is first imported.
    """
    # importing hzval changes nothing: the backend loads when init runs
    from hzval.core import backend

    backend.prefer_working_llvm()
    return backend.variant(variant)
