//! The core clock, read from a chain of dependent integer additions, for
//! `acdf bench` to turn times into cycles.

use std::time::Instant;

/// The core clock in GHz: additions per second in a chain where each
/// waits for the one before, which takes one cycle per addition on x86-64
/// cores; the best of five runs of 10^8. `None` off x86-64.
///
/// The addend is a register, not an immediate: cores that fold chains of
/// immediate additions at register renaming would otherwise retire several
/// per cycle, and the reading would be a multiple of the clock.
#[cfg(target_arch = "x86_64")]
pub fn clock_ghz() -> Option<f64> {
    const ADDITIONS: u64 = 100_000_000;
    let seconds = (0..5)
        .map(|_| {
            let start = Instant::now();
            let mut x = 0u64;
            let one = std::hint::black_box(1u64);
            for _ in 0..ADDITIONS / 4 {
                // SAFETY: four additions of one register to another; no
                // memory, no stack.
                unsafe {
                    std::arch::asm!(
                        "add {x}, {one}",
                        "add {x}, {one}",
                        "add {x}, {one}",
                        "add {x}, {one}",
                        x = inout(reg) x,
                        one = in(reg) one,
                        options(nomem, nostack),
                    );
                }
            }
            std::hint::black_box(x);
            start.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
        .max(1e-9);
    Some(ADDITIONS as f64 / seconds / 1e9)
}

/// The core clock is not estimated off x86-64.
#[cfg(not(target_arch = "x86_64"))]
pub fn clock_ghz() -> Option<f64> {
    None
}
