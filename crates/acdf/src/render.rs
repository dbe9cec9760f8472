//! A test scene for samplers: a unit sphere of one material, lit only by an
//! environment, seen by an orthographic camera looking down `-z`, shaded by
//! BRDF sampling alone.
//!
//! For the pixel at (x, y) inside the unit disk the normal is
//! n = (x, y, sqrt(1 − x² − y²)); with the frame F built from n, the outgoing
//! direction is ω_o = F⁻¹(+z) and the pixel estimates
//!
//! L(ω_o) ≈ (1/N) Σ_k f_r(ω_o, ω_i,k) ⊙ L_env(F ω_i,k) cos θ_i,k / p(ω_i,k)
//!
//! with ω_i,k drawn by the sampler (a failed draw adds 0). Pixels outside the
//! sphere show L_env(−z).

use std::time::{Duration, Instant};

use acdf_core::{Brdf, BxdfSampler, Frame, Vec2, Vec3};
use glam::DVec3;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

use crate::env::Environment;

/// The sphere's radius in image units: it fills the image up to a thin
/// border.
const FRAME_HALF_WIDTH: f32 = 1.05;

/// A linear-radiance image that accumulates samples.
#[derive(Debug, Clone)]
pub struct Film {
    width: usize,
    height: usize,
    sums: Vec<DVec3>,
    samples_per_pixel: usize,
}

/// The geometry of one pixel: `None` outside the sphere.
fn pixel_frame(width: usize, height: usize, col: usize, row: usize) -> Option<(Frame, Vec3)> {
    let x = (2.0 * (col as f32 + 0.5) / width as f32 - 1.0) * FRAME_HALF_WIDTH;
    let y = (1.0 - 2.0 * (row as f32 + 0.5) / height as f32) * FRAME_HALF_WIDTH;
    let r2 = x * x + y * y;
    if r2 >= 1.0 {
        return None;
    }
    let n = Vec3::new(x, y, (1.0 - r2).sqrt());
    let frame = Frame::from_z(n);
    let wo = frame.to_local(Vec3::Z);
    (wo.z > 0.0).then_some((frame, wo))
}

fn pixel_seed(seed: u64, pass: u64, pixel: usize) -> u64 {
    let mut h = seed ^ 0x5851_F42D_4C95_7F2D;
    for v in [pass, pixel as u64] {
        h = (h ^ v).wrapping_mul(0x9E37_79B9_7F4A_7C15);
        h ^= h >> 31;
    }
    h
}

/// Bytes a render of `width` × `height` pixels with `images` 8-bit
/// images of that size kept (the compared samplers' and the composite)
/// takes: the film's f64 RGB sums and the images. Saturates instead of
/// overflowing; checked against the memory limit before rendering.
pub fn render_memory_estimate(width: usize, height: usize, images: usize) -> u64 {
    let pixels = (width as u64).saturating_mul(height as u64);
    let per_pixel = std::mem::size_of::<DVec3>() as u64 + 3 * images as u64;
    pixels.saturating_mul(per_pixel)
}

impl Film {
    /// A black film of `width` × `height` pixels with no samples.
    pub fn new(width: usize, height: usize) -> Film {
        Film {
            width,
            height,
            sums: vec![DVec3::ZERO; width * height],
            samples_per_pixel: 0,
        }
    }

    /// Width and height in pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Samples per pixel accumulated so far.
    pub fn samples_per_pixel(&self) -> usize {
        self.samples_per_pixel
    }

    /// Whether the pixel shows the sphere.
    pub fn is_sphere(&self, col: usize, row: usize) -> bool {
        pixel_frame(self.width, self.height, col, row).is_some()
    }

    /// Add `spp` samples per pixel, drawn with uniform numbers that depend
    /// only on (`seed`, `pass`, pixel), in parallel over rows.
    pub fn add_pass(
        &mut self,
        brdf: &dyn Brdf,
        sampler: &dyn BxdfSampler,
        env: &dyn Environment,
        seed: u64,
        pass: u64,
        spp: usize,
    ) {
        let (width, height) = (self.width, self.height);
        let background = env.radiance(-Vec3::Z).as_dvec3();
        self.sums
            .par_chunks_mut(width.max(1))
            .enumerate()
            .for_each(|(row, sums)| {
                for (col, sum) in sums.iter_mut().enumerate() {
                    let Some((frame, wo)) = pixel_frame(width, height, col, row) else {
                        *sum += background * spp as f64;
                        continue;
                    };
                    let mut rng =
                        rand_pcg::Pcg64::seed_from_u64(pixel_seed(seed, pass, row * width + col));
                    for _ in 0..spp {
                        let u = Vec2::new(rng.random(), rng.random());
                        let Some(s) = sampler.sample(wo, u) else {
                            continue;
                        };
                        if !(s.pdf > 0.0 && s.pdf.is_finite()) {
                            continue;
                        }
                        let f = brdf.eval(wo, s.wi);
                        let l = env.radiance(frame.to_world(s.wi));
                        let c = (f * l * (s.wi.z / s.pdf)).as_dvec3();
                        if c.is_finite() {
                            *sum += c;
                        }
                    }
                }
            });
        self.samples_per_pixel += spp;
    }

