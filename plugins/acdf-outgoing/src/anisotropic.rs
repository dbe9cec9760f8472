//! Adaptive outgoing angles for anisotropic materials: half-vector slices
//! kept on a tensor grid of θ_o and φ_o breakpoints chosen per material,
//! and a density that blends the four neighbouring slices bilinearly.
//!
//! **Frame.** A slice measures φ_h either from φ_o (the frame of the
//! isotropic outgoing sampler, [`HalfMap`]: the table of the outgoing
//! direction (θ_o, φ_o) at (x, v) is the material's density at the half
//! vector (θ_h, φ_o + 2π x)) or absolutely ([`PhiFrame`]). From φ_o, an
//! isotropic material's slices do not depend on φ_o at all and the horizon
//! cut-off (wi.z = 0) is the same for every φ_o, but a lobe fixed on the
//! surface (an anisotropic density of normals, on which the half vector
//! already centres the specular peak) turns with φ_o, and keeping it takes
//! nearly every fine φ_o node; measured absolutely that lobe stays put. So
//! the builder tabulates an anisotropic material in both frames and keeps
//! the one whose breakpoints keep fewer slices at the budget; an isotropic
//! one is tabulated from φ_o only (one φ_o breakpoint, the fewest).
//!
//! **Symmetry.** A material that is the same under a mirror of the
//! tangent plane (or the turn by π) has, at the mirrored wo, the mirrored
//! table, so slices over an arc of φ_o serve the whole circle
//! ([`symmetry`]): both mirrors x → −x and y → −y (an anisotropic density
//! of normals aligned with the axes) leave a quarter of the circle, one of
//! them or the turn by π half. The builder takes the largest symmetry the
//! fine tables have within the budget (each table against its partner's,
//! carried over), and breakpoints are chosen on the arc's nodes only; a
//! wo outside the arc has the signs of its x and y flipped into it, is
//! drawn from there and its draw flipped back, and its density is the
//! arc's at the flipped pair (exact: a flip of signs loses no bits). On
//! the GGX lobe of the `anisotropic_rgl` example at the storage cap, the
//! quarter circle keeps 41 slices at the tolerance 0.068 (relative
//! variance 0.151) where the whole circle keeps 65 at 0.126 (0.253;
//! `docs/results.md`).
//!
//! **Building.** The material is tabulated at `fine` θ_o nodes
//! u_j = j / (fine - 1) (θ_o = (π/2) u_j², as in the isotropic sampler)
//! times `fine_phi` φ_o nodes φ_l = 2π l / fine_phi, with [`tabulate_for`]
//! (from φ_o: on the material turned by φ_l). Breakpoints are chosen
//! greedily, as in the isotropic sampler: along θ_o the next kept node is
//! the farthest for which every dropped node of every φ_o column is
//! reproduced by the linear blend of its two kept neighbours within
//! `budget` of chi-square divergence. Then each kept θ_o row gets φ_o
//! breakpoints of its own, the same way along its fine φ_o nodes, from
//! φ_o = 0 round to 2π (the node at 2π is the one at 0, so the last
//! interval wraps across the seam), or over the arc of the symmetry from
//! its start to its end, both kept (a row whose nodes all lie within the
//! budget of its first keeps that one alone). A row keeps what its own θ_o needs:
//! on the normal one breakpoint, since φ_o is then undefined; towards the
//! horizon, where the cut-off wi.z = 0 moves through the lobe as φ_o
//! turns, more. (One set for every row, a tensor grid, would give every
//! row what the most demanding rows need: on the GGX lobe of the
//! `anisotropic_rgl` example at the budget 0.051, 96 slices where the rows
//! keep 51 in all, counted on its fine tables in the absolute frame.)
//! Each kept slice gets the support pass of
//! [`fill_support`] for the outgoing directions it serves (from the
//! previous to the next θ_o row, and from the previous to the next φ_o
//! breakpoint of its row), is simplified into an [`AdaptiveCdf2D`] (first
//! θ_h row pinned) and stored as a [`PackedCdf2D`].
//!
//! **Sampling.** For wo between θ_o rows k, k + 1 (weight t of the second,
//! linear in u_o), and in each row r of the two between its φ_o
//! breakpoints m_r, m_r + 1 (weight s_r, linear in φ_o, m_r + 1 taken
//! modulo the row's count on the circle; on an arc the last interval ends
//! at the arc's end), slice (k, m_k) is drawn from with probability
//! (1 - t)(1 - s_k), (k, m_k + 1) with (1 - t) s_k, (k + 1, m_{k+1}) with
//! t (1 - s_{k+1}) and (k + 1, m_{k+1} + 1) with t s_{k+1} (u.x decides and
//! is rescaled). The density is the same mixture of the four slices'
//! densities: exactly the density of that two-step draw, and continuous in
//! wo: in θ_o because row k + 1 has no weight at row k, in φ_o within each
//! row, across the seam as well (at φ_o → 2π, s_r → 1 and slice m_r + 1 is
//! the row's slice 0, which has all the weight at φ_o = 0). On the normal,
//! φ_o = 0.
//!
//! **Storage** counts every byte kept: the breakpoints (f32), a count per
//! θ_o row, and each slice's arrays. Under a cap
//! ([`OutgoingBuilder::max_bytes`]) the tolerance and the budget move
//! together on a ladder of steps of [`FILL_STEP`] (√1.5), from 12 steps
//! below the default to 14 above (1.5^7), to the smallest that fits:
//! judged first on an estimate that skips the support passes (the fine
//! tables at the kept nodes, simplified), then on builds, a step up at a
//! time while a build is over the cap. Where the default has room, the
//! room is spent on variance.

// `!(x > 0.0)` is how this module says "not positive, or NaN".
#![allow(clippy::neg_cmp_op_on_partial_ord)]

