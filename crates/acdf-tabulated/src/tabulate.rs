//! Tabulating a BRDF over the half vector, and the cell geometry shared by
//! the tabulation and the sampler.
//!
//! **Outgoing cells.** θ_o is spaced in u_o = sqrt(θ_o / (π/2)): cell i
//! covers u_o in [i/n, (i+1)/n) and is tabulated at its centre, which puts
//! more slices near the normal. φ_o cell j is *centred* on 2π j / n (it
//! covers 2π (j ± 1/2) / n), so a single φ_o cell is centred on φ_o = 0, the
//! frame an isotropic material is rotated into.
//!
//! **Half-vector axes.** A slice is a table over the unit square (x, v):
//! columns x give φ_h = 2π x, rows v give θ_h = (π/2) v² (the square-root
//! spacing of MERL tables, which packs rows near θ_h = 0 where specular peaks
//! are narrow). The solid angle of the half vector is
//! dω_h = sin θ_h dθ_h dφ_h = J dx dv with J = (π v)(2π) sin θ_h. The first
//! row (the polar cap, θ_h < (π/2)/n²) is mapped to equal solid angle
//! instead, so that densities stay bounded at θ_h = 0 ([`HalfMap`]).
//!
//! **Tabulated value.** Each cell holds the mean over 2×2 sub-points of
//! g(x, v) = Y(f(wo, wi)) cos θ_i · 4 (wo·h) · J(v), with wi = reflect(wo, h)
//! and Y the luminance: the density of incident directions,
//! Y(f) cos θ_i dω_i with dω_i = 4 |wo·h| dω_h, written in (x, v). The table
//! therefore integrates to the luminance albedo of wo. Half vectors with
//! wo·h ≤ 0 or whose wi is at or below the horizon give 0. A value that comes
//! out NaN, infinite or negative (which the [`Brdf`] contract excludes) is
//! sanitised to 0, so a tabulated slice always passes
//! [`validate_table`](acdf_core::validate_table).
//!
//! **Support.** A slice is tabulated at the centre of its outgoing cell but
//! serves every wo of the cell, and a sampler's density is 0 exactly where
//! its cell is. Two things would leave a cell at 0 where f cos θ_i > 0: a
//! cell that the horizon (wi.z = 0) or the lobe crosses, lit between the 2×2
//! sub-points but at none of them; and, mostly at grazing angles, a half
//! vector whose reflection is below the horizon for the centre wo but above
//! it for another wo of the cell (the last θ_o cell of 32 spans 84.5° to 90°;
//! with several φ_o cells, a slice keeps absolute φ_h and a wo turned within
//! its φ_o cell turns the lobe with it). [`tabulate_slice`] therefore gives
//! every cell that is 0 at the centre a second look ([`fill_support`]),
//! skipping the outgoing directions for which a bound shows that no half
//! vector of the cell reflects above the horizon: its mean of g by the
//! trapezoid rule on (S + 1)² points, corners and edges included (S =
//! [`SUPPORT_SUBDIVISIONS`]), for outgoing directions across the outgoing
//! cell, its edges included ([`served_outgoing`]), and takes the largest: the
//! cell's mass for the outgoing direction that lights it most, so that the
//! weight f cos θ_i / p stays bounded there (the average over the outgoing
//! directions would dilute the mass of a cell that only some of them
//! light, and the weight would grow by the same factor for those). Cells
//! that are positive at the centre keep their value, so no mass is added
//! where the centre tabulation had some.
//!
//! For a fixed h, wi.z = 2 (wo·h) h_z - wo_z, and wi.z > 0 implies
//! wo·h > 0 (for h_z >= 0); along θ_o it is a sinusoid, positive on an
//! interval of length π, so a half vector reflected above the horizon by
//! some wo of a θ_o cell is by one of the cell's two edges. The support of
//! f cos θ_i is open, so a lit point on a cell's border lights some of the
//! cell itself.

use crate::Resolution;
use acdf_core::fast::{fast_atan2, sin_cos_quarter_turns};
use acdf_core::geometry::{reflect, spherical_direction};
use acdf_core::{Brdf, Vec3};
use std::f32::consts::{FRAC_PI_2, PI, TAU};

/// Sub-points per cell along each half-vector axis in [`tabulate_slice`].
pub const SUBSAMPLES: usize = 2;

/// The cell of `x` in `n` uniform cells over [0, 1): floor(x n) clamped to
/// [0, n-1] (NaN and negatives give 0).
#[inline(always)]
pub fn unit_cell(x: f32, n: usize) -> usize {
    ((x * n as f32) as usize).min(n.max(1) - 1)
}

