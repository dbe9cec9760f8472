//! The battery must be able to fail. Each test here feeds it a deliberately
//! broken sampler or distribution, derived from a correct one, and asserts
//! that the battery rejects it, and by which check. Every mutant keeps
//! `sample` consistent with its own `pdf`, so only the distributional checks
//! (chi-square, ∫ pdf) can see the bug. The mutants run at a quarter of
//! the default number of draws: rejected there, they are rejected with
//! more draws too, since the power of the test only grows with N.

use acdf_conformance::reference::{PiecewiseConstant1D, PiecewiseConstant2D};
use acdf_conformance::samplers::{TabulatedSampler, TiltedLobeSampler};
use acdf_conformance::{
    assert_rejected, brdfs, check_distribution_1d, check_distribution_2d, check_sampler,
    check_sampler_family, Check, DistributionConfig, SamplerConfig,
};
use acdf_core::geometry::spherical_direction;
use acdf_core::{
    clamp_unit, BxdfSample, BxdfSampler, Distribution1D, Distribution2D, Result, Sample1D,
    Sample2D, Vec2, Vec3, ONE_MINUS_EPSILON,
};
use acdf_cosine::CosineSampler;
use std::f32::consts::{FRAC_PI_2, PI, TAU};

fn sampler_config() -> SamplerConfig {
    SamplerConfig {
        samples: 250_000,
        extreme_samples: 2_000,
        ..SamplerConfig::default()
    }
}

fn distribution_config() -> DistributionConfig {
    DistributionConfig {
        samples: 250_000,
        ..DistributionConfig::default()
    }
}

// ---------------------------------------------------------------- pdf × 1.05

/// The cosine sampler with its pdf (returned and evaluated) scaled by 1.05.
struct ScaledPdf;

