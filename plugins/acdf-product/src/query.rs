//! The product formed for one shading point: one weight per block of the
//! map, a CDF over the blocks, per block drawn from a CDF over its
//! sub-cells (formed when first needed), and the mixture with the BRDF
//! sampler.

use crate::env::{find, LocalPoints, ProductEnv};
use crate::ProductOptions;
use acdf_core::{clamp_unit, is_valid_outgoing, BxdfSample, BxdfSampler, Frame, Vec2, Vec3};
use std::sync::OnceLock;

/// The product at one shading frame and one outgoing direction (or at a
/// few shading points at once, [`build_over`](Self::build_over)).
///
/// **Blocks.** Block b of the map weighs
///
/// w_b = max(q_b, c_b / (c_b + c₀) · m_b),
///
/// two estimates of the block's product mass ∫_b p_S(wo, ω) L̄(ω) dω (L̄
/// the map's luminance averaged over sub-cells), per shading point:
/// - q_b = p̄_S(b) · M_b: M_b the block's light and p̄_S(b) the mean of
///   the BRDF sampler's density p_S(wo, ·) (which follows f_r cos θ_i)
///   over the block's evaluation points, those below the horizon counting
///   0; smooth, but blind to a lobe narrower than a block that passes
///   between its points;
/// - m_b, the BRDF sampler's mass: N draws of the BRDF sampler from fixed
///   stratified numbers (a Fibonacci lattice), each of the c_b landing
///   above the horizon in block b adding M_f / Ω_f / N (the mean radiance
///   of the sub-cell f it lands in); unbiased, and sees a narrow lobe
///   wherever it lies, but noisy where a block receives few draws (a broad
///   lobe), so that it counts by c_b / (c_b + c₀) (c₀ the mass prior,
///   [`ProductOptions::mass_prior`]), and never lowers q_b (with N = 0,
///   w_b = q_b).
///
/// **Sub-cells.** Inside block b, sub-cell f weighs
///
/// v_f = (1 − γ) · M_f p_S(wo, c_f) / Σ_g M_g p_S(wo, c_g) + γ · M_f / M_b,
///
/// g over the block's sub-cells, c_f the centre of f, p_S taken at the query's shading point (the middle of
/// its points when it serves several, [`build_over`](Self::build_over)),
/// and γ the light share ([`ProductOptions::refine_light_share`];
/// v_f = M_f / M_b where p_S is 0 at every centre of the block), formed the
/// first time a draw or a density needs the block and kept. A draw picks a
/// block by w, a sub-cell by v, a texel t of it by its light and a
/// direction uniform in the texel. With δ the defensive share, the density
/// of wi (local frame) is
///
/// p(wi) = (1 − δ) · (w_b / Σ w) · v_f · Y_t / M_f + δ · p_S(wo, wi),
///
/// (b, f, t) the block, sub-cell and texel of wi in the map's frame. All
/// these weights are fixed once formed (the N draws use fixed numbers, the
/// sub-cell tables are formed at the same shading point whichever call
/// forms them), so the density is exact, and positive wherever p_S is. A
/// draw that lands below the horizon is `None` (its share is the mass the
/// density does not cover). When every weight is 0 (a black map, or no lit
/// block that the lobe reaches) the query draws from the BRDF sampler
/// alone, δ = 1.
#[derive(Debug, Clone)]
pub struct ProductQuery {
    wo: Vec3,
    frame: Frame,
    /// The shading point (frame, wo) the sub-cell tables are formed at:
    /// the one the weights were formed over, or the mean of several
    /// ([`centre_of`]).
    centre: (Frame, Vec3),
    /// 1 − δ, or 0 when no block has weight.
    grid_share: f32,
    /// γ.
    light_share: f32,
    /// Per block, w_b / Σ w and its sub-cell table's index in `tables`
    /// (empty when `grid_share` is 0): one look-up for both.
    blocks: Vec<BlockShare>,
    /// The blocks' CDF: the value after each block, the last exactly 1.
    cdf: Vec<f32>,
    /// Per block with weight (when a block has several sub-cells), the
    /// CDF over its sub-cells, formed on first use; held inline, so that
    /// a draw reads it with one look-up.
    tables: Vec<OnceLock<[f32; MAX_SUB_CELLS]>>,
}

/// The most sub-cells a block has: 4 × 4 ([`ProductOptions::sub_cells`]
/// at most 4).
pub(crate) const MAX_SUB_CELLS: usize = 16;

/// A block's share of the block draws and the index of its sub-cell
/// table (`u32::MAX`: none, a block without weight or of one sub-cell).
#[derive(Debug, Clone, Copy)]
struct BlockShare {
    share: f32,
    slot: u32,
}

