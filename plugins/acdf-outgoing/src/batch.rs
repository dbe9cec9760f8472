//! The batch paths of [`OutgoingSampler`]: draws and densities a chunk at a
//! time, for one outgoing direction (`sample_batch`, `pdf_batch`) or one
//! per pair (`sample_each`, `pdf_each`, a wavefront of shading points).
//!
//! A draw is two table searches (the drawn slice, then the other slice's
//! density at the point), then about a hundred operations of geometry
//! (two sine/cosine pairs, a rotation, a reflection, a Jacobian). In the
//! AVX2 build the choice of slice and the searches run 8 lanes at a time
//! (`acdf_core::simd::shared_grid`: selects, then binary lifting over the grid's narrow
//! indices, each step one gather per group of 8 lanes); in the portable
//! build, or where an array is too large for 32-bit gather indices, they
//! run one lane at a time. The sines and cosines of the chunk's
//! angles are computed many at a time (`sin_cos_turns_each`, which reads
//! its table from registers), and the rest of the geometry runs as one
//! loop over the chunk's lanes ([`draw_at`], [`coordinates`], free of
//! branches), which the compiler turns into SIMD, 8 lanes wide in the AVX2
//! build of the batch functions. Each lane runs the IEEE operations of the
//! one-at-a-time path in the same order (no fused multiply-adds are
//! formed), so the results are bit-identical to `sample` and `pdf`
//! (`batch_forms_equal_single_calls`, `each_forms_equal_single_calls`).

// The lane loops index several arrays of one chunk by the same lane
// number; that is the layout the vectoriser wants, not an iterator chain.
#![allow(clippy::needless_range_loop)]

use super::{coordinates, draw_at, Coordinates, Outgoing, OutgoingSampler, Route, TablePoint};
use acdf_core::fast::{sin_cos_quarter_turns_each, sin_cos_turns_each};
use acdf_core::{is_valid_outgoing, BxdfSample, Vec2, Vec3};

/// Draws (or densities) per chunk: enough to amortise the stages, small
/// enough for the stack; a whole number of lane stages.
const CHUNK: usize = 64;

/// The AVX2 token where the batch function runs in AVX2 code, so that the
/// chunk's searches run in lanes (`acdf_core::simd::shared_grid`); `None` for
/// the portable path, which searches one lane at a time (always, elsewhere
/// than on x86-64, where no token is ever made).
pub(super) type Simd = Option<acdf_core::simd::Avx2>;

/// The token and the slices' arrays as the lane kernels read them, found
/// once per batch call; `None` where the chunks search one lane at a time.
#[cfg(target_arch = "x86_64")]
type Kernel<'a> = Option<(
    acdf_core::simd::Avx2,
    acdf_core::simd::shared_grid::SharedGrid<'a>,
)>;
#[cfg(not(target_arch = "x86_64"))]
type Kernel<'a> = Option<std::marker::PhantomData<&'a ()>>;

#[cfg(target_arch = "x86_64")]
const _: () = assert!(CHUNK.is_multiple_of(acdf_core::search::lanes::STAGE));

/// One `f32` per lane of a chunk.
type Lanes = [f32; CHUNK];

/// Where the lanes of a chunk take their outgoing direction from.
trait Frames {
    /// Lane l's wo and what its draws share ([`Outgoing`]); `None` for an
    /// invalid wo (the lane has no draw and no density).
    fn frame(&self, l: usize) -> Option<(Vec3, Outgoing)>;

    /// [`frame`](Self::frame) for the geometry loops, without a branch: an
    /// invalid wo gives a valid stand-in, whose results are dropped.
    fn lane(&self, l: usize) -> (Vec3, Outgoing);

    /// Whether lane l's wo is valid ([`frame`](Self::frame) is `Some`).
    fn valid(&self, l: usize) -> bool;
}

/// One valid wo for every lane (`sample_batch`, `pdf_batch`): the geometry
/// loop reads it as a constant.
struct OneFrame(Vec3, Outgoing);

impl Frames for OneFrame {
    #[inline(always)]
    fn frame(&self, _: usize) -> Option<(Vec3, Outgoing)> {
        Some((self.0, self.1))
    }

