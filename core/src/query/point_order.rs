//! Point queries answered in a spatial order: points sorted along a Morton curve of a grid over
//! their bounds, so that consecutive queries visit nearby nodes and strips, which are then in
//! cache (points scattered over the model each miss it otherwise). Each answer depends on its
//! point alone, so the order changes no answer; they are returned in input order.

use rayon::prelude::*;

use crate::geometry::Point;

/// Bits per axis of a point's cell: a 30-bit Morton code.
const CELL_BITS: u32 = 10;

/// Batches smaller than this are answered in their own order: too few points to share much.
const MIN_POINTS: usize = 1 << 12;

/// `answer` of every point (with per-thread state from `init`), in parallel on rayon's current
/// pool, computed in spatial order and returned in input order.
pub(crate) fn answer_in_spatial_order<S, T, I, F>(points: &[Point], init: I, answer: F) -> Vec<T>
where
    T: Copy + Send + Sync,
    I: Fn() -> S + Sync + Send,
    F: Fn(&mut S, &Point) -> T + Sync + Send,
{
    let Some(order) = spatial_order(points) else {
        return points.par_iter().map_init(init, answer).collect();
    };
    // Copied into curve order first: each query then reads the next point in sequence, where
    // reading it through `order` waited on a cache miss per query.
    let sorted_points: Vec<Point> = order.par_iter().map(|&i| points[i as usize]).collect();
    let sorted: Vec<T> = sorted_points.par_iter().map_init(init, answer).collect();
    in_input_order(&order, sorted)
}

/// `answer(group, answers)` for runs of up to `group_size` consecutive points along the curve
/// (so that one group's queries can share their walk), in parallel on rayon's current pool;
/// the answers returned in input order.
pub(crate) fn answer_groups_in_spatial_order<T, F>(
    points: &[Point],
    group_size: usize,
    answer: F,
) -> Vec<T>
where
    T: Copy + Default + Send + Sync,
    F: Fn(&[Point], &mut [T]) + Sync + Send,
{
    let order = spatial_order(points);
    let sorted_points: Vec<Point> = match &order {
        Some(order) => order.par_iter().map(|&i| points[i as usize]).collect(),
        None => points.to_vec(),
    };
    let mut sorted = vec![T::default(); points.len()];
    sorted
        .par_chunks_mut(group_size)
        .zip(sorted_points.par_chunks(group_size))
        .for_each(|(answers, group)| answer(group, answers));
    match order {
        Some(order) => in_input_order(&order, sorted),
        None => sorted,
    }
}

/// `sorted[k]`, the answer of point `order[k]`, back in the points' order.
fn in_input_order<T: Copy + Send + Sync>(order: &[u32], sorted: Vec<T>) -> Vec<T> {
    let mut rank = vec![0u32; order.len()];
    for (position, &index) in order.iter().enumerate() {
        rank[index as usize] = position as u32;
    }
    rank.par_iter().map(|&at| sorted[at as usize]).collect()
}

/// The indices of `points` by the Morton code of their cell (ties in input order), or `None`
/// for a small batch. Points with a non-finite coordinate share cell 0.
fn spatial_order(points: &[Point]) -> Option<Vec<u32>> {
    if points.len() < MIN_POINTS || u32::try_from(points.len()).is_err() {
        return None;
    }
    let finite = points.iter().filter(|p| p.iter().all(|x| x.is_finite()));
    let (low, high) = finite.fold(([f32::MAX; 3], [f32::MIN; 3]), |(low, high), p| {
        (
            std::array::from_fn(|axis| low[axis].min(p[axis])),
            std::array::from_fn(|axis| high[axis].max(p[axis])),
        )
    });
    let cells = f64::from(1u32 << CELL_BITS);
    let scale: [f64; 3] = std::array::from_fn(|axis| {
        let extent = f64::from(high[axis]) - f64::from(low[axis]);
        if extent > 0.0 {
            cells / extent
        } else {
            0.0
        }
    });
    let key = |p: &Point| -> u32 {
        if !p.iter().all(|x| x.is_finite()) {
            return 0;
        }
        (0..3)
            .map(|axis| {
                let cell = (f64::from(p[axis]) - f64::from(low[axis])) * scale[axis];
                spread_bits((cell as u32).min((1 << CELL_BITS) - 1)) << axis
            })
            .fold(0, |code, bits| code | bits)
    };
    let keys: Vec<u32> = points.par_iter().map(key).collect();
    let mut order: Vec<u32> = (0..points.len() as u32).collect();
    order.par_sort_by_key(|&index| keys[index as usize]);
    Some(order)
}

/// The low [`CELL_BITS`] bits of `x`, two zero bits after each.
fn spread_bits(x: u32) -> u32 {
    let mut x = x & ((1 << CELL_BITS) - 1);
    x = (x | x << 16) & 0x0300_00ff;
    x = (x | x << 8) & 0x0300_f00f;
    x = (x | x << 4) & 0x030c_30c3;
    (x | x << 2) & 0x0924_9249
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_spread_three_apart() {
        assert_eq!(spread_bits(0b11_1111_1111), 0x0924_9249);
        assert_eq!(spread_bits(0b10_0000_0001), 1 << 27 | 1);
    }

    #[test]
    fn answers_come_back_in_input_order() {
        let points: Vec<Point> = (0..3 * MIN_POINTS)
            .map(|i| {
                let x = ((i * 7919) % 1000) as f32;
                [x, (i % 13) as f32, if i == 5 { f32::NAN } else { 0.5 }]
            })
            .collect();
        assert!(spatial_order(&points)
            .is_some_and(|order| order != (0..points.len() as u32).collect::<Vec<_>>()));
        let answers = answer_in_spatial_order(&points, || (), |_, p| p.map(f32::to_bits));
        let expected: Vec<_> = points.iter().map(|p| p.map(f32::to_bits)).collect();
        assert_eq!(answers, expected);
        for group_size in [1, 8] {
            let grouped = answer_groups_in_spatial_order(&points, group_size, |group, answers| {
                assert!(group.len() <= group_size);
                for (answer, p) in answers.iter_mut().zip(group) {
                    *answer = p.map(f32::to_bits);
                }
            });
            assert_eq!(grouped, expected);
        }
    }
}
