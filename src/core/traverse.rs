//! Ray traversal of an obvhs compressed wide BVH (CWBVH, Ylitie et al. 2017): our own stack
//! loop over obvhs' node data, specialised for closest hit (children and leaves visited
//! nearest first, stack entries culled by distance) and for any hit (occlusion, all hits).
//! A single ray prefetches the children and leaves a node test hits before it tests the
//! leaves, so their cache misses overlap the triangle tests (incoherent rays are bound by
//! those misses); a stream prefetches the item each of its rays visits next. Coherent rays
//! can instead walk the tree in groups that share each node (`group`).
//! The loops are generic over [`WideBvhNode`], so another 8-wide node format can plug in.
//!
//! The eight child boxes of a node are tested at once: with AVX and FMA (and AVX2's one-step
//! widening of the quantised planes where present) in one 8-wide pass, otherwise by a scalar
//! loop. The node test is chosen at run time, so the binary still runs on any x86-64;
//! [`ISA_VARIABLE`] can lower it.
//! Both are conservative in the same way as obvhs' own test: the child boxes are quantised
//! outwards, and [`crate::core::accel`] pads primitive bounds by a few ulps, which covers the
//! rounding of the slab distances. A direction component of -0.0 is turned into +0.0 first,
//! so the near side of every slab agrees with the sign of the inverse direction.

mod group;
pub use group::GROUP_WIDTH;

use std::mem::{MaybeUninit, offset_of};

use super::flat::{FlatRay, FlatTriangles, safe_inverse};
use glam::{Vec2, Vec3, Vec3A};
use obvhs::cwbvh::node::CwBvhNode;

/// Stack entries held on the thread's stack; deeper trees use a heap stack.
const INLINE_STACK: usize = 256;

/// The per-ray constants of the node test.
#[derive(Clone, Copy, Debug)]
pub struct NodeRay {
    origin: Vec3A,
    inv_dir: Vec3A,
    /// Byte offsets of the near and far quantised planes of each axis from the first plane
    /// row of a [`CwBvhNode`] ([`FIRST_ROW`]): 0, 8, ..., 40.
    near: [usize; 3],
    far: [usize; 3],
    t_min: f32,
}

impl NodeRay {
    /// Node-test constants of the ray `origin + t dir`, `t` in `(t_min, ..]`.
    #[inline(always)]
    pub fn new(origin: Vec3, dir: Vec3, t_min: f32) -> Self {
        // +0.0 turns -0.0 into +0.0, so the sign tests below and `safe_inverse` agree.
        let dir = Vec3A::from(dir) + Vec3A::ZERO;
        let inv_dir = safe_inverse(dir);
        let lo = [
            offset_of!(CwBvhNode, child_min_x) - FIRST_ROW,
            offset_of!(CwBvhNode, child_min_y) - FIRST_ROW,
            offset_of!(CwBvhNode, child_min_z) - FIRST_ROW,
        ];
        let hi = [
            offset_of!(CwBvhNode, child_max_x) - FIRST_ROW,
            offset_of!(CwBvhNode, child_max_y) - FIRST_ROW,
            offset_of!(CwBvhNode, child_max_z) - FIRST_ROW,
        ];
        let neg = [dir.x < 0.0, dir.y < 0.0, dir.z < 0.0];
        let pick = |k: usize, near: bool| if neg[k] == near { hi[k] } else { lo[k] };
        Self {
            origin: origin.into(),
            inv_dir,
            near: [pick(0, true), pick(1, true), pick(2, true)],
            far: [pick(0, false), pick(1, false), pick(2, false)],
            t_min: t_min.max(0.0),
        }
    }
}

/// Byte offset in a [`CwBvhNode`] of its first row of eight quantised planes; the six rows
/// (min x, max x, min y, max y, min z, max z) follow one another.
const FIRST_ROW: usize = offset_of!(CwBvhNode, child_min_x);

/// The eight quantised planes at byte `offset` from the first row of `node`.
#[inline(always)]
fn planes(node: &CwBvhNode, offset: usize) -> [u8; 8] {
    let at = |k: usize| match k {
        0 => node.child_min_x,
        1 => node.child_max_x,
        2 => node.child_min_y,
        3 => node.child_max_y,
        4 => node.child_min_z,
        _ => node.child_max_z,
    };
    at(offset / 8)
}

/// Slab slopes and offsets of a node for a ray: the distance to quantised plane `q` along axis
/// `k` is `q * scale[k] + shift[k]`.
#[inline(always)]
fn node_frame(node: &CwBvhNode, ray: &NodeRay) -> (Vec3A, Vec3A) {
    let extent = Vec3A::new(
        f32::from_bits(u32::from(node.e[0]) << 23),
        f32::from_bits(u32::from(node.e[1]) << 23),
        f32::from_bits(u32::from(node.e[2]) << 23),
    );
    (extent * ray.inv_dir, (Vec3A::from(node.p) - ray.origin) * ray.inv_dir)
}

/// Bit `i` set when child slot `i` is not empty.
#[inline(always)]
fn occupied(node: &CwBvhNode) -> u32 {
    node.child_meta.iter().enumerate().fold(0, |m, (i, &c)| m | (u32::from(c != 0) << i))
}

/// Child boxes hit on `(t_min, t_max]`: the slot mask and each slot's entry distance.
#[inline(always)]
fn node_hits_scalar(node: &CwBvhNode, ray: &NodeRay, t_max: f32) -> (u32, [f32; 8]) {
    let (scale, shift) = node_frame(node, ray);
    let near = [planes(node, ray.near[0]), planes(node, ray.near[1]), planes(node, ray.near[2])];
    let far = [planes(node, ray.far[0]), planes(node, ray.far[1]), planes(node, ray.far[2])];
    let mut tnear = [0.0f32; 8];
    let mut mask = 0;
    for i in 0..8 {
        let t = |q: u8, k: usize| f32::from(q) * scale[k] + shift[k];
        let t0 = t(near[0][i], 0).max(t(near[1][i], 1)).max(t(near[2][i], 2)).max(ray.t_min);
        let t1 = t(far[0][i], 0).min(t(far[1][i], 1)).min(t(far[2][i], 2)).min(t_max);
        tnear[i] = t0;
        mask |= u32::from(t0 <= t1) << i;
    }
    (mask & occupied(node), tnear)
}

