//! Any-hit traversal of a group of up to [`GROUP_WIDTH`] rays at once: one walk of the tree
//! in which every stack entry carries the mask of rays still to visit it (the masked ray
//! streams of Embree, after Tsakok 2009 and Fuetterling et al. 2015). A node is fetched once
//! for all the rays that reach it and each of them tests its eight boxes with the single-ray
//! node test, so a coherent group (camera rays, or shadow rays of neighbouring pixels) shares
//! the node loads and the stack work that a ray alone pays for by itself. A ray leaves the
//! group at its first hit. [`GROUPS_IN_FLIGHT`] groups step in turn, so that one group's
//! cache misses overlap the others' work, as a stream of single rays does.
//!
//! The answers are those of the single-ray test: a ray is occluded exactly when a triangle in
//! a leaf whose box it enters is hit, whatever the order of the walk.

use std::marker::PhantomData;
use std::mem::offset_of;

use obvhs::cwbvh::node::CwBvhNode;

use super::{
    AnyLeaves, LEAF_FIRST_MASK, LEAF_FLAG, NodeRay, NodeTest, WideBvhNode, node_frame, prefetch_node,
};

/// Rays in a group: one bit each in a stack entry's mask.
pub const GROUP_WIDTH: usize = 32;

/// `SPREAD[m]` has byte `i` equal to bit `i` of `m`: a node's hit slots, one byte a slot.
static SPREAD: [u64; 256] = {
    let mut t = [0u64; 256];
    let mut m = 0;
    while m < 256 {
        let mut i = 0;
        while i < 8 {
            if m & (1 << i) != 0 {
                t[m] |= 1 << (8 * i);
            }
            i += 1;
        }
        m += 1;
    }
    t
};

/// The rays of a group that enter each child box of a node.
pub(super) trait GroupTest {
    /// Bit `r` of entry `s` is set when ray `r` of `mask` enters child slot `s` of `node` on
    /// `(t_min, t_max[r]]`, by the single-ray node test.
    fn masks(node: &CwBvhNode, rays: &[NodeRay], t_max: &[f32], mask: u32) -> [u32; 8];
}

/// Any single-ray node test, ray by ray.
pub(super) struct EachRay<T>(PhantomData<T>);

impl<T: NodeTest> GroupTest for EachRay<T> {
    #[inline(always)]
    fn masks(node: &CwBvhNode, rays: &[NodeRay], t_max: &[f32], mut mask: u32) -> [u32; 8] {
        // Byte `s` of `slots[j]` collects bits `8j..8j+8` of slot `s`'s ray mask.
        let mut slots = [0u64; GROUP_WIDTH / 8];
        while mask != 0 {
            let r = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let (hits, _) = T::hits(node, &rays[r], t_max[r]);
            slots[r / 8] |= SPREAD[hits as usize] << (r % 8);
        }
        std::array::from_fn(|slot| {
            slots
                .iter()
                .enumerate()
                .fold(0u32, |acc, (j, s)| acc | (((s >> (8 * slot)) & 0xff) as u32) << (8 * j))
        })
    }
}

/// Groups a thread keeps in flight: while one waits for its next node or leaf from memory,
/// the others work.
pub const GROUPS_IN_FLIGHT: usize = 4;

/// One group of rays in flight: its rays, their distance limits and leaf tests, the rays
/// still looking (`active`) and those that hit (`found`), the item to visit next with the
/// rays that visit it, and its stack of (item, ray mask) entries.
pub(super) struct Group<V> {
    first: usize,
    rays: Vec<NodeRay>,
    t_max: Vec<f32>,
    visitors: Vec<V>,
    active: u32,
    found: u32,
    current: u32,
    mask: u32,
    stack: Vec<(u32, u32)>,
}

impl<V> Group<V> {
    pub(super) fn new(stack_len: usize) -> Self {
        Self {
            first: 0,
            rays: Vec::with_capacity(GROUP_WIDTH),
            t_max: Vec::with_capacity(GROUP_WIDTH),
            visitors: Vec::with_capacity(GROUP_WIDTH),
            active: 0,
            found: 0,
            current: 0,
            mask: 0,
            stack: Vec::with_capacity(stack_len),
        }
    }
}

/// One step of a group's walk: tests the leaf or visits the node `g.current` for the rays of
/// `g.mask` (a node's hit children go on the stack with the mask of rays that enter each,
/// leaves on top), then pops the next item that a ray still looking visits. Returns false
/// when the group is done.
#[inline(always)]
fn any_group_step<G: GroupTest, V: AnyLeaves>(nodes: &[CwBvhNode], g: &mut Group<V>) -> bool {
    if g.current & LEAF_FLAG != 0 {
        let (first, count) = (g.current & LEAF_FIRST_MASK, (g.current >> 29) & 3);
        let mut m = g.mask;
        while m != 0 {
            let r = m.trailing_zeros() as usize;
            m &= m - 1;
            if g.visitors[r].test(first, count) {
                g.found |= 1 << r;
                g.active &= !(1 << r);
            }
        }
        if g.active == 0 {
            return false;
        }
    } else {
        let node = &nodes[g.current as usize];
        let masks = G::masks(node, &g.rays, &g.t_max, g.mask);
        let any = (0..8).fold(0u32, |a, s| a | u32::from(masks[s] != 0) << s);
        let imask = node.inner_mask();
        // Nodes below leaves on the stack: leaves first, for an early exit.
        let mut inner = any & imask;
        while inner != 0 {
            let slot = inner.trailing_zeros() as usize;
            inner &= inner - 1;
            g.stack.push((node.child(slot), masks[slot]));
        }
        let mut leaves = any & !imask;
        while leaves != 0 {
            let slot = leaves.trailing_zeros() as usize;
            leaves &= leaves - 1;
            let (first, count) = node.leaf(slot);
            g.stack.push((LEAF_FLAG | count << 29 | first, masks[slot]));
        }
    }
    loop {
        let Some((id, m)) = g.stack.pop() else { return false };
        if m & g.active != 0 {
            (g.current, g.mask) = (id, m & g.active);
            return true;
        }
    }
}

