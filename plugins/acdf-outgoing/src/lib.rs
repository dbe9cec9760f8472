//! Adaptive outgoing angles: half-vector slices kept only at the θ_o
//! breakpoints a material needs, and a density that blends the two
//! neighbouring slices linearly in θ_o.
//!
//! **Building.** The material is tabulated at `fine` outgoing angles
//! θ_j = (π/2) u_j², u_j = j / (fine - 1) (the last one at
//! cos θ_o = [`GRAZING_COS`]), with [`tabulate_for`]. Breakpoints are
//! chosen greedily from θ_o = 0: from a kept slice a, the next kept slice
//! b is the farthest for which every dropped slice j between them is
//! reproduced by the blend q_j = (1 - t_j) p_a + t_j p_b (t_j the position
//! of cos θ_j between cos θ_a and cos θ_b, as sampling blends) within
//! `budget` of chi-square divergence,
//! Σ p_j² / q_j - 1 over the table cells (p normalised per slice): the
//! relative variance the blend adds where the BRDF equals its table. Each
//! kept slice then gets the support pass of [`fill_support`] for every
//! outgoing direction between its neighbouring breakpoints. The simplifier
//! chooses one grid for all of them on a table made of their normalised
//! tables (half their mean, half the sum of their square roots; an
//! [`AdaptiveCdf2D`](acdf_adaptive_cdf::AdaptiveCdf2D), first θ_h row pinned, as the
//! adaptive sampler does, but with a quarter of a chi-square tolerance
//! for the θ_h marginal and three quarters for the φ_h conditionals,
//! [`SHARED_MARGINAL_SHARE`](acdf_adaptive_cdf::quantised::SHARED_MARGINAL_SHARE)),
//! and every slice keeps its own masses on that
//! grid as 16-bit CDF values ([`SharedSlices`]); the grid is stored once,
//! as 16-bit θ_h and 8-bit φ_h grid indices.
//!
//! **Sampling.** For wo with cos θ_o between the cosines c_k > c_{k+1} of
//! breakpoints k and k + 1, t = (c_k - cos θ_o) / (c_k - c_{k+1}): slice k
//! is drawn from with probability 1 - t and slice k + 1 with probability t
//! (u.x decides and is rescaled), the other slice's density is read in the
//! drawn cell (the grid is shared, so no search), and the density is
//! p = ((1 - t) p_k(x, v) + t p_{k+1}(x, v)) / (J(v) · 4 (wo·h)), which is
//! exactly the density of that two-step draw and continuous in wo (the
//! weights are continuous and equal 0 or 1 at the breakpoints). The weight
//! is linear in cos θ_o rather than in u_o, the variable the breakpoints
//! are spaced in, so that k and t follow from wo.z by compares with the
//! breakpoints' cosines and one product (`ThetaOBlend`): no arctangent
//! or square root stands between wo and the first table read of a call,
//! where weights linear in u_o would need θ_o first (both are timed in
//! `docs/performance.md`). The half-vector coordinates are those of the
//! tabulated sampler ([`HalfMap`], φ_h measured from φ_o), so isotropic
//! materials only.
//! Wherever f cos θ_i > 0 for a wo between two breakpoints, one of the two
//! slices is positive (the support pass covered the interval), and its
//! weight is positive unless wo sits on the other breakpoint, whose own
//! slice then covers it.
//!
//! **Why the slices share one grid.** With vertices of its own, each slice
//! fits its own lobe, but a draw then searches the drawn slice (marginal
//! and conditional) and again the other slice at the drawn point, and a
//! density searches both: four searches. On one grid a draw searches the
//! drawn slice's CDF values once per axis and reads the other slice in the
//! same cell, and a density searches the positions once per axis and reads
//! both: two searches, and a slice costs two bytes per vertex instead of
//! three (conditional) to six (marginal), so the storage cap holds more
//! slices and vertices. The price is a grid that fits no slice as closely
//! as its own vertices would. Slices with their own vertices against the
//! shared grid, in instructions per call and in storage, variance and
//! fireflies at the storage cap, are compared in `docs/results.md`.
//!
//! The grid's table is half the mean of the kept slices' normalised
//! tables p_s and half Σ_s √p_s, each scaled to unit mass. Either alone
//! fails some materials (measured in `docs/results.md`): the mean gives
//! fireflies on the measured materials, the root a higher variance on
//! mirror-like ones. On the mean, a slice whose lobe is narrower than the
//! others' weighs little, and the simplifier merges the cells of its peak
//! and tails, hence the fireflies. The root lifts every slice's low values
//! towards its peak, so the grid keeps vertices wherever any slice
//! changes, but spends them on tails where a mirror-like lobe needs them
//! on its peak.
//!
//! **Storage** counts every byte a file keeps: the breakpoints (f32), the
//! grid and each slice's CDF values, without the end vertices of any
//! curve, which are always (0, 0) and (n, 65535) and are put back on
//! loading ([`CompactSlices`]); a conditional's vertices are located by a
//! count of its inner vertices (one byte per θ_h segment) rather than a
//! 16-bit offset. Memory holds the full curves, which the draws read.

// `!(x > 0.0)` is how this module says "not positive, or NaN": the negated
// comparison is the point, since NaN must take the rejecting branch.
#![allow(clippy::neg_cmp_op_on_partial_ord)]
#![forbid(unsafe_code)]

pub mod anisotropic;
mod batch;
pub mod persist;

pub use acdf_adaptive_cdf::quantised::{
    CompactSlices, GridCell, GridDraw, PackedCdf2D, SharedSlices, NO_CONDITIONAL,
};
pub use anisotropic::AnisotropicOutgoingSampler;

