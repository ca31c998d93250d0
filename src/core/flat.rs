//! Small meshes without a tree: triangles in blocks of 8, tested 8 at a time.
//!
//! Triangles are grouped into at most 16 spatially compact blocks, each stored
//! coordinate-major (nine runs of 8 floats: `v0.x` of the 8 triangles, `v0.y`, ..., `v2.z`)
//! with a bounding box. A query tests the block boxes 8 at a time, then the blocks it enters,
//! nearest first, each with the watertight test of [`super::triangle`] on all 8 lanes: the
//! very same operations in the same order (no fused multiply-add), so it finds the hits a
//! tree would, bit for bit. In effect a one-node wide BVH with 8-triangle leaves.
//!
//! The lane loops here are the portable reference; `avx` does each step in one 8-wide
//! instruction. On the 36-triangle Cornell box (callgrind, `propsim render`) a closest hit
//! takes 349 instructions against 590 for the CWBVH, which visits 1.6 nodes and 2 leaves of
//! at most 3 triangles, sorting and pushing on the way, and a shadow ray 214 against 737.

use glam::{Vec2, Vec3, Vec3A};

use super::traverse::nearest;
use super::triangle::RayShear;

#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)]
pub(crate) mod avx;

/// Triangles tested together, and block boxes tested together.
pub const LANES: usize = 8;

/// Meshes of at most this many triangles are tested without a tree ([`FlatTriangles`]).
/// Measured with `propsim bench trace` on the Cornell box plus small random triangles,
/// random rays inside, 2 threads (Mrays/s closest hit, tree vs flat): 64 triangles 20.5 vs
/// 31.6, 96 triangles 16.2 vs 27.1, 128 triangles 15.5 vs 12.2 (16 full blocks leave the
/// clustering no choice).
pub const FLAT_LIMIT: usize = 96;

/// Blocks at most: two box tests' worth, so that groups can follow the geometry (a wall a
/// block) rather than fill every lane.
const MAX_BLOCKS: usize = 2 * LANES;

/// One `f32` per lane.
pub type Lanes = [f32; LANES];

/// One block: corner `v`, axis `k` of lane `i` at `c[3 * v + k][i]`.
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(32))]
struct Block {
    c: [Lanes; 9],
}

/// The boxes of all blocks: `lo` x, y, z then `hi` x, y, z, one lane a block, so that
/// blocks `8 g..8 g + 8` are one 32-byte run and all 16 one 64-byte run (AVX-512).
#[derive(Clone, Copy, Debug, Default)]
#[repr(C, align(64))]
struct Boxes {
    b: [[f32; MAX_BLOCKS]; 6],
}

/// A small mesh's triangles in at most 16 blocks of [`LANES`]. A triangle's slot is
/// `8 * block + lane`; [`FlatTriangles::slots`] maps slots back to input order.
#[derive(Clone, Debug, Default)]
pub struct FlatTriangles {
    blocks: Vec<Block>,
    /// Lanes of each block that hold a triangle.
    occupied: Vec<u32>,
    /// Every block's box.
    boxes: Boxes,
    /// Input index of the triangle in each slot; `None` for empty lanes.
    slots: Vec<Option<u32>>,
}

/// Per-ray constants: the watertight shear of [`RayShear`] and the slab slopes.
#[derive(Clone, Copy, Debug)]
pub struct FlatRay {
    /// Origin coordinates along the permuted axes `kx`, `ky`, `kz`.
    origin: [f32; 3],
    /// Shear `sx`, `sy`, `sz`.
    shear: [f32; 3],
    /// The permuted axes.
    axis: [usize; 3],
    /// Origin and inverse direction (finite) for the box test.
    world_origin: [f32; 3],
    inv_dir: [f32; 3],
}

/// `1/x` without infinities, lane by lane and without branches (obvhs' `safe_inverse`): a
/// zero direction component gives a large finite slope, so slab products stay finite (no
/// `0 * inf`). The tree's node test and the blocks' box test both use it.
#[inline(always)]
pub(crate) fn safe_inverse(x: Vec3A) -> Vec3A {
    let tiny = x.abs().cmple(Vec3A::splat(f32::EPSILON));
    Vec3A::select(tiny, x.signum() / f32::EPSILON, Vec3A::ONE / x)
}

