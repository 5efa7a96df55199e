//! Per-vertex and per-triangle attributes a file may carry besides positions (format 2.5): the
//! input face id of every stored triangle, per-vertex normals in an octahedral encoding and
//! per-vertex RGBA8 colours.
//!
//! The octahedral encoding follows Meyer et al., "On Floating-Point Normal Vectors" (EGSR 2010)
//! and Cigolle et al., "A Survey of Efficient Representations for Independent Unit Vectors"
//! (JCGT 2014): a unit vector is projected onto the octahedron `|x| + |y| + |z| = 1`, whose
//! lower half is folded over the upper one, and the two remaining coordinates in `[-1, 1]` are
//! stored as signed fixed-point numbers. Encoding picks, among the four grid points around the
//! projection, the one whose decoded vector is closest to the input (the survey's "precise"
//! variant), which halves the worst error of plain rounding.

/// How per-vertex normals are stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum NormalEncoding {
    /// No normals.
    #[default]
    None = 0,
    /// Two signed 8-bit octahedral coordinates: 2 bytes per stored vertex, within 0.64° (worst of 20,000 random directions).
    Oct8 = 1,
    /// Two signed 16-bit octahedral coordinates: 4 bytes per stored vertex, within 0.0073° (worst of 20,000 random directions).
    Oct16 = 2,
}

impl NormalEncoding {
    pub fn from_u32(value: u32) -> Option<NormalEncoding> {
        match value {
            0 => Some(NormalEncoding::None),
            1 => Some(NormalEncoding::Oct8),
            2 => Some(NormalEncoding::Oct16),
            _ => None,
        }
    }

    /// The name configs and `inspect` use: `none`, `oct8` or `oct16`.
    pub fn name(self) -> &'static str {
        match self {
            NormalEncoding::None => "none",
            NormalEncoding::Oct8 => "oct8",
            NormalEncoding::Oct16 => "oct16",
        }
    }

    pub fn from_name(name: &str) -> Option<NormalEncoding> {
        [
            NormalEncoding::None,
            NormalEncoding::Oct8,
            NormalEncoding::Oct16,
        ]
        .into_iter()
        .find(|e| e.name() == name)
    }

    /// Bytes per stored vertex.
    pub fn bytes(self) -> usize {
        match self {
            NormalEncoding::None => 0,
            NormalEncoding::Oct8 => 2,
            NormalEncoding::Oct16 => 4,
        }
    }

    /// Largest fixed-point value of one coordinate (the value of 1.0).
    fn scale(self) -> f32 {
        match self {
            NormalEncoding::None => 0.0,
            NormalEncoding::Oct8 => 127.0,
            NormalEncoding::Oct16 => 32767.0,
        }
    }
}

/// A stored normal: two octahedral coordinates in fixed point, each within
/// `-scale ..= scale` of its [`NormalEncoding`].
pub type OctCode = [i16; 2];

/// The octahedral code of `normal` (any length; a zero or non-finite vector is stored as
/// `+z`), chosen among the four neighbouring codes as the one that decodes closest to it.
pub fn encode_normal(normal: [f32; 3], encoding: NormalEncoding) -> OctCode {
    let scale = encoding.scale();
    let length = normal.iter().map(|c| c * c).sum::<f32>().sqrt();
    if !(length.is_finite() && length > 0.0) || scale == 0.0 {
        return [0, 0];
    }
    let unit = normal.map(|c| c / length);
    let [x, y] = fold(unit);
    let floor = [(x * scale).floor(), (y * scale).floor()];
    let mut best = ([0i16; 2], f32::NEG_INFINITY);
    for (dx, dy) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0)] {
        let code = [floor[0] + dx, floor[1] + dy].map(|c| c.clamp(-scale, scale) as i16);
        let decoded = decode_normal(code, encoding);
        let cosine: f32 = (0..3).map(|a| decoded[a] * unit[a]).sum();
        if cosine > best.1 {
            best = (code, cosine);
        }
    }
    best.0
}

/// The unit vector `code` stands for.
pub fn decode_normal(code: OctCode, encoding: NormalEncoding) -> [f32; 3] {
    let scale = encoding.scale().max(1.0);
    let (x, y) = (
        (code[0] as f32 / scale).clamp(-1.0, 1.0),
        (code[1] as f32 / scale).clamp(-1.0, 1.0),
    );
    let z = 1.0 - x.abs() - y.abs();
    let (x, y) = if z < 0.0 {
        ((1.0 - y.abs()).copysign(x), (1.0 - x.abs()).copysign(y))
    } else {
        (x, y)
    };
    let length = (x * x + y * y + z * z).sqrt();
    [x / length, y / length, z / length]
}

