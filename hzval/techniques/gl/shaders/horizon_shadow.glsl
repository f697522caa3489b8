// Horizon mapping: Lengyel, "Smooth Horizon Mapping", GPU Zen 2 (2019), ch. 5,
// Listing 5.1, corrected and split so that an engine can call it.
//
// Validated by hzval: the `horizon-gl` technique runs this file on OpenGL
// (hzval/horizon_gl.py) and tests/techniques/gl/test_horizon_gl.py checks it against hzval's
// own emulation of the GPU (`hzval sweep --path gpu`), which is itself scored
// against Mitsuba's ray-traced truth.
//
// What was corrected in the listing:
//   * `float4` is HLSL; GLSL's type is `vec4`.
//   * The listing's `color = ...` placeholder is left to the caller: these
//     functions return the illumination factor F; multiply your light's
//     contribution by it (ambient light is not shadowed by it).
//   * The factor cube map must be sampled at level 0 with seamless cube
//     filtering enabled (glEnable(GL_TEXTURE_CUBE_MAP_SEAMLESS), on by default
//     only in GL ES 3 and Vulkan): without it, lights within half a cube texel
//     of a face edge get factors up to 0.13 wrong (hzval issue 31).
//
// Conventions (hzval.conventions):
//   * Tangent space: +x right on screen (increasing column), +y up on screen
//     (decreasing row), +z out of the surface. `L` points toward the light.
//   * horizonMap: a 2-D array texture of two RGBA8 layers; layer 0 holds the
//     horizon sines (the sine of the horizon's elevation) toward azimuths 0,
//     45, 90, 135 degrees (counterclockwise from +x), layer 1 toward 180, 225,
//     270, 315. Texture row 0 (t = 0) is the top row of the image.
//   * factorCube: the 16 x 16 RGBA8 channel-factor cube (hzval.bake.weight_cube):
//     component c holds (w_c - w_{c+4} + 1) / 2, the linear interpolation
//     weights between the two channels adjacent to L's azimuth.
//   * hardness: k of eq. 5.4; Lengyel's kShadowHardness is 8.

#ifndef HORIZON_SHADOW_GLSL
#define HORIZON_SHADOW_GLSL

const float kShadowHardness = 8.0;

// Eq. 5.3 and 5.4 from the filtered texels: `factors` the cube's texel, `h0`
// and `h1` the two layers of the horizon map. Returns F in [0, 1].
float horizonFactor(vec4 factors, vec4 h0, vec4 h1, float Lz, float hardness)
{
    // Positive factors weigh layer 0, negative ones layer 1 (eq. 5.3).
    vec4 f0 = clamp(factors * 2.0 - 1.0, 0.0, 1.0);
    vec4 f1 = clamp(factors * -2.0 + 1.0, 0.0, 1.0);
    // The horizon's sine toward the light's azimuth.
    float s = dot(h0, f0) + dot(h1, f1);
    // Eq. 5.4, clamped instead of max() (free saturation on most GPUs).
    return clamp((Lz - s) * hardness + 1.0, 0.0, 1.0);
}

// In a fragment shader: implicit derivatives choose the horizon map's mip level.
// `L` must be normalised before its z is used.
float horizonShadow(sampler2DArray horizonMap, samplerCube factorCube, vec2 texcoord, vec3 L, float hardness)
{
    vec4 factors = textureLod(factorCube, L, 0.0);
    vec4 h0 = texture(horizonMap, vec3(texcoord, 0.0));
    vec4 h1 = texture(horizonMap, vec3(texcoord, 1.0));
    return horizonFactor(factors, h0, h1, L.z, hardness);
}

// The same with explicit derivatives of texcoord across the pixel (x and y of
// the screen), for a deferred or compute pass, or wherever the implicit ones
// are not the footprint's (hzval's sample pass).
float horizonShadowGrad(sampler2DArray horizonMap, samplerCube factorCube, vec2 texcoord,
                        vec2 dx, vec2 dy, vec3 L, float hardness)
{
    vec4 factors = textureLod(factorCube, L, 0.0);
    vec4 h0 = textureGrad(horizonMap, vec3(texcoord, 0.0), dx, dy);
    vec4 h1 = textureGrad(horizonMap, vec3(texcoord, 1.0), dx, dy);
    return horizonFactor(factors, h0, h1, L.z, hardness);
}

#endif
