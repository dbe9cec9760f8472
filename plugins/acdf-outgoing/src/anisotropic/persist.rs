//! The anisotropic outgoing sampler in the sampler file format of
//! [`acdf_tabulated::persist`]: the kind is that of the isotropic outgoing
//! sampler ([`KIND`]), and the layout version that follows it,
//! [`ANISOTROPIC_VERSION`], says which of the two bodies the file holds
//! ([`is_anisotropic`]).
//!
//! The body, in order: the kind `outgoing` (`string`), the layout version
//! (u32, [`ANISOTROPIC_VERSION`]), the sampler name (`string`, e.g.
//! `outgoing:chi2`), the simplifier name (`string`), its tolerance (f64),
//! the breakpoint budget (f64), the fine θ_o and φ_o node counts (2 × u32),
//! the frame of φ_h (u8: 0 from φ_o, 1 absolute; [`PhiFrame`]), the arc
//! of φ_o the slices cover (u8: 0 the circle, 1 the turn by π, 2 the
//! mirror y → −y, 3 both mirrors; [`Symmetry`]), the material name (`string`), whether it is isotropic (u8, 0 or 1), its
//! fingerprint (u64), the half-vector cells θ_h and φ_h (2 × u32), the
//! cosine mixing fraction (f32), the θ_o breakpoints u_o (`f32 array`,
//! increasing from 0 to 1), for each θ_o breakpoint its row's φ_o
//! breakpoints in turns (`f32 array`, increasing from 0: below 1 on the
//! circle; on an arc of s turns 0 alone or ending at s), then
//! the slices row by row (θ_o breakpoint, then φ_o breakpoint of the row),
//! each as in the isotropic layout: the
//! marginal positions (u16), the marginal CDF values (u16), the
//! conditional offsets (u16), the conditional positions (u8) and the
//! conditional CDF values (u16), each array a u32 count and the values.

use super::{AnisotropicOutgoingSampler, PhiFrame, Symmetry};
use crate::persist::{invalid, read_slice, write_slice, KIND, OUTGOING_VERSION};
use crate::OutgoingBuilder;
use acdf_adaptive_cdf::simplify::simplifier_by_name;
use acdf_core::BxdfSampler;
use acdf_io::fsio::write_atomic;
use acdf_tabulated::persist::{
    open, read_file, seal, ByteReader, ByteWriter, PersistError, StoredMaterial,
};
use acdf_tabulated::Resolution;
use std::path::Path;
use std::sync::Arc;

/// The layout version of the anisotropic body: 7, with φ_o breakpoints
/// per θ_o row over the arc of a [`Symmetry`].
pub const ANISOTROPIC_VERSION: u32 = 7;

/// The layout before the arcs, φ_o breakpoints per θ_o row round the
/// whole circle: recognised, so that its files are refused with the
/// reason, and the sampler is built again.
const CIRCLE_VERSION: u32 = 4;

/// The earlier anisotropic layout, one set of φ_o breakpoints for every θ_o
/// row: recognised, so that its files are refused with the reason, and
/// the sampler is built again.
const TENSOR_VERSION: u32 = 2;

// The layouts of the kind must stay apart.
const _: () = assert!(
    ANISOTROPIC_VERSION != OUTGOING_VERSION
        && TENSOR_VERSION != OUTGOING_VERSION
        && CIRCLE_VERSION != OUTGOING_VERSION
);

/// Whether a sampler file of kind [`KIND`] holds the anisotropic layout
/// (its envelope checked; an error for a file of another kind).
pub fn is_anisotropic(bytes: &[u8]) -> Result<bool, PersistError> {
    let mut r = ByteReader::new(open(bytes)?);
    r.kind(KIND)?;
    let version = r.u32("outgoing version")?;
    Ok([ANISOTROPIC_VERSION, CIRCLE_VERSION, TENSOR_VERSION].contains(&version))
}