impl FlatRay {
    /// The constants of a ray from `origin` along `dir`.
    #[inline(always)]
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        let s = RayShear::new(origin, dir);
        // +0.0 turns -0.0 into +0.0 before the inverse.
        let d = Vec3A::from(dir) + Vec3A::ZERO;
        Self {
            origin: [s.kx, s.ky, s.kz].map(|k| origin.to_array()[k]),
            shear: [s.sx, s.sy, s.sz],
            axis: [s.kx.min(2), s.ky.min(2), s.kz.min(2)],
            world_origin: origin.to_array(),
            inv_dir: safe_inverse(d).to_array(),
        }
    }
}

/// What a block test gives: the mask of lanes hit on `(t_min, t_max]`, and each lane's
/// distance and barycentric weights of `v1` and `v2`.
type BlockHits = (u32, [Lanes; 3]);

/// The two tests, portable or in SIMD; [`closest_with`] and [`any_with`] drive them.
trait Kernel {
    /// Of the 8 blocks of box group `g`, those whose boxes the ray crosses on
    /// `(t_min, t_max]`, and the entry distances.
    fn boxes(flat: &FlatTriangles, g: usize, ray: &FlatRay, t_min: f32, t_max: f32) -> (u32, Lanes);
    /// The blocks whose boxes the ray crosses on `(t_min, t_max]` (bit `b` for block `b`),
    /// and their entry distances: a box test per 8 blocks, unless the kernel is wider.
    #[inline(always)]
    fn entered(flat: &FlatTriangles, ray: &FlatRay, t_min: f32, t_max: f32) -> (u32, [f32; MAX_BLOCKS]) {
        let mut near = [0.0; MAX_BLOCKS];
        if flat.blocks.is_empty() {
            return (0, near);
        }
        let (blocks, first) = Self::boxes(flat, 0, ray, t_min, t_max);
        near[..LANES].copy_from_slice(&first);
        if flat.blocks.len() <= LANES {
            return (blocks, near);
        }
        let (more, second) = Self::boxes(flat, 1, ray, t_min, t_max);
        near[LANES..].copy_from_slice(&second);
        (blocks | more << LANES, near)
    }
    /// The watertight test of the triangles of block `b`. Two-sided.
    fn block(flat: &FlatTriangles, b: usize, ray: &FlatRay, t_min: f32, t_max: f32) -> BlockHits;
}

/// `f` of every lane. (Plain loops, which inline where an iterator's closures may not, and
/// vectorise.)
#[inline(always)]
pub fn lanes(f: impl Fn(usize) -> f32) -> Lanes {
    let mut out = [0.0; LANES];
    for (i, o) in out.iter_mut().enumerate() {
        *o = f(i);
    }
    out
}

/// Bit `i` set where `f(i)` holds.
#[inline(always)]
fn mask(f: impl Fn(usize) -> bool) -> u32 {
    let mut m = 0;
    for i in 0..LANES {
        m |= u32::from(f(i)) << i;
    }
    m
}

/// The lane-by-lane reference of [`Kernel`].
struct Portable;

impl Kernel for Portable {
    #[inline(always)]
    fn boxes(flat: &FlatTriangles, g: usize, ray: &FlatRay, t_min: f32, t_max: f32) -> (u32, Lanes) {
        let b = &flat.boxes.b;
        let slab = |k: usize, i: usize| {
            let t0 = (b[k][LANES * g + i] - ray.world_origin[k]) * ray.inv_dir[k];
            let t1 = (b[3 + k][LANES * g + i] - ray.world_origin[k]) * ray.inv_dir[k];
            (t0.min(t1), t0.max(t1))
        };
        let near = lanes(|i| slab(0, i).0.max(slab(1, i).0).max(slab(2, i).0.max(t_min)));
        let far = lanes(|i| slab(0, i).1.min(slab(1, i).1).min(slab(2, i).1.min(t_max)));
        (mask(|i| near[i] <= far[i]) & flat.block_mask(g), near)
    }

