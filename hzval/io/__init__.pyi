# Written by tests/stubs.py from each module's __all__ (python -m tests.stubs); do not edit.
from . import atomic, codecs, documents, external, heightmap, ktx2, paths, staging, storage
from .atomic import (
    atomic_path as atomic_path,
)
from .codecs import (
    HALF_MAX as HALF_MAX,
    write_exr as write_exr,
    is_grey as is_grey,
    read_exr as read_exr,
    read_exr_attributes as read_exr_attributes,
    read_rgb_exr as read_rgb_exr,
    rgb_of as rgb_of,
    library_output as library_output,
    run_writers as run_writers,
    Writers as Writers,
    Indexed as Indexed,
    write_png as write_png,
    PREVIEW_ABOVE_PX as PREVIEW_ABOVE_PX,
    PREVIEW_PX as PREVIEW_PX,
    write_figure as write_figure,
    preview_of as preview_of,
    write_png_with_preview as write_png_with_preview,
    unit_to_u8 as unit_to_u8,
)
from .documents import (
    MAX_DEPTH as MAX_DEPTH,
    depth as depth,
    read_json as read_json,
    read_toml as read_toml,
    loads_json as loads_json,
    loads_toml as loads_toml,
    write_json as write_json,
)
from .external import (
    Encoding as Encoding,
    VALUES as VALUES,
    CLEARLY_BETTER as CLEARLY_BETTER,
    DESCRIBES_CORRELATION as DESCRIBES_CORRELATION,
    load as load,
    read_layers as read_layers,
    to_hzval as to_hzval,
    rings as rings,
    detect as detect,
    correlation as correlation,
    advice as advice,
    warnings as warnings,
    repeated_layers as repeated_layers,
)
from .heightmap import (
    SUFFIXES as SUFFIXES,
    MIN_SIDE as MIN_SIDE,
    HeightMap as HeightMap,
    probe_shape as probe_shape,
    load_height as load_height,
    check_usable as check_usable,
    from_array as from_array,
)
from .ktx2 import (
    IDENTIFIER as IDENTIFIER,
    Format as Format,
    FORMATS as FORMATS,
    Texture as Texture,
    write as write,
    read as read,
    dfd as dfd,
    encode_level as encode_level,
    decode_level as decode_level,
)
from .paths import (
    MAX_NAME_CHARS as MAX_NAME_CHARS,
    file_name as file_name,
    inside as inside,
    resolved as resolved,
    is_data_uri as is_data_uri,
    uri_path as uri_path,
    no_symlink_below as no_symlink_below,
    stored_input as stored_input,
)
from .staging import (
    LOCK_NAME as LOCK_NAME,
    MARKER_NAME as MARKER_NAME,
    folder_lock as folder_lock,
    foreign_files as foreign_files,
    os_error as os_error,
    output_folder as output_folder,
    report_path as report_path,
    portable_command as portable_command,
    swapped_in as swapped_in,
    file_digest as file_digest,
    Staging as Staging,
)
from .storage import (
    Storage as Storage,
    STORAGES as STORAGES,
    get as get,
    names as names,
)
