//! The batch paths of [`TabulatedBrdfSampler`]: chunks of draws (or of
//! densities), for one outgoing direction (`sample_batch`, `pdf_batch`) or
//! one per pair (`sample_each`, `pdf_each`, a wavefront of shading points).
//!
//! A draw is a table search, then about a hundred operations of geometry
//! (two sine/cosine pairs, a reflection, a Jacobian), then a check of the
//! drawn cell. The searches of a chunk go through the slice's distribution
//! (`SliceDistribution::sample_batch_and_same_cell`, or its
//! `sample_each` stages for a wavefront); the sines and cosines of the
//! chunk's angles are computed many at a time (they read a table), and
//! the rest of the geometry of the whole chunk runs as one loop over lanes
//! ([`Slice::draw`] and [`Slice::coordinates_of`] have no branches), which
//! the compiler turns into SIMD, 8 lanes wide where the CPU has AVX2
//! (selected at run time); the per-draw checks and any exact recomputation
//! follow lane by lane.
//! Each lane runs the same IEEE operations in the same order as the
//! one-at-a-time path (no fused multiply-adds are formed), so the batch
//! results are bit-identical to `sample` and `pdf`.

// The lane loops index several arrays of one chunk by the same lane
// number; that is the layout the vectoriser wants, not an iterator chain.
#![allow(clippy::needless_range_loop)]

use super::{
    mix_with_cosine, Slice, SliceGeometry, TableCoordinates, TableDraw, TabulatedBrdfSampler,
    BATCH_CHUNK, CELL_MARGIN,
};
use crate::tabulate::HalfMap;
use crate::{SliceBuilder, SliceDistribution};
use acdf_core::fast::{sin_cos_quarter_turns_each, sin_cos_turns_each};
use acdf_core::simd::Avx2;
use acdf_core::{clamp_unit, is_valid_outgoing, BxdfSample, Distribution2D, Sample2D, Vec2, Vec3};

/// The geometry of a chunk of draws, one array per quantity (the layout
/// the SIMD loop reads and writes).
struct DrawLanes {
    wi_x: [f32; BATCH_CHUNK],
    wi_y: [f32; BATCH_CHUNK],
    wi_z: [f32; BATCH_CHUNK],
    table: [f32; BATCH_CHUNK],
    shortcut_geometry: [bool; BATCH_CHUNK],
}

impl DrawLanes {
    fn new() -> Self {
        DrawLanes {
            wi_x: [0.0; BATCH_CHUNK],
            wi_y: [0.0; BATCH_CHUNK],
            wi_z: [0.0; BATCH_CHUNK],
            table: [0.0; BATCH_CHUNK],
            shortcut_geometry: [false; BATCH_CHUNK],
        }
    }

    /// Lane l as the one-at-a-time path has it.
    #[inline(always)]
    fn get(&self, l: usize) -> TableDraw {
        TableDraw {
            wi: Vec3::new(self.wi_x[l], self.wi_y[l], self.wi_z[l]),
            table: self.table[l],
            shortcut_geometry: self.shortcut_geometry[l],
        }
    }
}

/// The table coordinates of a chunk of incident directions, one array per
/// quantity.
struct CoordinateLanes {
    x: [f32; BATCH_CHUNK],
    v: [f32; BATCH_CHUNK],
    denominator: [f32; BATCH_CHUNK],
    defined: [bool; BATCH_CHUNK],
}

impl CoordinateLanes {
    fn new() -> Self {
        CoordinateLanes {
            x: [0.0; BATCH_CHUNK],
            v: [0.0; BATCH_CHUNK],
            denominator: [0.0; BATCH_CHUNK],
            defined: [false; BATCH_CHUNK],
        }
    }

    /// Lane l as the one-at-a-time path has it.
    #[inline(always)]
    fn get(&self, l: usize) -> TableCoordinates {
        TableCoordinates {
            p: Vec2::new(self.x[l], self.v[l]),
            denominator: self.denominator[l],
            defined: self.defined[l],
        }
    }
}