/// The shading point at the middle of `at`: the mean of their normals
/// and of their outgoing directions (in the world), as a frame and a local
/// wo; the only point when there is one, the first when the mean is not a
/// valid point, `None` for none. Where a query serves several points (a
/// pixel's), one table per block at their middle costs a quarter of one
/// over four points.
fn centre_of(at: &[(Frame, Vec3)]) -> Option<(Frame, Vec3)> {
    let first = *at.first()?;
    if at.len() == 1 {
        return Some(first);
    }
    let n: Vec3 = at.iter().map(|(f, _)| f.z).sum();
    let o: Vec3 = at.iter().map(|(f, wo)| f.to_world(*wo)).sum();
    let (Some(n), Some(o)) = (n.try_normalize(), o.try_normalize()) else {
        return Some(first);
    };
    let frame = Frame::from_z(n);
    let wo = frame.to_local(o);
    Some(if is_valid_outgoing(wo) {
        (frame, wo)
    } else {
        first
    })
}

/// The fixed numbers of the N draws that estimate the blocks' BRDF mass:
/// the Fibonacci lattice ((i + ½) / N, frac(i / φ + ½)).
fn lattice(n: usize) -> Vec<Vec2> {
    let g = 0.618_033_988_749_894_9_f64;
    (0..n)
        .map(|i| {
            let x = (i as f64 + 0.5) / n as f64;
            let y = (i as f64 * g + 0.5).fract();
            Vec2::new(
                (x as f32).min(acdf_core::ONE_MINUS_EPSILON),
                (y as f32).min(acdf_core::ONE_MINUS_EPSILON),
            )
        })
        .collect()
}

impl ProductQuery {
    /// Form the product for `wo` at the shading frame `frame`, whose
    /// evaluation points are `points` ([`ProductEnv::local_points`]), with
    /// the BRDF sampler `brdf` and the shares and draw count of `options`.
    /// One `pdf_batch` of the BRDF sampler over the points above the
    /// horizon, one `sample_batch` of N draws and one pass over the blocks.
    pub fn build(
        env: &ProductEnv,
        frame: Frame,
        points: &LocalPoints,
        brdf: &dyn BxdfSampler,
        wo: Vec3,
        options: &ProductOptions,
    ) -> ProductQuery {
        let usable = if is_valid_outgoing(wo) {
            vec![(frame, wo)]
        } else {
            Vec::new()
        };
        let mut densities = vec![0f64; env.block_count()];
        if !usable.is_empty() && options.defensive < 1.0 {
            add_densities(&mut densities, points, brdf, wo);
        }
        Self::form(env, (frame, wo), usable, densities, brdf, options)
    }

    /// Form one product for several shading points (a frame and a wo
    /// each, the first being the query's own): the blocks' mass and point
    /// estimates are averaged over the points (the point densities at each
    /// point's own block points above its horizon), and the sub-cell tables
    /// are formed at their middle (the mean normal and wo). One density serves all these points (a renderer's samples
    /// spread over a pixel): any query's density is exact wherever it is
    /// used ([`sample_at`](Self::sample_at)); the sums make the blocks
    /// cover the lobe at each of the points, not only at one. Points whose
    /// wo is not valid are skipped; with none left (or δ = 1) the query
    /// draws from the BRDF sampler alone.
    pub fn build_over(
        env: &ProductEnv,
        at: &[(Frame, Vec3)],
        brdf: &dyn BxdfSampler,
        options: &ProductOptions,
    ) -> ProductQuery {
        let usable: Vec<(Frame, Vec3)> = at
            .iter()
            .copied()
            .filter(|(_, wo)| is_valid_outgoing(*wo))
            .collect();
        let own = at
            .first()
            .copied()
            .unwrap_or((Frame::from_z(Vec3::Z), Vec3::Z));
        let mut densities = vec![0f64; env.block_count()];
        if options.defensive < 1.0 {
            for (frame, wo) in &usable {
                add_densities(&mut densities, &env.local_points(frame), brdf, *wo);
            }
        }
        Self::form(env, own, usable, densities, brdf, options)
    }

