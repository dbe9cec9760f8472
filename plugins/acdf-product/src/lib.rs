//! `acdf-product` samples the product of the two factors of direct
//! lighting from an environment map at one shading point: it draws the
//! incident direction wi in proportion to f_r(wo, wi) cos θ_i · L(wi),
//! resolved to sub-cells of blocks of the map in the BRDF factor and to its
//! texels in the light, instead of to one factor alone as a BRDF sampler
//! or an environment sampler does. The BRDF factor is any BRDF sampler's
//! density (which follows f_r cos θ_i), taken through
//! `acdf_core::BxdfSampler`, so the family wraps whichever sampler the
//! caller builds. The map is cut once into blocks of texels and each block
//! into sub-cells, each with its light and the CDFs that draw a texel
//! inside it ([`ProductEnv`]). Per query (normal, wo), a few draws of the
//! BRDF sampler (its mass in each block, which sees a lobe narrower than a
//! block) and its density at a few points of each block weigh the blocks'
//! light; a block is drawn from these weights, a sub-cell of it by its
//! light times the BRDF density at its centre (formed the first time the
//! block is needed), a texel by its light, and wi uniformly in the texel.
//! A defensive share δ of draws comes from the BRDF sampler itself, so the
//! density, (1 − δ) × (block's share) × (sub-cell's share) × Y_t / M_f +
//! δ × p_S(wo, wi), is exact and positive wherever the BRDF sampler's is
//! ([`ProductQuery`]). [`ProductSampler`] fixes the shading normal and is a
//! `BxdfSampler`, so the conformance battery and `acdf sample`/`acdf pdf`
//! use it as any other.
//!
//! Frames: the normal is given in the map's frame (`acdf_lights::latlong`),
//! wo and wi are in the local shading frame of
//! [`acdf_core::Frame::from_z`] of that normal (the frame `acdf render`
//! shades in; at the normal +z the local axes are the map's).

#![forbid(unsafe_code)]
// `!(x > 0.0)` is "not positive, or NaN" on purpose.
#![allow(clippy::neg_cmp_op_on_partial_ord)]

mod env;
mod query;

pub use env::{LocalPoints, ProductEnv};
pub use query::{ProductDraw, ProductQuery};

use acdf_core::{is_valid_outgoing, BxdfSample, BxdfSampler, Error, Frame, Result, Vec2, Vec3};
use std::sync::{Arc, Mutex};

/// The knobs of the product sampler.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProductOptions {
    /// Block columns of the map (block rows: half as many), at most the
    /// map's texels.
    pub block_columns: usize,
    /// Evaluation points of the BRDF factor per block side: s² per block.
    pub points_per_side: usize,
    /// δ: the share of draws from the BRDF sampler, in [0, 1]; above 0
    /// the density covers every direction the BRDF sampler's does.
    pub defensive: f32,
    /// N: draws of the BRDF sampler per shading point that estimate each
    /// block's BRDF mass times its light (0, the default: the point
    /// densities alone; docs/environment.md measures where they help and
    /// where they hurt).
    pub mass_draws: usize,
    /// c₀ ≥ 0: how many of the N draws must land in a block before its
    /// mass counts half against its point densities (a block of c draws
    /// weighs max(point estimate, c / (c + c₀) × mass estimate)).
    pub mass_prior: f32,
    /// k, 1 to 4: sub-cells per block side (fewer where a block has fewer
    /// texels), drawn inside a block by light × the BRDF density at their centres;
    /// 1 draws a block's texels by their light alone.
    pub sub_cells: usize,
    /// γ in [0, 1]: the share of a block's sub-cell draws by light alone.
    pub refine_light_share: f32,
}

impl Default for ProductOptions {
    /// 64 × 32 blocks, 2 × 2 points per block, δ = 0.15, N = 0, c₀ = 64,
    /// 4 × 4 sub-cells, γ = 0.1.
    fn default() -> Self {
        ProductOptions {
            block_columns: 64,
            points_per_side: 2,
            defensive: 0.15,
            mass_draws: 0,
            mass_prior: 64.0,
            sub_cells: 4,
            refine_light_share: 0.1,
        }
    }
}

impl ProductOptions {
    /// A typed error for a count of 0 or above 1024 (sub-cells: above 4,
    /// draws: above 65,536),
    /// a share outside [0, 1] or a mass prior below 0 or not finite.
    pub fn validate(&self) -> Result<()> {
        for (name, v, lo, hi) in [
            ("block columns", self.block_columns, 1, 1024),
            ("points per side", self.points_per_side, 1, 1024),
            ("sub-cells per side", self.sub_cells, 1, 4),
            ("mass draws", self.mass_draws, 0, 65536),
        ] {
            if !(lo..=hi).contains(&v) {
                return Err(Error::InvalidParameter {
                    name,
                    reason: format!("{v} is not in {lo}..={hi}"),
                });
            }
        }
        for (name, v) in [
            ("defensive share", self.defensive),
            ("refinement light share", self.refine_light_share),
        ] {
            if !(0.0..=1.0).contains(&v) {
                return Err(Error::InvalidParameter {
                    name,
                    reason: format!("{v} is not in [0, 1]"),
                });
            }
        }
        if !(self.mass_prior >= 0.0 && self.mass_prior.is_finite()) {
            return Err(Error::InvalidParameter {
                name: "mass prior",
                reason: format!("{} is not a finite count of at least 0", self.mass_prior),
            });
        }
        Ok(())
    }
}