/// Where each lane of a chunk takes its outgoing direction and slice axes
/// from: one pair for the whole chunk (`sample_batch`, `pdf_batch`) or one
/// per lane (`sample_each`, `pdf_each`).
trait LaneFrames {
    fn wo(&self, l: usize) -> Vec3;
    fn geometry(&self, l: usize) -> SliceGeometry;
}

/// One outgoing direction and slice for every lane.
struct OneFrame {
    wo: Vec3,
    geometry: SliceGeometry,
}

impl LaneFrames for OneFrame {
    #[inline(always)]
    fn wo(&self, _: usize) -> Vec3 {
        self.wo
    }

    #[inline(always)]
    fn geometry(&self, _: usize) -> SliceGeometry {
        self.geometry
    }
}

/// The outer-map sines and cosines of a chunk's half-vector angles (θ_h =
/// (π/2) v² and φ_h = 2π x, see [`SliceGeometry::angles_of`]).
struct AngleLanes {
    sin_theta: [f32; BATCH_CHUNK],
    cos_theta: [f32; BATCH_CHUNK],
    sin_phi: [f32; BATCH_CHUNK],
    cos_phi: [f32; BATCH_CHUNK],
}

impl AngleLanes {
    /// The angles of the draws, computed many at a time
    /// ([`sin_cos_turns_each`]): the sine and cosine read a table, which a
    /// loop of `angles_of` would do one lane at a time rather than in SIMD.
    fn of(drawn: &[Sample2D]) -> Self {
        let n = drawn.len().min(BATCH_CHUNK);
        let (mut squares, mut xs) = ([0.0f32; BATCH_CHUNK], [0.0f32; BATCH_CHUNK]);
        for l in 0..n {
            // θ_h in quarter turns, as `HalfMap::angles` takes it.
            squares[l] = drawn[l].p.y * drawn[l].p.y;
            xs[l] = drawn[l].p.x;
        }
        let mut angles = AngleLanes {
            sin_theta: [0.0; BATCH_CHUNK],
            cos_theta: [0.0; BATCH_CHUNK],
            sin_phi: [0.0; BATCH_CHUNK],
            cos_phi: [0.0; BATCH_CHUNK],
        };
        sin_cos_quarter_turns_each(&squares[..n], &mut angles.sin_theta, &mut angles.cos_theta);
        sin_cos_turns_each(&xs[..n], &mut angles.sin_phi, &mut angles.cos_phi);
        angles
    }

    /// Lane l's angles as [`SliceGeometry::angles_of`] gives them, bit for
    /// bit (the polar cap's map in the first row).
    #[inline(always)]
    fn get(&self, map: &HalfMap, v: f32, l: usize) -> ((f32, f32), (f32, f32)) {
        (
            map.polar(v, || (self.sin_theta[l], self.cos_theta[l])),
            (self.sin_phi[l], self.cos_phi[l]),
        )
    }
}

/// [`SliceGeometry::draw`] of every lane, into `out`, the angles from
/// `angles`. The frames are read by value, so the loop body depends on
/// nothing the stores could change.
#[inline(always)]
fn draw_lanes_generic<F: LaneFrames>(
    frames: &F,
    drawn: &[Sample2D],
    angles: &AngleLanes,
    out: &mut DrawLanes,
    _: Option<Avx2>,
) {
    for l in 0..drawn.len().min(BATCH_CHUNK) {
        let geometry = frames.geometry(l);
        let s = drawn[l];
        let d = geometry.draw_from_angles(frames.wo(l), s, angles.get(&geometry.map, s.p.y, l));
        out.wi_x[l] = d.wi.x;
        out.wi_y[l] = d.wi.y;
        out.wi_z[l] = d.wi.z;
        out.table[l] = d.table;
        out.shortcut_geometry[l] = d.shortcut_geometry;
    }
}

/// [`SliceGeometry::coordinates_of`] of every lane, into `out`.
#[inline(always)]
fn coordinate_lanes_generic<F: LaneFrames>(
    frames: &F,
    wi: &[Vec3],
    out: &mut CoordinateLanes,
    _: Option<Avx2>,
) {
    for l in 0..wi.len().min(BATCH_CHUNK) {
        let c = frames.geometry(l).coordinates_of(frames.wo(l), wi[l]);
        out.x[l] = c.p.x;
        out.v[l] = c.p.y;
        out.denominator[l] = c.denominator;
        out.defined[l] = c.defined;
    }
}

