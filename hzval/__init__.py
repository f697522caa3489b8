"""hzval: a physically based validation harness for horizon mapping.

The package follows the data flow of docs/ARCHITECTURE.md, one module per stage:

``conventions``  axes, directions, height scale, boundaries, colour (the only
                 module that defines them)
``heightmap``    reading height maps from PNG, EXR and .npy
``materials``    the built-in procedural materials (a registry: bricks, cobblestones, ...)
``bake``         height map -> normal, horizon and ambient maps, weight cube map
``mesh``         height map -> displaced triangle mesh for Mitsuba
``scene``        the scene description (TOML): material, camera, light, effects
``shading``      how a point turns light into radiance, for the truth and every technique
``truth``        the ground truth: Mitsuba traces the displaced mesh
``surface``      the flat surface's shading in Dr.Jit, which every technique builds on
``technique``    the Technique interface and the registry of techniques:
``horizon``        Lengyel's horizon mapping (``horizon``)
``terrain``        Raudins' per-light terrain shadows (``terrain``)
``pom``            ray-marched height-field shadows, parallax occlusion mapping's (``pom``)
``compare``      metrics of a frame against the truth
``images``       the visibility-difference and FLIP maps and their colours
``sweep``        truth and techniques over a light sweep, compared
``report``       the sweep's HTML report and plots
``check``        image-diff regression against ``reference/``
``tradeoff``     what accuracy costs: settings measured against a converged truth
``suite``        many materials' sweeps on worker processes or a Dask cluster, one overview
``export``       the truth as a Mitsuba 3 scene file
``files``        atomic EXR, PNG and JSON writing
``backend``      choosing the Mitsuba/Dr.Jit variant, checking LLVM
``errors``       the errors the CLI turns into one-line messages and exit codes
``cli``          the ``hzval`` command, a thin layer over the above

A script calls :func:`init` to choose the LLVM library and the Mitsuba
variant before it imports hzval's rendering modules; the ``hzval`` command
chooses the LLVM first thing in :func:`hzval.cli.main`. Importing the package
changes nothing in the environment.
"""

from importlib.metadata import PackageNotFoundError, version as _version

try:
    __version__ = _version("hzval")          # the installed package's, i.e. pyproject.toml's
except PackageNotFoundError:                 # run from a source tree that was never installed
    __version__ = "0+unknown"


def init(variant: str | None = None) -> str:
    """Choose, once, the LLVM library Dr.Jit's CPU backend loads and the Mitsuba variant hzval
    renders with (:func:`hzval.backend.prefer_working_llvm`, :func:`hzval.backend.variant`);
    return the variant. Call it before anything imports Dr.Jit: Dr.Jit reads
    ``DRJIT_LIBLLVM_PATH`` when it is first imported."""
    from hzval import backend

    backend.prefer_working_llvm()
    return backend.variant(variant)
