//! Closest-hit traversal of a group of up to [`GROUP_WIDTH`] rays at once: one walk of the
//! tree in which every stack entry carries the mask of rays still to visit it (the masked ray
//! streams of Embree, after Tsakok 2009 and Fuetterling et al. 2015). A node is fetched once
//! for all the rays that reach it and each of them tests its eight boxes with the single-ray
//! node test, so a coherent group shares the node loads and the stack work that a ray alone
//! pays for by itself. The launcher's batches send their coherent runs here (on large trees:
//! the rays of a Fibonacci lattice's polar caps, whose consecutive directions are close).
//! [`GROUPS_IN_FLIGHT`] groups step in turn, so that one group's cache misses overlap the
//! others' work, as a stream of single rays does.
//!
//! Children are visited nearest first by the smallest entry distance of the group's rays, and
//! each ray tests boxes and leaves against its own closest hit so far. Its closest distance
//! is that of the single-ray query, bit for bit; on an exact tie (a ray through an edge
//! shared by two triangles) the triangle may be the other one.

use std::marker::PhantomData;

use obvhs::cwbvh::node::CwBvhNode;

use super::{
    ClosestLeaves, FIRST_ROW, LEAF_FLAG, NodeRay, NodeTest, WideBvhNode, far_to_near, item_id, leaf_of,
    node_frame, prefetch_node,
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
    /// Bit `r` of `masks[s]` is set when ray `r` of `mask` enters child slot `s` of `node` on
    /// `(t_min, t_max[r]]`, by the single-ray node test; `distances[s]` is the smallest entry
    /// distance of those rays (infinite for none); bit `s` of `any` is set when `masks[s]`
    /// is not empty. Returns `(masks, distances, any)`.
    fn hits(node: &CwBvhNode, rays: &[NodeRay], t_max: &[f32], mask: u32) -> ([u32; 8], [f32; 8], u32);
}

/// Any single-ray node test, ray by ray.
pub(super) struct EachRay<T>(PhantomData<T>);

impl<T: NodeTest> GroupTest for EachRay<T> {
    #[inline(always)]
    fn hits(node: &CwBvhNode, rays: &[NodeRay], t_max: &[f32], mut mask: u32) -> ([u32; 8], [f32; 8], u32) {
        // Byte `s` of `slots[j]` collects bits `8j..8j+8` of slot `s`'s ray mask.
        let mut slots = [0u64; GROUP_WIDTH / 8];
        let mut distances = [f32::INFINITY; 8];
        let mut any = 0;
        while mask != 0 {
            let r = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            let (hits, tnear) = T::hits(node, &rays[r], t_max[r]);
            any |= hits;
            slots[r / 8] |= SPREAD[hits as usize] << (r % 8);
            for (s, d) in distances.iter_mut().enumerate() {
                if hits & (1 << s) != 0 {
                    *d = d.min(tnear[s]);
                }
            }
        }
        let masks = std::array::from_fn(|slot| {
            slots
                .iter()
                .enumerate()
                .fold(0u32, |acc, (j, s)| acc | (((s >> (8 * slot)) & 0xff) as u32) << (8 * j))
        });
        (masks, distances, any)
    }
}

/// Groups a thread keeps in flight: while one waits for its next node or leaf from memory,
/// the others work. With tiled groups and leaves prefetched as they are pushed, 8 beat 4 by
/// 12 % / 16 % (closest hit / occlusion, since removed, coherent benchmark rays, 1 thread, paired runs), and
/// 6 and 12 were slower than 8.
pub const GROUPS_IN_FLIGHT: usize = 8;

/// One group of rays in flight: its rays, their distance limits (the closest hits so far)
/// and leaf tests, the item to visit next with the rays that visit it, and its stack of
/// (item, ray mask, smallest entry distance) entries.
pub(super) struct Group<V> {
    first: usize,
    rays: Vec<NodeRay>,
    t_max: Vec<f32>,
    visitors: Vec<V>,
    current: u32,
    mask: u32,
    stack: Vec<(u32, u32, f32)>,
}

impl<V> Group<V> {
    pub(super) fn new(stack_len: usize) -> Self {
        Self {
            first: 0,
            rays: Vec::with_capacity(GROUP_WIDTH),
            t_max: Vec::with_capacity(GROUP_WIDTH),
            visitors: Vec::with_capacity(GROUP_WIDTH),
            current: 0,
            mask: 0,
            stack: Vec::with_capacity(stack_len),
        }
    }

    /// The rays of `mask` whose closest hit so far is not nearer than `t`.
    #[inline(always)]
    fn not_beyond(&self, mut mask: u32, t: f32) -> u32 {
        let mut keep = 0;
        while mask != 0 {
            let r = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            keep |= u32::from(t <= self.t_max[r]) << r;
        }
        keep
    }
}