pub mod persist;
pub mod symmetry;

pub use symmetry::Symmetry;

use super::{
    blend_divergence, coordinates, half_vector, outgoing_at, served_between, OutgoingBuilder,
    PackedCdf2D, CAP_TRIES, FILL_STEP,
};
use acdf_adaptive_cdf::AdaptiveCdf2D;
use acdf_core::fast::{fast_atan2, sin_cos_turns};
use acdf_core::geometry::sin_theta;
use acdf_core::warp::square_to_cosine_hemisphere;
use acdf_core::{
    clamp_unit, is_valid_outgoing, Brdf, BxdfSample, BxdfSampler, Error, Result, Rgb, Vec2, Vec3,
    ONE_MINUS_EPSILON,
};
use acdf_tabulated::tabulate::{fill_support, HalfMap};
use acdf_tabulated::{tabulate_for, Resolution};
use rayon::prelude::*;
use std::collections::HashMap;
use std::f32::consts::{FRAC_PI_2, TAU};
use std::sync::Arc;

/// The default number of fine θ_o nodes per θ_o cell of the requested
/// resolution for an anisotropic material (32 cells: 64 nodes).
pub const ANISOTROPIC_FINE_PER_CELL: usize = 2;

/// The default tolerance of the anisotropic sampler over its simplifier's
/// default. Its slices keep their own vertices, so a tolerance costs more
/// storage per slice than on the isotropic sampler's shared grid; the
/// storage cap raises it further on every anisotropic material measured.
pub const ANISOTROPIC_TOLERANCE_SCALE: f64 = 6.0;

/// The budget of chi-square divergence for a dropped slice at the
/// anisotropic default tolerance; at another tolerance it scales with it.
pub const ANISOTROPIC_BUDGET: f64 = 0.003;

/// The default number of fine φ_o nodes per φ_o cell of the requested
/// resolution (16 cells: 32 nodes, 11.25° apart).
pub const FINE_PHI_PER_CELL: usize = 2;

/// The largest step in φ_o, in turns, between the outgoing directions
/// that stand for a kept slice in its support pass.
const SERVED_PHI_STEP: f32 = 1.0 / 64.0;

/// A material turned about the normal by φ: `eval(wo, wi)` is the
/// material's at (R wo, R wi), R the rotation by φ. A table of the turned
/// material at wo with φ_o = 0 is the material's table at φ_o = φ with
/// φ_h measured from φ_o.
struct Turned<'a> {
    brdf: &'a dyn Brdf,
    cos: f32,
    sin: f32,
}

impl<'a> Turned<'a> {
    fn new(brdf: &'a dyn Brdf, turns: f32) -> Self {
        let (sin, cos) = sin_cos_turns(turns);
        Turned { brdf, cos, sin }
    }

    #[inline]
    fn turn(&self, v: Vec3) -> Vec3 {
        Vec3::new(
            self.cos * v.x - self.sin * v.y,
            self.sin * v.x + self.cos * v.y,
            v.z,
        )
    }
}

impl Brdf for Turned<'_> {
    fn name(&self) -> &str {
        self.brdf.name()
    }
    fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
        self.brdf.eval(self.turn(wo), self.turn(wi))
    }
    fn is_isotropic(&self) -> bool {
        self.brdf.is_isotropic()
    }
    fn luminance(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.brdf.luminance(self.turn(wo), self.turn(wi))
    }
    /// The material's own ring at the turned wo and columns, so that a
    /// measured table keeps its hoisted ring evaluation.
    fn luminance_half_ring(
        &self,
        wo: Vec3,
        polar: (f32, f32),
        columns: &[(f32, f32)],
        out: &mut [f32],
    ) {
        let turned: Vec<(f32, f32)> = columns
            .iter()
            .map(|&(c, s)| (c * self.cos - s * self.sin, s * self.cos + c * self.sin))
            .collect();
        self.brdf
            .luminance_half_ring(self.turn(wo), polar, &turned, out);
    }
}

/// Where a slice measures φ_h from (module documentation, **Frame**).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PhiFrame {
    /// φ_h from φ_o: an isotropic material's slices do not depend on φ_o.
    Relative,
    /// φ_h absolute: a lobe fixed on the surface (an anisotropic density of
    /// normals) does not turn with φ_o.
    Absolute,
}

impl PhiFrame {
    /// The frame's code in a sampler file.
    pub fn code(self) -> u8 {
        match self {
            PhiFrame::Relative => 0,
            PhiFrame::Absolute => 1,
        }
    }

    /// The frame of a file code.
    pub fn from_code(code: u8) -> Option<Self> {
        match code {
            0 => Some(PhiFrame::Relative),
            1 => Some(PhiFrame::Absolute),
            _ => None,
        }
    }
}

/// The table of the outgoing direction at u_o = `u`, φ_o = `turns` in the
/// frame `frame`.
fn table_at(
    brdf: &dyn Brdf,
    frame: PhiFrame,
    u: f32,
    turns: f32,
    (n_theta_h, n_phi_h): (usize, usize),
) -> Vec<f32> {
    let turned = Turned::new(brdf, turns);
    match frame {
        PhiFrame::Relative => tabulate_for(&turned, outgoing_at(u), n_theta_h, n_phi_h),
        PhiFrame::Absolute => tabulate_for(brdf, turned.turn(outgoing_at(u)), n_theta_h, n_phi_h),
    }
}

