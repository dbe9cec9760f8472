//! Orientation-aware environment sampling: for a shading normal n, draw
//! directions roughly in proportion to L(ω) max(0, n·ω), the integrand of
//! the irradiance, rather than to L(ω) alone.
//!
//! The sphere of normals is cut into regions ([`NormalGrid`]): the cells of
//! an equal-area grid, and a cap around each pole. Each region's node gets
//! one table ([`oriented_table`]) that follows L · Ω · g, with g the root
//! mean square of max(0, n·ω) over the normals n within the region's
//! radius of the node's normal, and that is positive on every texel any
//! of those normals sees; the plug-in's [`TableBuilder`] compresses it. A
//! node is built the first time a query needs it, so a scene pays only for
//! the orientations it has.
//!
//! A normal draws from its region's table alone, and the density is that
//! table's: one table searched per draw, whose density comes with the
//! draw, so a call costs finding the normal's region (its row from z, its
//! column from the octant of its azimuth and a few compares, with no
//! division) and a draw from one table. The estimator is unbiased for
//! every normal because the table covers every texel the normal sees. An
//! optional defensive share mixes in the plain luminance table (the
//! mixture's density then needs one lookup in the table that was not
//! drawn from).

use acdf_core::simd::Avx2;
use std::sync::{Arc, OnceLock};

use acdf_core::{
    clamp_unit, Distribution2D, Error, Result, SphereSample, SphereSampler, Vec2, Vec3,
    ONE_MINUS_EPSILON,
};

use acdf_core::fast::grid_cell;

use crate::envmap::EnvMap;
use crate::sampler::{finish_draw, TableBuilder};
use crate::tables::{luminance_table, oriented_table};

/// An equal-area grid of `rows` × `columns` cells over the sphere of
/// normals: row r covers z ∈ [1 − 2(r+1)/R, 1 − 2r/R], column c covers
/// φ ∈ [2πc/C, 2π(c+1)/C), so every cell has the solid angle 4π/(RC).
///
/// Every normal belongs to one node ([`node_of`](Self::node_of)): the cell
/// holding it, except within a cap around each pole, which belongs to a
/// node of its own (indices RC and RC + 1), so that the first and last
/// rows' wedges, which reach the poles, do not stretch over the whole cap.
/// A cap's angular radius is half the polar angle of the first row's
/// centres. [`node_radius`](Self::node_radius) bounds the angle between a
/// node's normal and every normal of its region.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NormalGrid {
    pub rows: usize,
    pub columns: usize,
}

impl NormalGrid {
    /// The default grid, 16 × 32 cells (each about 0.025 sr).
    pub const DEFAULT: NormalGrid = NormalGrid {
        rows: 16,
        columns: 32,
    };

    /// A grid of `rows` × `columns` cells, each at least 1 and the product
    /// at most 2^16.
    pub fn new(rows: usize, columns: usize) -> Result<NormalGrid> {
        if rows == 0 || columns == 0 || rows.saturating_mul(columns) > 1 << 16 {
            return Err(Error::InvalidParameter {
                name: "normal cells",
                reason: format!(
                    "{rows}x{columns}: need at least one row and column, at most 65536 cells"
                ),
            });
        }
        Ok(NormalGrid { rows, columns })
    }

    /// The number of cells R · C.
    pub fn cell_count(&self) -> usize {
        self.rows * self.columns
    }

    /// The number of nodes: the cells and the two polar caps.
    pub fn node_count(&self) -> usize {
        self.cell_count() + 2
    }

    /// cos of the polar caps' angular radius: half the polar angle of the
    /// first row's centres (z = 1 − 1/R), cos(θ/2) = sqrt((1 + cos θ)/2).
    #[inline]
    fn cap_z(&self) -> f64 {
        (1.0 - 0.5 / self.rows as f64).sqrt()
    }

    /// The normal of node `i`: a cell's centre (z halfway through its row,
    /// φ halfway through its column), or a pole.
    pub fn node_normal(&self, i: usize) -> Vec3 {
        let cells = self.cell_count();
        if i == cells {
            return Vec3::Z;
        }
        if i > cells {
            return -Vec3::Z;
        }
        let (r, c) = (i / self.columns, i % self.columns);
        let z = 1.0 - (2 * r + 1) as f64 / self.rows as f64;
        let phi = std::f64::consts::TAU * (c as f64 + 0.5) / self.columns as f64;
        unit(z, phi)
    }

