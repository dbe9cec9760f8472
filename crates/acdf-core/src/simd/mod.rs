//! The one module of acdf that holds SIMD intrinsics, inline assembly and
//! the choice of code by CPU; everything outside it is plain Rust.
//!
//! - [`cpu`] detects the features once and hands out the [`Avx2`] token
//!   that proves them;
//! - [`dispatch!`](crate::dispatch!) is the one way the rest of acdf runs
//!   code compiled for AVX2 and FMA: a caller names a plain function that
//!   takes an `Option<Avx2>` last, and gets it compiled twice, once for the
//!   target's baseline (called with `None`) and once with AVX2 and FMA
//!   enabled (called with the token, where the CPU has them);
//! - [`search`] and [`fast`] are the vector forms of the sorted-list
//!   searches and of the many-angle sines and cosines;
//! - the batch kernels of the samplers, behind safe functions that take
//!   the token and plain views of the stored arrays:
//!   [`shared_grid`] (the outgoing sampler's quantised slices);
//!   [`piecewise_constant`] (the uniform plug-in's piecewise-constant
//!   tables); [`adaptive_cdf`] (the adaptive distributions of
//!   `acdf-adaptive-cdf`);
//! - [`clock`] reads the core clock for `acdf bench`.
//!
//! Every vector form computes the same IEEE operations in the same order as
//! the plain code it stands for, with no fused multiply-add, so results do
//! not depend on the path; the tests of each kernel, and the conformance
//! crate's `portable` tests, compare the two bit for bit.

pub mod adaptive_cdf;
pub mod clock;
pub mod cpu;
pub mod fast;
pub mod piecewise_constant;
pub mod search;
#[cfg(target_arch = "x86_64")]
pub mod shared_grid;

pub use cpu::Avx2;

/// Runs code compiled with AVX2, FMA and POPCNT enabled, when the CPU has
/// them and the portable path is not forced, and compiled for the target's
/// baseline otherwise. The code is handed an `Option<Avx2>`, its last
/// argument: the token in the first case, `None` in the second.
///
/// This is the one way acdf chooses code by CPU. The code is inlined into
/// one of two instances, so what it calls with `#[inline(always)]` (the
/// plain arithmetic of a draw, and the vector kernels it picks when handed
/// the token) is compiled for the features of the instance it runs in.
/// Both instances compute the same results; the choice only decides the
/// speed.
///
/// `dispatch!(f, a, b, ...)` calls `f(a, b, ..., cpu)` (up to six
/// arguments before `cpu`), a method as `dispatch!(Self::sample_one, self,
/// wo, u)`. The arguments are passed as parameters of the compiled
/// instances, not captured: in a closure's environment the compiler no
/// longer knows that a `&mut` slice aliases nothing else, leaves loops over
/// it scalar, and reads small values such as a direction back from memory.
///
/// # Examples
///
/// ```
/// use acdf_core::simd::Avx2;
///
/// /// Plain code, compiled once per instance; `cpu` is `Some` where AVX2
/// /// code may run, for a kernel that has a vector form.
/// #[inline(always)]
/// fn scale(by: f32, v: &mut [f32], cpu: Option<Avx2>) {
///     let _ = cpu;
///     v.iter_mut().for_each(|x| *x *= by);
/// }
///
/// let mut v = [1.0, 2.0];
/// acdf_core::dispatch!(scale, 3.0, &mut v);
/// assert_eq!(v, [3.0, 6.0]);
/// ```
#[macro_export]
macro_rules! dispatch {
    ($f:expr $(,)?) => {
        $crate::simd::dispatch(
            #[inline(always)]
            |cpu| $f(cpu),
        )
    };
    ($f:expr, $a:expr $(,)?) => {
        $crate::simd::dispatch1(
            #[inline(always)]
            |a, cpu| $f(a, cpu),
            $a,
        )
    };
    ($f:expr, $a:expr, $b:expr $(,)?) => {
        $crate::simd::dispatch2(
            #[inline(always)]
            |a, b, cpu| $f(a, b, cpu),
            $a,
            $b,
        )
    };
    ($f:expr, $a:expr, $b:expr, $c:expr $(,)?) => {
        $crate::simd::dispatch3(
            #[inline(always)]
            |a, b, c, cpu| $f(a, b, c, cpu),
            $a,
            $b,
            $c,
        )
    };
    ($f:expr, $a:expr, $b:expr, $c:expr, $d:expr $(,)?) => {
        $crate::simd::dispatch4(
            #[inline(always)]
            |a, b, c, d, cpu| $f(a, b, c, d, cpu),
            $a,
            $b,
            $c,
            $d,
        )
    };
    ($f:expr, $a:expr, $b:expr, $c:expr, $d:expr, $e:expr $(,)?) => {
        $crate::simd::dispatch5(
            #[inline(always)]
            |a, b, c, d, e, cpu| $f(a, b, c, d, e, cpu),
            $a,
            $b,
            $c,
            $d,
            $e,
        )
    };
    ($f:expr, $a:expr, $b:expr, $c:expr, $d:expr, $e:expr, $g:expr $(,)?) => {
        $crate::simd::dispatch6(
            #[inline(always)]
            |a, b, c, d, e, g, cpu| $f(a, b, c, d, e, g, cpu),
            $a,
            $b,
            $c,
            $d,
            $e,
            $g,
        )
    };
}

/// The two instances behind one spelling of [`dispatch!`](crate::dispatch!):
/// a function taking the listed arguments and the CPU choice, a compiled
/// copy of it for AVX2 and one out of line for the baseline.
macro_rules! instances {
    ($name:ident, $($arg:ident: $ty:ident),*) => {
        #[doc(hidden)]
        #[allow(clippy::too_many_arguments)]
        #[inline(always)]
        pub fn $name<$($ty,)* R>(
            kernel: impl FnOnce($($ty,)* Option<Avx2>) -> R,
            $($arg: $ty),*
        ) -> R {
            #[cfg(target_arch = "x86_64")]
            if let Some(cpu) = cpu::avx2() {
                #[allow(clippy::too_many_arguments)]
                #[target_feature(enable = "avx2,fma,popcnt")]
                fn compiled<$($ty,)* R>(
                    cpu: Avx2,
                    kernel: impl FnOnce($($ty,)* Option<Avx2>) -> R,
                    $($arg: $ty),*
                ) -> R {
                    kernel($($arg,)* Some(cpu))
                }
                // SAFETY: the token proves the CPU has AVX2 and FMA, the
                // features `compiled` is built for (detection requires
                // POPCNT beside them).
                return unsafe { compiled(cpu, kernel, $($arg),*) };
            }
            #[allow(clippy::too_many_arguments)]
            #[inline(never)]
            fn portable<$($ty,)* R>(
                kernel: impl FnOnce($($ty,)* Option<Avx2>) -> R,
                $($arg: $ty),*
            ) -> R {
                kernel($($arg,)* None)
            }
            portable(kernel, $($arg),*)
        }
    };
}

instances!(dispatch,);
instances!(dispatch1, a: A);
instances!(dispatch2, a: A, b: B);
instances!(dispatch3, a: A, b: B, c: C);
instances!(dispatch4, a: A, b: B, c: C, d: D);
instances!(dispatch5, a: A, b: B, c: C, d: D, e: E);
instances!(dispatch6, a: A, b: B, c: C, d: D, e: E, g: G);
