//! The generic environment sampler: any 2D distribution over the unit
//! square, read as a latitude-longitude table, draws directions over the
//! sphere.

use acdf_core::simd::Avx2;
pub use acdf_core::TableBuilder;
use acdf_core::{Distribution2D, Result, Sample2D, SphereSample, SphereSampler, Vec2, Vec3};

use crate::envmap::EnvMap;
use crate::latlong::LatLong;
use crate::tables::TableKind;

/// Directions over the sphere drawn from a 2D distribution over the texels
/// of a lat-long grid: a point (u, v) of the distribution becomes the
/// direction of [`LatLong::direction_of_point`], and a direction's density
/// is the distribution's density at its texel's centre times the texel's
/// Jacobian. The shading normal is ignored.
///
/// `sample` returns the density of the texel it drew from, which is the
/// density `pdf` finds for the direction, unless the drawn point lies within
/// a thousandth of a texel of the texel's edge: then it returns `pdf` of the
/// direction, so that the two always agree.
#[derive(Debug, Clone)]
pub struct LatLongSampler<D> {
    name: String,
    grid: LatLong,
    dist: D,
}

impl<D: Distribution2D> LatLongSampler<D> {
    /// A sampler named `name` over `grid` with the distribution `dist`
    /// (whose density must be constant over each texel of `grid`).
    pub fn new(name: impl Into<String>, grid: LatLong, dist: D) -> Self {
        LatLongSampler {
            name: name.into(),
            grid,
            dist,
        }
    }

    /// The sampler of `map`'s table of `kind`, built by `builder`, named
    /// `name`.
    pub fn build<B: TableBuilder<Dist = D>>(
        name: impl Into<String>,
        map: &EnvMap,
        kind: TableKind,
        builder: &B,
    ) -> Result<Self> {
        let (w, h) = map.size();
        let dist = builder.build(&kind.table(map), w, h)?;
        Ok(Self::new(name, map.grid().clone(), dist))
    }

    /// [`sample`](SphereSampler::sample) itself.
    #[inline(always)]
    fn sample_one(&self, u: Vec2, _: Option<Avx2>) -> Option<SphereSample> {
        let s = self.dist.sample(u);
        finish_draw(
            &self.grid,
            s,
            |_, _| s.pdf,
            |dir| texel_density(&self.grid, &self.dist, dir),
        )
    }

    /// [`pdf`](SphereSampler::pdf) itself.
    #[inline(always)]
    fn pdf_one(&self, dir: Vec3, _: Option<Avx2>) -> f32 {
        texel_density(&self.grid, &self.dist, dir)
    }

    /// The distribution over the unit square.
    pub fn distribution(&self) -> &D {
        &self.dist
    }

    /// The texel grid.
    pub fn grid(&self) -> &LatLong {
        &self.grid
    }
}

/// The sphere sample of the distribution's draw `s`, whose density at a
/// texel is `density(column, row)` (for the draw's own texel when the draw
/// is inside it) and `pdf(dir)` otherwise.
///
/// A draw near its texel's edge can have a direction that rounds into the
/// neighbouring texel; its density is then that texel's, `pdf(dir)`. Where
/// that neighbour has no mass (a compensated or per-normal table is 0 over
/// whole regions), the draw would fail although its own texel has mass:
/// it is moved inside its texel by the margin instead
/// ([`LatLong::direction_of_point_inside`]), and has its texel's density.
/// The points so moved lie within rounding of a texel edge, a share of the
/// draws of order 1e-6.
#[inline(always)]
pub fn finish_draw(
    grid: &LatLong,
    s: Sample2D,
    density: impl FnOnce(usize, usize) -> f32,
    pdf: impl FnOnce(Vec3) -> f32,
) -> Option<SphereSample> {
    let (dir, column, row, inside) = grid.direction_of_point(s.p);
    let (dir, pdf) = if inside {
        (dir, density(column, row) * grid.inv_jacobian(row))
    } else {
        let p = pdf(dir);
        if positive_finite(p) {
            (dir, p)
        } else {
            (
                grid.direction_of_point_inside(s.p),
                density(column, row) * grid.inv_jacobian(row),
            )
        }
    };
    positive_finite(pdf).then_some(SphereSample { dir, pdf })
}

/// pdf > 0 and finite, as one integer compare: the bit patterns of the
/// positive finite floats are 1 ..= 0x7f7f_ffff (NaN, infinities, zeros and
/// negatives fall outside).
#[inline(always)]
fn positive_finite(pdf: f32) -> bool {
    pdf.to_bits().wrapping_sub(1) < 0x7f7f_ffff
}

/// The solid-angle density of `dir` under a distribution over `grid`'s
/// texels: `dist.pdf` at the centre of the texel holding `dir`, times the
/// texel's Jacobian; 0 for a direction that is not finite or has no length.
#[inline(always)]
pub fn texel_density<D: Distribution2D + ?Sized>(grid: &LatLong, dist: &D, dir: Vec3) -> f32 {
    match grid.texel_of(dir) {
        Some((k, j)) => dist.pdf(grid.texel_centre(k, j)) * grid.inv_jacobian(j),
        None => 0.0,
    }
}

impl<D: Distribution2D> SphereSampler for LatLongSampler<D> {
    fn name(&self) -> &str {
        &self.name
    }

    #[inline]
    fn sample(&self, _normal: Option<Vec3>, u: Vec2) -> Option<SphereSample> {
        acdf_core::dispatch!(Self::sample_one, self, u)
    }

    #[inline]
    fn pdf(&self, _normal: Option<Vec3>, dir: Vec3) -> f32 {
        acdf_core::dispatch!(Self::pdf_one, self, dir)
    }

    fn storage_bytes(&self) -> usize {
        self.dist.storage_bytes()
    }

    /// The distribution's batch draws, then one direction each.
    fn sample_batch(&self, _normal: Option<Vec3>, u: &[Vec2], out: &mut [Option<SphereSample>]) {
        let mut draws = [Sample2D::default(); 64];
        for (u, out) in u.chunks(64).zip(out.chunks_mut(64)) {
            let n = u.len().min(out.len());
            self.dist.sample_batch(&u[..n], &mut draws[..n]);
            for (o, &s) in out.iter_mut().zip(&draws[..n]) {
                *o = finish_draw(
                    &self.grid,
                    s,
                    |_, _| s.pdf,
                    |dir| texel_density(&self.grid, &self.dist, dir),
                );
            }
        }
    }

    /// The texel centres, then the distribution's batch densities.
    fn pdf_batch(&self, _normal: Option<Vec3>, dir: &[Vec3], out: &mut [f32]) {
        let mut points = [Vec2::ZERO; 64];
        let mut rows = [usize::MAX; 64];
        let mut dens = [0.0f32; 64];
        for (dir, out) in dir.chunks(64).zip(out.chunks_mut(64)) {
            let n = dir.len().min(out.len());
            for ((p, r), &d) in points.iter_mut().zip(rows.iter_mut()).zip(&dir[..n]) {
                (*p, *r) = match self.grid.texel_of(d) {
                    Some((k, j)) => (self.grid.texel_centre(k, j), j),
                    None => (Vec2::ZERO, usize::MAX),
                };
            }
            self.dist.pdf_batch(&points[..n], &mut dens[..n]);
            for ((o, &p), &r) in out.iter_mut().zip(&dens[..n]).zip(&rows[..n]) {
                *o = if r == usize::MAX {
                    0.0
                } else {
                    p * self.grid.inv_jacobian(r)
                };
            }
        }
    }
}
