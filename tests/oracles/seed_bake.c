/*
 * seed_bake.c -- the seed horizon bake (FGED2 ch. 7, ConstructHorizonMap;
 * Lengyel, GPU Zen 2 section 5.2) as a standalone C program: hzval's
 * independent peer for tests (tests/bake/test_horizon_peer.py) and its timing
 * baseline (benchmarks/bench_bake.py).
 *
 * Build (literal seed loop, the default; and the hoisted-table variant):
 *   gcc -O3 -march=native -fopenmp -o seed_bake seed_bake.c -lm
 *   gcc -O3 -march=native -fopenmp -DHOISTED_TABLE -o seed_bake_hoisted seed_bake.c -lm
 *
 * Usage:
 *   seed_bake IN.f32 ROWS COLS DEPTH RADIUS ANGLES wrap|open OUT.f32
 *
 * IN  is raw little-endian float32 H[row][col] (normalised heights).
 * OUT is raw float32 [row][col][10]: the 8 channel sines (channel k toward
 *     azimuth 45k degrees), then mean_cos and mean_cos2.
 * The time of the bake loop alone (for -DHOISTED_TABLE including building
 * the table) is printed to stderr, with the variant's name.
 *
 * The loop body is the seed's, statement for statement, in the same float32
 * math (atan2f, atanf, sqrtf, floorf, ceilf, fmaxf). The ONLY deliberate
 * changes, each marked "CHANGE (x)" where it is made, are:
 *   (a) radius, angle count and boundary are run-time parameters; the angle
 *       count must be a multiple of 16, and "& (N - 1)" becomes a positive
 *       modulo "% N" (pmod) so that any multiple of 16 works;
 *   (b) any image size: "wrap" uses a positive modulo instead of
 *       "& (width - 1)"; "open" skips neighbours outside the image;
 *   (c) hzval's conventions: row 0 is the TOP of the image and tangent +y is
 *       UP, so the neighbour at tangent offset (i, j) is at pixel
 *       (row - j, col + i); direction = atan2f(j, i) stays as in the seed;
 *   (d) heights are converted to texel units first: h = H * depth * cols
 *       (the original design notes, "height scale");
 *   (e) the ambient output is the average (the seed's "sum * kAngleCount"
 *       means one), without the seed's pow(., ambientPower):
 *       mean_cos = mean of 1/sqrt(t+1), and also mean_cos2 = mean of 1/(t+1);
 *   (f) two_pi is the float constant 6.2831855f and
 *       kAngleIndex = float(N) / two_pi is computed in float;
 *   (g) ONLY when compiled with -DHOISTED_TABLE (the default build is the
 *       literal loop): the offset-to-bins table is computed once, before the
 *       texel loops, as the original design notes says ("The offset-to-bins table is the same
 *       for every texel: compute it once"). For every offset (i, j) with
 *       0 < r2 < R^2, in the seed's order (j outer, i inner), the table holds
 *       i, float(r2) and minIndex/maxIndex computed by the very same float
 *       expressions (atan2f, atanf, sqrtf, floorf, ceilf), grouped by j. The
 *       per-texel loop keeps the seed's j loop (one row lookup per j, same
 *       wrap/open handling) and walks row j's entries; per entry it does only
 *       what the seed does that does not depend on the offset alone: fetch
 *       the neighbour height (same wrap/open handling), the dh > 0 test,
 *       t = dh*dh / float(r2) and the bin max loop. Nothing else is
 *       optimised (no SIMD intrinsics; the same bin loop with pmod). Every
 *       value and every fmaxf update are the same, in the same order, so the
 *       output is bit-identical to the literal variant's
 *       (tests/bake/test_horizon_peer.py checks it). This variant is the speed peer
 *       of benchmarks/bench_bake.py: the literal one recomputes atan2f, atanf
 *       and sqrtf for every texel and every higher neighbour.
 * Output layout (the 10-float record per texel instead of two ColorRGBA
 * layers and an ambient map) is I/O, not algorithm.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <omp.h>

#define OUT_CHANNELS 10

/* CHANGE (a), (b): positive modulo, replaces "& (n - 1)" (power-of-two only). */
static inline int pmod(int a, int n)
{
    int m = a % n;
    return m < 0 ? m + n : m;
}