impl BxdfSampler for ScaledPdf {
    fn name(&self) -> &str {
        "mutant-scaled-pdf"
    }
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        CosineSampler.sample(wo, u).map(|s| BxdfSample {
            wi: s.wi,
            pdf: 1.05 * s.pdf,
        })
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        1.05 * CosineSampler.pdf(wo, wi)
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

/// A global scale of the pdf is what the integral check is for: it sees
/// ∫ pdf = 1.05 at any N. The chi-square test sees it too, but weakly
/// (over-predicted counts also shrink the statistic's variance term), so
/// this mutant runs at the default 10^6 draws, where it fails clearly.
#[test]
fn rejects_pdf_scaled_by_1_05() {
    let report = check_sampler(
        "mutant_scaled_pdf",
        &ScaledPdf,
        None,
        &SamplerConfig {
            extreme_samples: 2_000,
            ..SamplerConfig::default()
        },
    );
    assert_rejected(&report, Check::Integral);
    assert!(report.failed(Check::ChiSquare), "{report}");
}

// ------------------------------------------------- sin θ Jacobian left out

/// Draws θ and φ uniformly and reports the density per dθ dφ, 1/π², as if
/// it were per solid angle: the 1/sin θ of dω = sin θ dθ dφ is missing.
struct MissingJacobian;

impl BxdfSampler for MissingJacobian {
    fn name(&self) -> &str {
        "mutant-missing-jacobian"
    }
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        if !acdf_core::is_valid_outgoing(wo) {
            return None;
        }
        let wi = spherical_direction(FRAC_PI_2 * clamp_unit(u.x), TAU * clamp_unit(u.y));
        (wi.z > 0.0).then(|| BxdfSample {
            wi,
            pdf: self.pdf(wo, wi),
        })
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if acdf_core::is_valid_outgoing(wo) && wi.z > 0.0 && wi.is_finite() {
            1.0 / (PI * PI)
        } else {
            0.0
        }
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

#[test]
fn rejects_missing_sin_theta_jacobian() {
    let report = check_sampler(
        "mutant_missing_jacobian",
        &MissingJacobian,
        None,
        &sampler_config(),
    );
    assert_rejected(&report, Check::ChiSquare);
}

// ------------------------------------------------------ wo and wi swapped

/// The tilted lobe, whose pdf is not symmetric in (wo, wi), with the two
/// arguments of `pdf` swapped; samples are drawn correctly.
struct Swapped(TiltedLobeSampler);

impl BxdfSampler for Swapped {
    fn name(&self) -> &str {
        "mutant-swapped"
    }
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        let s = self.0.sample(wo, u)?;
        let pdf = self.pdf(wo, s.wi);
        (pdf > 0.0).then_some(BxdfSample { wi: s.wi, pdf })
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if !acdf_core::is_valid_outgoing(wo) {
            return 0.0;
        }
        self.0.pdf(wi, wo)
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

#[test]
fn rejects_wo_and_wi_swapped() {
    let report = check_sampler(
        "mutant_swapped",
        &Swapped(TiltedLobeSampler { exponent: 20.0 }),
        None,
        &sampler_config(),
    );
    assert_rejected(&report, Check::ChiSquare);
}

// ------------------------------------------- samples from a shifted table

/// Samples from the reference table with every sample moved `.1` of a cell
/// to the right (wrapping at 1); the pdf is the unshifted one.
struct Shifted1D(PiecewiseConstant1D, f64);

impl Distribution1D for Shifted1D {
    fn sample(&self, u: f32) -> Sample1D {
        let x = self.0.sample(u).x as f64 + self.1 / self.0.len() as f64;
        let x = (x.fract() as f32).min(ONE_MINUS_EPSILON);
        Sample1D {
            x,
            pdf: self.pdf(x),
        }
    }
    fn pdf(&self, x: f32) -> f32 {
        self.0.pdf(x)
    }
    fn invert(&self, x: f32) -> f32 {
        self.0.invert(x)
    }
    fn integral(&self) -> f64 {
        self.0.integral()
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

#[test]
fn rejects_1d_samples_from_a_shifted_table() {
    let report = check_distribution_1d(
        "mutant_shifted_1d",
        |t: &[f32]| Ok(Shifted1D(PiecewiseConstant1D::new(t)?, 0.2)),
        &distribution_config(),
    );
    assert_rejected(&report, Check::ChiSquare);
}

/// A shift of 2% of a cell, at the default 10^6 draws, is still caught by
/// the chi-square test on the tables without zero cells (where it cannot
/// produce samples of pdf 0 that other checks would see).
#[test]
fn rejects_1d_samples_from_a_slightly_shifted_table() {
    let report = check_distribution_1d(
        "mutant_slightly_shifted_1d",
        |t: &[f32]| Ok(Shifted1D(PiecewiseConstant1D::new(t)?, 0.02)),
        &DistributionConfig::default(),
    );
    report.print();
    let caught = |table: &str| {
        report
            .chi_square
            .iter()
            .any(|l| l.case.contains(table) && !l.passed())
    };
    assert!(caught("random-300") && caught("random-64"), "{report}");
}

/// The 2D reference with every sample moved 0.2 of a column to the right.
struct Shifted2D(PiecewiseConstant2D, usize);

impl Shifted2D {
    fn new(t: &[f32], nx: usize, ny: usize) -> Result<Self> {
        Ok(Shifted2D(PiecewiseConstant2D::new(t, nx, ny)?, nx))
    }
}

impl Distribution2D for Shifted2D {
    fn sample(&self, u: Vec2) -> Sample2D {
        let s = self.0.sample(u);
        let x = ((s.p.x as f64 + 0.2 / self.1 as f64).fract() as f32).min(ONE_MINUS_EPSILON);
        let p = Vec2::new(x, s.p.y);
        Sample2D {
            p,
            pdf: self.pdf(p),
        }
    }
    fn pdf(&self, p: Vec2) -> f32 {
        self.0.pdf(p)
    }
    fn invert(&self, p: Vec2) -> Vec2 {
        self.0.invert(p)
    }
    fn integral(&self) -> f64 {
        self.0.integral()
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

#[test]
fn rejects_2d_samples_from_a_shifted_table() {
    let report = check_distribution_2d("mutant_shifted_2d", Shifted2D::new, &distribution_config());
    assert_rejected(&report, Check::ChiSquare);
}

/// A table on the sphere (through `TabulatedSampler`) sampled shifted.
#[test]
fn rejects_sampler_drawing_from_a_shifted_table() {
    let table: Vec<f32> = (0..12 * 10).map(|k| ((k * 37) % 11) as f32).collect();
    let report = check_sampler_family(
        "mutant_shifted_sphere_table",
        |_| {
            Ok(TabulatedSampler {
                distribution: Shifted2D::new(&table, 12, 10)?,
            })
        },
        &brdfs::ordinary_brdfs()[..1],
        &sampler_config(),
    );
    assert_rejected(&report, Check::ChiSquare);
}

// --------------------------------------------------- off-by-one cell index

/// Finds the cell k for u correctly, then places the sample in cell k + 1
/// (the last cell stays) with the offset computed for cell k.
struct OffByOne1D(PiecewiseConstant1D);

impl OffByOne1D {
    fn sample_f64(&self, u: f64) -> f32 {
        let k = self.0.find_cell(u);
        let x = self.0.position_in_cell(k, u) as f64;
        let n = self.0.len();
        let shifted = if k + 1 < n { x + 1.0 / n as f64 } else { x };
        (shifted as f32).min(ONE_MINUS_EPSILON)
    }
}

impl Distribution1D for OffByOne1D {
    fn sample(&self, u: f32) -> Sample1D {
        let x = self.sample_f64(clamp_unit(u) as f64);
        Sample1D {
            x,
            pdf: self.pdf(x),
        }
    }
    fn pdf(&self, x: f32) -> f32 {
        self.0.pdf(x)
    }
    fn invert(&self, x: f32) -> f32 {
        self.0.invert(x)
    }
    fn integral(&self) -> f64 {
        self.0.integral()
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

#[test]
fn rejects_1d_off_by_one_cell_index() {
    let report = check_distribution_1d(
        "mutant_off_by_one_1d",
        |t: &[f32]| Ok(OffByOne1D(PiecewiseConstant1D::new(t)?)),
        &distribution_config(),
    );
    assert_rejected(&report, Check::ChiSquare);
}

/// The 2D reference whose row (marginal) index is off by one.
struct OffByOne2D(PiecewiseConstant2D);

impl Distribution2D for OffByOne2D {
    fn sample(&self, u: Vec2) -> Sample2D {
        let m = &self.0.marginal;
        let uy = clamp_unit(u.y) as f64;
        let row = m.find_cell(uy);
        let y = m.position_in_cell(row, uy) as f64;
        let (row, y) = if row + 1 < m.len() {
            (row + 1, y + 1.0 / m.len() as f64)
        } else {
            (row, y)
        };
        let x = self.0.conditionals[row].sample(u.x).x;
        let p = Vec2::new(x, (y as f32).min(ONE_MINUS_EPSILON));
        Sample2D {
            p,
            pdf: self.pdf(p),
        }
    }
    fn pdf(&self, p: Vec2) -> f32 {
        self.0.pdf(p)
    }
    fn invert(&self, p: Vec2) -> Vec2 {
        self.0.invert(p)
    }
    fn integral(&self) -> f64 {
        self.0.integral()
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

#[test]
fn rejects_2d_off_by_one_cell_index() {
    let report = check_distribution_2d(
        "mutant_off_by_one_2d",
        |t: &[f32], nx, ny| Ok(OffByOne2D(PiecewiseConstant2D::new(t, nx, ny)?)),
        &distribution_config(),
    );
    assert_rejected(&report, Check::ChiSquare);
}

/// A table on the sphere whose row index is off by one.
#[test]
fn rejects_sampler_with_off_by_one_cell_index() {
    let table: Vec<f32> = (0..12 * 10).map(|k| ((k * 37) % 11) as f32 + 0.5).collect();
    let report = check_sampler_family(
        "mutant_off_by_one_sphere_table",
        |_| {
            Ok(TabulatedSampler {
                distribution: OffByOne2D(PiecewiseConstant2D::new(&table, 12, 10)?),
            })
        },
        &brdfs::ordinary_brdfs()[..1],
        &sampler_config(),
    );
    assert_rejected(&report, Check::ChiSquare);
}

// ------------------------------------------- extremes and construction

/// The cosine sampler without its check of wo: it samples for wo at and
/// below the horizon, where the contract says `None`.
struct NoHorizonCheck;

impl BxdfSampler for NoHorizonCheck {
    fn name(&self) -> &str {
        "mutant-no-horizon-check"
    }
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        CosineSampler.sample(Vec3::Z, u).map(|s| BxdfSample {
            wi: s.wi,
            pdf: self.pdf(wo, s.wi),
        })
    }
    fn pdf(&self, _wo: Vec3, wi: Vec3) -> f32 {
        CosineSampler.pdf(Vec3::Z, wi)
    }
    fn storage_bytes(&self) -> usize {
        0
    }
}

#[test]
fn rejects_sampling_for_wo_below_the_horizon() {
    let report = check_sampler(
        "mutant_no_horizon_check",
        &NoHorizonCheck,
        None,
        &sampler_config(),
    );
    assert_rejected(&report, Check::Extremes);
}

/// The reference 1D distribution without input validation: NaN and
/// negative entries are silently replaced by 0 instead of being rejected.
#[test]
fn rejects_constructor_that_accepts_bad_tables() {
    let report = check_distribution_1d(
        "mutant_lenient_constructor",
        |t: &[f32]| {
            let cleaned: Vec<f32> = t
                .iter()
                .map(|&v| if v.is_finite() && v > 0.0 { v } else { 0.0 })
                .collect();
            if cleaned.is_empty() {
                PiecewiseConstant1D::new(&[0.0])
            } else {
                PiecewiseConstant1D::new(&cleaned)
            }
        },
        &DistributionConfig {
            samples: 100_000,
            ..distribution_config()
        },
    );
    assert_rejected(&report, Check::Construction);
}

// ------------------------------------------- one wo for a whole wavefront

/// A lobe around the mirror direction whose `sample_each` and `pdf_each`
/// use the first pair's wo for every pair: a batch path that hoisted the
/// slice lookup out of its loop. Its one-at-a-time calls are correct, so
/// only the batch check can see it.
struct FirstWoForAll(TiltedLobeSampler);

impl BxdfSampler for FirstWoForAll {
    fn name(&self) -> &str {
        "mutant-first-wo-for-all"
    }
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        self.0.sample(wo, u)
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        self.0.pdf(wo, wi)
    }
    fn storage_bytes(&self) -> usize {
        0
    }
    fn sample_each(&self, wo: &[Vec3], u: &[Vec2], out: &mut [Option<BxdfSample>]) {
        if let Some(&first) = wo.first() {
            self.0.sample_batch(first, u, out);
        }
    }
    fn pdf_each(&self, wo: &[Vec3], wi: &[Vec3], out: &mut [f32]) {
        if let Some(&first) = wo.first() {
            self.0.pdf_batch(first, wi, out);
        }
    }
}

#[test]
fn rejects_sample_each_with_one_wo_for_all_pairs() {
    let report = check_sampler(
        "mutant_first_wo_for_all",
        &FirstWoForAll(TiltedLobeSampler { exponent: 20.0 }),
        None,
        &sampler_config(),
    );
    assert_rejected(&report, Check::Batch);
}

// ------------------------------------------ a batch density off by a row

/// The 2D reference whose `pdf_batch` reads each point's density one row
/// of cells higher (the last row stays): a batch path that computed the
/// row index once too often. `sample` and `pdf` are correct, so only the
/// batch check can see it.
struct RowAbovePdfBatch(PiecewiseConstant2D, usize);

impl RowAbovePdfBatch {
    fn new(t: &[f32], nx: usize, ny: usize) -> Result<Self> {
        Ok(RowAbovePdfBatch(PiecewiseConstant2D::new(t, nx, ny)?, ny))
    }
}

impl Distribution2D for RowAbovePdfBatch {
    fn sample(&self, u: Vec2) -> Sample2D {
        self.0.sample(u)
    }
    fn pdf(&self, p: Vec2) -> f32 {
        self.0.pdf(p)
    }
    fn invert(&self, p: Vec2) -> Vec2 {
        self.0.invert(p)
    }
    fn integral(&self) -> f64 {
        self.0.integral()
    }
    fn storage_bytes(&self) -> usize {
        0
    }
    fn pdf_batch(&self, p: &[Vec2], out: &mut [f32]) {
        let step = 1.0 / self.1 as f32;
        for (o, &p) in out.iter_mut().zip(p) {
            let above = p.y + step;
            let y = if above < 1.0 { above } else { p.y };
            *o = self.0.pdf(Vec2::new(p.x, y));
        }
    }
}

#[test]
fn rejects_pdf_batch_reading_the_row_above() {
    let report = check_distribution_2d(
        "mutant_pdf_batch_row_above",
        RowAbovePdfBatch::new,
        &distribution_config(),
    );
    assert_rejected(&report, Check::Batch);
}

// ------------------------------------------- one partly lit cell zeroed

/// The uniform tabulated sampler at the isotropic resolution with one
/// half-vector cell of its grazing slice (θ_o from 84.5° to 90°) left at 0:
/// the cell that the centre of the slice (87.2°) reflects below the horizon
/// but other outgoing directions of the slice do not, with the most mass.
/// `sample` returns `None` for draws in it and `pdf` is 0 there, so sample
/// and pdf agree and ∫ pdf equals the fraction of successful draws: only
/// the support check can see it.
struct ZeroedCell {
    inner: acdf_uniform::UniformBrdfSampler,
    resolution: acdf_tabulated::Resolution,
    /// (column, row) of the zeroed cell in the last θ_o slice.
    cell: (usize, usize),
}

impl ZeroedCell {
    fn new(brdf: std::sync::Arc<dyn acdf_core::Brdf>) -> Result<Self> {
        use acdf_tabulated::tabulate::{slice_outgoing, tabulate_for, tabulate_slice};
        let resolution = acdf_tabulated::Resolution::ISOTROPIC;
        let last = resolution.theta_o - 1;
        let (n_phi, n_theta) = (resolution.phi_h, resolution.theta_h);
        let centre = tabulate_for(&*brdf, slice_outgoing(&resolution, last, 0), n_theta, n_phi);
        let filled = tabulate_slice(&*brdf, &resolution, last, 0);
        let index = centre
            .iter()
            .zip(&filled)
            .enumerate()
            .filter(|(_, (c, f))| **c == 0.0 && **f > 0.0)
            .max_by(|a, b| a.1 .1.total_cmp(b.1 .1))
            .map(|(k, _)| k)
            .ok_or_else(|| acdf_core::Error::InvalidParameter {
                name: "brdf",
                reason: "no partly lit cell to zero".into(),
            })?;
        let inner = acdf_uniform::UniformBrdfSampler::new(
            brdf,
            resolution,
            acdf_uniform::PiecewiseConstantBuilder,
        )?;
        Ok(ZeroedCell {
            inner,
            resolution,
            cell: (index % n_phi, index / n_phi),
        })
    }

    fn zeroed(&self, wo: Vec3, wi: Vec3) -> bool {
        let res = &self.resolution;
        if acdf_tabulated::outgoing_cell(res, wo).0 != res.theta_o - 1 {
            return false;
        }
        let h = (wo + wi).normalize();
        acdf_tabulated::half_vector_cell(h, wo.y.atan2(wo.x), res.phi_h, res.theta_h) == self.cell
    }
}

impl BxdfSampler for ZeroedCell {
    fn name(&self) -> &str {
        "mutant-zeroed-cell"
    }
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        self.inner.sample(wo, u).filter(|s| !self.zeroed(wo, s.wi))
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        if wi.is_finite() && self.zeroed(wo, wi) {
            0.0
        } else {
            self.inner.pdf(wo, wi)
        }
    }
    fn storage_bytes(&self) -> usize {
        self.inner.storage_bytes()
    }
}

#[test]
fn rejects_a_partly_lit_cell_left_at_zero() {
    let lambert = acdf_materials::builtin("lambert").expect("built-in material");
    let report = check_sampler_family(
        "mutant-zeroed-cell",
        ZeroedCell::new,
        &[lambert],
        &sampler_config(),
    );
    assert_rejected(&report, Check::Support);
}

// ------------------------------------ wi re-rounded in f32 before the lookup

/// The uniform tabulated sampler of the built-in near-mirror, whose `pdf`
/// first normalises wi again in `f32`, as a caller that renormalises its
/// directions would: an ulp of wi is a different direction where wo + wi
/// nearly cancels, so at grazing outgoing angles the density it looks up is
/// not the one the draw had.
struct RenormalisedLookup(acdf_uniform::UniformBrdfSampler);

impl BxdfSampler for RenormalisedLookup {
    fn name(&self) -> &str {
        "mutant-renormalised-lookup"
    }
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        self.0.sample(wo, u)
    }
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        let length = (wi.x * wi.x + wi.y * wi.y + wi.z * wi.z).sqrt();
        self.0.pdf(wo, wi / length)
    }
    fn storage_bytes(&self) -> usize {
        self.0.storage_bytes()
    }
}

/// The grazing agreement check (θ_o up to 89.999°) sees the re-rounded
/// lookup: near the horizon the mutant's densities differ from its draws'
/// by far more than 1e-4.
#[test]
fn rejects_a_pdf_that_renormalises_wi_in_f32() {
    let brdf = acdf_materials::builtin("near-mirror").unwrap();
    let resolution = acdf_tabulated::Resolution::ISOTROPIC;
    let inner = acdf_uniform::UniformBrdfSampler::new(
        brdf.clone(),
        resolution,
        acdf_uniform::PiecewiseConstantBuilder,
    )
    .unwrap();
    let mutant = RenormalisedLookup(inner);
    let config = SamplerConfig {
        samples: 100_000,
        wo_theta_degrees: vec![30.0],
        extreme_samples: 500,
        ..SamplerConfig::default()
    };
    let report = check_sampler("mutant_renormalised_lookup", &mutant, Some(&*brdf), &config);
    assert_rejected(&report, Check::PdfMismatch);
    assert!(
        report.failures.iter().any(|f| f.case.contains("grazing")),
        "the grazing agreement check should see it:\n{report}"
    );
}