/// One step of a group's closest-hit walk: tests the leaf or visits the node `g.current` for
/// the rays of `g.mask` (the nearest hit child is next, the others go on the stack farthest
/// first, leaves and nodes alike), then pops the next item that a ray may still find a
/// closer hit in. Returns false when the group is done.
#[inline(always)]
fn closest_group_step<G: GroupTest, V: ClosestLeaves>(nodes: &[CwBvhNode], g: &mut Group<V>) -> bool {
    if g.current & LEAF_FLAG != 0 {
        let (first, count) = leaf_of(g.current);
        let mut m = g.mask;
        while m != 0 {
            let r = m.trailing_zeros() as usize;
            m &= m - 1;
            g.visitors[r].test(first, count, &mut g.t_max[r]);
        }
    } else {
        let node = &nodes[g.current as usize];
        let (masks, distances, any) = G::hits(node, &g.rays, &g.t_max, g.mask);
        if any != 0 {
            let imask = node.inner_mask();
            let (order, n) =
                far_to_near(any, |slot| ((item_id(node, imask, slot), masks[slot]), distances[slot]));
            g.stack.extend(order[..n - 1].iter().map(|&((id, m), t)| (id, m, t)));
            ((g.current, g.mask), _) = order[n - 1];
            return true;
        }
    }
    loop {
        let Some((id, m, t)) = g.stack.pop() else { return false };
        let m = g.not_beyond(m, t);
        if m != 0 {
            (g.current, g.mask) = (id, m);
            return true;
        }
    }
}

/// One group's closest-hit walk with a leaf test for the whole group, for trees that stay
/// in the cache (the levels of an instanced scene): `leaf(first, count, mask, t_max)` tests
/// leaf `(first, count)` for the rays of `mask`, lowering their `t_max` on closer hits.
/// Children are visited and culled as in [`closest_group_step`].
#[inline(always)]
pub(super) fn walk_one_group<G: GroupTest>(
    nodes: &[CwBvhNode],
    rays: &[NodeRay],
    t_max: &mut [f32],
    stack: &mut Vec<(u32, u32, f32)>,
    mut leaf: impl FnMut(u32, u32, u32, &mut [f32]),
) {
    let n = rays.len().min(GROUP_WIDTH);
    if n == 0 || nodes.is_empty() {
        return;
    }
    stack.clear();
    let (mut current, mut mask) = (0u32, if n == 32 { u32::MAX } else { (1u32 << n) - 1 });
    loop {
        if current & LEAF_FLAG != 0 {
            let (first, count) = leaf_of(current);
            leaf(first, count, mask, t_max);
        } else {
            let node = &nodes[current as usize];
            let (masks, distances, any) = G::hits(node, rays, t_max, mask);
            if any != 0 {
                let imask = node.inner_mask();
                let (order, k) =
                    far_to_near(any, |slot| ((item_id(node, imask, slot), masks[slot]), distances[slot]));
                stack.extend(order[..k - 1].iter().map(|&((id, m), t)| (id, m, t)));
                ((current, mask), _) = order[k - 1];
                continue;
            }
        }
        loop {
            let Some((id, mut m, t)) = stack.pop() else { return };
            // The rays whose closest hit so far is not nearer than the entry distance.
            let mut keep = 0;
            while m != 0 {
                let r = m.trailing_zeros() as usize;
                m &= m - 1;
                keep |= u32::from(t <= t_max[r]) << r;
            }
            if keep != 0 {
                (current, mask) = (id, keep);
                break;
            }
        }
    }
}

impl<V: ClosestLeaves> Group<V> {
    /// Hands each ray's leaf test back to `finish(i, leaves)`.
    pub(super) fn leaf_tests(&mut self, finish: &mut impl FnMut(usize, V)) {
        let first = self.first;
        self.visitors.drain(..).enumerate().for_each(|(r, v)| finish(first + r, v));
    }
}

/// The closest-hit walk of rays `0..count` in groups of [`GROUP_WIDTH`] consecutive rays,
/// [`GROUPS_IN_FLIGHT`] groups interleaved one step each, the item each group visits next
/// prefetched when it is chosen; `done` gets each finished group.
#[inline(always)]
pub(super) fn groups_loop<G: GroupTest, V: ClosestLeaves>(
    nodes: &[CwBvhNode],
    count: usize,
    mut start: impl FnMut(usize) -> (NodeRay, f32, V),
    mut done: impl FnMut(&mut Group<V>),
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
                g.mask = if end - next >= 32 { u32::MAX } else { (1u32 << (end - next)) - 1 };
                g.current = 0;
                next = end;
                *busy = true;
            }
            any_busy = true;
            if closest_group_step::<G, V>(nodes, g) {
                if g.current & LEAF_FLAG != 0 {
                    let r = g.mask.trailing_zeros() as usize;
                    let (first, count) = leaf_of(g.current);
                    g.visitors[r].prefetch(first, count);
                } else {
                    prefetch_node(nodes, g.current);
                }
            } else {
                done(g);
                *busy = false;
            }
        }
        if !any_busy {
            return;
        }
    }
}