    /// The mean radiance of every pixel, row-major.
    pub fn radiance(&self) -> Vec<Vec3> {
        let n = self.samples_per_pixel.max(1) as f64;
        self.sums.iter().map(|s| (*s / n).as_vec3()).collect()
    }

    /// sqrt of the mean over sphere pixels and the three channels of
    /// (self − reference)², in linear radiance.
    pub fn rmse(&self, reference: &Film) -> f64 {
        let a = self.radiance();
        let b = reference.radiance();
        let (mut sum, mut count) = (0.0f64, 0usize);
        for row in 0..self.height.min(reference.height) {
            for col in 0..self.width.min(reference.width) {
                if !self.is_sphere(col, row) {
                    continue;
                }
                let d = (a[row * self.width + col] - b[row * reference.width + col]).as_dvec3();
                sum += d.length_squared();
                count += 3;
            }
        }
        if count == 0 {
            0.0
        } else {
            (sum / count as f64).sqrt()
        }
    }

    /// Tone-map to 8-bit sRGB: scale by `exposure`, clamp to [0, 1], apply the
    /// sRGB transfer curve.
    pub fn to_rgb8(&self, exposure: f32) -> image::RgbImage {
        let radiance = self.radiance();
        let mut img = image::RgbImage::new(self.width as u32, self.height as u32);
        for (p, l) in img.pixels_mut().zip(radiance) {
            let c = l * exposure;
            p.0 = [srgb8(c.x), srgb8(c.y), srgb8(c.z)];
        }
        img
    }
}

/// The sRGB transfer curve of a linear value clamped to [0, 1], as a byte.
pub fn srgb8(linear: f32) -> u8 {
    let x = if linear.is_finite() {
        linear.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let v = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (v * 255.0 + 0.5) as u8
}

/// Render with `spp` samples per pixel in passes of at most `pass_spp`,
/// calling `progress` with the samples per pixel done after each pass.
#[allow(clippy::too_many_arguments)]
pub fn render_equal_samples(
    brdf: &dyn Brdf,
    sampler: &dyn BxdfSampler,
    env: &dyn Environment,
    width: usize,
    spp: usize,
    pass_spp: usize,
    seed: u64,
    mut progress: impl FnMut(usize),
) -> Film {
    let mut film = Film::new(width, width);
    let pass_spp = pass_spp.max(1);
    let mut pass = 0u64;
    while film.samples_per_pixel() < spp {
        let n = pass_spp.min(spp - film.samples_per_pixel());
        film.add_pass(brdf, sampler, env, seed, pass, n);
        pass += 1;
        progress(film.samples_per_pixel());
    }
    film
}

/// Render passes of one sample per pixel until `budget` has elapsed (at
/// least one pass), calling `progress` with the elapsed fraction.
pub fn render_equal_time(
    brdf: &dyn Brdf,
    sampler: &dyn BxdfSampler,
    env: &dyn Environment,
    width: usize,
    budget: Duration,
    seed: u64,
    mut progress: impl FnMut(f64),
) -> Film {
    let mut film = Film::new(width, width);
    let start = Instant::now();
    let mut pass = 0u64;
    loop {
        film.add_pass(brdf, sampler, env, seed, pass, 1);
        pass += 1;
        let elapsed = start.elapsed();
        progress((elapsed.as_secs_f64() / budget.as_secs_f64().max(1e-9)).min(1.0));
        if elapsed >= budget {
            break;
        }
    }
    film
}

#[cfg(test)]
mod tests {
    use super::*;
    use acdf_core::Rgb;
    use acdf_materials::analytic::Lambert;

    /// The Lambertian material of albedo `rho` in every channel.
    fn lambert(rho: f32) -> Lambert {
        Lambert::new("lambert", Rgb::splat(rho)).unwrap()
    }

    struct White;
    impl Environment for White {
        fn radiance(&self, _dir: Vec3) -> Rgb {
            Vec3::ONE
        }
    }

    /// A white furnace: a Lambertian sphere of albedo 1/2 under unit light
    /// is 1/2 everywhere with cosine sampling, with no noise.
    #[test]
    fn furnace_sphere_is_flat() {
        let film = render_equal_samples(
            &lambert(0.5),
            &acdf_cosine::CosineSampler,
            &White,
            16,
            4,
            2,
            1,
            |_| {},
        );
        assert_eq!(film.samples_per_pixel(), 4);
        let r = film.radiance();
        for row in 0..16 {
            for col in 0..16 {
                let want = if film.is_sphere(col, row) { 0.5 } else { 1.0 };
                let got = r[row * 16 + col];
                assert!(
                    (got - Vec3::splat(want)).abs().max_element() < 1e-4,
                    "{got} at {col},{row}"
                );
            }
        }
        assert!(film.rmse(&film) == 0.0);
        let img = film.to_rgb8(1.0);
        assert_eq!(img.dimensions(), (16, 16));
    }

    #[test]
    fn srgb_is_monotone_and_clamped() {
        assert_eq!(srgb8(-1.0), 0);
        assert_eq!(srgb8(f32::NAN), 0);
        assert_eq!(srgb8(2.0), 255);
        assert!(srgb8(0.2) < srgb8(0.5));
    }
}