use acdf_adaptive_cdf::simplify::{simplifier_by_name, validate_tolerance, Simplifier};
use acdf_core::fast::{fast_atan2, sin_cos_turns};
use acdf_core::geometry::sin_theta;
use acdf_core::warp::square_to_cosine_hemisphere;
use acdf_core::{
    clamp_unit, is_valid_outgoing, Brdf, BxdfSample, BxdfSampler, Error, Result, Vec2, Vec3,
    ONE_MINUS_EPSILON,
};
use acdf_tabulated::tabulate::{fill_support, HalfMap, GRAZING_COS};
use acdf_tabulated::{tabulate_for, Resolution};
use batch::Simd;
use rayon::prelude::*;
use std::f32::consts::{FRAC_PI_2, TAU};
use std::sync::Arc;

/// The budget of chi-square divergence for a dropped θ_o slice at the
/// default tolerance; at another tolerance it scales with it.
///
/// With [`TOLERANCE_SCALE`] it was chosen by `acdf report` on
/// `nbrdf:nickel`, `nbrdf:blue-metallic-paint` and `nbrdf:gray-plastic` at
/// the storage cap, among 0.002, 0.004 and 0.008: 0.004 gives nearly the
/// variance of 0.002 with fewer kept slices, so it builds faster, and the
/// lower fireflies on two of the three materials; 0.008 raises the
/// variance on blue-metallic-paint and the fireflies on gray-plastic
/// (measured in `docs/results.md`).
pub const DEFAULT_BUDGET: f64 = 0.004;

/// The default tolerance of an outgoing sampler over its simplifier's
/// default (see [`DEFAULT_BUDGET`]); the storage cap's fill steps then
/// lower it to where the sampler fits.
pub const TOLERANCE_SCALE: f64 = 2.0;

/// The default number of fine θ_o slices per θ_o cell of the requested
/// resolution (32 cells: 128 fine slices).
pub const FINE_PER_CELL: usize = 4;

/// The parameters of an outgoing sampler.
#[derive(Debug, Clone)]
pub struct OutgoingBuilder {
    /// The curve simplifier of each kept slice.
    pub simplifier: Arc<dyn Simplifier>,
    /// Its tolerance.
    pub tolerance: f64,
    /// The chi-square budget of a dropped θ_o slice.
    pub budget: f64,
    /// Fine θ_o slices tabulated to choose the breakpoints from (at least 2).
    pub fine: usize,
    /// A storage cap: when the sampler would store more, the tolerance and
    /// the budget are raised together by [`CAP_STEP`] until it fits (at
    /// most 7 times); when it stores less, they are lowered by
    /// [`FILL_STEP`] while it still fits (at most [`FILL_TRIES`] times; a
    /// step that overshoots is retried once at its square root).
    /// [`by_name`](Self::by_name) sets
    /// [`DEFAULT_MAX_BYTES`] at the default tolerance and none at a given
    /// one. A built sampler records the tolerance and budget it used.
    pub max_bytes: Option<usize>,
}

impl OutgoingBuilder {
    /// The simplifier called `name` at `tolerance` (when `None`, its default
    /// times [`TOLERANCE_SCALE`] with the storage cap [`DEFAULT_MAX_BYTES`]),
    /// the budget in proportion, and `fine` fine slices.
    pub fn by_name(name: &str, tolerance: Option<f64>, fine: usize) -> Result<Self> {
        Self::with_defaults(name, tolerance, fine, TOLERANCE_SCALE, DEFAULT_BUDGET)
    }

    /// [`by_name`](Self::by_name) for the anisotropic sampler, whose
    /// slices keep their own vertices: its default tolerance is the
    /// simplifier's times
    /// [`ANISOTROPIC_TOLERANCE_SCALE`](anisotropic::ANISOTROPIC_TOLERANCE_SCALE),
    /// with the budget
    /// [`ANISOTROPIC_BUDGET`](anisotropic::ANISOTROPIC_BUDGET) there.
    pub fn anisotropic_by_name(name: &str, tolerance: Option<f64>, fine: usize) -> Result<Self> {
        Self::with_defaults(
            name,
            tolerance,
            fine,
            anisotropic::ANISOTROPIC_TOLERANCE_SCALE,
            anisotropic::ANISOTROPIC_BUDGET,
        )
    }

    /// The builder at `tolerance`, or at the simplifier's default times
    /// `scale` (with the storage cap), the budget `budget_at_default` times
    /// the tolerance over that default.
    fn with_defaults(
        name: &str,
        tolerance: Option<f64>,
        fine: usize,
        scale: f64,
        budget_at_default: f64,
    ) -> Result<Self> {
        let simplifier = simplifier_by_name(name)?;
        let default = simplifier.default_tolerance() * scale;
        let at_default = tolerance.is_none();
        let tolerance = tolerance.unwrap_or(default);
        // The budget follows the tolerance, so that one knob (the
        // tolerance, as `--tolerance` and `--target-efficiency` set it)
        // trades storage for variance along both axes.
        let budget = if default > 0.0 {
            budget_at_default * tolerance / default
        } else {
            budget_at_default
        };
        let b = OutgoingBuilder {
            simplifier,
            max_bytes: at_default.then_some(DEFAULT_MAX_BYTES),
            tolerance,
            budget,
            fine,
        };
        b.validate()?;
        Ok(b)
    }

