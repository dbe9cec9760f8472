//! The CPU features the hot paths choose their code by, detected once.
//!
//! Two choices are made at run time, everywhere through this module:
//! - **AVX2 and FMA** ([`avx2`], which also requires POPCNT, present on
//!   every CPU with AVX2): the batch searches in SIMD lanes
//!   ([`search::lanes`](crate::search::lanes)), the distributions' batch
//!   paths built on them, the many-angle sines and cosines of
//!   [`fast`](crate::fast), and the tabulated samplers' copies of `sample`
//!   and `pdf` compiled for AVX2. Without them the portable code runs.
//! - **AVX-512 F, VL and BW** ([`mask_compares`]): the window compare of
//!   [`search`](crate::search) into mask registers; without them, SSE2
//!   compares (the x86-64 baseline).
//!
//! Every path gives the same results bit for bit; the choice only decides
//! the speed. Detection runs on the first query; after that each query is
//! one relaxed load of a cached flag and a branch that always goes the same
//! way, cheap enough for every draw of a one-at-a-time `sample`.
//!
//! [`avx2`] answers with a token, [`Avx2`], rather than a `bool`: the only
//! way to obtain one is a detection that found the features, so a function
//! that takes it needs no `unsafe` contract for them.
//!
//! # Forcing the portable path
//!
//! - The environment variable `ACDF_CPU=portable`, read once, at the first
//!   query, makes the whole process run the portable code (as a CPU
//!   without AVX2, FMA and AVX-512 would). Any other value, or none, leaves
//!   detection alone.
//! - [`lock_paths`] gives a test (or a tool) exclusive control of the
//!   choice: [`PathLock::force_portable`] switches between the portable and
//!   the detected paths, and dropping the lock restores detection.
//!
//! Forcing can only turn features off, never on, so a token handed out
//! before a switch stays true to the CPU.
//!
//! **Tests in parallel threads.** The choice is process-global: flipping it
//! in one test changes the path that every thread takes while it is
//! flipped. That never changes a result (all paths agree bit for bit), but
//! a test comparing the two paths must know which one ran. So the switch
//! is only reachable through [`PathLock`], which holds a process-wide
//! mutex: comparisons that take it run one after another, each sure of its
//! own path; and the comparison tests live in a test binary of their own
//! (`tests/tests/portable.rs` of the conformance crate), so that while one
//! of them forces the portable path no other test in the process is
//! quietly moved off the vectorised one. A thread-local switch would avoid
//! the lock but cost a thread-local read on every query.

use std::sync::atomic::{AtomicU8, Ordering};
use std::sync::{Mutex, MutexGuard, OnceLock};

/// Proof that the CPU has AVX2, FMA and POPCNT and that the vectorised
/// paths are chosen: obtained only from [`avx2`]. It has no size and costs nothing
/// to pass.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Avx2 {
    _detected: (),
}

/// The features the hot paths use, as detected (and possibly forced off).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Features {
    /// AVX2, FMA and POPCNT: the lanes and the samplers' AVX2 copies.
    pub avx2_fma: bool,
    /// AVX-512 F, VL and BW: the window compares into mask registers.
    pub mask_compares: bool,
}

impl Features {
    /// No optional feature: the portable paths.
    pub const PORTABLE: Features = Features {
        avx2_fma: false,
        mask_compares: false,
    };
}

/// A cached flag: not yet detected, absent, present.
const UNKNOWN: u8 = 0;
const ABSENT: u8 = 1;
const PRESENT: u8 = 2;

static AVX2_FMA: AtomicU8 = AtomicU8::new(UNKNOWN);
static MASK_COMPARES: AtomicU8 = AtomicU8::new(UNKNOWN);

/// What detection found, after `ACDF_CPU`.
static DETECTED: OnceLock<Features> = OnceLock::new();

/// The environment variable that forces the portable path.
pub const ENV_VAR: &str = "ACDF_CPU";

/// An [`Avx2`] token when the CPU has AVX2, FMA and POPCNT and the
/// portable path is not forced; `None` otherwise.
#[inline(always)]
pub fn avx2() -> Option<Avx2> {
    let present = match AVX2_FMA.load(Ordering::Relaxed) {
        PRESENT => true,
        ABSENT => false,
        _ => detect().avx2_fma,
    };
    present.then_some(Avx2 { _detected: () })
}

/// Whether the CPU has AVX-512 F, VL and BW and the portable path is not
/// forced.
#[inline(always)]
pub fn mask_compares() -> bool {
    match MASK_COMPARES.load(Ordering::Relaxed) {
        PRESENT => true,
        ABSENT => false,
        _ => detect().mask_compares,
    }
}

/// The features the hot paths use now (detected, unless forced off).
pub fn features() -> Features {
    Features {
        avx2_fma: avx2().is_some(),
        mask_compares: mask_compares(),
    }
}

/// What the CPU has, whatever is forced: detection, then `ACDF_CPU`.
pub fn detected() -> Features {
    *DETECTED.get_or_init(|| {
        if std::env::var(ENV_VAR).is_ok_and(|v| v.trim().eq_ignore_ascii_case("portable")) {
            return Features::PORTABLE;
        }
        detect_cpu()
    })
}

#[cfg(target_arch = "x86_64")]
fn detect_cpu() -> Features {
    use std::arch::is_x86_feature_detected;
    Features {
        avx2_fma: is_x86_feature_detected!("avx2")
            && is_x86_feature_detected!("fma")
            && is_x86_feature_detected!("popcnt"),
        mask_compares: is_x86_feature_detected!("avx512f")
            && is_x86_feature_detected!("avx512vl")
            && is_x86_feature_detected!("avx512bw"),
    }
}

#[cfg(not(target_arch = "x86_64"))]
fn detect_cpu() -> Features {
    Features::PORTABLE
}

/// The first query: detect, cache, answer. Out of line, so that the
/// queries inline as a load and a branch.
#[cold]
#[inline(never)]
fn detect() -> Features {
    let features = detected();
    publish(features);
    features
}

/// Make `features` the answer of every query.
fn publish(features: Features) {
    let flag = |present: bool| if present { PRESENT } else { ABSENT };
    AVX2_FMA.store(flag(features.avx2_fma), Ordering::Relaxed);
    MASK_COMPARES.store(flag(features.mask_compares), Ordering::Relaxed);
}

/// Exclusive control of the path choice (see the module documentation):
/// while it lives no other [`PathLock`] exists in the process. Dropping it
/// restores the detected paths.
pub struct PathLock {
    _exclusive: MutexGuard<'static, ()>,
}

/// Wait for, then take, exclusive control of the path choice.
pub fn lock_paths() -> PathLock {
    static EXCLUSIVE: Mutex<()> = Mutex::new(());
    // A test that panicked while holding the lock has restored detection
    // on the way out (`Drop`), so its poison carries no broken state.
    let guard = EXCLUSIVE.lock().unwrap_or_else(|e| e.into_inner());
    PathLock { _exclusive: guard }
}

impl PathLock {
    /// Run the portable paths (`true`) or the detected ones (`false`) from
    /// now on, in every thread.
    pub fn force_portable(&self, portable: bool) {
        publish(if portable {
            Features::PORTABLE
        } else {
            detected()
        });
    }

    /// `f` on the portable paths, then the detected ones are restored.
    pub fn portable<T>(&self, f: impl FnOnce() -> T) -> T {
        self.force_portable(true);
        let result = f();
        self.force_portable(false);
        result
    }
}

impl Drop for PathLock {
    fn drop(&mut self) {
        self.force_portable(false);
    }
}