    #[inline(always)]
    fn block(flat: &FlatTriangles, b: usize, ray: &FlatRay, t_min: f32, t_max: f32) -> BlockHits {
        let c = &flat.blocks[b].c;
        let [kx, ky, kz] = ray.axis.map(|k| k.min(2));
        let [ox, oy, oz] = ray.origin;
        let [sx, sy, sz] = ray.shear;
        let corner = |v: usize, k: usize| &c[3 * v + k];
        // Corners relative to the origin, in the permuted frame, then sheared.
        let az = lanes(|i| corner(0, kz)[i] - oz);
        let bz = lanes(|i| corner(1, kz)[i] - oz);
        let cz = lanes(|i| corner(2, kz)[i] - oz);
        let ax = lanes(|i| corner(0, kx)[i] - ox - sx * az[i]);
        let ay = lanes(|i| corner(0, ky)[i] - oy - sy * az[i]);
        let bx = lanes(|i| corner(1, kx)[i] - ox - sx * bz[i]);
        let by = lanes(|i| corner(1, ky)[i] - oy - sy * bz[i]);
        let cx = lanes(|i| corner(2, kx)[i] - ox - sx * cz[i]);
        let cy = lanes(|i| corner(2, ky)[i] - oy - sy * cz[i]);
        let mut u = lanes(|i| cx[i] * by[i] - cy[i] * bx[i]);
        let mut v = lanes(|i| ax[i] * cy[i] - ay[i] * cx[i]);
        let mut w = lanes(|i| bx[i] * ay[i] - by[i] * ax[i]);
        let occupied = flat.occupied[b];
        let zero = mask(|i| (u[i] == 0.0) | (v[i] == 0.0) | (w[i] == 0.0)) & occupied;
        if zero != 0 {
            edge_functions_f64(zero, [&ax, &ay, &bx, &by, &cx, &cy], [&mut u, &mut v, &mut w]);
        }
        let det = lanes(|i| u[i] + v[i] + w[i]);
        let inside = mask(|i| {
            let negative = (u[i] < 0.0) | (v[i] < 0.0) | (w[i] < 0.0);
            let positive = (u[i] > 0.0) | (v[i] > 0.0) | (w[i] > 0.0);
            !(negative & positive) & (det[i] != 0.0)
        });
        let t_scaled = lanes(|i| u[i] * (sz * az[i]) + v[i] * (sz * bz[i]) + w[i] * (sz * cz[i]));
        let inv_det = lanes(|i| 1.0 / det[i]);
        let t = lanes(|i| t_scaled[i] * inv_det[i]);
        let in_range = mask(|i| (t[i] > t_min) & (t[i] <= t_max));
        (inside & in_range & occupied, [t, lanes(|i| v[i] * inv_det[i]), lanes(|i| w[i] * inv_det[i])])
    }
}

/// The closest hit on `(t_min, t_max]` as (slot, distance, barycentrics): the blocks the ray
/// enters, nearest first, until the next one starts beyond the closest hit.
#[inline(always)]
fn closest_with<K: Kernel>(
    flat: &FlatTriangles,
    ray: &FlatRay,
    t_min: f32,
    mut t_max: f32,
) -> Option<(u32, f32, Vec2)> {
    let (mut blocks, near) = K::entered(flat, ray, t_min, t_max);
    let mut best = None;
    while blocks != 0 {
        let b = nearest(blocks, &near);
        if near[b] > t_max {
            break;
        }
        blocks &= !(1 << b);
        let (mut hits, [t, u, v]) = K::block(flat, b, ray, t_min, t_max);
        while hits != 0 {
            let lane = hits.trailing_zeros() as usize;
            hits &= hits - 1;
            // Only a strictly closer hit replaces the best one, as in the tree's leaves.
            if t[lane] < t_max {
                t_max = t[lane];
                best = Some(((b * LANES + lane) as u32, t_max, Vec2::new(u[lane], v[lane])));
            }
        }
    }
    best
}