static void ConstructHorizonMap(const float *heightMap, float *out,
                                int width, int height,
                                int kHorizonRadius, int kAngleCount, int wrap)
{
    /* CHANGE (f): two_pi as a float constant; kAngleIndex computed in float. */
    const float two_pi = 6.2831855f;
    const float kAngleIndex = (float)kAngleCount / two_pi;

#ifdef HOISTED_TABLE
    /* CHANGE (g): the offset-to-bins table, computed once for all texels:
     * the seed's j, i loops and r2 test, and its float expressions for
     * direction, delta, minIndex and maxIndex, unchanged. The entries of
     * row j (in the seed's i order) are tab*[rowStart[j + R - 1]] up to
     * tab*[rowStart[j + R] - 1], so that the texel loop keeps the seed's row
     * structure (one row lookup per j). */
    int side = 2*kHorizonRadius - 1;
    size_t cap = (size_t)side * (size_t)side;
    int *tabI = malloc(cap * sizeof(int));
    float *tabR2 = malloc(cap * sizeof(float));
    int *tabMin = malloc(cap * sizeof(int));
    int *tabMax = malloc(cap * sizeof(int));
    int *rowStart = malloc((size_t)(side + 1) * sizeof(int));
    if (!tabI || !tabR2 || !tabMin || !tabMax || !rowStart) {
        fprintf(stderr, "seed_bake: out of memory\n");
        exit(1);
    }
    int tabCount = 0;
    for (int j = -kHorizonRadius + 1; j < kHorizonRadius; j++)
    {
        rowStart[j + kHorizonRadius - 1] = tabCount;
        for (int i = -kHorizonRadius + 1; i < kHorizonRadius; i++)
        {
            int r2 = i*i + j*j;
            if ((r2 < kHorizonRadius*kHorizonRadius) && (r2 != 0))
            {
                float direction = atan2f((float)j, (float)i);
                float delta = atanf(0.7071f / sqrtf((float)r2));
                tabI[tabCount] = i;
                tabR2[tabCount] = (float)r2;
                tabMin[tabCount] = (int)floorf((direction - delta) * kAngleIndex);
                tabMax[tabCount] = (int)ceilf((direction + delta) * kAngleIndex);
                tabCount++;
            }
        }
    }
    rowStart[side] = tabCount;
#endif

    #pragma omp parallel for schedule(dynamic, 8)
    for (int y = 0; y < height; y++)
    {
        const float *centerRow = heightMap + (size_t)y * width;
        /* CHANGE (a): kAngleCount is a run-time value, so the array is a VLA. */
        float maxTan2[kAngleCount];
        for (int x = 0; x < width; x++)
        {
            // Get central height. Initialize max squared tangent array to all zeros.
            float h0 = centerRow[x];
            memset(maxTan2, 0, sizeof(float) * (size_t)kAngleCount);

            // Search neighborhood for larger heights
#ifdef HOISTED_TABLE
            /* CHANGE (g): walk the precomputed table, in the seed's order:
             * the seed's j loop, then row j's table entries in its i order. */
            for (int j = -kHorizonRadius + 1; j < kHorizonRadius; j++)
            {
                /* CHANGE (b), (c): as in the literal variant below. */
                int ry = y - j;
                if (wrap) ry = pmod(ry, height);
                else if (ry < 0 || ry >= height) continue;
                const float *row = heightMap + (size_t)ry * width;
                int eEnd = rowStart[j + kHorizonRadius];
                for (int e = rowStart[j + kHorizonRadius - 1]; e < eEnd; e++)
                {
                    int cx = x + tabI[e];
                    if (wrap) cx = pmod(cx, width);
                    else if (cx < 0 || cx >= width) continue;
                    float dh = row[cx] - h0;
                    if (dh > 0.0f)
                    {
                        // calculate squared tangent with equation 7.53
                        float t = dh*dh / tabR2[e];
                        for (int n = tabMin[e]; n <= tabMax[e]; n++)
                        {
                            int m = pmod(n, kAngleCount);  /* CHANGE (a) */
                            maxTan2[m] = fmaxf(maxTan2[m], t);
                        }
                    }
                }
            }
#else
            for (int j = -kHorizonRadius + 1; j < kHorizonRadius; j++)
            {
                /* CHANGE (c): tangent +y is up the image and row 0 is the top,
                 * so offset j is row y - j (the seed reads row y + j).
                 * CHANGE (b): wrap with a positive modulo; open skips rows
                 * outside the image. */
                int ry = y - j;
                if (wrap) ry = pmod(ry, height);
                else if (ry < 0 || ry >= height) continue;
                const float *row = heightMap + (size_t)ry * width;
                for (int i = -kHorizonRadius + 1; i < kHorizonRadius; i++)
                {
                    int r2 = i*i + j*j;
                    if ((r2 < kHorizonRadius*kHorizonRadius) && (r2 != 0))
                    {
                        /* CHANGE (b): wrap with a positive modulo; open skips
                         * columns outside the image. */
                        int cx = x + i;
                        if (wrap) cx = pmod(cx, width);
                        else if (cx < 0 || cx >= width) continue;
                        float dh = row[cx] - h0;
                        if (dh > 0.0f)
                        {
                            // larger height found, apply to array entries
                            float direction = atan2f((float)j, (float)i);
                            float delta = atanf(0.7071f / sqrtf((float)r2));

                            int minIndex = (int)floorf((direction - delta) * kAngleIndex);
                            int maxIndex = (int)ceilf((direction + delta) * kAngleIndex);

                            // calculate squared tangent with equation 7.53
                            float t = dh*dh / (float)r2;
                            for (int n = minIndex; n <= maxIndex; n++)
                            {
                                int m = pmod(n, kAngleCount);  /* CHANGE (a) */
                                maxTan2[m] = fmaxf(maxTan2[m], t);
                            }
                        }
                    }
                }
            }
#endif

            // Generate eight channels of horizon map
            float *texel = out + ((size_t)y * width + x) * OUT_CHANNELS;
            for (int layer = 0; layer < 2; layer++)
            {
                float red = 0.0f, green = 0.0f, blue = 0.0f, alpha = 0.0f;
                int firstIndex = kAngleCount/16 + layer * (kAngleCount/2);
                int lastIndex = firstIndex + kAngleCount/8;
                for (int index = firstIndex; index <= lastIndex; index++)
                {
                    float tr = maxTan2[pmod(index - kAngleCount/8, kAngleCount)];  /* CHANGE (a) */
                    float tg = maxTan2[index];
                    float tb = maxTan2[index + kAngleCount/8];
                    float ta = maxTan2[pmod(index + kAngleCount/4, kAngleCount)];  /* CHANGE (a) */

                    red += sqrtf(tr / (tr+1.0f));
                    green += sqrtf(tg / (tg+1.0f));
                    blue += sqrtf(tb / (tb+1.0f));
                    alpha += sqrtf(ta / (ta+1.0f));
                }
                // layerData[x] = color / float(kAngleCount/8 + 1);
                float count = (float)(kAngleCount/8 + 1);
                texel[4*layer + 0] = red / count;
                texel[4*layer + 1] = green / count;
                texel[4*layer + 2] = blue / count;
                texel[4*layer + 3] = alpha / count;
            }

            // generate ambient light factor
            float sum = 0.0f;
            float sum2 = 0.0f;  /* CHANGE (e): cosine-weighted term */
            for (int k = 0; k < kAngleCount; k++) {
                sum += 1.0f / sqrtf(maxTan2[k] + 1.0f);
                sum2 += 1.0f / (maxTan2[k] + 1.0f);  /* CHANGE (e) */
            }
            /* CHANGE (e): the seed writes pow(sum * float(kAngleCount),
             * ambientPower); an average is meant, and no power is applied. */
            texel[8] = sum / (float)kAngleCount;
            texel[9] = sum2 / (float)kAngleCount;
        }
    }
#ifdef HOISTED_TABLE
    free(tabI); free(tabR2); free(tabMin); free(tabMax); free(rowStart);
#endif
}

