/*
 * Draw directions from acdf's samplers through the C interface.
 *
 *   sample MATERIAL SAMPLER WO_X,WO_Y,WO_Z < PAIRS
 *       for each line "u0,u1" of standard input, one draw for the outgoing
 *       direction wo (local shading frame), printed as `acdf sample` prints
 *       it: "wi_x,wi_y,wi_z,pdf,1", or "0,0,0,0,0" for no draw.
 *   sample --env MAP SAMPLER N_X,N_Y,N_Z < PAIRS
 *       the same for an environment sampler and a shading normal in the
 *       map's frame, as `acdf env-sample` prints it: "x,y,z,pdf", or
 *       "0,0,0,0".
 *   sample --bench MATERIAL SAMPLER N
 *       the time of N draws for one wo, one call at a time and as one
 *       batch, in nanoseconds per draw (tables built first).
 *
 * Failures print acdf_last_error() and exit with status 1.
 */
#define _POSIX_C_SOURCE 199309L
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "acdf.h"

static int parse3(const char *s, float v[3]) {
    return sscanf(s, "%f,%f,%f", &v[0], &v[1], &v[2]) == 3;
}

static int fail(const char *what) {
    fprintf(stderr, "%s: %s\n", what, acdf_last_error());
    return 1;
}

static int brdf(const char *spec, const char *name, const float wo[3]) {
    AcdfMaterial *m = acdf_material_load(spec);
    if (!m) return fail("acdf_material_load");
    AcdfSampler *s = acdf_sampler_new(m, name);
    if (!s) {
        acdf_material_free(m);
        return fail("acdf_sampler_new");
    }
    float u[2], wi[3], pdf;
    while (scanf("%f,%f", &u[0], &u[1]) == 2) {
        if (acdf_sampler_sample(s, wo, u, wi, &pdf))
            printf("%.9g,%.9g,%.9g,%.9g,1\n", wi[0], wi[1], wi[2], pdf);
        else
            printf("0,0,0,0,0\n");
    }
    acdf_sampler_free(s);
    acdf_material_free(m);
    return 0;
}

static int env(const char *path, const char *name, const float normal[3]) {
    AcdfEnvMap *map = acdf_envmap_load(path);
    if (!map) return fail("acdf_envmap_load");
    AcdfEnvSampler *s = acdf_env_sampler_new(map, name);
    if (!s) {
        acdf_envmap_free(map);
        return fail("acdf_env_sampler_new");
    }
    float u[2], dir[3], pdf;
    while (scanf("%f,%f", &u[0], &u[1]) == 2) {
        if (acdf_env_sampler_sample(s, normal, u, dir, &pdf))
            printf("%.9g,%.9g,%.9g,%.9g\n", dir[0], dir[1], dir[2], pdf);
        else
            printf("0,0,0,0\n");
    }
    acdf_env_sampler_free(s);
    acdf_envmap_free(map);
    return 0;
}

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int bench(const char *spec, const char *name, size_t n) {
    AcdfMaterial *m = acdf_material_load(spec);
    if (!m) return fail("acdf_material_load");
    AcdfSampler *s = acdf_sampler_new(m, name);
    if (!s) {
        acdf_material_free(m);
        return fail("acdf_sampler_new");
    }
    const float wo[3] = {0.5f, 0.0f, 0.8660254f};
    float *u = malloc(2 * n * sizeof *u), *wi = malloc(3 * n * sizeof *wi), *pdf = malloc(n * sizeof *pdf);
    if (!u || !wi || !pdf) return 1;
    unsigned long x = 88172645463325252ul; /* xorshift64 */
    for (size_t k = 0; k < 2 * n; ++k) {
        x ^= x << 13, x ^= x >> 7, x ^= x << 17;
        u[k] = (float)(x >> 40) / 16777216.0f;
    }
    acdf_sampler_sample_batch(s, wo, u, n, wi, pdf); /* builds the tables */
    double best_single = 1e30, best_batch = 1e30, sum = 0;
    for (int pass = 0; pass < 3; ++pass) {
        double t = now();
        for (size_t k = 0; k < n; ++k) {
            float d[3], p = 0;
            acdf_sampler_sample(s, wo, u + 2 * k, d, &p);
            sum += p;
        }
        t = now() - t;
        if (t < best_single) best_single = t;
        t = now();
        acdf_sampler_sample_batch(s, wo, u, n, wi, pdf);
        t = now() - t;
        if (t < best_batch) best_batch = t;
    }
    printf("%s,%.1f,%.1f\n", name, 1e9 * best_single / n, 1e9 * best_batch / n);
    fprintf(stderr, "(checksum %g)\n", sum);
    free(u), free(wi), free(pdf);
    acdf_sampler_free(s);
    acdf_material_free(m);
    return 0;
}

int main(int argc, char **argv) {
    float v[3];
    if (argc == 5 && strcmp(argv[1], "--env") == 0 && parse3(argv[4], v)) return env(argv[2], argv[3], v);
    if (argc == 5 && strcmp(argv[1], "--bench") == 0) return bench(argv[2], argv[3], strtoul(argv[4], NULL, 10));
    if (argc == 4 && parse3(argv[3], v)) return brdf(argv[1], argv[2], v);
    fprintf(stderr,
            "usage: %s MATERIAL SAMPLER WO_X,WO_Y,WO_Z < PAIRS\n"
            "       %s --env MAP SAMPLER N_X,N_Y,N_Z < PAIRS\n"
            "       %s --bench MATERIAL SAMPLER N\n",
            argv[0], argv[0], argv[0]);
    return 2;
}
