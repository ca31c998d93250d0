//! The collapse of a binary BVH into a CWBVH (Ylitie, Karras, Laine 2017, "Efficient
//! Incoherent Ray Traversal on GPUs Through Compressed Wide BVHs", sec. 4.1): a dynamic
//! programme picks, for every binary node, the SAH-cheapest way to spread up to eight subtrees
//! over a wide node's slots, then a top-down pass emits and quantises the wide nodes.
//!
//! It follows obvhs' `bvh2_to_cwbvh` step by step (same costs, same ties, same node layout),
//! with four changes: the cost pass runs in parallel (rayon) and returns the costs up the
//! walk, so only the decisions are stored, packed in 8 bytes a binary node instead of
//! 56; both passes walk an 8-byte copy of the binary nodes and prefetch a level ahead; and
//! the emission's top levels emit their subtrees in parallel and splice them in order. Each
//! cost depends only on its subtree and each part lands where the sequential pass puts it,
//! so the result is the same whatever the thread count.

use std::sync::atomic::{AtomicU64, Ordering::Relaxed};

use glam::Vec3A;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::cwbvh::node::CwBvhNode;
use rayon::prelude::*;

use crate::core::traverse::prefetch;

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

/// What the passes walk of a binary node, in 8 bytes instead of 48: the half area of its
/// box, and its first child, or with [`LEAF_BIT`] its primitive's slot. Siblings are
/// adjacent, and so are the pairs PLOC merged in one pass, so a depth-first walk finds more
/// of what it needs in each cache line (cost pass 55 -> 37 ms on 1M triangles, 2 threads).
#[derive(Clone, Copy, Default)]
struct WalkNode {
    half_area: f32,
    first: u32,
}

/// Marks a leaf in [`WalkNode::first`].
const LEAF_BIT: u32 = 1 << 31;

impl WalkNode {
    fn new(node: &Bvh2Node) -> Self {
        assert!(
            !node.is_leaf() || node.prim_count == 1,
            "the collapse expects one primitive per binary leaf"
        );
        let leaf = if node.is_leaf() { LEAF_BIT } else { 0 };
        Self { half_area: node.aabb().half_area(), first: node.first_index | leaf }
    }

    #[inline(always)]
    fn is_leaf(self) -> bool {
        self.first & LEAF_BIT != 0
    }

    /// The first child, or a leaf's primitive slot.
    #[inline(always)]
    fn index(self) -> usize {
        (self.first & !LEAF_BIT) as usize
    }
}

/// Starts loading the children of the children of binary node `n` (whose own children are
/// loaded): the tree is walked depth first over nodes scattered through memory, so each
/// level's loads are issued one level ahead and overlap the work on the sibling subtree.
/// The cost pass was waiting on these loads half of its time.
#[inline(always)]
fn prefetch_grandchildren(nodes: &[WalkNode], n: WalkNode) {
    if n.is_leaf() {
        return;
    }
    let first = n.index();
    for c in [first, first + 1] {
        if let Some(child) = nodes.get(c)
            && !child.is_leaf()
            && let Some(grandchild) = nodes.get(child.index())
        {
            prefetch(grandchild);
        }
    }
}

/// The costs of a subtree spread over 1..=7 slots, and its primitive count.
type Costs = ([f32; 7], u32);

/// The SAH costs of `n`'s subtree spread over 1..=7 slots, and its primitive count; stores
/// the decisions of `n` and below. The top [`PARALLEL_LEVELS`] levels recurse (costing their
/// two subtrees in parallel); below them [`cost_below`] walks the subtrees with an explicit
/// stack, so the call depth stays within `PARALLEL_LEVELS` + 1 however deep the tree.
fn cost(nodes: &[WalkNode], decisions: &[AtomicU64], n: usize, max_prims: u32, level: u32) -> Costs {
    let node = nodes[n];
    if level >= PARALLEL_LEVELS || node.is_leaf() {
        return cost_below(nodes, decisions, n, max_prims);
    }
    prefetch_grandchildren(nodes, node);
    let (a, b) = (node.index(), node.index() + 1);
    let (left, right) = rayon::join(
        || cost(nodes, decisions, a, max_prims, level + 1),
        || cost(nodes, decisions, b, max_prims, level + 1),
    );
    combine(decisions, n, node.half_area, left, right, max_prims)
}

/// [`cost`] of the subtree at `root` on one thread, depth first (left, right, then the node)
/// with an explicit stack.
fn cost_below(nodes: &[WalkNode], decisions: &[AtomicU64], root: usize, max_prims: u32) -> Costs {
    // (node, its children are done); the costs of finished subtrees, innermost last.
    let mut todo: Vec<(usize, bool)> = vec![(root, false)];
    let mut done: Vec<Costs> = Vec::new();
    while let Some((n, children_done)) = todo.pop() {
        let node = nodes[n];
        if node.is_leaf() {
            decisions[n].store(0, Relaxed);
            done.push(([node.half_area * PRIM_COST; 7], 1));
        } else if children_done {
            let (Some(right), Some(left)) = (done.pop(), done.pop()) else {
                unreachable!("both subtrees of a binary node are costed before it")
            };
            done.push(combine(decisions, n, node.half_area, left, right, max_prims));
        } else {
            prefetch_grandchildren(nodes, node);
            todo.push((n, true));
            todo.push((node.index() + 1, false));
            todo.push((node.index(), false));
        }
    }
    done.pop().unwrap_or(([0.0; 7], 0))
}

