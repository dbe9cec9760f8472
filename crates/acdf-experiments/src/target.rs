//! A quality target instead of a tolerance: the smallest adaptive sampler
//! whose noise-free efficiency ([`efficiency`](crate::efficiency)) is at
//! least a given fraction of a reference sampler's, found by searching the
//! simplifier's tolerance.
//!
//! A larger tolerance keeps fewer vertices (less storage) and usually
//! costs variance. The search starts at the given tolerance (by default the
//! simplifier's own; a survey passes the previous material's answer) and
//! steps by factors of [`STEP`] (up while the target is met, down while it
//! is not) until the target changes sides, then halves the
//! bracketing interval in log-tolerance [`BISECTIONS`] times. Every
//! candidate is built in full, its relative variance taken by quadrature
//! and its time measured in turns with the reference's
//! ([`time_samplers`]); the answer is the candidate of least storage among
//! those that meet the target. When none does, down to
//! [`STEPS_DOWN`] steps below the default and tolerance 0 (every vertex
//! kept), the outcome says so and holds the best candidate found.

use std::time::Instant;

use acdf_core::BxdfSampler;
use serde::Serialize;

use crate::efficiency::{efficiency_of, time_samplers, EfficiencyConfig, Integrands};
use crate::sweep::{default_tolerance, spec_default_tolerance};
use acdf::core::HemisphereGrid;
use acdf::env::Sky;
use acdf::error::{Error, Result};
use acdf::material::Material;
use acdf::registry::{make_sampler_tabulated, AnySampler, SamplerOptions, Tabulation};
use acdf::spec::{SamplerAt, SamplerSpec, SimplifierName};

/// The factor between the tolerances of the stepping phase.
pub const STEP: f64 = 4.0;
/// Steps above the starting tolerance at most; the stepping also stops
/// when a step no longer shrinks the storage (every curve is down to its
/// two ends).
pub const STEPS_UP: usize = 10;
/// Steps below the starting tolerance at most (then tolerance 0).
pub const STEPS_DOWN: usize = 8;
/// Halvings of the bracketing interval in log-tolerance: the answer is
/// within a factor 4^(1/4) ≈ 1.41 of the largest tolerance that meets the
/// target (if efficiency falls with tolerance).
pub const BISECTIONS: usize = 2;

/// One tolerance the search tried.
#[derive(Debug, Clone, Serialize)]
pub struct Candidate {
    pub tolerance: f64,
    pub storage_bytes: usize,
    /// By quadrature.
    pub relative_variance: f64,
    /// Efficiency over the reference's, timed in turns with it.
    pub relative_efficiency: f64,
    /// t_s of the candidate and of the reference in that timing.
    pub sampler_seconds: f64,
    pub reference_seconds: f64,
    pub build_seconds: f64,
}

/// What the search found for one simplifier.
#[derive(Debug, Clone, Serialize)]
pub struct TargetOutcome {
    /// `adaptive:SIMPLIFIER`.
    pub sampler: String,
    /// The fraction of the reference's efficiency asked for.
    pub target: f64,
    /// Whether some tolerance met it.
    pub reached: bool,
    /// The chosen candidate: the least storage among those that meet the
    /// target, or, when none does, the most efficient one.
    pub chosen: Candidate,
    /// Every candidate, in the order tried.
    pub tried: Vec<Candidate>,
}

impl TargetOutcome {
    /// One line for the user: what was found, or that the target was not
    /// reached and the best found.
    pub fn describe(&self, reference: &str) -> String {
        let c = &self.chosen;
        if self.reached {
            format!(
                "{}: tolerance {:.3e} meets {} x the efficiency of {reference} ({:.3}, {} bytes; {} tolerances tried)",
                self.sampler,
                c.tolerance,
                self.target,
                c.relative_efficiency,
                c.storage_bytes,
                self.tried.len()
            )
        } else {
            format!(
                "{}: no tolerance reaches {} x the efficiency of {reference}; the best found is {:.3} at tolerance {:.3e} ({} bytes; {} tolerances tried)",
                self.sampler,
                self.target,
                c.relative_efficiency,
                c.tolerance,
                c.storage_bytes,
                self.tried.len()
            )
        }
    }
}

impl TargetOutcome {
    /// [`Error::TargetNotReached`], saying the best found, when no
    /// tolerance met the target; `reference` names the reference.
    pub fn require_reached(&self, reference: &str) -> Result<()> {
        if self.reached {
            return Ok(());
        }
        let c = &self.chosen;
        Err(Error::TargetNotReached {
            sampler: self.sampler.clone(),
            target: self.target,
            reference: reference.to_string(),
            best: format!(
                "the best found is {:.3} at tolerance {:.3e} ({} tolerances tried)",
                c.relative_efficiency,
                c.tolerance,
                self.tried.len()
            ),
        })
    }
}

