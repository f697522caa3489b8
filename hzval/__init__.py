"""hzval: a physically based validation harness for horizon mapping.

The package follows the data flow of docs/ARCHITECTURE.md, one module per stage:

``conventions``  axes, directions, height scale, boundaries, colour (the only
                 module that defines them)
``heightmap``    reading height maps from PNG, EXR and .npy
``materials``    the built-in procedural materials (a registry: bricks, cobblestones, ...)
``strict``       strict reading of hzval's TOML files
``bake``         height map -> normal, horizon and ambient maps, weight cube map
``storage``      how a horizon map is stored for the GPU (float, 8-bit, block-compressed)
``external``     your own horizon map: read, converted, its convention detected
``mesh``         height map -> the tile's displaced triangle mesh for Mitsuba
``model``        the base mesh of a model: built-in shapes and OBJ/PLY/glTF files
``tangents``     tangent frames (the only module that defines them)
``cells``        a base mesh cut along the texel grid in UV space
``displace``     the displaced model the truth traces
``scene``        the scene description (TOML): material, camera, light, effects
``camera``       the view: rays, footprints, its record
``shading``      how a point turns light into radiance, for the truth and every technique
``truth``        the ground truth: Mitsuba traces the displaced mesh
``truth_bands``  the truth's mesh built a band of rows at a time, when it would not fit whole
``model_truth``  the ground truth on a model, and the techniques' samples there
``lookup``       where a technique reads its textures, and how
``surface``      the flat surface's shading in Dr.Jit, which every technique builds on
``technique``    the Technique interface and the registry of techniques:
``horizon``        Lengyel's horizon mapping (``horizon``)
``horizon_fit``    the horizon map fitted to the truth (``horizon-fit``; ``fit``, ``fit_guard``)
``horizon_curved`` the horizon map corrected for curvature (``horizon-curved``)
``horizon_gl``     the shipped GLSL shaders on OpenGL (``horizon-gl``, ``pom-gl``; ``gl``, ``cubemap``)
``terrain``        Raudins' per-light terrain shadows (``terrain``)
``pom``            ray-marched height-field shadows, parallax occlusion mapping's (``pom``)
``tangent_bugs`` engine tangent-frame bugs on purpose
``compare``      metrics of a frame against the truth (``flip``: LDR-FLIP in Dr.Jit)
``facing``       what a frame's truth has to shadow; metrics over light-facing pixels
``images``       the visibility-difference and FLIP maps and their colours
``sweep``        truth and techniques over a light sweep, compared
``gates``        ``--fail-if`` and ``--baseline``: gates that fail a build
``report``       the sweep's HTML report and plots
``check``        image-diff regression against ``reference/``
``tradeoff``     what accuracy costs: settings measured against a converged truth
``suite``        many materials' sweeps on worker processes or a Dask cluster, one overview
``views``        the light sweep from a set of views
``models_study`` what curvature costs (``curvature_band``, ``seam_share``, ``bug_signatures``)
``score``        an engine's own frames scored beside the techniques (``brightness``, ``bug_match``)
``export``       the truth as a Mitsuba 3 scene file
``files``        atomic EXR, PNG and JSON writing
``backend``      choosing the Mitsuba/Dr.Jit variant, checking LLVM
``interrupts``   SIGTERM unwinds like Ctrl-C
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