#ifdef HOISTED_TABLE
#define VARIANT "hoisted"  /* CHANGE (g) */
#else
#define VARIANT "literal"
#endif

static int usage(void)
{
    fprintf(stderr, "usage: seed_bake IN.f32 ROWS COLS DEPTH RADIUS ANGLES wrap|open OUT.f32\n");
    return 2;
}

int main(int argc, char **argv)
{
    if (argc != 9) return usage();
    const char *in_path = argv[1];
    int rows = atoi(argv[2]);
    int cols = atoi(argv[3]);
    double depth = strtod(argv[4], NULL);
    int radius = atoi(argv[5]);
    int angles = atoi(argv[6]);
    const char *boundary = argv[7];
    const char *out_path = argv[8];
    int wrap;
    if (strcmp(boundary, "wrap") == 0) wrap = 1;
    else if (strcmp(boundary, "open") == 0) wrap = 0;
    else return usage();
    if (rows < 1 || cols < 1 || radius < 1 || angles < 16 || angles % 16 != 0 || !(depth > 0.0)) {
        fprintf(stderr, "seed_bake: bad parameters (ROWS, COLS >= 1; RADIUS >= 1; "
                        "ANGLES a multiple of 16; DEPTH > 0)\n");
        return 2;
    }

    size_t n = (size_t)rows * cols;
    float *h = malloc(n * sizeof(float));
    float *out = malloc(n * OUT_CHANNELS * sizeof(float));
    if (!h || !out) { fprintf(stderr, "seed_bake: out of memory\n"); return 1; }

    FILE *f = fopen(in_path, "rb");
    if (!f) { perror(in_path); return 1; }
    if (fread(h, sizeof(float), n, f) != n) {
        fprintf(stderr, "seed_bake: %s: expected %zu float32 values\n", in_path, n);
        return 1;
    }
    fclose(f);

    /* CHANGE (d): heights in texel units, H * depth * cols, in float32 as
     * hzval.conventions.heights_in_texels computes them: the scale
     * depth * cols is computed in double and rounded once to float. */
    float scale = (float)(depth * (double)cols);
    for (size_t k = 0; k < n; k++) h[k] = h[k] * scale;

    double t0 = omp_get_wtime();
    ConstructHorizonMap(h, out, cols, rows, radius, angles, wrap);
    double t1 = omp_get_wtime();
    fprintf(stderr, "loop_s %.6f threads %d variant %s\n", t1 - t0, omp_get_max_threads(), VARIANT);

    f = fopen(out_path, "wb");
    if (!f) { perror(out_path); return 1; }
    if (fwrite(out, sizeof(float), n * OUT_CHANNELS, f) != n * OUT_CHANNELS) {
        perror(out_path);
        return 1;
    }
    fclose(f);
    free(h);
    free(out);
    return 0;
}