    /// Check the parameters.
    pub fn validate(&self) -> Result<()> {
        validate_tolerance(self.tolerance)?;
        if !(self.budget >= 0.0 && self.budget.is_finite()) {
            return Err(Error::InvalidParameter {
                name: "outgoing budget",
                reason: format!("{} is not a finite non-negative number", self.budget),
            });
        }
        if !(2..=4096).contains(&self.fine) {
            return Err(Error::InvalidParameter {
                name: "fine theta_o slices",
                reason: format!("{} is not in 2..=4096", self.fine),
            });
        }
        Ok(())
    }

    /// `outgoing:<simplifier>`.
    pub fn name(&self) -> String {
        format!("outgoing:{}", self.simplifier.name())
    }
}

/// The outgoing sampler of an isotropic material (module documentation).
pub struct OutgoingSampler {
    brdf: Arc<dyn Brdf>,
    builder: OutgoingBuilder,
    name: String,
    n_theta_h: usize,
    n_phi_h: usize,
    /// (n_phi_h, n_theta_h) as floats, as the slices take them.
    cells: (f32, f32),
    map: HalfMap,
    /// u_o of each kept slice: 0 first, 1 last, increasing.
    breakpoints: Vec<f32>,
    /// The blend weights of the breakpoints' slices.
    blend: ThetaOBlend,
    slices: SharedSlices,
    cosine_fraction: f32,
}

/// The bytes of `breakpoints` breakpoints (f32) and their slices, as a
/// file stores them.
fn stored_bytes(breakpoints: usize, slices: &SharedSlices) -> usize {
    4 * breakpoints + slices.storage_bytes()
}

/// The storage the default tolerance keeps within: 1000 times less than
/// the 32x16x256x32 table of Lawrence et al. (the uniform sampler at that
/// resolution, 17,627,136 bytes).
pub const DEFAULT_MAX_BYTES: usize = 17_627;

/// The factor by which a capped build raises its tolerance and budget.
pub const CAP_STEP: f64 = 1.5;

/// Builds a capped sampler tries at most.
pub(crate) const CAP_TRIES: usize = 8;

/// The factor by which a capped build whose first try has room under the
/// cap lowers its tolerance and budget, as long as the sampler still fits;
/// a step that overshoots the cap is followed by one try of its square
/// root.
///
/// √1.5: two steps make one [`CAP_STEP`]. With the square-root try, the
/// three measured materials of the outgoing sampler's report land 0.5 to
/// 15% under the cap (17.1, 14.7 and 15.7 KiB; `docs/results.md`, section
/// "Adaptive outgoing angles").
pub const FILL_STEP: f64 = 1.224_744_871;

/// Lowerings of the tolerance a capped build tries at most (down to
/// FILL_STEP^-4, about 0.44 times the default).
pub const FILL_TRIES: usize = 4;

/// The weight t of the second slice when wo's cos θ_o = z lies between
/// the cosines c_a >= z >= c_b of two breakpoints: (c_a - z) / (c_a - c_b),
/// 0 where the two cosines are equal.
pub(crate) fn cos_weight(c_a: f32, c_b: f32, z: f32) -> f32 {
    if c_a > c_b {
        ((c_a - z) / (c_a - c_b)).clamp(0.0, 1.0)
    } else {
        0.0
    }
}

/// Where an outgoing direction falls among the kept breakpoints: its two
/// slices k and k + 1 and the weight t of the second, linear in cos θ_o
/// (module documentation).
#[derive(Debug, Clone)]
struct ThetaOBlend {
    /// -cos θ_o of the inner breakpoints (ascending), padded with +∞ to a
    /// multiple of 8 so that the count compiles to whole SIMD compares.
    negative_inner_cos: Vec<f32>,
    /// Per breakpoint k but the last: (c_k, 1 / (c_k - c_{k+1})), the second
    /// 0 where the cosines are equal.
    steps: Vec<(f32, f32)>,
}

impl ThetaOBlend {
    /// The blend of the breakpoints `u` (u_o, increasing from 0 to 1).
    fn new(u: &[f32]) -> Self {
        let cos = cos_theta_o(u);
        let inner = cos.len().saturating_sub(2);
        let mut negative_inner_cos: Vec<f32> = cos[1..1 + inner].iter().map(|&c| -c).collect();
        negative_inner_cos.resize(inner.div_ceil(8).max(1) * 8, f32::INFINITY);
        let steps = cos
            .windows(2)
            .map(|w| {
                (
                    w[0],
                    if w[0] > w[1] {
                        1.0 / (w[0] - w[1])
                    } else {
                        0.0
                    },
                )
            })
            .collect();
        ThetaOBlend {
            negative_inner_cos,
            steps,
        }
    }

    /// (k, t) for cos θ_o = z in [0, 1]: k the number of inner breakpoints
    /// whose cosine is at or above z (a count with no data-dependent
    /// branch), t = (c_k - z) / (c_k - c_{k+1}) clamped to [0, 1]. A single
    /// breakpoint gives (0, 0); NaN gives (0, 0). With the AVX2 token the
    /// count is one mask per eight breakpoints
    /// ([`count_ascending_at_or_below`](acdf_core::search::lanes::count_ascending_at_or_below)),
    /// with no sum across lanes at the end: k heads the chain of a per-call
    /// `sample`, whose first table search waits for it. Both count the
    /// same, since the list ascends.
    #[inline(always)]
    fn at(&self, simd: Simd, z: f32) -> (usize, f32) {
        let key = -z;
        let k = match simd {
            #[cfg(target_arch = "x86_64")]
            Some(cpu) => acdf_core::search::lanes::count_ascending_at_or_below(
                cpu,
                &self.negative_inner_cos,
                key,
            ),
            _ => {
                // Eight counts side by side, one per lane of a vector
                // compare, added up at the end.
                let mut counts = [0u32; 8];
                for chunk in self.negative_inner_cos.chunks_exact(8) {
                    for (count, &b) in counts.iter_mut().zip(chunk) {
                        *count += u32::from(b <= key);
                    }
                }
                counts.iter().sum::<u32>() as usize
            }
        };
        match self.steps.get(k) {
            Some(&(c, inverse)) => {
                let t = (c - z) * inverse;
                // `t > 0.0` is false for NaN.
                (k, if t > 0.0 { t.min(1.0) } else { 0.0 })
            }
            None => (0, 0.0),
        }
    }
}

