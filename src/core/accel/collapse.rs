//! The collapse of a binary BVH into a CWBVH (Ylitie, Karras, Laine 2017, "Efficient
//! Incoherent Ray Traversal on GPUs Through Compressed Wide BVHs", sec. 4.1): a dynamic
//! programme picks, for every binary node, the SAH-cheapest way to spread up to eight subtrees
//! over a wide node's slots, then a top-down pass emits and quantises the wide nodes.
//!
//! It follows obvhs' `bvh2_to_cwbvh` step by step (same costs, same ties), with two changes:
//! the cost pass runs in parallel (rayon) and returns the costs up the recursion, so only the
//! decisions are stored, packed in 8 bytes a binary node instead of 56. Each cost depends only
//! on its subtree, so the result is the same whatever the thread count.

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use glam::Vec3A;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::cwbvh::node::CwBvhNode;
use rayon::prelude::*;

/// SAH cost of a primitive relative to a node visit (obvhs' value).
const PRIM_COST: f32 = 0.3;
/// Quantisation steps of a child box along an axis.
const DENOM: f32 = 1.0 / 255.0;
/// Binary-tree levels whose two subtrees are costed in parallel.
const PARALLEL_LEVELS: u32 = 10;

/// Decision kinds: a binary node becomes a leaf, a wide node, or spreads its subtrees over
/// its parent's slots.
const LEAF: u8 = 0;
const INTERNAL: u8 = 1;
const DISTRIBUTE: u8 = 2;

/// Decision `i` (for `i + 1` slots) of a binary node: kind, and how many slots minus one go
/// to the left and right children when it distributes.
#[inline]
fn pack(kind: u8, left: usize, right: usize) -> u8 {
    kind | (left as u8) << 2 | (right as u8) << 5
}

#[inline]
fn unpack(decisions: &[AtomicU64], node: usize, i: usize) -> (u8, usize, usize) {
    let d = (decisions[node].load(Relaxed) >> (8 * i)) as u8;
    (d & 3, usize::from(d >> 2 & 7), usize::from(d >> 5))
}

/// The SAH costs of `n`'s subtree spread over 1..=7 slots, and its primitive count; stores
/// the decisions of `n` and below.
fn cost(
    nodes: &[Bvh2Node],
    decisions: &[AtomicU64],
    n: usize,
    max_prims: u32,
    level: u32,
) -> ([f32; 7], u32) {
    let node = &nodes[n];
    let half_area = node.aabb().half_area();
    if node.is_leaf() {
        assert_eq!(node.prim_count, 1, "the collapse expects one primitive per binary leaf");
        decisions[n].store(0, Relaxed);
        return ([half_area * PRIM_COST; 7], 1);
    }
    let (a, b) = (node.first_index as usize, node.first_index as usize + 1);
    let ((ca, pa), (cb, pb)) = if level < PARALLEL_LEVELS {
        rayon::join(
            || cost(nodes, decisions, a, max_prims, level + 1),
            || cost(nodes, decisions, b, max_prims, level + 1),
        )
    } else {
        (cost(nodes, decisions, a, max_prims, level + 1), cost(nodes, decisions, b, max_prims, level + 1))
    };
    let prims = pa + pb;
    let mut costs = [0.0f32; 7];
    let mut packed = [0u8; 7];
    // One slot: a leaf, or a wide node whose children spread over 8 slots.
    let cost_leaf = if prims <= max_prims { prims as f32 * half_area * PRIM_COST } else { f32::INFINITY };
    let (mut cost_spread, mut left, mut right) = (f32::INFINITY, 0, 0);
    for k in 0..7 {
        let c = ca[k] + cb[6 - k];
        if c < cost_spread {
            (cost_spread, left, right) = (c, k, 6 - k);
        }
    }
    let cost_internal = cost_spread + half_area;
    let kind = if cost_leaf < cost_internal { LEAF } else { INTERNAL };
    costs[0] = cost_leaf.min(cost_internal);
    packed[0] = pack(kind, left, right);
    // i + 1 slots: as with i slots, or spread over the two children.
    for i in 1..7 {
        let mut best = costs[i - 1];
        let mut spread = None;
        for k in 0..i {
            let c = ca[k] + cb[i - k - 1];
            if c < best {
                best = c;
                spread = Some((k, i - k - 1));
            }
        }
        costs[i] = best;
        packed[i] = match spread {
            Some((l, r)) => pack(DISTRIBUTE, l, r),
            None => packed[i - 1],
        };
    }
    let word = packed.iter().enumerate().fold(0u64, |w, (i, &d)| w | u64::from(d) << (8 * i));
    decisions[n].store(word, Relaxed);
    (costs, prims)
}

