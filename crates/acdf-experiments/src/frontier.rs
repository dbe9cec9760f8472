//! The storage frontier: for each material and sampler family, the
//! smallest storage that reaches given fractions ("levels") of a reference
//! sampler's efficiency, by default the 32x16x256x32 table of Lawrence et
//! al.
//!
//! Every family is first built as `acdf build` builds it without a
//! tolerance: its default. A family without a tolerance (cosine, uniform
//! at its one resolution, lobes) has that one point, its storage and
//! relative efficiency; it reaches every level up to that efficiency. A
//! family with a tolerance (every `adaptive:SIMPLIFIER`, `outgoing:chi2`)
//! is also searched with the target search ([`search_tolerance`]) once per
//! level, in increasing order, each search starting at the tolerance the
//! previous level chose (the first at the family's default tolerance).
//! The default and every candidate of every search are kept, and the
//! frontier at a level is the
//! least storage among the candidates whose relative efficiency reaches
//! it: a candidate that reaches a level reaches every lower one, so the
//! storage is monotone in the level by construction. When no tolerance
//! (down to 0) reaches a level, or only tolerance 0 (every vertex kept)
//! does, the higher levels are not searched: the candidates already tried
//! include the finest sampler the family has, and decide them.
//! Relative efficiency is the deterministic one of the target search: the
//! relative variance by quadrature on the same integrands, and the
//! sampler's own time measured in turns with the reference's
//! ([`time_samplers`]).

use std::io::Write;
use std::path::Path;

use acdf_core::BxdfSampler;
use serde::Serialize;

use crate::efficiency::{efficiency_of, time_samplers, EfficiencyConfig, Integrands};
use crate::plot::{figure_bytes, Figure, Marker, Panel, Series, Style};
use crate::sweep::spec_default_tolerance;
use crate::target::{check_target, relative, search_tolerance, Reference};
use acdf::env::Environment;
use acdf::error::{Error, Result};
use acdf::material::Material;
use acdf::registry::{make_sampler_tabulated, plain_samplers, SamplerOptions, Tabulation};
use acdf::spec::{SamplerAt, SamplerSpec, SimplifierName};

/// The levels of `acdf survey --frontier` without a list.
pub const DEFAULT_LEVELS: [f64; 5] = [0.5, 0.8, 0.95, 1.0, 2.0];

/// The storage bounds of the summary's counts, in bytes.
pub const COUNT_BOUNDS: [usize; 2] = [1024, 4096];

/// The families of the frontier for `material`: those without a tolerance
/// the registry knows for it (cosine, uniform, lobes), `adaptive` with
/// every simplifier, and `outgoing:chi2`.
pub fn frontier_families(material: &Material) -> Vec<SamplerSpec> {
    let mut families = plain_samplers(material);
    families.extend(SimplifierName::all().map(SamplerSpec::adaptive));
    let chi2 = SimplifierName::find("chi2").unwrap_or_else(SimplifierName::default_simplifier);
    families.push(
        format!("{}:{chi2}", acdf::registry::OUTGOING)
            .parse()
            .expect("the outgoing family takes every simplifier"),
    );
    families
}

/// Levels checked and sorted: finite positive numbers, in increasing order,
/// without repeats; else [`Error::InvalidArgument`].
pub fn check_levels(levels: &[f64]) -> Result<Vec<f64>> {
    let mut out = levels
        .iter()
        .map(|&l| check_target(l))
        .collect::<Result<Vec<f64>>>()?;
    if out.is_empty() {
        return Err(Error::InvalidArgument {
            what: "frontier levels",
            value: String::new(),
            reason: "give at least one level".into(),
        });
    }
    out.sort_by(f64::total_cmp);
    out.dedup();
    Ok(out)
}

/// One measured sampler: a candidate of a search or a family's one point.
#[derive(Debug, Clone, Copy, Serialize)]
pub struct Point {
    pub tolerance: Option<f64>,
    pub storage_bytes: usize,
    pub relative_efficiency: f64,
}