/// u_o = sqrt(θ_o / (π/2)), the coordinate in which θ_o cells are uniform.
#[inline]
pub fn theta_o_to_unit(theta_o: f32) -> f32 {
    (theta_o.max(0.0) / FRAC_PI_2).sqrt()
}

/// The θ_o cell of an outgoing direction with polar angle `theta_o`.
#[inline]
pub fn theta_o_cell(theta_o: f32, n_theta_o: usize) -> usize {
    unit_cell(theta_o_to_unit(theta_o), n_theta_o)
}

/// The θ_o at the centre of cell i: (π/2) ((i + 1/2) / n)².
#[inline]
pub fn theta_o_center(i: usize, n_theta_o: usize) -> f32 {
    let u = (i as f32 + 0.5) / n_theta_o as f32;
    FRAC_PI_2 * u * u
}

/// The φ_o cell whose centre 2π j / n is nearest to `phi_o`.
#[inline]
pub fn phi_o_cell(phi_o: f32, n_phi_o: usize) -> usize {
    let j = (phi_o / TAU * n_phi_o as f32 + 0.5).floor();
    // `as usize` saturates NaN and negatives to 0; the modulo folds the
    // last half cell back onto cell 0.
    (j as usize) % n_phi_o.max(1)
}

/// The φ_o at the centre of cell j: 2π j / n.
#[inline]
pub fn phi_o_center(j: usize, n_phi_o: usize) -> f32 {
    TAU * j as f32 / n_phi_o as f32
}

/// θ_h = (π/2) v² for the row coordinate v in [0, 1] (the map outside the
/// polar cap row; see [`HalfMap`] for the full map).
#[inline(always)]
pub fn theta_h_of(v: f32) -> f32 {
    FRAC_PI_2 * v * v
}

/// v = sqrt(θ_h / (π/2)), the inverse of [`theta_h_of`].
#[inline(always)]
pub fn v_of_theta_h(theta_h: f32) -> f32 {
    (theta_h.max(0.0) / FRAC_PI_2).sqrt()
}

/// The half-vector row map of a slice with `n_theta_h` rows: v ↦ θ_h.
///
/// Rows 1.. follow θ_h = (π/2) v² ([`theta_h_of`]). The first row, the
/// polar cap θ_h < θ_1 = (π/2) / n², is mapped to equal solid angle
/// instead: 1 - cos θ_h = (v / v_1)(1 - cos θ_1) with v_1 = 1 / n. With
/// (π/2) v² down to the pole, a density constant in (x, v) would be
/// p_ω ∝ 1 / (v sin θ_h) per solid angle, infinite at θ_h = 0; with the
/// cap it is bounded (constant across the cap), and the map stays
/// continuous at v_1.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfMap {
    /// v_1 = 1 / n_theta_h, the top of the cap row.
    v1: f32,
    /// θ_1 = (π/2) v_1².
    theta1: f32,
    /// 1 - cos θ_1 = 2 sin²(θ_1 / 2), without cancellation.
    one_minus_cos1: f32,
    /// J in the cap, 2π (1 - cos θ_1) / v_1: a division every draw would
    /// otherwise pay.
    cap_jacobian: f32,
}

impl HalfMap {
    /// The map of a slice with `n_theta_h` rows (at least 1).
    pub fn new(n_theta_h: usize) -> Self {
        let v1 = 1.0 / n_theta_h.max(1) as f32;
        let theta1 = theta_h_of(v1);
        let s = (0.5 * theta1).sin();
        let one_minus_cos1 = 2.0 * s * s;
        HalfMap {
            v1,
            theta1,
            one_minus_cos1,
            cap_jacobian: TAU * one_minus_cos1 / v1,
        }
    }

    /// v_1 = 1 / n_theta_h, the top of the polar cap row.
    #[inline(always)]
    pub fn cap_top(&self) -> f32 {
        self.v1
    }

    /// (sin θ_h, cos θ_h) for the row coordinate v in [0, 1].
    #[inline(always)]
    pub fn angles(&self, v: f32) -> (f32, f32) {
        // θ_h = (π/2) v² is v² quarter turns.
        self.polar(v, || sin_cos_quarter_turns(v * v))
    }

