//! An adaptive 2D CDF over the texels of an environment map in a compact
//! form: the orientation-aware sampler keeps one table per region of
//! normals, and a scene whose normals reach a few dozen regions reads all
//! of them, so their size decides how many of their reads hit the cache.
//!
//! [`PackedEnvCdf2D`] keeps the vertices an [`AdaptiveCdf2D`] chose and
//! recomputes their masses from the table: the conditionals (nearly all of
//! the storage) as 16-bit column indices and 16-bit CDF values, 4 bytes a
//! vertex instead of 8; the marginal (a few hundred vertices) as `f32`
//! row positions and CDF values in units of 2^-24, searched through a
//! guide that also holds the one value most of its cells contain. Every
//! segment whose texels hold mass keeps at least one unit of its curve,
//! so every texel with a positive table value has a positive density, and
//! the density returned with a draw is the one
//! [`pdf`](Distribution2D::pdf) gives its point: the quantisation changes
//! which distribution is sampled (slightly), never the exactness of its
//! density.

use acdf_core::search::{count_one, mask_at_or_below, short_window_at_or_below_u32, Guide, WINDOW};
use acdf_core::{clamp_unit, Distribution2D, Error, Result, Sample2D, Vec2, ONE_MINUS_EPSILON};
use acdf_lights::TableBuilder;

use crate::curve::{f32_below, segment_density, segment_samples, Segment};
use crate::{AdaptiveBuilder, AdaptiveCdf2D};

/// The cells of the marginal's guide over u.y: fine enough that most
/// cells hold at most one of the marginal's CDF values, which the guide
/// keeps, so that the marginal segment is found from the guide alone.
/// Each cell spans 2^16 units of the marginal's CDF (2^-24).
pub const MARGINAL_GUIDE_CELLS: usize = 256;
/// log2 of the marginal CDF units per guide cell: a CDF value's cell is
/// value >> this.
const MARGINAL_CELL_SHIFT: u32 = 16;
const _: () = assert!(MARGINAL_GUIDE_CELLS << MARGINAL_CELL_SHIFT == Q24 as usize);

/// The largest quantised conditional CDF value: c is stored as about
/// c · 65535.
const Q16: u32 = u16::MAX as u32;
/// The marginal's CDF unit, 2^-24: multiples of it below 1 are exact in
/// `f32`, and so are their differences.
const Q24: u32 = 1 << 24;
/// A packed conditional vertex: column index in the low 16 bits, quantised
/// CDF value in the high 16.
type Pair = u32;

/// The cells of each conditional's guide over u.x (a power of two: cell
/// k holds the quantised keys k · 65536 / G ..= (k + 1) · 65536 / G − 1).
pub const CONDITIONAL_GUIDE_CELLS: usize = 16;
/// log2 of 65536 / [`CONDITIONAL_GUIDE_CELLS`]: a key's cell is key >> this.
const CONDITIONAL_CELL_SHIFT: u32 = 16 - CONDITIONAL_GUIDE_CELLS.trailing_zeros();
/// The candidates of a conditional's search compared at once without a
/// four-way step, when the guide leaves no more.
const SHORT_WINDOW: usize = 8;

/// One conditional's guide: entry k is the number of its inner vertices
/// (all but the first and last) whose CDF value is at most the last key of
/// cell k, so the vertices a key of cell k must be compared with are
/// those from entry k − 1 (0 for k = 0) to entry k. One cache line holds
/// it (32 bytes, aligned).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C, align(32))]
struct ConditionalGuide([u16; CONDITIONAL_GUIDE_CELLS]);

impl ConditionalGuide {
    /// The guide of a conditional with the quantised CDF values `cdf`.
    fn new(cdf: &[u32]) -> ConditionalGuide {
        let inner = &cdf[1..cdf.len().max(2) - 1];
        ConditionalGuide(std::array::from_fn(|k| {
            let last = (((k + 1) << CONDITIONAL_CELL_SHIFT) - 1) as u32;
            // At most 65534 inner vertices: columns are below 2^16.
            inner.partition_point(|&c| c <= last) as u16
        }))
    }

    /// The inner vertices (offsets from the first inner one, start and
    /// count) that a key of cell `cell` is compared with.
    #[inline(always)]
    fn candidates(&self, cell: usize) -> (usize, usize) {
        let hi = self.0[cell] as usize;
        let lo = if cell > 0 {
            self.0[cell - 1] as usize
        } else {
            0
        };
        (lo, hi.saturating_sub(lo))
    }
}

