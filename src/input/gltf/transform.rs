//! Node transforms as affine `f64` matrices: composed down the hierarchy and applied to
//! positions and normals, rounding to `f32` once at the end. Plain multiplications and
//! additions only (no fused multiply-add), so results are the same on every machine.

use gltf::json::scene::Node;

/// The rows of an affine transform: `[linear | translation]`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Transform {
    rows: [[f64; 4]; 3],
}

impl Transform {
    pub(super) const IDENTITY: Transform = Transform {
        rows: [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
        ],
    };

    /// A node's local transform: its `matrix` (column-major) or `translation * rotation *
    /// scale`.
    pub(super) fn of_node(node: &Node) -> Transform {
        if let Some(m) = node.matrix {
            let at = |row: usize, column: usize| f64::from(m[column * 4 + row]);
            return Transform {
                rows: std::array::from_fn(|row| std::array::from_fn(|column| at(row, column))),
            };
        }
        let [x, y, z, w] = node
            .rotation
            .map_or([0.0, 0.0, 0.0, 1.0], |q| q.0)
            .map(f64::from);
        let rotation = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - z * w),
                2.0 * (x * z + y * w),
            ],
            [
                2.0 * (x * y + z * w),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - x * w),
            ],
            [
                2.0 * (x * z - y * w),
                2.0 * (y * z + x * w),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        let scale = node.scale.unwrap_or([1.0; 3]).map(f64::from);
        let translation = node.translation.unwrap_or([0.0; 3]).map(f64::from);
        Transform {
            rows: std::array::from_fn(|row| {
                let r = rotation[row];
                [
                    r[0] * scale[0],
                    r[1] * scale[1],
                    r[2] * scale[2],
                    translation[row],
                ]
            }),
        }
    }

    /// `self` applied after `local`: the global transform of a child whose parent's is `self`.
    pub(super) fn then(&self, local: &Transform) -> Transform {
        let (a, b) = (&self.rows, &local.rows);
        Transform {
            rows: std::array::from_fn(|row| {
                std::array::from_fn(|column| {
                    let product = a[row][0] * b[0][column]
                        + a[row][1] * b[1][column]
                        + a[row][2] * b[2][column];
                    if column == 3 {
                        product + a[row][3]
                    } else {
                        product
                    }
                })
            }),
        }
    }

    /// `point` transformed and rounded to `f32`. Terms with a zero coefficient are left out,
    /// so an identity or axis-aligned transform keeps every bit, `-0.0` included.
    pub(super) fn point(&self, point: [f64; 3]) -> [f32; 3] {
        self.rows.map(|row| {
            let terms = [(row[0], point[0]), (row[1], point[1]), (row[2], point[2])];
            let mut sum: Option<f64> = None;
            for (coefficient, value) in terms {
                if coefficient != 0.0 {
                    let term = coefficient * value;
                    sum = Some(sum.map_or(term, |s| s + term));
                }
            }
            let sum = match (sum, row[3] != 0.0) {
                (Some(sum), true) => sum + row[3],
                (Some(sum), false) => sum,
                (None, _) => row[3],
            };
            sum as f32
        })
    }

    /// `normal` by the inverse transpose of the linear part (the cofactor matrix, with the
    /// determinant's sign) and renormalized; as read when the linear part is the identity.
    pub(super) fn normal(&self, normal: [f64; 3]) -> [f32; 3] {
        if self.linear_is_identity() {
            return normal.map(|value| value as f32);
        }
        let m = |row: usize, column: usize| self.rows[row % 3][column % 3];
        let cofactor = |row: usize, column: usize| {
            m(row + 1, column + 1) * m(row + 2, column + 2)
                - m(row + 1, column + 2) * m(row + 2, column + 1)
        };
        let sign = if self.mirrors() { -1.0 } else { 1.0 };
        let transformed: [f64; 3] = std::array::from_fn(|row| {
            sign * (cofactor(row, 0) * normal[0]
                + cofactor(row, 1) * normal[1]
                + cofactor(row, 2) * normal[2])
        });
        let length = (transformed[0] * transformed[0]
            + transformed[1] * transformed[1]
            + transformed[2] * transformed[2])
            .sqrt();
        if length > 0.0 {
            transformed.map(|value| (value / length) as f32)
        } else {
            transformed.map(|value| value as f32)
        }
    }

    /// True when the transform mirrors (negative determinant), which reverses winding.
    pub(super) fn mirrors(&self) -> bool {
        let r = &self.rows;
        let determinant = r[0][0] * (r[1][1] * r[2][2] - r[1][2] * r[2][1])
            - r[0][1] * (r[1][0] * r[2][2] - r[1][2] * r[2][0])
            + r[0][2] * (r[1][0] * r[2][1] - r[1][1] * r[2][0]);
        determinant < 0.0
    }

    fn linear_is_identity(&self) -> bool {
        (0..3).all(|row| {
            (0..3).all(|column| self.rows[row][column] == f64::from(u8::from(row == column)))
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn node(json: &str) -> Node {
        serde_json::from_str(json).unwrap()
    }

    #[test]
    fn identity_keeps_every_bit() {
        let point = [-0.0, 1.0e-30, -7.25];
        let kept = Transform::IDENTITY.point(point);
        assert_eq!(
            kept.map(f32::to_bits),
            [-0.0f32, 1.0e-30, -7.25].map(f32::to_bits)
        );
    }

    #[test]
    fn translation_rotation_scale_compose_in_order() {
        // A quarter turn about z, scale 2, then a translation: (1, 0, 0) -> (0, 2, 0) + t.
        let half = std::f32::consts::FRAC_1_SQRT_2;
        let local = Transform::of_node(&node(&format!(
            r#"{{"translation": [10, 20, 30], "rotation": [0, 0, {half}, {half}], "scale": [2, 2, 2]}}"#
        )));
        let [x, y, z] = local.point([1.0, 0.0, 0.0]);
        assert!((x - 10.0).abs() < 1e-6 && (y - 22.0).abs() < 1e-6 && z == 30.0);
        let parent = Transform::of_node(&node(r#"{"translation": [1, 0, 0]}"#));
        let [x, ..] = parent.then(&local).point([1.0, 0.0, 0.0]);
        assert!((x - 11.0).abs() < 1e-6);
    }

    #[test]
    fn a_mirror_is_detected_and_flips_normals_correctly() {
        let mirror = Transform::of_node(&node(r#"{"scale": [-1, 1, 1]}"#));
        assert!(mirror.mirrors());
        assert_eq!(mirror.normal([1.0, 0.0, 0.0]), [-1.0, 0.0, 0.0]);
        assert!(!Transform::IDENTITY.mirrors());
    }

    #[test]
    fn a_column_major_matrix_is_read_by_columns() {
        let matrix = node(r#"{"matrix": [1,0,0,0, 0,1,0,0, 0,0,1,0, 5,6,7,1]}"#);
        assert_eq!(
            Transform::of_node(&matrix).point([1.0, 1.0, 1.0]),
            [6.0, 7.0, 8.0]
        );
    }
}