/// The outgoing sampler of an anisotropic material (module documentation).
#[derive(Clone)]
pub struct AnisotropicOutgoingSampler {
    brdf: Arc<dyn Brdf>,
    builder: OutgoingBuilder,
    fine_phi: usize,
    frame: PhiFrame,
    symmetry: Symmetry,
    name: String,
    n_theta_h: usize,
    n_phi_h: usize,
    map: HalfMap,
    /// u_o of each kept θ_o slice row: 0 first, 1 last, increasing.
    pub(crate) theta_breakpoints: Vec<f32>,
    /// For each θ_o row, φ_o / 2π of its φ_o breakpoints: 0 first,
    /// increasing, below 1 on the periodic circle, ending at the arc's end
    /// on an arc of a [`Symmetry`] (unless the row keeps one).
    pub(crate) phi_breakpoints: Vec<Vec<f32>>,
    /// Where each θ_o row's slices start in `slices` (one more entry than
    /// rows, the last the slice count).
    row_start: Vec<usize>,
    /// Row by row: slice (k, m) at `row_start[k] + m`.
    pub(crate) slices: Vec<PackedCdf2D>,
    cosine_fraction: f32,
}

/// The bytes of `rows` θ_o rows holding `slices`: per row its θ_o
/// breakpoint and its count of φ_o breakpoints, per slice its φ_o
/// breakpoint (4 bytes each), and the slices' arrays.
fn stored_bytes(rows: usize, slices: &[PackedCdf2D]) -> usize {
    4 * (2 * rows + slices.len()) + slices.iter().map(PackedCdf2D::storage_bytes).sum::<usize>()
}

/// One build of the sampler's parts at a tolerance and budget: the kept
/// θ_o nodes, each row's φ_o breakpoints (turns), the slices row by row,
/// and the bytes they store.
struct Built {
    kept_theta: Vec<usize>,
    phi: Vec<Vec<f32>>,
    slices: Vec<PackedCdf2D>,
    bytes: usize,
}

/// A slice's table simplified at the builder's tolerance (first θ_h row
/// pinned) and packed.
fn simplified(
    values: &[f32],
    (n_theta_h, n_phi_h): (usize, usize),
    builder: &OutgoingBuilder,
) -> Result<PackedCdf2D> {
    let d = AdaptiveCdf2D::from_values_pinned(
        values,
        n_phi_h,
        n_theta_h,
        &*builder.simplifier,
        builder.tolerance,
        1,
    )?;
    PackedCdf2D::from_adaptive(&d, values, n_phi_h, n_theta_h)
}

/// The builder with its tolerance and budget times [`FILL_STEP`]^k.
fn scaled(builder: &OutgoingBuilder, k: i32) -> OutgoingBuilder {
    let mut b = builder.clone();
    let f = FILL_STEP.powi(k);
    b.tolerance *= f;
    b.budget *= f;
    b
}

/// The most steps of [`FILL_STEP`] a capped build lowers the tolerance and
/// budget by (FILL_STEP^-12 = 1.5^-6, about 0.09 times the default, so
/// about half the simplifier's own default tolerance).
pub const LOWER_STEPS: i32 = 12;

/// The build under the storage cap `cap`: the smallest tolerance (and the
/// budget with it) on the ladder builder · [`FILL_STEP`]^k, k from
/// -[`LOWER_STEPS`] to 2 ([`CAP_TRIES`] - 1) (up to [`CAP_STEP`](crate::CAP_STEP)^7), whose
/// sampler fits, spending the room on variance. The rung is found on
/// `estimate` (no support passes, a little below what a build stores),
/// then built, and raised a rung at a time while the build is over the
/// cap (the highest rung is taken whatever it stores).
fn fit_under_cap(
    builder: OutgoingBuilder,
    cap: usize,
    estimate: impl Fn(&OutgoingBuilder) -> Result<usize>,
    mut build: impl FnMut(&OutgoingBuilder) -> Result<Built>,
) -> Result<(OutgoingBuilder, Built)> {
    let highest = 2 * (CAP_TRIES as i32 - 1);
    let fits = |k: i32| -> Result<bool> { Ok(estimate(&scaled(&builder, k))? <= cap) };
    let mut k = 0;
    if fits(0)? {
        while k > -LOWER_STEPS && fits(k - 1)? {
            k -= 1;
        }
    } else {
        while k < highest && !fits(k)? {
            k += 1;
        }
    }
    let mut built = build(&scaled(&builder, k))?;
    while built.bytes > cap && k < highest {
        k += 1;
        built = build(&scaled(&builder, k))?;
    }
    Ok((scaled(&builder, k), built))
}

