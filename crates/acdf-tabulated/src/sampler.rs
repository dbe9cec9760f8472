//! The tabulated measured-BRDF sampler: one half-vector distribution per
//! outgoing cell, built on first use.

use crate::tabulate::{phi_o_cell, tabulate_slice, unit_cell, HalfMap};
use crate::{Resolution, SliceBuilder, SliceDistribution};
use acdf_core::fast::{fast_atan2, sin_cos_turns};
use acdf_core::geometry::{reflect_given_dot, sin_theta, wrap_angle};
use acdf_core::search::{count_linear, count_sorted, LINEAR_ROW, SHORT_WINDOW};
use acdf_core::simd::Avx2;
use acdf_core::warp::{cosine_hemisphere_pdf, square_to_cosine_hemisphere};
use acdf_core::{
    clamp_unit, is_valid_outgoing, Brdf, BxdfSample, BxdfSampler, Distribution2D, Error, Result,
    Sample2D, Vec2, Vec3, ONE_MINUS_EPSILON,
};
use rayon::prelude::*;
use std::f32::consts::TAU;
use std::sync::{Arc, OnceLock};

/// Importance sampling of a BRDF from tabulated half-vector distributions.
///
/// For the outgoing cell of `wo` (see [`tabulate`](crate::tabulate)) a 2D
/// distribution over (x, v) ∈ [0, 1)^2 is drawn from, giving the half vector
/// φ_h = 2π x (+ φ_o for a relative slice), θ_h = (π/2) v² (equal solid
/// angle in the first row, see [`HalfMap`]), and wi = reflect(wo, h). Its
/// solid-angle density is p(wi) = p_xv(x, v) / (J(v) · 4 (wo·h)), with
/// J(v) = (π v)(2π) sin θ_h = dω_h / (dx dv).
///
/// - **Isotropic slices.** When the material is isotropic and
///   `resolution.phi_o == 1`, there is one slice per θ_o cell, tabulated at
///   φ_o = 0, and φ_h is measured from φ_o of the actual `wo`. Otherwise all
///   `phi_o` slices are kept with absolute φ_h (the paper's configuration);
///   an anisotropic material with `phi_o == 1` is rejected by
///   [`new`](Self::new).
/// - **Lazy, thread-safe building.** A slice is tabulated and built the
///   first time a `wo` in its cell is seen ([`OnceLock`] per cell);
///   [`build_all`](Self::build_all) builds every slice in parallel.
/// - **Failures.** A slice whose BRDF is zero for every wi falls back to the
///   distribution's all-zero behaviour (uniform over (x, v) for the
///   uniform plug-in's piecewise-constant tables), so it still samples the
///   hemisphere. A slice whose build fails (impossible for the uniform
///   builder, since tabulated values are sanitised) samples nothing: `sample` gives `None` and the
///   table part of `pdf` is 0.
/// - **Cosine mixing.** With [`with_cosine_mix`](Self::with_cosine_mix)(a),
///   the density is (1 - a) p_table + a cos θ_i / π in both `sample` and
///   `pdf`.
/// - **Consistency.** `sample` reports `pdf(wo, wi)` of the returned wi to
///   5e-5 relative: from the drawn cell when the recomputed cell is
///   certainly of the same density (and the distribution can tell cheaply,
///   see [`SliceDistribution::same_cell_around`]), otherwise by the same routine as
///   `pdf`, which agrees exactly. A draw whose density comes out 0 or
///   non-finite (below the horizon, or a half vector whose recomputed cell
///   has zero density) is `None`.
/// - **Speed.** The half-vector maps use a polynomial arctangent
///   ([`fast_atan2`]) and a sine and cosine from a table of 64 angles and
///   short polynomials ([`sin_cos_turns`]), within a few 1e-7 rad and the
///   same in `sample` and `pdf`, and the θ_o cell is counted from cos θ_o
///   without an arctangent. One call is a chain of dependent steps (cell,
///   two searches, trigonometry, reflection); where the CPU has AVX2 it
///   runs a copy compiled for it. The batch entry points
///   overlap many draws instead: `sample_batch` and `pdf_batch` (one wo)
///   and `sample_each` and `pdf_each` (one wo per pair) search a chunk of
///   draws, then compute the geometry of the whole chunk as SIMD lanes (see
///   `sampler_batch.rs`), with results bit-identical to `sample` and `pdf`.
///   With cosine mixing, `sample_batch`, `sample_each` and `pdf_each` take
///   the one-at-a-time path.
///
/// # Examples
///
/// A sampler family is a [`TableBuilder`](acdf_core::TableBuilder) and the
/// [`SliceDistribution`] it builds. The plug-ins `acdf-uniform` and `acdf-adaptive` provide the
/// real ones (`UniformBrdfSampler`, `AdaptiveBrdfSampler`); this crate
/// depends on no plug-in, so the example brings the smallest family of its
/// own, a distribution uniform over the half-vector square, and samples a
/// Lambertian BRDF with it:
///
/// ```
/// use acdf_core::{
///     Brdf, BxdfSampler, Distribution2D, Result, Rgb, Sample2D, TableBuilder, Vec2, Vec3,
///     clamp_unit,
/// };
/// use acdf_tabulated::{Resolution, SliceDistribution, TabulatedBrdfSampler};
/// use std::sync::Arc;
///
/// /// Uniform over [0, 1)^2, whatever the table.
/// struct Flat;
///
/// impl Distribution2D for Flat {
///     fn sample(&self, u: Vec2) -> Sample2D {
///         Sample2D { p: Vec2::new(clamp_unit(u.x), clamp_unit(u.y)), pdf: 1.0 }
///     }
///     fn pdf(&self, p: Vec2) -> f32 {
///         let inside = (0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y);
///         if inside { 1.0 } else { 0.0 }
///     }
///     fn invert(&self, p: Vec2) -> Vec2 {
///         p.clamp(Vec2::ZERO, Vec2::ONE)
///     }
///     fn integral(&self) -> f64 {
///         1.0
///     }
///     fn storage_bytes(&self) -> usize {
///         0
///     }
/// }
///
/// // The sampler's fast paths are optional: the defaults are correct.
/// impl SliceDistribution for Flat {}
///
/// struct FlatBuilder;
///
/// impl TableBuilder for FlatBuilder {
///     type Dist = Flat;
///     fn name(&self) -> String {
///         "flat".into()
///     }
///     fn build(&self, _values: &[f32], _nx: usize, _ny: usize) -> Result<Flat> {
///         Ok(Flat)
///     }
/// }
///
/// struct Lambert;
///
/// impl Brdf for Lambert {
///     fn name(&self) -> &str {
///         "lambert"
///     }
///     fn eval(&self, wo: Vec3, wi: Vec3) -> Rgb {
///         let above = wo.z > 0.0 && wi.z > 0.0;
///         Rgb::splat(if above { 0.5 / std::f32::consts::PI } else { 0.0 })
///     }
///     fn is_isotropic(&self) -> bool {
///         true
///     }
/// }
///
/// let sampler = TabulatedBrdfSampler::new(Arc::new(Lambert), Resolution::ISOTROPIC, FlatBuilder)?;
/// assert_eq!(sampler.name(), "flat");
/// let wo = Vec3::new(0.6, 0.0, 0.8);
/// let s = sampler.sample(wo, Vec2::new(0.3, 0.2)).expect("a direction above the horizon");
/// assert!(s.wi.z > 0.0 && s.pdf > 0.0);
/// // `sample` reports the density `pdf` gives its direction.
/// let pdf = sampler.pdf(wo, s.wi);
/// assert!((pdf - s.pdf).abs() <= 1e-4 * pdf);
/// // Below the horizon there is nothing to sample.
/// assert_eq!(sampler.pdf(wo, Vec3::new(0.0, 0.6, -0.8)), 0.0);
/// # Ok::<(), acdf_core::Error>(())
/// ```
pub struct TabulatedBrdfSampler<B: SliceBuilder> {
    brdf: Arc<dyn Brdf>,
    resolution: Resolution,
    builder: B,
    name: String,
    relative_phi: bool,
    cosine_fraction: f32,
    half_map: HalfMap,
    theta_o_cells: ThetaOCells,
    /// Whether cells are wide enough for the drawn-cell shortcut of
    /// `sample` (at most 1 / (2 [`CELL_MARGIN`]) cells along each
    /// half-vector axis).
    shortcut_cells: bool,
    slices: Vec<OnceLock<Result<B::Dist>>>,
}