/// A node of an 8-wide BVH that the traversal loops below run over.
pub trait WideBvhNode: Sized {
    /// Bit `i` set when child slot `i` is an internal node.
    fn inner_mask(&self) -> u32;
    /// Primitive range `(first, count)` of leaf child `slot`.
    fn leaf(&self, slot: usize) -> (u32, u32);
    /// Node index of internal child `slot`.
    fn child(&self, slot: usize) -> u32;
    /// Bit `i` set when slot `i` holds a child.
    fn occupied_mask(&self) -> u32;
    /// The portable test of the eight child boxes: the mask of slots hit on `(t_min, t_max]`
    /// and each slot's entry distance.
    fn hits_portable(&self, ray: &NodeRay, t_max: f32) -> (u32, [f32; 8]);
    /// The same test, 8-wide.
    ///
    /// # Safety
    /// The CPU must have AVX, FMA and SSE4.1 (and AVX2 if `AVX2`).
    #[cfg(target_arch = "x86_64")]
    unsafe fn hits_avx<const AVX2: bool>(&self, ray: &NodeRay, t_max: f32) -> (u32, [f32; 8]);
}

impl WideBvhNode for CwBvhNode {
    #[inline(always)]
    fn inner_mask(&self) -> u32 {
        u32::from(self.imask)
    }

    #[inline(always)]
    fn leaf(&self, slot: usize) -> (u32, u32) {
        leaf_range(self, slot)
    }

    #[inline(always)]
    fn child(&self, slot: usize) -> u32 {
        child_index(self, slot)
    }

    fn occupied_mask(&self) -> u32 {
        occupied(self)
    }

    #[inline(always)]
    fn hits_portable(&self, ray: &NodeRay, t_max: f32) -> (u32, [f32; 8]) {
        node_hits_scalar(self, ray, t_max)
    }

    #[cfg(target_arch = "x86_64")]
    #[inline(always)]
    unsafe fn hits_avx<const AVX2: bool>(&self, ray: &NodeRay, t_max: f32) -> (u32, [f32; 8]) {
        // SAFETY: the caller guarantees the CPU features.
        unsafe { avx::cw_hits::<AVX2>(self, ray, t_max) }
    }
}

/// A test of a node's eight child boxes with one instruction set.
trait NodeTest {
    fn hits<N: WideBvhNode>(node: &N, ray: &NodeRay, t_max: f32) -> (u32, [f32; 8]);
}

/// The portable node test.
struct ScalarTest;

impl NodeTest for ScalarTest {
    #[inline(always)]
    fn hits<N: WideBvhNode>(node: &N, ray: &NodeRay, t_max: f32) -> (u32, [f32; 8]) {
        node.hits_portable(ray, t_max)
    }
}

#[cfg(target_arch = "x86_64")]
mod avx {
    use std::arch::x86_64::*;

    use super::{CwBvhNode, NodeRay, NodeTest, WideBvhNode, node_frame};

    /// The 8-wide node test; every function here is `inline(always)` so that it ends up in
    /// the `target_feature` functions that call it, where the intrinsics inline too.
    /// With `AVX2`, the eight plane bytes of a CWBVH node widen in one instruction.
    pub(super) struct AvxTest<const AVX2: bool>;

    impl<const AVX2: bool> NodeTest for AvxTest<AVX2> {
        #[inline(always)]
        fn hits<N: WideBvhNode>(node: &N, ray: &NodeRay, t_max: f32) -> (u32, [f32; 8]) {
            // SAFETY: `AvxTest` is only used inside functions compiled with AVX, FMA and
            // SSE4.1 (and AVX2 for `AvxTest<true>`), entered after `is_x86_feature_detected!`
            // confirmed them.
            unsafe { node.hits_avx::<AVX2>(ray, t_max) }
        }
    }

    /// Distances to the eight quantised planes at byte `offset` from the first plane row of
    /// `node` along an axis with slab slope `scale` and offset `shift`.
    ///
    /// # Safety
    /// The CPU must have AVX, FMA and SSE4.1 (and AVX2 if `AVX2`), and `offset` must be one of
    /// the six rows' (at most 40).
    #[inline(always)]
    unsafe fn slab<const AVX2: bool>(node: &CwBvhNode, offset: usize, scale: f32, shift: f32) -> __m256 {
        let offset = offset + super::FIRST_ROW;
        debug_assert!(offset + 8 <= size_of::<CwBvhNode>());
        let p = (node as *const CwBvhNode).cast::<u8>();
        // SAFETY: per the contract, the eight bytes read lie inside `*node` (unaligned loads)
        // and the intrinsics' features are present.
        unsafe {
            let q = if AVX2 {
                _mm256_cvtepu8_epi32(_mm_loadl_epi64(p.add(offset).cast()))
            } else {
                let lo = _mm_cvtepu8_epi32(_mm_cvtsi32_si128(p.add(offset).cast::<i32>().read_unaligned()));
                let hi =
                    _mm_cvtepu8_epi32(_mm_cvtsi32_si128(p.add(offset + 4).cast::<i32>().read_unaligned()));
                _mm256_insertf128_si256::<1>(_mm256_castsi128_si256(lo), hi)
            };
            _mm256_fmadd_ps(_mm256_cvtepi32_ps(q), _mm256_set1_ps(scale), _mm256_set1_ps(shift))
        }
    }

