//! The sampler registry: every concrete sampler behind one enum,
//! [`AnySampler`], built from its command-line name by [`make_sampler`].
//!
//! Why a `macro_rules!` match and not `enum_dispatch`: `enum_dispatch` must
//! see the trait's definition, and `BxdfSampler` lives in acdf-core, which we
//! do not change. A local mirror trait with `#[enum_dispatch]` would need a
//! blanket `impl<T: BxdfSampler> Mirror for T` to cover the plug-ins, and that
//! blanket impl collides (coherence) with the generated `impl Mirror for
//! AnySampler` as soon as `AnySampler` itself implements `BxdfSampler`, which
//! is the whole point. The macro below writes the same static dispatch (one
//! `match` per method, no vtable, no allocation), the `From` conversions, and
//! keeps the list of variants in one place.

use std::path::Path;
use std::sync::Arc;

use acdf_adaptive::{average_resolution, AdaptiveBrdfSampler, AdaptiveBuilder};
use acdf_core::{BxdfSample, BxdfSampler, Vec2, Vec3};
use acdf_cosine::CosineSampler;
use acdf_rgl::RglSampler;
use acdf_tabulated::persist;
use acdf_tabulated::{Resolution, TabulatedBrdfSampler};
use acdf_uniform::{PiecewiseConstantBuilder, UniformBrdfSampler};

use crate::error::{Error, Result};
use crate::material::Material;
use crate::spec::{SamplerSpec, SimplifierName};

/// Options shared by the tabulated samplers.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SamplerOptions {
    /// Tabulation counts θ_o × φ_o × θ_h × φ_h.
    pub resolution: Resolution,
    /// Simplifier tolerance of the adaptive sampler; `None` for the
    /// simplifier's default.
    pub tolerance: Option<f64>,
    /// Probability a of drawing from the cosine lobe instead of the table:
    /// p = (1 − a) p_table + a cos θ_i / π.
    pub cosine_mix: f32,
}

impl Default for SamplerOptions {
    /// The isotropic resolution 32x1x256x32, default tolerances, no cosine
    /// mixing.
    fn default() -> Self {
        SamplerOptions {
            resolution: Resolution::ISOTROPIC,
            tolerance: None,
            cosine_mix: 0.0,
        }
    }
}