    /// The node whose region holds the unit normal `n`: a polar cap's node
    /// within the cap, else the cell of n's row (in z) and column (in φ).
    /// The same node a sampler over this grid finds, by a binary search
    /// (over the octant's tangents, or over the column boundaries' pseudo
    /// azimuths) instead of the sampler's compares or table of bins.
    pub fn node_of(&self, n: Vec3) -> usize {
        let column = match OctantColumns::new(self.columns) {
            Some(octants) => {
                let (o, odd, lo, hi) = octant_of(n.x, n.y);
                let k = octants.per_octant;
                let tangents = &octants.tangents[..k - 1];
                o * k
                    + if !odd {
                        tangents.partition_point(|&t| lo >= t * hi)
                    } else {
                        k - 1 - tangents.partition_point(|&t| !(lo <= t * hi))
                    }
            }
            None => {
                let p = pseudo_azimuth(n.x, n.y);
                let (mut lo, mut hi) = (0, self.columns - 1);
                // The column is the number of boundaries 1 ..= C − 1 at or
                // below p.
                while lo < hi {
                    let mid = (lo + hi).div_ceil(2);
                    if column_boundary(mid, self.columns) <= p {
                        lo = mid;
                    } else {
                        hi = mid - 1;
                    }
                }
                lo
            }
        };
        RowLocator::new(*self).node_at(n, column)
    }

    /// A bound on the angle (radians) between node `i`'s normal and every
    /// normal of its region (with a margin for the rounding of
    /// [`node_of`](Self::node_of)). A region is bounded by arcs of
    /// latitude circles and of meridians. Over a latitude arc, the cosine
    /// of the angle to the node's normal falls with the distance in φ from
    /// the node's; over a meridian at most a quarter turn away in φ (two
    /// columns or more) it is concave in z. So the angle is largest at a
    /// corner of the region; a grid of one column is bounded by π.
    pub fn node_radius(&self, i: usize) -> f64 {
        const MARGIN: f64 = 1e-3;
        let cells = self.cell_count();
        let cap = self.cap_z();
        if i >= cells {
            return cap.acos() + MARGIN;
        }
        if self.columns == 1 {
            return std::f64::consts::PI;
        }
        let (r, c) = (i / self.columns, i % self.columns);
        let (rows, cols) = (self.rows as f64, self.columns as f64);
        let z_hi = (1.0 - 2.0 * r as f64 / rows).min(cap);
        let z_lo = (1.0 - 2.0 * (r + 1) as f64 / rows).max(-cap);
        let tau = std::f64::consts::TAU;
        let (p0, p1) = (tau * c as f64 / cols, tau * (c + 1) as f64 / cols);
        let centre = self.node_normal(i).as_dvec3();
        let mut radius = 0.0f64;
        for z in [z_lo, z_hi] {
            for p in [p0, p1] {
                let corner = unit(z, p).as_dvec3();
                radius = radius.max(centre.dot(corner).clamp(-1.0, 1.0).acos());
            }
        }
        radius + MARGIN
    }
}

/// A stand-in for the azimuth φ of (x, y) that needs no arctangent: with
/// a = min(|x|, |y|) / max(|x|, |y|), the tangent of the angle to the
/// nearest axis, it is a on [0, π/4), 2 − a on [π/4, π/2), 2 + a on
/// [π/2, 3π/4), and so on around to 8 − a just below 2π: continuous and
/// increasing in φ over [0, 2π), from 0 to 8, at a rate between 1 and 2
/// per radian. One division and three selects, where an arctangent adds
/// a polynomial to the division. (0, 0), NaN and infinite inputs give a
/// finite value.
#[inline(always)]
fn pseudo_azimuth(x: f32, y: f32) -> f32 {
    let (ax, ay) = (x.abs(), y.abs());
    let a = ax.min(ay) / ax.max(ay);
    // NaN (0/0, ∞/∞, a NaN input) fails the comparison and becomes 0.
    let a = if a >= 0.0 { a.min(1.0) } else { 0.0 };
    let r = if ay > ax { 2.0 - a } else { a };
    let r = if x < 0.0 { 4.0 - r } else { r };
    if y < 0.0 {
        8.0 - r
    } else {
        r
    }
}