    #[inline(always)]
    fn lane(&self, _: usize) -> (Vec3, Outgoing) {
        (self.0, self.1)
    }

    #[inline(always)]
    fn valid(&self, _: usize) -> bool {
        true
    }
}

/// A wo per lane (`sample_each`, `pdf_each`), each with its [`Outgoing`]
/// found once per chunk, one array per quantity (the layout the geometry
/// loop vectorises over); an invalid wo keeps the lane idle and holds the
/// stand-in (wo on the normal, [`Outgoing::NORMAL`]).
struct EachFrame {
    wo_x: Lanes,
    wo_y: Lanes,
    wo_z: Lanes,
    k: [usize; CHUNK],
    t: Lanes,
    rotation_x: Lanes,
    rotation_y: Lanes,
    sin_o: Lanes,
    valid: [bool; CHUNK],
}

impl EachFrame {
    fn new() -> Self {
        EachFrame {
            wo_x: [0.0; CHUNK],
            wo_y: [0.0; CHUNK],
            wo_z: [1.0; CHUNK],
            k: [0; CHUNK],
            t: [0.0; CHUNK],
            rotation_x: [1.0; CHUNK],
            rotation_y: [0.0; CHUNK],
            sin_o: [0.0; CHUNK],
            valid: [false; CHUNK],
        }
    }

    /// The frames of the chunk's directions `wo`.
    #[inline(always)]
    fn fill(&mut self, simd: Simd, sampler: &OutgoingSampler, wo: &[Vec3]) {
        for (l, &w) in wo.iter().enumerate().take(CHUNK) {
            let valid = is_valid_outgoing(w);
            let (w, o) = if valid {
                (w, sampler.outgoing(simd, w))
            } else {
                (Vec3::Z, Outgoing::NORMAL)
            };
            self.wo_x[l] = w.x;
            self.wo_y[l] = w.y;
            self.wo_z[l] = w.z;
            self.k[l] = o.k;
            self.t[l] = o.t;
            self.rotation_x[l] = o.rotation.x;
            self.rotation_y[l] = o.rotation.y;
            self.sin_o[l] = o.sin_o;
            self.valid[l] = valid;
        }
    }
}

impl Frames for EachFrame {
    #[inline(always)]
    fn frame(&self, l: usize) -> Option<(Vec3, Outgoing)> {
        self.valid[l].then(|| self.lane(l))
    }

    #[inline(always)]
    fn lane(&self, l: usize) -> (Vec3, Outgoing) {
        let wo = Vec3::new(self.wo_x[l], self.wo_y[l], self.wo_z[l]);
        let o = Outgoing {
            k: self.k[l],
            t: self.t[l],
            rotation: Vec2::new(self.rotation_x[l], self.rotation_y[l]),
            sin_o: self.sin_o[l],
        };
        (wo, o)
    }

    #[inline(always)]
    fn valid(&self, l: usize) -> bool {
        self.valid[l]
    }
}

/// The table points of a chunk, one array per quantity.
struct PointLanes {
    x: Lanes,
    v: Lanes,
    p_xv: Lanes,
    /// -1 where `TablePoint::same` holds, 0 elsewhere (a lane mask).
    same: [i32; CHUNK],
}

/// The draws of a chunk in the shading frame, one array per quantity.
struct ChunkDraws {
    wi_x: Lanes,
    wi_y: Lanes,
    wi_z: Lanes,
    /// The density of the draw where `shortcut` holds: the table's mixed
    /// with the cosine lobe's, as `sample_table` mixes them.
    pdf: Lanes,
    shortcut: [bool; CHUNK],
}

/// The coordinates of a chunk of wi, one array per quantity.
struct ChunkCoordinates {
    x: Lanes,
    v: Lanes,
    sin_h: Lanes,
    wo_h: Lanes,
    defined: [bool; CHUNK],
}

impl ChunkCoordinates {
    /// Lane l's coordinates.
    #[inline(always)]
    fn at(&self, l: usize) -> Coordinates {
        Coordinates {
            x: self.x[l],
            v: self.v[l],
            sin_h: self.sin_h[l],
            wo_h: self.wo_h[l],
            defined: self.defined[l],
        }
    }
}

