//! Form factors by ray casting: the unoccluded point-to-polygon form factor in closed form
//! (Lambert 1760; the contour integral of Baum, Rushmeier and Winget 1989, eq. 5), integrated
//! over the receiver by stratified Monte Carlo, with visibility from one shadow ray per
//! receiver point through the shared core's occlusion query (as the ray-traced form factors of
//! Wallace, Elmquist and Haines 1989).
//!
//! The estimator of the form factor from triangle `p` to triangle `q`, for `S` stratified
//! uniform points `x_k` on `p`:
//!
//! `F_pq ~ [(1/S) sum_k F(x_k -> q ∩ H(x_k))] · [sum_k w_k V_k / sum_k w_k]`
//!
//! where `F(x -> P) = |sum_edges gamma_e n·(R_e x R_e+1)/|R_e x R_e+1|| / (2 pi)` is the
//! exact form factor from the differential area at `x` (normal `n`) to the polygon `P`,
//! `H(x)` the half-space in front of `x` (so `q` is clipped to what `x` can see), `V_k` is 1
//! when the shadow ray from `x_k` to a uniform point `y_k` of the clipped polygon is free, and
//! `w_k = cos_x cos_y / (pi r^2) · area` its kernel weight: the visible fraction is weighted
//! by the kernel, pooled over the link's rays. Unoccluded, the estimator is unbiased and its
//! integrand is bounded (at most 1), so it keeps a finite variance even for patches that share
//! an edge, where the area-to-area estimator `cos cos / (pi r^2)` does not. Partly occluded,
//! the pooled ratio is consistent (bias O(1/S)); weighting the visible fraction by area
//! instead lost 7 % of the light in the closed Cornell box, where the blocks hide the grazing
//! (low-weight) directions of the floor.
//!
//! Surfaces are two-sided: the four numbers `f[a][b]` are the form factor from side `a` of `p`
//! (0 front, the side the winding's normal points to; 1 back) to side `b` of `q`.

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

use crate::core::rng::{Rng64, uniform};
use crate::core::sampling::{stratified_2d, uniform_triangle};
use crate::core::{Accel, Ray};

/// A planar triangle and what the form factors need of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tri {
    /// Corners, metres, in winding order.
    pub corners: [Vec3; 3],
    /// Unit normal of the winding (the front side).
    pub normal: Vec3,
    /// Area, m^2.
    pub area_m2: f32,
}

impl Tri {
    /// The triangle of corners `c`; `None` when it is degenerate (no area, or not finite).
    pub fn new(c: [Vec3; 3]) -> Option<Self> {
        let cross = (c[1] - c[0]).cross(c[2] - c[0]);
        let area_m2 = 0.5 * cross.length();
        (area_m2 > 0.0 && area_m2.is_finite()).then(|| Self {
            corners: c,
            normal: cross.normalize(),
            area_m2,
        })
    }

    /// The centroid.
    pub fn centroid(&self) -> Vec3 {
        (self.corners[0] + self.corners[1] + self.corners[2]) / 3.0
    }

    /// The point of barycentrics `b` (weights of the second and third corners).
    pub fn at(&self, b: Vec2) -> Vec3 {
        let [a, p1, p2] = self.corners;
        a + b.x * (p1 - a) + b.y * (p2 - a)
    }

    /// The four triangles of the midpoint subdivision: the three corner triangles, then the
    /// middle one. Each keeps the winding, so the normal and the side convention.
    pub fn split(&self) -> [Tri; 4] {
        let [a, b, c] = self.corners;
        let (ab, bc, ca) = ((a + b) * 0.5, (b + c) * 0.5, (c + a) * 0.5);
        let area_m2 = self.area_m2 * 0.25;
        let n = self.normal;
        [[a, ab, ca], [ab, b, bc], [ca, bc, c], [bc, ca, ab]].map(|corners| Tri {
            corners,
            normal: n,
            area_m2,
        })
    }

    /// The smallest barycentric coordinate of `x` projected onto the triangle's plane:
    /// non-negative inside, negative outside.
    pub fn min_barycentric(&self, x: Vec3) -> f32 {
        let [a, b, c] = self.corners;
        let n = (b - a).cross(c - a);
        let d = n.length_squared();
        let w1 = (x - a).cross(c - a).dot(n) / d;
        let w2 = (b - a).cross(x - a).dot(n) / d;
        w1.min(w2).min(1.0 - w1 - w2)
    }
}