/// The octant of the azimuth of (x, y), counted from φ = 0 as φ grows
/// (octant o covers φ ∈ [oπ/4, (o + 1)π/4]), whether it is odd, and
/// min(|x|, |y|) and max(|x|, |y|): their ratio is the tangent of the
/// angle from the octant's start in the even octants, from its end in the
/// odd ones. The octant comes from three signs and needs no division; its
/// parity, the parity of those signs, comes without waiting for it.
#[inline(always)]
fn octant_of(x: f32, y: f32) -> (usize, bool, f32, f32) {
    let (ax, ay) = (x.abs(), y.abs());
    let (x_negative, y_negative, steep) = (x < 0.0, y < 0.0, ay > ax);
    let upper = if x_negative {
        3 - steep as usize
    } else {
        steep as usize
    };
    let o = if y_negative { 7 - upper } else { upper };
    let odd = x_negative ^ y_negative ^ steep;
    (o, odd, ax.min(ay), ax.max(ay))
}

/// The column lookup of a grid whose column count C is a multiple of 8 and
/// at most [`OctantColumns::MAX_COLUMNS`]: each octant holds K = C / 8
/// columns, and by the octants' symmetry the column boundaries inside any
/// octant lie where the ratio min/max of [`octant_of`] equals one of the
/// same K − 1 tangents t_j = tan(2πj / C). The column of (x, y) in octant
/// o is o K plus the number of boundaries it has passed in the octant: in
/// an even octant the number of j with min ≥ t_j max, in an odd one
/// (where the ratio falls as φ grows) the number with min ≤ t_j max.
/// Eight products and compares against constants, where the
/// pseudo-azimuth needs a division and a table read in a chain.
#[derive(Debug, Clone, Copy, PartialEq)]
struct OctantColumns {
    /// K: columns per octant.
    per_octant: usize,
    /// t_1 < ... < t_{K−1}, then NaN.
    tangents: [f32; 8],
}

impl OctantColumns {
    /// The largest column count with this lookup (K − 1 ≤ 8 tangents).
    const MAX_COLUMNS: usize = 72;

    /// The lookup of a grid of `columns` columns, if it has one.
    fn new(columns: usize) -> Option<OctantColumns> {
        if !columns.is_multiple_of(8) || columns > Self::MAX_COLUMNS {
            return None;
        }
        let mut tangents = [f32::NAN; 8];
        for (j, t) in tangents.iter_mut().enumerate().take(columns / 8 - 1) {
            *t = (std::f64::consts::TAU * (j + 1) as f64 / columns as f64).tan() as f32;
        }
        Some(OctantColumns {
            per_octant: columns / 8,
            tangents,
        })
    }

    /// The column of the azimuth of (x, y), without a branch (the octant
    /// of a scene's next normal is anyone's guess): in an even octant the
    /// signs of min and max are flipped, so that one compare, min ≤ t_j
    /// max, holds where min ≥ t_j max does before the flip, and the column
    /// within the octant is the count of compares that hold (the padding,
    /// NaN, fails every compare).
    #[inline(always)]
    fn column_of(&self, x: f32, y: f32) -> usize {
        let (o, odd, lo, hi) = octant_of(x, y);
        let flip = ((!odd) as u32) << 31;
        let lo = f32::from_bits(lo.to_bits() ^ flip);
        let hi = f32::from_bits(hi.to_bits() ^ flip);
        let within: u32 = self.tangents.iter().map(|&t| (lo <= t * hi) as u32).sum();
        o * self.per_octant + within as usize
    }
}

/// The column lookup of a [`NodeLocator`]: by octant compares where the
/// column count allows ([`OctantColumns`]), else by bins of the
/// pseudo-azimuth ([`ColumnBins`]).
#[derive(Debug, Clone)]
enum ColumnLookup {
    Octants(OctantColumns),
    Bins(ColumnBins),
}

impl ColumnLookup {
    fn new(columns: usize) -> ColumnLookup {
        match OctantColumns::new(columns) {
            Some(o) => ColumnLookup::Octants(o),
            None => ColumnLookup::Bins(ColumnBins::new(columns)),
        }
    }

    /// The column of the azimuth of (x, y).
    #[inline(always)]
    fn column_of(&self, x: f32, y: f32) -> usize {
        match self {
            ColumnLookup::Octants(o) => o.column_of(x, y),
            ColumnLookup::Bins(b) => b.column_of(x, y),
        }
    }
}