/// Greedy breakpoints along an axis of `n` nodes (indices into them), from
/// node 0: from a kept node a the next is the farthest b for which
/// `fits(a, b)`; the last kept node is `n - 1` (for a periodic axis the
/// caller passes one more node than it has, the copy of node 0).
fn greedy(n: usize, fits: impl Fn(usize, usize) -> bool) -> Vec<usize> {
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

/// The θ_o breakpoints for normalised tables `p` (θ_o node j, φ_o node l
/// at j · n_phi + l) at nodes `u`: every dropped node of every φ_o column
/// of `cols` within `budget` of the blend of its kept neighbours.
fn choose_theta_breakpoints(
    p: &[Vec<f32>],
    u: &[f32],
    (n_phi, cols): (usize, &[usize]),
    budget: f64,
) -> Vec<usize> {
    greedy(u.len(), |a, b| {
        ((a + 1)..b)
            .flat_map(|j| cols.iter().map(move |&l| (j, l)))
            .collect::<Vec<_>>()
            .into_par_iter()
            .all(|(j, l)| {
                let t = (u[j] - u[a]) / (u[b] - u[a]);
                blend_divergence(&p[j * n_phi + l], &p[a * n_phi + l], &p[b * n_phi + l], t)
                    <= budget
            })
    })
}

/// The φ_o breakpoints (indices into `row`, 0 first) of one θ_o row,
/// whose normalised tables at its φ_o nodes in order are `row`: every
/// dropped node within `budget` of the blend of its kept neighbours. Round
/// the circle when `periodic` (node `row.len()` is node 0); on an arc the
/// last node is kept too, unless every node is within `budget` of the
/// first alone (the row on the normal), which is then kept alone.
fn choose_phi_breakpoints(row: &[&[f32]], periodic: bool, budget: f64) -> Vec<usize> {
    let n_phi = row.len();
    if periodic {
        let mut kept = greedy(n_phi + 1, |a, b| {
            ((a + 1)..b).into_par_iter().all(|l| {
                let s = (l - a) as f32 / (b - a) as f32;
                blend_divergence(row[l], row[a], row[b % n_phi], s) <= budget
            })
        });
        kept.pop();
        return kept;
    }
    if row
        .par_iter()
        .all(|t| blend_divergence(t, row[0], row[0], 0.0) <= budget)
    {
        return vec![0];
    }
    greedy(n_phi, |a, b| {
        ((a + 1)..b).into_par_iter().all(|l| {
            let s = (l - a) as f32 / (b - a) as f32;
            blend_divergence(row[l], row[a], row[b], s) <= budget
        })
    })
}

/// The kept nodes of the normalised tables `p` (θ_o node j at `u[j]`, φ_o
/// node l at j · n_phi + l) at `budget`, over the φ_o nodes `cols` of the
/// arc of `symmetry`: the θ_o breakpoints (fine node indices), and for
/// each the φ_o breakpoints of its row (fine φ_o node indices).
fn kept_nodes(
    p: &[Vec<f32>],
    u: &[f32],
    (n_phi, symmetry): (usize, Symmetry),
    budget: f64,
) -> (Vec<usize>, Vec<Vec<usize>>) {
    let cols = symmetry.arc_nodes(n_phi);
    let kept_theta = choose_theta_breakpoints(p, u, (n_phi, &cols), budget);
    let kept_phi = kept_theta
        .iter()
        .map(|&j| {
            let row: Vec<&[f32]> = cols.iter().map(|&l| &p[j * n_phi + l][..]).collect();
            choose_phi_breakpoints(&row, symmetry.is_periodic(), budget)
                .into_iter()
                .map(|m| cols[m])
                .collect()
        })
        .collect();
    (kept_theta, kept_phi)
}

/// The φ_o (in turns) that stand for the slice at φ_o node m of `phi` (in
/// turns) in its support pass: from the previous φ_o breakpoint to the
/// next (the whole circle, or the whole arc of `span` turns, for one
/// breakpoint; on an arc, from its start for the first and to its end for
/// the last), in steps of at most [`SERVED_PHI_STEP`], both ends included.
fn served_phi(phi: &[f32], m: usize, symmetry: Symmetry) -> Vec<f32> {
    let k = phi.len();
    let span = symmetry.span();
    let (lo, hi) = if k == 1 {
        (0.0, span)
    } else if symmetry.is_periodic() {
        let prev = if m == 0 { phi[k - 1] - 1.0 } else { phi[m - 1] };
        let next = if m + 1 == k { 1.0 } else { phi[m + 1] };
        (prev, next)
    } else {
        (phi[m.saturating_sub(1)], phi[(m + 1).min(k - 1)])
    };
    let steps = (((hi - lo) / SERVED_PHI_STEP).ceil() as usize).max(1);
    (0..=steps)
        .map(|i| lo + (hi - lo) * i as f32 / steps as f32)
        .collect()
}

/// What a kept slice's table depends on, as fine node indices: its θ_o
/// node and those of its θ_o neighbours, its φ_o node and those of its φ_o
/// neighbours (`fine_phi` for the end of the circle after the last
/// breakpoint; `usize::MAX` for both when one φ_o breakpoint serves the
/// whole circle).
type SliceKey = [usize; 6];

/// The [`SliceKey`] of the kept slice (i, m), `kept_phi` the φ_o
/// breakpoints of row i.
fn slice_key(
    kept_theta: &[usize],
    kept_phi: &[usize],
    fine_phi: usize,
    i: usize,
    m: usize,
) -> SliceKey {
    let (prev, next) = match kept_phi.len() {
        1 => (usize::MAX, usize::MAX),
        k => (
            kept_phi[if m == 0 { k - 1 } else { m - 1 }],
            if m + 1 == k {
                fine_phi
            } else {
                kept_phi[m + 1]
            },
        ),
    };
    [
        kept_theta[i],
        kept_theta[i.saturating_sub(1)],
        kept_theta[(i + 1).min(kept_theta.len() - 1)],
        kept_phi[m],
        prev,
        next,
    ]
}

/// The table of the kept slice at u_o = `u`, φ_o = `phi` turns in
/// `frame`, with the support pass for θ_o from `u_lo` to `u_hi` and the φ_o
/// of `served`: a cell that is 0 at the slice's own wo gets the largest of
/// what [`fill_support`] gives it for the served outgoing directions (in
/// the relative frame one pass per served φ_o, on the material turned by
/// it, and the largest taken).
fn kept_table(
    brdf: &dyn Brdf,
    frame: PhiFrame,
    (u, u_lo, u_hi): (f32, f32, f32),
    phi: f32,
    served: &[f32],
    cells: (usize, usize),
) -> Vec<f32> {
    let (n_theta_h, n_phi_h) = cells;
    let mut values = table_at(brdf, frame, u, phi, cells);
    let thetas = served_between(u_lo, u_hi);
    match frame {
        PhiFrame::Absolute => {
            let outgoing: Vec<Vec3> = served
                .iter()
                .flat_map(|&turns| {
                    let turned = Turned::new(brdf, turns);
                    thetas.iter().map(move |&wo| turned.turn(wo))
                })
                .collect();
            fill_support(brdf, &outgoing, n_theta_h, n_phi_h, &mut values);
        }
        PhiFrame::Relative => {
            let filled: Vec<Vec<f32>> = served
                .par_iter()
                .map(|&turns| {
                    let mut v = values.clone();
                    fill_support(
                        &Turned::new(brdf, turns),
                        &thetas,
                        n_theta_h,
                        n_phi_h,
                        &mut v,
                    );
                    v
                })
                .collect();
            for (i, cell) in values.iter_mut().enumerate() {
                if *cell == 0.0 {
                    *cell = filled.iter().map(|v| v[i]).fold(0.0, f32::max);
                }
            }
        }
    }
    values
}

impl AnisotropicOutgoingSampler {
    /// Build the sampler of `brdf` with `resolution.theta_h` ×
    /// `resolution.phi_h` half-vector cells per slice, `builder.fine` θ_o
    /// nodes and `fine_phi` φ_o nodes (module documentation). Any material
    /// is accepted; an isotropic one keeps a single φ_o breakpoint.
    /// Errors: a zero material, an invalid resolution or node count, a
    /// table beyond the memory limit.
    pub fn new(
        brdf: Arc<dyn Brdf>,
        resolution: Resolution,
        builder: OutgoingBuilder,
        fine_phi: usize,
    ) -> Result<Self> {
        Self::with_symmetry(brdf, resolution, builder, fine_phi, None)
    }

    /// [`new`](Self::new) with the φ_o arc given: `None` finds the largest
    /// [`Symmetry`] the material's fine tables have within the budget (as
    /// `new` does), `Some(s)` takes `s` (a symmetry the material lacks
    /// still gives an exact density, of more variance). Errors: those of
    /// `new`, and a symmetry whose arc does not end on a fine φ_o node (1/2
    /// turn needs an even `fine_phi` and `resolution.phi_h`, 1/4 turn a
    /// `fine_phi` divisible by 4).
    pub fn with_symmetry(
        brdf: Arc<dyn Brdf>,
        resolution: Resolution,
        builder: OutgoingBuilder,
        fine_phi: usize,
        symmetry: Option<Symmetry>,
    ) -> Result<Self> {
        resolution.validate()?;
        builder.validate()?;
        validate_fine_phi(fine_phi)?;
        if let Some(s) = symmetry {
            if !s.fits_grid(fine_phi, resolution.phi_h) {
                return Err(Error::InvalidParameter {
                    name: "symmetry",
                    reason: format!(
                        "{s:?} needs fine phi_o nodes and phi_h cells that split its arc \
                         evenly ({fine_phi} nodes, {} cells)",
                        resolution.phi_h
                    ),
                });
            }
        }
        if brdf.is_zero_everywhere() {
            return Err(Error::ZeroMaterial {
                material: brdf.name().to_string(),
            });
        }
        let (n_theta_h, n_phi_h) = (resolution.theta_h, resolution.phi_h);
        let fine = builder.fine;
        acdf_io::limits::check_memory(
            "the fine tabulation of an anisotropic outgoing sampler",
            (fine as u64)
                .saturating_mul(fine_phi as u64)
                .saturating_mul(resolution.cells_per_slice() as u64)
                .saturating_mul(4),
        )?;
        let u: Vec<f32> = (0..fine).map(|j| j as f32 / (fine - 1) as f32).collect();
        let phi: Vec<f32> = (0..fine_phi).map(|l| l as f32 / fine_phi as f32).collect();
        let tabulate = |frame: PhiFrame| -> Vec<Vec<f32>> {
            (0..fine * fine_phi)
                .into_par_iter()
                .map(|i| {
                    let (j, l) = (i / fine_phi, i % fine_phi);
                    let mut t = table_at(&*brdf, frame, u[j], phi[l], (n_theta_h, n_phi_h));
                    let sum: f64 = t.iter().map(|&v| v as f64).sum();
                    let scale = if sum > 0.0 { (1.0 / sum) as f32 } else { 0.0 };
                    t.iter_mut().for_each(|v| *v *= scale);
                    t
                })
                .collect()
        };
        let kept_count = |p: &[Vec<f32>]| {
            kept_nodes(p, &u, (fine_phi, Symmetry::None), builder.budget)
                .1
                .iter()
                .map(Vec::len)
                .sum::<usize>()
        };
        // An isotropic material keeps one φ_o breakpoint in the relative
        // frame, the fewest there are; an anisotropic one takes the frame
        // that keeps fewer slices at the budget.
        let relative = tabulate(PhiFrame::Relative);
        let (frame, normalised) = if brdf.is_isotropic() {
            (PhiFrame::Relative, relative)
        } else {
            let absolute = tabulate(PhiFrame::Absolute);
            if kept_count(&absolute) < kept_count(&relative) {
                (PhiFrame::Absolute, absolute)
            } else {
                (PhiFrame::Relative, relative)
            }
        };
        // An isotropic material needs no arc: its one φ_o breakpoint per
        // row serves the circle.
        let symmetry = match symmetry {
            Some(s) => s,
            None if brdf.is_isotropic() => Symmetry::None,
            None => symmetry::detect(&normalised, fine_phi, n_phi_h, frame, builder.budget),
        };
        let nodes = (fine_phi, symmetry);
        // The kept slices' tables (with their support passes) depend only on
        // the fine nodes of the slice and of its neighbours, so another
        // tolerance under the storage cap rebuilds only the slices whose
        // neighbourhood changed.
        let mut tables: HashMap<SliceKey, Vec<f32>> = HashMap::new();
        let mut build = |builder: &OutgoingBuilder| -> Result<Built> {
            let (kept_theta, kept_phi) = kept_nodes(&normalised, &u, nodes, builder.budget);
            let phi_kept: Vec<Vec<f32>> = kept_phi
                .iter()
                .map(|row| row.iter().map(|&l| phi[l]).collect())
                .collect();
            let cells: Vec<(usize, usize)> = kept_phi
                .iter()
                .enumerate()
                .flat_map(|(i, row)| (0..row.len()).map(move |m| (i, m)))
                .collect();
            let keys: Vec<SliceKey> = cells
                .iter()
                .map(|&(i, m)| slice_key(&kept_theta, &kept_phi[i], fine_phi, i, m))
                .collect();
            let mut missing: Vec<(usize, usize, SliceKey)> = Vec::new();
            for (&(i, m), &key) in cells.iter().zip(&keys) {
                if !tables.contains_key(&key) && !missing.iter().any(|&(_, _, k)| k == key) {
                    missing.push((i, m, key));
                }
            }
            let built: Vec<(SliceKey, Vec<f32>)> = missing
                .par_iter()
                .map(|&(i, m, key)| {
                    let lo = u[kept_theta[i.saturating_sub(1)]];
                    let hi = u[kept_theta[(i + 1).min(kept_theta.len() - 1)]];
                    let values = kept_table(
                        &*brdf,
                        frame,
                        (u[kept_theta[i]], lo, hi),
                        phi_kept[i][m],
                        &served_phi(&phi_kept[i], m, symmetry),
                        (n_theta_h, n_phi_h),
                    );
                    (key, values)
                })
                .collect();
            tables.extend(built);
            let slices = keys
                .par_iter()
                .map(|key| simplified(&tables[key], (n_theta_h, n_phi_h), builder))
                .collect::<Result<Vec<_>>>()?;
            let bytes = stored_bytes(kept_theta.len(), &slices);
            Ok(Built {
                kept_theta,
                phi: phi_kept,
                slices,
                bytes,
            })
        };
        // The bytes a build would store, estimated from the fine tables of
        // the nodes it keeps, without the support passes (which only give
        // mass to cells a slice's own table has none in, so that the
        // estimate comes out a little below what the build stores: 10 to
        // 12% on the GGX lobe of the `anisotropic_rgl` example): a tolerance
        // whose estimate is over the cap is passed over without a build,
        // whose support passes take most of the time.
        let estimate = |builder: &OutgoingBuilder| -> Result<usize> {
            let (kept_theta, kept_phi) = kept_nodes(&normalised, &u, nodes, builder.budget);
            let slices = kept_theta
                .iter()
                .zip(&kept_phi)
                .flat_map(|(&j, row)| row.iter().map(move |&l| j * fine_phi + l))
                .collect::<Vec<usize>>()
                .par_iter()
                .map(|&i| simplified(&normalised[i], (n_theta_h, n_phi_h), builder))
                .collect::<Result<Vec<_>>>()?;
            Ok(stored_bytes(kept_theta.len(), &slices))
        };
        let (builder, built) = match builder.max_bytes {
            None => {
                let built = build(&builder)?;
                (builder, built)
            }
            Some(cap) => fit_under_cap(builder, cap, estimate, build)?,
        };
        let Built {
            kept_theta,
            phi: kept_phi,
            slices,
            ..
        } = built;
        let theta_breakpoints = kept_theta.iter().map(|&k| u[k]).collect();
        Ok(Self::from_parts(
            brdf,
            builder,
            (fine_phi, frame, symmetry),
            (n_theta_h, n_phi_h),
            theta_breakpoints,
            kept_phi,
            slices,
        ))
    }

    /// A sampler of stored parts (checked by the caller).
    pub(crate) fn from_parts(
        brdf: Arc<dyn Brdf>,
        builder: OutgoingBuilder,
        (fine_phi, frame, symmetry): (usize, PhiFrame, Symmetry),
        (n_theta_h, n_phi_h): (usize, usize),
        theta_breakpoints: Vec<f32>,
        phi_breakpoints: Vec<Vec<f32>>,
        slices: Vec<PackedCdf2D>,
    ) -> Self {
        let mut row_start = vec![0];
        for row in &phi_breakpoints {
            row_start.push(row_start[row_start.len() - 1] + row.len());
        }
        debug_assert_eq!(row_start[row_start.len() - 1], slices.len());
        AnisotropicOutgoingSampler {
            name: builder.name(),
            brdf,
            builder,
            fine_phi,
            frame,
            symmetry,
            n_theta_h,
            n_phi_h,
            map: HalfMap::new(n_theta_h),
            theta_breakpoints,
            phi_breakpoints,
            row_start,
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

    /// The parameters (`fine` counts the θ_o nodes).
    pub fn builder(&self) -> &OutgoingBuilder {
        &self.builder
    }

    /// The frame the slices measure φ_h in.
    pub fn frame(&self) -> PhiFrame {
        self.frame
    }

    /// The arc of φ_o the slices cover.
    pub fn symmetry(&self) -> Symmetry {
        self.symmetry
    }

    /// The number of fine φ_o nodes the breakpoints were chosen from.
    pub fn fine_phi(&self) -> usize {
        self.fine_phi
    }

    /// The kept θ_o breakpoints, as θ_o in radians.
    pub fn theta_breakpoint_angles(&self) -> Vec<f32> {
        self.theta_breakpoints
            .iter()
            .map(|&u| FRAC_PI_2 * u * u)
            .collect()
    }

    /// The kept φ_o breakpoints of each θ_o row, as φ_o in radians (0
    /// first).
    pub fn phi_breakpoint_angles(&self) -> Vec<Vec<f32>> {
        self.phi_breakpoints
            .iter()
            .map(|row| row.iter().map(|&x| TAU * x).collect())
            .collect()
    }

    /// The kept slices, row by row: slice (θ_o row k, its φ_o breakpoint
    /// m) at [`row_start`](Self::row_start)`(k) + m`.
    pub fn slices(&self) -> &[PackedCdf2D] {
        &self.slices
    }

    /// Where θ_o row k's slices start in [`slices`](Self::slices).
    pub fn row_start(&self, k: usize) -> usize {
        self.row_start[k]
    }

    /// Half-vector cells per slice (θ_h, φ_h).
    pub fn half_vector_cells(&self) -> (usize, usize) {
        (self.n_theta_h, self.n_phi_h)
    }

    /// (mean marginal vertices, mean vertices of the stored conditionals)
    /// over the kept slices.
    pub fn mean_vertices(&self) -> (f64, f64) {
        let n = self.slices.len().max(1) as f64;
        let marginal = self
            .slices
            .iter()
            .map(|s| s.marginal_vertex_count())
            .sum::<usize>();
        let (vertices, stored) = self
            .slices
            .iter()
            .map(|s| s.conditional_vertices())
            .fold((0, 0), |(a, b), (c, d)| (a + c, b + d));
        (marginal as f64 / n, vertices as f64 / stored.max(1) as f64)
    }

    /// The four slices around a valid wo and their weights (summing to 1):
    /// (k, m_k), (k, m_k + 1), (k + 1, m_{k+1}), (k + 1, m_{k+1} + 1).
    #[inline]
    fn blend_of(&self, wo: Vec3) -> ([usize; 4], [f32; 4]) {
        let s_theta = sin_theta(wo);
        let theta = fast_atan2(s_theta, wo.z).max(0.0);
        let u = (theta / FRAC_PI_2).sqrt().min(1.0);
        let b = &self.theta_breakpoints;
        let last = b.len() - 1;
        let k = b[1..last].iter().filter(|&&x| x <= u).count();
        let t = ((u - b[k]) / (b[k + 1] - b[k])).clamp(0.0, 1.0);
        let turns = if s_theta > 0.0 {
            let phi = fast_atan2(wo.y, wo.x);
            let turns = phi / TAU;
            if turns < 0.0 {
                (turns + 1.0).min(ONE_MINUS_EPSILON)
            } else {
                turns
            }
        } else {
            0.0
        };
        let (lo, s_lo) = self.phi_blend(k, turns);
        let (hi, s_hi) = self.phi_blend(k + 1, turns);
        (
            [lo[0], lo[1], hi[0], hi[1]],
            [
                (1.0 - t) * (1.0 - s_lo),
                (1.0 - t) * s_lo,
                t * (1.0 - s_hi),
                t * s_hi,
            ],
        )
    }

    /// In θ_o row k, the slices of the φ_o breakpoints m and m + 1 around
    /// φ_o = 2π `turns` and the weight of the second: on the periodic
    /// circle m + 1 modulo the row's count, on an arc the last interval
    /// ends at the arc's last breakpoint (a row of one breakpoint has it
    /// alone).
    #[inline]
    fn phi_blend(&self, k: usize, turns: f32) -> ([usize; 2], f32) {
        let p = &self.phi_breakpoints[k];
        let n = p.len();
        let start = self.row_start[k];
        let (m, next, hi) = if self.symmetry.is_periodic() {
            let m = p[1..].iter().filter(|&&x| x <= turns).count();
            if m + 1 == n {
                (m, 0, 1.0)
            } else {
                (m, m + 1, p[m + 1])
            }
        } else if n == 1 {
            return ([start, start], 0.0);
        } else {
            let m = p[1..n - 1].iter().filter(|&&x| x <= turns).count();
            (m, m + 1, p[m + 1])
        };
        let s = ((turns - p[m]) / (hi - p[m])).clamp(0.0, 1.0);
        ([start + m, start + next], s)
    }

    /// (cos φ_o, sin φ_o) of a valid wo in the relative frame (φ_o = 0 on
    /// the normal), (1, 0) in the absolute one: the turn from slice to world
    /// coordinates.
    #[inline]
    fn rotation(&self, wo: Vec3) -> Vec2 {
        let s = sin_theta(wo);
        if self.frame == PhiFrame::Relative && s > 0.0 {
            Vec2::new(wo.x, wo.y) / s
        } else {
            Vec2::X
        }
    }

    /// What the draws and densities of the valid wo share.
    fn blend(&self, wo: Vec3) -> Blend {
        let (slices, weights) = self.blend_of(wo);
        Blend {
            slices,
            weights,
            rotation: self.rotation(wo),
        }
    }

    /// The blended table density at wi for a valid wo whose [`Blend`] is
    /// `b`, per solid angle.
    fn table_pdf(&self, b: &Blend, wo: Vec3, wi: Vec3) -> f32 {
        let c = coordinates::<true>(self.map, b.rotation, wo, wi);
        if !c.defined {
            return 0.0;
        }
        let (nx, ny) = (self.n_phi_h as f32, self.n_theta_h as f32);
        let mut p = 0.0;
        for (&i, &w) in b.slices.iter().zip(&b.weights) {
            if w > 0.0 {
                p += w * self.slices[i].pdf(c.x, c.v, nx, ny);
            }
        }
        let p = p / (self.map.jacobian(c.v, c.sin_h) * 4.0 * c.wo_h);
        if p.is_finite() && p > 0.0 {
            p
        } else {
            0.0
        }
    }

    /// A table draw for a valid wo whose [`Blend`] is `b`: one of the four
    /// slices picked by the blend weights with u.x (rescaled), then (x, v)
    /// from it.
    fn sample_table(&self, b: &Blend, wo: Vec3, u: Vec2) -> Vec3 {
        let (slices, weights) = (b.slices, b.weights);
        let mut chosen = 3;
        let mut below = 0.0;
        for (i, &w) in weights.iter().enumerate() {
            if w > 0.0 && (u.x < below + w || i == 3) {
                chosen = i;
                break;
            }
            below += w;
        }
        // A last slice of weight 0 is never drawn from: fall back to the
        // last positive one (the weights sum to 1, so one is positive).
        while !(weights[chosen] > 0.0) && chosen > 0 {
            chosen -= 1;
        }
        let w = weights[chosen];
        let start: f32 = weights[..chosen].iter().sum();
        let ux = clamp_unit((u.x - start) / w);
        let n = (self.n_phi_h as f32, self.n_theta_h as f32);
        let d = self.slices[slices[chosen]].sample(ux, u.y, n, (0.0, 0.0));
        let (x, v) = d.p;
        let (sin_h, cos_h) = self.map.angles(v);
        let (sin_p, cos_p) = sin_cos_turns(x);
        let (_, h) = half_vector(b.rotation, ((sin_h, cos_h), (sin_p, cos_p)));
        (2.0 * wo.dot(h) * h - wo).normalize_or_zero()
    }
}

/// `v` with its x and y times the signs (s_x, s_y) of a [`Symmetry`]:
/// into its arc and, the same again, back.
#[inline]
fn flip(v: Vec3, (sx, sy): (f32, f32)) -> Vec3 {
    Vec3::new(sx * v.x, sy * v.y, v.z)
}

/// Check a fine φ_o node count: 1 to 4096.
fn validate_fine_phi(fine_phi: usize) -> Result<()> {
    if !(1..=4096).contains(&fine_phi) {
        return Err(Error::InvalidParameter {
            name: "fine phi_o nodes",
            reason: format!("{fine_phi} is not in 1..=4096"),
        });
    }
    Ok(())
}

impl BxdfSampler for AnisotropicOutgoingSampler {
    fn name(&self) -> &str {
        &self.name
    }

    /// With probability a a cosine draw, otherwise a table draw from the
    /// slice picked by the bilinear blend weights; the density is `pdf` of
    /// the returned wi.
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        if !is_valid_outgoing(wo) {
            return None;
        }
        let signs = self.symmetry.signs(wo);
        let wo = flip(wo, signs);
        self.sample_in(&self.blend(wo), wo, u).map(|d| BxdfSample {
            wi: flip(d.wi, signs),
            pdf: d.pdf,
        })
    }

    /// (1 - a) times the bilinearly blended table density plus
    /// a cos θ_i / π; 0 for an invalid wo, a non-finite wi or one at or
    /// below the horizon.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !is_valid_outgoing(wo) {
            return 0.0;
        }
        let signs = self.symmetry.signs(wo);
        let wo = flip(wo, signs);
        self.pdf_in(&self.blend(wo), wo, flip(wi, signs))
    }

    /// `sample` for every u, with the blend and rotation of wo found once.
    fn sample_batch(&self, wo: Vec3, u: &[Vec2], out: &mut [Option<BxdfSample>]) {
        if !is_valid_outgoing(wo) {
            out.iter_mut().zip(u).for_each(|(o, _)| *o = None);
            return;
        }
        let signs = self.symmetry.signs(wo);
        let wo = flip(wo, signs);
        let b = self.blend(wo);
        for (o, &u) in out.iter_mut().zip(u) {
            *o = self.sample_in(&b, wo, u).map(|d| BxdfSample {
                wi: flip(d.wi, signs),
                pdf: d.pdf,
            });
        }
    }

    /// `pdf` for every wi, with the blend and rotation of wo found once.
    fn pdf_batch(&self, wo: Vec3, wi: &[Vec3], out: &mut [f32]) {
        if !is_valid_outgoing(wo) {
            out.iter_mut().zip(wi).for_each(|(o, _)| *o = 0.0);
            return;
        }
        let signs = self.symmetry.signs(wo);
        let wo = flip(wo, signs);
        let b = self.blend(wo);
        for (o, &wi) in out.iter_mut().zip(wi) {
            *o = self.pdf_in(&b, wo, flip(wi, signs));
        }
    }

    /// The breakpoints (4 bytes each), a count per θ_o row, and every
    /// slice's stored arrays.
    fn storage_bytes(&self) -> usize {
        stored_bytes(self.theta_breakpoints.len(), &self.slices)
    }
}