/// The costs of binary node `n` (of half area `half_area`) from those of its children;
/// stores its decisions.
#[inline(always)]
fn combine(
    decisions: &[AtomicU64],
    n: usize,
    half_area: f32,
    (ca, pa): Costs,
    (cb, pb): Costs,
    max_prims: u32,
) -> Costs {
    let prims = pa + pb;
    // spread[j]: the cheapest split of j + 2 slots between the children (ca[k] + cb[j - k]),
    // and the first k that gives it. Branch-free: which split wins is not predictable.
    let mut spread = [f32::INFINITY; 7];
    let mut spread_k = [0usize; 7];
    for k in 0..7 {
        for j in k..7 {
            let c = ca[k] + cb[j - k];
            let better = c < spread[j];
            spread[j] = if better { c } else { spread[j] };
            spread_k[j] = if better { k } else { spread_k[j] };
        }
    }
    let mut costs = [0.0f32; 7];
    let mut packed = [0u8; 7];
    // One slot: a leaf, or a wide node whose children spread over 8 slots.
    let cost_leaf = if prims <= max_prims { prims as f32 * half_area * PRIM_COST } else { f32::INFINITY };
    let (left, right) = (spread_k[6], 6 - spread_k[6]);
    let cost_internal = spread[6] + half_area;
    let kind = if cost_leaf < cost_internal { LEAF } else { INTERNAL };
    costs[0] = cost_leaf.min(cost_internal);
    packed[0] = pack(kind, left, right);
    // i + 1 slots: as with i slots, or spread over the two children.
    for i in 1..7 {
        let (c, k) = (spread[i - 1], spread_k[i - 1]);
        let better = c < costs[i - 1];
        costs[i] = if better { c } else { costs[i - 1] };
        packed[i] = if better { pack(DISTRIBUTE, k, i - k - 1) } else { packed[i - 1] };
    }
    let word = packed.iter().enumerate().fold(0u64, |w, (i, &d)| w | u64::from(d) << (8 * i));
    decisions[n].store(word, Relaxed);
    (costs, prims)
}

/// The top-down emission of the wide nodes, in obvhs' layout: the internal children of a node
/// are contiguous from `child_base_idx`, its leaves' primitives from `primitive_base_idx`.
struct Emit<'a> {
    nodes: &'a [Bvh2Node],
    walk: &'a [WalkNode],
    decisions: &'a [AtomicU64],
    order: &'a [u32],
    out: Vec<CwBvhNode>,
    prims: Vec<u32>,
}

