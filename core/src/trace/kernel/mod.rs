//! Which SIMD kernel the tracer runs, chosen at run time.
//!
//! One portable binary: the baseline kernel is what every x86-64 CPU runs (SSE2, through
//! `wide`), and on a CPU that reports AVX2 (and BMI2, whose `pdep` unpacks a block's packed
//! references) the strip blocks run as 256-bit operations ([`super::avx2`]). `wide` picks its instructions when the crate is compiled, so it
//! stays SSE2 inside a function compiled for AVX2; the AVX2 kernel therefore uses `std::arch`
//! itself. Every kernel runs the same IEEE operations in the same order per lane (no fused
//! multiply-add), so hits and occlusion answers are bit-identical whichever runs.
//!
//! `REDUCEM_KERNEL=sse2|avx2` forces a kernel (tests and benchmarks); asking for one this CPU
//! lacks is an error rather than a silent fallback, so a benchmark never reports a kernel it did
//! not run. No AVX-512 kernel: the strip block is eight windows wide, which AVX2 covers in one
//! register, and a 16-lane block would change the strip kd-tree's leaf size and the file. Nor
//! do sixteen-ray packets pay at the top level: closest-hit packets of sixteen camera rays (two
//! rows of an 8×8 tile), each child box clipped for all of them in one 512-bit operation and
//! split into two eight-ray halves at the leaves, took 142.2 ms of CPU against 136.8 for
//! eight-ray packets (`reducem query`, 1M camera rays of the 1M scan, 1 thread, `perf stat`
//! task-clock, medians of 9 alternating runs): the walk's time did not shrink, as the rows part
//! near the leaves, where most node visits are.

use std::fmt;

/// A tracer kernel.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Kernel {
    /// 128-bit SSE2 (or `wide`'s scalar fallback off x86-64): runs everywhere.
    Sse2,
    /// 256-bit AVX2 strip blocks with gathered vertices.
    Avx2,
}

/// The environment variable that forces a kernel.
pub const KERNEL_VARIABLE: &str = "REDUCEM_KERNEL";

impl Kernel {
    /// Every kernel, baseline first.
    pub const ALL: [Kernel; 2] = [Kernel::Sse2, Kernel::Avx2];

    /// The fastest kernel this CPU runs.
    pub fn detect() -> Kernel {
        if Kernel::Avx2.is_supported() {
            Kernel::Avx2
        } else {
            Kernel::Sse2
        }
    }

    /// [`Kernel::detect`], unless `REDUCEM_KERNEL` names one: then that one, or an error when
    /// the name is unknown or this CPU cannot run it.
    pub fn from_env() -> Result<Kernel, KernelError> {
        match std::env::var(KERNEL_VARIABLE) {
            Ok(name) => Kernel::by_name(&name),
            Err(_) => Ok(Kernel::detect()),
        }
    }

    /// The kernel called `name` (`sse2`, `avx2`), if this CPU runs it.
    pub fn by_name(name: &str) -> Result<Kernel, KernelError> {
        let kernel = Kernel::ALL
            .into_iter()
            .find(|kernel| kernel.name() == name)
            .ok_or_else(|| KernelError::Unknown(name.to_string()))?;
        if kernel.is_supported() {
            Ok(kernel)
        } else {
            Err(KernelError::Unsupported(kernel))
        }
    }

    /// The kernels this CPU runs, baseline first.
    pub fn supported() -> Vec<Kernel> {
        Kernel::ALL
            .into_iter()
            .filter(|kernel| kernel.is_supported())
            .collect()
    }

    pub fn is_supported(self) -> bool {
        match self {
            Kernel::Sse2 => true,
            Kernel::Avx2 => avx2_detected(),
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Kernel::Sse2 => "sse2",
            Kernel::Avx2 => "avx2",
        }
    }
}

impl fmt::Display for Kernel {
    fn fmt(&self, f: &mut fmt::Formatter) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// Whether the CPU runs the AVX2 kernel: AVX2, and BMI2 for its reference decoding (every
/// CPU with AVX2 the project knows of has both).
#[cfg(target_arch = "x86_64")]
pub(super) fn avx2_detected() -> bool {
    std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("bmi2")
}

#[cfg(not(target_arch = "x86_64"))]
pub(super) fn avx2_detected() -> bool {
    false
}

/// Why a forced kernel cannot run.
#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum KernelError {
    #[error("{KERNEL_VARIABLE}={0}: unknown kernel (expected sse2 or avx2)")]
    Unknown(String),
    #[error("{KERNEL_VARIABLE}={0}: this CPU does not support it")]
    Unsupported(Kernel),
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_unknown_names_are_refused() {
        for kernel in Kernel::supported() {
            assert_eq!(Kernel::by_name(kernel.name()), Ok(kernel));
        }
        assert_eq!(
            Kernel::by_name("avx9"),
            Err(KernelError::Unknown("avx9".into()))
        );
        assert!(Kernel::supported().contains(&Kernel::detect()));
        assert_eq!(Kernel::supported()[0], Kernel::Sse2);
    }
}