/// The queries a [`ProductSampler`] keeps, most recent last: the battery
/// and the command line ask many draws and densities of one wo in turn.
const RECENT_QUERIES: usize = 8;

/// The product sampler at one shading normal: a `BxdfSampler` whose
/// draws follow p_S(wo, wi) · L(wi), with wo and wi in the normal's local
/// frame ([`Frame::from_z`]). The query for a wo is formed on first use
/// and kept among the last few.
pub struct ProductSampler {
    name: String,
    brdf: Arc<dyn BxdfSampler>,
    env: Arc<ProductEnv>,
    /// The blocks' evaluation points above this normal's horizon.
    points: LocalPoints,
    frame: Frame,
    normal: Vec3,
    options: ProductOptions,
    recent: Mutex<Vec<Arc<ProductQuery>>>,
}

impl std::fmt::Debug for ProductSampler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ProductSampler")
            .field("name", &self.name)
            .field("normal", &self.normal)
            .field("options", &self.options)
            .finish()
    }
}

impl ProductSampler {
    /// The product of `brdf`'s density and the map of `env` at the shading
    /// normal `normal` (the map's frame; normalised), with the shares and
    /// draw count of `options` (its block and sub-cell counts are `env`'s). A typed error
    /// for a normal that is not finite or has no length, or bad options.
    pub fn new(
        brdf: Arc<dyn BxdfSampler>,
        env: Arc<ProductEnv>,
        normal: Vec3,
        options: ProductOptions,
    ) -> Result<ProductSampler> {
        options.validate()?;
        let normal = acdf_core::usable_normal(Some(normal)).ok_or(Error::InvalidParameter {
            name: "normal",
            reason: format!("{normal} is not a finite direction with a length"),
        })?;
        let frame = Frame::from_z(normal);
        let points = env.local_points(&frame);
        Ok(ProductSampler {
            name: format!("product:{}", brdf.name()),
            brdf,
            env,
            points,
            frame,
            normal,
            options,
            recent: Mutex::new(Vec::new()),
        })
    }

    /// The shading normal, unit, in the map's frame.
    pub fn normal(&self) -> Vec3 {
        self.normal
    }

    /// The options it was built with.
    pub fn options(&self) -> ProductOptions {
        self.options
    }

    /// The map's blocks.
    pub fn env(&self) -> &Arc<ProductEnv> {
        &self.env
    }

    /// The BRDF sampler it wraps.
    pub fn brdf_sampler(&self) -> &Arc<dyn BxdfSampler> {
        &self.brdf
    }

    /// The product for `wo` (formed now, or kept from a recent call);
    /// `None` for a wo that is not valid.
    pub fn query(&self, wo: Vec3) -> Option<Arc<ProductQuery>> {
        if !is_valid_outgoing(wo) {
            return None;
        }
        let same = |q: &Arc<ProductQuery>| {
            q.wo().to_array().map(f32::to_bits) == wo.to_array().map(f32::to_bits)
        };
        {
            let recent = self.recent.lock().unwrap_or_else(|e| e.into_inner());
            if let Some(q) = recent.iter().rev().find(|q| same(q)) {
                return Some(q.clone());
            }
        }
        let q = Arc::new(ProductQuery::build(
            &self.env,
            self.frame,
            &self.points,
            self.brdf.as_ref(),
            wo,
            &self.options,
        ));
        let mut recent = self.recent.lock().unwrap_or_else(|e| e.into_inner());
        if recent.len() >= RECENT_QUERIES {
            recent.remove(0);
        }
        recent.push(q.clone());
        Some(q)
    }
}

impl BxdfSampler for ProductSampler {
    fn name(&self) -> &str {
        &self.name
    }

    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        self.query(wo)?.sample(&self.env, self.brdf.as_ref(), u)
    }

    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.query(wo)
            .map_or(0.0, |q| q.pdf(&self.env, self.brdf.as_ref(), wi))
    }

    /// The wrapped sampler's tables, the map's blocks, the points of this
    /// normal, and the queries kept.
    fn storage_bytes(&self) -> usize {
        let kept: usize = self
            .recent
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .iter()
            .map(|q| q.storage_bytes())
            .sum();
        self.brdf.storage_bytes() + self.env.storage_bytes() + self.points.storage_bytes() + kept
    }

    fn sample_batch(&self, wo: Vec3, u: &[Vec2], out: &mut [Option<BxdfSample>]) {
        let q = self.query(wo);
        for (o, &u) in out.iter_mut().zip(u) {
            *o = q
                .as_ref()
                .and_then(|q| q.sample(&self.env, self.brdf.as_ref(), u));
        }
    }

    fn pdf_batch(&self, wo: Vec3, wi: &[Vec3], out: &mut [f32]) {
        let q = self.query(wo);
        for (o, &wi) in out.iter_mut().zip(wi) {
            *o = q
                .as_ref()
                .map_or(0.0, |q| q.pdf(&self.env, self.brdf.as_ref(), wi));
        }
    }
}

#[cfg(test)]
mod tests;