    /// (sin θ_h, cos θ_h) at v: `outer()` above the cap, the cap map below.
    ///
    /// Only the formula of v's side of the cap is computed: one draw at a
    /// time, the cap's division and square root would otherwise delay
    /// every draw's angles, while the branch, taken on the few draws that
    /// land in the polar cap, is nearly always predicted (the same choice
    /// as for `unit_reflection` in the sampler); in the batch loops the
    /// compiler makes the branch a select, so they still vectorise.
    /// [`v_of`](Self::v_of) and [`jacobian`](Self::jacobian) compute both
    /// formulas and select one.
    #[inline(always)]
    pub fn polar(&self, v: f32, outer: impl FnOnce() -> (f32, f32)) -> (f32, f32) {
        if v >= self.v1 {
            return outer();
        }
        let one_minus_cos = (v / self.v1) * self.one_minus_cos1;
        let cos_cap = 1.0 - one_minus_cos;
        // sin² = (1 - cos)(1 + cos), exact near the pole.
        let sin_cap = (one_minus_cos * (1.0 + cos_cap)).max(0.0).sqrt();
        (sin_cap, cos_cap)
    }

    /// The row coordinate v of the half vector with sin θ_h = `scale` ·
    /// `rho` and cos θ_h = `scale` · `z` (the inverse of
    /// [`angles`](Self::angles)); `scale` is 1 for a unit vector's
    /// (sin θ_h, cos θ_h).
    ///
    /// θ_h = atan2(rho, z) needs no scale, so a caller holding an
    /// unnormalised half vector (wi + wo) gets v without waiting for its
    /// normalisation; only the polar cap's formula uses `scale`.
    #[inline(always)]
    pub fn v_of(&self, rho: f32, z: f32, scale: f32) -> f32 {
        let theta = fast_atan2(rho, z);
        let outer = v_of_theta_h(theta);
        let (sin_h, cos_h) = (rho * scale, z * scale);
        // 1 - cos θ = sin² θ / (1 + cos θ), exact near the pole.
        let one_minus_cos = sin_h * sin_h / (1.0 + cos_h);
        let cap = (self.v1 * one_minus_cos / self.one_minus_cos1).min(self.v1);
        if theta >= self.theta1 {
            outer
        } else {
            cap
        }
    }

    /// J(v) = dω_h / (dx dv), so that dω_h = J dx dv: outside the cap,
    /// |∂(θ_h, φ_h)/∂(x, v)| sin θ_h = (π v)(2π) sin θ_h under
    /// θ_h = (π/2) v² and φ_h = 2π x; inside it, the constant
    /// 2π (1 - cos θ_1) / v_1.
    #[inline(always)]
    pub fn jacobian(&self, v: f32, sin_h: f32) -> f32 {
        let cap = self.cap_jacobian;
        if v >= self.v1 {
            PI * v * TAU * sin_h
        } else {
            cap
        }
    }
}

/// The outgoing direction at the centre of slice (i, j).
pub fn slice_outgoing(res: &Resolution, theta_o_index: usize, phi_o_index: usize) -> Vec3 {
    spherical_direction(
        theta_o_center(theta_o_index, res.theta_o),
        phi_o_center(phi_o_index, res.phi_o),
    )
}

/// The table of slice (θ_o cell, φ_o cell): `res.theta_h` rows of
/// `res.phi_h` values, φ_h absolute (for one φ_o cell the slice's wo has
/// φ_o = 0, so absolute and relative φ_h coincide): [`tabulate_for`] at the
/// cell's centre, then, except for the first θ_o cell, [`fill_support`] for
/// the outgoing directions the slice serves ([`served_outgoing`]). See the
/// module documentation.
pub fn tabulate_slice(
    brdf: &dyn Brdf,
    res: &Resolution,
    theta_o_index: usize,
    phi_o_index: usize,
) -> Vec<f32> {
    let mut values = tabulate_for(
        brdf,
        slice_outgoing(res, theta_o_index, phi_o_index),
        res.theta_h,
        res.phi_h,
    );
    // The first θ_o cell is left as tabulated: it spans θ_o < 0.088° (of
    // 32), where the light its centre misses is under 1e-6 (9e-7 of a
    // Lambertian surface's at its edge; 0 on the measured materials at
    // 0.05° and 0.087° in tests/tests/support.rs), while filling it would
    // lose draws at the pole (`None`; 2 of 200,000 on a Lambertian surface
    // at θ_o = 0), which the conformance battery, whose pdf integral there
    // reads 1 to within its quadrature error, rejects.
    if theta_o_index > 0 {
        let served = served_outgoing(res, theta_o_index, phi_o_index);
        fill_support(brdf, &served, res.theta_h, res.phi_h, &mut values);
    }
    values
}