impl AnisotropicOutgoingSampler {
    /// The sampler as a file image (module documentation).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut w = ByteWriter::new();
        w.string(KIND);
        w.u32(ANISOTROPIC_VERSION);
        w.string(self.name());
        let b = &self.builder;
        w.string(b.simplifier.name());
        w.f64(b.tolerance);
        w.f64(b.budget);
        w.length(b.fine);
        w.length(self.fine_phi);
        w.u8(self.frame.code());
        w.u8(self.symmetry.code());
        w.string(self.brdf.name());
        w.u8(self.brdf.is_isotropic() as u8);
        w.u64(self.brdf.fingerprint());
        w.length(self.n_theta_h);
        w.length(self.n_phi_h);
        w.f32(self.cosine_fraction);
        w.f32_array(&self.theta_breakpoints);
        for row in &self.phi_breakpoints {
            w.f32_array(row);
        }
        for s in &self.slices {
            write_slice(&mut w, s);
        }
        seal(&w.into_bytes())
    }

    /// Save to `path` atomically ([`acdf_io::fsio::write_atomic`]).
    pub fn save(&self, path: &Path) -> Result<(), PersistError> {
        let bytes = self.to_bytes();
        Ok(write_atomic(path, |w| w.write_all(&bytes))?)
    }

    /// Read a sampler from a file image, checking every field.
    pub fn from_bytes(bytes: &[u8]) -> Result<Self, PersistError> {
        let mut r = ByteReader::new(open(bytes)?);
        r.kind(KIND)?;
        let version = r.u32("outgoing version")?;
        if version != ANISOTROPIC_VERSION {
            let why = if version == TENSOR_VERSION {
                " (layout 2 keeps one set of phi_o breakpoints for every theta_o row: build the sampler again)"
            } else if version == CIRCLE_VERSION {
                " (layout 4 has no phi_o symmetry: build the sampler again)"
            } else {
                ""
            };
            return Err(invalid(
                "outgoing version",
                format!(
                    "{version} is not the anisotropic layout this build reads ({ANISOTROPIC_VERSION}){why}"
                ),
            ));
        }
        let name = r.string("sampler name")?;
        let simplifier = simplifier_by_name(&r.string("simplifier")?)?;
        let tolerance = r.f64("tolerance")?;
        let budget = r.f64("budget")?;
        let fine = r.u32("fine theta_o nodes")? as usize;
        let fine_phi = r.u32("fine phi_o nodes")? as usize;
        let code = r.u8("phi_h frame")?;
        let frame = PhiFrame::from_code(code)
            .ok_or_else(|| invalid("phi_h frame", format!("{code} is not 0 or 1")))?;
        let code = r.u8("phi_o symmetry")?;
        let symmetry = Symmetry::from_code(code)
            .ok_or_else(|| invalid("phi_o symmetry", format!("{code} is not 0 to 3")))?;
        let builder = OutgoingBuilder {
            simplifier,
            max_bytes: None,
            tolerance,
            budget,
            fine,
        };
        builder.validate().map_err(PersistError::Table)?;
        super::validate_fine_phi(fine_phi).map_err(PersistError::Table)?;
        if builder.name() != name {
            return Err(invalid(
                "sampler name",
                format!(
                    "`{name}` does not match its parameters (`{}`)",
                    builder.name()
                ),
            ));
        }
        let material = r.string("material")?;
        let isotropic = match r.u8("isotropic")? {
            0 => false,
            1 => true,
            other => return Err(invalid("isotropic", format!("{other} is not 0 or 1"))),
        };
        let fingerprint = r.u64("fingerprint")?;
        let n_theta_h = r.u32("theta_h cells")? as usize;
        let n_phi_h = r.u32("phi_h cells")? as usize;
        Resolution::new(1, 1, n_theta_h, n_phi_h).map_err(PersistError::Table)?;
        if !symmetry.fits_grid(fine_phi, n_phi_h) {
            return Err(invalid(
                "phi_o symmetry",
                format!(
                    "{symmetry:?} does not fit {fine_phi} phi_o nodes and {n_phi_h} phi_h cells"
                ),
            ));
        }
        let cosine_mix = r.f32("cosine mix")?;
        let theta = r.f32_array("theta_o breakpoints")?;
        let n = theta.len();
        if n < 2
            || theta[0] != 0.0
            || theta[n - 1] != 1.0
            || theta.windows(2).any(|w| !(w[1] > w[0]))
        {
            return Err(invalid(
                "theta_o breakpoints",
                "not increasing from 0 to 1".into(),
            ));
        }
        let mut phi = Vec::with_capacity(n);
        for _ in 0..n {
            let row = r.f32_array("phi_o breakpoints")?;
            let m = row.len();
            let span = symmetry.span();
            let ends = if symmetry.is_periodic() {
                m > 0 && row[m - 1] < 1.0
            } else {
                m == 1 || (m > 1 && row[m - 1] == span)
            };
            if !ends || row[0] != 0.0 || row.windows(2).any(|w| !(w[1] > w[0])) {
                return Err(invalid(
                    "phi_o breakpoints",
                    format!(
                        "not increasing from 0 and {}",
                        if symmetry.is_periodic() {
                            "below 1".to_string()
                        } else {
                            format!("ending at {span}")
                        }
                    ),
                ));
            }
            phi.push(row);
        }
        // Each slice takes at least five u32 counts: a count beyond the
        // bytes left is a corrupt file, never an allocation.
        let count: usize = phi.iter().map(Vec::len).sum();
        if count.saturating_mul(20) > r.remaining() {
            return Err(PersistError::FieldOverrun {
                field: "slices",
                needed: count as u64 * 20,
                remaining: r.remaining() as u64,
            });
        }
        let mut slices = Vec::with_capacity(count);
        for _ in 0..count {
            slices.push(read_slice(&mut r, n_phi_h, n_theta_h)?);
        }
        r.finish()?;
        let brdf = Arc::new(StoredMaterial {
            name: material,
            isotropic,
            fingerprint,
        });
        AnisotropicOutgoingSampler::from_parts(
            brdf,
            builder,
            (fine_phi, frame, symmetry),
            (n_theta_h, n_phi_h),
            theta,
            phi,
            slices,
        )
        .with_cosine_mix(cosine_mix)
        .map_err(PersistError::Table)
    }

    /// Load a sampler saved with [`save`](Self::save).
    pub fn load(path: &Path) -> Result<Self, PersistError> {
        Self::from_bytes(&read_file(path)?)
    }
}
