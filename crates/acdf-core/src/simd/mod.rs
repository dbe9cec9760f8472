//! The one module of acdf that holds SIMD intrinsics, inline assembly and
//! the choice of code by CPU; everything outside it is plain Rust.
//!
//! - [`cpu`] detects the features once and hands out the [`Avx2`] token
//!   that proves them;
//! - [`dispatch!`](crate::dispatch!) is the one way the rest of acdf runs
//!   code compiled for AVX2 and FMA: a caller passes its plain code as a
//!   closure that takes `Option<Avx2>`, and gets it compiled twice, once for the target's
//!   baseline (called with `None`) and once with AVX2 and FMA enabled
//!   (called with the token, where the CPU has them);
//! - [`search`], [`fast`] and the kernels below them are the vector forms of
//!   the searches, trigonometry and batch draws, behind safe functions
//!   that take the token.
//!
//! Every vector form computes the same IEEE operations in the same order as
//! the plain code it stands for, with no fused multiply-add, so results do
//! not depend on the path; the tests of each kernel, and the conformance
//! crate's `portable` tests, compare the two bit for bit.

pub mod cpu;
pub mod fast;
pub mod search;

pub use cpu::Avx2;

/// Runs an expression compiled with AVX2 and FMA enabled, when the CPU has
/// them and the portable path is not forced, and compiled for the target's
/// baseline otherwise: `dispatch!(|cpu| body)`, where `cpu` is an
/// `Option<Avx2>`, the token in the first case and `None` in the second.
///
/// This is the one way acdf chooses code by CPU. The body is inlined into
/// one of two instances, so the code it calls with `#[inline(always)]`
/// (the plain arithmetic of a draw, and the vector kernels it picks when
/// handed the token) is compiled for the features of the instance it runs
/// in. Both instances compute the same results; the choice only decides
/// the speed. (The macro marks the closure `#[inline(always)]`: a closure
/// left out of line would be compiled for the baseline, its vector kernels
/// with it, whichever instance called it.)
///
/// # Examples
///
/// ```
/// let sum = acdf_core::dispatch!(|cpu| {
///     // `cpu` is `Some` where AVX2 code may run; plain code runs either way.
///     let _ = cpu;
///     (1..=4).map(|k| k as f32).sum::<f32>()
/// });
/// assert_eq!(sum, 10.0);
/// ```
#[macro_export]
macro_rules! dispatch {
    (|$cpu:ident| $body:expr) => {
        $crate::simd::dispatch(
            #[inline(always)]
            |$cpu: ::core::option::Option<$crate::simd::Avx2>| $body,
        )
    };
}

/// The function behind [`dispatch!`](crate::dispatch!), which calls it with
/// an `#[inline(always)]` closure; call the macro, not this.
#[doc(hidden)]
#[inline(always)]
pub fn dispatch<R>(kernel: impl FnOnce(Option<Avx2>) -> R) -> R {
    #[cfg(target_arch = "x86_64")]
    if let Some(cpu) = cpu::avx2() {
        return with_avx2(cpu, kernel);
    }
    portable(kernel)
}

/// `kernel(Some(cpu))` compiled for AVX2, FMA and POPCNT.
#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn with_avx2<R>(cpu: Avx2, kernel: impl FnOnce(Option<Avx2>) -> R) -> R {
    #[target_feature(enable = "avx2,fma,popcnt")]
    fn compiled<R>(cpu: Avx2, kernel: impl FnOnce(Option<Avx2>) -> R) -> R {
        kernel(Some(cpu))
    }
    // SAFETY: the token proves the CPU has AVX2 and FMA, the features
    // `compiled` is built for (detection requires POPCNT beside them).
    unsafe { compiled(cpu, kernel) }
}

/// `kernel(None)`, out of line so that the caller's fast path stays small.
#[inline(never)]
fn portable<R>(kernel: impl FnOnce(Option<Avx2>) -> R) -> R {
    kernel(None)
}
