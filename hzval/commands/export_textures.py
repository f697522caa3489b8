"""``hzval export-textures``: a run's textures as KTX2 files an engine loads.

They are in the storage they were scored with, with full mip chains and ``textures.json`` saying what each
channel means.

:func:`export` reads ``RUN_DIR``, what ``hzval sweep`` (its ``bake/`` and ``metrics.json``), ``hzval
bake`` (``bake.json``) or ``hzval fit`` (``fit.json``) wrote, and writes one KTX2 file
(:mod:`hzval.io.ktx2`) per texture of the techniques the run selected, named after its bake file:

``horizon<i>.ktx2``
    the horizon map's sines (``hzval.core.conventions``: channel ``k`` toward ``360 k / D``
    degrees, counterclockwise from +x, +y up the image), in its ``--horizon-storage``: float as
    RGBA16F layers, ``u8`` as RGBA8, ``bc7``/``bc3`` as RGBA blocks, ``bc1`` three channels a
    texture, ``bc4`` one; ``-sqrt`` storages hold ``sqrt(s)``;
``normal.ktx2``, ``bent_normal.ktx2``
    unit tangent-space vectors: RGBA16F ``(x, y, z, 1)``, or RGBA8 ``0.5 + 0.5 n`` (``u8``);
``ambient.ktx2``
    ``AO``, the cosine-weighted unoccluded fraction (the ambient map's ``mean_cos2``): R16F or R8;
``ssbump.ktx2``
    Valve's three channels (RGBA16F with A = 1, or RGBA8).

Each file has every mip level down to 1x1, made as the technique's lookup makes them
(:func:`hzval.scene.lookup.mip_chain`: 2x2 averages, the horizon map's 2x2 maxima where the run's
``--mips max`` says so), each level quantised to the storage before the next is made from it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from hzval.bake import maps as bake
from hzval.core import conventions as cv
from hzval.core.errors import InputError
from hzval.io import codecs, documents, ktx2, staging
from hzval.io import storage as hz_storage
from hzval.metrics.results import SweepResult
from hzval.scene import lookup
from hzval.scene import spec as sc
from hzval.techniques import registry as technique
from hzval.techniques.fitted import store as fitted_store

__all__ = ["export", "FILE", "plan"]

#: The description written beside the textures.
FILE = "textures.json"
#: The KTX2 format of each horizon storage's textures (``-sqrt`` storages: the same format).
HORIZON_FORMATS = {
    "float": "R16G16B16A16_SFLOAT",
    "u8": "R8G8B8A8_UNORM",
    "bc7": "BC7_UNORM_BLOCK",
    "bc3": "BC3_UNORM_BLOCK",
    "bc1": "BC1_RGB_UNORM_BLOCK",
    "bc4": "BC4_UNORM_BLOCK",
}
#: Each texture's formula and source, for textures.json.
SOURCES = {
    "horizon_map": "F = clamp(k (L.z - s) + 1, 0, 1), s the weighted sines of the two channels beside "
    "the light's azimuth (Lengyel, 'Smooth Horizon Mapping', GPU Pro 3 / FGED2 ch. 7)",
    "ambient": "AO = the cosine-weighted unoccluded fraction (1 = open): Filament's aperture "
    "inversesqrt(1 - AO), HDRP's micro-shadowing, a bent cone's cos = sqrt(1 - AO) (docs/techniques.md)",
    "bent_normal": "the cosine-weighted mean unoccluded direction (Jimenez et al. 2016; docs/techniques.md)",
    "ssbump_map": "Valve's self-shadowed bump map, one channel per Half-Life 2 basis vector (Green 2007)",
    "normal": "normalize(-dH/dx, -dH/dy, 1), heights in texels (FGED2 ch. 7, corrected)",
}


#: The textures, by the names of the bake's contents (:data:`hzval.bake.maps.CONTENTS`).
TEXTURES: tuple[str, ...] = bake.CONTENTS
#: The bake's file of Valve's map: its KTX2 file takes its stem.
_SSBUMP_FILE = "ssbump.exr"


def _content_of(storage_key: str) -> str:
    """Return the bake content a technique's ``parameters.storage`` key stores (``ao``: the ambient map)."""
    key = storage_key.replace("-", "_")
    return "ambient" if key == "ao" else key if key in TEXTURES else f"{key}_map"


