//! `acdf-conformance` is the battery every acdf sampler and distribution
//! passes: chi-square goodness of fit of the samples against the pdf the
//! code reports, consistency of `sample` with `pdf`, the integral of the pdf,
//! finite weights, and a list of extreme inputs (outgoing directions at and
//! below the horizon, uniform numbers at and beyond the edges of [0, 1),
//! degenerate and invalid tables, extreme BRDFs) each with a stated outcome.
//! A plug-in joins with one macro call; the battery itself is tested against
//! deliberately broken samplers (`tests/mutants.rs`), since a check that
//! cannot fail proves nothing.
//!
//! # Joining the battery
//!
//! ```text
//! // plugins' tests live in this crate: tests/tests/<plugin>.rs
//! use acdf_conformance::{brdfs, distribution_1d_battery, distribution_2d_battery, sampler_battery};
//!
//! // A sampler family: `build` makes a sampler from an `Arc<dyn Brdf>`; each
//! // BRDF of `brdfs` must build and pass; the battery also feeds the extreme
//! // BRDFs of `brdfs::extreme_brdfs()` (an `Err` is an accepted outcome).
//! sampler_battery!(uniform_analytic, build = |brdf| UniformSampler::new(brdf, Resolution::ISOTROPIC),
//!                  brdfs = brdfs::ordinary_brdfs());
//! // Optional: a config (e.g. fewer samples for a slow sampler).
//! sampler_battery!(rgl_quick, build = |b| RglSampler::new(b), brdfs = vec![my_brdf()],
//!                  config = acdf_conformance::SamplerConfig { samples: 200_000, ..Default::default() });
//!
//! // Distributions: the battery supplies the tables (including the extreme
//! // ones) and checks the stated outcome of each.
//! distribution_1d_battery!(pc1d, build = |t: &[f32]| PiecewiseConstant1D::new(t));
//! distribution_2d_battery!(pc2d, build = |t: &[f32], nx, ny| PiecewiseConstant2D::new(t, nx, ny));
//! // Vertex-valued tables (piecewise-linear semantics of `integral()`):
//! distribution_1d_battery!(pl1d, build = |t: &[f32]| PiecewiseLinear1D::new(t),
//!                          config = acdf_conformance::DistributionConfig::piecewise_linear());
//! ```
//!
//! Each macro expands to one `#[test] fn <name>()` that runs the battery,
//! prints one line per chi-square test (sampler, BRDF, wo, p-value, visible
//! with `-- --nocapture`) and asserts [`Report::passed`]. For a test that
//! must first locate data (and print `skipping: ...` when it is absent), call
//! the functions directly:
//!
//! ```text
//! #[test]
//! fn uniform_on_merl_nickel() {
//!     let Some(dir) = acdf_materials::shared_data_dir() else { return println!("skipping: no data") };
//!     let brdf: Arc<dyn Brdf> = Arc::new(load(dir.join("merl/nickel.binary")).unwrap());
//!     let report = acdf_conformance::check_sampler_family("uniform_nickel",
//!         |b| UniformSampler::new(b, ..), &[brdf], &SamplerConfig::default());
//!     report.print();
//!     assert!(report.passed(), "{report}");
//! }
//! ```
//!
//! # API
//!
//! - [`check_sampler_family`]`(subject, build: Fn(Arc<dyn Brdf>) -> Result<S>, brdfs: &[Arc<dyn Brdf>], &SamplerConfig) -> Report`
//! - [`check_sampler`]`(subject, &dyn BxdfSampler, Option<&dyn Brdf>, &SamplerConfig) -> Report`
//! - [`check_distribution_1d`]`(subject, build: Fn(&[f32]) -> Result<D>, &DistributionConfig) -> Report`
//! - [`check_distribution_2d`]`(subject, build: Fn(&[f32], usize, usize) -> Result<D>, &DistributionConfig) -> Report`
//! - [`Report`]: `passed()`, `failed(Check)`, `chi_square` lines, `failures`, `print()`, `Display`.
//!
//! Cost per (BRDF, wo), run in parallel over wo with rayon: N draws, 2N pdf
//! evaluations (consistency, stratified integral) and about 10^6 for the
//! quadrature of the 10^4 upper-hemisphere cells (independent of N); plus
//! 2 · 10^4 draws for the extreme wo and, per extreme BRDF the constructor
//! accepts, `extreme_samples` draws per wo. Lower `SamplerConfig::samples`
//! for a slow sampler rather than dropping outgoing directions.
//!
//! # What is checked, and the stated outcomes
//!
//! Samplers (per BRDF, at wo with θ ∈ {0, 30, 60, 85, 89.5}° and φ = 1 rad):
//! 10^6 draws binned over 100 × 200 equal-area cells of (cos θ, φ) on the
//! sphere plus one bin for `None`; expected counts N ∫_cell pdf d(cos θ) dφ
//! by adaptive Simpson quadrature in f64, each cell first cut into 1 × 4
//! pieces (φ × cos θ) so that a sampler's own finer grid does not alias
//! with the nodes (cells below the horizon expect 0, the `None` bin
//! N (1 - ∫ pdf)); cells under 5 expected are
//! pooled; a sample in a cell expecting 0 fails outright; α = 0.01, Sidak
//! over all (BRDF, wo) of the call. Every sample: unit finite wi with
//! wi.z > 0, finite pdf > 0 equal to `pdf(wo, wi)` to 1e-4 relative;
//! f cos θ_i / pdf finite (f32). Support: where a BRDF is given, the share
//! of Y(f) cos θ_i (Y the luminance) on which `pdf` is 0,
//! [`missed_share`](acdf_core::missed_share), is at most
//! `max_missed_share` (1e-7 by default) at every configured wo, by the
//! midpoint rule on 128 × 256 equal-area cells of (cos θ_i, φ_i) over the
//! upper hemisphere (cells of 1.9e-4 sr); the battery's reference samplers,
//! which draw a density unrelated to the BRDF they are paired with, set it
//! to `None`. ∫ pdf, estimated by stratified Monte Carlo
//! (N jittered points, two per stratum, with its own standard error), is
//! ≤ 1 + 1e-3; and either that estimate is within 3 combined standard errors
//! of the fraction of successful draws, or the quadrature's ∫ pdf is (within
//! 3 standard errors of the fraction plus 1e-3). The two estimates have
//! opposite blind spots (an isolated spike no Monte Carlo point hits; fine
//! structure aligned with the quadrature's nodes), while a wrong pdf moves
//! both; a note names the one that disagreed. `pdf` is 0 at and below the
//! horizon and finite for NaN wi.
//! `sample(u) == sample(clamp_unit(u))` bit for bit for u in [`EXTREME_U`]².
//! wo at θ = 0, 1e-6 rad, 89.99°: `None` or a valid sample; wo at exactly
//! 90° (z = ±0), below the horizon or not finite: always `None`, pdf 0.
//! Grazing agreement: at θ_o ∈ [`GRAZING_THETA_DEGREES`] (0 to 89.999°),
//! with φ_o at the configured azimuth and at 0 (a cell edge), 2,000 draws
//! each, every valid draw's density equals `pdf(wo, wi)` to 1e-4.
//! Extreme BRDFs ([`brdfs::extreme_brdfs`]): the constructor may return an
//! error; a sampler it returns must draw valid samples with finite weights
//! (no chi-square test for them).
//!
//! Distributions (tables of [`tables_1d`] / [`tables_2d`]): each accepted
//! table gets 10^6 draws over 1009 (1D) or 101 × 103 (2D) cells, primes so
//! that cell edges never align with table edges inside the domain and at
//! least two cells per table cell; the same chi-square rule; sample in the
//! domain with a finite pdf > 0 equal to `pdf`; ∫ pdf = 1 to 1e-4;
//! `integral()` equals the table's integral under the configured semantics
//! (mean of cells by default) to 1e-5 relative; `invert(sample(u)) == u`
//! to 1e-5 (1D) / 1e-4 (2D) plus f32 rounding times the peak density;
//! `u ∈ {0, 1 - ε/2, CDF at every table edge, values outside [0, 1)}` give
//! valid samples, equal to those of `clamp_unit(u)`; pdf 0 outside the
//! domain. All-zero tables: uniform pdf 1 and `integral() == 0`. Bad tables:
//! the `acdf_core::Error` variant (and index) stated in [`ExpectedError`].
//! Panics anywhere are caught and reported as [`Check::Panic`].
//!
//! Environment samplers (directions over the whole sphere for a lat-long
//! map and a shading normal) have a battery of their own, [`env`](mod@env):
//! [`check_env_family`] over the maps of [`env_test_maps`] (a structured
//! sky and the extremes) and the normals of [`env_test_normals`].