/// cos θ_o of the nodes `u` (u_o), as [`outgoing_at`] places them.
fn cos_theta_o(u: &[f32]) -> Vec<f32> {
    u.iter().map(|&u| outgoing_at(u).z).collect()
}

/// θ_o of the fine node u (the grazing end at cos θ_o = [`GRAZING_COS`]).
pub(crate) fn outgoing_at(u: f32) -> Vec3 {
    let theta = FRAC_PI_2 * u * u;
    let (sin_t, cos_t) = theta.sin_cos();
    if cos_t > GRAZING_COS {
        Vec3::new(sin_t, 0.0, cos_t)
    } else {
        Vec3::new((1.0 - GRAZING_COS * GRAZING_COS).sqrt(), 0.0, GRAZING_COS)
    }
}

/// Σ p² / q - 1 of the table `p` against the blend `(1 - t) a + t b` (all
/// normalised), where q = 0 with p > 0 counts p² / (p / 1000): a missing
/// cell costs a thousand times its mass.
pub(crate) fn blend_divergence(p: &[f32], a: &[f32], b: &[f32], t: f32) -> f64 {
    let mut sum = 0.0f64;
    for ((&p, &a), &b) in p.iter().zip(a).zip(b) {
        if p > 0.0 {
            let q = ((1.0 - t) * a + t * b).max(1e-3 * p);
            sum += (p as f64) * (p as f64) / q as f64;
        }
    }
    sum - 1.0
}

/// The breakpoints (indices into the fine nodes) kept for tables `p`
/// (normalised) at nodes `u`: the greedy choice of the module
/// documentation.
fn choose_breakpoints(p: &[Vec<f32>], u: &[f32], budget: f64) -> Vec<usize> {
    let n = p.len();
    let cos = cos_theta_o(u);
    let fits = |a: usize, b: usize| {
        ((a + 1)..b).into_par_iter().all(|j| {
            let t = cos_weight(cos[a], cos[b], cos[j]);
            blend_divergence(&p[j], &p[a], &p[b], t) <= budget
        })
    };
    let mut kept = vec![0];
    let mut a = 0;
    while a < n - 1 {
        let mut b = a + 1;
        while b + 1 < n && fits(a, b + 1) {
            b += 1;
        }
        kept.push(b);
        a = b;
    }
    kept
}

/// The outgoing directions a kept slice serves, at φ_o = 0: from u_lo to
/// u_hi in steps of at most 1/64 in u_o, both ends included.
pub(crate) fn served_between(u_lo: f32, u_hi: f32) -> Vec<Vec3> {
    let steps = (((u_hi - u_lo) * 64.0).ceil() as usize).max(1);
    (0..=steps)
        .map(|k| outgoing_at(u_lo + (u_hi - u_lo) * k as f32 / steps as f32))
        .collect()
}