/// One marginal vertex: its row position j / n_y, and the first conditional
/// vertex of the marginal segment that starts at it (for the last vertex,
/// the end of the conditionals).
#[derive(Debug, Clone, Copy, PartialEq)]
#[repr(C)]
struct MarginalVertex {
    y: f32,
    first: u32,
}

/// A piecewise-linear 2D CDF over the unit square whose vertices lie on the
/// texel grid of an `n_x` × `n_y` table: a marginal over rows (y) and, per
/// marginal segment, a conditional over columns (x). See the module
/// documentation.
///
/// The layout follows the chain of reads of a draw, so that the chain has
/// few links: the marginal's guide is read first, from u.y alone (an
/// allocation of its own, so that the slots of regions not yet built stay
/// small), and for a cell with at most one CDF value (96% of the
/// benchmark's draws on rooitou_park's region tables) it holds that value
/// too, so the marginal segment follows from the guide's entry without a
/// read of the CDF values; the marginal's CDF values are contiguous, for
/// the window that compares 32 of them at once in the other cells; each
/// marginal vertex carries its row position and its conditional's first
/// vertex together (one read gives both); a conditional's vertices are
/// packed pairs (column index, CDF value) in one `u32`, so that the window
/// searched for u.x also holds the segment's ends; and each conditional
/// has a guide over u.x that leaves at most 8 candidates for three draws
/// in four (rooitou_park's region tables, counted over the benchmark's
/// draws), so that the window is found without the four-way steps that
/// long conditionals need.
///
/// Storage: 12 bytes per marginal vertex, 1028 for the marginal's guide,
/// 4 bytes per conditional vertex, 32 per marginal segment for its
/// conditional's guide, and padding after the marginal's CDF values and
/// the conditionals (32 entries each) so that a window can always be read.
#[derive(Debug, Clone, PartialEq)]
pub struct PackedEnvCdf2D {
    /// Entry g: in the high 16 bits, the number of the marginal's inner
    /// CDF values (c_1 .. c_{m−2}) below 1 whose cell is below g, so that
    /// cell g's candidates run from entry g's count to entry g + 1's; in
    /// the low 16 bits, the first candidate's value less g · 2^16, in units
    /// of 2^-24 (0 when the cell has none). Values of 1 are left out: no u
    /// reaches them.
    guide: Box<[u32; MARGINAL_GUIDE_CELLS + 1]>,
    /// The marginal's m CDF values (multiples of 2^-24 from 0 to 1), then
    /// the padding (1.0).
    marginal_cdf: Box<[f32]>,
    /// The marginal's m vertices.
    marginal: Box<[MarginalVertex]>,
    /// The conditionals' vertices (column index 0 = p_0 < ... < p_{k-1} =
    /// n_x, CDF values 0 = c_0 <= ... <= c_{k-1} = 65535), one conditional
    /// after another, then the padding (all ones).
    conditionals: Box<[Pair]>,
    /// Per marginal segment, its conditional's guide (all zeros for a
    /// segment without mass).
    conditional_guide: Box<[ConditionalGuide]>,
    n_x: f32,
    /// n_x / 65535: a conditional segment's density is its mass in units
    /// times this, over its width in columns.
    density_scale: f32,
    integral: f64,
}

/// The typed error of a table the packed form cannot hold.
fn too_large(reason: String) -> Error {
    Error::InvalidParameter {
        name: "packed environment table",
        reason,
    }
}

