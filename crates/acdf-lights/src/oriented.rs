//! Orientation-aware environment sampling: for a shading normal n, draw
//! directions roughly in proportion to L(ω) max(0, n·ω), the integrand of
//! the irradiance, rather than to L(ω) alone.
//!
//! The sphere of normals is cut into an equal-area grid of cells
//! ([`NormalGrid`]); each cell's centre normal n_c gets its own table of
//! L · Ω · max(0, n_c·ω) ([`oriented_table`]), compressed by the plug-in's
//! [`TableBuilder`]. A cell is built the first time a query needs it, so a
//! scene pays only for the orientations it has. For a normal n the sampler
//! draws from an exact mixture: the neighbouring cells of n (linear in
//! the grid's coordinates, each weighted by its irradiance too), plus a
//! defensive share of the plain luminance table, which covers every texel
//! with light, so that the estimator is unbiased whatever the normal; the
//! pdf is the mixture's.
//!
//! The neighbouring cells are the three corners of the triangle of cell
//! centres around n (linear weights in (z, φ)), each weighted further by
//! its table's integral, which is its irradiance: the mixture then
//! interpolates the integrand L max(0, n·ω) rather than normalised
//! densities.

use std::sync::{Arc, OnceLock};

use acdf_core::{
    clamp_unit, usable_normal, Distribution2D, Error, Result, SphereSample, SphereSampler, Vec2,
    Vec3, ONE_MINUS_EPSILON,
};

use crate::envmap::EnvMap;
use crate::sampler::{finish_draw, TableBuilder};
use crate::tables::{luminance_table, oriented_table};

/// An equal-area grid of `rows` × `columns` cells over the sphere of
/// normals: row r covers z ∈ [1 − 2(r+1)/R, 1 − 2r/R], column c covers
/// φ ∈ [2πc/C, 2π(c+1)/C), so every cell has the solid angle 4π/(RC).
/// Besides the cells' centres, the two poles are interpolation nodes of
/// their own (indices RC and RC + 1), so that a normal near a pole blends
/// towards a table made for the pole rather than towards the tilted centres
/// of the first row only.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct NormalGrid {
    pub rows: usize,
    pub columns: usize,
}

/// At most this many nodes take part in one normal's mixture.
pub const MAX_NODES: usize = 3;

/// The nodes of a normal's mixture and their weights.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Nodes {
    pub index: [usize; MAX_NODES],
    pub weight: [f32; MAX_NODES],
    pub len: usize,
}

impl NormalGrid {
    /// The default grid, 8 × 16 cells (each about 0.1 sr).
    pub const DEFAULT: NormalGrid = NormalGrid {
        rows: 8,
        columns: 16,
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

    /// The number of interpolation nodes: the cells and the two poles.
    pub fn node_count(&self) -> usize {
        self.cell_count() + 2
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
        let s = (1.0 - z * z).max(0.0).sqrt();
        Vec3::new((s * phi.cos()) as f32, (s * phi.sin()) as f32, z as f32)
    }

    /// The nodes whose tables a normal `n` (unit) mixes, with weights
    /// linear in (z, φ): the square of four cell centres around n is cut
    /// along a diagonal into two triangles, and n gets the barycentric
    /// weights of the three corners of its triangle (three tables to
    /// evaluate per density rather than four). Above the first row's
    /// centres (below the last row's) the weight moves linearly in z from
    /// the row's two nearest cells to the pole's node. Zero weights are
    /// left out; the weights sum to 1.
    pub fn nodes(&self, n: Vec3) -> Nodes {
        let (rows, cols) = (self.rows, self.columns);
        let sz = (1.0 - n.z.clamp(-1.0, 1.0)) * 0.5 * rows as f32 - 0.5;
        let sp = acdf_core::geometry::phi(n) * (cols as f32 / std::f32::consts::TAU) - 0.5;
        let spf = sp.floor();
        let fp = (sp - spf).clamp(0.0, 1.0);
        let c0 = (spf as i64).rem_euclid(cols as i64) as usize;
        let c1 = (c0 + 1) % cols;
        let mut out = Nodes {
            index: [0; MAX_NODES],
            weight: [0.0; MAX_NODES],
            len: 0,
        };
        let mut push = |i: usize, w: f32| {
            if w > 0.0 {
                out.index[out.len] = i;
                out.weight[out.len] = w;
                out.len += 1;
            }
        };
        let last = (rows - 1) as f32;
        if sz < 0.0 || sz > last {
            let (row, pole, lambda) = if sz < 0.0 {
                (0, self.cell_count(), (-2.0 * sz).min(1.0))
            } else {
                (
                    rows - 1,
                    self.cell_count() + 1,
                    (2.0 * (sz - last)).min(1.0),
                )
            };
            push(row * cols + c0, (1.0 - lambda) * (1.0 - fp));
            push(row * cols + c1, (1.0 - lambda) * fp);
            push(pole, lambda);
        } else {
            let r0 = (sz.floor() as usize).min(rows - 1);
            let r1 = (r0 + 1).min(rows - 1);
            let fz = if r1 == r0 { 0.0 } else { sz - r0 as f32 };
            if fz + fp <= 1.0 {
                push(r0 * cols + c0, 1.0 - fz - fp);
                push(r1 * cols + c0, fz);
                push(r0 * cols + c1, fp);
            } else {
                push(r1 * cols + c1, fz + fp - 1.0);
                push(r1 * cols + c0, 1.0 - fp);
                push(r0 * cols + c1, 1.0 - fz);
            }
        }
        out
    }
}

/// One built node: its distribution, and the integral of its table (the
/// irradiance at the node's normal, up to a constant factor).
#[derive(Debug)]
struct Node<D> {
    dist: D,
    irradiance: f64,
}

/// A node built on first use; `None` inside once built means its table
/// could not be built.
type LazyNode<D> = OnceLock<Option<Node<D>>>;

/// The mixture a normal samples from: up to [`MAX_NODES`] node
/// distributions with their probabilities, and the defensive (plain
/// luminance) distribution's probability.
struct Mixture<'a, D> {
    nodes: [Option<&'a D>; MAX_NODES],
    prob: [f32; MAX_NODES],
    len: usize,
    defensive: f32,
}

/// The orientation-aware sampler over a map, generic in the builder of its
/// tables (see the module documentation).
///
/// Storage: the defensive luminance table and every node built so far
/// ([`built_nodes`](Self::built_nodes) of [`node_count`](Self::node_count)).
/// Building is thread-safe: concurrent first queries of one node build it
/// once.
pub struct OrientedSampler<B: TableBuilder> {
    name: String,
    map: Arc<EnvMap>,
    builder: B,
    grid: NormalGrid,
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
    pub const DEFAULT_DEFENSIVE: f32 = 0.05;

