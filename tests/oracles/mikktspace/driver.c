/* The reference MikkTSpace (mikktspace.c, Morten S. Mikkelsen, zlib licence) run on a mesh of
 * triangles, the tests' oracle for hzval.geometry.mikktspace.
 *
 * usage: driver IN OUT
 * IN:  int32 face count F, then per corner (F * 3, face-major) 8 float32: position xyz,
 *      normal xyz, texture coordinate uv.
 * OUT: per corner 4 float32: tangent xyz and sign (setTSpaceBasic's).
 */
#include <stdio.h>
#include <stdlib.h>
#include "mikktspace.h"

typedef struct { int faces; float *in; float *out; } Mesh;

static int num_faces(const SMikkTSpaceContext *c) { return ((Mesh *)c->m_pUserData)->faces; }
static int num_verts(const SMikkTSpaceContext *c, const int f) { (void)c; (void)f; return 3; }
static const float *corner(const SMikkTSpaceContext *c, int f, int v) {
    return ((Mesh *)c->m_pUserData)->in + (f * 3 + v) * 8;
}
static void position(const SMikkTSpaceContext *c, float out[], const int f, const int v) {
    const float *p = corner(c, f, v); out[0] = p[0]; out[1] = p[1]; out[2] = p[2];
}
static void normal(const SMikkTSpaceContext *c, float out[], const int f, const int v) {
    const float *p = corner(c, f, v); out[0] = p[3]; out[1] = p[4]; out[2] = p[5];
}
static void texcoord(const SMikkTSpaceContext *c, float out[], const int f, const int v) {
    const float *p = corner(c, f, v); out[0] = p[6]; out[1] = p[7];
}
static void tspace(const SMikkTSpaceContext *c, const float t[], const float sign, const int f, const int v) {
    float *o = ((Mesh *)c->m_pUserData)->out + (f * 3 + v) * 4;
    o[0] = t[0]; o[1] = t[1]; o[2] = t[2]; o[3] = sign;
}

int main(int argc, char **argv) {
    if (argc != 3) { fprintf(stderr, "usage: driver IN OUT\n"); return 2; }
    FILE *fin = fopen(argv[1], "rb");
    Mesh m;
    if (!fin || fread(&m.faces, 4, 1, fin) != 1) return 1;
    m.in = malloc(sizeof(float) * 24 * m.faces);
    m.out = calloc(12 * m.faces, sizeof(float));
    if (fread(m.in, sizeof(float), 24 * (size_t)m.faces, fin) != 24 * (size_t)m.faces) return 1;
    fclose(fin);
    SMikkTSpaceInterface iface = {0};
    iface.m_getNumFaces = num_faces;
    iface.m_getNumVerticesOfFace = num_verts;
    iface.m_getPosition = position;
    iface.m_getNormal = normal;
    iface.m_getTexCoord = texcoord;
    iface.m_setTSpaceBasic = tspace;
    SMikkTSpaceContext ctx = {&iface, &m};
    if (!genTangSpaceDefault(&ctx)) return 1;
    FILE *fout = fopen(argv[2], "wb");
    fwrite(m.out, sizeof(float), 12 * (size_t)m.faces, fout);
    fclose(fout);
    return 0;
}