impl PackedEnvCdf2D {
    /// The packed form of `d`, built from `values` (row-major, `n_y` rows of
    /// `n_x`, the table `d` was built from): the vertices `d` kept, with
    /// their masses summed from the table in f64 and quantised. An error
    /// when `d`'s vertices are off the texel grid or the table has more
    /// than 65535 columns or rows.
    pub fn from_adaptive(
        d: &AdaptiveCdf2D,
        values: &[f32],
        n_x: usize,
        n_y: usize,
    ) -> Result<Self> {
        if n_x == 0 || n_y == 0 || values.len() != n_x * n_y {
            return Err(Error::SizeMismatch {
                what: "packed environment table",
                expected: n_x * n_y,
                got: values.len(),
            });
        }
        // Rows: the guide counts the marginal's vertices in 16 bits.
        if n_x > Q16 as usize || n_y > Q16 as usize {
            return Err(too_large(format!(
                "{n_x} x {n_y} texels: at most 65535 columns and 65535 rows"
            )));
        }
        let rows = row_sums(values, n_x);
        let total: f64 = rows.iter().sum();
        let cells = (n_x * n_y) as f64;
        let m = d.marginal_vertex_count();
        let marginal_rows = grid_indices(&d.marginal[..m], n_y)?;
        let (marginal_rows, segment_mass) = if total > 0.0 {
            let mass = segment_masses(&rows, &marginal_rows);
            (marginal_rows, mass)
        } else {
            // No mass: the uniform density over one segment.
            (vec![0, n_y], vec![1.0])
        };
        let quantised = quantise(&segment_mass, Q24);
        let mut marginal_cdf: Vec<f32> = quantised
            .iter()
            .map(|&c| (c as f64 / Q24 as f64) as f32)
            .collect();

        let mut firsts = vec![0u32];
        let mut conditionals: Vec<Pair> = Vec::new();
        let mut conditional_guide: Vec<ConditionalGuide> = Vec::new();
        for (j, w) in marginal_rows.windows(2).enumerate() {
            if quantised[j + 1] > quantised[j] {
                let xs = if total > 0.0 {
                    let (a, b) = (d.offsets[j] as usize, d.offsets[j + 1] as usize);
                    &d.conditionals[2 * a..2 * a + (b - a)]
                } else {
                    &[][..]
                };
                let pos = if xs.len() >= 2 {
                    grid_indices(xs, n_x)?
                } else {
                    vec![0, n_x]
                };
                let columns = if total > 0.0 {
                    column_sums(values, n_x, w[0]..w[1])
                } else {
                    vec![1.0; n_x]
                };
                let masses = segment_masses(&columns, &pos);
                let cdf = quantise(&masses, Q16);
                conditionals.extend(pos.iter().zip(&cdf).map(|(&p, &c)| p as u32 | c << 16));
                conditional_guide.push(ConditionalGuide::new(&cdf));
            } else {
                conditional_guide.push(ConditionalGuide([0; CONDITIONAL_GUIDE_CELLS]));
            }
            let end = u32::try_from(conditionals.len())
                .map_err(|_| too_large("more than 2^32 conditional vertices".into()))?;
            firsts.push(end);
        }
        conditionals.extend([Pair::MAX; WINDOW]);
        let marginal: Vec<MarginalVertex> = marginal_rows
            .iter()
            .zip(&firsts)
            .map(|(&j, &first)| MarginalVertex {
                y: (j as f64 / n_y as f64) as f32,
                first,
            })
            .collect();
        // The inner values in units, whose cell is value >> 16 (256 for 1,
        // which no cell holds).
        let inner = &quantised[1..quantised.len() - 1];
        let mut guide = [0u32; MARGINAL_GUIDE_CELLS + 1];
        let mut k = 0;
        for (g, entry) in guide.iter_mut().enumerate() {
            let cell_of = |c: u32| (c >> MARGINAL_CELL_SHIFT) as usize;
            while k < inner.len() && cell_of(inner[k]) < g {
                k += 1;
            }
            let first = match inner.get(k) {
                Some(&c) if cell_of(c) == g => c & 0xffff,
                _ => 0,
            };
            // k < 2^16: at most n_y − 1 inner values.
            *entry = (k as u32) << 16 | first;
        }
        marginal_cdf.extend([1.0f32; WINDOW]);
        Ok(PackedEnvCdf2D {
            guide: Box::new(guide),
            marginal_cdf: marginal_cdf.into_boxed_slice(),
            marginal: marginal.into_boxed_slice(),
            conditionals: conditionals.into_boxed_slice(),
            conditional_guide: conditional_guide.into_boxed_slice(),
            n_x: n_x as f32,
            density_scale: (n_x as f64 / Q16 as f64) as f32,
            integral: if total > 0.0 { total / cells } else { 0.0 },
        })
    }

    /// The number of marginal vertices.
    pub fn marginal_vertex_count(&self) -> usize {
        self.marginal.len()
    }

    /// The number of conditional vertices stored, over all conditionals.
    pub fn conditional_vertex_total(&self) -> usize {
        self.conditionals.len() - WINDOW
    }

    /// Marginal segment j, from vertex j to j + 1.
    #[inline(always)]
    fn marginal_segment(&self, j: usize) -> (Segment, usize, usize) {
        let (v0, v1) = (self.marginal[j], self.marginal[j + 1]);
        let segment = Segment {
            x0: v0.y,
            x1: v1.y,
            c0: self.marginal_cdf[j],
            c1: self.marginal_cdf[j + 1],
        };
        (segment, v0.first as usize, v1.first as usize)
    }