    /// The CWBVH node test.
    ///
    /// # Safety
    /// The CPU must have AVX, FMA and SSE4.1 (and AVX2 if `AVX2`).
    #[inline(always)]
    pub(super) unsafe fn cw_hits<const AVX2: bool>(
        node: &CwBvhNode,
        ray: &NodeRay,
        t_max: f32,
    ) -> (u32, [f32; 8]) {
        let (scale, shift) = node_frame(node, ray);
        let mut tnear = [0.0f32; 8];
        // SAFETY: the features are present per the contract; the plane offsets are the six
        // of `NodeRay`; the store writes 8 floats into `tnear`.
        let mask = unsafe {
            let t0 = _mm256_max_ps(
                _mm256_max_ps(
                    slab::<AVX2>(node, ray.near[0], scale.x, shift.x),
                    slab::<AVX2>(node, ray.near[1], scale.y, shift.y),
                ),
                _mm256_max_ps(slab::<AVX2>(node, ray.near[2], scale.z, shift.z), _mm256_set1_ps(ray.t_min)),
            );
            let t1 = _mm256_min_ps(
                _mm256_min_ps(
                    slab::<AVX2>(node, ray.far[0], scale.x, shift.x),
                    slab::<AVX2>(node, ray.far[1], scale.y, shift.y),
                ),
                _mm256_min_ps(slab::<AVX2>(node, ray.far[2], scale.z, shift.z), _mm256_set1_ps(t_max)),
            );
            _mm256_storeu_ps(tnear.as_mut_ptr(), t0);
            let hit = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t0, t1)) as u32;
            let meta = _mm_loadl_epi64(node.child_meta.as_ptr().cast());
            let empty = _mm_movemask_epi8(_mm_cmpeq_epi8(meta, _mm_setzero_si128())) as u32;
            hit & !empty & 0xff
        };
        (mask, tnear)
    }
}

/// A hint to load the cache line holding `x`.
#[inline(always)]
pub fn prefetch<T>(x: &T) {
    #[cfg(target_arch = "x86_64")]
    // SAFETY: a prefetch has no effect but on the cache, and SSE is part of x86-64.
    unsafe {
        use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
        _mm_prefetch::<_MM_HINT_T0>((x as *const T).cast());
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = x;
}

/// A hint to load every cache line of `nodes[index]` (nothing if out of range).
#[inline(always)]
fn prefetch_node<N>(nodes: &[N], index: u32) {
    if let Some(node) = nodes.get(index as usize) {
        let p = (node as *const N).cast::<u8>();
        let mut offset = 0;
        while offset < size_of::<N>() {
            #[cfg(target_arch = "x86_64")]
            // SAFETY: a prefetch has no effect but on the cache (it never faults), and SSE is
            // part of x86-64.
            unsafe {
                use std::arch::x86_64::{_MM_HINT_T0, _mm_prefetch};
                _mm_prefetch::<_MM_HINT_T0>(p.wrapping_add(offset).cast());
            }
            offset += 64;
        }
        #[cfg(not(target_arch = "x86_64"))]
        let _ = p;
    }
}

/// A traversal stack of (node, entry distance) pairs.
struct Stack<'a> {
    items: &'a mut [MaybeUninit<(u32, f32)>],
    len: usize,
}

impl Stack<'_> {
    #[inline(always)]
    fn push(&mut self, node: u32, t: f32) {
        self.items[self.len].write((node, t));
        self.len += 1;
    }

    #[inline(always)]
    fn pop(&mut self) -> Option<(u32, f32)> {
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: every slot below `len` was written by `push` before `len` passed it.
        Some(unsafe { self.items.get_unchecked(self.len).assume_init_read() })
    }
}

/// Which node test the traversal uses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(crate) enum Isa {
    Scalar,
    /// AVX, FMA, SSE4.1 and POPCNT.
    #[cfg(target_arch = "x86_64")]
    Avx,
    /// Those and AVX2 and BMI1.
    #[cfg(target_arch = "x86_64")]
    Avx2,
    /// Those and AVX-512F: AVX2's node tests; a flat mesh's 16 block boxes in one test.
    #[cfg(target_arch = "x86_64")]
    Avx512,
}

/// Environment variable that lowers the node test below the best the CPU has: `portable`,
/// `avx`, `avx2` or `avx512` (to compare them, or to rule one out); other values are ignored.
pub const ISA_VARIABLE: &str = "PROPSIM_TRAVERSAL";

impl Isa {
    /// The best node test the CPU has, or the one [`ISA_VARIABLE`] asks for if the CPU has it.
    fn chosen() -> Self {
        let best = Self::best();
        let asked = match std::env::var(ISA_VARIABLE).as_deref() {
            Ok("portable") => Some(Isa::Scalar),
            #[cfg(target_arch = "x86_64")]
            Ok("avx") => Some(Isa::Avx),
            #[cfg(target_arch = "x86_64")]
            Ok("avx2") => Some(Isa::Avx2),
            #[cfg(target_arch = "x86_64")]
            Ok("avx512") => Some(Isa::Avx512),
            _ => None,
        };
        asked.filter(|a| *a <= best).unwrap_or(best)
    }

    /// The best node test the CPU has.
    fn best() -> Self {
        #[cfg(target_arch = "x86_64")]
        {
            let avx = is_x86_feature_detected!("avx")
                && is_x86_feature_detected!("fma")
                && is_x86_feature_detected!("sse4.1")
                && is_x86_feature_detected!("popcnt");
            let avx2 = avx && is_x86_feature_detected!("avx2") && is_x86_feature_detected!("bmi1");
            if avx2 && is_x86_feature_detected!("avx512f") {
                Isa::Avx512
            } else if avx2 {
                Isa::Avx2
            } else if avx {
                Isa::Avx
            } else {
                Isa::Scalar
            }
        }
        #[cfg(not(target_arch = "x86_64"))]
        Isa::Scalar
    }
}

/// The traversal over a CWBVH's nodes: what a query needs besides the nodes themselves.
#[derive(Clone, Copy, Debug)]
pub struct Traverser {
    isa: Isa,
    /// Stack entries a traversal may need: up to 8 pushed per internal level.
    stack_len: usize,
    /// Whether batches go as streams: trees of at least [`STREAM_MIN_NODES`] nodes.
    stream: bool,
}

/// Nodes (80 B each, about 10 triangles a node) from which batch queries trace streams. A
/// smaller tree stays in the cache, where there is no memory latency to hide and a stream's
/// bookkeeping only costs. Measured (2 threads, single rays vs streams, Mrays/s closest
/// hit): a tree over the 36-triangle Cornell box 27.9 vs 22.6; generated terrains of 30k
/// triangles 9.35 vs 9.16 incoherent and 24.0 vs 19.7 coherent, of 100k triangles 5.2 vs
/// 7.1 incoherent.
pub const STREAM_MIN_NODES: usize = 1 << 13;

