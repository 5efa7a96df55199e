//! Small geometric primitives shared by the build and read sides.

/// A point or vector in model space, stored exactly as the file stores it.
pub type Point = [f32; 3];

/// Largest coordinate magnitude the project accepts from input files. The watertight ray test
/// multiplies coordinates (edge functions are products of two, the hit distance of three) in
/// f32; beyond about 1e12 those products overflow, so inputs are held well inside that.
pub const MAX_COORDINATE: f32 = 1e11;

/// Axis-aligned bounding box. An empty box has `min > max` on every axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    pub min: Point,
    pub max: Point,
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        min: [f32::INFINITY; 3],
        max: [f32::NEG_INFINITY; 3],
    };

    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a Point>) -> Aabb {
        let mut aabb = Aabb::EMPTY;
        for p in points {
            aabb.grow_point(p);
        }
        aabb
    }

    pub fn grow_point(&mut self, p: &Point) {
        self.min = [0, 1, 2].map(|axis| self.min[axis].min(p[axis]));
        self.max = [0, 1, 2].map(|axis| self.max[axis].max(p[axis]));
    }

    pub fn grow(&mut self, other: &Aabb) {
        for axis in 0..3 {
            self.min[axis] = self.min[axis].min(other.min[axis]);
            self.max[axis] = self.max[axis].max(other.max[axis]);
        }
    }

    pub fn union(mut self, other: &Aabb) -> Aabb {
        self.grow(other);
        self
    }

    pub fn is_empty(&self) -> bool {
        (0..3).any(|axis| self.min[axis] > self.max[axis])
    }

    pub fn extent(&self, axis: usize) -> f32 {
        (self.max[axis] - self.min[axis]).max(0.0)
    }

    pub fn centroid(&self, axis: usize) -> f32 {
        0.5 * self.min[axis] + 0.5 * self.max[axis]
    }

    /// Surface area in f64, so that sums over millions of boxes keep their precision.
    pub fn surface_area(&self) -> f64 {
        if self.is_empty() {
            return 0.0;
        }
        let [x, y, z] = [0, 1, 2].map(|axis| self.extent(axis) as f64);
        2.0 * (x * y + y * z + z * x)
    }

    pub fn contains(&self, p: &Point) -> bool {
        (0..3).all(|axis| self.min[axis] <= p[axis] && p[axis] <= self.max[axis])
    }

    pub fn contains_box(&self, other: &Aabb) -> bool {
        other.is_empty() || (self.contains(&other.min) && self.contains(&other.max))
    }

    pub fn longest_axis(&self) -> usize {
        let e = [0, 1, 2].map(|axis| self.extent(axis));
        if e[0] >= e[1] && e[0] >= e[2] {
            0
        } else if e[1] >= e[2] {
            1
        } else {
            2
        }
    }
}

/// True when the triangle has zero area: its three corners are collinear or coincide.
///
/// The cross product is evaluated in f64. Products of two f32 values are exact in f64, so for
/// coordinates of similar magnitude the test is exact; it is the one definition of "zero area"
/// used by adjacency (which drops such triangles) and by the round-trip tests.
pub fn is_degenerate(a: &Point, b: &Point, c: &Point) -> bool {
    let e1 = [0, 1, 2].map(|i| b[i] as f64 - a[i] as f64);
    let e2 = [0, 1, 2].map(|i| c[i] as f64 - a[i] as f64);
    let cross = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    cross == [0.0; 3]
}

/// Euclidean distance in f64.
pub fn distance(a: &Point, b: &Point) -> f64 {
    let squared: f64 = (0..3).map(|i| (a[i] as f64 - b[i] as f64).powi(2)).sum();
    squared.sqrt()
}

/// How far a set of points moved (from the input to where they are stored, or to the vertex
/// they were welded into): count, largest distance and sum of squares, which add up over
/// chunks in a fixed order, so the totals do not depend on the thread count.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[cfg_attr(feature = "serde", derive(serde::Serialize, serde::Deserialize))]
pub struct Displacement {
    pub count: u64,
    pub max: f64,
    pub squared_sum: f64,
}

impl Displacement {
    pub fn record(&mut self, distance: f64) {
        self.count += 1;
        self.max = self.max.max(distance);
        self.squared_sum += distance * distance;
    }

    pub fn add(&mut self, other: &Displacement) {
        self.count += other.count;
        self.max = self.max.max(other.max);
        self.squared_sum += other.squared_sum;
    }

    /// Root mean square distance; 0 for no points.
    pub fn rms(&self) -> f64 {
        if self.count == 0 {
            0.0
        } else {
            (self.squared_sum / self.count as f64).sqrt()
        }
    }
}