    /// The marginal segment a draw with uy (in [0, 1)) falls in: the
    /// number of inner CDF values at or below uy. The guide's cell of uy
    /// leaves its candidates; one candidate (or none) is compared with the
    /// value the guide holds, more are searched in the CDF values.
    #[inline(always)]
    fn drawn_marginal_segment(&self, uy: f32) -> usize {
        let g = Guide::cell(uy, MARGINAL_GUIDE_CELLS);
        let (entry, next) = (self.guide[g], self.guide[g + 1]);
        let (a, b) = ((entry >> 16) as usize, (next >> 16) as usize);
        if b - a <= 1 {
            // Exact: an integer below 2^24 times a power of two.
            let c =
                ((g as u32) << MARGINAL_CELL_SHIFT | (entry & 0xffff)) as f32 * (1.0 / Q24 as f32);
            a + ((b > a) & (c <= uy)) as usize
        } else {
            a + count_one(&self.marginal_cdf, 1 + a, b - a, uy)
        }
    }

    /// The marginal segment j holding y in [0, 1): the last vertex at or
    /// below y.
    #[inline]
    fn marginal_segment_of(&self, y: f32) -> usize {
        let m = self.marginal.len();
        self.marginal[1..m - 1].partition_point(|v| v.y <= y)
    }

    /// The segment of a conditional (vertices `first..end`, at least two)
    /// holding column position t: the last vertex whose column is at or
    /// below t.
    #[inline]
    fn conditional_segment_of(&self, first: usize, end: usize, t: f32) -> usize {
        first
            + self.conditionals[first + 1..end - 1].partition_point(|&e| ((e & 0xffff) as f32) <= t)
    }

    /// The density of the conditional segment from vertex i to i + 1.
    #[inline(always)]
    fn conditional_density(&self, e0: Pair, e1: Pair) -> f32 {
        let mass = ((e1 >> 16) - (e0 >> 16)) as f32;
        let width = ((e1 & 0xffff) - (e0 & 0xffff)) as f32;
        mass * self.density_scale / width
    }
}

impl Distribution2D for PackedEnvCdf2D {
    /// y from the marginal with u.y, then x from the conditional of y's
    /// marginal segment with u.x: x = (p_k + (u' − c_k) / (c_{k+1} − c_k)
    /// (p_{k+1} − p_k)) / n_x with u' = u.x · 65535 and c_k <= ⌊u'⌋ <
    /// c_{k+1}; pdf = p_marginal(y) · (c_{k+1} − c_k) n_x / (65535 (p_{k+1}
    /// − p_k)).
    #[inline(always)]
    fn sample(&self, u: Vec2) -> Sample2D {
        let uy = clamp_unit(u.y);
        let us = clamp_unit(u.x) * Q16 as f32;
        let key = ((us as u32) << 16) | 0xffff;
        let cell = (us as u32 >> CONDITIONAL_CELL_SHIFT) as usize;
        let j = self.drawn_marginal_segment(uy);
        let (segment, first, _) = self.marginal_segment(j);
        let ([y], [py]) = segment_samples(&[segment], &[uy]);
        // A drawn segment has mass, so its conditional has two vertices or
        // more, and the guide's candidates lie between them.
        let (lo, n) = self.conditional_guide[j].candidates(cell);
        let start = first + 1 + lo;
        let i = first
            + lo
            + if n <= SHORT_WINDOW {
                count_short_window(&self.conditionals, start, n, key)
            } else {
                count_one(&self.conditionals, start, n, key)
            };
        let (e0, e1) = (self.conditionals[i], self.conditionals[i + 1]);
        let (c0, c1) = ((e0 >> 16) as f32, (e1 >> 16) as f32);
        let (p0, p1) = ((e0 & 0xffff) as f32, (e1 & 0xffff) as f32);
        let frac = ((us - c0) / (c1 - c0)).clamp(0.0, 1.0);
        // Kept below p_{k+1}, so that `pdf` finds the segment again (exactly
        // when n_x is a power of two; the samplers' texel margins cover
        // the rounding of x n_x otherwise).
        let t = (p0 + frac * (p1 - p0)).min(f32_below(p1));
        let x = (t / self.n_x).min(ONE_MINUS_EPSILON);
        Sample2D {
            p: Vec2::new(x, y),
            pdf: py * self.conditional_density(e0, e1),
        }
    }