/// What a closest-hit traversal does at the leaves.
pub trait ClosestLeaves {
    /// Tests primitives `first..first + count` (leaf order), lowering `t_max` on a closer hit.
    fn test(&mut self, first: u32, count: u32, t_max: &mut f32);
    /// A hint that leaf `(first, count)` is tested next; loads it into the cache.
    fn prefetch(&self, _first: u32, _count: u32) {}
}

/// What an any-hit traversal does at the leaves.
pub trait AnyLeaves {
    /// Tests primitives `first..first + count`; returns true to stop the traversal.
    fn test(&mut self, first: u32, count: u32) -> bool;
    /// A hint that leaf `(first, count)` is tested next; loads it into the cache.
    fn prefetch(&self, _first: u32, _count: u32) {}
}

/// Primitive range `(first, count)` of leaf child `slot`.
#[inline(always)]
fn leaf_range(node: &CwBvhNode, slot: usize) -> (u32, u32) {
    let meta = node.child_meta[slot];
    (node.primitive_base_idx + u32::from(meta & 0b1_1111), (meta >> 5).count_ones())
}

/// Node index of internal child `slot`.
#[inline(always)]
fn child_index(node: &CwBvhNode, slot: usize) -> u32 {
    node.child_base_idx + (u32::from(node.imask) & ((1u32 << slot) - 1)).count_ones()
}

impl Traverser {
    /// The traversal of `nodes`, with the best node test this CPU has.
    pub fn new<N: WideBvhNode>(nodes: &[N]) -> Self {
        Self {
            isa: Isa::chosen(),
            stack_len: 8 * (depth(nodes) + 1),
            stream: nodes.len() >= STREAM_MIN_NODES && leaves_fit_stream_entries(nodes),
        }
    }

    /// This traversal with streams on or off whatever the tree's size: for tests.
    #[cfg(test)]
    pub(crate) fn with_streams(self, on: bool) -> Self {
        Self { stream: on, ..self }
    }

    /// Whether batches of rays should go as streams ([`STREAM_MIN_NODES`]).
    pub fn streams(&self) -> bool {
        self.stream
    }

    /// The instruction set this traversal uses.
    pub(crate) fn isa(&self) -> Isa {
        self.isa
    }

    /// Every traversal this CPU can run, the portable one first: for tests of one against
    /// the others.
    #[cfg(test)]
    pub(crate) fn all_available<N: WideBvhNode>(nodes: &[N]) -> Vec<Self> {
        let one = Self::new(nodes);
        let best = Isa::best();
        let mut all = vec![Self { isa: Isa::Scalar, ..one }];
        #[cfg(target_arch = "x86_64")]
        all.extend(
            [Isa::Avx, Isa::Avx2, Isa::Avx512]
                .into_iter()
                .filter(|i| *i <= best)
                .map(|isa| Self { isa, ..one }),
        );
        all
    }

