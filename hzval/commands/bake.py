"""``hzval bake``: a height map's textures written to a folder, and optionally its displaced mesh.

The textures are :func:`hzval.bake.maps.bake`'s.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from hzval.bake import maps as bake
from hzval.geometry import tile as mesh
from hzval.io import staging
from hzval.scene import spec as sc
from hzval.truth import memory

__all__ = ["BakeRun", "run"]


@dataclass
class BakeRun:
    """What :func:`run` did: the material's record, the files written and the wall time in seconds.

    The material's record is ``bake.json``'s ``input``.
    """

    info: dict
    written: list[Path]
    seconds: float


def run(scene, params: bake.BakeParams, out: Path, *, what: str, mesh_too: bool = False, force=False):
    """Bake ``scene``'s material with ``params`` into ``out``, the mesh too with ``mesh_too``.

    Parameters
    ----------
    scene : hzval.scene.spec.Scene
        Its material is baked.
    params : hzval.bake.maps.BakeParams
        The bake's settings, checked.
    out : pathlib.Path
        The output folder (:func:`hzval.io.staging.output_folder`, ``force`` as there).
    what : str
        The file or flag an error names (``--size`` for a built-in material).
    mesh_too : bool
        Also write the displaced mesh as ``mesh.ply``.

    Returns
    -------
    BakeRun

    Raises
    ------
    hzval.core.errors.InputError
        Before anything is decoded or written, when the bake or the mesh would not fit in memory.
    """
    rows, cols = memory.material_shape(scene)  # estimated before the map is decoded or generated
    bake.check_fits(what, rows, cols, params)
    t0 = time.perf_counter()
    with staging.output_folder(out, force=force):
        height, info = sc.material_record(scene)
        info["path"] = staging.report_path(info["path"], out)  # bake.json carries no absolute folders
        t_load = time.perf_counter() - t0
        if mesh_too:  # before the bake: a mesh that cannot be built leaves nothing written
            need = bake.estimate_bytes(*height.shape, params)
            mesh.check_fits(what, height, params.depth, params.boundary, also=need)
        result = bake.bake(height, params)
        result.timings = {"load_s": t_load, **result.timings}
        written = bake.write_bake(result, out, input_info=info)
        if mesh_too:
            m = mesh.displaced_mesh(height, params.depth, params.boundary)
            mesh.write_ply(m, out / "mesh.ply")
            written.append(out / "mesh.ply")
    return BakeRun(info, written, time.perf_counter() - t0)