impl OutgoingSampler {
    /// Build the sampler of `brdf` (isotropic) with `resolution.theta_h` ×
    /// `resolution.phi_h` half-vector cells per slice and
    /// [`FINE_PER_CELL`] × `resolution.theta_o` fine θ_o slices unless the
    /// builder says otherwise. Errors: an anisotropic or zero material, an
    /// invalid resolution or a table beyond the memory limit.
    pub fn new(
        brdf: Arc<dyn Brdf>,
        resolution: Resolution,
        builder: OutgoingBuilder,
    ) -> Result<Self> {
        resolution.validate()?;
        builder.validate()?;
        if brdf.is_zero_everywhere() {
            return Err(Error::ZeroMaterial {
                material: brdf.name().to_string(),
            });
        }
        if !brdf.is_isotropic() {
            return Err(Error::InvalidParameter {
                name: "material",
                reason: format!(
                    "`{}` is anisotropic; the outgoing sampler serves isotropic materials",
                    brdf.name()
                ),
            });
        }
        let (n_theta_h, n_phi_h) = (resolution.theta_h, resolution.phi_h);
        let fine = builder.fine;
        acdf_io::limits::check_memory(
            "the fine tabulation of an outgoing sampler",
            (fine as u64).saturating_mul(resolution.cells_per_slice() as u64) * 8,
        )?;
        let u: Vec<f32> = (0..fine).map(|j| j as f32 / (fine - 1) as f32).collect();
        let tables: Vec<Vec<f32>> = u
            .par_iter()
            .map(|&u| tabulate_for(&*brdf, outgoing_at(u), n_theta_h, n_phi_h))
            .collect();
        let normalised: Vec<Vec<f32>> = tables
            .par_iter()
            .map(|t| {
                let sum: f64 = t.iter().map(|&v| v as f64).sum();
                let scale = if sum > 0.0 { (1.0 / sum) as f32 } else { 0.0 };
                t.iter().map(|&v| v * scale).collect()
            })
            .collect();
        // The kept breakpoints and their slices at a builder's tolerance
        // and budget.
        let build = |b: &OutgoingBuilder| -> Result<(Vec<usize>, SharedSlices)> {
            let kept = choose_breakpoints(&normalised, &u, b.budget);
            let filled: Vec<Vec<f32>> = kept
                .par_iter()
                .enumerate()
                .map(|(i, &k)| {
                    let lo = u[kept[i.saturating_sub(1)]];
                    let hi = u[kept[(i + 1).min(kept.len() - 1)]];
                    let mut values = tables[k].clone();
                    fill_support(
                        &*brdf,
                        &served_between(lo, hi),
                        n_theta_h,
                        n_phi_h,
                        &mut values,
                    );
                    values
                })
                .collect();
            let slices =
                SharedSlices::build(&filled, n_phi_h, n_theta_h, &*b.simplifier, b.tolerance)?;
            Ok((kept, slices))
        };
        let bytes = |(kept, slices): &(Vec<usize>, SharedSlices)| stored_bytes(kept.len(), slices);
        let mut builder = builder;
        let mut built = build(&builder)?;
        if let Some(cap) = builder.max_bytes {
            if bytes(&built) > cap {
                // Over the cap: the tolerance and the budget grow together
                // by CAP_STEP until the sampler fits (or CAP_TRIES builds
                // are spent).
                for _ in 1..CAP_TRIES {
                    if bytes(&built) <= cap {
                        break;
                    }
                    builder.tolerance *= CAP_STEP;
                    builder.budget *= CAP_STEP;
                    built = build(&builder)?;
                }
            } else {
                // Room under the cap: both shrink by FILL_STEP while the
                // sampler still fits (at most FILL_TRIES times), spending
                // the storage on variance; where a step overshoots, half
                // of it (in ratio) is tried once.
                let finer = |b: &OutgoingBuilder, step: f64| {
                    let mut finer = b.clone();
                    finer.tolerance /= step;
                    finer.budget /= step;
                    finer
                };
                for _ in 0..FILL_TRIES {
                    let mut next = finer(&builder, FILL_STEP);
                    let mut candidate = build(&next)?;
                    let overshoot = bytes(&candidate) > cap;
                    if overshoot {
                        next = finer(&builder, FILL_STEP.sqrt());
                        candidate = build(&next)?;
                        if bytes(&candidate) > cap {
                            break;
                        }
                    }
                    (builder, built) = (next, candidate);
                    if overshoot {
                        break;
                    }
                }
            }
        }
        let (kept, slices) = built;
        let breakpoints = kept.iter().map(|&k| u[k]).collect();
        Ok(Self::from_parts(
            brdf,
            builder,
            n_theta_h,
            n_phi_h,
            breakpoints,
            slices,
        ))
    }

    /// A sampler of stored parts (checked by the caller).
    pub(crate) fn from_parts(
        brdf: Arc<dyn Brdf>,
        builder: OutgoingBuilder,
        n_theta_h: usize,
        n_phi_h: usize,
        breakpoints: Vec<f32>,
        slices: SharedSlices,
    ) -> Self {
        OutgoingSampler {
            name: builder.name(),
            brdf,
            builder,
            n_theta_h,
            n_phi_h,
            cells: (n_phi_h as f32, n_theta_h as f32),
            map: HalfMap::new(n_theta_h),
            blend: ThetaOBlend::new(&breakpoints),
            breakpoints,
            slices,
            cosine_fraction: 0.0,
        }
    }

    /// Mix in the cosine lobe with probability `fraction` in [0, 1]:
    /// p = (1 - a) p_table + a cos θ_i / π.
    pub fn with_cosine_mix(mut self, fraction: f32) -> Result<Self> {
        self.cosine_fraction = acdf_tabulated::check_cosine_fraction(fraction)?;
        Ok(self)
    }

    /// The probability of drawing from the cosine lobe.
    pub fn cosine_mix(&self) -> f32 {
        self.cosine_fraction
    }

    /// The material sampled (for a loaded sampler, its record).
    pub fn brdf(&self) -> &Arc<dyn Brdf> {
        &self.brdf
    }

    /// The parameters.
    pub fn builder(&self) -> &OutgoingBuilder {
        &self.builder
    }

    /// The kept θ_o breakpoints, as θ_o in radians.
    pub fn breakpoint_angles(&self) -> Vec<f32> {
        self.breakpoints
            .iter()
            .map(|&u| FRAC_PI_2 * u * u)
            .collect()
    }

    /// The kept slices on their shared grid, in the order of the
    /// breakpoints.
    pub fn slices(&self) -> &SharedSlices {
        &self.slices
    }

    /// Half-vector cells per slice (θ_h, φ_h).
    pub fn half_vector_cells(&self) -> (usize, usize) {
        (self.n_theta_h, self.n_phi_h)
    }

    /// (marginal vertices, mean vertices of the stored conditionals) of the
    /// slices' shared grid.
    pub fn mean_vertices(&self) -> (f64, f64) {
        let (vertices, stored) = self.slices.conditional_vertices();
        (
            self.slices.marginal_vertex_count() as f64,
            vertices as f64 / stored.max(1) as f64,
        )
    }

    /// What the draws and densities of a valid wo share: its two slices and
    /// the weight of the second, (k, t) with breakpoint k at or before θ_o
    /// ([`ThetaOBlend::at`]), sin θ_o and the rotation (cos φ_o, sin φ_o)
    /// (φ_o = 0 on the pole). The batch forms compute it once for all their
    /// draws.
    #[inline(always)]
    fn outgoing(&self, simd: Simd, wo: Vec3) -> Outgoing {
        let s = sin_theta(wo);
        let rotation = if s > 0.0 {
            Vec2::new(wo.x, wo.y) / s
        } else {
            Vec2::X
        };
        let (k, t) = self.blend.at(simd, wo.z);
        Outgoing {
            k,
            t,
            rotation,
            sin_o: s,
        }
    }