/// Re-exported so that the macros name the same traits as the caller.
pub use acdf_core;

pub mod brdfs;
pub mod chi2;
pub mod distribution_checks;
pub mod env;
pub mod quadrature;
pub mod reference;
pub mod report;
pub mod sampler_checks;
pub mod samplers;

pub use distribution_checks::{
    check_distribution_1d, check_distribution_2d, tables_1d, tables_2d, DistributionConfig, Expect,
    ExpectedError, Table1D, Table2D,
};
pub use env::{
    check_env_family, check_env_sampler, env_test_maps, env_test_normals, EnvConfig, EnvTarget,
};
pub use report::{assert_rejected, Check, ChiSquareLine, Failure, Report};
pub use sampler_checks::{
    check_sampler, check_sampler_family, SamplerConfig, EXTREME_U, GRAZING_THETA_DEGREES,
};

/// One `#[test]` running [`check_sampler_family`] on `build` with `brdfs`
/// (an expression giving `Vec<Arc<dyn Brdf>>` or an array of them) and an
/// optional [`SamplerConfig`].
#[macro_export]
macro_rules! sampler_battery {
    ($name:ident, build = $build:expr, brdfs = $brdfs:expr $(,)?) => {
        $crate::sampler_battery!(
            $name,
            build = $build,
            brdfs = $brdfs,
            config = $crate::SamplerConfig::default()
        );
    };
    ($name:ident, build = $build:expr, brdfs = $brdfs:expr, config = $config:expr $(,)?) => {
        #[test]
        fn $name() {
            let brdfs: ::std::vec::Vec<::std::sync::Arc<dyn $crate::acdf_core::Brdf>> =
                ::std::iter::IntoIterator::into_iter($brdfs).collect();
            let config: $crate::SamplerConfig = $config;
            let report = $crate::check_sampler_family(stringify!($name), $build, &brdfs, &config);
            report.print();
            assert!(report.passed(), "{report}");
        }
    };
}