/// The top-down emission of the wide nodes, in obvhs' layout: the internal children of a node
/// are contiguous from `child_base_idx`, its leaves' primitives from `primitive_base_idx`.
struct Emit<'a> {
    nodes: &'a [Bvh2Node],
    decisions: &'a [AtomicU64],
    order: &'a [u32],
    out: Vec<CwBvhNode>,
    prims: Vec<u32>,
}

impl Emit<'_> {
    /// The binary nodes that fill the slots of `n` with decision `i`.
    fn children(&self, n: usize, i: usize, children: &mut [usize; 8], count: &mut usize) {
        let node = &self.nodes[n];
        if node.is_leaf() {
            children[*count] = n;
            *count += 1;
            return;
        }
        let (_, left, right) = unpack(self.decisions, n, i);
        for (c, d) in [(node.first_index as usize, left), (node.first_index as usize + 1, right)] {
            if unpack(self.decisions, c, d).0 == DISTRIBUTE {
                self.children(c, d, children, count);
            } else {
                children[*count] = c;
                *count += 1;
            }
        }
    }

    /// Appends the primitives under `n`, left to right; returns their count.
    fn push_primitives(&mut self, n: usize) -> u32 {
        let node = &self.nodes[n];
        if node.is_leaf() {
            self.prims.push(self.order[node.first_index as usize]);
            return 1;
        }
        let first = node.first_index as usize;
        self.push_primitives(first) + self.push_primitives(first + 1)
    }

    /// Fills wide node `at` from binary node `n`, then its internal children.
    fn emit(&mut self, at: usize, n: usize) {
        let aabb = *self.nodes[n].aabb();
        let mut node = CwBvhNode { p: aabb.min.into(), ..Default::default() };
        let extent = (aabb.max - aabb.min).max(Vec3A::splat(1e-20)) * DENOM;
        let e = extent.to_array().map(|x| x.log2().ceil().exp2());
        let rcp_e = Vec3A::from_array(e.map(|x| 1.0 / x));
        node.e = e.map(|x| (x.to_bits() >> 23) as u8);
        let (mut children, mut count) = ([0usize; 8], 0);
        self.children(n, 0, &mut children, &mut count);
        node.primitive_base_idx = self.prims.len() as u32;
        node.child_base_idx = self.out.len() as u32;
        let (mut internal, mut prims) = (0, 0u32);
        let p = Vec3A::from(node.p);
        for (i, &c) in children[..count].iter().enumerate() {
            let b = self.nodes[c].aabb();
            let lo = ((b.min - p) * rcp_e).floor().clamp(Vec3A::ZERO, Vec3A::splat(255.0));
            let hi = ((b.max - p) * rcp_e).ceil().clamp(Vec3A::ZERO, Vec3A::splat(255.0));
            node.child_min_x[i] = lo.x as u8;
            node.child_min_y[i] = lo.y as u8;
            node.child_min_z[i] = lo.z as u8;
            node.child_max_x[i] = hi.x as u8;
            node.child_max_y[i] = hi.y as u8;
            node.child_max_z[i] = hi.z as u8;
            if unpack(self.decisions, c, 0).0 == LEAF {
                let k = self.push_primitives(c);
                debug_assert!((1..=3).contains(&k));
                node.child_meta[i] = prims as u8 | [0, 0b0010_0000, 0b0110_0000, 0b1110_0000][k as usize];
                prims += k;
            } else {
                node.imask |= 1 << i;
                node.child_meta[i] = (24 + i as u8) | 0b0010_0000;
                internal += 1;
            }
        }
        self.out.resize(self.out.len() + internal, CwBvhNode::default());
        self.out[at] = node;
        let mut next = node.child_base_idx as usize;
        for (i, &c) in children[..count].iter().enumerate() {
            if node.imask & (1 << i) != 0 {
                self.emit(next, c);
                next += 1;
            }
        }
    }
}

/// The CWBVH nodes of `bvh2` (one primitive per binary leaf) with at most `max_prims`
/// (1..=3) primitives a leaf, and the primitive indices in leaf order.
pub fn collapse(bvh2: &Bvh2, max_prims: u32) -> (Vec<CwBvhNode>, Vec<u32>) {
    if bvh2.nodes.is_empty() {
        return (Vec::new(), Vec::new());
    }
    let decisions: Vec<AtomicU64> =
        (0..bvh2.nodes.len()).into_par_iter().map(|_| AtomicU64::new(0)).collect();
    cost(&bvh2.nodes, &decisions, 0, max_prims.clamp(1, 3), 0);
    let prims = bvh2.primitive_indices.len();
    let mut emit = Emit {
        nodes: &bvh2.nodes,
        decisions: &decisions,
        order: &bvh2.primitive_indices,
        out: Vec::with_capacity(prims / 4 + 1),
        prims: Vec::with_capacity(prims),
    };
    emit.out.push(CwBvhNode::default());
    emit.emit(0, 0);
    (emit.out, emit.prims)
}
