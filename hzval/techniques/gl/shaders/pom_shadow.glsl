// Ray-marched height-field shadows, as parallax occlusion mapping casts them
// (Tatarchuk, "Dynamic parallax occlusion mapping with approximate soft
// shadows", I3D 2006): hzval's `pom` technique (hzval/pom.py) in GLSL.
//
// Validated by hzval: the `pom-gl` technique runs this file on OpenGL
// (hzval/horizon_gl.py) against hzval's Dr.Jit `pom`, which is scored
// against Mitsuba's ray-traced truth.
//
// Conventions (hzval.conventions): tangent space in texel units, +x right,
// +y up on screen, +z out of the surface. heightMap holds heights in texels
// (H * depth * width) in its red channel, filtered bilinearly at level 0;
// its row 0 (t = 0) is the image's top row, so one texel toward +y is
// -1/rows in t.
//
//   uvStep  one texel toward the light's azimuth phi in texture coordinates:
//           (cos(phi) / cols, -sin(phi) / rows)
//   tanE    tan of the light's elevation (> 0)
//   hMax    the highest height of the map, texels: the ray leaves the relief there
//   steps   N linear steps, sampling t_i = i t_max / N, i = 1..N
//   eps     how far a sample must rise above the ray to block it (a few
//           ulps of the heights: bilinear filtering of a flat patch is not exact)
//   softness  0: the hard test (F = 0 if any sample is above the ray);
//           w > 0: Tatarchuk's soft shadow, F = clamp(1 - w max_i (H_i - z_i) / t_i, 0, 1)
//   openTile  true: nothing exists beyond the tile's border (a terrain);
//           false: the texture repeats (set its wrap mode to GL_REPEAT)

#ifndef POM_SHADOW_GLSL
#define POM_SHADOW_GLSL

float pomShadow(sampler2D heightMap, vec2 uv, vec2 uvStep, float tanE, float hMax,
                int steps, float eps, float softness, bool openTile)
{
    float h0 = textureLod(heightMap, uv, 0.0).r;
    float tMax = max(hMax - h0, 0.0) / tanE;     // where the ray leaves the relief
    float dt = tMax / float(steps);
    float rise = 0.0;                            // the steepest blocker, as a tangent
    for (int i = 1; i <= steps; ++i) {
        float t = dt * float(i);
        vec2 p = uv + uvStep * t;
        float above = textureLod(heightMap, p, 0.0).r - (h0 + t * tanE) - eps;   // H_i - z_i
        if (openTile && (p.x < 0.0 || p.x > 1.0 || p.y < 0.0 || p.y > 1.0))
            above = -1.0;                        // nothing beyond the border
        if (softness > 0.0) {
            rise = max(rise, above / t);
        } else if (above > 0.0) {
            return 0.0;                          // a sample above the ray: in shadow
        }
    }
    return softness > 0.0 ? clamp(1.0 - softness * rise, 0.0, 1.0) : 1.0;
}

#endif
