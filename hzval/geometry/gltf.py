"""glTF 2.0 meshes read by pygltflib: accessors, the node tree, buffers inside the model's folder.

pygltflib rather than trimesh, because trimesh 4-5 drops ``TANGENT`` (module docstring of
:mod:`hzval.geometry.model`). The reader checks what it is handed before it opens anything: every
buffer URI is embedded or names a file inside the glTF's folder (:func:`hzval.io.paths.uri_path`),
and the node tree is walked with every node visited at most once, so a cycle is refused, not
followed.
"""

from __future__ import annotations

import os
import warnings

import numpy as np
import pygltflib

from hzval.core.errors import InputError
from hzval.geometry import tangents as tg
from hzval.io import atomic, paths

__all__ = ["read_parts", "write_glb"]

#: glTF accessor component types (glTF 2.0, "Accessor Data Types") and the range a normalized one
#: maps to [0, 1] / [-1, 1] by.
_GLTF_COMPONENTS = {
    5120: (np.int8, 127.0),
    5121: (np.uint8, 255.0),
    5122: (np.int16, 32767.0),
    5123: (np.uint16, 65535.0),
    5125: (np.uint32, None),
    5126: (np.float32, None),
}
_GLTF_WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}


def _gltf_accessor(g, blob: bytes, index: int) -> np.ndarray:
    """Return accessor ``index`` of the glTF ``g`` as a ``(count, width)`` float64 array.

    Indices come as integers; ``byteStride`` and ``normalized`` are honoured. Sparse accessors:
    ``ValueError``.
    """
    a = g.accessors[index]
    if a.sparse is not None:
        raise ValueError(f"accessor {index} is sparse, which hzval does not read")
    dtype, scale = _GLTF_COMPONENTS[a.componentType]
    width = _GLTF_WIDTH[a.type]
    view = g.bufferViews[a.bufferView]
    item = np.dtype(dtype).itemsize * width
    stride = view.byteStride or item
    start = (view.byteOffset or 0) + (a.byteOffset or 0)
    raw = np.frombuffer(blob, np.uint8, count=stride * (a.count - 1) + item, offset=start)
    rows = np.lib.stride_tricks.as_strided(raw, (a.count, item), (stride, 1))
    out = np.ascontiguousarray(rows).view(dtype).reshape(a.count, width)
    if a.normalized and scale is not None:
        return np.maximum(out / scale, -1.0)
    return out.astype(np.int64 if scale is None and dtype == np.uint32 else np.float64)


def _gltf_node_matrix(node) -> np.ndarray:
    """Return a node's local 4 x 4 transform: its ``matrix`` (column-major) or ``T R S``."""
    if node.matrix is not None:
        return np.asarray(node.matrix, np.float64).reshape(4, 4).T
    x, y, z, w = node.rotation or (0.0, 0.0, 0.0, 1.0)
    r = np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )
    m = np.eye(4)
    m[:3, :3] = r * np.asarray(node.scale or (1.0, 1.0, 1.0))[None, :]
    m[:3, 3] = node.translation or (0.0, 0.0, 0.0)
    return m


def _gltf_primitives(g):
    """Yield ``(primitive, world matrix)`` of every mesh primitive the default scene instances.

    Without scenes, it yields those of every root node (a node no other lists as a child) and its subtree,
    walking the node tree.

    glTF 2.0 ("Nodes and Hierarchy") requires the nodes to form disjoint strict trees: a node
    reached twice (a cycle, a child listed twice, a node under two parents) is a ``ValueError``,
    so the walk visits each node at most once and ends.
    """
    roots = (
        g.scenes[g.scene or 0].nodes
        if g.scenes
        else sorted(set(range(len(g.nodes))) - {c for n in g.nodes for c in (n.children or [])})
    )
    stack = [(i, np.eye(4)) for i in roots or []]
    seen: set[int] = set()
    while stack:
        i, parent = stack.pop()
        if not isinstance(i, int) or not 0 <= i < len(g.nodes):
            raise ValueError(f"refers to node {i!r}, which does not exist ({len(g.nodes)} nodes)")
        if i in seen:
            raise ValueError(f"reaches node {i} twice (a cycle or a shared child): glTF nodes form trees")
        seen.add(i)
        node = g.nodes[i]
        m = parent @ _gltf_node_matrix(node)
        if node.mesh is not None:
            for prim in g.meshes[node.mesh].primitives:
                yield prim, m
        stack.extend((c, m) for c in node.children or [])