/// One (material, family, level) row of the frontier.
#[derive(Debug, Clone, Serialize)]
pub struct FrontierRow {
    pub material: String,
    pub family: String,
    /// The fraction of the reference's efficiency.
    pub level: f64,
    /// Whether some measured sampler of the family reaches it.
    pub reached: bool,
    /// The least storage that reaches it, with that sampler's relative
    /// efficiency and tolerance (`None` for the family as built without
    /// one).
    pub storage_bytes: Option<usize>,
    pub relative_efficiency: Option<f64>,
    pub tolerance: Option<f64>,
    /// The family at its default tolerance (or its one point).
    pub default_storage_bytes: usize,
    pub default_relative_efficiency: f64,
    /// Samplers measured for this family and material.
    pub candidates: usize,
}

/// The frontier rows of one family from its measured points, `default`
/// among them.
pub fn rows_from_points(
    material: &str,
    family: &str,
    levels: &[f64],
    points: &[Point],
    default: Point,
) -> Vec<FrontierRow> {
    levels
        .iter()
        .map(|&level| {
            let best = points
                .iter()
                .filter(|p| p.relative_efficiency >= level)
                .min_by(|a, b| {
                    a.storage_bytes
                        .cmp(&b.storage_bytes)
                        .then(b.relative_efficiency.total_cmp(&a.relative_efficiency))
                });
            FrontierRow {
                material: material.to_string(),
                family: family.to_string(),
                level,
                reached: best.is_some(),
                storage_bytes: best.map(|p| p.storage_bytes),
                relative_efficiency: best.map(|p| p.relative_efficiency),
                tolerance: best.and_then(|p| p.tolerance),
                default_storage_bytes: default.storage_bytes,
                default_relative_efficiency: default.relative_efficiency,
                candidates: points.len(),
            }
        })
        .collect()
}

/// What the frontier measures with: the reference, the resolution of the
/// other samplers, and the noise-free measures and timing.
#[derive(Debug, Clone)]
pub struct FrontierConfig {
    pub reference: SamplerAt,
    pub options: SamplerOptions,
    pub levels: Vec<f64>,
    pub efficiency: EfficiencyConfig,
    /// Only the families of these names ([`frontier_families`] as text,
    /// e.g. `outgoing:chi2`); all when `None`.
    pub families: Option<Vec<String>>,
}

impl FrontierConfig {
    /// The families of [`frontier_families`] this configuration measures
    /// for `material`.
    pub fn families_of(&self, material: &Material) -> Vec<SamplerSpec> {
        frontier_families(material)
            .into_iter()
            .filter(|f| {
                self.families
                    .as_ref()
                    .is_none_or(|names| names.contains(&f.to_string()))
            })
            .collect()
    }
}

/// The frontier of one material: the rows of every family of
/// [`FrontierConfig::families_of`] at every level (see the module
/// documentation).
/// `progress` is called with what is being done.
pub fn frontier_material(
    material: &Material,
    env: &dyn Environment,
    config: &FrontierConfig,
    mut progress: impl FnMut(&str),
) -> Result<Vec<FrontierRow>> {
    let levels = check_levels(&config.levels)?;
    // Only the samplers' own work is compared, as in the target search.
    let efficiency = EfficiencyConfig {
        time_eval: false,
        ..config.efficiency.clone()
    };
    let reference_options = SamplerOptions {
        resolution: config
            .reference
            .resolution
            .unwrap_or(config.options.resolution),
        ..config.options
    };
    progress("reference");
    let reference_tables = Tabulation::by_rotation(material, reference_options.resolution);
    let reference_sampler = make_sampler_tabulated(
        config.reference.sampler,
        material,
        &reference_options,
        &reference_tables,
    )?;
    drop(reference_tables);
    progress("tabulation");
    let tables = Tabulation::new(material, config.options.resolution);
    progress("quadrature");
    let integrands = Integrands::new(material.brdf.as_ref(), env, &efficiency);
    let reference = Reference {
        sampler: &reference_sampler,
        relative_variance: integrands.noise_free(&reference_sampler).relative_variance,
    };
    let label = material.label();
    let mut rows = Vec::new();
    for spec in config.families_of(material) {
        let family = spec.to_string();
        progress(&family);
        // The family as built without a tolerance: for a family with one,
        // its default (which may differ from any tolerance given, e.g. a
        // storage cap that applies only by default).
        let sampler = make_sampler_tabulated(spec, material, &config.options, &tables)?;
        let rv = integrands.noise_free(&sampler).relative_variance;
        let times = time_samplers(
            material.brdf.as_ref(),
            &[reference.sampler, &sampler as &dyn BxdfSampler],
            &efficiency,
        );
        let default = Point {
            tolerance: None,
            storage_bytes: sampler.storage_bytes(),
            relative_efficiency: relative(
                efficiency_of(rv, times[1].sampler_seconds()),
                efficiency_of(reference.relative_variance, times[0].sampler_seconds()),
            ),
        };
        drop(sampler);
        let mut points = vec![default];
        if spec_default_tolerance(spec).is_some() {
            points.extend(family_searched(
                material,
                spec,
                config,
                &reference,
                &integrands,
                &tables,
                &levels,
                &efficiency,
                |t| progress(&format!("{family}: tolerance {t:.2e}")),
            )?);
        }
        rows.extend(rows_from_points(&label, &family, &levels, &points, default));
    }
    Ok(rows)
}

