/*
 * Draw directions from an acdf sampler through the C interface.
 *
 *   sample MATERIAL SAMPLER WO_X,WO_Y,WO_Z N
 *       N draws for the outgoing direction wo (local shading frame) from
 *       the pairs u_k = ((k + 0.5) / N, frac(0.5 + k * 0.6180339887)):
 *       one line "u0,u1,wi_x,wi_y,wi_z,pdf,pdf_again" per draw, where
 *       pdf_again is acdf_sampler_pdf of the drawn wi (0,0,0,0 for no draw).
 *   sample --env MAP SAMPLER N_X,N_Y,N_Z N
 *       the same for an environment sampler and a shading normal (the
 *       map's frame): "u0,u1,x,y,z,pdf,pdf_again".
 *
 * Failures print acdf_last_error() and exit with status 1.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "acdf.h"

static int parse3(const char *s, float v[3]) {
    return sscanf(s, "%f,%f,%f", &v[0], &v[1], &v[2]) == 3;
}

static int fail(const char *what) {
    fprintf(stderr, "%s: %s\n", what, acdf_last_error());
    return 1;
}

static void pair(unsigned long k, unsigned long n, float u[2]) {
    double a = 0.5 + (double)k * 0.6180339887498949;
    u[0] = (float)(((double)k + 0.5) / (double)n);
    u[1] = (float)(a - floor(a));
}

static int brdf(const char *spec, const char *name, const float wo[3], unsigned long n) {
    AcdfMaterial *m = acdf_material_load(spec);
    if (!m) return fail("acdf_material_load");
    AcdfSampler *s = acdf_sampler_new(m, name);
    if (!s) {
        acdf_material_free(m);
        return fail("acdf_sampler_new");
    }
    for (unsigned long k = 0; k < n; ++k) {
        float u[2], wi[3], pdf;
        pair(k, n, u);
        if (acdf_sampler_sample(s, wo, u, wi, &pdf)) {
            printf("%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n", u[0], u[1], wi[0], wi[1], wi[2], pdf,
                   acdf_sampler_pdf(s, wo, wi));
        } else {
            printf("%.9g,%.9g,0,0,0,0,0\n", u[0], u[1]);
        }
    }
    fprintf(stderr, "%s: %zu bytes of tables\n", name, acdf_sampler_storage_bytes(s));
    acdf_sampler_free(s);
    acdf_material_free(m);
    return 0;
}

static int env(const char *path, const char *name, const float normal[3], unsigned long n) {
    AcdfEnvMap *map = acdf_envmap_load(path);
    if (!map) return fail("acdf_envmap_load");
    AcdfEnvSampler *s = acdf_env_sampler_new(map, name);
    if (!s) {
        acdf_envmap_free(map);
        return fail("acdf_env_sampler_new");
    }
    for (unsigned long k = 0; k < n; ++k) {
        float u[2], dir[3], pdf;
        pair(k, n, u);
        if (acdf_env_sampler_sample(s, normal, u, dir, &pdf)) {
            printf("%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n", u[0], u[1], dir[0], dir[1], dir[2], pdf,
                   acdf_env_sampler_pdf(s, normal, dir));
        } else {
            printf("%.9g,%.9g,0,0,0,0,0\n", u[0], u[1]);
        }
    }
    acdf_env_sampler_free(s);
    acdf_envmap_free(map);
    return 0;
}

int main(int argc, char **argv) {
    float v[3];
    if (argc == 6 && argv[1][0] == '-' && parse3(argv[4], v))
        return env(argv[2], argv[3], v, strtoul(argv[5], NULL, 10));
    if (argc == 5 && parse3(argv[3], v))
        return brdf(argv[1], argv[2], v, strtoul(argv[4], NULL, 10));
    fprintf(stderr, "usage: %s MATERIAL SAMPLER WO_X,WO_Y,WO_Z N\n"
                    "       %s --env MAP SAMPLER N_X,N_Y,N_Z N\n", argv[0], argv[0]);
    return 2;
}