    /// The marginal density of y's segment times the conditional density
    /// of x's segment; 0 outside [0, 1)^2 and on segments without mass.
    #[inline]
    fn pdf(&self, p: Vec2) -> f32 {
        if !((0.0..1.0).contains(&p.x) && (0.0..1.0).contains(&p.y)) {
            return 0.0;
        }
        let j = self.marginal_segment_of(p.y);
        let (segment, first, end) = self.marginal_segment(j);
        let py = segment_density(segment);
        if py == 0.0 || end < first + 2 {
            return 0.0;
        }
        let i = self.conditional_segment_of(first, end, p.x * self.n_x);
        py * self.conditional_density(self.conditionals[i], self.conditionals[i + 1])
    }

    /// (P_marginal(y), P_j(x)) with j the marginal segment of y, both
    /// piecewise linear through the stored vertices.
    fn invert(&self, p: Vec2) -> Vec2 {
        let clamp = |v: f32| if v > 0.0 { v.min(1.0) } else { 0.0 };
        let (x, y) = (clamp(p.x), clamp(p.y));
        let j = self.marginal_segment_of(y);
        let (s, first, end) = self.marginal_segment(j);
        let fy = ((y - s.x0) / (s.x1 - s.x0)).clamp(0.0, 1.0);
        let uy = (s.c0 + fy * (s.c1 - s.c0)).clamp(s.c0, s.c1);
        if end < first + 2 {
            return Vec2::new(x, uy);
        }
        let t = x * self.n_x;
        let i = self.conditional_segment_of(first, end, t);
        let (e0, e1) = (self.conditionals[i], self.conditionals[i + 1]);
        let (p0, p1) = ((e0 & 0xffff) as f32, (e1 & 0xffff) as f32);
        let (c0, c1) = ((e0 >> 16) as f32, (e1 >> 16) as f32);
        let f = ((t - p0) / (p1 - p0)).clamp(0.0, 1.0);
        Vec2::new(((c0 + f * (c1 - c0)) / Q16 as f32).min(1.0), uy)
    }

    /// The table's mean value.
    fn integral(&self) -> f64 {
        self.integral
    }

    /// The guide, the marginal's CDF values and vertices, the conditionals
    /// and the padding.
    fn storage_bytes(&self) -> usize {
        std::mem::size_of_val(&*self.guide)
            + std::mem::size_of_val(&*self.marginal_cdf)
            + std::mem::size_of_val(&*self.marginal)
            + std::mem::size_of_val(&*self.conditionals)
            + std::mem::size_of_val(&*self.conditional_guide)
    }
}

/// Builds [`PackedEnvCdf2D`]s: the adaptive table of the wrapped
/// [`AdaptiveBuilder`], packed.
#[derive(Debug, Clone)]
pub struct PackedEnvBuilder(pub AdaptiveBuilder);

impl TableBuilder for PackedEnvBuilder {
    type Dist = PackedEnvCdf2D;

    /// `adaptive:NAME`, the simplifier's family.
    fn name(&self) -> String {
        TableBuilder::name(&self.0)
    }

    fn build(&self, values: &[f32], nx: usize, ny: usize) -> Result<PackedEnvCdf2D> {
        let d = self.0.build(values, nx, ny)?;
        PackedEnvCdf2D::from_adaptive(&d, values, nx, ny)
    }
}

/// Grid indices k of positions k / n (exact for the vertices a simplifier
/// keeps of a tabulated CDF): the stored form of a curve's positions, for
/// the packed environment tables and the outgoing samplers' slices. The
/// error is the first position off the grid.
pub(crate) fn grid_positions(xs: &[f32], n: usize) -> std::result::Result<Vec<usize>, f32> {
    xs.iter()
        .map(|&x| {
            let t = x as f64 * n as f64;
            let k = t.round();
            if (t - k).abs() > 1e-3 || k < 0.0 || k > n as f64 {
                Err(x)
            } else {
                Ok(k as usize)
            }
        })
        .collect()
}

/// [`grid_positions`], an error of the packed table for a position off
/// the grid.
fn grid_indices(xs: &[f32], n: usize) -> Result<Vec<usize>> {
    grid_positions(xs, n)
        .map_err(|x| too_large(format!("vertex at {x} is not on the grid of {n} cells")))
}

/// The sums of the rows of `values` (rows of `n_x`), in f64.
pub(crate) fn row_sums(values: &[f32], n_x: usize) -> Vec<f64> {
    values
        .chunks_exact(n_x)
        .map(|r| r.iter().map(|&v| v as f64).sum())
        .collect()
}