/// Every candidate of the target searches of `spec` at `levels` (in
/// increasing order).
#[allow(clippy::too_many_arguments)]
fn family_searched(
    material: &Material,
    spec: SamplerSpec,
    config: &FrontierConfig,
    reference: &Reference,
    integrands: &Integrands,
    tables: &Tabulation,
    levels: &[f64],
    efficiency: &EfficiencyConfig,
    mut progress: impl FnMut(f64),
) -> Result<Vec<Point>> {
    let mut points: Vec<Point> = Vec::new();
    let mut start = None;
    for &level in levels {
        let (outcome, _) = search_tolerance(
            material,
            spec,
            &SamplerOptions {
                tolerance: start,
                ..config.options
            },
            reference,
            integrands,
            tables,
            efficiency,
            level,
            &mut progress,
        )?;
        let tried = outcome.tried.iter().map(|c| Point {
            tolerance: Some(c.tolerance),
            storage_bytes: c.storage_bytes,
            relative_efficiency: c.relative_efficiency,
        });
        points.extend(tried);
        if !outcome.reached {
            break;
        }
        start = Some(outcome.chosen.tolerance).filter(|t| *t > 0.0);
        if start.is_none() {
            break;
        }
    }
    Ok(points)
}

/// A family's frontier over the materials at one level.
#[derive(Debug, Clone, Serialize)]
pub struct LevelSummary {
    pub level: f64,
    /// Materials where some sampler of the family reaches the level.
    pub reached: usize,
    /// The median storage over every material, a material that does not
    /// reach the level counting as infinite: `None` when that is the
    /// median.
    pub median_storage_bytes: Option<f64>,
    /// The largest storage over every material, `None` when some material
    /// does not reach the level; the material.
    pub worst_storage_bytes: Option<usize>,
    pub worst_material: Option<String>,
}

/// One family's line of the frontier summary.
#[derive(Debug, Clone, Serialize)]
pub struct FamilySummary {
    pub family: String,
    pub materials: usize,
    pub levels: Vec<LevelSummary>,
    /// The level of the counts (the survey's target efficiency).
    pub count_level: f64,
    /// Materials that reach `count_level` within each of
    /// [`COUNT_BOUNDS`] bytes.
    pub within: Vec<(usize, usize)>,
    /// Materials where the family at its default tolerance (or its one
    /// point) reaches `count_level`.
    pub at_default: usize,
}

/// The median of storages, `None` standing for infinity (not reached);
/// `None` when the median is infinite or there is no value.
fn median_storage(values: &[Option<usize>]) -> Option<f64> {
    let v: Vec<f64> = values
        .iter()
        .map(|s| s.map_or(f64::INFINITY, |b| b as f64))
        .collect();
    let m = crate::efficiency::median(&v);
    (!v.is_empty() && m.is_finite()).then_some(m)
}

