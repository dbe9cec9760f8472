use acdf::cosine::CosineSampler;
use acdf::lambert_albedo_estimate;
use acdf_core::Vec3;

fn main() {
    let rho = 0.8;
    let (mean, se) = lambert_albedo_estimate(&CosineSampler, rho, Vec3::Z, 100_000, 1);
    println!("cosine sampler, Lambertian albedo {rho}: estimate {mean:.6} ± {se:.2e}");
}
