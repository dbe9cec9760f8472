//! The product formed for one shading point: one weight per block of the
//! map, a CDF over the blocks, and the mixture with the BRDF sampler.

use crate::env::{LocalPoints, ProductEnv};
use acdf_core::{clamp_unit, is_valid_outgoing, BxdfSample, BxdfSampler, Frame, Vec2, Vec3};

/// The product at one shading frame and one outgoing direction.
///
/// Block b of the map weighs w_b = p̄_S(b) · M_b: M_b the block's light
/// (see [`ProductEnv`]) and p̄_S(b) the mean of the BRDF sampler's density
/// p_S(wo, ·) (which follows f_r cos θ_i) over the block's evaluation
/// points, those below the horizon counting 0. A draw picks a block from
/// the weights' CDF, then a texel t of it in proportion to its light and a
/// direction uniform in the texel, so that the product is resolved to the
/// block in the BRDF factor and to the texel in the light. With δ the
/// defensive share, the density of wi (local frame) is
///
/// p(wi) = (1 − δ) · (w_b / Σ w) · Y_t / M_b + δ · p_S(wo, wi),
///
/// (b, t) the block and texel of wi in the map's frame: exact, and
/// positive wherever p_S is. A draw that lands below the horizon is
/// `None` (its share is the mass the density does not cover). When every
/// weight is 0 (a black map, or no lit block whose points the lobe
/// reaches) the query draws from the BRDF sampler alone, δ = 1.
#[derive(Debug, Clone)]
pub struct ProductQuery {
    wo: Vec3,
    frame: Frame,
    /// 1 − δ, or 0 when no block has weight.
    grid_share: f32,
    /// Per block, w_b / Σ w (empty when `grid_share` is 0).
    share: Vec<f32>,
    /// The blocks' CDF: the value after each block, the last exactly 1.
    cdf: Vec<f32>,
}

impl ProductQuery {
    /// Form the product for `wo` at the shading frame `frame`, whose
    /// evaluation points are `points` ([`ProductEnv::local_points`]), with
    /// the BRDF sampler `brdf`; `defensive` is δ in [0, 1]. One
    /// `pdf_batch` of the BRDF sampler over the points above the horizon
    /// and one pass over the blocks.
    pub fn build(
        env: &ProductEnv,
        frame: Frame,
        points: &LocalPoints,
        brdf: &dyn BxdfSampler,
        wo: Vec3,
        defensive: f32,
    ) -> ProductQuery {
        let none = |wo| ProductQuery {
            wo,
            frame,
            grid_share: 0.0,
            share: Vec::new(),
            cdf: Vec::new(),
        };
        if !is_valid_outgoing(wo) || !(defensive < 1.0) || points.is_empty() {
            return none(wo);
        }
        let mut p = vec![0f32; points.len()];
        brdf.pdf_batch(wo, &points.dirs, &mut p);
        let mut weights = vec![0f64; env.block_count()];
        for (&b, &p) in points.blocks.iter().zip(&p) {
            if p > 0.0 && p.is_finite() {
                weights[b as usize] += p as f64;
            }
        }
        let per = points.points_per_block as f64;
        let mut total = 0.0;
        for (b, w) in weights.iter_mut().enumerate() {
            *w *= env.light(b) / per;
            total += *w;
        }
        if !(total > 0.0 && total.is_finite()) {
            return none(wo);
        }
        let share = weights.iter().map(|&w| (w / total) as f32).collect();
        let mut cdf = Vec::with_capacity(weights.len());
        let mut running = 0.0;
        for &w in &weights {
            running += w;
            cdf.push((running / total) as f32);
        }
        *cdf.last_mut().expect("a map has a block") = 1.0;
        ProductQuery {
            wo,
            frame,
            grid_share: 1.0 - defensive.clamp(0.0, 1.0),
            share,
            cdf,
        }
    }

    /// The outgoing direction it was formed for.
    pub fn wo(&self) -> Vec3 {
        self.wo
    }

    /// The share of draws from the blocks: 1 − δ, or 0 when no block has
    /// weight.
    pub fn grid_share(&self) -> f32 {
        self.grid_share
    }

    /// Heap bytes: the blocks' shares and CDF.
    pub fn storage_bytes(&self) -> usize {
        (self.share.len() + self.cdf.len()) * std::mem::size_of::<f32>()
    }

    /// Draw wi from `u`: the BRDF sampler with probability δ (u.x below δ,
    /// rescaled), otherwise a block from the CDF (u.x's rest) and a
    /// direction in it ([`ProductEnv::sample_in_block`], with the rest of
    /// u.x and u.y). `None` when the BRDF sampler's draw is, the direction
    /// is below the horizon, or it has no density.
    pub fn sample(&self, env: &ProductEnv, brdf: &dyn BxdfSampler, u: Vec2) -> Option<BxdfSample> {
        if !is_valid_outgoing(self.wo) {
            return None;
        }
        let u = Vec2::new(clamp_unit(u.x), clamp_unit(u.y));
        let delta = 1.0 - self.grid_share as f64;
        let ux = u.x as f64;
        let wi = if ux < delta {
            let x = ((ux / delta) as f32).min(acdf_core::ONE_MINUS_EPSILON);
            brdf.sample(self.wo, Vec2::new(x, u.y))?.wi
        } else {
            let x = (ux - delta) / self.grid_share as f64;
            let b = self
                .cdf
                .partition_point(|&v| v as f64 <= x)
                .min(self.cdf.len() - 1);
            let lo = if b == 0 { 0.0 } else { self.cdf[b - 1] as f64 };
            let f = ((x - lo) / (self.cdf[b] as f64 - lo)).clamp(0.0, 1.0);
            let dir = env.sample_in_block(b, Vec2::new(f as f32, u.y))?;
            self.frame.to_local(dir)
        };
        if !(wi.z > 0.0) {
            return None;
        }
        let pdf = self.pdf(env, brdf, wi);
        (pdf > 0.0 && pdf.is_finite()).then_some(BxdfSample { wi, pdf })
    }

    /// The density p(wi) of [`sample`](Self::sample) (see the type's
    /// documentation); 0 at or below the horizon and for a wi that is not
    /// finite.
    pub fn pdf(&self, env: &ProductEnv, brdf: &dyn BxdfSampler, wi: Vec3) -> f32 {
        if !is_valid_outgoing(self.wo) || !(wi.z > 0.0) || !wi.is_finite() {
            return 0.0;
        }
        let brdf_part = if self.grid_share < 1.0 {
            (1.0 - self.grid_share) * brdf.pdf(self.wo, wi)
        } else {
            0.0
        };
        let grid_part = if self.grid_share > 0.0 {
            env.block_density(self.frame.to_world(wi))
                .map_or(0.0, |(b, density)| self.share[b] * density)
        } else {
            0.0
        };
        let p = self.grid_share * grid_part + brdf_part;
        if p.is_finite() {
            p
        } else {
            0.0
        }
    }
}