/// The table draws of a chunk carried to the shading frame.
fn draw_lanes<F: LaneFrames>(frames: &F, drawn: &[Sample2D], out: &mut DrawLanes) {
    let angles = AngleLanes::of(drawn);
    acdf_core::dispatch!(draw_lanes_generic, frames, drawn, &angles, out)
}

/// The table coordinates of a chunk of incident directions.
fn coordinate_lanes<F: LaneFrames>(frames: &F, wi: &[Vec3], out: &mut CoordinateLanes) {
    acdf_core::dispatch!(coordinate_lanes_generic, frames, wi, out)
}

impl<B: SliceBuilder> TabulatedBrdfSampler<B> {
    /// Table draws for every u (no cosine lobe), a chunk at a time: the
    /// searches and cell tests by the distribution's
    /// `sample_batch_and_same_cell`, the geometry by [`draw_lanes`], then
    /// each draw's check.
    pub(super) fn sample_table_batch(
        &self,
        slice: &Slice<'_, B::Dist>,
        wo: Vec3,
        u: &[Vec2],
        out: &mut [Option<BxdfSample>],
    ) {
        let mut table_u = [Vec2::ZERO; BATCH_CHUNK];
        let mut drawn = [Sample2D::default(); BATCH_CHUNK];
        let mut draws = DrawLanes::new();
        let mut same_cell = [false; BATCH_CHUNK];
        let mut wi = [Vec3::ZERO; BATCH_CHUNK];
        let mut coordinates = CoordinateLanes::new();
        let frame = OneFrame {
            wo,
            geometry: slice.geometry(),
        };
        for (uc, oc) in u.chunks(BATCH_CHUNK).zip(out.chunks_mut(BATCH_CHUNK)) {
            let n = uc.len().min(oc.len());
            for (t, &u) in table_u.iter_mut().zip(&uc[..n]) {
                *t = Vec2::new(clamp_unit(u.x), clamp_unit(u.y));
            }
            slice.dist.sample_batch_and_same_cell(
                &table_u[..n],
                CELL_MARGIN,
                &mut drawn[..n],
                &mut same_cell[..n],
            );
            draw_lanes(&frame, &drawn[..n], &mut draws);
            // The exact density of every draw's wi, as `pdf` finds it, for
            // the draws whose cell check fails: cheaper for the whole chunk
            // in SIMD than one by one.
            for (l, w) in wi[..n].iter_mut().enumerate() {
                *w = Vec3::new(draws.wi_x[l], draws.wi_y[l], draws.wi_z[l]);
            }
            coordinate_lanes(&frame, &wi[..n], &mut coordinates);
            for (l, o) in oc[..n].iter_mut().enumerate() {
                *o = self.finish_draw_with(
                    &draws.get(l),
                    || same_cell[l],
                    || {
                        mix_with_cosine(
                            self.cosine_fraction,
                            coordinates.get(l).table_pdf(slice.dist),
                            wi[l],
                        )
                    },
                );
            }
        }
    }

    /// The mixed density at every wi, a chunk at a time: the coordinates
    /// by [`coordinate_lanes`], then each table lookup.
    pub(super) fn pdf_table_batch(
        &self,
        slice: &Slice<'_, B::Dist>,
        wo: Vec3,
        wi: &[Vec3],
        out: &mut [f32],
    ) {
        let mut coordinates = CoordinateLanes::new();
        let frame = OneFrame {
            wo,
            geometry: slice.geometry(),
        };
        let mut points = [Vec2::ZERO; BATCH_CHUNK];
        let mut p_xv = [0.0f32; BATCH_CHUNK];
        for (wc, oc) in wi.chunks(BATCH_CHUNK).zip(out.chunks_mut(BATCH_CHUNK)) {
            let n = wc.len().min(oc.len());
            coordinate_lanes(&frame, &wc[..n], &mut coordinates);
            // All lanes' densities in one call to the slice (lanes without
            // a density look up a point that is then ignored).
            for (l, p) in points[..n].iter_mut().enumerate() {
                *p = Vec2::new(coordinates.x[l], coordinates.v[l]);
            }
            slice.dist.pdf_batch(&points[..n], &mut p_xv[..n]);
            for (l, (o, &wi)) in oc[..n].iter_mut().zip(&wc[..n]).enumerate() {
                *o = if wi.is_finite() && wi.z > 0.0 {
                    mix_with_cosine(
                        self.cosine_fraction,
                        coordinates.get(l).table_pdf_from(p_xv[l]),
                        wi,
                    )
                } else {
                    0.0
                };
            }
        }
    }
}