/// The pseudo-azimuth of the boundary between columns c − 1 and c of a
/// grid of `columns` columns (φ = 2πc / C), increasing in c.
fn column_boundary(c: usize, columns: usize) -> f32 {
    let phi = std::f64::consts::TAU * c as f64 / columns as f64;
    pseudo_azimuth(phi.cos() as f32, phi.sin() as f32)
}

/// One bin of the column lookup: the column at the bin's start, and the
/// pseudo-azimuth of the one column boundary inside the bin (infinite if
/// none).
#[derive(Debug, Clone, Copy, PartialEq)]
struct ColumnBin {
    column: u32,
    boundary: f32,
}

/// The column lookup of a [`NodeLocator`] for the other column counts.
///
/// The column is found from the [`pseudo_azimuth`] p of the normal: p is
/// cut into bins of width 1/B, B the power of two at or above the column
/// count, and each bin stores the column where it starts and the boundary
/// of the next column if that falls inside the bin. Column boundaries are
/// 2π/C apart in φ, so at least 2π/C > 1/B apart in p: a bin holds at
/// most one, and one comparison finishes the lookup. p B is exact (B is a
/// power of two), so a p always lands in the bin whose range holds it.
#[derive(Debug, Clone)]
struct ColumnBins {
    /// Bins per unit of pseudo-azimuth (B).
    bin_scale: f32,
    last_bin: f32,
    bins: Box<[ColumnBin]>,
}

impl ColumnBins {
    /// The bins of a grid of `columns` columns.
    fn new(columns: usize) -> ColumnBins {
        let boundaries: Vec<f32> = (1..columns).map(|c| column_boundary(c, columns)).collect();
        let per_unit = columns.next_power_of_two();
        let bin_scale = per_unit as f32;
        let bins: Box<[ColumnBin]> = (0..8 * per_unit)
            .map(|b| {
                let (lo, hi) = (b as f32 / bin_scale, (b + 1) as f32 / bin_scale);
                let column = boundaries.partition_point(|&p| p <= lo);
                let boundary = boundaries
                    .get(column)
                    .copied()
                    .filter(|&p| p < hi)
                    .unwrap_or(f32::INFINITY);
                debug_assert!(boundaries.get(column + 1).is_none_or(|&p| p >= hi));
                ColumnBin {
                    column: column as u32,
                    boundary,
                }
            })
            .collect();
        ColumnBins {
            bin_scale,
            last_bin: (bins.len() - 1) as f32,
            bins,
        }
    }

    /// The column of the azimuth of (x, y): the number of column
    /// boundaries at or below its pseudo-azimuth.
    #[inline(always)]
    fn column_of(&self, x: f32, y: f32) -> usize {
        let p = pseudo_azimuth(x, y);
        let bin = self.bins[grid_cell(p * self.bin_scale, self.last_bin)];
        bin.column as usize + (p >= bin.boundary) as usize
    }
}

/// The grid's constants, converted once, that turn a normal and its column
/// into its node.
#[derive(Debug, Clone, Copy)]
struct RowLocator {
    /// z at and above which a normal is in the north cap (−cap: south).
    cap: f32,
    /// R / 2: the row of z is ⌊(1 − z) R / 2⌋.
    half_rows: f32,
    last_row: f32,
    column_count: usize,
    cells: usize,
}

impl RowLocator {
    fn new(grid: NormalGrid) -> RowLocator {
        RowLocator {
            cap: grid.cap_z() as f32,
            half_rows: 0.5 * grid.rows as f32,
            last_row: (grid.rows - 1) as f32,
            column_count: grid.columns,
            cells: grid.cell_count(),
        }
    }

    /// The node of the unit normal `n` whose column is `column`: the cell
    /// of its row and that column, or a cap's node. The compiled code may
    /// branch on the cap: the caps hold a small share of the sphere's
    /// normals (1.6% with 16 rows), so the branch is rarely mispredicted,
    /// and where it is predicted it keeps a select off the chain.
    #[inline(always)]
    fn node_at(&self, n: Vec3, column: usize) -> usize {
        let r = grid_cell((1.0 - n.z) * self.half_rows, self.last_row);
        let cell = r * self.column_count + column;
        let north = (n.z >= self.cap) as usize;
        let south = (n.z <= -self.cap) as usize;
        let polar = self.cells + south;
        if north + south > 0 {
            polar
        } else {
            cell
        }
    }
}

