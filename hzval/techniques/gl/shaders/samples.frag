// hzval's sample pass (not for an engine): one fragment per sample of the
// sweep, so that a GL technique reads its textures exactly where every other
// technique of the sweep does (hzval.lookup.Samples) and is scored like them.
// Sample i of the band sits at fragment (i % bandWidth, i / bandWidth); it is
// sample i % spp of pixel (first + i) / spp. The shadow function is chosen by
// a #define: HORIZON (horizon_shadow.glsl) or POM (pom_shadow.glsl), whose
// text is prepended.

uniform sampler2D samplePositions;   // RG32F: the sample's (u, v)
uniform sampler2D pixelFootprints;   // RGBA32F: (du/dcol, dv/dcol, du/drow, dv/drow)
uniform int firstSample;             // the band's first sample in the image
uniform int samplesPerPixel;
uniform int bandWidth;
uniform int footprintWidth;
uniform vec3 L;                      // toward the light, tangent space, unit

#ifdef HORIZON
uniform sampler2DArray horizonMap;
uniform samplerCube factorCube;
uniform float hardness;
#endif
#ifdef POM
uniform sampler2D heightMap;
uniform vec2 uvStep;
uniform float tanE;
uniform float hMax;
uniform int steps;
uniform float eps;
uniform float softness;
uniform bool openTile;
#endif

out float factor;

void main()
{
    ivec2 frag = ivec2(gl_FragCoord.xy);
    vec2 uv = texelFetch(samplePositions, frag, 0).xy;
#ifdef HORIZON
    int pixel = (firstSample + frag.y * bandWidth + frag.x) / samplesPerPixel;
    vec4 fp = texelFetch(pixelFootprints, ivec2(pixel % footprintWidth, pixel / footprintWidth), 0);
    factor = horizonShadowGrad(horizonMap, factorCube, uv, fp.xy, fp.zw, L, hardness);
#endif
#ifdef POM
    factor = pomShadow(heightMap, uv, uvStep, tanE, hMax, steps, eps, softness, openTile);
#endif
}