/// A convex polygon of at most four corners: a triangle clipped by one plane.
#[derive(Clone, Copy, Debug, Default)]
pub struct Poly {
    /// Corners; the first `len` are used.
    pub corners: [Vec3; 4],
    /// Number of corners.
    pub len: usize,
}

impl Poly {
    /// The corners in use.
    pub fn points(&self) -> &[Vec3] {
        &self.corners[..self.len]
    }

    /// The area, m^2.
    pub fn area_m2(&self) -> f32 {
        let p = self.points();
        if p.len() < 3 {
            return 0.0;
        }
        (1..p.len() - 1).map(|i| (p[i] - p[0]).cross(p[i + 1] - p[0]).length()).sum::<f32>() * 0.5
    }

    /// A uniform point on the polygon (fan of triangles chosen by area) from `u` in [0,1)^3.
    pub fn sample(&self, u: Vec2, u_choice: f32) -> Vec3 {
        let p = self.points();
        let a0 = p[0];
        let area = |i: usize| (p[i] - a0).cross(p[i + 1] - a0).length();
        let total: f32 = (1..p.len() - 1).map(area).sum();
        let mut pick = u_choice * total;
        let mut i = 1;
        while i + 2 < p.len() && pick > area(i) {
            pick -= area(i);
            i += 1;
        }
        let b = uniform_triangle(u);
        a0 + b.x * (p[i] - a0) + b.y * (p[i + 1] - a0)
    }
}

/// Triangle `t` clipped to the half-space `n·(y - x) >= 0` (Sutherland-Hodgman, one plane).
pub fn clip(t: &Tri, x: Vec3, n: Vec3) -> Poly {
    let mut out = Poly::default();
    let d = t.corners.map(|c| n.dot(c - x));
    for i in 0..3 {
        let j = (i + 1) % 3;
        let (a, b) = (t.corners[i], t.corners[j]);
        if d[i] >= 0.0 {
            out.corners[out.len] = a;
            out.len += 1;
        }
        if (d[i] >= 0.0) != (d[j] >= 0.0) {
            let s = d[i] / (d[i] - d[j]);
            out.corners[out.len] = a + s * (b - a);
            out.len += 1;
        }
    }
    out
}

/// The exact form factor from a differential area at `x` with unit normal `n` to the polygon
/// `p`, which must lie in front of `x` (`n·(y - x) >= 0`, see [`clip`]): Lambert's contour
/// formula `|sum_e gamma_e n·(R_e x R_e+1)/|R_e x R_e+1|| / (2 pi)`, `R_e` the corners
/// relative to `x`, `gamma_e` the angle between consecutive ones (Baum et al. 1989, eq. 5).
pub fn point_to_polygon(x: Vec3, n: Vec3, p: &[Vec3]) -> f32 {
    if p.len() < 3 {
        return 0.0;
    }
    let mut sum = 0.0f32;
    for i in 0..p.len() {
        let (a, b) = (p[i] - x, p[(i + 1) % p.len()] - x);
        let c = a.cross(b);
        let len = c.length();
        if len <= 0.0 || !len.is_finite() {
            continue;
        }
        let gamma = len.atan2(a.dot(b));
        sum += gamma * n.dot(c) / len;
    }
    (sum.abs() / (2.0 * PI)).min(1.0)
}

/// Which side of `q` a point `x` sees: 0 front, 1 back, `None` in its plane.
#[inline]
fn side_seen(q: &Tri, x: Vec3) -> Option<usize> {
    let d = q.normal.dot(x - q.corners[0]);
    if d > 0.0 {
        Some(0)
    } else if d < 0.0 {
        Some(1)
    } else {
        None
    }
}

/// The unoccluded form factor from the point `x` of `p` to `q`, per side pair: cheap, for the
/// refinement oracle (no rays).
pub fn from_point(p: &Tri, x: Vec3, q: &Tri) -> [[f32; 2]; 2] {
    let mut f = [[0.0; 2]; 2];
    let Some(b) = side_seen(q, x) else { return f };
    for (a, n) in [(0, p.normal), (1, -p.normal)] {
        let poly = clip(q, x, n);
        f[a][b] = point_to_polygon(x, n, poly.points());
    }
    f
}

