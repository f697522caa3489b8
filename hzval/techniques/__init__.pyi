# Written by tests/stubs.py from each module's __all__ (python -m tests.stubs); do not edit.
from . import bent_cone, cubemap, horizon, horizon_curved, microshadow_filament, microshadow_hdrp, perpixel, pom, registry, ssbump, surface, terminator, terrain, fitted, gl
from .bent_cone import (
    BentCone as BentCone,
    INTERSECTIONS as INTERSECTIONS,
    cap_intersection as cap_intersection,
    cap_intersection_filament as cap_intersection_filament,
)
from .cubemap import (
    FACE_AXES as FACE_AXES,
    face_coordinates as face_coordinates,
    bilinear as bilinear,
)
from .horizon import (
    Horizon as Horizon,
    PATHS as PATHS,
    WEIGHTS as WEIGHTS,
    AMBIENT_TERMS as AMBIENT_TERMS,
    DEFAULT_K as DEFAULT_K,
    DEFAULT_FADE as DEFAULT_FADE,
    CUBE_SIZE as CUBE_SIZE,
    CUBE_BYTES as CUBE_BYTES,
)
from .horizon_curved import (
    sine_change as sine_change,
    bin_tangents as bin_tangents,
    CurvedHorizon as CurvedHorizon,
)
from .microshadow_filament import (
    MicroshadowFilament as MicroshadowFilament,
    micro_shadow as micro_shadow,
)
from .microshadow_hdrp import (
    MicroshadowHDRP as MicroshadowHDRP,
    DEFAULT_OPACITY as DEFAULT_OPACITY,
)
from .perpixel import (
    PerPixelFactor as PerPixelFactor,
    FactorKernel as FactorKernel,
    BaseShadow as BaseShadow,
    Texture as Texture,
    TEXTURES as TEXTURES,
    stored as stored,
    texture_bytes as texture_bytes,
    add_storage_flag as add_storage_flag,
    through as through,
)
from .pom import (
    RayMarchShadow as RayMarchShadow,
    DEFAULT_STEPS as DEFAULT_STEPS,
    DEFAULT_SOFTNESS as DEFAULT_SOFTNESS,
    TRADEOFF_STEPS as TRADEOFF_STEPS,
    SKIP_RADIUS as SKIP_RADIUS,
    SkipTable as SkipTable,
)
from .registry import (
    REGISTRY as REGISTRY,
    Technique as Technique,
    Context as Context,
    Variant as Variant,
    Unavailable as Unavailable,
    get as get,
    names as names,
    defaults as defaults,
    select as select,
    bake_needs as bake_needs,
)
from .ssbump import (
    SSBump as SSBump,
)
from .surface import (
    FlatShading as FlatShading,
    Unshadowed as Unshadowed,
    unshadowed as unshadowed,
    HeightFieldShadow as HeightFieldShadow,
    NOT_MODELLED as NOT_MODELLED,
)
from .terminator import (
    Terminator as Terminator,
    conty as conty,
    chiang as chiang,
)
from .terrain import (
    TerrainShadow as TerrainShadow,
    SweepPlan as SweepPlan,
    plan_sweep as plan_sweep,
    boundaries_numpy as boundaries_numpy,
    factor_numpy as factor_numpy,
    DEFAULT_RAMP as DEFAULT_RAMP,
    FLOOR_ELEVATION_DEG as FLOOR_ELEVATION_DEG,
    MAX_ELEVATION_DEG as MAX_ELEVATION_DEG,
    MAX_PRIME_TILES as MAX_PRIME_TILES,
    IMPLS as IMPLS,
)