    /// Runs `f` with a stack large enough for this tree.
    #[inline(always)]
    fn with_stack<R>(&self, f: impl FnOnce(Stack<'_>) -> R) -> R {
        if self.stack_len <= INLINE_STACK {
            let mut items = [const { MaybeUninit::uninit() }; INLINE_STACK];
            f(Stack { items: &mut items, len: 0 })
        } else {
            let mut items = vec![MaybeUninit::uninit(); self.stack_len];
            f(Stack { items: &mut items, len: 0 })
        }
    }

    /// Closest-hit traversal of `nodes` for `ray` up to `t_max`: `leaves` tests each
    /// leaf whose box the ray enters before the current closest distance, nearest boxes first.
    #[inline]
    pub fn closest<N: WideBvhNode>(
        &self,
        nodes: &[N],
        ray: &NodeRay,
        t_max: f32,
        leaves: &mut impl ClosestLeaves,
    ) {
        if nodes.is_empty() {
            return;
        }
        match self.isa {
            Isa::Scalar => self.with_stack(|s| closest_loop::<ScalarTest, N>(nodes, ray, t_max, leaves, s)),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx` is only chosen when the CPU has AVX, FMA, SSE4.1 and POPCNT.
            Isa::Avx => self.with_stack(|s| unsafe { closest_avx(nodes, ray, t_max, leaves, s) }),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx2` and `Isa::Avx512` are only chosen when the CPU has AVX2, FMA,
            // BMI1 and POPCNT.
            Isa::Avx2 | Isa::Avx512 => {
                self.with_stack(|s| unsafe { closest_avx2(nodes, ray, t_max, leaves, s) })
            }
        }
    }

    /// Any-hit traversal: `leaves` tests every leaf whose box the ray crosses on
    /// `(t_min, t_max]` until it returns true. Returns whether it did.
    #[inline]
    pub fn any<N: WideBvhNode>(
        &self,
        nodes: &[N],
        ray: &NodeRay,
        t_max: f32,
        leaves: &mut impl AnyLeaves,
    ) -> bool {
        if nodes.is_empty() {
            return false;
        }
        match self.isa {
            Isa::Scalar => self.with_stack(|s| any_loop::<ScalarTest, N>(nodes, ray, t_max, leaves, s)),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx` is only chosen when the CPU has AVX, FMA, SSE4.1 and POPCNT.
            Isa::Avx => self.with_stack(|s| unsafe { any_avx(nodes, ray, t_max, leaves, s) }),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx2` and `Isa::Avx512` are only chosen when the CPU has AVX2, FMA,
            // BMI1 and POPCNT.
            Isa::Avx2 | Isa::Avx512 => self.with_stack(|s| unsafe { any_avx2(nodes, ray, t_max, leaves, s) }),
        }
    }
}

impl Traverser {
    /// Runs `f` with [`STREAM_WIDTH`] stacks large enough for this tree.
    #[inline(always)]
    fn with_stacks<R>(&self, f: impl FnOnce(&mut [Stack<'_>; STREAM_WIDTH]) -> R) -> R {
        let mut items = vec![MaybeUninit::uninit(); STREAM_WIDTH * self.stack_len];
        let mut parts = items.chunks_mut(self.stack_len);
        let mut stacks: [Stack<'_>; STREAM_WIDTH] =
            std::array::from_fn(|_| Stack { items: parts.next().unwrap_or_default(), len: 0 });
        f(&mut stacks)
    }

    /// Closest-hit traversal of rays `0..count` as a stream (`closest_stream_loop`):
    /// `start(i)` gives ray `i`'s node constants, distance limit and leaf test, and
    /// `finish(i, leaves)` receives the leaf test back when ray `i` is done.
    pub fn closest_stream<N: WideBvhNode, V: ClosestLeaves>(
        &self,
        nodes: &[N],
        count: usize,
        mut start: impl FnMut(usize) -> (NodeRay, f32, V),
        mut finish: impl FnMut(usize, V),
    ) {
        if nodes.is_empty() {
            (0..count).for_each(|i| finish(i, start(i).2));
            return;
        }
        if !self.stream {
            for i in 0..count {
                let (ray, t_max, mut visitor) = start(i);
                self.closest(nodes, &ray, t_max, &mut visitor);
                finish(i, visitor);
            }
            return;
        }
        self.with_stacks(|stacks| match self.isa {
            Isa::Scalar => closest_stream_loop::<ScalarTest, N, V>(nodes, count, start, finish, stacks),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx` is only chosen when the CPU has AVX, FMA, SSE4.1 and POPCNT.
            Isa::Avx => unsafe { closest_stream_avx(nodes, count, start, finish, stacks) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx2` and `Isa::Avx512` are only chosen when the CPU has AVX2, FMA,
            // BMI1 and POPCNT.
            Isa::Avx2 | Isa::Avx512 => unsafe { closest_stream_avx2(nodes, count, start, finish, stacks) },
        })
    }
}

impl Traverser {
    /// Closest-hit traversal of rays `0..count` in groups of [`GROUP_WIDTH`] consecutive
    /// rays (`group`): `start(i)` gives ray `i`'s node constants, distance limit and leaf
    /// test, and `finish(i, leaves)` receives the leaf test back.
    pub fn closest_groups<V: ClosestLeaves>(
        &self,
        nodes: &[CwBvhNode],
        count: usize,
        mut start: impl FnMut(usize) -> (NodeRay, f32, V),
        mut finish: impl FnMut(usize, V),
    ) {
        if nodes.is_empty() {
            (0..count).for_each(|i| finish(i, start(i).2));
            return;
        }
        self.walk_groups::<V>(nodes, count, start, |g| g.leaf_tests(&mut finish));
    }

    /// The closest-hit group walk over `nodes` with this traversal's instruction set.
    fn walk_groups<V: ClosestLeaves>(
        &self,
        nodes: &[CwBvhNode],
        count: usize,
        start: impl FnMut(usize) -> (NodeRay, f32, V),
        done: impl FnMut(&mut group::Group<V>),
    ) {
        let mut groups: [group::Group<V>; group::GROUPS_IN_FLIGHT] =
            std::array::from_fn(|_| group::Group::new(self.stack_len));
        let g = &mut groups;
        match self.isa {
            Isa::Scalar => group::groups_loop::<group::EachRay<ScalarTest>, V>(nodes, count, start, done, g),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx` is only chosen when the CPU has AVX, FMA, SSE4.1 and POPCNT.
            Isa::Avx => unsafe { groups_avx::<V>(nodes, count, start, done, g) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx2` and `Isa::Avx512` are only chosen when the CPU has AVX2,
            // FMA, BMI1 and POPCNT.
            Isa::Avx2 | Isa::Avx512 => unsafe { groups_avx2::<V>(nodes, count, start, done, g) },
        }
    }
}

impl Traverser {
    /// Closest-hit walk of one group of at most [`GROUP_WIDTH`] rays over a tree that stays
    /// in the cache, the leaf test made for the whole group at once
    /// (`leaf(first, count, ray mask, t_max)`, see `group::walk_one_group`); `stack` is
    /// scratch space. The instanced batch query walks both levels this way.
    pub fn closest_one_group(
        &self,
        nodes: &[CwBvhNode],
        rays: &[NodeRay],
        t_max: &mut [f32],
        stack: &mut Vec<(u32, u32, f32)>,
        leaf: impl FnMut(u32, u32, u32, &mut [f32]),
    ) {
        match self.isa {
            Isa::Scalar => {
                group::walk_one_group::<group::EachRay<ScalarTest>>(nodes, rays, t_max, stack, leaf)
            }
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx` is only chosen when the CPU has AVX, FMA, SSE4.1 and POPCNT.
            Isa::Avx => unsafe { one_group_avx(nodes, rays, t_max, stack, leaf) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx2` and `Isa::Avx512` are only chosen when the CPU has AVX2,
            // FMA, BMI1 and POPCNT.
            Isa::Avx2 | Isa::Avx512 => unsafe { one_group_avx2(nodes, rays, t_max, stack, leaf) },
        }
    }
}

/// [`group::walk_one_group`] compiled for one instruction set.
macro_rules! one_group_entry_point {
    ($features:literal, $test:ty, $name:ident) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        fn $name(
            nodes: &[CwBvhNode],
            rays: &[NodeRay],
            t_max: &mut [f32],
            stack: &mut Vec<(u32, u32, f32)>,
            leaf: impl FnMut(u32, u32, u32, &mut [f32]),
        ) {
            group::walk_one_group::<$test>(nodes, rays, t_max, stack, leaf)
        }
    };
}

one_group_entry_point!("avx,fma,sse4.1,popcnt", group::EachRay<avx::AvxTest<false>>, one_group_avx);
one_group_entry_point!("avx2,fma,bmi1,popcnt", group::Avx2Group, one_group_avx2);

/// [`group::groups_loop`] compiled for one instruction set.
macro_rules! group_entry_point {
    ($features:literal, $test:ty, $name:ident) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        fn $name<V: ClosestLeaves>(
            nodes: &[CwBvhNode],
            count: usize,
            start: impl FnMut(usize) -> (NodeRay, f32, V),
            done: impl FnMut(&mut group::Group<V>),
            groups: &mut [group::Group<V>; group::GROUPS_IN_FLIGHT],
        ) {
            group::groups_loop::<$test, V>(nodes, count, start, done, groups)
        }
    };
}

group_entry_point!("avx,fma,sse4.1,popcnt", group::EachRay<avx::AvxTest<false>>, groups_avx);
group_entry_point!("avx2,fma,bmi1,popcnt", group::Avx2Group, groups_avx2);

impl Traverser {
    /// [`FlatTriangles::closest`], 8 lanes wide where the CPU has AVX.
    #[inline]
    pub fn flat_closest(
        &self,
        flat: &FlatTriangles,
        ray: &FlatRay,
        t_min: f32,
        t_max: f32,
    ) -> Option<(u32, f32, Vec2)> {
        match self.isa {
            Isa::Scalar => flat.closest(ray, t_min, t_max),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx` and `Isa::Avx2` are only chosen when the CPU has AVX.
            Isa::Avx | Isa::Avx2 => unsafe { super::flat::avx::closest(flat, ray, t_min, t_max) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx512` is only chosen when the CPU has AVX-512F (and AVX).
            Isa::Avx512 => unsafe { super::flat::avx::closest512(flat, ray, t_min, t_max) },
        }
    }