impl<B: SliceBuilder> TabulatedBrdfSampler<B> {
    /// A sampler of `brdf` at `resolution` whose slices `builder` makes.
    /// Errors: an invalid resolution; tables whose
    /// [`memory estimate`](Resolution::memory_estimate) exceeds the memory
    /// limit ([`acdf_io::limits`]); a material that is zero everywhere
    /// ([`Brdf::is_zero_everywhere`]: there is nothing to sample in
    /// proportion to); an anisotropic material with
    /// `resolution.phi_o == 1`.
    pub fn new(brdf: Arc<dyn Brdf>, resolution: Resolution, builder: B) -> Result<Self> {
        resolution.validate()?;
        acdf_io::limits::check_memory(
            &format!("the tables of a sampler at {resolution}"),
            resolution.memory_estimate(),
        )?;
        if brdf.is_zero_everywhere() {
            return Err(Error::ZeroMaterial {
                material: brdf.name().to_string(),
            });
        }
        let isotropic = brdf.is_isotropic();
        if !isotropic && resolution.phi_o == 1 {
            return Err(Error::InvalidParameter {
                name: "resolution",
                reason: format!(
                    "{resolution}: material `{}` is anisotropic and needs more than one phi_o cell",
                    brdf.name()
                ),
            });
        }
        let slices = (0..resolution.slices()).map(|_| OnceLock::new()).collect();
        Ok(TabulatedBrdfSampler {
            name: builder.name(),
            brdf,
            resolution,
            builder,
            relative_phi: resolution.phi_o == 1,
            cosine_fraction: 0.0,
            half_map: HalfMap::new(resolution.theta_h),
            theta_o_cells: ThetaOCells::new(resolution.theta_o),
            shortcut_cells: (resolution.phi_h as f32) * CELL_MARGIN.x <= 0.5
                && (resolution.theta_h as f32) * CELL_MARGIN.y <= 0.5,
            slices,
        })
    }

    /// A sampler whose every slice is already built (read from a file, see
    /// [`persist`](crate::persist)); `slices` are in the order of
    /// [`slice`](Self::slice) indices, θ_o-major. Errors as [`new`](Self::new),
    /// and for a slice count other than `resolution.slices()`.
    pub fn from_built_slices(
        brdf: Arc<dyn Brdf>,
        resolution: Resolution,
        builder: B,
        slices: Vec<B::Dist>,
    ) -> Result<Self> {
        let mut sampler = Self::new(brdf, resolution, builder)?;
        if slices.len() != sampler.slices.len() {
            return Err(Error::SizeMismatch {
                what: "built slices",
                expected: sampler.slices.len(),
                got: slices.len(),
            });
        }
        sampler.slices = slices.into_iter().map(|d| OnceLock::from(Ok(d))).collect();
        Ok(sampler)
    }