/// The outgoing side of a chunk with one wo per lane: the direction, the
/// rotation of its slice and the slice's distribution (`None` for an
/// invalid wo or a slice that failed to build).
struct OutgoingLanes<'a, D> {
    wo_x: [f32; BATCH_CHUNK],
    wo_y: [f32; BATCH_CHUNK],
    wo_z: [f32; BATCH_CHUNK],
    rotation_x: [f32; BATCH_CHUNK],
    rotation_y: [f32; BATCH_CHUNK],
    dist: [Option<&'a D>; BATCH_CHUNK],
    map: HalfMap,
}

/// The θ_o cell of every lane's wo (the number of cell bounds at or below
/// -cos θ_o, as `ThetaOCells::cell` counts them), the rotation
/// (cos φ_o, sin φ_o) = (x, y) / sin θ_o, or (1, 0) on the pole, as
/// `slice_for` computes them, and whether wo is valid
/// (`is_valid_outgoing`): the same IEEE operations, with the lanes as the
/// inner loop so that the compiler vectorises across them.
#[inline(always)]
fn outgoing_cells_generic<D>(
    bounds: &[f32],
    lanes: &mut OutgoingLanes<'_, D>,
    n: usize,
    cells: &mut [u32; BATCH_CHUNK],
    valid: &mut [bool; BATCH_CHUNK],
    _: Option<Avx2>,
) {
    for l in 0..n {
        let wo = Vec3::new(lanes.wo_x[l], lanes.wo_y[l], lanes.wo_z[l]);
        valid[l] = is_valid_outgoing(wo);
    }
    // Eight lanes at a time with the bounds as the inner loop, so that each
    // block's counts stay in one register across all the bounds.
    for (block, cells) in cells.chunks_exact_mut(8).take(n.div_ceil(8)).enumerate() {
        let z: [f32; 8] = std::array::from_fn(|k| -lanes.wo_z[8 * block + k]);
        let mut count = [0u32; 8];
        // The bounds come padded to a multiple of eight: eight per
        // iteration, unrolled.
        for eight in bounds.chunks_exact(8) {
            for &b in eight {
                for k in 0..8 {
                    count[k] += (b <= z[k]) as u32;
                }
            }
        }
        cells.copy_from_slice(&count);
    }
    for l in 0..n {
        let (x, y) = (lanes.wo_x[l], lanes.wo_y[l]);
        let sin_o = (x * x + y * y).sqrt();
        let inverse = 1.0 / sin_o;
        let pole = !(sin_o > 0.0);
        lanes.rotation_x[l] = if pole { 1.0 } else { x * inverse };
        lanes.rotation_y[l] = if pole { 0.0 } else { y * inverse };
    }
}

/// The θ_o cells and rotations of a chunk's outgoing directions.
fn outgoing_cells<D>(
    bounds: &[f32],
    lanes: &mut OutgoingLanes<'_, D>,
    n: usize,
    cells: &mut [u32; BATCH_CHUNK],
    valid: &mut [bool; BATCH_CHUNK],
) {
    acdf_core::dispatch!(outgoing_cells_generic, bounds, lanes, n, cells, valid)
}