/// Subdivisions per cell and axis of the support pass of [`fill_support`]:
/// it looks at (S + 1)² points per cell, corners and edges included.
pub const SUPPORT_SUBDIVISIONS: usize = 4;

/// Steps across a θ_o cell in [`served_outgoing`]: θ_o at its two edges
/// and 7 points between, equally spaced in u_o.
pub const SERVED_THETA_STEPS: usize = 8;

/// The smallest cos θ_o of [`served_outgoing`]: the last θ_o cell reaches
/// the horizon, where wo itself is invalid, so its grazing edge is taken
/// at cos θ_o = 1e-6 (θ_o = 90° - 2e-4°).
pub const GRAZING_COS: f32 = 1e-6;

/// Steps across a φ_o cell in [`served_outgoing`] when there are several:
/// φ_o at its two edges and 3 points between, equally spaced.
pub const SERVED_PHI_STEPS: usize = 4;

/// The outgoing directions that stand for slice (θ_o cell, φ_o cell) in
/// [`fill_support`]: θ_o at the cell's two edges and
/// [`SERVED_THETA_STEPS`] - 1 points between, equally spaced in u_o (the
/// grazing edge at cos θ_o = [`GRAZING_COS`]); the edges cover every θ_o of
/// the cell (module documentation). With one φ_o cell, φ_o = 0 (the slice
/// is relative to φ_o). With several, the slice keeps absolute φ_h and
/// serves every φ_o of its cell, so φ_o also runs over the cell's two edges
/// and [`SERVED_PHI_STEPS`] - 1 points between: turning wo turns the lobe,
/// and the cells it turns into must not be 0.
pub fn served_outgoing(res: &Resolution, theta_o_index: usize, phi_o_index: usize) -> Vec<Vec3> {
    let n = res.theta_o as f32;
    // θ_o = (π/2) u_o², as for the cell centres.
    let theta_at = |u: f32| FRAC_PI_2 * u * u;
    let thetas: Vec<f32> = (0..=SERVED_THETA_STEPS)
        .map(|k| theta_at((theta_o_index as f32 + k as f32 / SERVED_THETA_STEPS as f32) / n))
        .collect();
    let centre = phi_o_center(phi_o_index, res.phi_o);
    let phis: Vec<f32> = if res.phi_o == 1 {
        vec![centre]
    } else {
        let width = TAU / res.phi_o as f32;
        (0..=SERVED_PHI_STEPS)
            .map(|k| centre + width * (k as f32 / SERVED_PHI_STEPS as f32 - 0.5))
            .collect()
    };
    let mut out = Vec::with_capacity(thetas.len() * phis.len());
    for &t in &thetas {
        let (sin_t, cos_t) = t.sin_cos();
        let cos_t = cos_t.max(GRAZING_COS);
        let sin_t = if cos_t > GRAZING_COS {
            sin_t
        } else {
            (1.0 - cos_t * cos_t).sqrt()
        };
        for &p in &phis {
            let (sin_p, cos_p) = p.sin_cos();
            out.push(Vec3::new(sin_t * cos_p, sin_t * sin_p, cos_t));
        }
    }
    out
}