    /// Mix in the cosine lobe with probability `fraction` in [0, 1]:
    /// p = (1 - a) p_table + a cos θ_i / π. Errors for a fraction outside
    /// [0, 1] or NaN.
    pub fn with_cosine_mix(mut self, fraction: f32) -> Result<Self> {
        self.cosine_fraction = check_cosine_fraction(fraction)?;
        Ok(self)
    }

    /// The probability a of drawing from the cosine lobe.
    pub fn cosine_mix(&self) -> f32 {
        self.cosine_fraction
    }

    /// The tabulation resolution.
    pub fn resolution(&self) -> Resolution {
        self.resolution
    }

    /// The material sampled.
    pub fn brdf(&self) -> &Arc<dyn Brdf> {
        &self.brdf
    }

    /// The slice builder.
    pub fn builder(&self) -> &B {
        &self.builder
    }

    /// Whether φ_h is measured relative to φ_o (one φ_o slice).
    pub fn is_relative_phi(&self) -> bool {
        self.relative_phi
    }

    /// Build every slice now, in parallel; the first build error, if any.
    pub fn build_all(&self) -> Result<()> {
        (0..self.slices.len())
            .into_par_iter()
            .try_for_each(|index| self.slice_at(index).map(|_| ()).map_err(Clone::clone))
    }

    /// The slices built so far (those that built successfully).
    pub fn built_slices(&self) -> impl Iterator<Item = &B::Dist> {
        self.slices
            .iter()
            .filter_map(|s| s.get().and_then(|r| r.as_ref().ok()))
    }

    /// The distribution of slice (θ_o cell, φ_o cell), building it if
    /// needed; `None` for indices out of range, the build error if it failed.
    pub fn slice(&self, theta_o_index: usize, phi_o_index: usize) -> Option<Result<&B::Dist>> {
        if theta_o_index >= self.resolution.theta_o || phi_o_index >= self.resolution.phi_o {
            return None;
        }
        let index = theta_o_index * self.resolution.phi_o + phi_o_index;
        Some(self.slice_at(index).map_err(Clone::clone))
    }

    fn slice_at(&self, index: usize) -> std::result::Result<&B::Dist, &Error> {
        self.slices[index]
            .get_or_init(|| {
                let res = &self.resolution;
                let (i, j) = (index / res.phi_o, index % res.phi_o);
                let values = tabulate_slice(&*self.brdf, res, i, j);
                self.builder.build_slice(&values, res.phi_h, res.theta_h)
            })
            .as_ref()
    }