/// A target efficiency, checked: a finite positive number (a fraction of
/// the reference's efficiency), else [`Error::InvalidArgument`].
pub fn check_target(target: f64) -> Result<f64> {
    if target.is_finite() && target > 0.0 {
        Ok(target)
    } else {
        Err(Error::InvalidArgument {
            what: "target efficiency",
            value: target.to_string(),
            reason: "must be a positive number (a fraction of the reference's efficiency)".into(),
        })
    }
}

/// The measurement settings of [`build_for_target`]: the noise-free
/// variance on a 512 x 256 half-vector grid (within 1.2% of the finest on
/// the report's materials), no Monte Carlo draws, and the fastest of 20
/// timed repeats of 2^9 draws per outgoing direction.
pub fn single_search_config() -> EfficiencyConfig {
    EfficiencyConfig {
        samples_per_direction: 0,
        grid: HemisphereGrid::HalfVector { n_v: 512, n_x: 256 },
        timing_samples_per_direction: 1 << 9,
        timing_repeats: 20,
        ..EfficiencyConfig::default()
    }
}

/// What [`build_for_target`] is doing, for a progress display.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SearchStep {
    /// Building the reference sampler.
    Reference,
    /// Tabulating the material at the sampler's resolution.
    Tabulating,
    /// The quadrature of the integrands and of the reference's variance.
    Quadrature,
    /// Trying a tolerance.
    Tolerance(f64),
}

/// The adaptive sampler `spec` (its simplifier, at `options`' resolution
/// and cosine mixing; `options.tolerance` is where the search starts) for
/// `material` whose efficiency is at least `target` times `reference`'s,
/// under the dome sky and [`single_search_config`]: what `acdf build
/// --target-efficiency` builds. A reference without `@RES` takes
/// `options`' resolution. Returns the outcome (check
/// [`TargetOutcome::require_reached`]) and the chosen sampler, built.
/// `progress` is called before each step.
pub fn build_for_target(
    material: &Material,
    spec: SamplerSpec,
    options: &SamplerOptions,
    reference: SamplerAt,
    target: f64,
    mut progress: impl FnMut(SearchStep),
) -> Result<(TargetOutcome, AnySampler)> {
    let target = check_target(target)?;
    spec.simplifier().ok_or_else(|| Error::InvalidArgument {
        what: "sampler",
        value: spec.to_string(),
        reason: "a target efficiency searches the tolerance of an adaptive sampler (adaptive:S or outgoing:S)".into(),
    })?;
    let reference_options = SamplerOptions {
        resolution: reference.resolution.unwrap_or(options.resolution),
        ..*options
    };
    progress(SearchStep::Reference);
    let config = single_search_config();
    let reference_tables = Tabulation::new(material, reference_options.resolution);
    let reference_sampler = make_sampler_tabulated(
        reference.sampler,
        material,
        &reference_options,
        &reference_tables,
    )?;
    drop(reference_tables);
    progress(SearchStep::Tabulating);
    let tables = Tabulation::new(material, options.resolution);
    progress(SearchStep::Quadrature);
    let integrands = Integrands::new(material.brdf.as_ref(), &Sky::dome(), &config);
    let relative_variance = integrands.noise_free(&reference_sampler).relative_variance;
    search_tolerance(
        material,
        spec,
        options,
        &Reference {
            sampler: &reference_sampler,
            relative_variance,
        },
        &integrands,
        &tables,
        &config,
        target,
        |t| progress(SearchStep::Tolerance(t)),
    )
}

/// The reference a search compares with: a built sampler and its relative
/// variance on the same integrands.
pub struct Reference<'a> {
    pub sampler: &'a dyn BxdfSampler,
    pub relative_variance: f64,
}