/// Whether any triangle lies on `(t_min, t_max]`.
#[inline(always)]
fn any_with<K: Kernel>(flat: &FlatTriangles, ray: &FlatRay, t_min: f32, t_max: f32) -> bool {
    let (mut blocks, _) = K::entered(flat, ray, t_min, t_max);
    while blocks != 0 {
        let b = blocks.trailing_zeros() as usize;
        blocks &= blocks - 1;
        if K::block(flat, b, ray, t_min, t_max).0 != 0 {
            return true;
        }
    }
    false
}

impl FlatTriangles {
    /// At most [`FLAT_LIMIT`] triangles given by their corners, grouped into blocks.
    pub fn new(triangles: &[[Vec3; 3]]) -> Self {
        assert!(triangles.len() <= FLAT_LIMIT, "{} triangles for a flat set", triangles.len());
        let mut flat = Self::default();
        let (lo, hi) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));
        for (b, members) in group(triangles).iter().enumerate() {
            let mut block = Block::default();
            let (mut min, mut max) = (lo, hi);
            for (lane, &i) in members.iter().enumerate() {
                for (v, corner) in triangles[i as usize].iter().enumerate() {
                    for k in 0..3 {
                        block.c[3 * v + k][lane] = corner[k];
                    }
                    (min, max) = (min.min(*corner), max.max(*corner));
                }
            }
            // A few ulps of padding keep the box test conservative, as the tree's boxes.
            let pad = Vec3::splat(1.0e-6 * (1.0 + min.abs().max(max.abs()).max_element()));
            for k in 0..3 {
                flat.boxes.b[k][b] = min[k] - pad[k];
                flat.boxes.b[3 + k][b] = max[k] + pad[k];
            }
            flat.blocks.push(block);
            flat.occupied.push((1u32 << members.len()) - 1);
            flat.slots.extend((0..LANES).map(|lane| members.get(lane).copied()));
        }
        flat
    }

    /// Input index of the triangle in each slot (`8 * block + lane`); `None` for empty lanes.
    pub fn slots(&self) -> &[Option<u32>] {
        &self.slots
    }

    /// Bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.blocks.len() * (size_of::<Block>() + 4) + size_of::<Boxes>() + self.slots.len() * 8
    }

    /// Bit `i` set for each block `8 g + i` of box group `g`.
    #[inline(always)]
    fn block_mask(&self, g: usize) -> u32 {
        let n = self.blocks.len().saturating_sub(LANES * g).min(LANES);
        (1u32 << n) - 1
    }

    /// Bit `b` set for each block.
    #[inline(always)]
    fn blocks_mask(&self) -> u32 {
        (1u32 << self.blocks.len()) - 1
    }

    /// The closest hit on `(t_min, t_max]` as (slot, distance, barycentrics).
    #[inline(always)]
    pub fn closest(&self, ray: &FlatRay, t_min: f32, t_max: f32) -> Option<(u32, f32, Vec2)> {
        closest_with::<Portable>(self, ray, t_min, t_max)
    }

    /// Whether any triangle lies on `(t_min, t_max]`.
    #[inline(always)]
    pub fn any(&self, ray: &FlatRay, t_min: f32, t_max: f32) -> bool {
        any_with::<Portable>(self, ray, t_min, t_max)
    }

    /// Calls `f(slot, t, uv)` for every hit on `(t_min, t_max]`.
    pub fn for_each_hit(&self, ray: &FlatRay, t_min: f32, t_max: f32, mut f: impl FnMut(u32, f32, Vec2)) {
        for b in 0..self.blocks.len() {
            let (mut hits, [t, u, v]) = Portable::block(self, b, ray, t_min, t_max);
            while hits != 0 {
                let lane = hits.trailing_zeros() as usize;
                hits &= hits - 1;
                f((b * LANES + lane) as u32, t[lane], Vec2::new(u[lane], v[lane]));
            }
        }
    }
}

/// The cost of a box test (8 boxes at once) relative to a block test. About 0.35 in
/// instructions, but 0.35 merged the Cornell box's walls into room-sized blocks, and 0.1
/// (9 blocks instead of 7) took 10 % fewer instructions a sample in `propsim render`.
const BOX_TEST_COST: f32 = 0.1;