def _gltf_part(g, blob, prim, m):
    """Return one triangle primitive as ``(positions, uvs, normals, tangents, faces)``.

    They are in the file's axes with its node's transform applied; glTF's ``v`` is flipped to hzval's (``1 -
    v``).
    """
    at = prim.attributes
    if at.TEXCOORD_0 is None:
        raise ValueError("has no texture coordinates (TEXCOORD_0)")
    p = _gltf_accessor(g, blob, at.POSITION)
    faces = (
        _gltf_accessor(g, blob, prim.indices).reshape(-1, 3)
        if prim.indices is not None
        else np.arange(len(p)).reshape(-1, 3)
    )
    uv = _gltf_accessor(g, blob, at.TEXCOORD_0) * [1.0, -1.0] + [0.0, 1.0]
    n = None if at.NORMAL is None else _gltf_accessor(g, blob, at.NORMAL) @ np.linalg.inv(m[:3, :3])
    t = None if at.TANGENT is None else tg.rotate(_gltf_accessor(g, blob, at.TANGENT), m[:3, :3])
    if np.linalg.det(m[:3, :3]) < 0:  # a mirroring node turns the winding over (glTF 2.0, "Transformations")
        faces = faces[:, ::-1]
    return p @ m[:3, :3].T + m[:3, 3], uv, n, t, faces.astype(np.int64)


def _gltf_check_uris(g, path: str) -> None:
    """Check that every buffer URI of the glTF at ``path`` is embedded or names a file in its folder.

    Embedded means ``data:``; a named file must be inside the glTF's folder (:func:`hzval.io.paths.uri_path`).
    The check runs before any buffer is opened.
    """
    folder = os.path.dirname(os.fspath(path)) or "."
    for i, b in enumerate(g.buffers or []):
        if b.uri is not None and not paths.is_data_uri(b.uri):
            paths.uri_path(folder, b.uri, path, f"buffers[{i}].uri")


def _gltf_check(g, blob: bytes) -> None:
    """Raise ``ValueError`` for what the reader cannot decode.

    That is required extensions (Draco, meshopt compression...) or buffer data missing or shorter than the
    file says (a ``.bin`` not beside the ``.gltf``).
    """
    if g.extensionsRequired:
        raise ValueError(
            f"needs glTF extension(s) {', '.join(g.extensionsRequired)}, which hzval does not "
            "read (export without compression)"
        )
    need = sum(b.byteLength or 0 for b in g.buffers)
    if len(blob) < need:
        raise ValueError(
            f"its buffer data is missing or short ({len(blob)} of {need} bytes; is its .bin file beside it?)"
        )


def read_parts(path: str) -> tuple:
    """Return the triangles of a glTF 2.0 file (``.gltf`` with its buffers, or ``.glb``), by pygltflib.

    Every triangle primitive of the default scene with its node transforms applied, in the file's
    axes; ``TEXCOORD_0`` (``v -> 1 - v``), ``NORMAL`` and ``TANGENT`` where every primitive has them.

    Parameters
    ----------
    path : str
        The file.

    Returns
    -------
    tuple
        ``(positions, uvs, normals or None, tangents or None, faces)``: ``(V, 3)``, ``(V, 2)``,
        ``(V, 3)``, ``(V, 4)`` float64 and ``(F, 3)`` int64, the primitives concatenated.

    Raises
    ------
    hzval.core.errors.InputError
        One line naming the file: a URI outside its folder, a node reached twice, missing buffer
        data, a required extension, no triangles, or content pygltflib cannot read.
    """
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            g = pygltflib.GLTF2().load(path)
            _gltf_check_uris(g, path)
            g.convert_buffers(pygltflib.BufferFormat.BINARYBLOB)
        blob = g.binary_blob() or b""
        _gltf_check(g, blob)
        parts = [
            _gltf_part(g, blob, prim, m)
            for prim, m in _gltf_primitives(g)
            if prim.mode in (None, pygltflib.TRIANGLES)
        ]
    except InputError:
        raise
    except ValueError as exc:
        raise InputError(path, str(exc)) from None
    except RecursionError:
        raise InputError(path, "nests too deeply to be a glTF file") from None
    except Exception as exc:  # a broken file: pygltflib raises many kinds
        raise InputError(path, f"cannot be read as glTF ({type(exc).__name__}: {exc})") from None
    if not parts:
        raise InputError(path, "the mesh is empty (no triangles)")
    offsets = np.cumsum([0] + [len(q[0]) for q in parts])

    def cat(k):
        return None if any(q[k] is None for q in parts) else np.concatenate([q[k] for q in parts])

    faces = np.concatenate([q[4] + o for q, o in zip(parts, offsets)])
    return cat(0), cat(1), cat(2), cat(3), faces


