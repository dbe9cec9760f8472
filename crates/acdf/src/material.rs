//! Loading a material from its command-line name ([`MaterialSpec`]).
//!
//! A Neural-BRDF material (`nbrdf:NAME`) is evaluated as a renderer
//! evaluates measured data: its network is baked once into a MERL-layout
//! table (90 θ_h × 90 θ_d × 180 φ_d, [`NeuralBrdf::bake`]) and every
//! evaluation is a trilinear lookup in that table. Bakes are kept per
//! process ([`baked_network`]), so that loading the same material again
//! reuses the table. The network itself is what [`load_network`] returns,
//! for baking and for checking against the reference outputs shipped with
//! the weights.

use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};

use acdf_core::Brdf;
use acdf_materials::merl::MerlTable;
use acdf_materials::nbrdf::{NbrdfLibrary, NeuralBrdf, NAMES_FILE, WEIGHTS_FILE};
use acdf_materials::rgl::RglBrdf;

use crate::error::{Error, Result};
use crate::spec::MaterialSpec;

/// The Neural-BRDF weight file used when `--nbrdf-weights` is not given,
/// relative to the working directory (the repository root, with `shared/`
/// beside it).
pub const DEFAULT_NBRDF_WEIGHTS: &str = "../shared/data/merl-neural-brdf/merl_nbrdf_weights.f32";

/// A loaded material: the BRDF every sampler and estimator uses, and the RGL
/// file itself when the material is one (the `rgl` sampler needs it).
#[derive(Clone)]
pub struct Material {
    /// What it was loaded from.
    pub spec: MaterialSpec,
    /// f_r.
    pub brdf: Arc<dyn Brdf>,
    /// The `.bsdf` data, for RGL materials only.
    pub rgl: Option<Arc<RglBrdf>>,
}

impl std::fmt::Debug for Material {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Material")
            .field("spec", &self.spec)
            .field("brdf", &self.brdf.name())
            .finish()
    }
}

impl Material {
    /// A short name for tables.
    pub fn label(&self) -> String {
        self.spec.label()
    }
}

fn material_error(spec: &MaterialSpec, e: impl std::fmt::Display) -> Error {
    Error::Material {
        spec: spec.to_string(),
        message: e.to_string().replace('\n', " "),
    }
}

/// The error of picking a network from a library: a name the library lacks
/// is an unknown material, anything else (non-finite weights, an output
/// that overflows) an error of that material.
fn network_error(spec: &MaterialSpec, e: acdf_materials::MaterialError) -> Error {
    match e {
        acdf_materials::MaterialError::UnknownMaterial { .. } => Error::UnknownMaterial {
            spec: spec.to_string(),
            reason: e.to_string(),
        },
        e => material_error(spec, e),
    }
}

/// Where the Neural-BRDF weights are: `explicit` if given, else
/// [`DEFAULT_NBRDF_WEIGHTS`] if it exists, else the shared data directory of
/// `acdf_materials::shared_data_dir`.
pub fn nbrdf_weights_path(explicit: Option<&Path>) -> Option<PathBuf> {
    if let Some(p) = explicit {
        return Some(p.to_path_buf());
    }
    let default = PathBuf::from(DEFAULT_NBRDF_WEIGHTS);
    if default.is_file() {
        return Some(default);
    }
    acdf_materials::shared_data_dir()
        .map(|d| d.join(acdf_materials::nbrdf::DATA_DIR).join(WEIGHTS_FILE))
}

/// Load the network library from a weight file (whose material names are in
/// `merl_nbrdf_materials.txt` beside it) or from the directory holding both.
pub fn load_nbrdf_library(path: &Path) -> std::result::Result<NbrdfLibrary, String> {
    if path.is_dir() {
        return NbrdfLibrary::load(path).map_err(|e| e.to_string());
    }
    let names_path = path
        .parent()
        .unwrap_or_else(|| Path::new("."))
        .join(NAMES_FILE);
    NbrdfLibrary::read_files(path, &names_path).map_err(|e| e.to_string())
}

/// Load the material `spec` names. `nbrdf_weights` overrides where
/// Neural-BRDF weights are read from (see [`nbrdf_weights_path`]).
pub fn load_material(spec: &MaterialSpec, nbrdf_weights: Option<&Path>) -> Result<Material> {
    let (brdf, rgl): (Arc<dyn Brdf>, Option<Arc<RglBrdf>>) = match spec {
        MaterialSpec::Builtin(name) => (
            acdf_materials::builtin(name).map_err(|e| Error::UnknownMaterial {
                spec: spec.to_string(),
                reason: e.to_string(),
            })?,
            None,
        ),
        MaterialSpec::Merl(path) => (
            Arc::new(MerlTable::read(path).map_err(|e| material_error(spec, e))?),
            None,
        ),
        MaterialSpec::Rgl(path) => {
            let rgl = Arc::new(RglBrdf::open(path).map_err(|e| material_error(spec, e))?);
            (rgl.clone(), Some(rgl))
        }
        MaterialSpec::Nbrdf(_) => (baked_network(spec, nbrdf_weights)?, None),
    };
    Ok(Material {
        spec: spec.clone(),
        brdf,
        rgl,
    })
}