impl Emit<'_> {
    /// Starts loading the children of binary node `n` and their decisions: the emission, too,
    /// walks nodes scattered through memory.
    #[inline(always)]
    fn prefetch_children(&self, n: usize) {
        let node = self.walk[n];
        if node.is_leaf() {
            return;
        }
        let first = node.index();
        // A pair of 48-byte nodes may span two cache lines.
        if let (Some(a), Some(b), Some(w), Some(d)) = (
            self.nodes.get(first),
            self.nodes.get(first + 1),
            self.walk.get(first),
            self.decisions.get(first),
        ) {
            prefetch(a);
            prefetch(b);
            prefetch(w);
            prefetch(d);
        }
    }

    /// The binary nodes that fill the slots of `n` with decision `i`. Recurses at most 7 deep:
    /// each level spreads fewer slots than the one above.
    fn children(&self, n: usize, i: usize, children: &mut [usize; 8], count: &mut usize) {
        let node = self.walk[n];
        if node.is_leaf() {
            children[*count] = n;
            *count += 1;
            return;
        }
        let first = node.index();
        self.prefetch_children(first);
        self.prefetch_children(first + 1);
        let (_, left, right) = unpack(self.decisions, n, i);
        for (c, d) in [(first, left), (first + 1, right)] {
            if unpack(self.decisions, c, d).0 == DISTRIBUTE {
                self.children(c, d, children, count);
            } else {
                children[*count] = c;
                *count += 1;
            }
        }
    }

    /// Appends the primitives under `n`, left to right; returns their count. Called on leaf
    /// decisions only (at most 3 primitives), so it recurses at most 2 deep.
    fn push_primitives(&mut self, n: usize) -> u32 {
        let node = self.walk[n];
        if node.is_leaf() {
            self.prims.push(self.order[node.index()]);
            return 1;
        }
        let first = node.index();
        self.push_primitives(first) + self.push_primitives(first + 1)
    }

    /// Fills wide node `at` from binary node `n` and appends its leaves' primitives; reserves
    /// the slots of its internal children and returns them, binary node per slot in order.
    fn node(&mut self, at: usize, n: usize) -> Internal {
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
        let mut internal = Internal::default();
        let mut prims = 0u32;
        let p = Vec3A::from(node.p);
        // The next loads: the leaves' primitives and the internal children's own children.
        for &c in &children[..count] {
            self.prefetch_children(c);
        }
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
                internal.nodes[internal.count] = c;
                internal.count += 1;
            }
        }
        self.out.resize(self.out.len() + internal.count, CwBvhNode::default());
        self.out[at] = node;
        internal
    }

    /// Fills wide node `at` from binary node `n`, then its internal children, depth first in
    /// slot order, with an explicit stack (a degenerate tree may be thousands of levels deep).
    fn emit(&mut self, at: usize, n: usize) {
        let mut todo: Vec<(usize, usize)> = vec![(at, n)];
        while let Some((at, n)) = todo.pop() {
            let internal = self.node(at, n);
            let first = self.out[at].child_base_idx as usize;
            let children = internal.nodes[..internal.count].iter().enumerate();
            todo.extend(children.rev().map(|(k, &c)| (first + k, c)));
        }
    }

    /// Emits the wide subtree rooted at binary node `n` on its own, as a [`Part`]. The top
    /// [`PARALLEL_EMIT_LEVELS`] levels emit their children's subtrees in parallel and splice
    /// them in, which gives the same nodes as one sequential pass.
    fn part(&self, n: usize, level: u32) -> Part {
        let mut emit = Emit {
            nodes: self.nodes,
            walk: self.walk,
            decisions: self.decisions,
            order: self.order,
            out: vec![CwBvhNode::default()],
            prims: Vec::new(),
        };
        if level >= PARALLEL_EMIT_LEVELS {
            emit.emit(0, n);
            return Part { nodes: emit.out, prims: emit.prims };
        }
        let internal = emit.node(0, n);
        let parts: Vec<Part> =
            internal.nodes[..internal.count].par_iter().map(|&c| self.part(c, level + 1)).collect();
        let (mut nodes, mut prims) = (emit.out, emit.prims);
        nodes.reserve(parts.iter().map(|p| p.nodes.len() - 1).sum());
        prims.reserve(parts.iter().map(|p| p.prims.len()).sum());
        for (k, part) in parts.into_iter().enumerate() {
            // The part's root fills slot `k`; its node `x >= 1` goes to `nodes.len() + x - 1`,
            // its primitives after ours: where a sequential pass would have put them.
            let base = nodes.len() as u32 - 1;
            let prim_base = prims.len() as u32;
            let from = nodes.len();
            nodes.extend_from_slice(&part.nodes[1..]);
            nodes[1 + k] = part.nodes[0];
            for node in std::iter::once(1 + k).chain(from..nodes.len()) {
                nodes[node].child_base_idx += base;
                nodes[node].primitive_base_idx += prim_base;
            }
            prims.extend_from_slice(&part.prims);
        }
        Part { nodes, prims }
    }
}

/// The binary nodes of a wide node's internal children, in slot order.
#[derive(Default)]
struct Internal {
    nodes: [usize; 8],
    count: usize,
}

/// Wide-node levels whose children's subtrees are emitted in parallel.
const PARALLEL_EMIT_LEVELS: u32 = 2;

/// A wide subtree emitted on its own: its root first, node and primitive indices counted from
/// its own start.
struct Part {
    nodes: Vec<CwBvhNode>,
    prims: Vec<u32>,
}

/// The CWBVH nodes of `bvh2` (one primitive per binary leaf) with at most `max_prims`
/// (1..=3) primitives a leaf, and the primitive indices in leaf order.
///
/// Works on trees of any depth in bounded stack: no call chain is deeper than
/// [`PARALLEL_LEVELS`] + 1 (the cost pass) or [`PARALLEL_EMIT_LEVELS`] + 9 (the emission);
/// deeper levels are walked with explicit heap stacks.
pub fn collapse(bvh2: &Bvh2, max_prims: u32) -> (Vec<CwBvhNode>, Vec<u32>) {
    if bvh2.nodes.is_empty() {
        return (Vec::new(), Vec::new());
    }
    let decisions: Vec<AtomicU64> =
        (0..bvh2.nodes.len()).into_par_iter().map(|_| AtomicU64::new(0)).collect();
    let walk: Vec<WalkNode> = bvh2.nodes.par_iter().map(WalkNode::new).collect();
    cost(&walk, &decisions, 0, max_prims.clamp(1, 3), 0);
    let emit = Emit {
        nodes: &bvh2.nodes,
        walk: &walk,
        decisions: &decisions,
        order: &bvh2.primitive_indices,
        out: Vec::new(),
        prims: Vec::new(),
    };
    let whole = emit.part(0, 0);
    (whole.nodes, whole.prims)
}