    /// The slice for a valid `wo`, with the rotation that carries its
    /// half-vector axis to the world: by φ_o for relative slices, none for
    /// absolute ones.
    #[inline(always)]
    fn slice_for(&self, wo: Vec3) -> Option<Slice<'_, B::Dist>> {
        let res = &self.resolution;
        let sin_o = sin_theta(wo);
        let i = self.theta_o_cells.cell(wo.z);
        let (j, rotation) = if self.relative_phi {
            // (cos φ_o, sin φ_o) without trigonometry; φ_o = 0 on the pole.
            let rotation = if sin_o > 0.0 {
                Vec2::new(wo.x, wo.y) * (1.0 / sin_o)
            } else {
                Vec2::X
            };
            (0, rotation)
        } else {
            (phi_o_cell(azimuth(wo), res.phi_o), Vec2::X)
        };
        self.slice_at(i * res.phi_o + j).ok().map(|dist| Slice {
            dist,
            rotation,
            map: self.half_map,
        })
    }

    /// The table part of the density, p_xv(x, v) / (J(v) · 4 (wo·h)), for a
    /// valid wo and any wi; 0 where it cannot be drawn or is not finite.
    #[inline(always)]
    fn table_pdf(slice: &Slice<'_, B::Dist>, wo: Vec3, wi: Vec3) -> f32 {
        slice.coordinates_of(wo, wi).table_pdf(slice.dist)
    }

    /// The slice of a valid wo, unless the pure cosine lobe needs none (then
    /// none is built).
    #[inline]
    fn slice_for_mix(&self, wo: Vec3) -> Option<Slice<'_, B::Dist>> {
        if self.cosine_fraction < 1.0 {
            self.slice_for(wo)
        } else {
            None
        }
    }

    /// With probability a (decided by u.x, then rescaled to [0, 1)) a cosine
    /// draw, otherwise a table draw of (x, v) and wi = reflect(wo, h); the
    /// reported density is the mixed pdf at the returned wi, so it equals
    /// `pdf(wo, wi)` exactly. `wo` must be valid.
    #[inline(always)]
    fn sample_in(
        &self,
        slice: Option<&Slice<'_, B::Dist>>,
        wo: Vec3,
        u: Vec2,
    ) -> Option<BxdfSample> {
        let a = self.cosine_fraction;
        if a == 0.0 {
            // The distribution clamps u itself.
            let slice = slice?;
            let (s, same_cell) = slice.dist.sample_and_same_cell(u, CELL_MARGIN);
            let draw = slice.draw(wo, s);
            return self.finish_draw_with(
                &draw,
                || same_cell,
                || self.pdf_in(Some(slice), wo, draw.wi),
            );
        }
        let u = Vec2::new(clamp_unit(u.x), clamp_unit(u.y));
        let wi = if u.x < a {
            square_to_cosine_hemisphere(Vec2::new(clamp_unit(u.x / a), u.y))
        } else {
            let slice = slice?;
            let ux = if a > 0.0 {
                clamp_unit((u.x - a) / (1.0 - a))
            } else {
                u.x
            };
            let s = slice.dist.sample(Vec2::new(ux, u.y));
            return self.finish_table_draw(slice, wo, s);
        };
        let pdf = self.pdf_in(slice, wo, wi);
        (pdf > 0.0).then_some(BxdfSample { wi, pdf })
    }

    /// The sample for a table draw s = (x, v) with density p_xv: wi =
    /// reflect(wo, h(x, v)) and the mixed density at wi, equal to
    /// `pdf(wo, wi)` to 5e-5 relative.
    ///
    /// `pdf(wo, wi)` recovers (x', v') from wi, which costs a normalisation,
    /// two arctangents and a table lookup. When (x', v') is certainly in a
    /// cell of the same density as (x, v), the table part is instead
    /// p_xv / (J(v) · 4 (wo·h)) with the drawn h. The recomputed
    /// h' = normalise(wi + wo) differs from h by the rounding of reflect,
    /// add and normalise: wi + wo = 2 (wo·h) h is found to a few 1e-8
    /// absolute, so h' is within about 6e-8 / (wo·h) of h, wo·h' is within
    /// 6e-8 / (wo·h)² relative of wo·h, θ_h' within 6e-8 / ((wo·h) sin θ_h)
    /// relative of θ_h, and φ_h' within 6e-8 / ((wo·h) sin θ_h) radians of
    /// φ_h. The shortcut is taken when wo·h >= 1/8 and (wo·h) sin θ_h >=
    /// 1/512, outside the polar cap row: the relative errors are then under
    /// 3.9e-6 for wo·h and 3.1e-5 for θ_h, so J, which goes as θ_h^1.5 near
    /// the pole, and wo·h, hence the density, agree to 5e-5 (the worst seen
    /// in 8 million draws of nickel and near-mirror at the isotropic
    /// resolution, θ_o from 1° to 89°, was 4.6e-5; the conformance battery
    /// allows 1e-4). It is also required that the slice's density be
    /// constant over the box of half-widths [`CELL_MARGIN`] around the draw:
    /// x' is within 6e-8 · 512 / 2π < 4.9e-6 of x, and v' within 4.2e-6 of
    /// v (counting the arctangent's 4e-7 radians in full, with v at least
    /// 0.035 where θ_h >= 1/512). Otherwise, and for tabulations finer than
    /// the margins allow, the density is recomputed exactly as `pdf` does.
    ///
    /// Why 1/512 for (wo·h) sin θ_h: a bound of 1/128 keeps the density
    /// within 2e-5, but on the specular built-in nickel 6.4% of the draws
    /// fall below it and take the recomputation, against 0.5% below 1/512.
    /// The recomputation (a normalisation, two arctangents and a lookup) is
    /// the slow path of a draw, so the lower bound keeps nearly every draw
    /// on the shortcut while staying inside the battery's 1e-4.
    #[inline(always)]
    fn finish_table_draw(
        &self,
        slice: &Slice<'_, B::Dist>,
        wo: Vec3,
        s: Sample2D,
    ) -> Option<BxdfSample> {
        self.finish_draw(slice, wo, s, &slice.draw(wo, s))
    }

    /// The second half of [`finish_table_draw`](Self::finish_table_draw)
    /// once `draw` = `slice.draw(wo, s)` is known; the batch path computes
    /// the draws of a chunk together and ends each one here.
    #[inline(always)]
    fn finish_draw(
        &self,
        slice: &Slice<'_, B::Dist>,
        wo: Vec3,
        s: Sample2D,
        draw: &TableDraw,
    ) -> Option<BxdfSample> {
        self.finish_draw_with(
            draw,
            // Inlined so that the box test, taken by most draws, is
            // compiled with the caller's target features (AVX2 in the
            // AVX2 instance of `dispatch!`); the exact density, the rare path, stays out
            // of line.
            #[inline(always)]
            || slice.dist.same_cell_around(s.p, CELL_MARGIN),
            || self.pdf_in(Some(slice), wo, draw.wi),
        )
    }

    /// [`finish_draw`](Self::finish_draw) with the builder's box test of
    /// the draw supplied by `same_cell` and the exact density of `draw.wi`,
    /// `pdf(wo, wi)`, by `exact` (each called only when needed).
    #[inline(always)]
    fn finish_draw_with(
        &self,
        draw: &TableDraw,
        same_cell: impl FnOnce() -> bool,
        exact: impl FnOnce() -> f32,
    ) -> Option<BxdfSample> {
        let wi = draw.wi;
        if !(wi.z > 0.0) {
            return None;
        }
        let shortcut = self.shortcut_cells && draw.shortcut_geometry && same_cell();
        // A cell density that is positive and finite (a denominator at or
        // below zero makes it negative or infinite); anything else takes
        // the exact density.
        let usable = is_positive_finite(draw.table);
        let pdf = if shortcut && usable {
            mix_with_cosine(self.cosine_fraction, draw.table, wi)
        } else {
            exact()
        };
        (pdf > 0.0).then_some(BxdfSample { wi, pdf })
    }

    /// The mixed density for a valid wo; 0 for a non-finite wi or one at or
    /// below the horizon.
    #[inline(always)]
    fn pdf_in(&self, slice: Option<&Slice<'_, B::Dist>>, wo: Vec3, wi: Vec3) -> f32 {
        if !wi.is_finite() || !(wi.z > 0.0) {
            return 0.0;
        }
        self.mixed_pdf(slice, wo, wi)
    }

    /// The mixed density (1 - a) p_table + a cos θ_i / π for a valid wo.
    #[inline(always)]
    fn mixed_pdf(&self, slice: Option<&Slice<'_, B::Dist>>, wo: Vec3, wi: Vec3) -> f32 {
        let a = self.cosine_fraction;
        let table = match slice {
            Some(slice) if a < 1.0 => Self::table_pdf(slice, wo, wi),
            _ => 0.0,
        };
        mix_with_cosine(self.cosine_fraction, table, wi)
    }
}