/// Bake a material into a MERL table: Neural-BRDF networks are evaluated at
/// the exact grid angles, a MERL table is read as it is (so baking it
/// reproduces its table exactly), every other BRDF is tabulated with the
/// MERL rule that marks grid points below the horizon unmeasured.
pub fn bake_material(spec: &MaterialSpec, nbrdf_weights: Option<&Path>) -> Result<MerlTable> {
    if let MaterialSpec::Nbrdf(_) = spec {
        return Ok(load_network(spec, nbrdf_weights)?.bake());
    }
    // A MERL table is its own baking: the file is read back as it is, so
    // writing it reproduces every value and unmeasured entry.
    if let MaterialSpec::Merl(path) = spec {
        return MerlTable::read(path).map_err(|e| material_error(spec, e));
    }
    let material = load_material(spec, nbrdf_weights)?;
    Ok(acdf_materials::nbrdf::bake(material.brdf.as_ref()))
}

/// The network of `nbrdf:NAME` itself (evaluated in `f64` at every call);
/// [`Error::UnknownMaterial`] listing every name of the weight file for a
/// name it does not hold, and [`Error::Material`] for any other spec.
pub fn load_network(spec: &MaterialSpec, nbrdf_weights: Option<&Path>) -> Result<NeuralBrdf> {
    let MaterialSpec::Nbrdf(name) = spec else {
        return Err(material_error(
            spec,
            "not a Neural-BRDF material (nbrdf:NAME)",
        ));
    };
    let path = nbrdf_weights_path(nbrdf_weights).ok_or_else(|| {
        material_error(
            spec,
            format!(
                "no Neural-BRDF weights: pass --nbrdf-weights or put {DEFAULT_NBRDF_WEIGHTS} in place"
            ),
        )
    })?;
    let library = load_nbrdf_library(&path).map_err(|e| material_error(spec, e))?;
    library.material(name).map_err(|e| network_error(spec, e))
}

/// How many baked tables [`baked_network`] keeps (about 23 MiB each with
/// the luminance plane a sampler's tabulation adds): enough for the
/// materials of one command, few enough that a pass over all 100 MERL
/// materials holds only the recent ones.
pub const BAKED_CACHE: usize = 4;

/// The process's recent bakes: (weight file, material name, table), most
/// recent last.
type BakeCache = Vec<(PathBuf, String, Arc<MerlTable>)>;

static BAKED: Mutex<BakeCache> = Mutex::new(Vec::new());

/// `nbrdf:NAME` baked into a MERL-layout table ([`NeuralBrdf::bake`]),
/// evaluated by trilinear lookup. The table is baked once and reused while
/// it is among the [`BAKED_CACHE`] most recently used in this process
/// (keyed by the weight file and the name).
pub fn baked_network(spec: &MaterialSpec, nbrdf_weights: Option<&Path>) -> Result<Arc<MerlTable>> {
    let MaterialSpec::Nbrdf(name) = spec else {
        return Err(material_error(
            spec,
            "not a Neural-BRDF material (nbrdf:NAME)",
        ));
    };
    let key = nbrdf_weights_path(nbrdf_weights).unwrap_or_default();
    let found = |cache: &mut BakeCache| {
        let k = cache.iter().position(|(p, n, _)| *p == key && n == name)?;
        let entry = cache.remove(k);
        let table = entry.2.clone();
        cache.push(entry);
        Some(table)
    };
    // A poisoned lock only means another thread panicked while holding
    // it; the cache itself is always a valid list.
    if let Some(table) = found(&mut BAKED.lock().unwrap_or_else(|e| e.into_inner())) {
        return Ok(table);
    }
    // Bake outside the lock: two threads may bake the same table once each.
    let table = Arc::new(load_network(spec, nbrdf_weights)?.bake());
    let mut cache = BAKED.lock().unwrap_or_else(|e| e.into_inner());
    if let Some(table) = found(&mut cache) {
        return Ok(table);
    }
    if cache.len() >= BAKED_CACHE {
        cache.remove(0);
    }
    cache.push((key, name.clone(), table.clone()));
    Ok(table)
}

/// Write a baked table (atomically), mapping errors to the facade's: a
/// failure to write names the output file, not a material.
pub fn write_merl(table: &MerlTable, path: &Path) -> Result<()> {
    table.write(path).map_err(|e| match e {
        acdf_materials::MaterialError::File(e) => Error::File(e),
        e => Error::io(path, std::io::Error::other(e.to_string())),
    })
}
