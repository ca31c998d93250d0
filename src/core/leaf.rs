//! Triangles of BVH leaves, stored coordinate-major per leaf, with a 4-wide watertight test.
//!
//! A leaf of `n <= 3` triangles starting at leaf-order slot `first` keeps its corners at
//! `data[9 * first..9 * (first + n)]` as nine runs of `n` floats: `v0.x`, `v0.y`, `v0.z`,
//! `v1.x`, ..., `v2.z`. One unaligned 4-wide load then reads one coordinate of every triangle
//! of the leaf (the lanes past `n` read neighbouring data and are masked off), so the leaf's
//! triangles are tested at once without transposing, in 36 bytes per triangle.
//!
//! The test is the watertight one of [`super::triangle`], lane by lane with the very same
//! operations in the same order (no fused multiply-add), so a ray gets bit-identical results
//! from both, and the edge functions of an edge shared by two triangles agree exactly.

use glam::{BVec4A, Vec2, Vec3, Vec4};
use rayon::prelude::*;

use super::traverse::prefetch;
use super::triangle::{RayShear, TriangleRt};

/// Floats a leaf test may read from its first float on: nine runs of up to 3, and 3 more
/// lanes. A fixed window lets the compiler drop the bounds checks of the nine loads.
const WINDOW: usize = 31;
/// Floats after the last leaf, so that its window is readable.
const PAD: usize = WINDOW;

/// All triangles of a BVH's leaves, in leaf order.
#[derive(Clone, Debug, Default)]
pub struct LeafTriangles {
    data: Vec<f32>,
}

/// Per-ray constants of the leaf test: the watertight shear of [`RayShear`], with the origin
/// in the permuted frame, as 4-wide splats.
#[derive(Clone, Copy, Debug)]
pub struct LeafRay {
    /// Origin coordinates along the permuted axes `kx`, `ky`, `kz`.
    origin: [Vec4; 3],
    /// Shear `sx`, `sy`, `sz`.
    shear: [Vec4; 3],
    /// The permuted axes.
    axis: [usize; 3],
}

impl LeafRay {
    /// The leaf-test constants of the sheared ray `s`.
    #[inline(always)]
    pub fn new(s: &RayShear) -> Self {
        Self {
            origin: [s.kx, s.ky, s.kz].map(|k| Vec4::splat(s.origin[k])),
            shear: [s.sx, s.sy, s.sz].map(Vec4::splat),
            axis: [s.kx, s.ky, s.kz],
        }
    }
}

/// The triangles of one leaf hit by a ray: lanes `0..count` of the leaf.
#[derive(Clone, Copy, Debug)]
pub struct LeafHits {
    /// Bit `i` set when triangle `first + i` is hit on `(t_min, t_max]`.
    pub mask: u32,
    /// Distance of each hit.
    pub t: Vec4,
    /// Barycentric weights of `v1`...
    pub u: Vec4,
    /// ... and of `v2`.
    pub v: Vec4,
}

impl LeafTriangles {
    /// Packs `count` triangles leaf by leaf, in parallel: `corners(slot)` gives the corners of
    /// the triangle at leaf-order slot `slot`; `leaves` are the `(first, count)` ranges of the
    /// BVH's leaves, sorted, which tile `0..count`.
    pub fn new(count: usize, leaves: &[(u32, u32)], corners: impl Fn(usize) -> [Vec3; 3] + Sync) -> Self {
        let mut data = vec![0.0f32; 9 * count + PAD];
        // Split the output into one disjoint slice per leaf, then fill the leaves in parallel.
        let mut parts = Vec::with_capacity(leaves.len());
        let mut rest = &mut data[..9 * count];
        let mut at = 0;
        for &(first, n) in leaves {
            let (first, n) = (first as usize, n as usize);
            if first < at || 9 * (first - at + n) > rest.len() {
                continue;
            }
            let (_, tail) = std::mem::take(&mut rest).split_at_mut(9 * (first - at));
            let (leaf, tail) = tail.split_at_mut(9 * n);
            parts.push((first, n, leaf));
            (rest, at) = (tail, first + n);
        }
        debug_assert_eq!(at, count, "the leaves tile the triangles");
        parts.into_par_iter().for_each(|(first, n, out)| {
            for lane in 0..n {
                for (v, corner) in corners(first + lane).iter().enumerate() {
                    for k in 0..3 {
                        out[(3 * v + k) * n + lane] = corner[k];
                    }
                }
            }
        });
        Self { data }
    }