    /// A sampler named `name` over `map` with the normal cells of `grid`,
    /// the tables built by `builder`, and the defensive share `defensive`
    /// (in (0, 1]; the luminance table is built now, the nodes when first
    /// needed).
    pub fn new(
        name: impl Into<String>,
        map: Arc<EnvMap>,
        builder: B,
        grid: NormalGrid,
        defensive: f32,
    ) -> Result<Self> {
        if !(defensive > 0.0 && defensive <= 1.0) {
            return Err(Error::InvalidParameter {
                name: "defensive share",
                reason: format!("must be in (0, 1], got {defensive}"),
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

    /// The number of interpolation nodes (cells and poles).
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

    /// Node `i`, built on first use; `None` if its table could not be built
    /// (its weight is then 0 and the defensive share covers its directions).
    fn node(&self, i: usize) -> Option<&Node<B::Dist>> {
        self.nodes[i]
            .get_or_init(|| {
                let (w, h) = self.map.size();
                let table = oriented_table(&self.map, self.grid.node_normal(i));
                let dist = self.builder.build(&table, w, h).ok()?;
                let irradiance = dist.integral();
                Some(Node { dist, irradiance })
            })
            .as_ref()
    }

    /// The mixture for the unit normal `n`.
    fn mixture(&self, n: Vec3) -> Mixture<'_, B::Dist> {
        let nodes = self.grid.nodes(n);
        let mut mix = Mixture {
            nodes: [None; MAX_NODES],
            prob: [0.0; MAX_NODES],
            len: 0,
            defensive: 1.0,
        };
        let mut total = 0.0f64;
        let mut weights = [0.0f64; MAX_NODES];
        for k in 0..nodes.len {
            if let Some(node) = self.node(nodes.index[k]) {
                let w = nodes.weight[k] as f64 * node.irradiance;
                if w > 0.0 && w.is_finite() {
                    mix.nodes[mix.len] = Some(&node.dist);
                    weights[mix.len] = w;
                    total += w;
                    mix.len += 1;
                }
            }
        }
        if total > 0.0 {
            let share = (1.0 - self.defensive) as f64 / total;
            for (p, w) in mix.prob.iter_mut().zip(&weights).take(mix.len) {
                *p = (w * share) as f32;
            }
            mix.defensive = self.defensive;
        } else {
            mix.len = 0;
        }
        mix
    }

    /// The mixture's density (in the unit square) at the centre of texel
    /// (column, row).
    #[inline]
    fn mixture_density(&self, mix: &Mixture<'_, B::Dist>, column: usize, row: usize) -> f32 {
        let c = self.map.grid().texel_centre(column, row);
        let mut p = mix.defensive * self.plain.pdf(c);
        for k in 0..mix.len {
            if let Some(d) = mix.nodes[k] {
                p += mix.prob[k] * d.pdf(c);
            }
        }
        p
    }

    fn mixture_pdf(&self, mix: &Mixture<'_, B::Dist>, dir: Vec3) -> f32 {
        match self.map.grid().texel_of(dir) {
            Some((k, j)) => self.mixture_density(mix, k, j) * self.map.grid().inv_jacobian(j),
            None => 0.0,
        }
    }
}

impl<B: TableBuilder> SphereSampler for OrientedSampler<B> {
    fn name(&self) -> &str {
        &self.name
    }

    /// Without a usable normal, a draw from the plain luminance table (with
    /// its own density). With one, u.x picks a component of the normal's
    /// mixture (the defensive table first) and is rescaled to draw from it.
    fn sample(&self, normal: Option<Vec3>, u: Vec2) -> Option<SphereSample> {
        let grid = self.map.grid();
        let Some(n) = usable_normal(normal) else {
            let s = self.plain.sample(u);
            return finish_draw(grid, s, |_, _| s.pdf, |dir| self.pdf(None, dir));
        };
        let mix = self.mixture(n);
        let ux = clamp_unit(u.x);
        let mut dist = &self.plain;
        let (mut lo, mut width) = (0.0f32, mix.defensive);
        if ux >= mix.defensive {
            let mut acc = mix.defensive;
            for k in 0..mix.len {
                let p = mix.prob[k];
                if let Some(d) = mix.nodes[k] {
                    if p > 0.0 {
                        (dist, lo, width) = (d, acc, p);
                    }
                }
                acc += p;
                if ux < acc {
                    break;
                }
            }
        }
        let ux = ((ux - lo) / width).clamp(0.0, ONE_MINUS_EPSILON);
        let s = dist.sample(Vec2::new(ux, u.y));
        finish_draw(
            grid,
            s,
            |k, j| self.mixture_density(&mix, k, j),
            |dir| self.mixture_pdf(&mix, dir),
        )
    }

    fn pdf(&self, normal: Option<Vec3>, dir: Vec3) -> f32 {
        match usable_normal(normal) {
            Some(n) => self.mixture_pdf(&self.mixture(n), dir),
            None => crate::sampler::texel_density(self.map.grid(), &self.plain, dir),
        }
    }

    /// The plain table and the nodes built so far.
    fn storage_bytes(&self) -> usize {
        self.plain.storage_bytes()
            + self
                .nodes
                .iter()
                .filter_map(|n| n.get().and_then(Option::as_ref))
                .map(|n| n.dist.storage_bytes())
                .sum::<usize>()
    }

    /// The mixture is found once for the whole batch.
    fn pdf_batch(&self, normal: Option<Vec3>, dir: &[Vec3], out: &mut [f32]) {
        match usable_normal(normal) {
            Some(n) => {
                let mix = self.mixture(n);
                for (o, &d) in out.iter_mut().zip(dir) {
                    *o = self.mixture_pdf(&mix, d);
                }
            }
            None => {
                for (o, &d) in out.iter_mut().zip(dir) {
                    *o = self.pdf(None, d);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_weights_sum_to_one_and_poles_use_their_node() {
        let g = NormalGrid::new(4, 6).unwrap();
        for n in [
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            Vec3::new(0.3, -0.4, 0.5).normalize(),
            Vec3::new(0.0, -1e-7, 1.0).normalize(),
            Vec3::new(1.0, -0.0, 0.0),
        ] {
            let nodes = g.nodes(n);
            let sum: f32 = nodes.weight[..nodes.len].iter().sum();
            assert!((sum - 1.0).abs() < 1e-5, "{n}: {sum}");
            assert!(nodes.index[..nodes.len].iter().all(|&i| i < g.node_count()));
        }
        let north = g.nodes(Vec3::Z);
        assert_eq!((north.len, north.index[0]), (1, g.cell_count()));
        let south = g.nodes(-Vec3::Z);
        assert_eq!((south.len, south.index[0]), (1, g.cell_count() + 1));
        // A cell's own centre uses that cell alone.
        for i in [0, 7, 23] {
            let nodes = g.nodes(g.node_normal(i));
            let best = (0..nodes.len)
                .max_by(|&a, &b| nodes.weight[a].total_cmp(&nodes.weight[b]))
                .unwrap();
            assert_eq!(nodes.index[best], i);
            assert!(nodes.weight[best] > 0.999);
        }
        assert!(NormalGrid::new(0, 3).is_err());
    }
}