/// Give every cell of `values` (`n_theta_h` rows of `n_phi_h`, tabulated
/// at one wo) that is 0 but lit for some of `outgoing` a positive value:
/// the cell's mean of g (the module's density, with its Jacobian) by the
/// trapezoid rule on the (S + 1)² points at offsets 0, 1/S, ..., 1 along
/// each axis (S = [`SUPPORT_SUBDIVISIONS`]), the largest over `outgoing`,
/// at least the smallest positive normal f32. The trapezoid rule weighs the
/// points on the cell's border by half (a quarter at the corners), so a
/// cell lit only along its border, typically by a horizon that g meets at
/// 0, gets about the little mass it has. Draws
/// from such a cell are lost (`None`) for the outgoing directions that do
/// not light it.
pub fn fill_support(
    brdf: &dyn Brdf,
    outgoing: &[Vec3],
    n_theta_h: usize,
    n_phi_h: usize,
    values: &mut [f32],
) {
    if values.len() != n_theta_h * n_phi_h || outgoing.is_empty() {
        return;
    }
    let sub = SUPPORT_SUBDIVISIONS;
    let map = HalfMap::new(n_theta_h);
    let points = (sub * sub) as f64;
    // The trapezoid rule's weights: 1/2 on the cell's edges, 1 inside.
    let trapezoid = |k: usize| if k == 0 || k == sub { 0.5 } else { 1.0 };
    // The sum of g over the cell's points, per outgoing direction.
    let mut acc = vec![0.0f64; outgoing.len()];
    // Per outgoing direction: (sin θ_o, cos θ_o), and the largest
    // cos(φ_h - φ_o) over each column of cells.
    let polar: Vec<(f32, f32)> = outgoing.iter().map(|wo| (wo.x.hypot(wo.y), wo.z)).collect();
    let column_cos: Vec<Vec<f32>> = outgoing
        .iter()
        .map(|wo| largest_cos_per_column(wo.y.atan2(wo.x), n_phi_h))
        .collect();
    let mut lit = vec![false; outgoing.len()];
    for (iy, row) in values.chunks_exact_mut(n_phi_h).enumerate() {
        // The row's sub-point rings: (v, sin θ_h, cos θ_h, J).
        let rings: Vec<(f32, f32, f32)> = (0..=sub)
            .map(|b| {
                let v = (iy as f32 + b as f32 / sub as f32) / n_theta_h as f32;
                let (sin_h, cos_h) = map.angles(v);
                (sin_h, cos_h, map.jacobian(v, sin_h))
            })
            .collect();
        for (ix, cell) in row.iter_mut().enumerate() {
            if *cell > 0.0 {
                continue;
            }
            // Skip the outgoing directions that reflect no half vector of
            // the cell above the horizon (a bound, so none is skipped that
            // lights it), and the cell if none is left.
            let (sin_lo, cos_hi) = (rings[0].0, rings[0].1);
            let sin_hi = rings[sub].0;
            let mut any = false;
            for (k, flag) in lit.iter_mut().enumerate() {
                *flag = may_reflect_above(polar[k], column_cos[k][ix], (sin_lo, sin_hi, cos_hi));
                any |= *flag;
            }
            if !any {
                continue;
            }
            acc.iter_mut().for_each(|a| *a = 0.0);
            for a in 0..=sub {
                let x = (ix as f32 + a as f32 / sub as f32) / n_phi_h as f32;
                let (sin_p, cos_p) = (TAU * x).sin_cos();
                for (b, &(sin_h, cos_h, jacobian)) in rings.iter().enumerate() {
                    let h = Vec3::new(sin_h * cos_p, sin_h * sin_p, cos_h);
                    let w = trapezoid(a) * trapezoid(b) * jacobian as f64;
                    for ((acc, &wo), _) in acc
                        .iter_mut()
                        .zip(outgoing)
                        .zip(&lit)
                        .filter(|(_, &lit)| lit)
                    {
                        *acc += incident_density(brdf, wo, h) as f64 * w;
                    }
                }
            }
            let largest = acc.iter().copied().fold(0.0f64, f64::max);
            let mean = (largest / points) as f32;
            if mean.is_finite() && largest > 0.0 {
                *cell = mean.max(f32::MIN_POSITIVE);
            }
        }
    }
}

/// For each of `n` columns of cells (φ_h in [2π k / n, 2π (k + 1) / n]),
/// the largest cos(φ_h - φ_o) over the column: 1 where the column holds
/// φ_o, else the larger of its two edges' (cos is unimodal on the circle).
fn largest_cos_per_column(phi_o: f32, n: usize) -> Vec<f32> {
    let width = TAU / n as f32;
    (0..n)
        .map(|k| {
            let start = width * k as f32;
            let inside = (phi_o - start).rem_euclid(TAU) <= width;
            if inside {
                1.0
            } else {
                (start - phi_o).cos().max((start + width - phi_o).cos())
            }
        })
        .collect()
}

/// Whether some half vector h of a cell may reflect wo above the horizon:
/// false only when a bound shows that none does. wi.z = 2 (wo·h) cos θ_h -
/// cos θ_o, with wo·h <= sin θ_o sin θ_h c + cos θ_o cos θ_h, c the
/// largest cos(φ_h - φ_o) over the cell (`largest_cos`), and the cell's
/// θ_h range given by `(sin θ_lo, sin θ_hi, cos θ_lo)`. A margin of 1e-5
/// covers the rounding of the pointwise test in [`incident_density`].
#[inline]
fn may_reflect_above(
    (sin_o, cos_o): (f32, f32),
    largest_cos: f32,
    (sin_lo, sin_hi, cos_lo): (f32, f32, f32),
) -> bool {
    const MARGIN: f32 = 1e-5;
    let sin_h = if largest_cos >= 0.0 { sin_hi } else { sin_lo };
    let dot = sin_o * sin_h * largest_cos + cos_o * cos_lo;
    dot > -MARGIN && 2.0 * dot.max(0.0) * cos_lo - cos_o > -MARGIN
}