macro_rules! any_sampler {
    ($($(#[$doc:meta])* $variant:ident($ty:ty)),+ $(,)?) => {
        /// One of acdf's samplers, dispatched statically.
        pub enum AnySampler {
            $($(#[$doc])* $variant($ty)),+
        }

        $(impl From<$ty> for AnySampler {
            fn from(s: $ty) -> Self {
                AnySampler::$variant(s)
            }
        })+

        impl BxdfSampler for AnySampler {
            fn name(&self) -> &str {
                match self { $(AnySampler::$variant(s) => s.name()),+ }
            }
            #[inline]
            fn sample(&self, wo: Vec3, u: Vec2) -> Option<BxdfSample> {
                match self { $(AnySampler::$variant(s) => s.sample(wo, u)),+ }
            }
            #[inline]
            fn pdf(&self, wo: Vec3, wi: Vec3) -> f32 {
                match self { $(AnySampler::$variant(s) => s.pdf(wo, wi)),+ }
            }
            fn storage_bytes(&self) -> usize {
                match self { $(AnySampler::$variant(s) => s.storage_bytes()),+ }
            }
            fn sample_batch(&self, wo: Vec3, u: &[Vec2], out: &mut [Option<BxdfSample>]) {
                match self { $(AnySampler::$variant(s) => s.sample_batch(wo, u, out)),+ }
            }
            fn pdf_batch(&self, wo: Vec3, wi: &[Vec3], out: &mut [f32]) {
                match self { $(AnySampler::$variant(s) => s.pdf_batch(wo, wi, out)),+ }
            }
            fn sample_each(&self, wo: &[Vec3], u: &[Vec2], out: &mut [Option<BxdfSample>]) {
                match self { $(AnySampler::$variant(s) => s.sample_each(wo, u, out)),+ }
            }
            fn pdf_each(&self, wo: &[Vec3], wi: &[Vec3], out: &mut [f32]) {
                match self { $(AnySampler::$variant(s) => s.pdf_each(wo, wi, out)),+ }
            }
        }
    };
}

any_sampler! {
    /// `cosine`: p = cos θ_i / π.
    Cosine(CosineSampler),
    /// `uniform`: piecewise-constant tabulated CDFs.
    Uniform(UniformBrdfSampler),
    /// `adaptive:SIMPLIFIER`: curve-simplified tabulated CDFs.
    Adaptive(AdaptiveBrdfSampler),
    /// `rgl`: the RGL `.bsdf` file's own sampler.
    Rgl(RglSampler),
}

impl AnySampler {
    /// Build every table now (in parallel) rather than on first use, so that
    /// `storage_bytes` reports the whole sampler and timings exclude
    /// building.
    pub fn build_all(&self) -> Result<()> {
        match self {
            AnySampler::Cosine(_) | AnySampler::Rgl(_) => Ok(()),
            AnySampler::Uniform(s) => Ok(s.build_all()?),
            AnySampler::Adaptive(s) => Ok(s.build_all()?),
        }
    }

    /// A short description of the tables: the resolution θ_o×φ_o×θ_h×φ_h
    /// for the uniform sampler; for adaptive ones θ_o×φ_o× the mean kept
    /// marginal vertices × the mean kept conditional vertices (over the
    /// slices built so far); `-` for samplers without tables.
    pub fn resolution_label(&self) -> String {
        match self {
            AnySampler::Cosine(_) => "-".to_string(),
            AnySampler::Rgl(s) => {
                let (a, b) = s.brdf().grid_size();
                format!("{a}x{b} grid")
            }
            AnySampler::Uniform(s) => s.resolution().to_string(),
            AnySampler::Adaptive(s) => {
                let r = s.resolution();
                let (m, c) = average_resolution(s);
                format!("{}x{}x{m:.1}x{c:.1}", r.theta_o, r.phi_o)
            }
        }
    }

    /// The name of the material a tabulated sampler was built for (for a
    /// sampler loaded from a file, the name recorded in it); `None` for
    /// samplers without tables.
    pub fn material_name(&self) -> Option<&str> {
        match self {
            AnySampler::Uniform(s) => Some(s.brdf().name()),
            AnySampler::Adaptive(s) => Some(s.brdf().name()),
            AnySampler::Cosine(_) | AnySampler::Rgl(_) => None,
        }
    }

    /// For adaptive samplers, (mean marginal vertices, mean conditional
    /// vertices) over the slices built so far.
    pub fn mean_vertices(&self) -> Option<(f64, f64)> {
        match self {
            AnySampler::Adaptive(s) => Some(average_resolution(s)),
            _ => None,
        }
    }
}

impl std::fmt::Debug for AnySampler {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "AnySampler({})", self.name())
    }
}

/// Build the sampler named `name` (see [`SamplerSpec`]) for `material`.
pub fn make_sampler(
    name: &str,
    material: &Material,
    options: &SamplerOptions,
) -> Result<AnySampler> {
    let spec: SamplerSpec = name.parse()?;
    make_sampler_spec(spec, material, options)
}

/// [`make_sampler`] for an already parsed name.
pub fn make_sampler_spec(
    spec: SamplerSpec,
    material: &Material,
    options: &SamplerOptions,
) -> Result<AnySampler> {
    let brdf = material.brdf.clone();
    let resolution = effective_resolution(material, options.resolution);
    Ok(match spec {
        SamplerSpec::Cosine => CosineSampler.into(),
        SamplerSpec::Uniform => {
            UniformBrdfSampler::new(brdf, resolution, PiecewiseConstantBuilder)?
                .with_cosine_mix(options.cosine_mix)?
                .into()
        }
        SamplerSpec::Adaptive(simplifier) => {
            let builder = AdaptiveBuilder::by_name(simplifier.short(), options.tolerance)?;
            TabulatedBrdfSampler::new(brdf, resolution, builder)?
                .with_cosine_mix(options.cosine_mix)?
                .into()
        }
        SamplerSpec::Rgl => match &material.rgl {
            Some(rgl) => RglSampler::new(rgl.clone()).into(),
            None => {
                return Err(Error::Incompatible {
                    sampler: "rgl".into(),
                    material: material.spec.to_string(),
                    reason: "the rgl sampler needs an RGL .bsdf material".into(),
                })
            }
        },
    })
}

/// The resolution a tabulated sampler of `material` uses: `requested`, except
/// that an anisotropic material cannot use one φ_o slice and gets the paper's
/// 16 instead.
pub fn effective_resolution(material: &Material, requested: Resolution) -> Resolution {
    if !material.brdf.is_isotropic() && requested.phi_o == 1 {
        Resolution {
            phi_o: Resolution::PAPER.phi_o,
            ..requested
        }
    } else {
        requested
    }
}

/// The samplers a report compares for `material`: uniform, the four adaptive
/// simplifiers, cosine, and `rgl` for RGL materials.
pub fn report_samplers(material: &Material) -> Vec<SamplerSpec> {
    let mut out = vec![SamplerSpec::Uniform];
    out.extend(
        SimplifierName::ALL
            .iter()
            .map(|&s| SamplerSpec::Adaptive(s)),
    );
    out.push(SamplerSpec::Cosine);
    if material.rgl.is_some() {
        out.push(SamplerSpec::Rgl);
    }
    out
}

/// Build every table of a tabulated sampler (uniform or adaptive) and save
/// it to `path` in the sampler file format (`acdf_tabulated::persist`), so a
/// renderer can load it without rebuilding. Samplers without tables have
/// nothing to save and give [`Error::Incompatible`].
pub fn save_sampler(sampler: &AnySampler, path: &Path) -> Result<()> {
    let file_error = |source| Error::SamplerFile {
        path: path.to_path_buf(),
        source,
    };
    match sampler {
        AnySampler::Uniform(s) => s.save(path).map_err(file_error),
        AnySampler::Adaptive(s) => s.save(path).map_err(file_error),
        AnySampler::Cosine(_) | AnySampler::Rgl(_) => Err(Error::Incompatible {
            sampler: sampler.name().to_string(),
            material: "-".into(),
            reason: "only tabulated samplers (uniform, adaptive) are saved to files".into(),
        }),
    }
}

/// Load a sampler saved by [`save_sampler`]; the family recorded in the file
/// picks the type.
pub fn load_sampler(path: &Path) -> Result<AnySampler> {
    let file_error = |source| Error::SamplerFile {
        path: path.to_path_buf(),
        source,
    };
    let bytes = persist::read_file(path).map_err(file_error)?;
    let kind = persist::peek_kind(&bytes).map_err(file_error)?;
    match kind.as_str() {
        "adaptive" => Ok(AdaptiveBrdfSampler::from_bytes(&bytes)
            .map_err(file_error)?
            .into()),
        _ => Ok(UniformBrdfSampler::from_bytes(&bytes)
            .map_err(file_error)?
            .into()),
    }
}

/// Shared ownership of a built sampler, for experiments that hand it to
/// several threads.
pub type SharedSampler = Arc<AnySampler>;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::material::load_material;
    use crate::spec::MaterialSpec;

    fn nickel() -> Material {
        load_material(&MaterialSpec::Builtin("nickel".into()), None).unwrap()
    }

    /// Every name builds a sampler that calls itself by that name, so tables
    /// and JSON use the command-line names.
    #[test]
    fn every_name_builds_the_sampler_it_names() {
        let m = nickel();
        let options = SamplerOptions::default();
        for name in [
            "cosine",
            "uniform",
            "adaptive:dp",
            "adaptive:vw",
            "adaptive:rw",
            "adaptive:optimal",
        ] {
            let s = make_sampler(name, &m, &options).unwrap();
            assert_eq!(s.name(), name);
            let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
            let d = s.sample(wo, Vec2::new(0.3, 0.6)).unwrap();
            assert!((s.pdf(wo, d.wi) - d.pdf).abs() <= 1e-4 * d.pdf, "{name}");
        }
        assert_eq!(
            make_sampler("adaptive", &m, &options).unwrap().name(),
            "adaptive:dp"
        );
        assert!(matches!(
            make_sampler("rgl", &m, &options),
            Err(Error::Incompatible { .. })
        ));
        assert!(matches!(
            make_sampler("nope", &m, &options),
            Err(Error::UnknownSampler(_))
        ));
    }

    /// Building every slice makes an adaptive sampler report its storage,
    /// and that storage shrinks as the tolerance grows.
    #[test]
    fn adaptive_storage_shrinks_with_tolerance() {
        let m = nickel();
        let storage = |t: f64| {
            let s = make_sampler(
                "adaptive:dp",
                &m,
                &SamplerOptions {
                    tolerance: Some(t),
                    ..SamplerOptions::default()
                },
            )
            .unwrap();
            s.build_all().unwrap();
            assert!(s.mean_vertices().unwrap().0 >= 2.0);
            s.storage_bytes()
        };
        assert!(storage(1e-4) > storage(1e-2));
    }

    /// nickel, but claiming to depend on both azimuths.
    struct Anisotropic(Arc<dyn acdf_core::Brdf>);
    impl acdf_core::Brdf for Anisotropic {
        fn name(&self) -> &str {
            "anisotropic"
        }
        fn eval(&self, wo: Vec3, wi: Vec3) -> acdf_core::Rgb {
            self.0.eval(wo, wi)
        }
        fn is_isotropic(&self) -> bool {
            false
        }
    }

    #[test]
    fn anisotropic_materials_get_phi_o_slices() {
        let m = nickel();
        assert_eq!(
            effective_resolution(&m, Resolution::ISOTROPIC),
            Resolution::ISOTROPIC
        );
        let aniso = Material {
            brdf: Arc::new(Anisotropic(m.brdf.clone())),
            ..m
        };
        assert_eq!(
            effective_resolution(&aniso, Resolution::ISOTROPIC).phi_o,
            Resolution::PAPER.phi_o
        );
        // Without the adjustment the uniform plug-in would reject it.
        assert!(make_sampler("uniform", &aniso, &SamplerOptions::default()).is_ok());
    }
}