impl AnisotropicOutgoingSampler {
    /// [`sample`](BxdfSampler::sample) for a valid wo whose [`Blend`] is
    /// `b`.
    fn sample_in(&self, b: &Blend, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        let u = Vec2::new(clamp_unit(u.x), clamp_unit(u.y));
        let a = self.cosine_fraction;
        let wi = if u.x < a {
            square_to_cosine_hemisphere(Vec2::new(clamp_unit(u.x / a), u.y))
        } else {
            let ux = if a > 0.0 {
                clamp_unit((u.x - a) / (1.0 - a))
            } else {
                u.x
            };
            self.sample_table(b, wo, Vec2::new(ux, u.y))
        };
        if !(wi.z > 0.0) {
            return None;
        }
        let pdf = self.pdf_in(b, wo, wi);
        (pdf > 0.0).then_some(BxdfSample { wi, pdf })
    }

    /// [`pdf`](BxdfSampler::pdf) for a valid wo whose [`Blend`] is `b`.
    fn pdf_in(&self, b: &Blend, wo: Vec3, wi: Vec3) -> f32 {
        if !wi.is_finite() || !(wi.z > 0.0) {
            return 0.0;
        }
        let a = self.cosine_fraction;
        let table = if a < 1.0 {
            self.table_pdf(b, wo, wi)
        } else {
            0.0
        };
        acdf_tabulated::mix_with_cosine(a, table, wi)
    }
}

/// What the draws and densities of one outgoing direction share
/// ([`AnisotropicOutgoingSampler::blend`]): the four slices around it,
/// their bilinear weights, and the rotation from the slices' axes to the
/// shading frame.
#[derive(Debug, Clone, Copy)]
struct Blend {
    slices: [usize; 4],
    weights: [f32; 4],
    rotation: Vec2,
}

#[cfg(test)]
mod tests;
