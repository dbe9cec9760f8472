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
        let mut weights = vec![0f64; env.block_count()];
        add_densities(&mut weights, points, brdf, wo);
        Self::from_weights(env, frame, wo, weights, 1.0, defensive)
    }

    /// Form one product for several shading points (a frame and a wo
    /// each, the first being the query's own): block b weighs M_b times
    /// the mean, over the points, of the BRDF sampler's mean density over
    /// the block's evaluation points above that point's horizon. One
    /// density serves all these points (a renderer's samples spread over a
    /// pixel): any query's density is exact wherever it is used
    /// ([`sample_at`](Self::sample_at)); the mean makes the blocks cover
    /// the lobe at each of the points, not only at one. Points whose wo is
    /// not valid are skipped; with none left (or δ = 1) the query draws
    /// from the BRDF sampler alone.
    pub fn build_over(
        env: &ProductEnv,
        at: &[(Frame, Vec3)],
        brdf: &dyn BxdfSampler,
        defensive: f32,
    ) -> ProductQuery {
        let usable: Vec<&(Frame, Vec3)> =
            at.iter().filter(|(_, wo)| is_valid_outgoing(*wo)).collect();
        let (frame, wo) = at
            .first()
            .copied()
            .unwrap_or((Frame::from_z(Vec3::Z), Vec3::Z));
        let mut weights = vec![0f64; env.block_count()];
        if !usable.is_empty() && defensive < 1.0 {
            for (frame, wo) in &usable {
                add_densities(&mut weights, &env.local_points(frame), brdf, *wo);
            }
        }
        Self::from_weights(env, frame, wo, weights, usable.len() as f64, defensive)
    }

    /// The query of per-block sums of densities `weights` over `count`
    /// shading points: w_b = M_b × weights_b / (count × points per block).
    fn from_weights(
        env: &ProductEnv,
        frame: Frame,
        wo: Vec3,
        mut weights: Vec<f64>,
        count: f64,
        defensive: f32,
    ) -> ProductQuery {
        let none = ProductQuery {
            wo,
            frame,
            grid_share: 0.0,
            share: Vec::new(),
            cdf: Vec::new(),
        };
        if !(defensive < 1.0) || !(count > 0.0) {
            return none;
        }
        let per = env.points_per_block() as f64 * count;
        let mut total = 0.0;
        for (b, w) in weights.iter_mut().enumerate() {
            *w *= env.light(b) / per;
            total += *w;
        }
        if !(total > 0.0 && total.is_finite()) {
            return none;
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

    /// Draw wi from `u` at the frame and wo the query was formed for:
    /// [`sample_at`](Self::sample_at) there.
    pub fn sample(&self, env: &ProductEnv, brdf: &dyn BxdfSampler, u: Vec2) -> Option<BxdfSample> {
        self.sample_at(env, brdf, &self.frame, self.wo, u)
            .map(|d| BxdfSample {
                wi: d.wi,
                pdf: d.pdf,
            })
    }

    /// Draw wi (local to `frame`) from `u` at a shading point with the
    /// frame `frame` and outgoing direction `wo`, which may differ from
    /// those the query was formed for: the BRDF sampler at (`frame`, `wo`)
    /// with probability δ (u.x below δ, rescaled), otherwise a block from
    /// the CDF (u.x's rest) and a world direction in it
    /// ([`ProductEnv::sample_in_block`], with the rest of u.x and u.y).
    /// The density is that of [`pdf_at`](Self::pdf_at): the block part is
    /// a density of world directions, the same in any frame, so it stays
    /// exact away from the point the weights were formed at; block draws
    /// below this frame's horizon are lost (estimate 0), and the defensive
    /// part covers the BRDF sampler's support at this point. `None` when
    /// the BRDF sampler's draw is, the direction is below the horizon, or
    /// it has no density.
    pub fn sample_at(
        &self,
        env: &ProductEnv,
        brdf: &dyn BxdfSampler,
        frame: &Frame,
        wo: Vec3,
        u: Vec2,
    ) -> Option<ProductDraw> {
        if !is_valid_outgoing(wo) {
            return None;
        }
        let u = Vec2::new(clamp_unit(u.x), clamp_unit(u.y));
        let delta = 1.0 - self.grid_share as f64;
        let ux = u.x as f64;
        let wi = if ux < delta {
            let x = ((ux / delta) as f32).min(acdf_core::ONE_MINUS_EPSILON);
            brdf.sample(wo, Vec2::new(x, u.y))?.wi
        } else {
            let x = (ux - delta) / self.grid_share as f64;
            let b = self
                .cdf
                .partition_point(|&v| v as f64 <= x)
                .min(self.cdf.len() - 1);
            let lo = if b == 0 { 0.0 } else { self.cdf[b - 1] as f64 };
            let f = ((x - lo) / (self.cdf[b] as f64 - lo)).clamp(0.0, 1.0);
            frame.to_local(env.sample_in_block(b, Vec2::new(f as f32, u.y))?)
        };
        if !(wi.z > 0.0) {
            return None;
        }
        // The density of the direction as `pdf_at` finds it (through the
        // local direction), so that a draw and its density always agree.
        let brdf_pdf = brdf.pdf(wo, wi);
        let pdf = self.pdf_given(env, frame.to_world(wi), brdf_pdf);
        (pdf > 0.0 && pdf.is_finite()).then_some(ProductDraw { wi, pdf, brdf_pdf })
    }

    /// The density p(wi) of [`sample`](Self::sample) (see the type's
    /// documentation); 0 at or below the horizon and for a wi that is not
    /// finite.
    pub fn pdf(&self, env: &ProductEnv, brdf: &dyn BxdfSampler, wi: Vec3) -> f32 {
        self.pdf_at(env, brdf, &self.frame, self.wo, wi)
    }

    /// The density of [`sample_at`](Self::sample_at) at (`frame`, `wo`)
    /// of wi (local to `frame`): (1 − δ) (w_b / Σ w) Y_t / M_b at wi's
    /// world direction plus δ p_S(wo, wi); 0 at or below the horizon and
    /// for a wi or wo that is not valid.
    pub fn pdf_at(
        &self,
        env: &ProductEnv,
        brdf: &dyn BxdfSampler,
        frame: &Frame,
        wo: Vec3,
        wi: Vec3,
    ) -> f32 {
        if !is_valid_outgoing(wo) || !(wi.z > 0.0) || !wi.is_finite() {
            return 0.0;
        }
        let brdf_pdf = if self.grid_share < 1.0 {
            brdf.pdf(wo, wi)
        } else {
            0.0
        };
        self.pdf_given(env, frame.to_world(wi), brdf_pdf)
    }

    /// The density of a draw in the world direction `dir` (above the
    /// shading point's horizon) where the BRDF sampler's density is
    /// `brdf_pdf`: (1 − δ) (w_b / Σ w) Y_t / M_b + δ p_S. For a caller
    /// that already has p_S (multiple importance sampling with the BRDF
    /// sampler needs both), it saves evaluating it twice. 0 when the sum
    /// is not finite or `brdf_pdf` is negative or NaN.
    pub fn pdf_given(&self, env: &ProductEnv, dir: Vec3, brdf_pdf: f32) -> f32 {
        if !(brdf_pdf >= 0.0) {
            return 0.0;
        }
        let grid_part = if self.grid_share > 0.0 {
            env.block_density(dir)
                .map_or(0.0, |(b, density)| self.share[b] * density)
        } else {
            0.0
        };
        let p = self.grid_share * grid_part + (1.0 - self.grid_share) * brdf_pdf;
        if p.is_finite() {
            p
        } else {
            0.0
        }
    }
}

/// Add to `weights` (one per block) the BRDF sampler's densities at
/// `points` for `wo`: one `pdf_batch` over the points above the horizon.
fn add_densities(weights: &mut [f64], points: &LocalPoints, brdf: &dyn BxdfSampler, wo: Vec3) {
    if points.is_empty() {
        return;
    }
    let mut p = vec![0f32; points.len()];
    brdf.pdf_batch(wo, &points.dirs, &mut p);
    for (&b, &p) in points.blocks.iter().zip(&p) {
        if p > 0.0 && p.is_finite() {
            weights[b as usize] += p as f64;
        }
    }
}

/// One draw of [`ProductQuery::sample_at`]: wi in the local frame of the
/// shading point, its density, and the BRDF sampler's density there (the
/// defensive part's, and what multiple importance sampling with the BRDF
/// sampler weighs by).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProductDraw {
    /// The incident direction, local.
    pub wi: Vec3,
    /// Its density per solid angle under the query.
    pub pdf: f32,
    /// The BRDF sampler's density p_S(wo, wi).
    pub brdf_pdf: f32,
}
