//! The product formed for one shading point: one weight per grid cell, a
//! CDF over the cells, and the mixture with the BRDF sampler.

use crate::grid::HemisphereGrid;
use acdf_core::{clamp_unit, is_valid_outgoing, BxdfSample, BxdfSampler, Vec2, Vec3};
use acdf_core::{Frame, ONE_MINUS_EPSILON};

use crate::env::FilteredEnv;

/// The environment factor at each evaluation point of `grid` for the
/// shading frame `frame`: the filtered luminance towards the point turned
/// into the map's frame.
pub fn environment_at_points(grid: &HemisphereGrid, env: &FilteredEnv, frame: &Frame) -> Vec<f32> {
    grid.points()
        .iter()
        .map(|&p| env.lookup(frame.to_world(p)))
        .collect()
}

/// The product at one shading point and one outgoing direction.
///
/// Cell c of the grid weighs w_c = Σ_k p_S(wo, ω_k) L̄(ω_k) over its
/// evaluation points ω_k (p_S the BRDF sampler's density, which follows
/// f_r cos θ_i, and L̄ the filtered luminance). With δ the defensive
/// share, the density of a draw is
///
/// p(wi) = (1 − δ) w_c(wi) / (Σ_c w_c · A) + δ p_S(wo, wi),
///
/// A = 2π / N² the solid angle of a cell: exact (a cell is drawn from the
/// weights' CDF and wi uniformly in solid angle inside it), and positive
/// wherever p_S is. When every weight is 0 (a black map, or a lobe that
/// misses every evaluation point where the map is lit) the query draws
/// from the BRDF sampler alone, δ = 1.
#[derive(Debug, Clone)]
pub struct ProductQuery {
    wo: Vec3,
    /// 1 − δ, or 0 when no cell has weight.
    grid_share: f32,
    /// Per cell, the grid part's density there: w_c / (Σ w · A).
    density: Vec<f32>,
    /// The cells' CDF, N² + 1 entries from 0 to 1 (empty when
    /// `grid_share` is 0).
    cdf: Vec<f32>,
}

impl ProductQuery {
    /// Form the product for `wo` from the BRDF sampler `brdf` and the
    /// environment at the grid's points (`env`, from
    /// [`environment_at_points`]); `defensive` is δ in [0, 1]. One
    /// `pdf_batch` of the BRDF sampler over every point and one pass over
    /// the cells.
    pub fn build(
        grid: &HemisphereGrid,
        env: &[f32],
        brdf: &dyn BxdfSampler,
        wo: Vec3,
        defensive: f32,
    ) -> ProductQuery {
        let points = grid.points();
        let mut p = vec![0f32; points.len()];
        if is_valid_outgoing(wo) && defensive < 1.0 {
            brdf.pdf_batch(wo, points, &mut p);
        }
        let per_cell = grid.points_per_cell();
        let weights: Vec<f64> = p
            .chunks_exact(per_cell)
            .zip(env.chunks_exact(per_cell))
            .map(|(p, l)| {
                p.iter()
                    .zip(l)
                    .map(|(&p, &l)| (p as f64 * l as f64).max(0.0))
                    .sum::<f64>()
            })
            .collect();
        let total: f64 = weights.iter().sum();
        if !(total > 0.0 && total.is_finite()) {
            return ProductQuery {
                wo,
                grid_share: 0.0,
                density: Vec::new(),
                cdf: Vec::new(),
            };
        }
        let area = grid.cell_solid_angle() as f64;
        let density = weights
            .iter()
            .map(|&w| (w / (total * area)) as f32)
            .collect();
        let mut cdf = Vec::with_capacity(weights.len() + 1);
        let mut running = 0.0;
        cdf.push(0.0);
        for &w in &weights {
            running += w;
            cdf.push((running / total) as f32);
        }
        *cdf.last_mut().expect("the CDF has N² + 1 entries") = 1.0;
        ProductQuery {
            wo,
            grid_share: 1.0 - defensive.clamp(0.0, 1.0),
            density,
            cdf,
        }
    }

    /// The outgoing direction it was formed for.
    pub fn wo(&self) -> Vec3 {
        self.wo
    }

    /// The share of draws from the grid: 1 − δ, or 0 when no cell has
    /// weight.
    pub fn grid_share(&self) -> f32 {
        self.grid_share
    }

    /// Heap bytes: the per-cell densities and the CDF.
    pub fn storage_bytes(&self) -> usize {
        (self.density.len() + self.cdf.len()) * std::mem::size_of::<f32>()
    }

    /// Draw wi from `u`: the BRDF sampler with probability δ (u.x below δ,
    /// rescaled), otherwise a cell from the CDF (u.x's rest) and a point
    /// uniform in it (the rest of u.x and u.y). `None` when the BRDF
    /// sampler's draw is, or the draw has no density.
    pub fn sample(
        &self,
        grid: &HemisphereGrid,
        brdf: &dyn BxdfSampler,
        u: Vec2,
    ) -> Option<BxdfSample> {
        if !is_valid_outgoing(self.wo) {
            return None;
        }
        let u = Vec2::new(clamp_unit(u.x), clamp_unit(u.y));
        let delta = 1.0 - self.grid_share as f64;
        let ux = u.x as f64;
        let wi = if ux < delta {
            let x = ((ux / delta) as f32).min(ONE_MINUS_EPSILON);
            brdf.sample(self.wo, Vec2::new(x, u.y))?.wi
        } else {
            let x = (ux - delta) / self.grid_share as f64;
            // The cell whose CDF interval holds x: cdf[c] ≤ x < cdf[c + 1],
            // which has weight.
            let c = self
                .cdf
                .partition_point(|&v| v as f64 <= x)
                .clamp(1, self.density.len())
                - 1;
            let (lo, hi) = (self.cdf[c] as f64, self.cdf[c + 1] as f64);
            let f = (((x - lo) / (hi - lo)) as f32).clamp(0.0, ONE_MINUS_EPSILON);
            grid.direction_in_cell(c, Vec2::new(f, u.y))
        };
        let pdf = self.pdf(grid, brdf, wi);
        (wi.z > 0.0 && pdf > 0.0 && pdf.is_finite()).then_some(BxdfSample { wi, pdf })
    }

    /// The density p(wi) of [`sample`](Self::sample) (see the type's
    /// documentation); 0 at or below the horizon.
    pub fn pdf(&self, grid: &HemisphereGrid, brdf: &dyn BxdfSampler, wi: Vec3) -> f32 {
        if !is_valid_outgoing(self.wo) || !(wi.z > 0.0) {
            return 0.0;
        }
        let brdf_part = if self.grid_share < 1.0 {
            (1.0 - self.grid_share) * brdf.pdf(self.wo, wi)
        } else {
            0.0
        };
        let grid_part = if self.grid_share > 0.0 {
            grid.cell_of(wi).map_or(0.0, |c| self.density[c])
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
