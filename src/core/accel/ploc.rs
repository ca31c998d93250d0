//! PLOC (Meister and Bittner 2018, "Parallel Locally-Ordered Clustering for Bounding Volume
//! Hierarchy Construction"), as obvhs 0.4 builds it (`PlocBuilder::build`, MIT or Apache-2.0),
//! with one guard: a pass that would merge too few pairs merges neighbours in Morton order
//! instead.
//!
//! PLOC merges, in each pass, the pairs of clusters that are each other's cheapest neighbour
//! within a window of the Morton order. On ordinary meshes a pass merges a large share of the
//! clusters, so there are about log n passes. On degenerate input (copies of one triangle,
//! whose boxes tie everywhere, or the fan of a long polygon, whose boxes nest) a pass can
//! merge a single pair: n passes of n work (30,000 copies of a triangle took 40 s) and a
//! chain-shaped tree n deep. With the guard every pass over more than 64 clusters removes at
//! least a 32nd of them, so the work is linear in n and the tree's depth is bounded by
//! [`max_depth`]. A pass that merges enough is the obvhs pass unchanged, so the trees of
//! ordinary meshes (where no pass comes near the guard) are the ones obvhs builds.

use glam::DVec3;
use obvhs::aabb::Aabb;
use obvhs::bvh2::Bvh2;
use obvhs::bvh2::node::Bvh2Node;
use obvhs::ploc::morton::{morton_encode_u64_unorm, morton_encode_u128_unorm};
use obvhs::ploc::{PlocSearchDistance, SortPrecision};
use obvhs::{Boundable, BvhBuildParams};
use rayon::prelude::*;

/// A pass must merge at least one pair per this many clusters, or it merges neighbours in
/// Morton order (which halves the count).
const MIN_MERGE_SHARE: usize = 32;

/// Passes over at most this many clusters run unguarded: at the top of a tree few clusters
/// are left and a pass may merge one pair of ten, which is no cost.
const GUARD_FROM: usize = 64;

/// The greatest depth (edges from the root to a leaf) of a binary tree [`build`] makes over
/// `n` primitives: each pass adds at most one level; a guarded pass leaves at most 31/32 of
/// the clusters (rounded down), so at most `ceil(log_{32/31} n)` of them run (699 for 2^32
/// primitives), and then at most [`GUARD_FROM`] - 1 unguarded ones, each merging a pair.
pub fn max_depth(n: usize) -> usize {
    let guarded = (n.max(1) as f64).ln() / (MIN_MERGE_SHARE as f64 / (MIN_MERGE_SHARE - 1) as f64).ln();
    guarded.ceil() as usize + GUARD_FROM - 1
}

/// obvhs' `SearchCache`: the costs a cluster computed to its right-hand neighbours, read back
/// when those neighbours search to their left.
struct SearchCache<const S: usize>([[f32; S]; S]);

impl<const S: usize> SearchCache<S> {
    fn new() -> Self {
        Self([[0.0; S]; S])
    }

    /// The offset of the cheapest neighbour of cluster `index` (the `i`-th of its chunk)
    /// within `S` either side; ties go to the rightmost.
    #[allow(clippy::needless_range_loop)] // `other` also indexes the cache
    fn find_best(&mut self, index: usize, i: usize, nodes: &[Bvh2Node]) -> i8 {
        let mut best_node = index;
        let mut best_cost = f32::INFINITY;
        let begin = index - S.min(index);
        let end = (index + S + 1).min(nodes.len());
        let ours = nodes[index].aabb();
        for other in begin..index {
            // The first S of a chunk have not filled their cache slots yet.
            let area = if i <= S {
                ours.union(nodes[other].aabb()).half_area()
            } else {
                self.0[other % S][index % S]
            };
            if area <= best_cost {
                best_node = other;
                best_cost = area;
            }
        }
        for other in (index + 1)..end {
            let cost = ours.union(nodes[other].aabb()).half_area();
            self.0[index % S][other % S] = cost;
            if cost <= best_cost {
                best_node = other;
                best_cost = cost;
            }
        }
        (best_node as i64 - index as i64) as i8
    }
}

/// A Morton code and the cluster it belongs to, laid out as obvhs' (the sort is unstable, so
/// the same layout and sort keep ties in the same order).
#[derive(Clone, Copy)]
#[repr(C)]
struct Morton64 {
    code: u64,
    index: u64,
}

#[derive(Clone, Copy)]
#[repr(C)]
struct Morton128 {
    code: u128,
    index: u64,
    padding: u64,
}

/// The leaves in Morton order of their centres (obvhs' `sort_nodes_by_morton`).
fn sort_by_morton(
    nodes: &[Bvh2Node],
    precision: SortPrecision,
    scale: DVec3,
    offset: DVec3,
) -> Vec<Bvh2Node> {
    let center = |node: &Bvh2Node| node.aabb().center().as_dvec3() * scale + offset;
    match precision {
        SortPrecision::U64 => {
            let mut m: Vec<Morton64> = nodes
                .par_iter()
                .enumerate()
                .map(|(i, n)| Morton64 { code: morton_encode_u64_unorm(center(n)), index: i as u64 })
                .collect();
            m.par_sort_unstable_by_key(|m| m.code);
            m.par_iter().map(|m| nodes[m.index as usize]).collect()
        }
        SortPrecision::U128 => {
            let mut m: Vec<Morton128> = nodes
                .par_iter()
                .enumerate()
                .map(|(i, n)| Morton128 {
                    code: morton_encode_u128_unorm(center(n)),
                    index: i as u64,
                    padding: 0,
                })
                .collect();
            m.par_sort_unstable_by_key(|m| m.code);
            m.par_iter().map(|m| nodes[m.index as usize]).collect()
        }
    }
}