/// The masses between consecutive indices `bounds` of the per-row or
/// per-column sums `sums`: a curve's segment masses.
pub(crate) fn segment_masses<I: Copy + Into<usize>>(sums: &[f64], bounds: &[I]) -> Vec<f64> {
    bounds
        .windows(2)
        .map(|w| sums[w[0].into()..w[1].into()].iter().sum())
        .collect()
}

/// The sums of the columns of `values` (rows of `n_x`) over the rows
/// `rows` (a marginal segment), in f64.
pub(crate) fn column_sums(values: &[f32], n_x: usize, rows: std::ops::Range<usize>) -> Vec<f64> {
    let mut columns = vec![0.0f64; n_x];
    for row in values[rows.start * n_x..rows.end * n_x].chunks_exact(n_x) {
        for (c, &v) in columns.iter_mut().zip(row) {
            *c += v as f64;
        }
    }
    columns
}

/// Quantised CDF values (0 to `q`) of segments with these masses (not all
/// zero): round(c · q) of the exact CDF c, except that a segment with mass
/// keeps at least one unit and a segment without keeps none (so the curve
/// needs fewer positive segments than q). The last value is q: a trailing
/// run of empty segments keeps the value the last positive one carried to
/// q. The one quantisation of the packed environment and outgoing tables.
pub fn quantise(masses: &[f64], q: u32) -> Vec<u32> {
    let total: f64 = masses.iter().sum();
    let mut positive_after = vec![0u32; masses.len() + 1];
    for i in (0..masses.len()).rev() {
        positive_after[i] = positive_after[i + 1] + (masses[i] > 0.0) as u32;
    }
    let mut out = Vec::with_capacity(masses.len() + 1);
    out.push(0u32);
    let mut running = 0.0f64;
    for (i, &mass) in masses.iter().enumerate() {
        running += mass;
        let previous = *out.last().expect("one value");
        let v = if mass > 0.0 {
            let target = (running / total * q as f64).round() as u32;
            target
                .max(previous + 1)
                .min(q.saturating_sub(positive_after[i + 1]))
        } else {
            previous
        };
        out.push(v);
    }
    out
}