/// What a sampler keeps to find a normal's node ([`NormalGrid::node_of`])
/// on every call: the rows' constants and the column lookup.
#[derive(Debug, Clone)]
struct NodeLocator {
    rows: RowLocator,
    columns: ColumnLookup,
}

impl NodeLocator {
    fn new(grid: NormalGrid) -> NodeLocator {
        NodeLocator {
            rows: RowLocator::new(grid),
            columns: ColumnLookup::new(grid.columns),
        }
    }

    /// The node of the unit normal `n`.
    #[inline(always)]
    fn node_of(&self, n: Vec3) -> usize {
        self.rows.node_at(n, self.columns.column_of(n.x, n.y))
    }
}

/// The largest |‖n‖² − 1| of a normal taken as already unit length: a few
/// hundred times the rounding of a normalised `f32` vector, and so small
/// that the normal's angles move by under 1e-5 rad, far inside the
/// regions' margin.
const UNIT_SLACK: f32 = 1e-5;

/// `acdf_core::usable_normal` (the normal scaled to unit length, `None`
/// for one that is not finite or has no length), except that a normal
/// within [`UNIT_SLACK`] of unit length is returned as it is: renderers
/// pass unit normals, and for them the square root and the division leave
/// the chain of dependent steps of a draw (the branch is predicted). The
/// test on the squared length is one integer compare: the bit patterns of
/// the positive finite floats are 1 ..= 0x7f7f_ffff.
#[inline(always)]
fn unit_normal(normal: Option<Vec3>) -> Option<Vec3> {
    let n = normal?;
    let len2 = n.length_squared();
    if (len2 - 1.0).abs() <= UNIT_SLACK {
        return Some(n);
    }
    (len2.to_bits().wrapping_sub(1) < 0x7f7f_ffff).then(|| n / len2.sqrt())
}

/// The unit vector of height `z` and azimuth `phi`.
fn unit(z: f64, phi: f64) -> Vec3 {
    let s = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, z as f32)
}

/// A node's distribution, built on first use; `None` inside once built
/// means its table could not be built or holds nothing (its normals then
/// draw from the plain table).
type LazyNode<D> = OnceLock<Option<D>>;

/// The orientation-aware sampler over a map, generic in the builder of its
/// tables (see the module documentation).
///
/// Storage: the plain luminance table and every node built so far
/// ([`built_nodes`](Self::built_nodes) of [`node_count`](Self::node_count)).
/// Building is thread-safe: concurrent first queries of one node build it
/// once.
pub struct OrientedSampler<B: TableBuilder> {
    name: String,
    map: Arc<EnvMap>,
    builder: B,
    grid: NormalGrid,
    locator: NodeLocator,
    nodes: Box<[LazyNode<B::Dist>]>,
    plain: B::Dist,
    defensive: f32,
}

impl<B: TableBuilder> std::fmt::Debug for OrientedSampler<B> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("OrientedSampler")
            .field("name", &self.name)
            .field("grid", &self.grid)
            .field("built_nodes", &self.built_nodes())
            .field("defensive", &self.defensive)
            .finish()
    }
}

impl<B: TableBuilder> OrientedSampler<B> {
    /// The default defensive share: the probability of drawing from the
    /// plain luminance table whatever the normal.
    pub const DEFAULT_DEFENSIVE: f32 = 0.0;

    /// A sampler named `name` over `map` with the normal cells of `grid`,
    /// the tables built by `builder`, and the defensive share `defensive`
    /// (in [0, 1]; the luminance table is built now, the nodes when first
    /// needed).
    pub fn new(
        name: impl Into<String>,
        map: Arc<EnvMap>,
        builder: B,
        grid: NormalGrid,
        defensive: f32,
    ) -> Result<Self> {
        if !(0.0..=1.0).contains(&defensive) {
            return Err(Error::InvalidParameter {
                name: "defensive share",
                reason: format!("must be in [0, 1], got {defensive}"),
            });
        }
        let (w, h) = map.size();
        let plain = builder.build(&luminance_table(&map), w, h)?;
        let nodes = (0..grid.node_count()).map(|_| OnceLock::new()).collect();
        Ok(OrientedSampler {
            name: name.into(),
            map,
            builder,
            grid,
            locator: NodeLocator::new(grid),
            nodes,
            plain,
            defensive,
        })
    }