    /// The blended density of the two slices at the table point of
    /// defined coordinates `c` (over the unit square).
    #[inline(always)]
    fn blended_density(&self, o: &Outgoing, c: &Coordinates) -> f32 {
        let (k, t) = (o.k, o.t);
        let mut p = 0.0;
        if let (Some(cell), _) = self.slices.locate(c.x, c.v, self.cells, (0.0, 0.0)) {
            if t < 1.0 {
                p += (1.0 - t) * self.slices.density(k, &cell);
            }
            if t > 0.0 {
                p += t * self.slices.density(k + 1, &cell);
            }
        }
        p
    }

    /// The table's density per solid angle at coordinates `c` whose
    /// blended density is `blended` (any value where `c` is not defined or
    /// the table is never drawn from): 0 there, and 0 unless positive and
    /// finite. Written without branches, so that the batch path's loop
    /// over a chunk compiles to SIMD.
    #[inline(always)]
    fn table_density(&self, blended: f32, c: &Coordinates) -> f32 {
        let table = blended / (self.map.jacobian(c.v, c.sin_h) * 4.0 * c.wo_h);
        if is_positive_finite(table) & (self.cosine_fraction < 1.0) & c.defined {
            table
        } else {
            0.0
        }
    }

    /// The table point of a draw for a valid wo: slice k with probability
    /// 1 - t, slice k + 1 with t (u.x decides and is rescaled), and the
    /// blended density of the point, which the other slice's lookup
    /// completes.
    #[inline(always)]
    fn table_point(&self, o: &Outgoing, u: Vec2) -> TablePoint {
        let (drawn, other, ux, w_drawn) = pick_slice(o.k, o.t, u);
        let d = self.slices.sample(drawn, ux, u.y, self.cells, CELL_MARGIN);
        let (x, v) = d.p;
        let mut p_xv = w_drawn * self.slices.density(drawn, &d.cell);
        let w_other = 1.0 - w_drawn;
        if w_other > 0.0 {
            // The other slice's cells are the drawn one's: no search.
            p_xv += w_other * self.slices.density(other, &d.cell);
        }
        TablePoint {
            x,
            v,
            p_xv,
            same: d.same_around,
        }
    }

    /// A table draw for a valid wo: wi, and its density (the table's
    /// mixed with the cosine lobe's) when the drawn point certainly has the
    /// table density `pdf` would find for wi (see [`CELL_MARGIN`]), `None`
    /// when it must be recomputed.
    #[inline(always)]
    fn sample_table(&self, o: &Outgoing, wo: Vec3, u: Vec2) -> (Vec3, Option<f32>) {
        let point = self.table_point(o, u);
        let angles = (self.map.angles(point.v), sin_cos_turns(point.x));
        let d = draw_at(self.map, o, wo, &point, angles);
        let pdf = acdf_tabulated::mix_with_cosine(self.cosine_fraction, d.table, d.wi);
        (d.wi, d.shortcut.then_some(pdf))
    }
}

/// The slice a table draw with u comes from, for wo between slices k and
/// k + 1 at t: slice k with probability 1 - t, slice k + 1 with t (u.x
/// decides and is rescaled). Returns the drawn slice, the other, u.x
/// rescaled to [0, 1) and the drawn slice's weight. (The lanes of the
/// batch paths make the same choice with selects rather than a branch,
/// which a coin toss mispredicts on half the draws:
/// `acdf_core::simd::shared_grid`.)
#[inline(always)]
fn pick_slice(k: usize, t: f32, u: Vec2) -> (usize, usize, f32, f32) {
    let (drawn, other, ux, w_drawn) = if u.x < 1.0 - t {
        (k, k + 1, u.x / (1.0 - t), 1.0 - t)
    } else {
        (k + 1, k, (u.x - (1.0 - t)) / t, t)
    };
    (drawn, other, clamp_unit(ux), w_drawn)
}

/// A table draw before its geometry: the point (x, v) drawn in the unit
/// square, its blended density there, and whether both slices are
/// constant around it.
#[derive(Debug, Clone, Copy, Default)]
struct TablePoint {
    x: f32,
    v: f32,
    p_xv: f32,
    same: bool,
}

/// A table draw in the shading frame.
#[derive(Debug, Clone, Copy, Default)]
struct Drawn {
    wi: Vec3,
    /// p_xv / (J(v) · 4 (wo·h)).
    table: f32,
    /// Whether `table` stands for `pdf(wo, wi)` (both slices constant
    /// around the point, and the geometry far from its singular places).
    shortcut: bool,
}

/// The draw at `point` given its half vector's angles ((sin, cos) θ_h,
/// (sin, cos) φ_h). Free of branches but for the ones the compiler turns
/// into selects, so that the batch loop over a chunk of draws compiles to
/// SIMD (`batch.rs`); the one-at-a-time path runs the same operations.
#[inline(always)]
fn draw_at(
    map: HalfMap,
    o: &Outgoing,
    wo: Vec3,
    point: &TablePoint,
    ((sin_h, cos_h), (sin_p, cos_p)): ((f32, f32), (f32, f32)),
) -> Drawn {
    let (local, h) = half_vector(o.rotation, ((sin_h, cos_h), (sin_p, cos_p)));
    // wo·h in the slice's axes, where wo is (sin θ_o, 0, cos θ_o): it
    // does not wait for the rotation of h.
    let wo_h = o.sin_o * local.x + wo.z * local.z;
    let wi = acdf_tabulated::sampler::unit_reflection(wo, h, wo_h);
    let v = point.v;
    let geometry = (wo_h >= 0.125) & (wo_h * sin_h >= 1.0 / 512.0) & (v >= map.cap_top());
    let table = point.p_xv / (map.jacobian(v, sin_h) * 4.0 * wo_h);
    Drawn {
        wi,
        table,
        shortcut: point.same & geometry & is_positive_finite(table),
    }
}