/// Search the tolerance of the sampler `spec` (`adaptive:SIMPLIFIER` or
/// `outgoing:SIMPLIFIER`; a family without simplifiers is searched as its
/// first) (at `base`'s resolution and cosine
/// mixing) for the smallest sampler of `material` whose efficiency is at
/// least `target` times `reference`'s, on `integrands`, building the
/// candidates from `tables` (see the module documentation). Returns the outcome and the chosen sampler, built.
/// `progress` is called with each tolerance before it is tried.
#[allow(clippy::too_many_arguments)]
pub fn search_tolerance(
    material: &Material,
    spec: SamplerSpec,
    base: &SamplerOptions,
    reference: &Reference,
    integrands: &Integrands,
    tables: &Tabulation,
    config: &EfficiencyConfig,
    target: f64,
    mut progress: impl FnMut(f64),
) -> Result<(TargetOutcome, AnySampler)> {
    let simplifier = spec
        .simplifier()
        .unwrap_or_else(SimplifierName::default_simplifier);
    // Only the samplers' own work is compared.
    let config = &EfficiencyConfig {
        time_eval: false,
        ..config.clone()
    };
    let mut tried: Vec<(Candidate, AnySampler)> = Vec::new();
    let mut try_tolerance = |tolerance: f64| -> Result<(bool, usize)> {
        progress(tolerance);
        let options = SamplerOptions {
            tolerance: Some(tolerance),
            ..*base
        };
        let start = Instant::now();
        let sampler = make_sampler_tabulated(spec, material, &options, tables)?;
        // As if built alone: with the tabulation it shares.
        let build_seconds = start.elapsed().as_secs_f64() + tables.seconds;
        let noise_free = integrands.noise_free(&sampler);
        let times = time_samplers(
            material.brdf.as_ref(),
            &[reference.sampler, &sampler],
            config,
        );
        let reference_efficiency =
            efficiency_of(reference.relative_variance, times[0].sampler_seconds());
        let efficiency = efficiency_of(noise_free.relative_variance, times[1].sampler_seconds());
        let relative_efficiency = relative(efficiency, reference_efficiency);
        let candidate = Candidate {
            tolerance,
            storage_bytes: sampler.storage_bytes(),
            relative_variance: noise_free.relative_variance,
            relative_efficiency,
            sampler_seconds: times[1].sampler_seconds(),
            reference_seconds: times[0].sampler_seconds(),
            build_seconds,
        };
        let met = relative_efficiency >= target;
        let storage = candidate.storage_bytes;
        tried.push((candidate, sampler));
        Ok((met, storage))
    };

    // A start beyond the stepping's reach from the default is brought
    // back to it.
    let default = spec_default_tolerance(spec).unwrap_or_else(|| default_tolerance(simplifier));
    let start = base
        .tolerance
        .filter(|t| t.is_finite() && *t > 0.0)
        .map_or(default, |t| t.min(default * STEP.powi(STEPS_UP as i32)));
    // (tolerance that meets the target, tolerance that does not).
    let (mut good, mut bad): (Option<f64>, Option<f64>) = (None, None);
    let (met, mut storage) = try_tolerance(start)?;
    if met {
        good = Some(start);
        let mut t = start;
        for _ in 0..STEPS_UP {
            t *= STEP;
            let (met, smaller) = try_tolerance(t)?;
            if !met {
                bad = Some(t);
                break;
            }
            good = Some(t);
            if smaller >= storage {
                break;
            }
            storage = smaller;
        }
    } else {
        bad = Some(start);
        let mut t = start;
        for _ in 0..STEPS_DOWN {
            t /= STEP;
            if try_tolerance(t)?.0 {
                good = Some(t);
                break;
            }
            bad = Some(t);
        }
        if good.is_none() && try_tolerance(0.0)?.0 {
            good = Some(0.0);
        }
    }
    if let (Some(mut lo), Some(mut hi)) = (good, bad) {
        if lo > 0.0 {
            for _ in 0..BISECTIONS {
                let mid = (lo * hi).sqrt();
                if try_tolerance(mid)?.0 {
                    lo = mid;
                } else {
                    hi = mid;
                }
            }
        }
    }

    let meets = |c: &Candidate| c.relative_efficiency >= target;
    let reached = tried.iter().any(|(c, _)| meets(c));
    let best = if reached {
        tried
            .iter()
            .enumerate()
            .filter(|(_, (c, _))| meets(c))
            // Of equal storage, the smallest tolerance: beyond the point
            // where every curve keeps only its two ends, a larger
            // tolerance changes nothing.
            .min_by(|(_, (a, _)), (_, (b, _))| {
                a.storage_bytes
                    .cmp(&b.storage_bytes)
                    .then(a.tolerance.total_cmp(&b.tolerance))
            })
            .map(|(k, _)| k)
    } else {
        tried
            .iter()
            .enumerate()
            .max_by(|(_, (a, _)), (_, (b, _))| {
                a.relative_efficiency.total_cmp(&b.relative_efficiency)
            })
            .map(|(k, _)| k)
    }
    .expect("the search tries at least one tolerance");
    let candidates: Vec<Candidate> = tried.iter().map(|(c, _)| c.clone()).collect();
    let (chosen, sampler) = tried.swap_remove(best);
    Ok((
        TargetOutcome {
            sampler: spec.to_string(),
            target,
            reached,
            chosen,
            tried: candidates,
        },
        sampler,
    ))
}

/// a / b, 0 when b is infinite and a is not, 1 when both are infinite
/// (two samplers without variance), never NaN.
pub fn relative(a: f64, b: f64) -> f64 {
    match (a.is_finite(), b.is_finite()) {
        (true, true) if b > 0.0 => a / b,
        (false, false) => 1.0,
        (true, false) => 0.0,
        _ => f64::INFINITY,
    }
}