    /// The query over the shading points `at` whose per-block sums of
    /// point densities are `densities`: q_b = M_b × densities_b / (points
    /// per block × shading points), m_b from N draws at each point, and
    /// w_b from both (the type's documentation).
    fn form(
        env: &ProductEnv,
        (frame, wo): (Frame, Vec3),
        at: Vec<(Frame, Vec3)>,
        mut weights: Vec<f64>,
        brdf: &dyn BxdfSampler,
        options: &ProductOptions,
    ) -> ProductQuery {
        let centre = centre_of(&at).unwrap_or((frame, wo));
        let none = ProductQuery {
            wo,
            frame,
            centre,
            grid_share: 0.0,
            light_share: 1.0,
            blocks: Vec::new(),
            cdf: Vec::new(),
            tables: Vec::new(),
        };
        if !(options.defensive < 1.0) || at.is_empty() {
            return none;
        }
        // q_b, per shading point: the sums of densities over the block's
        // points and over the shading points, averaged.
        let per = (env.points_per_block() * at.len()) as f64;
        for (b, w) in weights.iter_mut().enumerate() {
            *w *= env.light(b) / per;
        }
        if options.mass_draws > 0 {
            let u = lattice(options.mass_draws);
            let scale = 1.0 / (u.len() * at.len()) as f64;
            let mut mass = vec![0f64; env.block_count()];
            let mut count = vec![0u32; env.block_count()];
            let mut drawn = vec![None; u.len()];
            for (frame, wo) in &at {
                brdf.sample_batch(*wo, &u, &mut drawn);
                for d in drawn.iter().flatten() {
                    if d.wi.z > 0.0 {
                        if let Some((b, l)) = env.block_radiance(frame.to_world(d.wi)) {
                            mass[b] += l as f64 * scale;
                            count[b] += 1;
                        }
                    }
                }
            }
            let prior = options.mass_prior as f64;
            for ((w, &m), &c) in weights.iter_mut().zip(&mass).zip(&count) {
                if c > 0 {
                    let c = c as f64;
                    *w = w.max(c / (c + prior) * m);
                }
            }
        }
        let total: f64 = weights.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return none;
        }
        let mut cdf = Vec::with_capacity(weights.len());
        let mut running = 0.0;
        for &w in &weights {
            running += w;
            cdf.push((running / total) as f32);
        }
        *cdf.last_mut().expect("a map has a block") = 1.0;
        let refined = env.sub_cells_per_block() > 1;
        let mut tables = Vec::new();
        let blocks = weights
            .iter()
            .map(|&w| {
                let share = (w / total) as f32;
                let slot = if refined && share > 0.0 {
                    tables.push(OnceLock::new());
                    (tables.len() - 1) as u32
                } else {
                    u32::MAX
                };
                BlockShare { share, slot }
            })
            .collect();
        ProductQuery {
            wo,
            frame,
            centre,
            grid_share: 1.0 - options.defensive.clamp(0.0, 1.0),
            light_share: options.refine_light_share.clamp(0.0, 1.0),
            blocks,
            cdf,
            tables,
        }
    }

    /// The CDF over the sub-cells of block `b` (which has weight), formed
    /// now if no call has formed it: v_f from M_f and p_S at the sub-cell
    /// centres at the query's centre point (one `pdf_batch`), mixed with
    /// the light alone by γ (the type's documentation).
    /// `None` with one sub-cell per block.
    fn sub_cdf(&self, env: &ProductEnv, brdf: &dyn BxdfSampler, b: usize) -> Option<&[f32]> {
        let slot = self.blocks.get(b)?.slot;
        let table = self.tables.get(slot as usize)?;
        let n = env.sub_cells_per_block();
        Some(
            &table.get_or_init(|| {
                let cells: Vec<usize> = (0..n).map(|s| env.cell_index(b, s)).collect();
                let mut density = vec![0f64; n];
                let (frame, wo) = self.centre;
                let (mut dirs, mut which) = (Vec::new(), Vec::new());
                for (s, &f) in cells.iter().enumerate() {
                    let local = frame.to_local(env.cell_centre(f));
                    if local.z > 0.0 {
                        dirs.push(local);
                        which.push(s);
                    }
                }
                let mut p = vec![0f32; dirs.len()];
                brdf.pdf_batch(wo, &dirs, &mut p);
                for (&s, &p) in which.iter().zip(&p) {
                    if p > 0.0 && p.is_finite() {
                        density[s] += p as f64;
                    }
                }
                let light: Vec<f64> = cells.iter().map(|&f| env.cell_light(f)).collect();
                let light_total: f64 = light.iter().sum();
                let product_total: f64 = light.iter().zip(&density).map(|(l, d)| l * d).sum();
                let gamma = if product_total > 0.0 && product_total.is_finite() {
                    self.light_share as f64
                } else {
                    1.0
                };
                let mut out = [0f32; MAX_SUB_CELLS];
                crate::env::cdf_into(
                    light.iter().zip(&density).map(|(&l, &d)| {
                        let lit = if light_total > 0.0 {
                            l / light_total
                        } else {
                            0.0
                        };
                        let product = if gamma < 1.0 {
                            l * d / product_total
                        } else {
                            0.0
                        };
                        (1.0 - gamma) * product + gamma * lit
                    }),
                    &mut out[..n],
                );
                out
            })[..n],
        )
    }

    /// The blocks whose sub-cell tables have been formed.
    pub fn formed_blocks(&self) -> Vec<usize> {
        self.blocks
            .iter()
            .enumerate()
            .filter(|(_, e)| {
                self.tables
                    .get(e.slot as usize)
                    .is_some_and(|t| t.get().is_some())
            })
            .map(|(b, _)| b)
            .collect()
    }

    /// Form the sub-cell tables of `blocks` (those with weight) now, as a
    /// draw or a density there would: what a renderer charges as the
    /// query's cost.
    pub fn form_blocks(&self, env: &ProductEnv, brdf: &dyn BxdfSampler, blocks: &[usize]) {
        for &b in blocks {
            std::hint::black_box(self.sub_cdf(env, brdf, b));
        }
    }

    /// The same query with no sub-cell table formed yet.
    pub fn unformed(&self) -> ProductQuery {
        let mut q = self.clone();
        for t in &mut q.tables {
            t.take();
        }
        q
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

    /// w_b / Σ w of block `b` (0 for a block without weight, or when no
    /// block has weight).
    pub fn block_share(&self, b: usize) -> f32 {
        self.blocks.get(b).map_or(0.0, |e| e.share)
    }

    /// Heap bytes: the blocks' shares, CDF and sub-cell tables (room for
    /// one per block with weight), and the shading points.
    pub fn storage_bytes(&self) -> usize {
        self.blocks.len() * std::mem::size_of::<BlockShare>()
            + self.cdf.len() * std::mem::size_of::<f32>()
            + self.tables.len() * std::mem::size_of::<OnceLock<[f32; MAX_SUB_CELLS]>>()
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
    /// the CDF (u.x's rest), a sub-cell of it from its table (the rest),
    /// and a world direction in it ([`ProductEnv::sample_in_cell`], with
    /// the rest of u.x and u.y). The density is that of
    /// [`pdf_at`](Self::pdf_at): the block part is a density of world
    /// directions, the same in any frame, so it stays exact away from the
    /// point the weights were formed at; block draws below this frame's
    /// horizon are lost (estimate 0), and the defensive part covers the
    /// BRDF sampler's support at this point. `brdf` is the sampler the
    /// query was formed with. `None` when the BRDF sampler's draw is, the
    /// direction is below the horizon, or it has no density.
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
            let (s, f) = match self.sub_cdf(env, brdf, b) {
                Some(cdf) => find(cdf, f)?,
                None => (0, f),
            };
            let cell = env.cell_index(b, s);
            frame.to_local(env.sample_in_cell(cell, Vec2::new(f as f32, u.y))?)
        };
        if !(wi.z > 0.0) {
            return None;
        }
        // The density of the direction as `pdf_at` finds it (through the
        // local direction), so that a draw and its density always agree.
        let brdf_pdf = brdf.pdf(wo, wi);
        let pdf = self.pdf_given(env, brdf, frame.to_world(wi), brdf_pdf);
        (pdf > 0.0 && pdf.is_finite()).then_some(ProductDraw { wi, pdf, brdf_pdf })
    }

    /// The density p(wi) of [`sample`](Self::sample) (see the type's
    /// documentation); 0 at or below the horizon and for a wi that is not
    /// finite.
    pub fn pdf(&self, env: &ProductEnv, brdf: &dyn BxdfSampler, wi: Vec3) -> f32 {
        self.pdf_at(env, brdf, &self.frame, self.wo, wi)
    }

    /// The density of [`sample_at`](Self::sample_at) at (`frame`, `wo`)
    /// of wi (local to `frame`): (1 − δ) (w_b / Σ w) v_f Y_t / M_f at wi's
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
        self.pdf_given(env, brdf, frame.to_world(wi), brdf_pdf)
    }

    /// The density of a draw in the world direction `dir` (above the
    /// shading point's horizon) where the BRDF sampler's density is
    /// `brdf_pdf`: (1 − δ) (w_b / Σ w) v_f Y_t / M_f + δ p_S, forming the
    /// sub-cell table of wi's block with `brdf` (the query's sampler) if
    /// no call has. For a caller that already has p_S (multiple importance
    /// sampling with the BRDF sampler needs both), it saves evaluating it
    /// twice. 0 when the sum is not finite or `brdf_pdf` is negative or
    /// NaN.
    pub fn pdf_given(
        &self,
        env: &ProductEnv,
        brdf: &dyn BxdfSampler,
        dir: Vec3,
        brdf_pdf: f32,
    ) -> f32 {
        if !(brdf_pdf >= 0.0) {
            return 0.0;
        }
        let grid_part = if self.grid_share > 0.0 {
            env.cell_density(dir).map_or(0.0, |(b, s, density)| {
                let share = self.blocks[b].share;
                if !(share > 0.0) {
                    return 0.0;
                }
                let sub = match self.sub_cdf(env, brdf, b) {
                    Some(cdf) => cdf[s] - if s == 0 { 0.0 } else { cdf[s - 1] },
                    None => 1.0,
                };
                share * sub * density
            })
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