def write_glb(path, positions, normals, uvs, tangents, faces, *, up: str = "y") -> None:
    """Write a mesh as a binary glTF 2.0 file: ``POSITION``, ``NORMAL``, ``TEXCOORD_0`` and ``TANGENT``.

    The inverse of :func:`read_parts` with hzval's model reader: hzval's z-up world turned to
    glTF's y up (``up="y"``, the spec's; ``"z"`` keeps the axes), ``v`` flipped back to glTF's
    (``1 - v``: glTF's origin is the image's top left), ``TANGENT.w`` the handedness as glTF
    defines it (the bitangent is ``w * cross(normal, tangent)``, toward hzval's +v), which is
    hzval's own.

    Parameters
    ----------
    path : str or path-like
        The ``.glb`` to write (atomically).
    positions, normals : numpy.ndarray
        ``(V, 3)`` in hzval's world (z up).
    uvs : numpy.ndarray
        ``(V, 2)`` hzval's texture coordinates (``v`` up).
    tangents : numpy.ndarray
        ``(V, 4)`` unit tangents along +u and their handedness.
    faces : numpy.ndarray
        ``(F, 3)`` vertex indices, counterclockwise from outside.
    up : {"y", "z"}
        The written file's up axis.
    """
    rot = tg.Y_UP_TO_Z_UP.T if up == "y" else np.eye(3)  # z-up world to the file's axes
    arrays = [
        ("POSITION", np.asarray(positions, np.float64) @ rot.T, "VEC3"),
        ("NORMAL", np.asarray(normals, np.float64) @ rot.T, "VEC3"),
        ("TEXCOORD_0", np.asarray(uvs, np.float64) * [1.0, -1.0] + [0.0, 1.0], "VEC2"),
        (
            "TANGENT",
            np.concatenate([np.asarray(tangents)[:, :3] @ rot.T, np.asarray(tangents)[:, 3:]], 1),
            "VEC4",
        ),
    ]
    index = np.ascontiguousarray(faces, np.uint32).ravel()
    blobs, views, accessors = [index.tobytes()], [], []
    views.append(pygltflib.BufferView(buffer=0, byteOffset=0, byteLength=len(blobs[0]), target=34963))
    accessors.append(pygltflib.Accessor(bufferView=0, componentType=5125, count=len(index), type="SCALAR"))
    offset = len(blobs[0])
    attributes = {}
    for name, values, kind in arrays:
        data = np.ascontiguousarray(values, np.float32)
        blobs.append(data.tobytes())
        views.append(pygltflib.BufferView(buffer=0, byteOffset=offset, byteLength=data.nbytes, target=34962))
        bounds = {"min": data.min(0).tolist(), "max": data.max(0).tolist()} if name == "POSITION" else {}
        accessors.append(
            pygltflib.Accessor(
                bufferView=len(views) - 1, componentType=5126, count=len(data), type=kind, **bounds
            )
        )
        attributes[name] = len(accessors) - 1
        offset += data.nbytes
    g = pygltflib.GLTF2(
        scene=0,
        scenes=[pygltflib.Scene(nodes=[0])],
        nodes=[pygltflib.Node(mesh=0)],
        meshes=[
            pygltflib.Mesh(
                primitives=[pygltflib.Primitive(attributes=pygltflib.Attributes(**attributes), indices=0)]
            )
        ],
        accessors=accessors,
        bufferViews=views,
        buffers=[pygltflib.Buffer(byteLength=offset)],
    )
    g.set_binary_blob(b"".join(blobs))
    with atomic.atomic_path(path) as tmp:
        g.save_binary(str(tmp))
