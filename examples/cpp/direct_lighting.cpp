// Direct lighting of a measured material under an environment map, through
// acdf's C interface with small RAII wrappers.
//
//   direct_lighting MATERIAL MAP NORMAL_THETA,NORMAL_PHI WO_THETA,WO_PHI N
//
// estimates the reflected radiance L_o(wo) = ∫ f_r(wo, wi) L(wi) cos θ_i dwi
// at a point whose shading normal points at (θ, φ) in the map's frame
// (degrees), for wo at (θ, φ) in the local shading frame, three ways with N
// draws each: BRDF sampling (adaptive:chi2), light sampling (the
// orientation-aware oriented:dp, which knows the normal) and both combined
// by multiple importance sampling (balance heuristic, N draws of each).
// Each line: "strategy,estimate_r,estimate_g,estimate_b,stderr_luminance".
//
// The local frame: z is the normal n; x is the unit vector along
// (0, 0, 1) x n (along (1, 0, 0) x n when n is nearly vertical); y = n x x.
#include <array>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <stdexcept>
#include <string>

#include "acdf.h"

namespace acdf {

using Vec = std::array<float, 3>;

[[noreturn]] void raise(const char *what) {
    throw std::runtime_error(std::string(what) + ": " + acdf_last_error());
}

template <typename T, void (*Free)(T *)>
struct Deleter {
    void operator()(T *p) const { Free(p); }
};

// A material: f_r(wo, wi) in the local frame.
class Material {
   public:
    explicit Material(const std::string &spec) : p_(acdf_material_load(spec.c_str())) {
        if (!p_) raise("loading the material");
    }
    Vec eval(const Vec &wo, const Vec &wi) const {
        Vec rgb;
        acdf_material_eval(p_.get(), wo.data(), wi.data(), rgb.data());
        return rgb;
    }
    const AcdfMaterial *get() const { return p_.get(); }

   private:
    std::unique_ptr<AcdfMaterial, Deleter<AcdfMaterial, acdf_material_free>> p_;
};

// A BRDF sampler; sample() returns false for no draw.
class Sampler {
   public:
    Sampler(const Material &m, const std::string &name) : p_(acdf_sampler_new(m.get(), name.c_str())) {
        if (!p_) raise("making the BRDF sampler");
    }
    bool sample(const Vec &wo, float u0, float u1, Vec &wi, float &pdf) const {
        const float u[2] = {u0, u1};
        return acdf_sampler_sample(p_.get(), wo.data(), u, wi.data(), &pdf) == 1;
    }
    float pdf(const Vec &wo, const Vec &wi) const { return acdf_sampler_pdf(p_.get(), wo.data(), wi.data()); }

   private:
    std::unique_ptr<AcdfSampler, Deleter<AcdfSampler, acdf_sampler_free>> p_;
};

// An environment map and its radiance.
class EnvMap {
   public:
    explicit EnvMap(const std::string &path) : p_(acdf_envmap_load(path.c_str())) {
        if (!p_) raise("loading the environment map");
    }
    Vec radiance(const Vec &dir) const {
        Vec rgb;
        acdf_envmap_radiance(p_.get(), dir.data(), rgb.data());
        return rgb;
    }
    const AcdfEnvMap *get() const { return p_.get(); }

   private:
    std::unique_ptr<AcdfEnvMap, Deleter<AcdfEnvMap, acdf_envmap_free>> p_;
};

// A sampler of directions towards a map, given the shading normal.
class EnvSampler {
   public:
    EnvSampler(const EnvMap &map, const std::string &name)
        : p_(acdf_env_sampler_new(map.get(), name.c_str())) {
        if (!p_) raise("making the environment sampler");
    }
    bool sample(const Vec &normal, float u0, float u1, Vec &dir, float &pdf) const {
        const float u[2] = {u0, u1};
        return acdf_env_sampler_sample(p_.get(), normal.data(), u, dir.data(), &pdf) == 1;
    }
    float pdf(const Vec &normal, const Vec &dir) const {
        return acdf_env_sampler_pdf(p_.get(), normal.data(), dir.data());
    }

   private:
    std::unique_ptr<AcdfEnvSampler, Deleter<AcdfEnvSampler, acdf_env_sampler_free>> p_;
};

}  // namespace acdf