    /// The grid of normal cells.
    pub fn normal_grid(&self) -> NormalGrid {
        self.grid
    }

    /// The defensive share.
    pub fn defensive(&self) -> f32 {
        self.defensive
    }

    /// The number of nodes (cells and polar caps).
    pub fn node_count(&self) -> usize {
        self.nodes.len()
    }

    /// How many nodes have been built so far.
    pub fn built_nodes(&self) -> usize {
        self.nodes.iter().filter(|n| n.get().is_some()).count()
    }

    /// Build every node now (for storage figures and timings that exclude
    /// building).
    pub fn build_all(&self) {
        for i in 0..self.nodes.len() {
            self.node(i);
        }
    }

    /// The plain luminance distribution (the defensive component, and what
    /// is sampled without a normal).
    pub fn plain(&self) -> &B::Dist {
        &self.plain
    }

    /// Node `i`'s distribution, built on first use; `None` if its table
    /// could not be built or is zero (no normal of its region sees light).
    fn node(&self, i: usize) -> Option<&B::Dist> {
        self.nodes[i]
            .get_or_init(|| {
                let (w, h) = self.map.size();
                let table = oriented_table(
                    &self.map,
                    self.grid.node_normal(i),
                    self.grid.node_radius(i),
                );
                let dist = self.builder.build(&table, w, h).ok()?;
                (dist.integral() > 0.0).then_some(dist)
            })
            .as_ref()
    }

    /// The distribution of the unit normal `n`'s node, if it has one.
    #[inline]
    fn node_dist(&self, n: Vec3) -> Option<&B::Dist> {
        self.node(self.locator.node_of(n))
    }

    /// The density (in the unit square) for a normal with the node
    /// distribution `node` at texel (column, row).
    #[inline]
    fn density_at(&self, node: Option<&B::Dist>, column: usize, row: usize) -> f32 {
        let c = self.map.grid().texel_centre(column, row);
        match node {
            Some(d) if self.defensive > 0.0 => {
                (1.0 - self.defensive) * d.pdf(c) + self.defensive * self.plain.pdf(c)
            }
            Some(d) => d.pdf(c),
            None => self.plain.pdf(c),
        }
    }

    fn density_of(&self, node: Option<&B::Dist>, dir: Vec3) -> f32 {
        match self.map.grid().texel_of(dir) {
            Some((k, j)) => self.density_at(node, k, j) * self.map.grid().inv_jacobian(j),
            None => 0.0,
        }
    }
}

impl<B: TableBuilder> SphereSampler for OrientedSampler<B> {
    fn name(&self) -> &str {
        &self.name
    }

    /// Without a usable normal, a draw from the plain luminance table. With
    /// one, a draw from the table of the normal's node; with a defensive
    /// share a > 0, u.x below a draws from the plain table instead (u.x
    /// rescaled), and the density is the mixture's, of which the drawn
    /// component's part comes with the draw.
    fn sample(&self, normal: Option<Vec3>, u: Vec2) -> Option<SphereSample> {
        acdf_core::dispatch!(Self::sample_one, self, normal, u)
    }

    fn pdf(&self, normal: Option<Vec3>, dir: Vec3) -> f32 {
        acdf_core::dispatch!(Self::pdf_one, self, normal, dir)
    }

    /// The plain table and the nodes built so far.
    fn storage_bytes(&self) -> usize {
        self.plain.storage_bytes()
            + self
                .nodes
                .iter()
                .filter_map(|n| n.get().and_then(Option::as_ref))
                .map(|d| d.storage_bytes())
                .sum::<usize>()
    }

    /// The node is found once for the whole batch.
    fn sample_batch(&self, normal: Option<Vec3>, u: &[Vec2], out: &mut [Option<SphereSample>]) {
        let node = unit_normal(normal).and_then(|n| self.node_dist(n));
        for (o, &u) in out.iter_mut().zip(u) {
            *o = self.sample_from(node, u);
        }
    }

    /// The node is found once for the whole batch.
    fn pdf_batch(&self, normal: Option<Vec3>, dir: &[Vec3], out: &mut [f32]) {
        let node = unit_normal(normal).and_then(|n| self.node_dist(n));
        for (o, &d) in out.iter_mut().zip(dir) {
            *o = self.density_of(node, d);
        }
    }
}