/// Groups of at most [`LANES`] triangles, at most [`MAX_BLOCKS`] of them, with small boxes:
/// agglomerative clustering (Walter et al. 2008) under the surface-area heuristic. A group
/// costs its box's area (the chance a ray enters it) times its blocks, and each 8 blocks add
/// a box test for every ray; starting from single triangles, the pair whose merge costs
/// least is merged, down to one group, and the cheapest grouping of at most
/// [`MAX_BLOCKS`] blocks seen on the way is kept. Coplanar pieces of a wall merge for free,
/// so a room's walls end up a block each, whose thin boxes a ray enters only where it hits.
fn group(triangles: &[[Vec3; 3]]) -> Vec<Vec<u32>> {
    type Group = (Vec<u32>, Vec3, Vec3);
    let blocks = |n: usize| n.div_ceil(LANES);
    let area = |lo: Vec3, hi: Vec3| {
        let e = (hi - lo).max(Vec3::ZERO);
        e.x * e.y + e.y * e.z + e.z * e.x
    };
    let mut groups: Vec<Group> = triangles
        .iter()
        .enumerate()
        .map(|(i, t)| (vec![i as u32], t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2])))
        .collect();
    let root =
        groups.iter().fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), g| (lo.min(g.1), hi.max(g.2)));
    let root_area = area(root.0, root.1).max(f32::MIN_POSITIVE);
    let cost = |groups: &[Group]| {
        let tests: f32 = groups.iter().map(|g| area(g.1, g.2) * blocks(g.0.len()) as f32).sum();
        let block_count: usize = groups.iter().map(|g| blocks(g.0.len())).sum();
        tests / root_area + BOX_TEST_COST * block_count.div_ceil(LANES) as f32
    };
    let mut best: Option<(f32, Vec<Group>)> = None;
    loop {
        if groups.iter().map(|g| blocks(g.0.len())).sum::<usize>() <= MAX_BLOCKS {
            let c = cost(&groups);
            if best.as_ref().is_none_or(|b| c < b.0) {
                best = Some((c, groups.clone()));
            }
        }
        if groups.len() <= 1 {
            break;
        }
        // The merge that raises the area-times-blocks cost least (ties: the first pair).
        let mut merge = (f32::INFINITY, 0, 0);
        for i in 0..groups.len() {
            for j in i + 1..groups.len() {
                let (a, b) = (&groups[i], &groups[j]);
                let n = a.0.len() + b.0.len();
                let delta = area(a.1.min(b.1), a.2.max(b.2)) * blocks(n) as f32
                    - area(a.1, a.2) * blocks(a.0.len()) as f32
                    - area(b.1, b.2) * blocks(b.0.len()) as f32;
                if delta < merge.0 {
                    merge = (delta, i, j);
                }
            }
        }
        let (_, i, j) = merge;
        let b = groups.swap_remove(j);
        let a = &mut groups[i];
        a.0.extend(b.0);
        (a.1, a.2) = (a.1.min(b.1), a.2.max(b.2));
    }
    // Within a group of more than 8, lanes follow input order; blocks are cut from it.
    let mut out = Vec::new();
    for (mut members, _, _) in best.map(|b| b.1).unwrap_or_default() {
        members.sort_unstable();
        out.extend(members.chunks(LANES).map(<[u32]>::to_vec));
    }
    out
}

/// The edge functions of the lanes in `zero` recomputed in double precision (Woop et al.,
/// sec. 3): the rare exact zeros of a ray through an edge or a vertex.
#[cold]
#[inline(never)]
fn edge_functions_f64(zero: u32, corners: [&Lanes; 6], uvw: [&mut Lanes; 3]) {
    let [ax, ay, bx, by, cx, cy] = corners.map(|x| x.map(f64::from));
    let [u, v, w] = uvw;
    for i in (0..LANES).filter(|i| zero & (1 << i) != 0) {
        u[i] = (cx[i] * by[i] - cy[i] * bx[i]) as f32;
        v[i] = (ax[i] * cy[i] - ay[i] * cx[i]) as f32;
        w[i] = (bx[i] * ay[i] - by[i] * ax[i]) as f32;
    }
}