impl<'a, D: Distribution2D> OutgoingLanes<'a, D> {
    /// The slices of `wo`: for relative slices (one φ_o cell), the θ_o
    /// cells and rotations of all lanes in one branch-free pass (SIMD where
    /// the CPU has AVX2), then each lane's slice; otherwise lane by lane.
    fn find<B: SliceBuilder<Dist = D>>(sampler: &'a TabulatedBrdfSampler<B>, wo: &[Vec3]) -> Self {
        let mut lanes = OutgoingLanes {
            wo_x: [0.0; BATCH_CHUNK],
            wo_y: [0.0; BATCH_CHUNK],
            wo_z: [0.0; BATCH_CHUNK],
            rotation_x: [1.0; BATCH_CHUNK],
            rotation_y: [0.0; BATCH_CHUNK],
            dist: [None; BATCH_CHUNK],
            map: sampler.half_map,
        };
        let n = wo.len().min(BATCH_CHUNK);
        for (l, &wo) in wo[..n].iter().enumerate() {
            lanes.wo_x[l] = wo.x;
            lanes.wo_y[l] = wo.y;
            lanes.wo_z[l] = wo.z;
        }
        if !sampler.relative_phi {
            for (l, &wo) in wo[..n].iter().enumerate() {
                if !is_valid_outgoing(wo) {
                    continue;
                }
                if let Some(slice) = sampler.slice_for(wo) {
                    lanes.rotation_x[l] = slice.rotation.x;
                    lanes.rotation_y[l] = slice.rotation.y;
                    lanes.dist[l] = Some(slice.dist);
                }
            }
            return lanes;
        }
        let mut cells = [0u32; BATCH_CHUNK];
        let mut valid = [false; BATCH_CHUNK];
        outgoing_cells(
            sampler.theta_o_cells.bounds(),
            &mut lanes,
            n,
            &mut cells,
            &mut valid,
        );
        let phi_o = sampler.resolution.phi_o;
        for l in 0..n {
            if valid[l] {
                lanes.dist[l] = sampler.slice_at(cells[l] as usize * phi_o).ok();
            }
        }
        lanes
    }
}

impl<D> LaneFrames for OutgoingLanes<'_, D> {
    #[inline(always)]
    fn wo(&self, l: usize) -> Vec3 {
        Vec3::new(self.wo_x[l], self.wo_y[l], self.wo_z[l])
    }

    #[inline(always)]
    fn geometry(&self, l: usize) -> SliceGeometry {
        SliceGeometry {
            rotation: Vec2::new(self.rotation_x[l], self.rotation_y[l]),
            map: self.map,
        }
    }
}

impl<B: SliceBuilder> TabulatedBrdfSampler<B> {
    /// `sample` of every (wo, u) pair without a cosine lobe, a chunk at a
    /// time: the outgoing cells in SIMD and the slices lane by lane, the
    /// draws and their box tests by the distribution's
    /// `sample_each_and_same_cell` (SIMD lanes with one table each, for
    /// both built-in distributions), the geometry and the exact densities in
    /// SIMD, then each draw's check.
    pub(super) fn sample_each_table(
        &self,
        wo: &[Vec3],
        u: &[Vec2],
        out: &mut [Option<BxdfSample>],
    ) {
        let mut drawn = [Sample2D::default(); BATCH_CHUNK];
        let mut draws = DrawLanes::new();
        let mut wi = [Vec3::ZERO; BATCH_CHUNK];
        let mut coordinates = CoordinateLanes::new();
        let mut dists = Vec::with_capacity(BATCH_CHUNK);
        let chunks = wo
            .chunks(BATCH_CHUNK)
            .zip(u.chunks(BATCH_CHUNK))
            .zip(out.chunks_mut(BATCH_CHUNK));
        for ((wc, uc), oc) in chunks {
            let n = wc.len().min(uc.len()).min(oc.len());
            let lanes = OutgoingLanes::find(self, &wc[..n]);
            // The draws of the lanes that have a slice, from their slices
            // together (the distribution overlaps them where it can).
            dists.clear();
            dists.extend(lanes.dist[..n].iter().flatten());
            let m = dists.len();
            let mut lane_u = [Vec2::ZERO; BATCH_CHUNK];
            let mut lane_of = [0usize; BATCH_CHUNK];
            if m < n {
                let with_slice = (0..n).filter(|&l| lanes.dist[l].is_some());
                for (k, l) in with_slice.enumerate() {
                    lane_u[k] = uc[l];
                    lane_of[k] = l;
                }
            }
            let mut same = [false; BATCH_CHUNK];
            let mut compact = [Sample2D::default(); BATCH_CHUNK];
            let mut compact_same = [false; BATCH_CHUNK];
            // When every lane has a slice (the usual case) the draws go
            // straight into place, without compaction.
            let every = m == n;
            let (lane_u, to, to_same) = if every {
                (&uc[..n], &mut drawn[..n], &mut same[..n])
            } else {
                (&lane_u[..m], &mut compact[..m], &mut compact_same[..m])
            };
            B::Dist::sample_each_and_same_cell(&dists, lane_u, CELL_MARGIN, to, to_same);
            if !every {
                for (k, &l) in lane_of[..m].iter().enumerate() {
                    drawn[l] = compact[k];
                    same[l] = compact_same[k];
                }
            }
            draw_lanes(&lanes, &drawn[..n], &mut draws);
            for (l, w) in wi[..n].iter_mut().enumerate() {
                *w = Vec3::new(draws.wi_x[l], draws.wi_y[l], draws.wi_z[l]);
            }
            coordinate_lanes(&lanes, &wi[..n], &mut coordinates);
            for (l, o) in oc[..n].iter_mut().enumerate() {
                *o = lanes.dist[l].and_then(|dist| {
                    self.finish_draw_with(
                        &draws.get(l),
                        || same[l],
                        || {
                            mix_with_cosine(
                                self.cosine_fraction,
                                coordinates.get(l).table_pdf(dist),
                                wi[l],
                            )
                        },
                    )
                });
            }
        }
    }