/// The number of the packed vertices `data[start..start + len]`, `len` at
/// most [`SHORT_WINDOW`], whose pair is `<= key`, when the vertex after
/// them is above the key (as the conditional guide's candidates are): the
/// run of ones from the first bit of one compare of [`SHORT_WINDOW`]
/// entries ([`short_window_at_or_below_u32`]; it may reach into the
/// padding after the conditionals). A `data` without room for the window
/// after `start` (none of the packed tables, whose padding leaves it) is
/// compared entry by entry up to its end.
#[inline(always)]
fn count_short_window(data: &[u32], start: usize, len: usize, key: u32) -> usize {
    let mask = match data.get(start..start + SHORT_WINDOW) {
        Some(window) => short_window_at_or_below_u32(
            window.try_into().expect("a window of SHORT_WINDOW entries"),
            key,
        ),
        None => mask_at_or_below(&data[start.min(data.len())..], key),
    };
    (mask.trailing_ones() as usize).min(len)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::DouglasPeucker;
    use acdf_core::search::Key;
    use rand::{Rng, SeedableRng};

    /// Both window compares (32 and 8 entries) give the portable form's
    /// bits, for random windows and keys at the edges of the signed and
    /// unsigned ranges.
    #[test]
    fn window_masks_agree_with_the_portable_compare() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        for _ in 0..2000 {
            let w: [u32; WINDOW] = std::array::from_fn(|_| rng.random());
            let short: &[u32; SHORT_WINDOW] = w[..SHORT_WINDOW].try_into().unwrap();
            for key in [
                0,
                1,
                i32::MAX as u32,
                1 << 31,
                u32::MAX - 1,
                u32::MAX,
                rng.random(),
                w[3],
                w[20],
            ] {
                assert_eq!(u32::window_mask(&w, key), mask_at_or_below(&w, key));
                assert_eq!(
                    short_window_at_or_below_u32(short, key),
                    mask_at_or_below(short, key)
                );
            }
        }
    }

    /// A short count over a list with no room for the window after it
    /// compares up to the list's end and gives the plain count.
    #[test]
    fn short_counts_without_padding_stop_at_the_end() {
        for len in 0..=SHORT_WINDOW {
            let data: Vec<u32> = (0..len as u32).map(|i| (3 * i) << 16 | i).collect();
            for start in 0..=len {
                for k in 0..(3 * len as u32 + 2) {
                    let key = k << 16 | 0xffff;
                    let expected = data[start..].partition_point(|&e| e <= key);
                    let n = len - start;
                    assert_eq!(
                        count_short_window(&data, start, n, key),
                        expected,
                        "{len} entries from {start}, key {k}"
                    );
                }
            }
        }
    }

    #[test]
    fn counts_agree_with_a_partition_point() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(4);
        for len in [0usize, 1, 2, 5, 31, 32, 33, 64, 100, 257, 1000] {
            let mut cdf: Vec<u32> = (0..len).map(|_| rng.random_range(0..2000)).collect();
            cdf.sort_unstable();
            let list: Vec<u32> = cdf
                .iter()
                .map(|&c| c << 16 | rng.random_range(0..1024))
                .collect();
            for pad in [0, WINDOW] {
                let mut data = vec![7u32; 3];
                data.extend(&list);
                data.extend(vec![0u32; pad]);
                for k in 0..2010u32 {
                    let expected = cdf.partition_point(|&c| c <= k);
                    let key = k << 16 | 0xffff;
                    assert_eq!(count_one(&data, 3, len, key), expected, "{len} {k}");
                }
            }
        }
    }

    /// The conditional guide's candidates, searched as `sample` searches
    /// them, give the plain count of inner CDF values at or below the key,
    /// for every key: on conditionals of 2 to 3000 vertices with runs of
    /// equal values (empty segments), values crowded into one cell (more
    /// candidates than the short window) and values on cell edges.
    #[test]
    fn guided_counts_are_the_plain_count() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(6);
        for (len, crowd) in [
            (2usize, false),
            (3, false),
            (9, true),
            (40, false),
            (40, true),
            (700, false),
            (3000, true),
        ] {
            let mut inner: Vec<u32> = (0..len - 2)
                .map(|_| match rng.random_range(0..4) {
                    0 if crowd => rng.random_range(8192..8200),
                    1 => (rng.random_range(0..16u32) << CONDITIONAL_CELL_SHIFT)
                        .saturating_sub(rng.random_range(0..2)),
                    _ => rng.random_range(0..Q16),
                })
                .collect();
            inner.sort_unstable();
            let cdf: Vec<u32> = std::iter::once(0)
                .chain(inner.iter().copied())
                .chain([Q16])
                .collect();
            let guide = ConditionalGuide::new(&cdf);
            let mut data = vec![5u32; 3];
            data.extend(
                cdf.iter()
                    .enumerate()
                    .map(|(i, &c)| (c << 16) | (i as u32 % 1024)),
            );
            data.extend([Pair::MAX; WINDOW]);
            for k in (0..Q16)
                .step_by(7)
                .chain([0, 4095, 4096, 8191, 8192, 65534])
            {
                let key = k << 16 | 0xffff;
                let (lo, n) = guide.candidates((k >> CONDITIONAL_CELL_SHIFT) as usize);
                let start = 3 + 1 + lo;
                let got = lo
                    + if n <= SHORT_WINDOW {
                        count_short_window(&data, start, n, key)
                    } else {
                        count_one(&data, start, n, key)
                    };
                assert_eq!(
                    got,
                    inner.partition_point(|&c| c <= k),
                    "{len} vertices, key {k}"
                );
            }
        }
    }

    /// The marginal segment a draw finds through the guide is the plain
    /// count of inner CDF values at or below u.y, for every u.y on a fine
    /// lattice, at every CDF value and a float step either side, and next
    /// to 1: on marginals whose values are spread (cells of one value or
    /// none), crowded (a cell with more than the window), repeated (empty
    /// rows) and equal to 1 at the end (trailing empty rows).
    #[test]
    fn guided_marginal_draws_find_the_plain_segment() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(8);
        type Row = fn(usize, &mut rand_pcg::Pcg64) -> f32;
        let tables: [(usize, Row); 3] = [
            (300, |_, r| r.random_range(0.5..1.5)),
            (700, |j, r| match j {
                0..40 => 0.0,
                40..400 => 1e-7 * r.random::<f32>(),
                400 => 5.0,
                600.. => 0.0,
                _ if j % 7 == 0 => 0.0,
                _ => r.random::<f32>(),
            }),
            (64, |j, _| if j == 10 { 1.0 } else { 0.0 }),
        ];
        for (ny, row) in tables {
            let nx = 2;
            let values: Vec<f32> = (0..ny)
                .flat_map(|j| {
                    let v = row(j, &mut rng);
                    [v, v]
                })
                .collect();
            let a = AdaptiveCdf2D::from_values(&values, nx, ny, &DouglasPeucker::vertical(), 0.0)
                .unwrap();
            let d = PackedEnvCdf2D::from_adaptive(&a, &values, nx, ny).unwrap();
            let m = d.marginal.len();
            let inner = &d.marginal_cdf[1..m - 1];
            let mut us: Vec<f32> = (0..=100_000).map(|k| k as f32 / 100_000.0).collect();
            for &c in inner {
                us.extend([c, f32_below(c), c + f32::EPSILON * c.max(1e-30)]);
            }
            us.push(ONE_MINUS_EPSILON);
            for u in us {
                let u = clamp_unit(u);
                assert_eq!(
                    d.drawn_marginal_segment(u),
                    inner.partition_point(|&c| c <= u),
                    "{ny} rows, u {u}"
                );
            }
        }
    }

    #[test]
    fn quantised_cdfs_keep_every_positive_segment() {
        let masses = [1.0, 1e-12, 0.0, 3.0, 1e-9, 0.0];
        for q in [Q16, Q24] {
            let c = quantise(&masses, q);
            assert_eq!((c[0], *c.last().unwrap()), (0, q));
            for (i, &m) in masses.iter().enumerate() {
                assert_eq!(c[i + 1] > c[i], m > 0.0, "segment {i}: {c:?}");
            }
        }
    }

    /// A peaked table with zero rows and columns: draws report the density
    /// `pdf` finds at their point; every texel with mass has a positive
    /// density; the density integrates to 1.
    #[test]
    fn packed_tables_are_exact_and_cover_the_support() {
        let (nx, ny) = (64, 32);
        let values: Vec<f32> = (0..nx * ny)
            .map(|i| {
                let (k, j) = (i % nx, i / nx);
                if j == 3 || k == 40 {
                    0.0
                } else if (k, j) == (10, 20) {
                    1e4
                } else {
                    1.0 + (k as f32 * 0.3).sin().abs() + 1e-6 * j as f32
                }
            })
            .collect();
        let a =
            AdaptiveCdf2D::from_values(&values, nx, ny, &DouglasPeucker::vertical(), 1e-3).unwrap();
        let d = PackedEnvCdf2D::from_adaptive(&a, &values, nx, ny).unwrap();
        let mut integral = 0.0f64;
        for j in 0..ny {
            for k in 0..nx {
                let c = Vec2::new((k as f32 + 0.5) / nx as f32, (j as f32 + 0.5) / ny as f32);
                let p = d.pdf(c);
                // Zero texels inside a segment with mass share its density.
                assert!(p > 0.0 || values[j * nx + k] == 0.0, "texel {k},{j}");
                integral += p as f64 / (nx * ny) as f64;
            }
        }
        assert!((integral - 1.0).abs() < 1e-5, "{integral}");
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        for _ in 0..20_000 {
            let u = Vec2::new(rng.random(), rng.random());
            let s = d.sample(u);
            assert!((0.0..1.0).contains(&s.p.x) && (0.0..1.0).contains(&s.p.y));
            // n_x a power of two: the draw's own point finds its segment.
            assert_eq!(s.pdf, d.pdf(s.p), "{u:?} -> {s:?}");
            assert!(s.pdf > 0.0);
            let back = d.invert(s.p);
            assert!((back - u).abs().max_element() < 1e-3, "{u:?} -> {back:?}");
        }
        // The vertices take less room than the adaptive table's; the guides
        // (a fixed 1028 bytes and 32 per marginal segment) are what the
        // packed form spends for speed.
        let guides =
            std::mem::size_of_val(&*d.guide) + std::mem::size_of_val(&*d.conditional_guide);
        assert!(d.storage_bytes() - guides < a.storage_bytes());
        assert!((d.integral() - a.integral()).abs() < 1e-9 * a.integral());
    }

    #[test]
    fn an_empty_table_is_uniform_with_no_integral() {
        let values = vec![0.0f32; 8 * 4];
        let a =
            AdaptiveCdf2D::from_values(&values, 8, 4, &DouglasPeucker::vertical(), 1e-3).unwrap();
        let d = PackedEnvCdf2D::from_adaptive(&a, &values, 8, 4).unwrap();
        assert_eq!(d.integral(), 0.0);
        let s = d.sample(Vec2::new(0.3, 0.6));
        assert!((s.pdf - 1.0).abs() < 1e-6, "{s:?}");
        assert_eq!(d.pdf(s.p), s.pdf);
    }
}