/// The upper-half octahedral coordinates of a unit vector.
fn fold([x, y, z]: [f32; 3]) -> [f32; 2] {
    let l1 = x.abs() + y.abs() + z.abs();
    let (px, py) = (x / l1, y / l1);
    if z >= 0.0 {
        [px, py]
    } else {
        [(1.0 - py.abs()).copysign(px), (1.0 - px.abs()).copysign(py)]
    }
}

/// Appends the little-endian bytes of `code` ([`NormalEncoding::bytes`] of them).
pub fn push_normal(code: OctCode, encoding: NormalEncoding, out: &mut Vec<u8>) {
    match encoding {
        NormalEncoding::None => {}
        NormalEncoding::Oct8 => out.extend(code.map(|c| c as i8 as u8)),
        NormalEncoding::Oct16 => code.iter().for_each(|c| out.extend(c.to_le_bytes())),
    }
}

/// The code stored at the start of `bytes` (at least [`NormalEncoding::bytes`] long).
pub fn read_normal(bytes: &[u8], encoding: NormalEncoding) -> OctCode {
    match encoding {
        NormalEncoding::None => [0, 0],
        NormalEncoding::Oct8 => [bytes[0] as i8 as i16, bytes[1] as i8 as i16],
        NormalEncoding::Oct16 => [
            i16::from_le_bytes([bytes[0], bytes[1]]),
            i16::from_le_bytes([bytes[2], bytes[3]]),
        ],
    }
}

/// The angle between two unit vectors, in degrees.
pub fn angle_degrees(a: [f32; 3], b: [f32; 3]) -> f64 {
    let dot: f64 = (0..3).map(|i| a[i] as f64 * b[i] as f64).sum();
    let cross = [
        a[1] as f64 * b[2] as f64 - a[2] as f64 * b[1] as f64,
        a[2] as f64 * b[0] as f64 - a[0] as f64 * b[2] as f64,
        a[0] as f64 * b[1] as f64 - a[1] as f64 * b[0] as f64,
    ];
    let sine = cross.iter().map(|c| c * c).sum::<f64>().sqrt();
    sine.atan2(dot).to_degrees()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn unit(seed: u64) -> [f32; 3] {
        let mut state = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f32 / (1u64 << 53) as f32 * 2.0 - 1.0
        };
        let v = [next(), next(), next()];
        let length = v.iter().map(|c| c * c).sum::<f32>().sqrt();
        v.map(|c| c / length)
    }

    fn worst_error(encoding: NormalEncoding) -> f64 {
        (1..20_000u64)
            .map(unit)
            .chain([[0.0, 0.0, -1.0], [1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])
            .map(|n| angle_degrees(n, decode_normal(encode_normal(n, encoding), encoding)))
            .fold(0.0, f64::max)
    }

    #[test]
    fn oct16_is_within_a_hundredth_of_a_degree() {
        let worst = worst_error(NormalEncoding::Oct16);
        assert!(worst < 0.01, "{worst}");
    }

    #[test]
    fn oct8_is_within_a_degree() {
        let worst = worst_error(NormalEncoding::Oct8);
        assert!(worst < 1.0, "{worst}");
    }

    #[test]
    fn codes_round_trip_through_bytes() {
        for encoding in [NormalEncoding::Oct8, NormalEncoding::Oct16] {
            for seed in 1..200 {
                let code = encode_normal(unit(seed), encoding);
                let mut bytes = Vec::new();
                push_normal(code, encoding, &mut bytes);
                assert_eq!(bytes.len(), encoding.bytes());
                assert_eq!(read_normal(&bytes, encoding), code);
            }
        }
    }

    #[test]
    fn degenerate_normals_are_stored_as_up() {
        for n in [[0.0; 3], [f32::NAN, 0.0, 1.0]] {
            let code = encode_normal(n, NormalEncoding::Oct16);
            assert_eq!(decode_normal(code, NormalEncoding::Oct16), [0.0, 0.0, 1.0]);
        }
    }
}