impl<B: SliceBuilder> TabulatedBrdfSampler<B> {
    /// [`BxdfSampler::sample`] itself.
    #[inline(always)]
    fn sample_one(&self, wo: Vec3, u: Vec2, _: Option<Avx2>) -> Option<BxdfSample> {
        if !is_valid_outgoing(wo) {
            return None;
        }
        self.sample_in(self.slice_for_mix(wo).as_ref(), wo, u)
    }

    /// [`BxdfSampler::pdf`] itself.
    #[inline(always)]
    fn pdf_one(&self, wo: Vec3, wi: Vec3, _: Option<Avx2>) -> f32 {
        if !is_valid_outgoing(wo) {
            return 0.0;
        }
        self.pdf_in(self.slice_for_mix(wo).as_ref(), wo, wi)
    }
}

/// The density of a sampler that draws from a cosine lobe with
/// probability `a` and from its tables otherwise: (1 - a) table +
/// a cos θ_i / π, 0 if not finite. Without a cosine lobe the table density
/// is the density, with no multiply and add on the chain of every draw.
#[inline(always)]
pub fn mix_with_cosine(a: f32, table: f32, wi: Vec3) -> f32 {
    let p = if a > 0.0 {
        (1.0 - a) * table + a * cosine_hemisphere_pdf(wi)
    } else {
        table
    };
    if p.is_finite() {
        p
    } else {
        0.0
    }
}

/// `fraction` if it is a probability of drawing from the cosine lobe (in
/// [0, 1]); an error naming it otherwise (NaN included). Shared by every
/// sampler that mixes in the cosine lobe.
pub fn check_cosine_fraction(fraction: f32) -> Result<f32> {
    if (0.0..=1.0).contains(&fraction) {
        Ok(fraction)
    } else {
        Err(Error::InvalidParameter {
            name: "cosine fraction",
            reason: format!("{fraction} is not in [0, 1]"),
        })
    }
}

/// The θ_o cell of an outgoing direction found from cos θ_o = wo.z alone.
///
/// Cell i covers θ_o in [θ_i, θ_{i+1}) with θ_i = (π/2)(i/n)² (see
/// [`tabulate`](crate::tabulate)), so the cell is the number of inner
/// boundaries with z <= cos θ_i, i = 1..n-1. Counting compares z with a
/// fixed table (stored as -cos θ_i, increasing, padded to a multiple of 8
/// with +∞) instead of computing θ_o = atan2(sin θ_o, z) and a square root:
/// the cell, and with it the address of the slice, is known a few cycles
/// after wo, which shortens the chain of dependent operations every
/// `sample` and `pdf` starts with. It agrees with
/// [`theta_o_cell`](crate::tabulate::theta_o_cell) except within an ulp or
/// two of a boundary. NaN gives cell 0.
#[derive(Debug, Clone)]
struct ThetaOCells {
    negative_cos_bounds: Vec<f32>,
}

impl ThetaOCells {
    fn new(n_theta_o: usize) -> Self {
        let n = n_theta_o.max(1);
        let mut negative_cos_bounds: Vec<f32> = (1..n)
            .map(|i| {
                let u = i as f64 / n as f64;
                -(std::f64::consts::FRAC_PI_2 * u * u).cos() as f32
            })
            .collect();
        let padded = negative_cos_bounds.len().div_ceil(SHORT_WINDOW).max(1) * SHORT_WINDOW;
        negative_cos_bounds.resize(padded, f32::INFINITY);
        ThetaOCells {
            negative_cos_bounds,
        }
    }

    /// The bounds -cos θ at the cell edges, ascending, padded with +∞ to a
    /// multiple of eight.
    pub(crate) fn bounds(&self) -> &[f32] {
        &self.negative_cos_bounds
    }

    /// The cell of cos θ_o = z, in [0, n).
    ///
    /// The slice, and so every table read of a draw, waits for this count.
    /// At 32 θ_o cells the bounds fill one window of
    /// [`acdf_core::search::count_window`], compared all at once: one load,
    /// one compare and a mask stand between wo and the slice, where the
    /// two-level [`count_linear`] chains two loads and two compares.
    #[inline(always)]
    fn cell(&self, z: f32) -> usize {
        // -NaN compares false with everything: cell 0.
        let bounds = &self.negative_cos_bounds;
        if bounds.len() == acdf_core::search::WINDOW {
            acdf_core::search::count_window(bounds, 0, bounds.len(), -z)
        } else if bounds.len() <= LINEAR_ROW {
            count_linear(bounds, -z)
        } else {
            count_sorted(bounds, -z)
        }
    }
}

/// The half-widths (x, v), in unit coordinates, of the box around a draw
/// over which the slice density must be constant for the drawn-cell
/// shortcut of `sample`: 2^-15 along x and 2^-16 along v, over six and
/// three and a half times the bounds on the error of the recomputed x' and
/// v' (see `finish_table_draw`), and small enough that tabulations of up
/// to 2^14 cells along φ_h and 2^15 along θ_h can use it. A draw fails the
/// box test with probability about 2 (n_x m_x + n_v m_v): 1% at 32 x 256
/// cells.
const CELL_MARGIN: Vec2 = Vec2::new(1.0 / 32768.0, 1.0 / 65536.0);

