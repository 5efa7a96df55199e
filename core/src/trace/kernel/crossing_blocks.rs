//! The candidate windows of a strip for the crossing walks (`query::crossings`): the same
//! kernel edge functions the closest-hit walk computes, eight windows per block, with every
//! lane that could cross kept (all weights of one sign with `t` in range, or a weight exactly
//! zero), so that the exact tie rule runs only on those few lanes, in scalar code.

use super::{TraceKernel, Walk, BLOCK};
use crate::format::reader::StripView;
use crate::format::vertices::{StripVertices, VertexAccess};
use crate::trace::watertight::{RayPoint, RaySpace};

/// Blocks of a strip offered in one call: bit `k` of a mask is block `first_block + k`.
pub const MASK_BLOCKS: usize = 64;

/// A strip's blocks to test for one ray.
#[derive(Clone, Copy)]
pub struct StripBlocks<'a, 'v> {
    pub view: &'a StripView<'v>,
    /// Bit `k`: test block `first_block + k` (windows `BLOCK * (first_block + k) ..`).
    pub mask: u64,
    pub first_block: usize,
}

/// Calls `each(window, corners)` for every real window of the blocks `blocks` names that the
/// ray of `space` may cross within `range`, on kernel `K`: its corners in ray space in strip
/// order, bit-identical to [`RaySpace::transform`] of its vertices. Every window the exact
/// tie rule or `watertight::resolve` would accept is among them. Inlined into the query walk
/// already compiled for `K` ([`QueryKernel::for_each_candidate`]), so a strip costs no call.
///
/// [`QueryKernel::for_each_candidate`]: super::query_kernel::QueryKernel::for_each_candidate
#[inline(always)]
pub(super) fn candidates_on<K: TraceKernel, F: FnMut(usize, [RayPoint; 3])>(
    space: &RaySpace,
    range: (f32, f32),
    blocks: StripBlocks,
    each: &mut F,
) {
    match blocks.view.vertices {
        StripVertices::F32(vertices) => by_axes::<K, _, F>(space, range, vertices, blocks, each),
        StripVertices::Grid(vertices) => by_axes::<K, _, F>(space, range, vertices, blocks, each),
    }
}

/// One walk per ray-space axis order, as the closest-hit strip walk.
#[inline(always)]
fn by_axes<K: TraceKernel, V: VertexAccess, F: FnMut(usize, [RayPoint; 3])>(
    space: &RaySpace,
    range: (f32, f32),
    vertices: V,
    blocks: StripBlocks,
    each: &mut F,
) {
    let args = (space, range, vertices, blocks);
    match space.axes() {
        [1, 2, 0] => Candidates::<V, F, 1, 2, 0>::new(args, each).run::<K>(),
        [2, 1, 0] => Candidates::<V, F, 2, 1, 0>::new(args, each).run::<K>(),
        [2, 0, 1] => Candidates::<V, F, 2, 0, 1>::new(args, each).run::<K>(),
        [0, 2, 1] => Candidates::<V, F, 0, 2, 1>::new(args, each).run::<K>(),
        [0, 1, 2] => Candidates::<V, F, 0, 1, 2>::new(args, each).run::<K>(),
        _ => Candidates::<V, F, 1, 0, 2>::new(args, each).run::<K>(),
    }
}

/// The candidate walk of one strip for a ray whose ray-space axes are `[KX, KY, KZ]`.
struct Candidates<'a, 'v, 'f, V, F, const KX: usize, const KY: usize, const KZ: usize> {
    space: &'a RaySpace,
    range: (f32, f32),
    vertices: V,
    blocks: StripBlocks<'a, 'v>,
    each: &'f mut F,
}

type CandidateArgs<'a, 'v, V> = (&'a RaySpace, (f32, f32), V, StripBlocks<'a, 'v>);

impl<'a, 'v, 'f, V, F, const KX: usize, const KY: usize, const KZ: usize>
    Candidates<'a, 'v, 'f, V, F, KX, KY, KZ>
{
    #[inline(always)]
    fn new((space, range, vertices, blocks): CandidateArgs<'a, 'v, V>, each: &'f mut F) -> Self {
        Candidates {
            space,
            range,
            vertices,
            blocks,
            each,
        }
    }
}

impl<V, F, const KX: usize, const KY: usize, const KZ: usize> Walk
    for Candidates<'_, '_, '_, V, F, KX, KY, KZ>
where
    V: VertexAccess,
    F: FnMut(usize, [RayPoint; 3]),
{
    type Output = ();

    #[inline(always)]
    fn run<K: TraceKernel>(self) {
        let view = self.blocks.view;
        let windows = view.window_count();
        let mut mask = self.blocks.mask;
        while mask != 0 {
            let block = self.blocks.first_block + mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let first = block * BLOCK;
            if first >= windows {
                break;
            }
            let count = BLOCK.min(windows - first);
            let references = K::references(&view.references, first);
            // `SITE` 2: apart from the closest-hit walks' instantiations.
            let edges = K::edges::<V, KX, KY, KZ, 2>(
                self.space,
                self.vertices,
                &references,
                count,
                self.range,
            );
            let Some(edges) = edges else {
                continue;
            };
            let mut candidates = edges.candidates;
            while candidates != 0 {
                let lane = candidates.trailing_zeros() as usize;
                candidates &= candidates - 1;
                let corners: [u8; 3] = std::array::from_fn(|k| references[lane + k]);
                // A swap repeats a corner: no triangle (`strip_windows::window_corners`).
                if corners[0] == corners[1] || corners[1] == corners[2] || corners[0] == corners[2]
                {
                    continue;
                }
                let c = std::array::from_fn(|k| {
                    let along_z = self.vertices.coordinate(corners[k] as usize, KZ);
                    RayPoint {
                        x: edges.x[k][lane],
                        y: edges.y[k][lane],
                        z: self.space.depth_as::<KZ>(along_z),
                    }
                });
                (self.each)(first + lane, c);
            }
        }
    }
}
