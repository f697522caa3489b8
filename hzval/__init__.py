"""hzval: a physically based validation harness for horizon mapping.

The package follows the data flow of ``DESIGN.md``, one module per stage:

``conventions``  axes, directions, height scale, boundaries, colour (the only
                 module that defines them)
``heightmap``    reading height maps from PNG, EXR and .npy
``material``     the material description and the built-in procedural bricks
``bake``         height map -> normal, horizon and ambient maps, weight cube map
``mesh``         height map -> displaced triangle mesh for Mitsuba
``backend``      choosing the Mitsuba/Dr.Jit variant, checking LLVM
``cli``          the ``hzval`` command, a thin layer over the above
"""

__version__ = "0.1.0"

from hzval.backend import prefer_working_llvm as _prefer_working_llvm

_prefer_working_llvm()