def plan(run_dir: Path) -> dict:
    """Return what ``run_dir`` holds: ``{kind, bake, storage: {texture: name}, mips, textures}``.

    A folder that is no run's is refused in one line naming it.
    """
    run_dir = Path(run_dir)
    if (run_dir / "fit.json").is_file():
        fit = documents.read_json(run_dir / "fit.json")
        store = fit.get("storage", "float") if isinstance(fit, dict) else "float"
        if isinstance(store, dict):  # a per-pixel technique's textures (hzval fit --technique)
            stores = {_content_of(t): s for t, s in store.items()}
            return _plan("texture-fit", run_dir, stores, "average", tuple(stores))
        return _plan("fit", run_dir, {"horizon_map": store}, "average", ("horizon_map",))
    if (run_dir / "bake.json").is_file():
        return _plan("bake", run_dir, {}, "average", TEXTURES)
    if not ((run_dir / "metrics.json").is_file() and (run_dir / "bake" / "bake.json").is_file()):
        raise InputError(
            run_dir, "holds no bake: give the folder hzval sweep (with its bake/), bake or fit wrote"
        )
    metrics = documents.read_json(run_dir / "metrics.json")
    techniques = SweepResult.of(metrics).techniques
    if not techniques:
        raise InputError(run_dir / "metrics.json", "not a sweep's metrics.json (no techniques)")
    textures: list[str] = []
    store: dict[str, str] = {}
    for name, info in techniques.items():
        params = info.parameters
        reads = technique.get(name).bake_needs(sc.Scene()) if name in technique.REGISTRY else frozenset()
        textures += [t for t in TEXTURES if t in reads and t not in textures]
        given = params.get("storage")
        if isinstance(given, str) and "horizon_map" in reads:  # the horizon map's --horizon-storage
            store.setdefault("horizon_map", given)
        for key, value in given.items() if isinstance(given, dict) else ():
            store.setdefault(_content_of(key), value)
    mips = (metrics.get("parameters") or {}).get("mips", "average")
    return _plan("sweep", run_dir / "bake", store, mips, tuple(textures) or ("normal",))


def _plan(kind: str, folder: Path, store: dict, mips: str, textures: tuple) -> dict:
    return {"kind": kind, "bake": folder, "storage": store, "mips": mips, "textures": textures}


def export(run_dir, out, *, zstd: bool = False, force: bool = False) -> list[Path]:
    """Write ``run_dir``'s textures into ``out`` as KTX2 (module docstring) and ``textures.json``.

    Return the paths written. All or nothing: the files are staged and swapped in whole.
    """
    p = plan(Path(run_dir))
    maps = _maps(p)
    if not maps:
        raise InputError(run_dir, "holds none of the textures its techniques read (a bake without them)")
    with staging.swapped_in(out, force=force) as work:
        described, written = {}, []
        for name, (values, fmt_name, what) in maps.items():
            tex = _texture(values, ktx2.FORMATS[fmt_name], max_mips=what.get("max_mips", False))
            ktx2.write(work / f"{name}.ktx2", tex, zstd=zstd)
            described[f"{name}.ktx2"] = {
                "format": f"VK_FORMAT_{fmt_name}",
                "size": [tex.width, tex.height],
                "levels": len(tex.levels),
                "bytes_level0": len(tex.levels[0]),
                "transfer": "linear",
                "supercompression": "zstd" if zstd else None,
                **{k: v for k, v in what.items() if k != "max_mips"},
            }
            written.append(Path(out) / f"{name}.ktx2")
        documents.write_json(work / FILE, _description(p, described))
        written.append(Path(out) / FILE)
    return written