/// The half-vector table for an arbitrary unit `wo`: `n_theta_h` rows of
/// `n_phi_h` values, φ_h absolute. Empty if either count is 0. Each
/// sub-row of half vectors is one θ_h ring, whose luminances come from one
/// [`Brdf::luminance_half_ring`] call.
pub fn tabulate_for(brdf: &dyn Brdf, wo: Vec3, n_theta_h: usize, n_phi_h: usize) -> Vec<f32> {
    let mut values = vec![0.0f32; n_theta_h * n_phi_h];
    if values.is_empty() {
        return values;
    }
    let sub = SUBSAMPLES;
    let inv_sub = 1.0 / sub as f32;
    // Sub-point columns: (cos φ_h, sin φ_h).
    let columns: Vec<(f32, f32)> = (0..n_phi_h * sub)
        .map(|c| {
            let x = (c as f32 + 0.5) / (n_phi_h * sub) as f32;
            let (s, co) = (TAU * x).sin_cos();
            (co, s)
        })
        .collect();
    let weight = 1.0 / (sub * sub) as f64;
    let map = HalfMap::new(n_theta_h);
    // One sub-row of half vectors is a ring at one θ_h: the BRDF evaluates
    // its luminance in one call (a measured table hoists its θ_h work).
    let mut ring = vec![0.0f32; columns.len()];
    for (iy, row) in values.chunks_exact_mut(n_phi_h).enumerate() {
        for t in 0..sub {
            let v = (iy as f32 + (t as f32 + 0.5) * inv_sub) / n_theta_h as f32;
            let (sin_h, cos_h) = map.angles(v);
            let jacobian = map.jacobian(v, sin_h);
            brdf.luminance_half_ring(wo, (sin_h, cos_h), &columns, &mut ring);
            for (ix, cell) in row.iter_mut().enumerate() {
                let mut acc = 0.0f64;
                let sub_columns = ix * sub..(ix + 1) * sub;
                let luminances = &ring[sub_columns.clone()];
                for (&(cos_p, sin_p), &y) in columns[sub_columns].iter().zip(luminances) {
                    let h = Vec3::new(sin_h * cos_p, sin_h * sin_p, cos_h);
                    acc += density_with(wo, h, |_| y) as f64 * jacobian as f64;
                }
                let mean = *cell as f64 + acc * weight;
                *cell = mean as f32;
            }
        }
    }
    for v in &mut values {
        if !(v.is_finite() && *v >= 0.0) {
            *v = 0.0;
        }
    }
    values
}

/// Y(f(wo, wi)) cos θ_i · 4 (wo·h) for wi = reflect(wo, h): the density of
/// incident directions per unit solid angle of the half vector; 0 when
/// wo·h ≤ 0 or wi is at or below the horizon, and for non-finite results.
#[inline]
pub fn incident_density(brdf: &dyn Brdf, wo: Vec3, h: Vec3) -> f32 {
    density_with(wo, h, |wi| brdf.luminance(wo, wi))
}

