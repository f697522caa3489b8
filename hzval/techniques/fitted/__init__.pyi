# Written by tests/stubs.py from each module's __all__ (python -m tests.stubs); do not edit.
from . import fit, guard, horizon_fit, model, perpixel_fit, store, textures, training
from .fit import (
    LEARNING_RATE as LEARNING_RATE,
    MAX_EPOCHS as MAX_EPOCHS,
    MAX_K as MAX_K,
    CONSTRAIN as CONSTRAIN,
    FitResult as FitResult,
    guarded as guarded,
    truths as truths,
)
from .guard import (
    ROUNDS as ROUNDS,
    neighbourhood_sum as neighbourhood_sum,
)
from .horizon_fit import (
    FittedHorizon as FittedHorizon,
)
from .model import (
    CHARBONNIER_EPS as CHARBONNIER_EPS,
    BATCH_LIGHTS as BATCH_LIGHTS,
    HALVINGS as HALVINGS,
    CONSTRAINT_FLOOR as CONSTRAINT_FLOOR,
    LightBatches as LightBatches,
    light_vectors as light_vectors,
    optimise as optimise,
    reweight as reweight,
    clip_unit as clip_unit,
    run_record as run_record,
)
from .perpixel_fit import (
    FittedTextures as FittedTextures,
    FittedFilament as FittedFilament,
    FittedHDRP as FittedHDRP,
    FittedBentCone as FittedBentCone,
    FittedSSBump as FittedSSBump,
    split as split,
)
from .store import (
    FIT_VERSION as FIT_VERSION,
    write_fit as write_fit,
    read_fit as read_fit,
    write_texture_fit as write_texture_fit,
    read_texture_fit as read_texture_fit,
    cache_key as cache_key,
    cached_fit as cached_fit,
    cached_texture_fit as cached_texture_fit,
)
from .textures import (
    SEARCH_STRIDE as SEARCH_STRIDE,
    TextureFit as TextureFit,
    TextureModel as TextureModel,
    fittable as fittable,
    check_fittable as check_fittable,
    separable as separable,
    search as search,
    facing_errors as facing_errors,
    fit_textures as fit_textures,
)
from .training import (
    check_held_out as check_held_out,
    TRAINING_LIGHTS as TRAINING_LIGHTS,
    HELD_OUT_LIGHTS as HELD_OUT_LIGHTS,
    TRAINING_SAMPLES as TRAINING_SAMPLES,
    BAND_SAMPLES as BAND_SAMPLES,
    parse_lights as parse_lights,
    training_spp as training_spp,
    fit_scene as fit_scene,
    visibility as visibility,
    estimate_bytes as estimate_bytes,
    check_fits as check_fits,
    light_errors as light_errors,
    mean_error as mean_error,
)