impl OutgoingSampler {
    /// The lane kernel of a batch in the instance `simd` names.
    #[inline(always)]
    fn kernel(&self, simd: Simd) -> Kernel<'_> {
        #[cfg(target_arch = "x86_64")]
        {
            simd.zip(self.slices.lane_grid())
        }
        #[cfg(not(target_arch = "x86_64"))]
        {
            let _ = simd;
            None
        }
    }

    /// [`BxdfSampler::sample_batch`](acdf_core::BxdfSampler::sample_batch)
    /// itself: the blend and rotation of wo found once, then
    /// [`sample_chunk`](Self::sample_chunk) per chunk.
    #[inline(always)]
    pub(super) fn sample_batch_one(
        &self,
        wo: Vec3,
        u: &[Vec2],
        out: &mut [Option<BxdfSample>],
        simd: Simd,
    ) {
        if !is_valid_outgoing(wo) {
            out.iter_mut().zip(u).for_each(|(o, _)| *o = None);
            return;
        }
        let frame = OneFrame(wo, self.outgoing(simd, wo));
        let kernel = self.kernel(simd);
        for (uc, oc) in u.chunks(CHUNK).zip(out.chunks_mut(CHUNK)) {
            self.sample_chunk(kernel, &frame, uc, oc);
        }
    }

    /// [`BxdfSampler::sample_each`](acdf_core::BxdfSampler::sample_each)
    /// itself: per chunk the blend and rotation of each wo, then
    /// [`sample_chunk`](Self::sample_chunk).
    #[inline(always)]
    pub(super) fn sample_each_one(
        &self,
        wo: &[Vec3],
        u: &[Vec2],
        out: &mut [Option<BxdfSample>],
        simd: Simd,
    ) {
        let mut frames = EachFrame::new();
        let kernel = self.kernel(simd);
        for ((wc, uc), oc) in wo
            .chunks(CHUNK)
            .zip(u.chunks(CHUNK))
            .zip(out.chunks_mut(CHUNK))
        {
            frames.fill(simd, self, wc);
            let n = wc.len().min(uc.len()).min(oc.len());
            self.sample_chunk(kernel, &frames, &uc[..n], &mut oc[..n]);
        }
    }

    /// [`BxdfSampler::pdf_batch`](acdf_core::BxdfSampler::pdf_batch)
    /// itself, as [`sample_batch_one`](Self::sample_batch_one).
    #[inline(always)]
    pub(super) fn pdf_batch_one(&self, wo: Vec3, wi: &[Vec3], out: &mut [f32], simd: Simd) {
        if !is_valid_outgoing(wo) {
            out.iter_mut().zip(wi).for_each(|(o, _)| *o = 0.0);
            return;
        }
        let frame = OneFrame(wo, self.outgoing(simd, wo));
        let kernel = self.kernel(simd);
        for (wc, oc) in wi.chunks(CHUNK).zip(out.chunks_mut(CHUNK)) {
            self.pdf_chunk(kernel, &frame, wc, oc);
        }
    }

    /// [`BxdfSampler::pdf_each`](acdf_core::BxdfSampler::pdf_each) itself,
    /// as [`sample_each_one`](Self::sample_each_one).
    #[inline(always)]
    pub(super) fn pdf_each_one(&self, wo: &[Vec3], wi: &[Vec3], out: &mut [f32], simd: Simd) {
        let mut frames = EachFrame::new();
        let kernel = self.kernel(simd);
        for ((wc, ic), oc) in wo
            .chunks(CHUNK)
            .zip(wi.chunks(CHUNK))
            .zip(out.chunks_mut(CHUNK))
        {
            frames.fill(simd, self, wc);
            let n = wc.len().min(ic.len()).min(oc.len());
            self.pdf_chunk(kernel, &frames, &ic[..n], &mut oc[..n]);
        }
    }

    /// The draws of one chunk (at most [`CHUNK`] pairs): the table points
    /// (in lanes where `kernel` is given, one lane at a time otherwise), their
    /// angles many at a time, the geometry as one loop over the lanes, and
    /// each draw's check.
    #[inline(always)]
    fn sample_chunk<F: Frames>(
        &self,
        kernel: Kernel<'_>,
        frames: &F,
        u: &[Vec2],
        out: &mut [Option<BxdfSample>],
    ) {
        let n = u.len().min(out.len()).min(CHUNK);
        let map = self.map;
        let mut cosine_u: [Option<Vec2>; CHUNK] = [None; CHUNK];
        // Each lane's slices and u; a cosine lane or one without a frame
        // keeps the stand-in (slice 0, u = 0), whose point and geometry
        // are computed and ignored.
        let mut k = [0i32; CHUNK];
        let (mut t, mut u_x, mut u_y): (Lanes, Lanes, Lanes) =
            ([0.0; CHUNK], [0.0; CHUNK], [0.0; CHUNK]);
        let mut table_u: [Option<Vec2>; CHUNK] = [None; CHUNK];
        for l in 0..n {
            match frames.frame(l).map(|(_, o)| (o, self.route(u[l]))) {
                Some((o, Route::Table(u))) => {
                    (k[l], t[l], u_x[l], u_y[l]) = (o.k as i32, o.t, u.x, u.y);
                    table_u[l] = Some(u);
                }
                Some((_, Route::Cosine(u))) => cosine_u[l] = Some(u),
                None => {}
            }
        }
        let mut points = PointLanes {
            x: [0.0; CHUNK],
            v: [0.0; CHUNK],
            p_xv: [0.0; CHUNK],
            same: [0; CHUNK],
        };
        // No closures here: a closure would not be compiled into the
        // caller's AVX2 code, and the intrinsics would become calls.
        #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
        let mut in_lanes = false;
        #[cfg(not(target_arch = "x86_64"))]
        let _ = kernel;
        #[cfg(target_arch = "x86_64")]
        if let Some((cpu, grid)) = kernel {
            use acdf_core::search::lanes::STAGE;
            use acdf_core::simd::shared_grid::{DrawInputs, DrawnPoints};
            in_lanes = true;
            for at in (0..CHUNK).step_by(STAGE) {
                let input = DrawInputs {
                    k: &k[at..],
                    t: &t[at..],
                    u_x: &u_x[at..],
                    u_y: &u_y[at..],
                };
                let out = DrawnPoints {
                    x: &mut points.x[at..],
                    y: &mut points.v[at..],
                    p: &mut points.p_xv[at..],
                    same: &mut points.same[at..],
                };
                in_lanes &= grid.sample_lanes(cpu, &input, self.cells, super::CELL_MARGIN, out);
            }
        }
        if !in_lanes {
            for l in 0..n {
                let point = match (frames.frame(l), table_u[l]) {
                    (Some((_, o)), Some(u)) => self.table_point(&o, u),
                    _ => TablePoint::default(),
                };
                points.x[l] = point.x;
                points.v[l] = point.v;
                points.p_xv[l] = point.p_xv;
                points.same[l] = -i32::from(point.same);
            }
        }
        // θ_h = (π/2) v² is v² quarter turns, as `HalfMap::angles` has it.
        let mut squares: Lanes = [0.0; CHUNK];
        for l in 0..n {
            squares[l] = points.v[l] * points.v[l];
        }
        let (mut sin_h, mut cos_h): (Lanes, Lanes) = ([0.0; CHUNK], [0.0; CHUNK]);
        let (mut sin_p, mut cos_p): (Lanes, Lanes) = ([0.0; CHUNK], [0.0; CHUNK]);
        sin_cos_quarter_turns_each(&squares[..n], &mut sin_h[..n], &mut cos_h[..n]);
        sin_cos_turns_each(&points.x[..n], &mut sin_p[..n], &mut cos_p[..n]);
        let mut draws = ChunkDraws {
            wi_x: [0.0; CHUNK],
            wi_y: [0.0; CHUNK],
            wi_z: [0.0; CHUNK],
            pdf: [0.0; CHUNK],
            shortcut: [false; CHUNK],
        };
        for l in 0..n {
            let (wo, o) = frames.lane(l);
            let point = TablePoint {
                x: points.x[l],
                v: points.v[l],
                p_xv: points.p_xv[l],
                same: points.same[l] != 0,
            };
            let theta = map.polar(point.v, || (sin_h[l], cos_h[l]));
            let d = draw_at(map, &o, wo, &point, (theta, (sin_p[l], cos_p[l])));
            draws.wi_x[l] = d.wi.x;
            draws.wi_y[l] = d.wi.y;
            draws.wi_z[l] = d.wi.z;
            draws.pdf[l] = acdf_tabulated::mix_with_cosine(self.cosine_fraction, d.table, d.wi);
            draws.shortcut[l] = d.shortcut;
        }
        for l in 0..n {
            let Some((wo, o)) = frames.frame(l) else {
                out[l] = None;
                continue;
            };
            out[l] = match cosine_u[l] {
                Some(u) => self.sample_cosine(&o, wo, u),
                None => {
                    let wi = Vec3::new(draws.wi_x[l], draws.wi_y[l], draws.wi_z[l]);
                    let pdf = draws.shortcut[l].then_some(draws.pdf[l]);
                    self.finish_draw(&o, wo, wi, pdf)
                }
            };
        }
    }

    /// The densities of one chunk (at most [`CHUNK`] pairs): the
    /// coordinates as one loop over the lanes, the blended densities of
    /// the table points in lanes where `kernel` is given, then each density's
    /// check and Jacobian (and the table lookups, without lanes).
    #[inline(always)]
    fn pdf_chunk<F: Frames>(&self, kernel: Kernel<'_>, frames: &F, wi: &[Vec3], out: &mut [f32]) {
        let n = wi.len().min(out.len()).min(CHUNK);
        let map = self.map;
        let mut lanes = ChunkCoordinates {
            x: [0.0; CHUNK],
            v: [0.0; CHUNK],
            sin_h: [0.0; CHUNK],
            wo_h: [0.0; CHUNK],
            defined: [false; CHUNK],
        };
        let (mut k, mut t) = ([0i32; CHUNK], [0.0f32; CHUNK]);
        for l in 0..n {
            let (wo, o) = frames.lane(l);
            let c = coordinates::<false>(map, o.rotation, wo, wi[l]);
            lanes.x[l] = c.x;
            lanes.v[l] = c.v;
            lanes.sin_h[l] = c.sin_h;
            lanes.wo_h[l] = c.wo_h;
            lanes.defined[l] = c.defined;
            (k[l], t[l]) = (o.k as i32, o.t);
        }
        #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
        let mut blended: Lanes = [0.0; CHUNK];
        // No closures, as in `sample_chunk`.
        #[cfg_attr(not(target_arch = "x86_64"), allow(unused_mut))]
        let mut in_lanes = false;
        #[cfg(not(target_arch = "x86_64"))]
        let _ = kernel;
        #[cfg(target_arch = "x86_64")]
        if let Some((cpu, grid)) = kernel {
            use acdf_core::search::lanes::STAGE;
            in_lanes = true;
            for at in (0..CHUNK).step_by(STAGE) {
                in_lanes &= grid.density_lanes(
                    cpu,
                    &k[at..],
                    &t[at..],
                    &lanes.x[at..],
                    &lanes.v[at..],
                    self.cells,
                    &mut blended[at..],
                );
            }
        }
        if in_lanes {
            // What `pdf_with` does with each lane's blended density, as one
            // loop free of branches, which compiles to SIMD.
            let a = self.cosine_fraction;
            for l in 0..n {
                let w = wi[l];
                let table = self.table_density(blended[l], &lanes.at(l));
                let p = acdf_tabulated::mix_with_cosine(a, table, w);
                let defined = frames.valid(l)
                    & w.x.is_finite()
                    & w.y.is_finite()
                    & w.z.is_finite()
                    & (w.z > 0.0);
                out[l] = if defined { p } else { 0.0 };
            }
            return;
        }
        for l in 0..n {
            out[l] = match frames.frame(l) {
                Some((_, o)) => self.pdf_with(&o, wi[l], &lanes.at(l)),
                None => 0.0,
            };
        }
    }
}