/// [`incident_density`] with the luminance Y(f(wo, wi)) given by
/// `luminance(wi)`, called only for the half vectors that reflect wo above
/// the horizon.
#[inline(always)]
fn density_with(wo: Vec3, h: Vec3, luminance: impl FnOnce(Vec3) -> f32) -> f32 {
    let wo_h = wo.dot(h);
    if !(wo_h > 0.0) {
        return 0.0;
    }
    let wi = reflect(wo, h);
    if !(wi.z > 0.0) {
        return 0.0;
    }
    let g = luminance(wi) * wi.z * 4.0 * wo_h;
    if g.is_finite() && g > 0.0 {
        g
    } else {
        0.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use acdf_core::geometry::{phi, theta};
    use acdf_core::Rgb;

    struct Lambert;
    impl Brdf for Lambert {
        fn name(&self) -> &str {
            "lambert"
        }
        fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
            if wo.z > 0.0 && wi.z > 0.0 {
                Rgb::splat(std::f32::consts::FRAC_1_PI)
            } else {
                Rgb::ZERO
            }
        }
        fn is_isotropic(&self) -> bool {
            true
        }
    }

    struct Broken;
    impl Brdf for Broken {
        fn name(&self) -> &str {
            "broken"
        }
        fn eval(&self, _: Vec3, wi: Vec3) -> Rgb {
            if wi.x > 0.0 {
                Rgb::splat(f32::NAN)
            } else {
                Rgb::splat(-1.0)
            }
        }
        fn is_isotropic(&self) -> bool {
            true
        }
    }

    #[test]
    fn cells_and_centres_agree() {
        for n in [1, 7, 32] {
            for i in 0..n {
                assert_eq!(theta_o_cell(theta_o_center(i, n), n), i);
                assert_eq!(phi_o_cell(phi_o_center(i, n), n), i);
            }
        }
        assert_eq!(theta_o_cell(0.0, 32), 0);
        assert_eq!(theta_o_cell(FRAC_PI_2, 32), 31);
        assert_eq!(theta_o_cell(f32::NAN, 32), 0);
        assert_eq!(phi_o_cell(TAU - 1e-4, 16), 0);
        assert_eq!(phi_o_cell(f32::NAN, 16), 0);
        assert_eq!(phi_o_cell(3.0, 1), 0);
        let wo = slice_outgoing(&Resolution::PAPER, 5, 3);
        assert_eq!(theta_o_cell(theta(wo), 32), 5);
        assert_eq!(phi_o_cell(phi(wo), 16), 3);
        for v in [0.0, 0.1, 0.5, 1.0] {
            approx::assert_relative_eq!(v_of_theta_h(theta_h_of(v)), v, max_relative = 1e-6);
        }
    }

    /// The table integrates (midpoint rule over its cells) to the luminance
    /// albedo; for a Lambertian surface of albedo 1 that is 1, up to the
    /// discretisation of the 64 × 16 table (about 1%).
    #[test]
    fn lambert_table_integrates_to_the_albedo() {
        for theta_o in [0.0f32, 0.5, 1.2] {
            let wo = spherical_direction(theta_o, 0.3);
            let t = tabulate_for(&Lambert, wo, 64, 16);
            let integral: f64 = t.iter().map(|&v| v as f64).sum::<f64>() / t.len() as f64;
            assert!((integral - 1.0).abs() < 0.02, "{theta_o}: {integral}");
        }
    }

    /// The cap map is continuous at v_1, inverts, and its Jacobian is the
    /// derivative of the solid angle: 2π d(1 - cos θ_h)/dv.
    #[test]
    fn half_map_is_continuous_and_inverts() {
        let map = HalfMap::new(256);
        let v1 = 1.0 / 256.0;
        let (below, above) = (map.angles(v1 * (1.0 - 1e-6)), map.angles(v1));
        approx::assert_relative_eq!(below.0, above.0, max_relative = 1e-4);
        for v in [0.0, 1e-5, 0.5 * v1, 0.99 * v1, v1, 0.01, 0.3, 0.999] {
            let (s, c) = map.angles(v);
            approx::assert_relative_eq!(s * s + c * c, 1.0, max_relative = 1e-6);
            approx::assert_abs_diff_eq!(map.v_of(s, c, 1.0), v, epsilon = 2e-6 * v.max(v1));
            // d(1 - cos θ)/dv by a central difference in f64.
            let dv = 1e-3 * v.max(v1) as f64;
            let omc = |v: f64| {
                if v >= v1 as f64 {
                    1.0 - (std::f64::consts::FRAC_PI_2 * v * v).cos()
                } else {
                    v / v1 as f64 * map.one_minus_cos1 as f64
                }
            };
            let (lo, hi) = if v >= v1 {
                (v as f64, v as f64 + dv)
            } else {
                (v as f64, v as f64 + dv.min(v1 as f64 - v as f64))
            };
            if hi > lo {
                let derivative = std::f64::consts::TAU * (omc(hi) - omc(lo)) / (hi - lo);
                approx::assert_relative_eq!(
                    map.jacobian(v, s) as f64,
                    derivative,
                    max_relative = 2e-3
                );
            }
        }
        assert!(map.jacobian(0.0, 0.0) > 0.0);
    }

    /// Every half vector that reflects some wo of a slice's outgoing cell
    /// above the horizon lies in a positive cell of that slice, for every
    /// θ_o cell (wo at 16 θ_o across each cell, the grazing one included,
    /// times 64 × 128 wi at the centres of equal-area cells), and cells
    /// that are positive at the centre wo keep exactly their value. Without
    /// the support pass the grazing cells fail (a Lambertian surface has
    /// f cos θ_i > 0 on the whole upper hemisphere).
    #[test]
    fn every_lit_half_vector_has_a_positive_cell() {
        let res = Resolution::new(8, 1, 32, 8).unwrap();
        let mut checked = 0usize;
        for i in 0..res.theta_o {
            let t = tabulate_slice(&Lambert, &res, i, 0);
            let centre = tabulate_for(&Lambert, slice_outgoing(&res, i, 0), 32, 8);
            for (a, b) in t.iter().zip(&centre) {
                assert!(*b == 0.0 || a == b, "slice {i}: {b} became {a}");
            }
            for s in 0..16 {
                let u = (i as f32 + (s as f32 + 0.5) / 16.0) / res.theta_o as f32;
                let theta_o = FRAC_PI_2 * u * u;
                let wo = spherical_direction(theta_o, 0.0);
                assert_eq!(crate::outgoing_cell(&res, wo).0, i);
                for k in 0..64 {
                    for l in 0..128 {
                        let cos_i = (k as f32 + 0.5) / 64.0;
                        let wi = spherical_direction(cos_i.acos(), TAU * (l as f32 + 0.5) / 128.0);
                        let h = (wo + wi).normalize();
                        let (x, y) = crate::half_vector_cell(h, 0.0, 8, 32);
                        assert!(
                            t[y * 8 + x] > 0.0,
                            "θ_o {theta_o}, wi {wi:?}: cell ({x}, {y}) of slice {i} is 0"
                        );
                        checked += 1;
                    }
                }
            }
        }
        assert_eq!(checked, 8 * 16 * 64 * 128);
    }

    /// With several φ_o cells a slice keeps absolute φ_h and serves every
    /// φ_o of its cell: a half vector that any wo of the cell (θ_o and φ_o
    /// across it) reflects above the horizon has a positive cell. (The
    /// first θ_o cell is left as tabulated; see [`tabulate_slice`].)
    #[test]
    fn every_half_vector_lit_across_a_phi_o_cell_has_a_positive_cell() {
        let res = Resolution::new(4, 4, 32, 8).unwrap();
        let mut checked = 0usize;
        for i in 1..res.theta_o {
            for j in [0, 1] {
                let t = tabulate_slice(&Lambert, &res, i, j);
                for s in 0..6 {
                    let u = (i as f32 + (s as f32 + 0.5) / 6.0) / res.theta_o as f32;
                    let theta_o = FRAC_PI_2 * u * u;
                    for q in 0..6 {
                        let width = TAU / res.phi_o as f32;
                        let phi_o =
                            phi_o_center(j, res.phi_o) + width * ((q as f32 + 0.5) / 6.0 - 0.5);
                        let wo = spherical_direction(theta_o, phi_o);
                        assert_eq!(crate::outgoing_cell(&res, wo), (i, j));
                        for k in 0..32 {
                            for l in 0..64 {
                                let cos_i = (k as f32 + 0.5) / 32.0;
                                let wi = spherical_direction(
                                    cos_i.acos(),
                                    TAU * (l as f32 + 0.5) / 64.0,
                                );
                                let h = (wo + wi).normalize();
                                let (x, y) = crate::half_vector_cell(h, 0.0, 8, 32);
                                assert!(
                                    t[y * 8 + x] > 0.0,
                                    "wo {wo:?}, wi {wi:?}: cell ({x}, {y}) of slice ({i}, {j}) is 0"
                                );
                                checked += 1;
                            }
                        }
                    }
                }
            }
        }
        assert_eq!(checked, 3 * 2 * 36 * 32 * 64);
    }

    /// The support pass adds mass only where the centre tabulation has none,
    /// and little of it: on the isotropic resolution's grazing slice of a
    /// Lambertian surface, well under the table's own mass.
    #[test]
    fn the_support_pass_adds_little_mass() {
        let res = Resolution::ISOTROPIC;
        let i = res.theta_o - 1;
        let filled: f64 = tabulate_slice(&Lambert, &res, i, 0)
            .iter()
            .map(|&v| v as f64)
            .sum();
        let centre: f64 = tabulate_for(&Lambert, slice_outgoing(&res, i, 0), 256, 32)
            .iter()
            .map(|&v| v as f64)
            .sum();
        assert!(
            filled > centre && filled < 1.2 * centre,
            "{filled} against {centre}"
        );
    }

    #[test]
    fn invalid_values_are_sanitised() {
        let t = tabulate_slice(&Broken, &Resolution::new(4, 1, 8, 8).unwrap(), 2, 0);
        assert!(t.iter().all(|v| *v == 0.0));
        assert!(tabulate_for(&Lambert, Vec3::Z, 0, 4).is_empty());
    }
}
