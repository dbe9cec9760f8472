//! What a slice is to the tabulated sampler: the two traits a sampler
//! family implements to plug its distribution into
//! [`TabulatedBrdfSampler`](crate::TabulatedBrdfSampler).
//!
//! - [`SliceDistribution`] is the distribution side: a [`Distribution2D`]
//!   over the half-vector square, plus the operations the sampler's fast
//!   paths ask of it (whether a drawn point's cell is certainly of one
//!   density, and draws and lookups across many slices at once). Every
//!   operation has a correct default, so a new distribution needs nothing
//!   beyond `Distribution2D` to work; it overrides what it can answer
//!   faster.
//! - The construction side is `acdf_core`'s [`TableBuilder`], the one
//!   builder trait of slices and environment tables: the sampler's name and
//!   how a tabulated slice becomes a distribution (for instance with which
//!   curve simplifier and tolerance). [`SliceBuilder`] names the builders
//!   whose distribution is a [`SliceDistribution`].

use acdf_core::{Distribution2D, Sample2D, TableBuilder, Vec2};

/// A distribution over the unit square (x → φ_h, y → θ_h) that a
/// [`TabulatedBrdfSampler`](crate::TabulatedBrdfSampler) draws half vectors
/// from.
///
/// The methods beyond [`Distribution2D`] are optional: each default is
/// correct and only slower than what a distribution that knows its own
/// layout can do. Overrides must return exactly what the defaults return
/// (bit for bit), since the sampler's one-at-a-time and batch paths rely on
/// giving identical results.
pub trait SliceDistribution: Distribution2D + Send + Sync + Sized {
    /// Whether this distribution can be the table of a slice tabulated on
    /// `n_x` (φ_h) × `n_y` (θ_h) cells: a sampler file records its
    /// resolution beside its slices, and a load checks the one against the
    /// other, so that an edited resolution is refused rather than used. The
    /// default accepts any grid; a distribution that knows its grid answers.
    fn fits_grid(&self, n_x: usize, n_y: usize) -> bool {
        let _ = (n_x, n_y);
        true
    }

    /// Whether `pdf` is the same at every point of the box
    /// [p.x ± margin.x] × [p.y ± margin.y], given that each margin is under
    /// half a tabulation cell.
    ///
    /// The sampler asks this to report a draw's density from the drawn cell
    /// instead of recomputing it from wi; `false` is always safe and only
    /// costs that recomputation. The default answers `false`: a
    /// distribution that can tell in a few operations overrides it.
    #[inline(always)]
    fn same_cell_around(&self, p: Vec2, margin: Vec2) -> bool {
        let _ = (p, margin);
        false
    }

    /// [`sample`](Distribution2D::sample) and
    /// [`same_cell_around`](Self::same_cell_around) of the sample, at once
    /// (a distribution can answer the box test from the draw's own search).
    #[inline(always)]
    fn sample_and_same_cell(&self, u: Vec2, margin: Vec2) -> (Sample2D, bool) {
        let s = self.sample(u);
        (s, self.same_cell_around(s.p, margin))
    }

    /// [`sample_batch`](Distribution2D::sample_batch) and, into `same`,
    /// [`same_cell_around`](Self::same_cell_around) of every sample (the
    /// three slices are equally long).
    fn sample_batch_and_same_cell(
        &self,
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
    ) {
        self.sample_batch(u, out);
        for (same, s) in same.iter_mut().zip(out.iter()) {
            *same = self.same_cell_around(s.p, margin);
        }
    }

    /// Draw `u[k]` from `dists[k]` for every k (the slices of a batch of
    /// shading points), exactly as `dists[k].sample(u[k])`. A distribution
    /// that can overlap draws from different slices overrides it.
    fn sample_each(dists: &[&Self], u: &[Vec2], out: &mut [Sample2D]) {
        for ((o, d), &u) in out.iter_mut().zip(dists).zip(u) {
            *o = d.sample(u);
        }
    }

    /// `dists[k].pdf(p[k])` for every k, bit for bit.
    fn pdf_each(dists: &[&Self], p: &[Vec2], out: &mut [f32]) {
        for ((o, d), &p) in out.iter_mut().zip(dists).zip(p) {
            *o = d.pdf(p);
        }
    }

    /// [`sample_each`](Self::sample_each) and, into `same`,
    /// [`same_cell_around`](Self::same_cell_around) of every sample in its
    /// own slice (the four slices are equally long).
    fn sample_each_and_same_cell(
        dists: &[&Self],
        u: &[Vec2],
        margin: Vec2,
        out: &mut [Sample2D],
        same: &mut [bool],
    ) {
        Self::sample_each(dists, u, out);
        for ((same, s), d) in same.iter_mut().zip(out.iter()).zip(dists) {
            *same = d.same_cell_around(s.p, margin);
        }
    }
}

/// A [`TableBuilder`] whose distribution can be a slice's: the builder of
/// a tabulated sampler family, which builds each slice with
/// [`TableBuilder::build_slice`]. Every such builder is one; a family
/// implements [`TableBuilder`] only.
pub trait SliceBuilder: TableBuilder<Dist: SliceDistribution> {}

impl<B: TableBuilder<Dist: SliceDistribution>> SliceBuilder for B {}