/// Draws per chunk of the batch path of `sample_batch`: large enough to
/// amortise the call, small enough for the stack.
const BATCH_CHUNK: usize = 64;

/// A slice's distribution and the rotation (cos φ, sin φ) about the normal
/// from its half-vector axes to the shading frame.
struct Slice<'a, D> {
    dist: &'a D,
    rotation: Vec2,
    map: HalfMap,
}

impl<D> Slice<'_, D> {
    /// The slice's maps, by value.
    #[inline(always)]
    fn geometry(&self) -> SliceGeometry {
        SliceGeometry {
            rotation: self.rotation,
            map: self.map,
        }
    }

    /// See [`SliceGeometry::draw`].
    #[inline(always)]
    fn draw(&self, wo: Vec3, s: Sample2D) -> TableDraw {
        self.geometry().draw(wo, s)
    }

    /// See [`SliceGeometry::coordinates_of`].
    #[inline(always)]
    fn coordinates_of(&self, wo: Vec3, wi: Vec3) -> TableCoordinates {
        self.geometry().coordinates_of(wo, wi)
    }
}

/// The maps between a slice's table coordinates and the shading frame.
#[derive(Debug, Clone, Copy)]
struct SliceGeometry {
    rotation: Vec2,
    map: HalfMap,
}

impl SliceGeometry {
    /// ((sin, cos) θ_h, (sin, cos) φ_h) of the table sample p = (x, v):
    /// (θ_h, φ_h) = ((π/2) v², 2π x) in the slice's axes (outside the
    /// polar cap row).
    #[inline(always)]
    fn angles_of(&self, p: Vec2) -> Angles {
        (self.map.angles(p.y), sin_cos_turns(p.x))
    }

    /// The slice-axes vector `v` in the shading frame (the rotation).
    #[inline(always)]
    fn to_shading(self, v: Vec3) -> Vec3 {
        let r = self.rotation;
        Vec3::new(r.x * v.x - r.y * v.y, r.y * v.x + r.x * v.y, v.z)
    }

    /// The shading-frame vector `h` in the slice's axes (the inverse
    /// rotation).
    #[inline(always)]
    fn to_slice(self, h: Vec3) -> Vec3 {
        let r = self.rotation;
        Vec3::new(r.x * h.x + r.y * h.y, r.x * h.y - r.y * h.x, h.z)
    }

    /// The direction of the table draw `s` and the density its cell gives
    /// it (see `finish_table_draw`). The batch paths compute the angles of
    /// a chunk of draws together (`AngleLanes` in `sampler_batch.rs`), then
    /// the rest as here, in [`draw_from_angles`](Self::draw_from_angles),
    /// which is free of branches so that their loop compiles to SIMD.
    #[inline(always)]
    fn draw(&self, wo: Vec3, s: Sample2D) -> TableDraw {
        self.draw_from_angles(wo, s, self.angles_of(s.p))
    }

    /// [`draw`](Self::draw) once the half vector's angles are known.
    ///
    /// wo·h is formed in the slice's axes, where wo's coordinates are known
    /// long before the draw's angles, so that it waits for one product of
    /// sines less than the dot product with the rotated h; the reflection
    /// then needs no normalisation of its own (see [`unit_reflection`]).
    /// Both shorten the chain that every `sample` ends with, which is what
    /// a call one at a time waits for.
    #[inline(always)]
    fn draw_from_angles(&self, wo: Vec3, s: Sample2D, angles: Angles) -> TableDraw {
        let ((sin_h, cos_h), (sin_p, cos_p)) = angles;
        let local = Vec3::new(sin_h * cos_p, sin_h * sin_p, cos_h);
        let h = self.to_shading(local);
        let wo_h = self.to_slice(wo).dot(local);
        let wi = unit_reflection(wo, h, wo_h);
        let denominator = self.map.jacobian(s.p.y, sin_h) * 4.0 * wo_h;
        // `&` rather than `&&`: no short-circuit branches.
        let shortcut_geometry =
            (wo_h >= 0.125) & (wo_h * sin_h >= 1.0 / 512.0) & (s.p.y >= self.map.cap_top());
        TableDraw {
            wi,
            table: s.pdf / denominator,
            shortcut_geometry,
        }
    }

    /// The table coordinates of wi and the Jacobian factor of its density
    /// (see [`TableCoordinates`]); free of branches like [`draw`](Self::draw).
    ///
    /// The half vector is the sum wi + wo scaled to unit length, but its
    /// angles, two arctangents, need no scale: they are taken from the sum
    /// itself, so they do not wait for the square root and division of the
    /// normalisation, which only sin θ_h and wo·h use, beside them. That
    /// takes the square root and the division off the chain of every `pdf`
    /// call, as [`draw_from_angles`](Self::draw_from_angles) does for
    /// `sample`.
    ///
    /// wo·h is |wo + wi| / 2 (for unit wo and wi, wo·(wo + wi) = 1 + wo·wi
    /// = |wo + wi|² / 2), not the dot product of wo with the normalised sum:
    /// where wo + wi nearly cancels (grazing wo, wi near the horizon on the
    /// other side) the dot product is a difference of nearly equal terms
    /// and keeps few of its digits, so one ulp of wi could move the density
    /// by orders of magnitude, whereas the length keeps its relative
    /// precision.
    #[inline(always)]
    fn coordinates_of(&self, wo: Vec3, wi: Vec3) -> TableCoordinates {
        let sum = wi + wo;
        let length_squared = sum.length_squared();
        let defined = (wi.z > 0.0) & (length_squared > 1e-20) & length_squared.is_finite();
        let scale = length_squared.sqrt().recip();
        let rho = sin_theta(sum);
        let sin_h = rho * scale;
        let wo_h = 0.5 * length_squared * scale;
        let v = self.map.v_of(rho, sum.z, scale).min(ONE_MINUS_EPSILON);
        let x = unit_azimuth(self.to_slice(sum));
        TableCoordinates {
            p: Vec2::new(x, v),
            denominator: self.map.jacobian(v, sin_h) * 4.0 * wo_h,
            defined,
        }
    }
}