impl<B: TableBuilder> OrientedSampler<B> {
    /// [`sample`](SphereSampler::sample) itself: the node of the normal,
    /// then the draw.
    #[inline(always)]
    fn sample_one(&self, normal: Option<Vec3>, u: Vec2, _: Option<Avx2>) -> Option<SphereSample> {
        self.sample_from(unit_normal(normal).and_then(|n| self.node_dist(n)), u)
    }

    /// [`pdf`](SphereSampler::pdf) itself.
    #[inline(always)]
    fn pdf_one(&self, normal: Option<Vec3>, dir: Vec3, _: Option<Avx2>) -> f32 {
        let node = unit_normal(normal).and_then(|n| self.node_dist(n));
        self.density_of(node, dir)
    }

    /// [`sample`](SphereSampler::sample) once the normal's node
    /// distribution `node` is known (`None`: no usable normal, or a node
    /// without light).
    #[inline(always)]
    fn sample_from(&self, node: Option<&B::Dist>, u: Vec2) -> Option<SphereSample> {
        let grid = self.map.grid();
        let Some(d) = node else {
            let s = self.plain.sample(u);
            return finish_draw(grid, s, |_, _| s.pdf, |dir| self.density_of(None, dir));
        };
        let a = self.defensive;
        if a == 0.0 {
            let s = d.sample(u);
            return finish_draw(grid, s, |_, _| s.pdf, |dir| self.density_of(node, dir));
        }
        let ux = clamp_unit(u.x);
        if ux < a {
            let ux = (ux / a).clamp(0.0, ONE_MINUS_EPSILON);
            let s = self.plain.sample(Vec2::new(ux, u.y));
            finish_draw(
                grid,
                s,
                |k, j| a * s.pdf + (1.0 - a) * d.pdf(grid.texel_centre(k, j)),
                |dir| self.density_of(node, dir),
            )
        } else {
            let ux = ((ux - a) / (1.0 - a)).clamp(0.0, ONE_MINUS_EPSILON);
            let s = d.sample(Vec2::new(ux, u.y));
            finish_draw(
                grid,
                s,
                |k, j| (1.0 - a) * s.pdf + a * self.plain.pdf(grid.texel_centre(k, j)),
                |dir| self.density_of(node, dir),
            )
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `unit_normal` agrees with `acdf_core::usable_normal` bit for bit,
    /// except that a normal within `UNIT_SLACK` of unit length comes back
    /// as given.
    #[test]
    fn unit_normals_agree_with_usable_normal() {
        for n in [
            Vec3::new(0.6, 0.8, 0.0),
            Vec3::new(0.36, 0.48, 0.8),
            Vec3::new(0.0, 0.0, 1.000_004),
            Vec3::new(0.0, -0.999_996, 0.0),
        ] {
            assert_eq!(unit_normal(Some(n)), Some(n));
            let u = acdf_core::usable_normal(Some(n)).unwrap();
            assert!((u - n).abs().max_element() <= 5e-6, "{n} {u}");
        }
        assert_ne!(
            unit_normal(Some(Vec3::new(0.0, 0.0, 1.000_1))),
            Some(Vec3::new(0.0, 0.0, 1.000_1))
        );
        let values = [
            0.0,
            -0.0,
            1.0,
            -2.5,
            1e-30,
            1e-20,
            3e19,
            1e30,
            f32::MIN_POSITIVE,
            f32::MAX,
            f32::INFINITY,
            f32::NEG_INFINITY,
            f32::NAN,
        ];
        for &x in &values {
            for &y in &values {
                for &z in &values[..6] {
                    let v = Vec3::new(x, y, z);
                    let n = Some(v);
                    if (v.length_squared() - 1.0).abs() <= UNIT_SLACK {
                        assert_eq!(unit_normal(n), n);
                        continue;
                    }
                    let (a, b) = (unit_normal(n), acdf_core::usable_normal(n));
                    assert_eq!(
                        a.map(|v| v.to_array().map(f32::to_bits)),
                        b.map(|v| v.to_array().map(f32::to_bits)),
                        "{n:?}"
                    );
                }
            }
        }
        assert_eq!(unit_normal(None), None);
    }

    /// Both column lookups (octant compares and bins of the
    /// pseudo-azimuth) give the column of φ computed in f64, except within
    /// 1e-5 rad of a column boundary (where either side is inside the
    /// regions' margin), for column counts that are and are not multiples
    /// of 8 and powers of two, on a lattice of azimuths that includes every
    /// boundary and the points a float step either side of it, and at the
    /// axes and the diagonals.
    #[test]
    fn column_lookups_match_the_azimuth() {
        let tau = std::f64::consts::TAU;
        let lookups = [
            1usize, 2, 3, 5, 8, 12, 16, 24, 32, 33, 64, 72, 80, 100, 1024, 65536,
        ]
        .into_iter()
        .flat_map(|cols| {
            let octants = OctantColumns::new(cols).map(ColumnLookup::Octants);
            assert_eq!(octants.is_some(), cols.is_multiple_of(8) && cols <= 72);
            [Some(ColumnLookup::Bins(ColumnBins::new(cols))), octants]
                .into_iter()
                .flatten()
                .map(move |l| (cols, l))
        });
        for (cols, locator) in lookups {
            let mut phis: Vec<f64> = (0..=4000).map(|k| tau * k as f64 / 4000.0).collect();
            for c in 0..=cols.min(2000) {
                let b = tau * c as f64 / cols as f64;
                phis.extend([b - 1e-6, b, b + 1e-6]);
            }
            phis.extend((0..8).map(|k| tau * k as f64 / 8.0));
            for phi in phis {
                let (x, y) = (phi.cos() as f32, phi.sin() as f32);
                let got = locator.column_of(x, y);
                let exact = (y as f64).atan2(x as f64).rem_euclid(tau);
                let want = ((exact / tau * cols as f64).floor() as usize).min(cols - 1);
                if got != want {
                    // Only next to a boundary, and then a neighbour.
                    let t = exact / tau * cols as f64;
                    let off = (t - t.round()).abs() * tau / cols as f64;
                    let neighbour = (got + 1) % cols == want || (want + 1) % cols == got;
                    assert!(
                        off < 1e-5 && neighbour,
                        "{cols} columns, φ = {phi}: column {got}, want {want}"
                    );
                }
            }
            // Finite columns for the inputs a sampler never passes.
            for (x, y) in [(0.0, 0.0), (f32::NAN, 1.0), (f32::INFINITY, f32::INFINITY)] {
                assert!(locator.column_of(x, y) < cols);
            }
        }
    }

    /// Every normal's node, as a sampler finds it, is within the node's
    /// radius of it, and `NormalGrid::node_of` finds the same node; the
    /// poles and the caps go to the polar nodes; a cell's centre to its
    /// cell.
    #[test]
    fn every_normal_is_within_its_nodes_radius() {
        for (rows, cols) in [
            (1, 1),
            (1, 2),
            (4, 6),
            (4, 8),
            (8, 16),
            (16, 32),
            (3, 72),
            (2, 80),
        ] {
            let g = NormalGrid::new(rows, cols).unwrap();
            let locator = NodeLocator::new(g);
            assert_eq!(locator.node_of(Vec3::Z), g.cell_count());
            assert_eq!(locator.node_of(-Vec3::Z), g.cell_count() + 1);
            for i in 0..g.cell_count() {
                assert_eq!(
                    locator.node_of(g.node_normal(i)),
                    i,
                    "{rows}x{cols} cell {i}"
                );
            }
            // A fine lattice over (z, φ), with the seam, the cap edges and
            // the row edges.
            let steps = 400;
            for a in 0..=steps {
                let z = 1.0 - 2.0 * a as f64 / steps as f64;
                for b in 0..=steps {
                    let phi = std::f64::consts::TAU * b as f64 / steps as f64;
                    let n = unit(z, phi).normalize();
                    let i = locator.node_of(n);
                    assert_eq!(g.node_of(n), i, "{rows}x{cols}: {n}");
                    assert!(i < g.node_count());
                    let angle = (g.node_normal(i).dot(n) as f64).clamp(-1.0, 1.0).acos();
                    assert!(
                        angle <= g.node_radius(i),
                        "{rows}x{cols}: {n} in node {i} at {angle} > {}",
                        g.node_radius(i)
                    );
                }
            }
        }
        assert!(NormalGrid::new(0, 3).is_err());
    }
}