    /// Bytes held.
    pub fn memory_bytes(&self) -> usize {
        self.data.len() * size_of::<f32>()
    }

    /// A hint to start loading the leaf `(first, count)` into the cache.
    #[inline(always)]
    pub fn prefetch(&self, first: u32, count: u32) {
        // Up to 108 bytes: three cache lines when unaligned.
        let (a, b) = (9 * first as usize, 9 * (first + count) as usize - 1);
        if let (Some(x), Some(y)) = (self.data.get(a), self.data.get(b)) {
            prefetch(x);
            prefetch(&self.data[(a + 16).min(b)]);
            prefetch(y);
        }
    }

    /// Triangle `lane` of the leaf `(first, count)`.
    pub fn triangle(&self, first: u32, count: u32, lane: usize) -> TriangleRt {
        let (base, n) = (9 * first as usize, count as usize);
        let corner = |v: usize| {
            let at = |k: usize| self.data[base + (3 * v + k) * n + lane];
            Vec3::new(at(0), at(1), at(2))
        };
        TriangleRt::new(corner(0), corner(1), corner(2))
    }

    /// The watertight test of every triangle of the leaf `(first, count)` against a ray, on
    /// `(t_min, t_max]`. Two-sided.
    #[inline(always)]
    pub fn intersect(&self, first: u32, count: u32, ray: &LeafRay, t_min: f32, t_max: f32) -> LeafHits {
        let base = 9 * first as usize;
        let Some(window) = self.data.get(base..base + WINDOW) else {
            return LeafHits::NONE;
        };
        // Lane counts and axes are at most 3 and 2: with these bounds and the fixed window
        // the compiler sees every load in range.
        let n = (count as usize).min(3);
        let [kx, ky, kz] = ray.axis.map(|k| k.min(2) * n);
        let load = |v: usize, k: usize| {
            let i = 3 * v * n + k;
            Vec4::from_slice(&window[i..i + 4])
        };
        let [ox, oy, oz] = ray.origin;
        let [sx, sy, sz] = ray.shear;
        // Corners relative to the origin, in the permuted frame, then sheared.
        let (az, bz, cz) = (load(0, kz) - oz, load(1, kz) - oz, load(2, kz) - oz);
        let ax = load(0, kx) - ox - sx * az;
        let ay = load(0, ky) - oy - sy * az;
        let bx = load(1, kx) - ox - sx * bz;
        let by = load(1, ky) - oy - sy * bz;
        let cx = load(2, kx) - ox - sx * cz;
        let cy = load(2, ky) - oy - sy * cz;
        let mut u = cx * by - cy * bx;
        let mut v = ax * cy - ay * cx;
        let mut w = bx * ay - by * ax;
        let lanes = (1u32 << n) - 1;
        let zero = (u.cmpeq(Vec4::ZERO) | v.cmpeq(Vec4::ZERO) | w.cmpeq(Vec4::ZERO)).bitmask() & lanes;
        if zero != 0 {
            (u, v, w) = edge_functions_f64(zero, [ax, ay, bx, by, cx, cy], [u, v, w]);
        }
        let negative = u.cmplt(Vec4::ZERO) | v.cmplt(Vec4::ZERO) | w.cmplt(Vec4::ZERO);
        let positive = u.cmpgt(Vec4::ZERO) | v.cmpgt(Vec4::ZERO) | w.cmpgt(Vec4::ZERO);
        let det = u + v + w;
        let inside: BVec4A = !(negative & positive) & det.cmpne(Vec4::ZERO);
        let t_scaled = u * (sz * az) + v * (sz * bz) + w * (sz * cz);
        let inv_det = Vec4::ONE / det;
        let t = t_scaled * inv_det;
        let in_range = t.cmpgt(Vec4::splat(t_min)) & t.cmple(Vec4::splat(t_max));
        LeafHits { mask: (inside & in_range).bitmask() & lanes, t, u: v * inv_det, v: w * inv_det }
    }
}