/// A table draw carried to the shading frame.
#[derive(Debug, Clone, Copy, Default)]
struct TableDraw {
    /// wi = reflect(wo, h), unit length.
    wi: Vec3,
    /// The drawn cell's density over solid angle, p_xv / (J(v) · 4 (wo·h)).
    table: f32,
    /// Whether wo·h and θ_h are far enough from 0 (and v outside the cap
    /// row) for `table` to stand for `pdf(wo, wi)`, given that the slice
    /// density is constant around the draw.
    shortcut_geometry: bool,
}

/// Where `pdf` looks a wi up: the table point (x, v) of its half vector and
/// J(v) · 4 (wo·h).
#[derive(Debug, Clone, Copy, Default)]
struct TableCoordinates {
    p: Vec2,
    denominator: f32,
    /// wi above the horizon and its half vector defined (wi ≠ -wo).
    defined: bool,
}

impl TableCoordinates {
    /// p_xv(p) / denominator, 0 where undefined or not finite.
    #[inline(always)]
    fn table_pdf(&self, dist: &impl Distribution2D) -> f32 {
        if !self.has_density() {
            return 0.0;
        }
        self.table_pdf_from(dist.pdf(self.p))
    }

    /// Whether the point has a density over wi at all (defined, and a
    /// positive denominator).
    #[inline(always)]
    fn has_density(&self) -> bool {
        self.defined && self.denominator > 0.0
    }

    /// [`table_pdf`](Self::table_pdf) given p_xv(p) (looked up in a batch).
    #[inline(always)]
    pub(crate) fn table_pdf_from(&self, p_xv: f32) -> f32 {
        if !self.has_density() {
            return 0.0;
        }
        let p = p_xv / self.denominator;
        if p.is_finite() {
            p
        } else {
            0.0
        }
    }
}

/// reflect(wo, h) = 2 (wo·h) h - wo scaled to unit length, given wo·h.
///
/// For unit h, |reflect(wo, h)| = |wo|, so the scale is 1 / |wo|, known
/// from wo alone: one Newton step from 1, (3 - |wo|²) / 2, leaves an error
/// of order (|wo|² - 1)², and it is ready long before h. The draw's h is
/// unit to a few ulps (its sines and cosines are), which leaves wi within
/// about 1e-6 of unit length (`sampled_directions_are_unit`). A wo far
/// from unit length (|wo|² off by 1e-3 or more) takes the full
/// normalisation of the reflection instead (zero for a degenerate result).
///
/// The full normalisation is computed only on its branch, which depends on
/// wo alone: a select would make every call wait for its square root and
/// division, whereas the branch, whose outcome is known as soon as wo is
/// and is the same on nearly every call, is predicted and costs a draw
/// nothing. In the batch loops the compiler still turns the branch into a
/// select, so they vectorise as before.
#[inline(always)]
pub fn unit_reflection(wo: Vec3, h: Vec3, wo_h: f32) -> Vec3 {
    let w = reflect_given_dot(wo, h, wo_h);
    let wo_length_squared = wo.length_squared();
    if (wo_length_squared - 1.0).abs() < 1e-3 {
        w * (1.5 - 0.5 * wo_length_squared)
    } else {
        let full = w * w.length_squared().sqrt().recip();
        if full.is_finite() {
            full
        } else {
            Vec3::ZERO
        }
    }
}

/// ((sin, cos) θ_h, (sin, cos) φ_h) of a half vector in a slice's axes.
type Angles = ((f32, f32), (f32, f32));

/// Whether `v` is positive (not zero) and finite: its bit pattern, less
/// one, is below that of the largest finite `f32` (zero wraps around,
/// negative values, infinity and NaN are above). Written as the two
/// compares `v > 0.0 && v < ∞`, the compiler turned it into a longer
/// classification of the bits on every draw; this is one subtraction and
/// one compare.
#[inline(always)]
fn is_positive_finite(v: f32) -> bool {
    v.to_bits().wrapping_sub(1) < f32::MAX.to_bits()
}

/// φ / 2π of a direction, in [0, 1): `acdf_core::geometry::phi` without
/// libm (see [`fast_atan2`]) for the sampler's hot path.
#[inline(always)]
fn unit_azimuth(w: Vec3) -> f32 {
    (azimuth(w) * (1.0 / TAU)).clamp(0.0, ONE_MINUS_EPSILON)
}

/// φ = atan2(y, x) of a direction in [0, 2π) by [`fast_atan2`]; the one
/// azimuth the sampler, [`outgoing_cell`] and [`half_vector_cell`] share.
#[inline(always)]
fn azimuth(w: Vec3) -> f32 {
    let a = fast_atan2(w.y, w.x);
    let a = if a < 0.0 { a + TAU } else { a };
    // a + 2π can round up to 2π for a tiny negative a.
    if a >= TAU {
        0.0
    } else {
        a
    }
}

impl<B: SliceBuilder> BxdfSampler for TabulatedBrdfSampler<B> {
    fn name(&self) -> &str {
        &self.name
    }