/// One `#[test]` running [`check_distribution_1d`] on `build` with an
/// optional [`DistributionConfig`].
#[macro_export]
macro_rules! distribution_1d_battery {
    ($name:ident, build = $build:expr $(,)?) => {
        $crate::distribution_1d_battery!(
            $name,
            build = $build,
            config = $crate::DistributionConfig::default()
        );
    };
    ($name:ident, build = $build:expr, config = $config:expr $(,)?) => {
        #[test]
        fn $name() {
            let config: $crate::DistributionConfig = $config;
            let report = $crate::check_distribution_1d(stringify!($name), $build, &config);
            report.print();
            assert!(report.passed(), "{report}");
        }
    };
}

/// One `#[test]` running [`check_distribution_2d`] on `build` with an
/// optional [`DistributionConfig`].
#[macro_export]
macro_rules! distribution_2d_battery {
    ($name:ident, build = $build:expr $(,)?) => {
        $crate::distribution_2d_battery!(
            $name,
            build = $build,
            config = $crate::DistributionConfig::default()
        );
    };
    ($name:ident, build = $build:expr, config = $config:expr $(,)?) => {
        #[test]
        fn $name() {
            let config: $crate::DistributionConfig = $config;
            let report = $crate::check_distribution_2d(stringify!($name), $build, &config);
            report.print();
            assert!(report.passed(), "{report}");
        }
    };
}