/// The summary of frontier rows per family, in the order of `families`, at
/// `levels`; the counts at `count_level` (which should be one of the
/// levels: a material without a row at it counts as not reaching it).
pub fn summarize_frontier(
    rows: &[FrontierRow],
    families: &[String],
    levels: &[f64],
    count_level: f64,
) -> Vec<FamilySummary> {
    families
        .iter()
        .map(|family| {
            let mine: Vec<&FrontierRow> = rows.iter().filter(|r| &r.family == family).collect();
            let mut materials: Vec<&str> = mine.iter().map(|r| r.material.as_str()).collect();
            materials.sort_unstable();
            materials.dedup();
            let at = |level: f64| -> Vec<&FrontierRow> {
                mine.iter().copied().filter(|r| r.level == level).collect()
            };
            let level_rows = levels
                .iter()
                .map(|&level| {
                    let here = at(level);
                    let storages: Vec<Option<usize>> = here
                        .iter()
                        .map(|r| r.storage_bytes.filter(|_| r.reached))
                        .collect();
                    let all_reached = storages.iter().all(Option::is_some);
                    let worst = here
                        .iter()
                        .filter_map(|r| r.storage_bytes.map(|s| (s, r)))
                        .max_by_key(|(s, _)| *s)
                        .filter(|_| all_reached && !here.is_empty());
                    LevelSummary {
                        level,
                        reached: storages.iter().flatten().count(),
                        median_storage_bytes: median_storage(&storages),
                        worst_storage_bytes: worst.map(|w| w.0),
                        worst_material: worst.map(|w| w.1.material.clone()),
                    }
                })
                .collect();
            let counted = at(count_level);
            let within = COUNT_BOUNDS
                .iter()
                .map(|&bound| {
                    let n = counted
                        .iter()
                        .filter(|r| r.reached && r.storage_bytes.is_some_and(|s| s <= bound))
                        .count();
                    (bound, n)
                })
                .collect();
            // The default point is on every row of a material.
            let mut defaults: Vec<(&str, f64)> = mine
                .iter()
                .map(|r| (r.material.as_str(), r.default_relative_efficiency))
                .collect();
            defaults.sort_by(|a, b| a.0.cmp(b.0));
            defaults.dedup_by(|a, b| a.0 == b.0);
            FamilySummary {
                family: family.clone(),
                materials: materials.len(),
                levels: level_rows,
                count_level,
                within,
                at_default: defaults.iter().filter(|d| d.1 >= count_level).count(),
            }
        })
        .collect()
}

