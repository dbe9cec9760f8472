//! `acdf-lights` makes environment maps into lights that acdf's
//! environment samplers can importance-sample. It reads latitude-longitude
//! Radiance `.hdr` and OpenEXR images through the `image` crate
//! ([`EnvMap`], with typed errors for files that are not lat-long maps or
//! carry NaN, infinite or negative texels), fixes the one direction
//! convention of every map and sampler ([`latlong`]: `+z` up, row 0 at the
//! zenith, φ = 0 along `+x`), and holds what the sampler plug-ins share, as
//! `acdf-tabulated` does for the BRDF samplers: the tables a sampler follows
//! ([`tables`]: luminance, compensated, per shading normal), the generic
//! sampler over any 2D distribution of a table ([`LatLongSampler`]), and the
//! generic orientation-aware sampler with its lazily built normal cells
//! ([`OrientedSampler`]). A plug-in supplies only the 2D distribution
//! through a [`TableBuilder`]; plug-ins depend on this crate and on
//! `acdf-core`, never on each other. [`EnvironmentLight`] pairs a map with
//! any sampler as an `acdf_core::Light`.
//!
//! # Example
//!
//! ```
//! use acdf_core::{Distribution2D, Light, Rgb, Vec2, Vec3};
//! use acdf_lights::{EnvMap, EnvironmentLight, LatLongSampler, TableBuilder, TableKind};
//!
//! // A 2D distribution: the crate leaves it to plug-ins; here, a trivial
//! // one that is uniform over the unit square (uniform in texels).
//! struct Flat;
//! impl Distribution2D for Flat {
//!     fn sample(&self, u: Vec2) -> acdf_core::Sample2D {
//!         acdf_core::Sample2D { p: u.clamp(Vec2::ZERO, Vec2::splat(0.999_999)), pdf: 1.0 }
//!     }
//!     fn pdf(&self, p: Vec2) -> f32 { 1.0 }
//!     fn invert(&self, p: Vec2) -> Vec2 { p }
//!     fn integral(&self) -> f64 { 1.0 }
//!     fn storage_bytes(&self) -> usize { 0 }
//! }
//! struct FlatBuilder;
//! impl TableBuilder for FlatBuilder {
//!     type Dist = Flat;
//!     fn name(&self) -> String { "flat".into() }
//!     fn build(&self, _: &[f32], _: usize, _: usize) -> acdf_core::Result<Flat> { Ok(Flat) }
//! }
//!
//! // A sky brighter overhead, 64 x 32 texels.
//! let map = EnvMap::from_fn(64, 32, |_, row| Rgb::splat(if row < 16 { 2.0 } else { 0.5 }))?;
//! let sampler = LatLongSampler::build("flat", &map, TableKind::Luminance, &FlatBuilder)?;
//! let light = EnvironmentLight::new(map.into(), sampler);
//! assert_eq!(light.radiance(Vec3::Z), Rgb::splat(2.0));
//! let s = light.sample(None, Vec2::new(0.3, 0.2)).unwrap();
//! assert!(s.dir.z > 0.0 && s.pdf > 0.0);
//! assert_eq!(s.pdf, light.pdf(None, s.dir));
//! # Ok::<(), acdf_lights::EnvError>(())
//! ```

#![allow(clippy::neg_cmp_op_on_partial_ord)]
#![forbid(unsafe_code)]

pub mod envmap;
pub mod error;
pub mod latlong;
pub mod light;
pub mod oriented;
pub mod sampler;
pub mod tables;

pub use envmap::{EnvMap, Repairs};
pub use error::{EnvError, Result};
pub use latlong::LatLong;
pub use light::EnvironmentLight;
pub use oriented::{NormalGrid, OrientedSampler};
pub use sampler::{finish_draw, texel_density, LatLongSampler, TableBuilder};
pub use tables::{compensated_table, luminance_table, oriented_table, TableKind};
