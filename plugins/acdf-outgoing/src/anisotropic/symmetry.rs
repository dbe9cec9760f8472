//! The mirror symmetries of an anisotropic material, found on its fine
//! tables, that let the sampler keep slices for part of the φ_o circle
//! only.
//!
//! A material with f(M wo, M wi) = f(wo, wi) for a transform M of the
//! tangent plane has, at M wo, the table of wo carried over by M, so the
//! slices of one arc of φ_o serve the whole circle: a wo outside the arc
//! is taken into it by M (flipping the signs of its x and y), drawn from
//! there and the draw flipped back; the density at (wo, wi) is the arc's
//! at (M wo, M wi). Every transform used here flips signs of x and y, so
//! it is its own inverse and exact in floating point. The three kept:
//!
//! - [`Symmetry::MirrorXY`]: mirrors across both axes (y → −y and
//!   x → −x), as an anisotropic density of normals aligned with the axes
//!   has. The arc φ_o ∈ [0, π/2], a quarter of the circle.
//! - [`Symmetry::MirrorY`]: y → −y alone. The arc [0, π].
//! - [`Symmetry::HalfTurn`]: the turn by π, (x, y) → (−x, −y), as any
//!   density of normals symmetric through the normal has whatever its
//!   axes. The arc [0, π].
//!
//! An arc is closed: its end is a φ_o breakpoint of every row (but a row
//! whose slices are all one, on the normal, keeps one) and slices are
//! blended within it, with no seam. The full circle ([`Symmetry::None`])
//! is periodic, as before.

use super::PhiFrame;
use crate::blend_divergence;
use acdf_core::Vec3;
use rayon::prelude::*;

/// Which part of the φ_o circle the slices cover (module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Symmetry {
    /// No symmetry used: the whole circle, periodic.
    None,
    /// The turn by π: φ_o in [0, π].
    HalfTurn,
    /// The mirror y → −y: φ_o in [0, π].
    MirrorY,
    /// The mirrors y → −y and x → −x: φ_o in [0, π/2].
    MirrorXY,
}

impl Symmetry {
    /// The symmetry's code in a sampler file.
    pub fn code(self) -> u8 {
        match self {
            Symmetry::None => 0,
            Symmetry::HalfTurn => 1,
            Symmetry::MirrorY => 2,
            Symmetry::MirrorXY => 3,
        }
    }

    /// The symmetry of a file code.
    pub fn from_code(code: u8) -> Option<Self> {
        [
            Symmetry::None,
            Symmetry::HalfTurn,
            Symmetry::MirrorY,
            Symmetry::MirrorXY,
        ]
        .into_iter()
        .find(|s| s.code() == code)
    }

    /// The arc of φ_o the slices cover, in turns: 1 (the periodic circle),
    /// 1/2 or 1/4.
    pub fn span(self) -> f32 {
        match self {
            Symmetry::None => 1.0,
            Symmetry::HalfTurn | Symmetry::MirrorY => 0.5,
            Symmetry::MirrorXY => 0.25,
        }
    }

    /// Whether the arc is the whole, periodic circle.
    pub fn is_periodic(self) -> bool {
        self == Symmetry::None
    }

    /// The signs (s_x, s_y) that take `wo` into the arc: (s_x wo.x,
    /// s_y wo.y, wo.z) has φ_o in [0, 2π span].
    #[inline]
    pub fn signs(self, wo: Vec3) -> (f32, f32) {
        let neg = |c: f32| if c < 0.0 { -1.0 } else { 1.0 };
        match self {
            Symmetry::None => (1.0, 1.0),
            Symmetry::HalfTurn => {
                let s = neg(wo.y);
                (s, s)
            }
            Symmetry::MirrorY => (1.0, neg(wo.y)),
            Symmetry::MirrorXY => (neg(wo.x), neg(wo.y)),
        }
    }

    /// The fine φ_o node indices of the arc, in order, for `fine_phi`
    /// nodes round the circle: all of them for the periodic circle, else
    /// 0 to the node at the arc's end, both included.
    pub(crate) fn arc_nodes(self, fine_phi: usize) -> Vec<usize> {
        if self.is_periodic() {
            (0..fine_phi).collect()
        } else {
            (0..=(fine_phi as f32 * self.span()) as usize).collect()
        }
    }