    /// `pdf` of every (wo, wi) pair without a cosine lobe, a chunk at a
    /// time: the slices as in `sample_each_table`, the coordinates in SIMD,
    /// the table lookups by the distribution's `pdf_each`, then each lane's
    /// mixing.
    pub(super) fn pdf_each_table(&self, wo: &[Vec3], wi: &[Vec3], out: &mut [f32]) {
        let mut coordinates = CoordinateLanes::new();
        let mut dists = Vec::with_capacity(BATCH_CHUNK);
        let chunks = wo
            .chunks(BATCH_CHUNK)
            .zip(wi.chunks(BATCH_CHUNK))
            .zip(out.chunks_mut(BATCH_CHUNK));
        for ((wc, ic), oc) in chunks {
            let n = wc.len().min(ic.len()).min(oc.len());
            let lanes = OutgoingLanes::find(self, &wc[..n]);
            coordinate_lanes(&lanes, &ic[..n], &mut coordinates);
            // The densities of the lanes with a slice, from their slices
            // together (the distribution overlaps the lookups where it can).
            dists.clear();
            dists.extend(lanes.dist[..n].iter().flatten());
            let m = dists.len();
            let mut points = [Vec2::ZERO; BATCH_CHUNK];
            let mut lane_of = [0usize; BATCH_CHUNK];
            let with_slice = (0..n).filter(|&l| lanes.dist[l].is_some());
            for (k, l) in with_slice.enumerate() {
                points[k] = Vec2::new(coordinates.x[l], coordinates.v[l]);
                lane_of[k] = l;
            }
            let mut p_xv = [0.0f32; BATCH_CHUNK];
            if m == n {
                // Every lane has a slice (the usual case): no compaction.
                B::Dist::pdf_each(&dists, &points[..n], &mut p_xv[..n]);
            } else {
                let mut compact_p = [0.0f32; BATCH_CHUNK];
                B::Dist::pdf_each(&dists, &points[..m], &mut compact_p[..m]);
                for (k, &l) in lane_of[..m].iter().enumerate() {
                    p_xv[l] = compact_p[k];
                }
            }
            for (l, o) in oc[..n].iter_mut().enumerate() {
                let wi = ic[l];
                *o = match lanes.dist[l] {
                    Some(_) if wi.is_finite() && wi.z > 0.0 => mix_with_cosine(
                        self.cosine_fraction,
                        coordinates.get(l).table_pdf_from(p_xv[l]),
                        wi,
                    ),
                    Some(_) => 0.0,
                    // An invalid wo, or a slice that failed to build.
                    None => self.pdf_one(wc[l], wi, None),
                };
            }
        }
    }
}