/// The form factor from `p` to `q` by the estimator of the module's doc with `samples` points
/// on `p` (a square number of strata, at least 1), drawing from `rng`; occlusion is tested on
/// `accel` (pass `None` for an empty scene). Returns the side pairs and the rays cast.
pub fn estimate(
    accel: Option<&Accel>,
    p: &Tri,
    q: &Tri,
    samples: u32,
    rng: &mut Rng64,
) -> ([[f32; 2]; 2], u64) {
    let side = (samples.max(1) as f32).sqrt().floor().max(1.0) as usize;
    let count = side * side;
    // Per side pair: the sum of point form factors, and the kernel weights of all and of the
    // visible shadow rays (the visible fraction, weighted by the kernel).
    let mut f = [[0.0f32; 2]; 2];
    let mut weight = [[0.0f32; 2]; 2];
    let mut visible = [[0.0f32; 2]; 2];
    let mut rays = 0u64;
    for k in 0..count {
        let u = stratified_2d(k, side, side, Vec2::new(uniform(rng), uniform(rng)));
        let x = p.at(uniform_triangle(u));
        let (uy, uc) = (Vec2::new(uniform(rng), uniform(rng)), uniform(rng));
        let Some(b) = side_seen(q, x) else { continue };
        for (a, n) in [(0, p.normal), (1, -p.normal)] {
            let poly = clip(q, x, n);
            let ff = point_to_polygon(x, n, poly.points());
            if ff <= 0.0 {
                continue;
            }
            f[a][b] += ff;
            if let Some(accel) = accel {
                let y = poly.sample(uy, uc);
                let d = y - x;
                let r2 = d.length_squared();
                if r2 <= 0.0 {
                    continue;
                }
                // cos_x cos_y / (pi r^2) times the clipped area: the area-sampling estimate
                // of the same point form factor.
                let w = n.dot(d).max(0.0) * q.normal.dot(d).abs() / (PI * r2 * r2) * poly.area_m2();
                if !(w.is_finite() && w > 0.0) {
                    continue;
                }
                rays += 1;
                weight[a][b] += w;
                if !accel.occluded(&Ray::between(x, n, y, q.normal)) {
                    visible[a][b] += w;
                }
            }
        }
    }
    for a in 0..2 {
        for b in 0..2 {
            f[a][b] /= count as f32;
            if accel.is_some() {
                f[a][b] *= if weight[a][b] > 0.0 { visible[a][b] / weight[a][b] } else { 0.0 };
            }
        }
    }
    (f, rays)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A differential area under the centre of a parallel square of side `2a` at height `h`:
    /// four times the catalogue's rectangle with a corner above the point (Howell's catalogue,
    /// B-3): `(1/2pi) [A/sqrt(1+A^2) atan(B/sqrt(1+A^2)) + B/sqrt(1+B^2) atan(A/sqrt(1+B^2))]`,
    /// `A = B = a/h`.
    #[test]
    fn point_to_square_matches_the_catalogue() {
        let (a, h) = (0.7f32, 1.3f32);
        let corner = |x: f32, y: f32| Vec3::new(x, y, h);
        let square = [corner(-a, -a), corner(a, -a), corner(a, a), corner(-a, a)];
        let f = point_to_polygon(Vec3::ZERO, Vec3::Z, &square);
        let r = a / h;
        let s = (1.0 + r * r).sqrt();
        let quarter = (1.0 / (2.0 * PI)) * 2.0 * (r / s) * (r / s).atan();
        assert!((f - 4.0 * quarter).abs() < 1e-5, "{f} vs {}", 4.0 * quarter);
    }

    /// Clipping keeps what is in front and the form factor of a polygon across the horizon is
    /// that of its visible part.
    #[test]
    fn clipping_keeps_the_front_part() {
        let t = Tri::new([Vec3::new(0.0, 0.0, -1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::new(0.0, 1.0, 1.0)])
            .unwrap();
        let p = clip(&t, Vec3::ZERO, Vec3::Z);
        assert_eq!(p.len, 4);
        assert!(p.points().iter().all(|c| c.z >= -1e-6));
        let back = clip(&t, Vec3::ZERO, -Vec3::Z);
        assert_eq!(back.len, 3);
    }
}