def _description(p: dict, described: dict) -> dict:
    return {
        "format": "hzval textures 1",
        "from": p["kind"],
        "conventions": {
            "rows": "row 0 at the top of the image (KTXorientation rd)",
            "tangent_space": "+x right (increasing column), +y up the image (decreasing row), +z out",
            "azimuth": "counterclockwise from +x as seen on screen",
            "horizon_channel_k": "toward azimuth 360 k / D degrees (channel 0 toward +x)",
            "heights": "texel units: H * depth * columns",
        },
        "mips": p["mips"],
        "files": described,
    }


def _maps(p: dict) -> dict:
    """``{file stem: (values (rows, cols, C) in the texture's encoding, KTX2 format, description)}``."""
    folder = p["bake"]
    if p["kind"] == "fit":
        layers = sorted(folder.glob("horizon*.exr"), key=lambda f: int(f.stem[7:] or 0))
        sines = np.concatenate([_rgba(codecs.read_exr(f)) for f in layers], axis=-1)
        return _horizon(sines, p["storage"].get("horizon_map", "float"), p["mips"])
    if p["kind"] == "texture-fit":
        planes, _ = fitted_store.read_texture_fit(folder)
        return _occlusion({_content_of(t): v for t, v in planes.items()}, p)
    b = bake.read_bake(folder)
    out = {}
    if "horizon_map" in p["textures"] and b.horizon is not None:
        out.update(_horizon(b.horizon, p["storage"].get("horizon_map", "float"), p["mips"]))
    if "normal" in p["textures"]:
        out["normal"] = _vector(b.normal, "float", "the normal map: unit tangent-space normal", "normal")
    maps = {"ambient": b.mean_cos2, "bent_normal": b.bent_normal, "ssbump_map": b.ssbump}
    out.update(_occlusion({k: v for k, v in maps.items() if v is not None}, p))
    return out


#: The KTX2 format of the AO and ssbump textures in each storage.
AO_FORMATS = {"float": "R16_SFLOAT", "u8": "R8_UNORM", "bc4": "BC4_UNORM_BLOCK"}
SSBUMP_FORMATS = {
    "float": "R16G16B16A16_SFLOAT",
    "u8": "R8G8B8A8_UNORM",
    "bc1": "BC1_RGB_UNORM_BLOCK",
    "bc7": "BC7_UNORM_BLOCK",
}


def _occlusion(maps: dict, p: dict) -> dict:
    """Return the AO, bent-normal and ssbump textures of ``maps`` (by bake content) that ``p`` selects.

    Each is in its storage.
    """
    out = {}
    if "ambient" in p["textures"] and "ambient" in maps:
        store = p["storage"].get("ambient", "float")
        what = {
            "bake_content": "ambient",
            "channels": ["AO"],
            "encoding": "AO in [0, 1]",
            "storage": store,
            "source": SOURCES["ambient"],
        }
        out["ambient"] = (np.asarray(maps["ambient"], np.float32)[..., None], AO_FORMATS[store], what)
    if "bent_normal" in p["textures"] and "bent_normal" in maps:
        store = p["storage"].get("bent_normal", "float")
        out["bent_normal"] = _vector(
            maps["bent_normal"], store, "the bent normal: unit tangent-space vector", "bent_normal"
        )
    if "ssbump_map" in p["textures"] and "ssbump_map" in maps:
        store = p["storage"].get("ssbump_map", "float")
        fmt = SSBUMP_FORMATS[store]
        three = ktx2.FORMATS[fmt].channels == 3
        what = {
            "bake_content": "ssbump_map",
            "channels": ["basis 0", "basis 1", "basis 2"] + ([] if three else ["1"]),
            "encoding": "as stored, in [0, 1]",
            "storage": store,
            "source": SOURCES["ssbump_map"],
        }
        v = np.asarray(maps["ssbump_map"], np.float32)
        out[Path(_SSBUMP_FILE).stem] = (v if three else _with_one(v), fmt, what)
    return out