/// The edge functions of the lanes in `zero` recomputed in double precision (Woop et al.,
/// sec. 3): the rare exact zeros of a ray through an edge or a vertex.
#[cold]
#[inline(never)]
fn edge_functions_f64(zero: u32, corners: [Vec4; 6], uvw: [Vec4; 3]) -> (Vec4, Vec4, Vec4) {
    let [ax, ay, bx, by, cx, cy] = corners.map(|x| x.to_array().map(f64::from));
    let [mut u, mut v, mut w] = uvw.map(|x| x.to_array());
    for i in (0..4).filter(|i| zero & (1 << i) != 0) {
        u[i] = (cx[i] * by[i] - cy[i] * bx[i]) as f32;
        v[i] = (ax[i] * cy[i] - ay[i] * cx[i]) as f32;
        w[i] = (bx[i] * ay[i] - by[i] * ax[i]) as f32;
    }
    (Vec4::from_array(u), Vec4::from_array(v), Vec4::from_array(w))
}

impl LeafHits {
    /// No hit.
    const NONE: Self = Self { mask: 0, t: Vec4::ZERO, u: Vec4::ZERO, v: Vec4::ZERO };

    /// Distance and barycentrics of hit lane `i`.
    #[inline(always)]
    pub fn lane(&self, i: usize) -> (f32, Vec2) {
        (self.t.to_array()[i], Vec2::new(self.u.to_array()[i], self.v.to_array()[i]))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::ray::Ray;
    use crate::core::rng::{stream, uniform};
    use crate::core::sampling::uniform_sphere;

    #[test]
    fn lanes_match_the_scalar_test_bit_for_bit() {
        let mut r = stream(8, 0, 0);
        let mut p = || Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 4.0 - 2.0;
        let mut tris: Vec<TriangleRt> = (0..600).map(|_| TriangleRt::new(p(), p(), p())).collect();
        // Axis-aligned and shared-edge triangles hit exact zeros of the edge functions.
        tris.push(TriangleRt::new(Vec3::ZERO, Vec3::X, Vec3::Y));
        tris.push(TriangleRt::new(Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y));
        tris.push(TriangleRt::new(Vec3::ZERO, Vec3::Y, Vec3::Z));
        let leaves: Vec<(u32, u32)> =
            (0..tris.len() as u32).step_by(3).map(|f| (f, 3.min(tris.len() as u32 - f))).collect();
        // Leaves of 1 and 2 too.
        let mut split = vec![(0, 1), (1, 2)];
        split.extend(leaves.iter().skip(1));
        let packed = LeafTriangles::new(tris.len(), &split, |i| tris[i].vertices());
        for k in 0..4000u64 {
            let mut r = stream(8, 1, k);
            let o = Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 6.0 - 3.0;
            let d = match k % 5 {
                0 => (Vec3::new(0.5, 0.5, 0.0) - o).normalize(),
                1 => -Vec3::Z,
                _ => uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r))),
            };
            let ray = Ray::segment(o, d, 2.0 + 3.0 * uniform(&mut r));
            let s = RayShear::new(ray.origin, ray.dir);
            let leaf_ray = LeafRay::new(&s);
            for &(first, count) in &split {
                let hits = packed.intersect(first, count, &leaf_ray, ray.t_min, ray.t_max);
                for lane in 0..count as usize {
                    let tri = tris[first as usize + lane];
                    assert_eq!(packed.triangle(first, count, lane), tri);
                    let expected = tri.intersect_sheared(&s, ray.t_min, ray.t_max);
                    let got = (hits.mask & (1 << lane) != 0).then(|| hits.lane(lane));
                    assert_eq!(got, expected, "ray {k}, triangle {}", first as usize + lane);
                }
            }
        }
    }
}