    /// [`FlatTriangles::any`], 8 lanes wide where the CPU has AVX.
    #[inline]
    pub fn flat_any(&self, flat: &FlatTriangles, ray: &FlatRay, t_min: f32, t_max: f32) -> bool {
        match self.isa {
            Isa::Scalar => flat.any(ray, t_min, t_max),
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx` and `Isa::Avx2` are only chosen when the CPU has AVX.
            Isa::Avx | Isa::Avx2 => unsafe { super::flat::avx::any(flat, ray, t_min, t_max) },
            #[cfg(target_arch = "x86_64")]
            // SAFETY: `Isa::Avx512` is only chosen when the CPU has AVX-512F (and AVX).
            Isa::Avx512 => unsafe { super::flat::avx::any512(flat, ray, t_min, t_max) },
        }
    }
}

/// The traversals (single rays, closest and any hit, and closest-hit streams) compiled for one
/// instruction set: `target_feature` entry points around the generic loops.
macro_rules! entry_points {
    ($features:literal, $test:ty, $closest:ident, $any:ident, $closest_stream:ident) => {
        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        fn $closest<N: WideBvhNode>(
            nodes: &[N],
            ray: &NodeRay,
            t_max: f32,
            leaves: &mut impl ClosestLeaves,
            stack: Stack<'_>,
        ) {
            closest_loop::<$test, N>(nodes, ray, t_max, leaves, stack);
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        fn $any<N: WideBvhNode>(
            nodes: &[N],
            ray: &NodeRay,
            t_max: f32,
            leaves: &mut impl AnyLeaves,
            stack: Stack<'_>,
        ) -> bool {
            any_loop::<$test, N>(nodes, ray, t_max, leaves, stack)
        }

        #[cfg(target_arch = "x86_64")]
        #[target_feature(enable = $features)]
        fn $closest_stream<N: WideBvhNode, V: ClosestLeaves>(
            nodes: &[N],
            count: usize,
            start: impl FnMut(usize) -> (NodeRay, f32, V),
            finish: impl FnMut(usize, V),
            stacks: &mut [Stack<'_>; STREAM_WIDTH],
        ) {
            closest_stream_loop::<$test, N, V>(nodes, count, start, finish, stacks);
        }
    };
}

entry_points!("avx,fma,sse4.1,popcnt", avx::AvxTest<false>, closest_avx, any_avx, closest_stream_avx);
entry_points!("avx2,fma,bmi1,popcnt", avx::AvxTest<true>, closest_avx2, any_avx2, closest_stream_avx2);

/// Prefetches the leaves and the internal children among the `hits` of `node`, so that their
/// loads overlap the leaf tests.
#[inline(always)]
fn prefetch_ahead<N: WideBvhNode>(nodes: &[N], node: &N, hits: u32, leaf: impl Fn(u32, u32)) {
    let imask = node.inner_mask();
    let mut ahead = hits;
    while ahead != 0 {
        let slot = ahead.trailing_zeros() as usize;
        ahead &= ahead - 1;
        if imask & (1 << slot) != 0 {
            prefetch_node(nodes, node.child(slot));
        } else {
            let (first, count) = node.leaf(slot);
            leaf(first, count);
        }
    }
}

/// Stack entries for leaves: the flag bit, the primitive count in bits 29-30 and the first
/// primitive below, so leaves and nodes share one distance-ordered stack.
const LEAF_FLAG: u32 = 1 << 31;
const LEAF_FIRST_MASK: u32 = (1 << 29) - 1;

/// The stack entry of child `slot` of `node` (whose inner mask is `imask`): its node index,
/// or for a leaf [`LEAF_FLAG`], the primitive count and the first primitive.
#[inline(always)]
fn item_id<N: WideBvhNode>(node: &N, imask: u32, slot: usize) -> u32 {
    if imask & (1 << slot) != 0 {
        node.child(slot)
    } else {
        let (first, count) = node.leaf(slot);
        LEAF_FLAG | count << 29 | first
    }
}

/// The primitive range `(first, count)` of a leaf's stack entry.
#[inline(always)]
fn leaf_of(id: u32) -> (u32, u32) {
    (id & LEAF_FIRST_MASK, (id >> 29) & 3)
}

/// Whether every leaf of `nodes` fits a stream's leaf stack entry (first primitive below
/// 2^29, about 540 million triangles); streams are off for trees that do not.
fn leaves_fit_stream_entries<N: WideBvhNode>(nodes: &[N]) -> bool {
    nodes.iter().all(|n| {
        let leaves = n.occupied_mask() & !n.inner_mask();
        (0..8).filter(|s| leaves & (1 << s) != 0).all(|s| n.leaf(s).0 <= LEAF_FIRST_MASK)
    })
}

/// Where one ray's traversal stands between steps: the node to visit next and the distance
/// limit (the closest hit so far, for closest-hit queries).
#[derive(Clone, Copy, Debug)]
struct Cursor {
    current: u32,
    t_max: f32,
}

/// One step of a stream's closest-hit traversal: tests the leaf or visits the node
/// `c.current` (pushing its hit children, leaves and nodes alike, farthest first), then pops
/// the next item entered before the closest hit so far. Returns false when the ray is done.
/// Leaves are tested in the same nearest-first order as nodes are entered, so a near hit
/// culls the farther leaves and subtrees alike; each step touches one item, whose data the
/// stream prefetches while it steps the other rays. (Prefetching all of a node's hits as
/// well, as single rays do, only cost: on the 1M-triangle benchmark's coherent rays that
/// hit, 12 % faster without, and 11-19 % fewer instructions a ray.)
#[inline(always)]
fn closest_step<T: NodeTest, N: WideBvhNode>(
    nodes: &[N],
    ray: &NodeRay,
    c: &mut Cursor,
    visitor: &mut impl ClosestLeaves,
    stack: &mut Stack<'_>,
) -> bool {
    if c.current & LEAF_FLAG != 0 {
        let (first, count) = leaf_of(c.current);
        visitor.test(first, count, &mut c.t_max);
    } else {
        let node = &nodes[c.current as usize];
        let (hits, tnear) = T::hits(node, ray, c.t_max);
        let imask = node.inner_mask();
        let item = |slot: usize| (item_id(node, imask, slot), tnear[slot]);
        // The nearest item is next (what a push and a pop would give: it is entered before
        // `t_max`); the others go on the stack, farthest first. One or two hits, the common
        // cases, take no sorting loop.
        match hits.count_ones() {
            0 => {}
            1 => {
                c.current = item(hits.trailing_zeros() as usize).0;
                return true;
            }
            2 => {
                let a = item(hits.trailing_zeros() as usize);
                let b = item((31 - hits.leading_zeros()) as usize);
                let (far, near) = if a.1 < b.1 { (b, a) } else { (a, b) };
                stack.push(far.0, far.1);
                c.current = near.0;
                return true;
            }
            _ => {
                c.current = push_all_but_nearest(hits, item, stack);
                return true;
            }
        }
    }
    loop {
        match stack.pop() {
            None => return false,
            Some((id, t)) if t <= c.t_max => {
                c.current = id;
                return true;
            }
            Some(_) => {}
        }
    }
}

/// Sorts the items `item(slot)` (id, entry distance) of the slots in `mask` (at least two)
/// by distance, pushes all but the nearest, farthest first, and returns the nearest's id,
/// to be visited next.
#[inline(always)]
fn push_all_but_nearest(mask: u32, item: impl Fn(usize) -> (u32, f32), stack: &mut Stack<'_>) -> u32 {
    let (order, n) = far_to_near(mask, item);
    for &(id, t) in &order[..n - 1] {
        stack.push(id, t);
    }
    order[n - 1].0
}

/// The items `item(slot)` (anything, entry distance) of the slots in `mask`, sorted
/// farthest first by insertion, and their count. Ties keep slot order (the later slot
/// counts as nearer).
#[inline(always)]
fn far_to_near<T: Copy + Default>(mask: u32, item: impl Fn(usize) -> (T, f32)) -> ([(T, f32); 8], usize) {
    let n = mask.count_ones() as usize;
    let mut order = [(T::default(), 0.0f32); 8];
    let mut rest = mask;
    for k in 0..n {
        let slot = rest.trailing_zeros() as usize;
        rest &= rest - 1;
        let item = item(slot);
        let mut j = k;
        while j > 0 && order[j - 1].1 < item.1 {
            order[j] = order[j - 1];
            j -= 1;
        }
        order[j] = item;
    }
    (order, n)
}

/// Starts loading the leaf or node that a cursor will visit next.
#[inline(always)]
fn prefetch_item<N: WideBvhNode>(nodes: &[N], id: u32, leaf: impl Fn(u32, u32)) {
    if id & LEAF_FLAG != 0 {
        let (first, count) = leaf_of(id);
        leaf(first, count);
    } else {
        prefetch_node(nodes, id);
    }
}

/// The set bit of `mask` (not zero) with the smallest `distance`; the lowest bit on ties.
#[inline(always)]
pub(crate) fn nearest<const N: usize>(mask: u32, distance: &[f32; N]) -> usize {
    let mut best = mask.trailing_zeros() as usize;
    let mut rest = mask & (mask - 1);
    while rest != 0 {
        let s = rest.trailing_zeros() as usize;
        rest &= rest - 1;
        if distance[s] < distance[best] {
            best = s;
        }
    }
    best
}

#[inline(always)]
fn closest_loop<T: NodeTest, N: WideBvhNode>(
    nodes: &[N],
    ray: &NodeRay,
    mut t_max: f32,
    visitor: &mut impl ClosestLeaves,
    mut stack: Stack<'_>,
) {
    let mut current = 0u32;
    loop {
        let node = &nodes[current as usize];
        let (hits, tnear) = T::hits(node, ray, t_max);
        let imask = node.inner_mask();
        let mut leaves = hits & !imask;
        prefetch_ahead(nodes, node, hits, |first, count| visitor.prefetch(first, count));
        let entry_t_max = t_max;
        while leaves != 0 {
            // Nearest leaf first, so that a hit culls the farther ones.
            let slot = nearest(leaves, &tnear);
            leaves &= !(1 << slot);
            // A leaf entered beyond a hit found in a sibling leaf cannot hold a closer one.
            if tnear[slot] <= t_max {
                let (first, count) = node.leaf(slot);
                visitor.test(first, count, &mut t_max);
            }
        }
        let mut inner = hits & imask;
        if t_max < entry_t_max {
            // Drop the children now entered beyond the closest hit.
            let mut m = inner;
            while m != 0 {
                let slot = m.trailing_zeros() as usize;
                m &= m - 1;
                if tnear[slot] > t_max {
                    inner &= !(1 << slot);
                }
            }
        }
        match inner.count_ones() {
            0 => {}
            1 => {
                current = node.child(inner.trailing_zeros() as usize);
                continue;
            }
            _ => {
                current = push_all_but_nearest(inner, |slot| (node.child(slot), tnear[slot]), &mut stack);
                continue;
            }
        }
        loop {
            match stack.pop() {
                None => return,
                Some((c, t)) if t <= t_max => {
                    current = c;
                    break;
                }
                Some(_) => {}
            }
        }
    }
}

#[inline(always)]
fn any_loop<T: NodeTest, N: WideBvhNode>(
    nodes: &[N],
    ray: &NodeRay,
    t_max: f32,
    visitor: &mut impl AnyLeaves,
    mut stack: Stack<'_>,
) -> bool {
    let mut current = 0u32;
    loop {
        let node = &nodes[current as usize];
        let (hits, _) = T::hits(node, ray, t_max);
        let imask = node.inner_mask();
        let mut leaves = hits & !imask;
        prefetch_ahead(nodes, node, hits, |first, count| visitor.prefetch(first, count));
        while leaves != 0 {
            let slot = leaves.trailing_zeros() as usize;
            leaves &= leaves - 1;
            let (first, count) = node.leaf(slot);
            if visitor.test(first, count) {
                return true;
            }
        }
        let mut inner = hits & imask;
        if inner == 0 {
            match stack.pop() {
                None => return false,
                Some((c, _)) => current = c,
            }
            continue;
        }
        current = node.child(inner.trailing_zeros() as usize);
        inner &= inner - 1;
        while inner != 0 {
            let slot = inner.trailing_zeros() as usize;
            inner &= inner - 1;
            stack.push(node.child(slot), 0.0);
        }
    }
}

/// Rays a stream traversal keeps in flight on one thread: enough independent loads to keep
/// the memory busy. Measured on the 1M-triangle benchmark (2 threads, Mrays/s closest hit /
/// occlusion, alternating rounds): 16 against 8 gave 8.9 / 11.3 against 7.8 / 9.5 on
/// incoherent rays and 6.9 / 8.7 against 6.4 / 7.9 on the coherent rays that hit; 24 and 32
/// were slower on incoherent rays.
pub const STREAM_WIDTH: usize = 16;

/// One ray in flight in a stream traversal: its index, node constants, cursor and leaf test.
type InFlight<V> = (usize, NodeRay, Cursor, V);

/// Takes the next ray of the stream into an empty lane.
#[inline(always)]
fn refill<V>(
    lane: &mut Option<InFlight<V>>,
    stack: &mut Stack<'_>,
    next: &mut usize,
    count: usize,
    start: &mut impl FnMut(usize) -> (NodeRay, f32, V),
) {
    if lane.is_none() && *next < count {
        let (ray, t_max, visitor) = start(*next);
        *lane = Some((*next, ray, Cursor { current: 0, t_max }, visitor));
        stack.len = 0;
        *next += 1;
    }
}

/// The closest-hit traversal of rays `0..count`, [`STREAM_WIDTH`] in flight, interleaved one
/// node step each: while one ray waits for its next node from memory, the others work, and
/// the node each ray will visit next is prefetched when it is chosen (software pipelining,
/// as in the stream tracers of Wald et al. 2014 and Barringer & Akenine-Möller 2014). Each
/// ray takes exactly the steps of its single-ray traversal, so results are the same.
#[inline(always)]
fn closest_stream_loop<T: NodeTest, N: WideBvhNode, V: ClosestLeaves>(
    nodes: &[N],
    count: usize,
    mut start: impl FnMut(usize) -> (NodeRay, f32, V),
    mut finish: impl FnMut(usize, V),
    stacks: &mut [Stack<'_>; STREAM_WIDTH],
) {
    let mut lanes: [Option<InFlight<V>>; STREAM_WIDTH] = std::array::from_fn(|_| None);
    let mut next = 0;
    loop {
        let mut busy = false;
        for (lane, stack) in lanes.iter_mut().zip(stacks.iter_mut()) {
            refill(lane, stack, &mut next, count, &mut start);
            let Some((_, ray, cursor, visitor)) = lane else { continue };
            busy = true;
            if closest_step::<T, N>(nodes, ray, cursor, visitor, stack) {
                prefetch_item(nodes, cursor.current, |first, count| visitor.prefetch(first, count));
            } else if let Some((i, _, _, visitor)) = lane.take() {
                finish(i, visitor);
            }
        }
        if !busy {
            return;
        }
    }
}

/// The `(first, count)` primitive ranges of all leaves, in primitive order.
pub fn leaf_ranges<N: WideBvhNode + Sync>(nodes: &[N]) -> Vec<(u32, u32)> {
    use rayon::prelude::*;
    let mut leaves: Vec<(u32, u32)> = nodes
        .par_iter()
        .flat_map_iter(|n| {
            let (inner, hit) = (n.inner_mask(), n.occupied_mask());
            (0..8).filter(move |&slot| hit & !inner & (1 << slot) != 0).map(|slot| n.leaf(slot))
        })
        .collect();
    // The collapse emits leaves in primitive order already; other trees may not.
    if !leaves.is_sorted() {
        leaves.par_sort_unstable();
    }
    leaves
}

/// Levels of the tree below the root (0 for a root whose children are all leaves).
fn depth<N: WideBvhNode>(nodes: &[N]) -> usize {
    if nodes.is_empty() {
        return 0;
    }
    // Children are stored after their parent, so one backward pass sees children first.
    let mut below = vec![0u32; nodes.len()];
    for i in (0..nodes.len()).rev() {
        let n = &nodes[i];
        let mut inner = n.inner_mask();
        let mut d = 0;
        while inner != 0 {
            let slot = inner.trailing_zeros() as usize;
            inner &= inner - 1;
            d = d.max(below.get(n.child(slot) as usize).map_or(0, |b| b + 1));
        }
        below[i] = d;
    }
    below[0] as usize
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn leaves_beyond_the_stream_entry_range_turn_streams_off() {
        // One leaf of one triangle in slot 0, starting at primitive `first`.
        let node = |first: u32| CwBvhNode {
            primitive_base_idx: first,
            child_meta: [0b0010_0000, 0, 0, 0, 0, 0, 0, 0],
            ..Default::default()
        };
        assert!(leaves_fit_stream_entries(&[node(0), node(LEAF_FIRST_MASK)]));
        assert!(!leaves_fit_stream_entries(&[node(0), node(LEAF_FIRST_MASK + 1)]));
        assert_eq!(node(7).leaf(0), (7, 1));
    }
}