/// The half vector of the angles ((sin, cos) θ_h, (sin, cos) φ_h) in the
/// slice's axes (`local`) and turned by `rotation` (cos φ, sin φ) about the
/// normal into the shading frame (`h`).
#[inline(always)]
fn half_vector(
    rotation: Vec2,
    ((sin_h, cos_h), (sin_p, cos_p)): ((f32, f32), (f32, f32)),
) -> (Vec3, Vec3) {
    let r = rotation;
    let local = Vec3::new(sin_h * cos_p, sin_h * sin_p, cos_h);
    let h = Vec3::new(
        r.x * local.x - r.y * local.y,
        r.y * local.x + r.x * local.y,
        local.z,
    );
    (local, h)
}

/// Where the density of a wi is looked up: the table point (x, v) of its
/// half vector, with sin θ_h and wo·h for the density's Jacobian
/// J(v) · 4 (wo·h).
#[derive(Debug, Clone, Copy, Default)]
struct Coordinates {
    x: f32,
    v: f32,
    sin_h: f32,
    wo_h: f32,
    /// The half vector defined (wi ≠ -wo, finite) and wo·h > 0.
    defined: bool,
}

/// The coordinates of wi for wo, whose slices' axes are turned by
/// `rotation` (cos φ, sin φ) about the normal; undefined coordinates may
/// hold anything.
///
/// With `ONE` false (the batch path) free of branches like [`draw_at`], so
/// that a loop over a chunk compiles to SIMD. With `ONE` true (one call at
/// a time) it returns as soon as the coordinates are known to be
/// undefined: the same operations in the same order for defined ones.
/// Without the returns the compiler pairs the two arctangents in vector
/// registers, and one call at a time then pays for packing and unpacking
/// them on every `pdf` and `sample` (the `hotpath` example counts the
/// instructions).
#[inline(always)]
fn coordinates<const ONE: bool>(map: HalfMap, rotation: Vec2, wo: Vec3, wi: Vec3) -> Coordinates {
    let sum = wi + wo;
    let length_squared = sum.length_squared();
    // `&` rather than `&&`: no short-circuit branches.
    let sum_defined = (length_squared > 1e-20) & length_squared.is_finite();
    if ONE && !sum_defined {
        return Coordinates::default();
    }
    let scale = length_squared.sqrt().recip();
    let rho = sin_theta(sum);
    let sin_h = rho * scale;
    // |wo + wi| / 2, which keeps its digits where the sum nearly cancels
    // (see `TabulatedBrdfSampler`'s `coordinates_of` in acdf-tabulated).
    let wo_h = 0.5 * length_squared * scale;
    if ONE && !(wo_h > 0.0) {
        return Coordinates::default();
    }
    let v = map.v_of(rho, sum.z, scale).min(ONE_MINUS_EPSILON);
    let r = rotation;
    let (hx, hy) = (r.x * sum.x + r.y * sum.y, r.x * sum.y - r.y * sum.x);
    let mut phi = fast_atan2(hy, hx);
    if phi < 0.0 {
        phi += TAU;
    }
    Coordinates {
        x: (phi / TAU).clamp(0.0, ONE_MINUS_EPSILON),
        v,
        sin_h,
        wo_h,
        defined: sum_defined & (wo_h > 0.0),
    }
}

/// What the draws and densities of one outgoing direction share
/// ([`OutgoingSampler::outgoing`]).
#[derive(Debug, Clone, Copy)]
struct Outgoing {
    k: usize,
    t: f32,
    rotation: Vec2,
    sin_o: f32,
}

impl Outgoing {
    /// A valid stand-in (wo on the normal, the first slice alone), for the
    /// batch lanes whose own wo is invalid: they compute with it and their
    /// results are dropped.
    const NORMAL: Outgoing = Outgoing {
        k: 0,
        t: 0.0,
        rotation: Vec2::X,
        sin_o: 0.0,
    };
}

/// The part of the mixture a draw comes from, with u rescaled to it
/// ([`OutgoingSampler::route`]).
#[derive(Debug, Clone, Copy)]
enum Route {
    Cosine(Vec2),
    Table(Vec2),
}

/// Whether `v` is positive (not zero) and finite: its bit pattern, less
/// one, is below that of the largest finite `f32` (zero wraps around;
/// negative values, infinity and NaN are above): one subtraction and one
/// compare, where `v > 0.0 && v.is_finite()` compiles to a longer
/// classification of the bits.
#[inline(always)]
fn is_positive_finite(v: f32) -> bool {
    v.to_bits().wrapping_sub(1) < f32::MAX.to_bits()
}

/// The half-widths (x, v), in unit coordinates, of the box around a draw
/// over which both blended slices must be constant for `sample` to report
/// the drawn cells' density instead of recomputing it from wi: the
/// tabulated sampler's margins (`acdf_tabulated`'s `CELL_MARGIN`, over six
/// and three and a half times the error of the recomputed coordinates
/// where wo·h >= 1/8 and (wo·h) sin θ_h >= 1/512, outside the polar cap
/// row).
const CELL_MARGIN: (f32, f32) = (1.0 / 32768.0, 1.0 / 65536.0);