    /// With probability a (decided by u.x, then rescaled to [0, 1)) a cosine
    /// draw, otherwise a table draw of (x, v) and wi = reflect(wo, h); the
    /// reported density is the mixed pdf at the returned wi.
    fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
        acdf_core::dispatch!(Self::sample_one, self, wo, u)
    }

    /// The mixed density at wi, 0 for an invalid wo, a non-finite wi or wi at
    /// or below the horizon.
    fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
        acdf_core::dispatch!(Self::pdf_one, self, wo, wi)
    }

    /// [`sample`](BxdfSampler::sample) for each u, finding the slice once.
    fn sample_batch(&self, wo: Vec3, u: &[Vec2], out: &mut [Option<BxdfSample>]) {
        if !is_valid_outgoing(wo) {
            out.iter_mut().zip(u).for_each(|(o, _)| *o = None);
            return;
        }
        let slice = self.slice_for_mix(wo);
        match slice {
            // Without the cosine lobe every draw goes to the table, so the
            // table draws can go through the distribution's batch path
            // (interleaved searches) a chunk at a time.
            Some(slice) if self.cosine_fraction == 0.0 => {
                self.sample_table_batch(&slice, wo, u, out);
            }
            _ => {
                for (o, &u) in out.iter_mut().zip(u) {
                    *o = self.sample_in(slice.as_ref(), wo, u);
                }
            }
        }
    }

    /// [`pdf`](BxdfSampler::pdf) for each wi, finding the slice once.
    fn pdf_batch(&self, wo: Vec3, wi: &[Vec3], out: &mut [f32]) {
        if !is_valid_outgoing(wo) {
            out.iter_mut().zip(wi).for_each(|(o, _)| *o = 0.0);
            return;
        }
        match self.slice_for_mix(wo) {
            Some(slice) if self.cosine_fraction < 1.0 => {
                self.pdf_table_batch(&slice, wo, wi, out);
            }
            slice => {
                for (o, &wi) in out.iter_mut().zip(wi) {
                    *o = self.pdf_in(slice.as_ref(), wo, wi);
                }
            }
        }
    }

    /// [`sample`](BxdfSampler::sample) for each (wo, u) pair; without a
    /// cosine lobe the draws of a chunk are overlapped and their geometry
    /// runs in SIMD (bit-identical to `sample`).
    fn sample_each(&self, wo: &[Vec3], u: &[Vec2], out: &mut [Option<BxdfSample>]) {
        if self.cosine_fraction == 0.0 {
            self.sample_each_table(wo, u, out);
        } else {
            for ((o, &wo), &u) in out.iter_mut().zip(wo).zip(u) {
                *o = self.sample(wo, u);
            }
        }
    }

    /// [`pdf`](BxdfSampler::pdf) for each (wo, wi) pair, the coordinates of
    /// a chunk in SIMD when there is no cosine lobe.
    fn pdf_each(&self, wo: &[Vec3], wi: &[Vec3], out: &mut [f32]) {
        if self.cosine_fraction == 0.0 {
            self.pdf_each_table(wo, wi, out);
        } else {
            for ((o, &wo), &wi) in out.iter_mut().zip(wo).zip(wi) {
                *o = self.pdf(wo, wi);
            }
        }
    }

    /// The container of slices plus the tables of every slice built so far.
    fn storage_bytes(&self) -> usize {
        self.slices.capacity() * std::mem::size_of::<OnceLock<Result<B::Dist>>>()
            + self
                .built_slices()
                .map(Distribution2D::storage_bytes)
                .sum::<usize>()
    }
}

/// The cell of `wo` in a resolution, as the sampler picks it: (θ_o index,
/// φ_o index); for one φ_o cell the φ_o index is 0.
pub fn outgoing_cell(res: &Resolution, wo: Vec3) -> (usize, usize) {
    (
        ThetaOCells::new(res.theta_o).cell(wo.z),
        if res.phi_o == 1 {
            0
        } else {
            phi_o_cell(azimuth(wo), res.phi_o)
        },
    )
}

/// The cell (column, row) of the half vector `h` in a slice table of
/// `n_phi_h` × `n_theta_h`, with φ_h measured from `phi_offset`.
pub fn half_vector_cell(
    h: Vec3,
    phi_offset: f32,
    n_phi_h: usize,
    n_theta_h: usize,
) -> (usize, usize) {
    let v = HalfMap::new(n_theta_h).v_of(sin_theta(h), h.z, 1.0);
    let x = wrap_angle(azimuth(h) - phi_offset) / TAU;
    (unit_cell(x, n_phi_h), unit_cell(v, n_theta_h))
}

#[path = "sampler_batch.rs"]
mod batch;

#[cfg(test)]
mod tests {
    use super::is_positive_finite;

    /// The bit test of a usable cell density accepts exactly the positive
    /// finite values: the extremes of both float classes, and not zero of
    /// either sign, negatives, infinities or NaN.
    #[test]
    fn positive_finite_is_the_two_compares() {
        let mut values = vec![
            0.0f32,
            -0.0,
            f32::from_bits(1),
            -f32::from_bits(1),
            f32::MIN_POSITIVE,
            f32::MAX,
            -f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
            -f32::NAN,
            f32::from_bits(0x7fc0_0001),
            1.0,
            -1.0,
        ];
        values.extend((0..64).map(|k| f32::from_bits(0x0123_4567u32.wrapping_mul(k * 2 + 1))));
        for v in values {
            assert_eq!(
                is_positive_finite(v),
                v > 0.0 && v < f32::INFINITY,
                "{v:e} ({:#x})",
                v.to_bits()
            );
        }
    }
}