/// Row `r` holds `1 << r` in all eight lanes: a ray's bit, ready to mark the slots it enters.
#[cfg(target_arch = "x86_64")]
#[repr(align(32))]
struct RayBits([[u32; 8]; GROUP_WIDTH]);

#[cfg(target_arch = "x86_64")]
static RAY_BITS: RayBits = RayBits({
    let mut t = [[0u32; 8]; GROUP_WIDTH];
    let mut r = 0;
    while r < GROUP_WIDTH {
        t[r] = [1 << r; 8];
        r += 1;
    }
    t
});

/// The AVX2 group test: the node's quantised planes are widened to floats once, then each
/// ray's slab distances are the same fused multiply-adds as in the single-ray test
/// ([`super::avx::cw_hits`]), so every ray gets the same answer as alone.
#[cfg(target_arch = "x86_64")]
pub(super) struct Avx2Group;

#[cfg(target_arch = "x86_64")]
impl GroupTest for Avx2Group {
    #[inline(always)]
    fn hits(node: &CwBvhNode, rays: &[NodeRay], t_max: &[f32], mut mask: u32) -> ([u32; 8], [f32; 8], u32) {
        use std::arch::x86_64::*;
        let base = (node as *const CwBvhNode).cast::<u8>();
        let mut out = [0u32; 8];
        let mut distances = [0.0f32; 8];
        let any;
        // SAFETY: `Avx2Group` is only used inside functions compiled with AVX2 and FMA,
        // entered after `is_x86_feature_detected!` confirmed them; the six 8-byte rows read
        // lie inside `*node`, and the row offsets of a `NodeRay` are at most 40, so that
        // `4 * offset` points at one of the six vectors of `rows`; the rays of `mask` are
        // below `rays.len()` (at most 32), so `RAY_BITS` has their aligned row.
        unsafe {
            let rows: [__m256; 6] = std::array::from_fn(|k| {
                _mm256_cvtepi32_ps(_mm256_cvtepu8_epi32(_mm_loadl_epi64(base.add(FIRST_ROW + 8 * k).cast())))
            });
            // Row `k` is at byte offset `8 k` in the node and `32 k` in `rows`.
            let row = |offset: usize| rows.as_ptr().cast::<u8>().add(4 * offset).cast::<__m256>().read();
            let mut acc = _mm256_setzero_si256();
            let mut nearest = _mm256_set1_ps(f32::INFINITY);
            let lane = [_mm256_set1_epi32(0), _mm256_set1_epi32(1), _mm256_set1_epi32(2)];
            while mask != 0 {
                let r = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                let ray = rays.get_unchecked(r);
                let (scale, shift) = node_frame(node, ray);
                // Lane `k` of `scale` and `shift` across all eight lanes, one permute each.
                let (scale, shift) =
                    (_mm256_castps128_ps256(scale.into()), _mm256_castps128_ps256(shift.into()));
                let across = |v: __m256, k: usize| _mm256_permutevar8x32_ps(v, lane[k]);
                let slab = |offset: usize, k: usize| {
                    _mm256_fmadd_ps(row(offset), across(scale, k), across(shift, k))
                };
                let t0 = _mm256_max_ps(
                    _mm256_max_ps(slab(ray.near[0], 0), slab(ray.near[1], 1)),
                    _mm256_max_ps(slab(ray.near[2], 2), _mm256_set1_ps(ray.t_min)),
                );
                let t1 = _mm256_min_ps(
                    _mm256_min_ps(slab(ray.far[0], 0), slab(ray.far[1], 1)),
                    _mm256_min_ps(slab(ray.far[2], 2), _mm256_set1_ps(*t_max.get_unchecked(r))),
                );
                let hit = _mm256_castps_si256(_mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1));
                let bit = _mm256_load_si256(RAY_BITS.0.as_ptr().add(r).cast());
                acc = _mm256_or_si256(acc, _mm256_and_si256(hit, bit));
                nearest = _mm256_blendv_ps(nearest, _mm256_min_ps(nearest, t0), _mm256_castsi256_ps(hit));
            }
            _mm256_storeu_ps(distances.as_mut_ptr(), nearest);
            let meta = _mm256_cvtepu8_epi32(_mm_loadl_epi64(node.child_meta.as_ptr().cast()));
            let empty = _mm256_cmpeq_epi32(meta, _mm256_setzero_si256());
            let masks = _mm256_andnot_si256(empty, acc);
            _mm256_storeu_si256(out.as_mut_ptr().cast(), masks);
            let none = _mm256_cmpeq_epi32(masks, _mm256_setzero_si256());
            any = !(_mm256_movemask_ps(_mm256_castsi256_ps(none)) as u32) & 0xff;
        }
        (out, distances, any)
    }
}