impl OutgoingSampler {
    /// [`BxdfSampler::sample`] itself: with probability a a cosine draw,
    /// otherwise a table draw from the slice picked by the blend weights;
    /// the density is `pdf` of the returned wi.
    #[inline(always)]
    fn sample_one(&self, wo: Vec3, u: Vec2, simd: Simd) -> Option<BxdfSample> {
        if !is_valid_outgoing(wo) {
            return None;
        }
        let o = &self.outgoing(simd, wo);
        match self.route(u) {
            Route::Cosine(u) => self.sample_cosine(o, wo, u),
            Route::Table(u) => {
                let (wi, pdf) = self.sample_table(o, wo, u);
                self.finish_draw(o, wo, wi, pdf)
            }
        }
    }

    /// Which part of the mixture u draws from, u rescaled to it: the
    /// cosine lobe for u.x below its fraction a, the table otherwise.
    #[inline(always)]
    fn route(&self, u: Vec2) -> Route {
        let u = Vec2::new(clamp_unit(u.x), clamp_unit(u.y));
        let a = self.cosine_fraction;
        if u.x < a {
            Route::Cosine(Vec2::new(clamp_unit(u.x / a), u.y))
        } else {
            let ux = if a > 0.0 {
                clamp_unit((u.x - a) / (1.0 - a))
            } else {
                u.x
            };
            Route::Table(Vec2::new(ux, u.y))
        }
    }

    /// A draw from the cosine lobe, its density that of the mixture.
    #[inline(always)]
    fn sample_cosine(&self, o: &Outgoing, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        self.finish_draw(o, wo, square_to_cosine_hemisphere(u), None)
    }

    /// The draw of wi, or none below the horizon; its density `pdf` where
    /// the drawn table point gave it, from [`pdf_in`](Self::pdf_in)
    /// otherwise.
    #[inline(always)]
    fn finish_draw(
        &self,
        o: &Outgoing,
        wo: Vec3,
        wi: Vec3,
        pdf: Option<f32>,
    ) -> Option<BxdfSample> {
        if !(wi.z > 0.0) {
            return None;
        }
        let pdf = match pdf {
            Some(pdf) => pdf,
            None => self.pdf_in(o, wo, wi),
        };
        (pdf > 0.0).then_some(BxdfSample { wi, pdf })
    }

    /// [`BxdfSampler::pdf`] itself.
    #[inline(always)]
    fn pdf_one(&self, wo: Vec3, wi: Vec3, simd: Simd) -> f32 {
        if !is_valid_outgoing(wo) {
            return 0.0;
        }
        self.pdf_in(&self.outgoing(simd, wo), wo, wi)
    }

    /// The density at wi for a valid wo whose [`Outgoing`] is `o`.
    #[inline(always)]
    fn pdf_in(&self, o: &Outgoing, wo: Vec3, wi: Vec3) -> f32 {
        // The check of `pdf_with` first, so that an invalid wi costs no
        // coordinates.
        if !wi.is_finite() || !(wi.z > 0.0) {
            return 0.0;
        }
        let c = coordinates::<true>(self.map, o.rotation, wo, wi);
        self.pdf_with(o, wi, &c)
    }

    /// [`pdf_in`](Self::pdf_in) given the coordinates `c` of wi (found for
    /// a whole chunk at once by the batch path, or one at a time).
    #[inline(always)]
    fn pdf_with(&self, o: &Outgoing, wi: Vec3, c: &Coordinates) -> f32 {
        if !wi.is_finite() || !(wi.z > 0.0) {
            return 0.0;
        }
        let a = self.cosine_fraction;
        let table = if c.defined && a < 1.0 {
            self.table_density(self.blended_density(o, c), c)
        } else {
            0.0
        };
        acdf_tabulated::mix_with_cosine(a, table, wi)
    }
}

impl BxdfSampler for OutgoingSampler {
    fn name(&self) -> &str {
        &self.name
    }

    /// With probability a a cosine draw, otherwise a table draw from the
    /// slice picked by the blend weights; the density is `pdf` of the
    /// returned wi (from the drawn cells where they certainly agree).
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        acdf_core::dispatch!(Self::sample_one, self, wo, u)
    }

    /// (1 - a) times the blended table density plus a cos θ_i / π; 0 for an
    /// invalid wo, a non-finite wi or one at or below the horizon.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        acdf_core::dispatch!(Self::pdf_one, self, wo, wi)
    }

    /// `sample` for every u, with the blend and rotation of wo found once.
    fn sample_batch(&self, wo: Vec3, u: &[Vec2], out: &mut [Option<BxdfSample>]) {
        acdf_core::dispatch!(Self::sample_batch_one, self, wo, u, out)
    }

    /// `pdf` for every wi, with the blend and rotation of wo found once.
    fn pdf_batch(&self, wo: Vec3, wi: &[Vec3], out: &mut [f32]) {
        acdf_core::dispatch!(Self::pdf_batch_one, self, wo, wi, out)
    }

    /// `sample` for every pair, a chunk of 64 at a time as
    /// [`sample_batch`](Self::sample_batch) does, with the blend and
    /// rotation of each wo.
    fn sample_each(&self, wo: &[Vec3], u: &[Vec2], out: &mut [Option<BxdfSample>]) {
        acdf_core::dispatch!(Self::sample_each_one, self, wo, u, out)
    }

    /// `pdf` for every pair, as [`sample_each`](Self::sample_each).
    fn pdf_each(&self, wo: &[Vec3], wi: &[Vec3], out: &mut [f32]) {
        acdf_core::dispatch!(Self::pdf_each_one, self, wo, wi, out)
    }

    /// The breakpoints (4 bytes each) and the slices' compact arrays
    /// ([`SharedSlices::storage_bytes`]).
    fn storage_bytes(&self) -> usize {
        stored_bytes(self.breakpoints.len(), &self.slices)
    }
}

#[cfg(test)]
mod tests;
