//! The resolution of a tabulated measured-BRDF sampler.

use acdf_core::{Error, Result};
use std::fmt;
use std::str::FromStr;

/// The number of cells along each of the four tabulated axes: the outgoing
/// direction (θ_o, φ_o) picks a slice, the half vector (θ_h, φ_h) is
/// tabulated within it. Written and parsed as `theta_oxphi_oxtheta_hxphi_h`,
/// e.g. `32x16x256x32`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct Resolution {
    pub theta_o: usize,
    pub phi_o: usize,
    pub theta_h: usize,
    pub phi_h: usize,
}

/// Largest accepted number of outgoing slices θ_o·φ_o.
const MAX_SLICES: usize = 1 << 16;
/// Largest accepted number of half-vector cells θ_h·φ_h per slice.
const MAX_SLICE_CELLS: usize = 1 << 22;

/// The memory estimate per tabulated cell of a sampler: the uniform
/// family keeps one `f32` of CDF per cell, an adaptive one at most two
/// (a position and a value per kept vertex), and building a slice holds a
/// table of one `f32` per cell; 8 bytes bounds the sum for every family.
pub const BYTES_PER_CELL: u64 = 8;

impl Resolution {
    /// The configuration of Lawrence et al. (2005): 32 θ_o × 16 φ_o slices of
    /// 256 θ_h × 32 φ_h cells.
    pub const PAPER: Resolution = Resolution {
        theta_o: 32,
        phi_o: 16,
        theta_h: 256,
        phi_h: 32,
    };

    /// The paper's resolution with one φ_o slice, enough for an isotropic
    /// material (φ_h is then measured relative to φ_o). The default.
    pub const ISOTROPIC: Resolution = Resolution {
        theta_o: 32,
        phi_o: 1,
        theta_h: 256,
        phi_h: 32,
    };

    /// A resolution after checking it: every count at least 1, at most
    /// 2^16 outgoing slices and 2^22 cells per slice.
    pub fn new(theta_o: usize, phi_o: usize, theta_h: usize, phi_h: usize) -> Result<Self> {
        let r = Resolution {
            theta_o,
            phi_o,
            theta_h,
            phi_h,
        };
        r.validate()?;
        Ok(r)
    }

    /// Check the invariants of [`new`](Self::new) (the fields are public).
    pub fn validate(&self) -> Result<()> {
        let invalid = |reason: String| Error::InvalidParameter {
            name: "resolution",
            reason,
        };
        if self.theta_o == 0 || self.phi_o == 0 || self.theta_h == 0 || self.phi_h == 0 {
            return Err(invalid(format!("{self}: every count must be at least 1")));
        }
        match self.theta_o.checked_mul(self.phi_o) {
            Some(n) if n <= MAX_SLICES => {}
            _ => return Err(invalid(format!("{self}: more than {MAX_SLICES} slices"))),
        }
        match self.theta_h.checked_mul(self.phi_h) {
            Some(n) if n <= MAX_SLICE_CELLS => {}
            _ => {
                return Err(invalid(format!(
                    "{self}: more than {MAX_SLICE_CELLS} cells per slice"
                )))
            }
        }
        Ok(())
    }

    /// The number of outgoing slices θ_o·φ_o.
    pub fn slices(&self) -> usize {
        self.theta_o * self.phi_o
    }

    /// The number of half-vector cells per slice θ_h·φ_h.
    pub fn cells_per_slice(&self) -> usize {
        self.theta_h * self.phi_h
    }

    /// Bytes a sampler at this resolution may take, estimated before any
    /// table is built: [`BYTES_PER_CELL`] per tabulated cell of every
    /// slice. Saturates instead of overflowing.
    pub fn memory_estimate(&self) -> u64 {
        (self.slices() as u64)
            .saturating_mul(self.cells_per_slice() as u64)
            .saturating_mul(BYTES_PER_CELL)
    }
}

impl Default for Resolution {
    fn default() -> Self {
        Resolution::ISOTROPIC
    }
}

impl fmt::Display for Resolution {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{}x{}x{}x{}",
            self.theta_o, self.phi_o, self.theta_h, self.phi_h
        )
    }
}

impl FromStr for Resolution {
    type Err = Error;

    /// Parse `AxBxCxD` (θ_o, φ_o, θ_h, φ_h); surrounding white space is
    /// ignored, `X` is accepted for `x`.
    fn from_str(s: &str) -> Result<Self> {
        let invalid = |reason: String| Error::InvalidParameter {
            name: "resolution",
            reason,
        };
        let parts: Vec<&str> = s.trim().split(['x', 'X']).collect();
        if parts.len() != 4 {
            return Err(invalid(format!(
                "`{s}`: expected four counts like 32x16x256x32"
            )));
        }
        let mut n = [0usize; 4];
        for (slot, part) in n.iter_mut().zip(&parts) {
            *slot = part
                .trim()
                .parse()
                .map_err(|e| invalid(format!("`{s}`: `{part}` is not a count ({e})")))?;
        }
        Resolution::new(n[0], n[1], n[2], n[3])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parse_and_display_round_trip() {
        let r: Resolution = "32x16x256x32".parse().unwrap();
        assert_eq!(r, Resolution::PAPER);
        assert_eq!(r.to_string(), "32x16x256x32");
        assert_eq!(
            " 32X1x256x32 ".parse::<Resolution>().unwrap(),
            Resolution::ISOTROPIC
        );
        assert_eq!(Resolution::default(), Resolution::ISOTROPIC);
        assert_eq!(Resolution::PAPER.slices(), 512);
        assert_eq!(Resolution::PAPER.cells_per_slice(), 8192);
    }

    #[test]
    fn bad_resolutions_are_rejected() {
        for s in [
            "",
            "32x16x256",
            "32x16x256x32x1",
            "32x0x256x32",
            "axbxcxd",
            "-1x1x1x1",
            "1x1x100000x100000",
            "100000x100000x1x1",
            "99999999999999999999999x1x1x1",
        ] {
            assert!(
                matches!(s.parse::<Resolution>(), Err(Error::InvalidParameter { .. })),
                "{s}"
            );
        }
    }
}
