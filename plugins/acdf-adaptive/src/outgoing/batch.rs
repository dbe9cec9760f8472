//! The batch paths of [`OutgoingSampler`] for one outgoing direction: a
//! chunk of draws (or densities) at a time, in stages.
//!
//! A draw is two table searches (the drawn slice, then the other slice's
//! density at the point), then about a hundred operations of geometry
//! (two sine/cosine pairs, a rotation, a reflection, a Jacobian). The
//! searches run one lane at a time; the sines and cosines of the chunk's
//! angles are computed many at a time (`sin_cos_turns_each`, which reads
//! its table from registers), and the rest of the geometry runs as one
//! loop over the chunk's lanes ([`draw_at`], [`coordinates`], free of
//! branches), which the compiler turns into SIMD, 8 lanes wide in the AVX2
//! build of the batch functions. Each lane runs the IEEE operations of the
//! one-at-a-time path in the same order (no fused multiply-adds are
//! formed), so the results are bit-identical to `sample` and `pdf`
//! (`batch_forms_equal_single_calls`).

// The lane loops index several arrays of one chunk by the same lane
// number; that is the layout the vectoriser wants, not an iterator chain.
#![allow(clippy::needless_range_loop)]

use super::{coordinates, draw_at, Coordinates, OutgoingSampler, Route, TablePoint};
use acdf_core::fast::{sin_cos_quarter_turns_each, sin_cos_turns_each};
use acdf_core::{is_valid_outgoing, BxdfSample, Vec2, Vec3};

/// Draws (or densities) per chunk: enough to amortise the stages, small
/// enough for the stack.
const CHUNK: usize = 64;

/// One `f32` per lane of a chunk.
type Lanes = [f32; CHUNK];

impl OutgoingSampler {
    /// [`BxdfSampler::sample_batch`](acdf_core::BxdfSampler::sample_batch)
    /// itself: the blend and rotation of wo found once, then per chunk the
    /// table points one lane at a time, their angles many at a time, the
    /// geometry as one loop over the lanes, and each draw's check.
    #[inline(always)]
    pub(super) fn sample_batch_one(&self, wo: Vec3, u: &[Vec2], out: &mut [Option<BxdfSample>]) {
        if !is_valid_outgoing(wo) {
            out.iter_mut().zip(u).for_each(|(o, _)| *o = None);
            return;
        }
        let o = self.outgoing(wo);
        let map = self.map;
        let mut cosine_u: [Option<Vec2>; CHUNK] = [None; CHUNK];
        let (mut x, mut v, mut p_xv) = ([0.0; CHUNK], [0.0; CHUNK], [0.0; CHUNK]);
        let mut same = [false; CHUNK];
        let mut squares: Lanes = [0.0; CHUNK];
        let (mut sin_h, mut cos_h): (Lanes, Lanes) = ([0.0; CHUNK], [0.0; CHUNK]);
        let (mut sin_p, mut cos_p): (Lanes, Lanes) = ([0.0; CHUNK], [0.0; CHUNK]);
        let (mut wi_x, mut wi_y, mut wi_z): (Lanes, Lanes, Lanes) =
            ([0.0; CHUNK], [0.0; CHUNK], [0.0; CHUNK]);
        let mut table: Lanes = [0.0; CHUNK];
        let mut shortcut = [false; CHUNK];
        for (uc, oc) in u.chunks(CHUNK).zip(out.chunks_mut(CHUNK)) {
            let n = uc.len().min(oc.len());
            // The searches, lane by lane (a cosine lane keeps the point
            // (0, 0), whose geometry is computed and ignored).
            for l in 0..n {
                let point = match self.route(uc[l]) {
                    Route::Cosine(u) => {
                        cosine_u[l] = Some(u);
                        TablePoint::default()
                    }
                    Route::Table(u) => {
                        cosine_u[l] = None;
                        self.table_point(&o, u)
                    }
                };
                x[l] = point.x;
                v[l] = point.v;
                p_xv[l] = point.p_xv;
                same[l] = point.same;
            }
            // θ_h = (π/2) v² is v² quarter turns, as `HalfMap::angles` has it.
            for l in 0..n {
                squares[l] = v[l] * v[l];
            }
            sin_cos_quarter_turns_each(&squares[..n], &mut sin_h[..n], &mut cos_h[..n]);
            sin_cos_turns_each(&x[..n], &mut sin_p[..n], &mut cos_p[..n]);
            for l in 0..n {
                let point = TablePoint {
                    x: x[l],
                    v: v[l],
                    p_xv: p_xv[l],
                    same: same[l],
                };
                let theta = map.polar(v[l], || (sin_h[l], cos_h[l]));
                let d = draw_at(map, &o, wo, &point, (theta, (sin_p[l], cos_p[l])));
                wi_x[l] = d.wi.x;
                wi_y[l] = d.wi.y;
                wi_z[l] = d.wi.z;
                table[l] = d.table;
                shortcut[l] = d.shortcut;
            }
            for l in 0..n {
                oc[l] = match cosine_u[l] {
                    Some(u) => self.sample_cosine(&o, wo, u),
                    None => {
                        let wi = Vec3::new(wi_x[l], wi_y[l], wi_z[l]);
                        self.finish_draw(&o, wo, wi, shortcut[l].then_some(table[l]))
                    }
                };
            }
        }
    }

    /// [`BxdfSampler::pdf_batch`](acdf_core::BxdfSampler::pdf_batch)
    /// itself: the coordinates of a chunk of wi as one loop over the lanes,
    /// then each density's table lookups.
    #[inline(always)]
    pub(super) fn pdf_batch_one(&self, wo: Vec3, wi: &[Vec3], out: &mut [f32]) {
        if !is_valid_outgoing(wo) {
            out.iter_mut().zip(wi).for_each(|(o, _)| *o = 0.0);
            return;
        }
        let o = self.outgoing(wo);
        let map = self.map;
        let (mut x, mut v): (Lanes, Lanes) = ([0.0; CHUNK], [0.0; CHUNK]);
        let (mut sin_h, mut wo_h): (Lanes, Lanes) = ([0.0; CHUNK], [0.0; CHUNK]);
        let mut defined = [false; CHUNK];
        for (wc, oc) in wi.chunks(CHUNK).zip(out.chunks_mut(CHUNK)) {
            let n = wc.len().min(oc.len());
            for l in 0..n {
                let c = coordinates::<false>(map, &o, wo, wc[l]);
                x[l] = c.x;
                v[l] = c.v;
                sin_h[l] = c.sin_h;
                wo_h[l] = c.wo_h;
                defined[l] = c.defined;
            }
            for l in 0..n {
                let c = Coordinates {
                    x: x[l],
                    v: v[l],
                    sin_h: sin_h[l],
                    wo_h: wo_h[l],
                    defined: defined[l],
                };
                oc[l] = self.pdf_with(&o, wc[l], &c);
            }
        }
    }
}