namespace {

using acdf::Vec;

Vec spherical(float theta_deg, float phi_deg) {
    const double t = theta_deg * M_PI / 180.0, p = phi_deg * M_PI / 180.0;
    return {float(std::sin(t) * std::cos(p)), float(std::sin(t) * std::sin(p)), float(std::cos(t))};
}

float dot(const Vec &a, const Vec &b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

Vec cross(const Vec &a, const Vec &b) {
    return {a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]};
}

Vec normalized(const Vec &v) {
    const float l = std::sqrt(dot(v, v));
    return {v[0] / l, v[1] / l, v[2] / l};
}

// The shading frame of a normal (see the file's comment).
struct Frame {
    Vec x, y, n;
    explicit Frame(const Vec &normal) : n(normal) {
        const Vec up = std::fabs(n[2]) < 0.999f ? Vec{0, 0, 1} : Vec{1, 0, 0};
        x = normalized(cross(up, n));
        y = cross(n, x);
    }
    Vec to_local(const Vec &w) const { return {dot(w, x), dot(w, y), dot(w, n)}; }
    Vec to_world(const Vec &v) const {
        return {x[0] * v[0] + y[0] * v[1] + n[0] * v[2], x[1] * v[0] + y[1] * v[1] + n[1] * v[2],
                x[2] * v[0] + y[2] * v[1] + n[2] * v[2]};
    }
};

// A running mean of RGB estimates and the variance of their luminance.
struct Mean {
    double sum[3] = {0, 0, 0}, y = 0, y2 = 0;
    unsigned long n = 0;
    void add(const Vec &v) {
        for (int c = 0; c < 3; ++c) sum[c] += v[c];
        const double l = 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
        y += l;
        y2 += l * l;
        ++n;
    }
    void print(const char *name) const {
        const double m = y / n, var = (y2 / n - m * m) / (n - 1);
        std::printf("%s,%.6g,%.6g,%.6g,%.6g\n", name, sum[0] / n, sum[1] / n, sum[2] / n,
                    std::sqrt(var > 0 ? var : 0));
    }
};

// u_k of stream `stream`: the R2 sequence (the plastic number's powers),
// shifted per stream, so that the two strategies draw independently.
void pair(unsigned long k, int stream, float &u0, float &u1) {
    const double a = 0.5 + stream * 0.37 + k * 0.7548776662466927;
    const double b = 0.5 + stream * 0.61 + k * 0.5698402909980532;
    u0 = float(a - std::floor(a));
    u1 = float(b - std::floor(b));
}

Vec scaled(const Vec &a, const Vec &b, float s) { return {a[0] * b[0] * s, a[1] * b[1] * s, a[2] * b[2] * s}; }

}  // namespace

int main(int argc, char **argv) {
    if (argc != 6) {
        std::fprintf(stderr, "usage: %s MATERIAL MAP NORMAL_THETA,NORMAL_PHI WO_THETA,WO_PHI N\n", argv[0]);
        return 2;
    }
    float nt, np, wt, wp;
    if (std::sscanf(argv[3], "%f,%f", &nt, &np) != 2 || std::sscanf(argv[4], "%f,%f", &wt, &wp) != 2) {
        std::fprintf(stderr, "angles are THETA,PHI in degrees\n");
        return 2;
    }
    const unsigned long n = std::strtoul(argv[5], nullptr, 10);
    try {
        const acdf::Material material(argv[1]);
        const acdf::Sampler brdf(material, "adaptive:chi2");
        const acdf::EnvMap map(argv[2]);
        const acdf::EnvSampler light(map, "oriented:dp");
        const Vec normal = spherical(nt, np);
        const Frame frame(normal);
        const Vec wo = spherical(wt, wp);

        Mean by_brdf, by_light, mis;
        for (unsigned long k = 0; k < n; ++k) {
            float u0, u1, pdf;
            // BRDF sampling.
            Vec wi, est = {0, 0, 0}, mis_est = {0, 0, 0};
            pair(k, 0, u0, u1);
            if (brdf.sample(wo, u0, u1, wi, pdf)) {
                const Vec dir = frame.to_world(wi);
                const Vec fl = scaled(material.eval(wo, wi), map.radiance(dir), wi[2]);
                est = scaled(fl, {1, 1, 1}, 1 / pdf);
                const float other = light.pdf(normal, dir);
                mis_est = scaled(fl, {1, 1, 1}, 1 / (pdf + other));
            }
            by_brdf.add(est);
            // Light sampling.
            Vec dir, light_est = {0, 0, 0};
            pair(k, 1, u0, u1);
            if (light.sample(normal, u0, u1, dir, pdf)) {
                const Vec wi_local = frame.to_local(dir);
                if (wi_local[2] > 0) {
                    const Vec fl = scaled(material.eval(wo, wi_local), map.radiance(dir), wi_local[2]);
                    light_est = scaled(fl, {1, 1, 1}, 1 / pdf);
                    const float other = brdf.pdf(wo, wi_local);
                    const Vec m = scaled(fl, {1, 1, 1}, 1 / (pdf + other));
                    for (int c = 0; c < 3; ++c) mis_est[c] += m[c];
                }
            }
            by_light.add(light_est);
            mis.add(mis_est);
        }
        by_brdf.print("brdf");
        by_light.print("light");
        mis.print("mis");
    } catch (const std::exception &e) {
        std::fprintf(stderr, "%s\n", e.what());
        return 1;
    }
    return 0;
}