/// The any-hit walk of rays `0..count` in groups of [`GROUP_WIDTH`] consecutive rays,
/// [`GROUPS_IN_FLIGHT`] groups interleaved one step each, the item each group visits next
/// prefetched when it is chosen. `finish(i, hit)` gets each ray's answer.
#[inline(always)]
pub(super) fn any_groups_loop<G: GroupTest, V: AnyLeaves>(
    nodes: &[CwBvhNode],
    count: usize,
    mut start: impl FnMut(usize) -> (NodeRay, f32, V),
    mut finish: impl FnMut(usize, bool),
    groups: &mut [Group<V>; GROUPS_IN_FLIGHT],
) {
    let mut busy = [false; GROUPS_IN_FLIGHT];
    let mut next = 0;
    loop {
        let mut any_busy = false;
        for (g, busy) in groups.iter_mut().zip(busy.iter_mut()) {
            if !*busy {
                if next >= count {
                    continue;
                }
                let end = (next + GROUP_WIDTH).min(count);
                g.rays.clear();
                g.t_max.clear();
                g.visitors.clear();
                g.stack.clear();
                for i in next..end {
                    let (ray, t, visitor) = start(i);
                    g.rays.push(ray);
                    g.t_max.push(t);
                    g.visitors.push(visitor);
                }
                g.first = next;
                g.active = if end - next >= 32 { u32::MAX } else { (1u32 << (end - next)) - 1 };
                (g.found, g.current, g.mask) = (0, 0, g.active);
                next = end;
                *busy = true;
            }
            any_busy = true;
            if any_group_step::<G, V>(nodes, g) {
                if g.current & LEAF_FLAG != 0 {
                    let r = g.mask.trailing_zeros() as usize;
                    g.visitors[r].prefetch(g.current & LEAF_FIRST_MASK, (g.current >> 29) & 3);
                } else {
                    prefetch_node(nodes, g.current);
                }
            } else {
                (0..g.rays.len()).for_each(|r| finish(g.first + r, g.found & (1 << r) != 0));
                *busy = false;
            }
        }
        if !any_busy {
            return;
        }
    }
}

/// The AVX2 group test: the node's quantised planes are widened to floats once, then each
/// ray's slab distances are the same fused multiply-adds as in the single-ray test
/// ([`super::avx::cw_hits`]), so every ray gets the same answer as alone.
#[cfg(target_arch = "x86_64")]
pub(super) struct Avx2Group;

#[cfg(target_arch = "x86_64")]
impl GroupTest for Avx2Group {
    #[inline(always)]
    fn masks(node: &CwBvhNode, rays: &[NodeRay], t_max: &[f32], mut mask: u32) -> [u32; 8] {
        use std::arch::x86_64::*;
        let first_row = offset_of!(CwBvhNode, child_min_x);
        let base = (node as *const CwBvhNode).cast::<u8>();
        let mut out = [0u32; 8];
        // SAFETY: `Avx2Group` is only used inside functions compiled with AVX2 and FMA,
        // entered after `is_x86_feature_detected!` confirmed them; the six 8-byte rows read
        // lie inside `*node`, and the row indices of a `NodeRay` are below 6.
        unsafe {
            let rows: [__m256; 6] = std::array::from_fn(|k| {
                _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(base.add(first_row + 8 * k).cast())))
            });
            let row = |offset: usize| *rows.get_unchecked((offset - first_row) / 8);
            let mut acc = _mm256_setzero_si256();
            while mask != 0 {
                let r = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let ray = rays.get_unchecked(r);
                let (scale, shift) = node_frame(node, ray);
                let slab = |offset: usize, scale: f32, shift: f32| {
                    _mm256_fmadd_ps(row(offset), _mm256_set1_ps(scale), _mm256_set1_ps(shift))
                };
                let t0 = _mm256_max_ps(
                    _mm256_max_ps(slab(ray.near[0], scale.x, shift.x), slab(ray.near[1], scale.y, shift.y)),
                    _mm256_max_ps(slab(ray.near[2], scale.z, shift.z), _mm256_set1_ps(ray.t_min)),
                );
                let t1 = _mm256_min_ps(
                    _mm256_min_ps(slab(ray.far[0], scale.x, shift.x), slab(ray.far[1], scale.y, shift.y)),
                    _mm256_min_ps(
                        slab(ray.far[2], scale.z, shift.z),
                        _mm256_set1_ps(*t_max.get_unchecked(r)),
                    ),
                );
                let hit = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1));
                acc = _mm256_or_si256(acc, _mm256_and_si256(hit, _mm256_set1_epi32(1 << r)));
            }
            let meta = _mm256_cvtepu8_epi32(_mm_loadl_epi64(node.child_meta.as_ptr().cast()));
            let empty = _mm256_cmpeq_epi32(meta, _mm256_setzero_si256());
            _mm256_storeu_si256(out.as_mut_ptr().cast(), _mm256_andnot_si256(empty, acc));
        }
        out
    }
}