/// The binary BVH over `aabbs` (primitive `i` has index `i`), one primitive a leaf, with
/// obvhs' PLOC parameters from `params`, and whether any pass needed the guard.
pub fn build<T: Boundable + Sync>(aabbs: &[T], params: &BvhBuildParams) -> (Bvh2, bool) {
    match params.ploc_search_distance {
        PlocSearchDistance::Minimum => build_with::<1, T>(aabbs, params),
        PlocSearchDistance::VeryLow => build_with::<2, T>(aabbs, params),
        PlocSearchDistance::Low => build_with::<6, T>(aabbs, params),
        PlocSearchDistance::Medium => build_with::<14, T>(aabbs, params),
        PlocSearchDistance::High => build_with::<24, T>(aabbs, params),
        PlocSearchDistance::VeryHigh => build_with::<32, T>(aabbs, params),
    }
}

/// Fills `merge` (one entry per cluster) with each cluster's chosen neighbour offset.
fn choose<const S: usize>(nodes: &[Bvh2Node], merge: &mut [i8], near_only: bool) {
    let count = nodes.len();
    if near_only {
        // Search distance 1: merge with the cheaper side.
        let cost = |i: usize| nodes[i].aabb().union(nodes[i + 1].aabb()).half_area();
        let threads = rayon::current_num_threads();
        let chunk = (count - 1).div_ceil(threads).max(1);
        merge[..count - 1].par_chunks_mut(chunk).enumerate().for_each(|(c, part)| {
            let start = c * chunk;
            let mut last = if start == 0 { f32::INFINITY } else { cost(start - 1) };
            for (k, m) in part.iter_mut().enumerate() {
                let here = cost(start + k);
                *m = if last < here { -1 } else { 1 };
                last = here;
            }
        });
        merge[count - 1] = -1;
        return;
    }
    let chunks = if count < 4000 { 1 } else { rayon::current_num_threads() * 4 };
    let chunk = count.div_ceil(chunks).max(1);
    merge.par_chunks_mut(chunk).enumerate().for_each(|(c, part)| {
        let mut cache = SearchCache::<S>::new();
        for (i, m) in part.iter_mut().enumerate() {
            *m = cache.find_best(c * chunk + i, i, nodes);
        }
    });
}

/// How many pairs `merge` pairs up (both sides agree).
fn merged_pairs(merge: &[i8]) -> usize {
    (0..merge.len())
        .into_par_iter()
        .filter(|&i| {
            let best = (i as i64 + i64::from(merge[i])) as usize;
            best < i && (best as i64 + i64::from(merge[best])) as usize == i
        })
        .count()
}

fn build_with<const S: usize, T: Boundable + Sync>(aabbs: &[T], params: &BvhBuildParams) -> (Bvh2, bool) {
    let n = aabbs.len();
    let mut bvh = Bvh2::zeroed(n);
    bvh.reset_for_reuse(n, Some((0..n as u32).collect()));
    if n == 0 {
        return (bvh, false);
    }
    let leaves: Vec<Bvh2Node> =
        aabbs.par_iter().enumerate().map(|(i, a)| Bvh2Node::new(a.aabb(), 1, i as u32)).collect();
    let total = leaves.iter().fold(Aabb::empty(), |mut t, l| {
        t.extend(l.aabb().min);
        t.extend(l.aabb().max);
        t
    });
    let scale = 1.0 / total.diagonal().as_dvec3();
    let offset = -total.min.as_dvec3() * scale;
    let mut current = sort_by_morton(&leaves, params.sort_precision, scale, offset);
    drop(leaves);
    let mut next = vec![Bvh2Node::default(); n];
    let mut merge = vec![0i8; n];
    let mut insert_index = bvh.nodes.len();
    let mut depth = 0usize;
    let mut count = n;
    let mut guarded = false;
    while count > 1 {
        let nodes = &current[..count];
        let merge = &mut merge[..count];
        choose::<S>(nodes, merge, S == 1 || depth < params.search_depth_threshold);
        let pairs = merged_pairs(merge);
        if count > GUARD_FROM && pairs * MIN_MERGE_SHARE < count {
            guarded = true;
            // Too little progress: pair the clusters in Morton order, (0, 1), (2, 3), ...;
            // an odd last one waits.
            for (i, m) in merge.iter_mut().enumerate() {
                *m = if i % 2 == 0 && i + 1 < count { 1 } else { -1 };
            }
        }
        let mut kept = 0;
        let mut index = 0;
        while index < count {
            let offset = merge[index] as i64;
            let best = (index as i64 + offset) as usize;
            if best as i64 + merge[best] as i64 != index as i64 {
                next[kept] = nodes[index];
                kept += 1;
                index += 1;
                continue;
            }
            if best > index {
                index += 1;
                continue;
            }
            let (left, right) = (nodes[index], nodes[best]);
            insert_index -= 2;
            bvh.nodes[insert_index] = left;
            bvh.nodes[insert_index + 1] = right;
            next[kept] = Bvh2Node::new(left.aabb().union(right.aabb()), 0, insert_index as u32);
            kept += 1;
            index += 1;
        }
        std::mem::swap(&mut current, &mut next);
        count = kept;
        depth += 1;
    }
    debug_assert_eq!(insert_index, 1);
    debug_assert!(depth <= max_depth(n));
    bvh.nodes[0] = current[0];
    bvh.max_depth = obvhs::bvh2::DEFAULT_MAX_STACK_DEPTH.max(depth + 1);
    bvh.children_are_ordered_after_parents = true;
    (bvh, guarded)
}