def _rgba(ch: dict) -> np.ndarray:
    return np.stack([ch[c] for c in "RGBA"], axis=-1)


def _with_one(v: np.ndarray) -> np.ndarray:
    return np.concatenate([v, np.ones((*v.shape[:2], 1), np.float32)], axis=-1)


def _vector(n: np.ndarray, store: str, meaning: str, key: str) -> tuple:
    channels = ["x", "y", "z", "1"]
    if store == "float":
        values, fmt, enc = _with_one(n), "R16G16B16A16_SFLOAT", "x, y, z as they are; A = 1"
    elif store == "bc5":  # a BC5 normal map's two channels: the shader rebuilds z
        values, fmt, enc = (
            0.5 + 0.5 * n[..., :2],
            "BC5_UNORM_BLOCK",
            "0.5 + 0.5 (x, y); z = sqrt(1 - x² - y²)",
        )
        channels = ["x", "y"]
    else:
        values, fmt, enc = _with_one(0.5 + 0.5 * n), "R8G8B8A8_UNORM", "0.5 + 0.5 (x, y, z); A = 1"
    what = {
        "bake_content": key,
        "channels": channels,
        "meaning": meaning,
        "encoding": enc,
        "storage": store,
        "source": SOURCES[key],
    }
    return values, fmt, what


def _horizon(sines: np.ndarray, store: str, mips: str) -> dict:
    """Return the horizon map's textures in storage ``store``.

    Its channels are packed as the storage packs them.
    """
    s = hz_storage.get(store)
    base = store.removesuffix("-sqrt")
    fmt = HORIZON_FORMATS[base]
    per = 4 if base in ("float", "u8", "bc7", "bc3") else s.channels
    v = np.clip(sines, 0.0, 1.0)
    v = np.sqrt(v) if s.sqrt else (sines if base == "float" else v)
    D = sines.shape[-1]
    out = {}
    for i, first in enumerate(range(0, D, per)):
        chans = list(range(first, min(first + per, D)))
        values = v[..., chans]
        want = ktx2.FORMATS[fmt].channels
        if values.shape[-1] < want:  # a last texture with room to spare
            values = np.concatenate(
                [values, np.zeros((*values.shape[:2], want - values.shape[-1]), np.float32)], -1
            )
        what = {
            "bake_content": "horizon_map",
            "channels": [f"sine toward {cv.channel_azimuth_deg(c, D):g} degrees" for c in chans],
            "encoding": "sqrt(sin(horizon angle)): square what is sampled"
            if s.sqrt
            else "sin(horizon angle)",
            "storage": store,
            "source": SOURCES["horizon_map"],
            "max_mips": mips == "max",
        }
        out[f"horizon{i}"] = (values.astype(np.float32), fmt, what)
    return out


def _texture(values: np.ndarray, fmt: ktx2.Format, *, max_mips: bool = False) -> ktx2.Texture:
    """Return every mip level of ``values`` (:func:`hzval.scene.lookup.mip_chain`), encoded.

    Each level is quantised to the format (8-bit or half) before the next is made from it.
    """
    everything = slice(None)
    if fmt.half:
        quantise = lambda a: a.astype(np.float16).astype(np.float32)  # noqa: E731
    else:
        quantise = lambda a: codecs.unit_to_u8(a).astype(np.float32) / np.float32(255.0)  # noqa: E731
    chain = lookup.mip_chain(
        quantise(values), everything if max_mips else None, stored=everything, quantise=quantise
    )
    rows, cols = values.shape[:2]
    return ktx2.Texture(fmt, cols, rows, [ktx2.encode_level(level, fmt) for level in chain])