    /// Whether `fine_phi` nodes round the circle and `n_phi_h` φ_h columns
    /// carry the symmetry node to node and column to column.
    pub(crate) fn fits_grid(self, fine_phi: usize, n_phi_h: usize) -> bool {
        let quarter = fine_phi.is_multiple_of(4);
        let half = fine_phi.is_multiple_of(2) && n_phi_h.is_multiple_of(2);
        match self {
            Symmetry::None => true,
            Symmetry::HalfTurn | Symmetry::MirrorY => half,
            Symmetry::MirrorXY => half && quarter,
        }
    }
}

/// One mirror or turn acting on the fine tables: the partner of φ_o node
/// l, and the column of a table that column c of its partner's table
/// becomes.
#[derive(Clone, Copy)]
enum Transform {
    /// y → −y.
    MirrorY,
    /// x → −x.
    MirrorX,
    /// (x, y) → (−x, −y).
    HalfTurn,
}

impl Transform {
    fn node(self, l: usize, fine_phi: usize) -> usize {
        match self {
            Transform::MirrorY => (fine_phi - l) % fine_phi,
            Transform::MirrorX => (fine_phi + fine_phi / 2 - l) % fine_phi,
            Transform::HalfTurn => (l + fine_phi / 2) % fine_phi,
        }
    }

    /// Column c of a table in `frame` at the partner node, carried over:
    /// φ_h → −φ_h (mirror y), π − φ_h (mirror x) or φ_h + π (turn) for
    /// absolute φ_h; from φ_o, a mirror reverses φ_h − φ_o and the turn
    /// keeps it.
    fn column(self, c: usize, n: usize, frame: PhiFrame) -> usize {
        match (self, frame) {
            (Transform::HalfTurn, PhiFrame::Relative) => c,
            (Transform::HalfTurn, PhiFrame::Absolute) => (c + n / 2) % n,
            (Transform::MirrorX, PhiFrame::Absolute) => (n + n / 2 - 1 - c) % n,
            (_, _) => n - 1 - c,
        }
    }

    /// Whether every fine table (θ_o node j, φ_o node l at index
    /// j · fine_phi + l, normalised, `n_phi_h` columns) is reproduced
    /// within `budget` of chi-square divergence by its partner's table
    /// carried over.
    fn holds(
        self,
        p: &[Vec<f32>],
        fine_phi: usize,
        n_phi_h: usize,
        frame: PhiFrame,
        budget: f64,
    ) -> bool {
        (0..p.len()).into_par_iter().all(|i| {
            let (j, l) = (i / fine_phi, i % fine_phi);
            let partner = &p[j * fine_phi + self.node(l, fine_phi)];
            let carried: Vec<f32> = (0..partner.len())
                .map(|k| {
                    let (row, c) = (k / n_phi_h, k % n_phi_h);
                    partner[row * n_phi_h + self.column(c, n_phi_h, frame)]
                })
                .collect();
            blend_divergence(&p[i], &carried, &carried, 0.0) <= budget
        })
    }
}

/// The largest symmetry the normalised fine tables `p` (θ_o node j, φ_o
/// node l at index j · fine_phi + l, in `frame`) have within `budget`: both
/// mirrors, then the mirror y → −y, then the turn by π, else none.
pub(crate) fn detect(
    p: &[Vec<f32>],
    fine_phi: usize,
    n_phi_h: usize,
    frame: PhiFrame,
    budget: f64,
) -> Symmetry {
    let holds = |t: Transform| t.holds(p, fine_phi, n_phi_h, frame, budget);
    let fits = |s: Symmetry| s.fits_grid(fine_phi, n_phi_h);
    let mirror_y = fits(Symmetry::MirrorY) && holds(Transform::MirrorY);
    if mirror_y && fits(Symmetry::MirrorXY) && holds(Transform::MirrorX) {
        Symmetry::MirrorXY
    } else if mirror_y {
        Symmetry::MirrorY
    } else if fits(Symmetry::HalfTurn) && holds(Transform::HalfTurn) {
        Symmetry::HalfTurn
    } else {
        Symmetry::None
    }
}
