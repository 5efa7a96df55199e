//! The triangle-strip convention shared by Strip-RT output, the encoder, the decoder and the tracer.
//!
//! A strip is a sequence of vertex references `s`. Window `k` is `(s[k], s[k+1], s[k+2])`; its
//! triangle in input winding is `(s[k], s[k+1], s[k+2])` for even `k` and `(s[k+1], s[k], s[k+2])`
//! for odd `k`. A window with a repeated reference is a swap (paper 3.2: "ABA") and is no triangle.

/// Number of windows (real triangles and swaps) in a strip of `len` references.
pub fn window_count(len: usize) -> usize {
    len.saturating_sub(2)
}

/// The triangle of window `k` in input winding, or `None` for a swap window.
#[inline]
pub fn window_triangle<T: Copy + PartialEq>(strip: &[T], k: usize) -> Option<[T; 3]> {
    window_corners([strip[k], strip[k + 1], strip[k + 2]], k)
}

/// The triangle of window `k` whose references are `[s[k], s[k+1], s[k+2]]`, in input winding,
/// or `None` for a swap.
#[inline]
pub fn window_corners<T: Copy + PartialEq>([a, b, c]: [T; 3], k: usize) -> Option<[T; 3]> {
    if a == b || b == c || a == c {
        return None;
    }
    Some(if k.is_multiple_of(2) {
        [a, b, c]
    } else {
        [b, a, c]
    })
}

/// All real triangles of a strip, in strip order and input winding.
pub fn triangles<T: Copy + PartialEq>(strip: &[T]) -> impl Iterator<Item = [T; 3]> + '_ {
    (0..window_count(strip.len())).filter_map(move |k| window_triangle(strip, k))
}
