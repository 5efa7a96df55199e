//! CPU detection: the one place that asks the CPU what it runs.

/// Whether the CPU runs the AVX2 kernel: AVX2, BMI2 for its reference decoding, POPCNT and
/// BMI1 for its bit masks (every CPU with AVX2 the project knows of has all four).
#[cfg(target_arch = "x86_64")]
pub(super) fn avx2() -> bool {
    std::is_x86_feature_detected!("avx2")
        && std::is_x86_feature_detected!("bmi2")
        && std::is_x86_feature_detected!("popcnt")
        && std::is_x86_feature_detected!("bmi1")
}

#[cfg(not(target_arch = "x86_64"))]
pub(super) fn avx2() -> bool {
    false
}