/// Bytes as the summary prints them: with thousands separators.
fn bytes(b: f64) -> String {
    let s = format!("{}", b.round() as u64);
    let mut out = String::new();
    for (k, c) in s.chars().enumerate() {
        if k > 0 && (s.len() - k) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// The summary as a Markdown table: per family, median and worst storage
/// (bytes) at each level ("-" where not reached), and the counts.
pub fn format_frontier(summary: &[FamilySummary]) -> String {
    let Some(first) = summary.first() else {
        return String::new();
    };
    let mut head = "| family |".to_string();
    let mut rule = "|:--|".to_string();
    for l in &first.levels {
        head.push_str(&format!(" ≥ {}: median, worst |", l.level));
        rule.push_str("--:|");
    }
    for (bound, _) in &first.within {
        head.push_str(&format!(
            " ≥ {} in ≤ {} B |",
            first.count_level,
            bytes(*bound as f64)
        ));
        rule.push_str("--:|");
    }
    head.push_str(&format!(" ≥ {} at the default |\n", first.count_level));
    rule.push_str("--:|\n");
    let mut out = head + &rule;
    for s in summary {
        out.push_str(&format!("| {} |", s.family));
        for l in &s.levels {
            let median = l.median_storage_bytes.map_or("-".into(), bytes);
            let worst = match (l.worst_storage_bytes, &l.worst_material) {
                (Some(w), Some(m)) => format!("{} ({m})", bytes(w as f64)),
                _ => format!("- ({}/{} reach)", l.reached, s.materials),
            };
            out.push_str(&format!(" {median}, {worst} |"));
        }
        for (_, n) in &s.within {
            out.push_str(&format!(" {n}/{} |", s.materials));
        }
        out.push_str(&format!(" {}/{} |\n", s.at_default, s.materials));
    }
    out
}

/// The CSV header of [`write_frontier_csv`].
pub const FRONTIER_CSV_HEADER: &str = "material,family,level,reached,storage_bytes,\
relative_efficiency,tolerance,default_storage_bytes,default_relative_efficiency,candidates";

/// Write the rows as CSV (empty fields where a level is not reached).
pub fn write_frontier_csv(rows: &[FrontierRow], out: &mut impl Write) -> std::io::Result<()> {
    let o = |x: Option<f64>| x.map(|v| format!("{v}")).unwrap_or_default();
    writeln!(out, "{FRONTIER_CSV_HEADER}")?;
    for r in rows {
        writeln!(
            out,
            "{},{},{},{},{},{},{},{},{},{}",
            r.material,
            r.family,
            r.level,
            r.reached,
            r.storage_bytes.map(|s| s.to_string()).unwrap_or_default(),
            o(r.relative_efficiency),
            o(r.tolerance),
            r.default_storage_bytes,
            r.default_relative_efficiency,
            r.candidates,
        )?;
    }
    Ok(())
}

/// The frontier's figure: storage (x, bytes) against the level of the
/// reference's efficiency (y), one curve per family with tables, in two
/// panels: the median material and the worst. A family without tables
/// (storage 0) is a note; a level not reached is left out of its curve
/// (a family with no level left is a note in that panel).
pub fn plot_frontier(
    summary: &[FamilySummary],
    title: &str,
    name: &Path,
) -> Result<(String, Vec<u8>)> {
    let panel = |worst: bool| {
        let mut series = Vec::new();
        let mut notes = Vec::new();
        for s in summary {
            let points: Vec<(f64, f64)> = s
                .levels
                .iter()
                .filter_map(|l| {
                    let storage = if worst {
                        l.worst_storage_bytes.map(|b| b as f64)
                    } else {
                        l.median_storage_bytes
                    };
                    Some((storage?, l.level))
                })
                .collect();
            // A family keeps its place (and colour) in both panels if it
            // has tables anywhere; one without is a note.
            let has_tables = s.levels.iter().any(|l| {
                l.median_storage_bytes.is_some_and(|b| b > 0.0)
                    || l.worst_storage_bytes.is_some_and(|b| b > 0)
            });
            if !has_tables {
                let top = points.iter().map(|p| p.1).reduce(f64::max);
                notes.push(match top {
                    Some(l) => format!("{} (no tables): reaches {l}", s.family),
                    None => format!("{}: reaches no level", s.family),
                });
                continue;
            }
            if points.is_empty() {
                notes.push(format!("{}: no level reached on every material", s.family));
            }
            series.push(Series {
                label: s.family.clone(),
                points,
                style: Style::Line,
            });
        }
        Panel {
            x_label: format!(
                "storage (bytes), {} material",
                if worst { "worst" } else { "median" }
            ),
            y_label: "efficiency relative to the reference".into(),
            series,
            markers: Vec::<Marker>::new(),
            notes,
            legend: !worst,
        }
    };
    let figure = Figure {
        title: title.to_string(),
        panels: vec![panel(false), panel(true)],
    };
    figure_bytes(&figure, name)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn point(storage: usize, e: f64) -> Point {
        Point {
            tolerance: Some(storage as f64),
            storage_bytes: storage,
            relative_efficiency: e,
        }
    }

    /// The frontier at a level is the least storage among the points that
    /// reach it, so it never shrinks as the level rises.
    #[test]
    fn rows_take_the_least_storage_that_reaches() {
        let points = [
            point(100, 0.7),
            point(400, 1.1),
            point(50, 0.4),
            point(300, 0.9),
        ];
        let rows = rows_from_points("m", "f", &[0.5, 0.8, 1.0, 2.0], &points, points[0]);
        let s: Vec<Option<usize>> = rows.iter().map(|r| r.storage_bytes).collect();
        assert_eq!(s, [Some(100), Some(300), Some(400), None]);
        assert!(!rows[3].reached && rows[2].reached);
        assert_eq!(rows[1].relative_efficiency, Some(0.9));
        assert!(rows
            .iter()
            .all(|r| r.default_storage_bytes == 100 && r.candidates == 4));
    }

    fn row(
        material: &str,
        family: &str,
        level: f64,
        storage: Option<usize>,
        default_e: f64,
    ) -> FrontierRow {
        FrontierRow {
            material: material.into(),
            family: family.into(),
            level,
            reached: storage.is_some(),
            storage_bytes: storage,
            relative_efficiency: storage.map(|_| level),
            tolerance: None,
            default_storage_bytes: 9999,
            default_relative_efficiency: default_e,
            candidates: 3,
        }
    }

    /// Median and worst over every material (a material that does not
    /// reach a level counting as infinite storage), and the counts within
    /// 1,024 and 4,096 bytes and at the default.
    #[test]
    fn summary_of_made_up_rows() {
        let rows = [
            row("a", "f", 0.5, Some(100), 1.2),
            row("a", "f", 0.95, Some(900), 1.2),
            row("b", "f", 0.5, Some(300), 0.9),
            row("b", "f", 0.95, Some(5000), 0.9),
            row("c", "f", 0.5, Some(200), 0.96),
            row("c", "f", 0.95, Some(2000), 0.96),
            row("a", "g", 0.5, Some(10), 0.6),
            row("a", "g", 0.95, None, 0.6),
            row("b", "g", 0.5, None, 0.1),
            row("b", "g", 0.95, None, 0.1),
        ];
        let families = ["f".to_string(), "g".to_string()];
        let s = summarize_frontier(&rows, &families, &[0.5, 0.95], 0.95);
        let f = &s[0];
        assert_eq!(f.materials, 3);
        assert_eq!(f.levels[0].median_storage_bytes, Some(200.0));
        assert_eq!(f.levels[0].worst_storage_bytes, Some(300));
        assert_eq!(f.levels[1].median_storage_bytes, Some(2000.0));
        assert_eq!(f.levels[1].worst_storage_bytes, Some(5000));
        assert_eq!(f.levels[1].worst_material.as_deref(), Some("b"));
        assert_eq!(f.within, [(1024, 1), (4096, 2)]);
        assert_eq!(f.at_default, 2);
        let g = &s[1];
        assert_eq!(g.materials, 2);
        // 10 and infinity: the median is infinite, the worst not reached.
        assert_eq!(g.levels[0].median_storage_bytes, None);
        assert_eq!(g.levels[0].worst_storage_bytes, None);
        assert_eq!(g.levels[0].reached, 1);
        assert_eq!(g.levels[1].reached, 0);
        assert_eq!(g.within, [(1024, 0), (4096, 0)]);
        assert_eq!(g.at_default, 0);
        let table = format_frontier(&s);
        assert_eq!(table.lines().count(), 4, "{table}");
        assert!(
            table.contains("| f | 200, 300 (b) | 2,000, 5,000 (b) | 1/3 | 2/3 | 2/3 |"),
            "{table}"
        );
        assert!(
            table.contains("| g | -, - (1/2 reach) | -, - (0/2 reach) | 0/2 | 0/2 | 0/2 |"),
            "{table}"
        );
        let mut csv = Vec::new();
        write_frontier_csv(&rows, &mut csv).unwrap();
        let csv = String::from_utf8(csv).unwrap();
        assert_eq!(csv.lines().next(), Some(FRONTIER_CSV_HEADER));
        assert!(csv.contains("\nb,g,0.5,false,,,,9999,0.1,3\n"), "{csv}");
    }

    #[test]
    fn levels_are_checked_and_sorted() {
        assert_eq!(
            check_levels(&[2.0, 0.5, 0.95, 0.5]).unwrap(),
            [0.5, 0.95, 2.0]
        );
        assert!(check_levels(&[]).is_err());
        assert!(check_levels(&[0.5, f64::NAN]).is_err());
        assert!(check_levels(&[-1.0]).is_err());
    }
}
