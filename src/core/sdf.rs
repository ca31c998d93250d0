//! Signed distance fields: solids given by a function `f(p)` that is negative inside, positive
//! outside and never more than `L` times the distance to the surface (`L`, the field's
//! Lipschitz bound, is 1 for an exact distance), intersected by sphere tracing ([Hart1996]):
//! from a point where `f = d`, no surface lies within `d / L`, so the ray may advance that far.
//!
//! The primitives are Quilez's distance functions ([Quilez]: sphere, box, rounded box, torus,
//! capsule; exact distances), his quadratic smooth minimum for the smooth union and
//! subtraction, and the power-`n` Mandelbulb ([White2009]) with the distance estimate
//! `0.5 ln(r) r / dr` ([HartSandinKauffman1989]). Each node may be placed by a similarity
//! (rotation, translation, one scale `s`: the distance scales by `s` and stays a distance).
//!
//! The tracer steps by `omega d / L` with over-relaxation `omega = 1.5` ([Keinert2014]),
//! falling back to the plain step `d / L` whenever the unbounding spheres of two successive
//! points do not overlap (the long step may have jumped a surface), and stops at
//! `d / L < eps(t)` with `eps(t) = ACCURACY_RELATIVE (t + extent)` (`extent`: half the
//! diagonal of the field's box), then refines the hit by secant steps along the ray. For an
//! exact-distance field the reported point lies within `eps(t)` of the surface; a ray that
//! passes farther than `eps` from the surface is never reported as a hit and, since no step
//! can cross the surface, a ray that meets it is never missed. A ray that runs out of its step
//! budget (creeping along a surface it nearly grazes) is a hit where it came within `2 eps`,
//! else a miss; the scene loader refuses a field on which that happens to more than 1 % of
//! probe rays (`crate::scene::sdf`). Tags: docs/references.md.

use glam::{Affine3A, Vec3};

use super::accel::instances::transformed_box;
use super::hit::SurfaceId;
use super::ray::Ray;

/// `eps(t) / (t + extent)`: the relative accuracy of a hit (0.1 mm per metre).
pub const ACCURACY_RELATIVE: f32 = 1.0e-4;
/// Over-relaxation factor of the long steps (Keinert et al. 2014 use 1.2 to 1.6).
const OVER_RELAXATION: f32 = 1.5;
/// Default budget of distance evaluations per ray.
pub const DEFAULT_MAX_STEPS: u32 = 512;
/// Lipschitz bound taken for the Mandelbulb's distance estimate. The estimate is only
/// asymptotically a distance ([HartSandinKauffman1989]), not a strict bound: on 84,967
/// pairs of points 1 cm apart outside the power-8 bulb (unit size), 13 difference quotients
/// exceeded 1.25 (the largest 3.2; the test `mandelbulb_lies_inside_its_box_and_within_its_
/// lipschitz_bound`), so a step may rarely overshoot a fine detail of the fractal.
pub const MANDELBULB_LIPSCHITZ: f32 = 1.25;
/// Escape radius of the Mandelbulb iteration.
const MANDELBULB_BAILOUT: f32 = 2.0;

/// A canonical distance function in its own frame.
#[derive(Clone, Debug, PartialEq)]
pub enum SdfShape {
    /// A sphere of radius `radius_m` about the origin.
    Sphere {
        /// Radius, metres.
        radius_m: f32,
    },
    /// A box of half sides `half_m` about the origin.
    Box {
        /// Half side lengths, metres.
        half_m: Vec3,
    },
    /// A box of half sides `half_m` (outer) whose edges are rounded with radius `rounding_m`.
    RoundBox {
        /// Outer half side lengths, metres.
        half_m: Vec3,
        /// Rounding radius, metres (at most the smallest half side).
        rounding_m: f32,
    },
    /// A torus about the z axis: a circle of radius `major_m` in the xy plane, thickened by
    /// `minor_m`.
    Torus {
        /// Radius of the centre circle, metres.
        major_m: f32,
        /// Radius of the tube, metres.
        minor_m: f32,
    },
    /// The points within `radius_m` of the segment `a`-`b`.
    Capsule {
        /// One end of the axis, metres.
        a: Vec3,
        /// The other end, metres.
        b: Vec3,
        /// Radius, metres.
        radius_m: f32,
    },
    /// The power-`power` Mandelbulb (unit size: it fits in a sphere of radius 1.25 for power
    /// 8, in the box of half side 2, the escape radius, for any power), `iterations`
    /// iterations of `z -> z^power + p` in spherical coordinates.
    Mandelbulb {
        /// The exponent (8 gives the classic bulb).
        power: f32,
        /// Iterations of the map.
        iterations: u32,
    },
    /// Quilez's smooth union of the children (folded left to right): within `blend_m` of
    /// both, the surfaces melt into each other.
    SmoothUnion {
        /// The joined fields.
        children: Vec<SdfNode>,
        /// Width of the blend, metres (0: the plain union).
        blend_m: f32,
    },
    /// The first child with the others carved out, the cut edges rounded over `blend_m`.
    SmoothSubtraction {
        /// The solid, then the cutters.
        children: Vec<SdfNode>,
        /// Width of the blend, metres (0: the plain difference).
        blend_m: f32,
    },
}

/// A distance function placed in its parent's frame by a similarity.
#[derive(Clone, Debug, PartialEq)]
pub struct SdfNode {
    /// The canonical function.
    pub shape: SdfShape,
    /// Parent to local frame (the inverse of the placement).
    parent_to_local: Affine3A,
    /// The placement's scale factor: distances in the parent frame are this times the local.
    scale: f32,
}

/// Quilez's quadratic smooth minimum: `min(a, b) - h^2 k / 4` with
/// `h = max(k - |a - b|, 0) / k`. Its partial derivatives are nonnegative and sum to 1, so it
/// keeps a Lipschitz bound of its arguments, and it is at most `k / 4` below `min(a, b)`.
#[inline]
pub fn smooth_min(a: f32, b: f32, k: f32) -> f32 {
    if k <= 0.0 {
        return a.min(b);
    }
    let h = (k - (a - b).abs()).max(0.0) / k;
    a.min(b) - h * h * k * 0.25
}

/// The smooth maximum, `-smooth_min(-a, -b)`.
#[inline]
pub fn smooth_max(a: f32, b: f32, k: f32) -> f32 {
    -smooth_min(-a, -b, k)
}

impl SdfShape {
    /// The function at `p` (local frame).
    fn distance(&self, p: Vec3) -> f32 {
        match self {
            SdfShape::Sphere { radius_m } => p.length() - radius_m,
            SdfShape::Box { half_m } => {
                let q = p.abs() - *half_m;
                q.max(Vec3::ZERO).length() + q.max_element().min(0.0)
            }
            SdfShape::RoundBox { half_m, rounding_m } => {
                let q = p.abs() - *half_m + Vec3::splat(*rounding_m);
                q.max(Vec3::ZERO).length() + q.max_element().min(0.0) - rounding_m
            }
            SdfShape::Torus { major_m, minor_m } => {
                let radial = (p.x * p.x + p.y * p.y).sqrt() - major_m;
                (radial * radial + p.z * p.z).sqrt() - minor_m
            }
            SdfShape::Capsule { a, b, radius_m } => {
                let (pa, ba) = (p - *a, *b - *a);
                let h = (pa.dot(ba) / ba.dot(ba)).clamp(0.0, 1.0);
                (pa - ba * h).length() - radius_m
            }
            SdfShape::Mandelbulb { power, iterations } => mandelbulb(p, *power, *iterations),
            SdfShape::SmoothUnion { children, blend_m } => children
                .iter()
                .map(|c| c.distance(p))
                .reduce(|a, b| smooth_min(a, b, *blend_m))
                .unwrap_or(f32::INFINITY),
            SdfShape::SmoothSubtraction { children, blend_m } => {
                let mut it = children.iter().map(|c| c.distance(p));
                let first = it.next().unwrap_or(f32::INFINITY);
                it.fold(first, |a, b| smooth_max(a, -b, *blend_m))
            }
        }
    }

    /// Local box holding the surface.
    fn bounds(&self) -> (Vec3, Vec3) {
        match self {
            SdfShape::Sphere { radius_m } => (Vec3::splat(-radius_m), Vec3::splat(*radius_m)),
            SdfShape::Box { half_m } | SdfShape::RoundBox { half_m, .. } => (-*half_m, *half_m),
            SdfShape::Torus { major_m, minor_m } => {
                let r = major_m + minor_m;
                (Vec3::new(-r, -r, -minor_m), Vec3::new(r, r, *minor_m))
            }
            SdfShape::Capsule { a, b, radius_m } => (a.min(*b) - *radius_m, a.max(*b) + *radius_m),
            // Beyond the escape radius the iteration stops at once with an estimate of at
            // least 0.5 ln(2) 2 = 0.69: no surface lies there, whatever the power.
            SdfShape::Mandelbulb { .. } => {
                (Vec3::splat(-MANDELBULB_BAILOUT), Vec3::splat(MANDELBULB_BAILOUT))
            }
            SdfShape::SmoothUnion { children, blend_m } => {
                // The smooth minimum lies at most blend / 4 below the plain one.
                let (lo, hi) = children
                    .iter()
                    .map(SdfNode::bounds)
                    .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), (a, b)| (lo.min(a), hi.max(b)));
                (lo - 0.25 * blend_m, hi + 0.25 * blend_m)
            }
            // The smooth maximum only ever removes from the first child.
            SdfShape::SmoothSubtraction { children, .. } => {
                children.first().map_or((Vec3::ZERO, Vec3::ZERO), SdfNode::bounds)
            }
        }
    }

    /// Lipschitz bound of the function.
    fn lipschitz(&self) -> f32 {
        match self {
            SdfShape::Mandelbulb { .. } => MANDELBULB_LIPSCHITZ,
            SdfShape::SmoothUnion { children, .. } | SdfShape::SmoothSubtraction { children, .. } => {
                children.iter().map(SdfNode::lipschitz).fold(1.0, f32::max)
            }
            _ => 1.0,
        }
    }
}

/// The Mandelbulb's distance estimate `0.5 ln(r) r / dr` at `p`, with `dr` the running
/// derivative `n r^(n-1) dr + 1` of the iteration (White and Nylander's formula).
fn mandelbulb(p: Vec3, power: f32, iterations: u32) -> f32 {
    let mut z = p;
    let mut dr = 1.0f32;
    let mut r = z.length();
    for _ in 0..iterations {
        r = z.length();
        if !(1.0e-12..=MANDELBULB_BAILOUT).contains(&r) {
            break;
        }
        let theta = (z.z / r).clamp(-1.0, 1.0).acos() * power;
        let phi = z.y.atan2(z.x) * power;
        let rn1 = r.powf(power - 1.0);
        dr = rn1 * power * dr + 1.0;
        let zr = rn1 * r;
        z = zr * Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()) + p;
        r = z.length();
    }
    let d = 0.5 * r.max(1.0e-12).ln() * r / dr;
    // Deep inside (r tiny) the estimate is a tiny negative number: inside either way.
    if d.is_finite() { d } else { 0.0 }
}

impl SdfNode {
    /// `shape` placed in its parent's frame by `local_to_parent`; `None` unless that is an
    /// invertible similarity (a rotation, a translation and one scale factor), the only
    /// transforms under which a distance stays a distance.
    pub fn new(shape: SdfShape, local_to_parent: Affine3A) -> Option<Self> {
        if !super::accel::Instance::transform_is_valid(&local_to_parent) {
            return None;
        }
        let m = local_to_parent.matrix3;
        let (x, y, z) = (m.x_axis, m.y_axis, m.z_axis);
        let s = x.length();
        let tol = 1.0e-4 * s;
        let similar = (y.length() - s).abs() <= tol
            && (z.length() - s).abs() <= tol
            && x.dot(y).abs() <= tol * s
            && x.dot(z).abs() <= tol * s
            && y.dot(z).abs() <= tol * s;
        similar.then(|| Self { shape, parent_to_local: local_to_parent.inverse(), scale: s })
    }

    /// The function at `p` (parent frame).
    #[inline]
    pub fn distance(&self, p: Vec3) -> f32 {
        self.scale * self.shape.distance(self.parent_to_local.transform_point3(p))
    }

    /// Box holding the surface, parent frame.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let (lo, hi) = self.shape.bounds();
        transformed_box(&self.parent_to_local.inverse(), lo, hi)
    }

    /// Lipschitz bound of [`SdfNode::distance`] (a similarity keeps it).
    pub fn lipschitz(&self) -> f32 {
        self.shape.lipschitz()
    }
}

/// How a march ended.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum March {
    /// The surface at this `t`.
    Hit(f32),
    /// No surface on the segment.
    Miss,
    /// The step budget ran out; the `t` where the field came nearest (in units of `eps`),
    /// and that ratio.
    Exhausted(f32, f32),
}

/// A placed signed distance field, ready for sphere tracing.
#[derive(Clone, Debug)]
pub struct Sdf {
    /// The field (world frame).
    pub root: SdfNode,
    /// World box holding the surface.
    lo: Vec3,
    hi: Vec3,
    /// Half the diagonal of the box, metres (the scale of `eps`).
    extent_m: f32,
    lipschitz: f32,
    /// Budget of distance evaluations per ray.
    max_steps: u32,
}

impl Sdf {
    /// `root` (in world coordinates) traced with at most `max_steps` evaluations per ray.
    pub fn new(root: SdfNode, max_steps: u32) -> Self {
        let (lo, hi) = root.bounds();
        let extent_m = 0.5 * (hi - lo).length();
        let lipschitz = root.lipschitz();
        Self { root, lo, hi, extent_m, lipschitz, max_steps: max_steps.max(1) }
    }

    /// World box `(lo, hi)` holding the surface.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (self.lo, self.hi)
    }

    /// The field at a world point.
    #[inline]
    pub fn distance(&self, p: Vec3) -> f32 {
        self.root.distance(p)
    }

    /// The hit tolerance at ray distance `t_m`, metres.
    #[inline]
    pub fn accuracy_m(&self, t_m: f32) -> f32 {
        ACCURACY_RELATIVE * (t_m.max(0.0) + self.extent_m)
    }

    /// Unit outward normal at `p`: the field's gradient by Quilez's tetrahedral differences
    /// (four evaluations at `p + h k_i`, `k_i` the corners of a tetrahedron) with step `h`.
    pub fn normal(&self, p: Vec3, h: f32) -> Vec3 {
        let k =
            [Vec3::new(1.0, -1.0, -1.0), Vec3::new(-1.0, -1.0, 1.0), Vec3::new(-1.0, 1.0, -1.0), Vec3::ONE];
        let g = k.iter().fold(Vec3::ZERO, |g, &k| g + k * self.distance(p + h * k));
        let n = g.normalize_or_zero();
        if n == Vec3::ZERO { Vec3::Z } else { n }
    }

    /// The ray's span `(t0, t1)` inside the (padded) box, if any.
    fn span(&self, ray: &Ray) -> Option<(f32, f32)> {
        let pad = self.accuracy_m(0.0);
        let inv = ray.dir.recip();
        let (a, b) = ((self.lo - pad - ray.origin) * inv, (self.hi + pad - ray.origin) * inv);
        // A zero direction component gives 0 * inf = NaN on a slab plane: treat as inside.
        let near = a.min(b);
        let far = a.max(b);
        let pick = |v: Vec3, f: fn(f32, f32) -> f32, init: f32| {
            [v.x, v.y, v.z].into_iter().filter(|x| !x.is_nan()).fold(init, f)
        };
        let t0 = pick(near, f32::max, ray.t_min);
        let t1 = pick(far, f32::min, ray.t_max);
        (t0 <= t1).then_some((t0, t1))
    }

    /// Sphere traces `ray` over `(t_min, t_max]` (see the module comment).
    pub fn march(&self, ray: &Ray) -> March {
        let Some((t0, t1)) = self.span(ray) else { return March::Miss };
        let dl = ray.dir.length();
        if !(dl > 0.0 && dl.is_finite()) {
            return March::Miss;
        }
        // Field values to ray parameter: a value d lets the ray advance d / (L |dir|).
        let to_t = 1.0 / (self.lipschitz * dl);
        let eps_t = |t: f32| self.accuracy_m(t * dl) / dl;
        let start = ray.at(t0);
        let f0 = self.distance(start);
        let e0 = eps_t(t0);
        // Which side the ray travels on: inside traces the way out. Starting in the box on
        // the surface (a secondary ray), the side is where the ray heads, and the ray must
        // first leave the band |f| < eps it starts in (it is "armed" once out).
        let entered = t0 > ray.t_min;
        let sign = if entered || f0 * to_t >= e0 {
            1.0
        } else if f0 * to_t <= -e0 {
            -1.0
        } else if self.normal(start, e0 * dl).dot(ray.dir) >= 0.0 {
            1.0
        } else {
            -1.0
        };
        // A ray from outside the box starts at least the box's padding away from the
        // surface, outside the solid: a hit may come at once.
        let mut armed = entered || (sign * f0) * to_t >= e0;
        let (mut t, mut t_prev, mut r_prev) = (t0, t0, 0.0f32);
        let mut omega = OVER_RELAXATION;
        let mut relaxed = false;
        let (mut best_t, mut best_ratio) = (t0, f32::INFINITY);
        for _ in 0..self.max_steps {
            let r = sign * self.distance(ray.at(t)) * to_t;
            let e = eps_t(t);
            // A long step is valid when the unbounding spheres at both ends overlap; else
            // take the plain step from the previous point, and no more long ones.
            if relaxed && (r < 0.0 || r_prev + r < t - t_prev) {
                t = t_prev + r_prev;
                omega = 1.0;
                relaxed = false;
                continue;
            }
            if armed && r < e {
                return self.refine(ray, sign * to_t, (t_prev, r_prev), (t, r), t1);
            }
            if !armed && r >= e {
                armed = true;
            }
            if armed && r / e < best_ratio {
                (best_t, best_ratio) = (t, r / e);
            }
            let step = if armed { omega * r } else { r.abs().max(e) };
            relaxed = armed && omega > 1.0;
            (t_prev, r_prev) = (t, r);
            t += step;
            // (A NaN step, which no finite field gives, ends the march too.)
            if t.is_nan() || t > t1 {
                // A long step may leave the box past a surface near its face: take the plain
                // one instead.
                if !relaxed {
                    return March::Miss;
                }
                (t, omega, relaxed) = (t_prev + r_prev, 1.0, false);
                if t > t1 {
                    return March::Miss;
                }
            }
        }
        March::Exhausted(best_t, best_ratio)
    }

    /// Secant steps from the hit `(t, r)` (with the previous sample `(t_prev, r_prev)`)
    /// towards the zero of the field along the ray, or a plain sphere-tracing step where
    /// the two samples give no secant (a hit at the first sample); the best point found, if
    /// within the segment.
    fn refine(&self, ray: &Ray, scale: f32, prev: (f32, f32), hit: (f32, f32), t1: f32) -> March {
        let (mut a, mut b) = (prev, hit);
        let mut best = hit;
        let fine = 1.0e-3 * (hit.1.abs() + f32::MIN_POSITIVE);
        for _ in 0..6 {
            if best.1.abs() <= fine {
                break;
            }
            let slope = b.1 - a.1;
            let t = if slope < 0.0 && b.0 > a.0 { b.0 - b.1 * (b.0 - a.0) / slope } else { b.0 + b.1 };
            if !(t.is_finite() && t > a.0.min(b.0)) || t == b.0 {
                break;
            }
            let r = self.distance(ray.at(t)) * scale;
            if r.abs() < best.1.abs() {
                best = (t, r);
            }
            (a, b) = (b, (t, r));
        }
        if best.0 <= t1 && best.0 > ray.t_min { March::Hit(best.0) } else { March::Miss }
    }

    /// The nearest hit on `(t_min, t_max]`: distance and unit outward normal. A ray that runs
    /// out of steps counts as a hit where it came within 2 `eps` of the surface (it was
    /// creeping along it), else as a miss.
    pub fn intersect(&self, ray: &Ray) -> Option<(f32, Vec3)> {
        let t = self.hit_distance(ray)?;
        let dl = ray.dir.length();
        let h = 0.5 * self.accuracy_m(t * dl);
        Some((t, self.normal(ray.at(t), h)))
    }
}

impl Sdf {
    /// The distance of [`Sdf::intersect`]'s hit, without the normal (shadow rays).
    pub fn hit_distance(&self, ray: &Ray) -> Option<f32> {
        match self.march(ray) {
            March::Hit(t) => Some(t),
            March::Exhausted(t, ratio) if ratio < 2.0 => Some(t),
            _ => None,
        }
    }
}

/// The placed fields of a scene, each with its surface; tested one after the other behind a
/// box test (scenes hold a handful).
#[derive(Default)]
pub struct SdfSet {
    /// The fields and their surfaces.
    pub sdfs: Vec<(Sdf, SurfaceId)>,
}

impl SdfSet {
    /// A set of `sdfs`.
    pub fn new(sdfs: Vec<(Sdf, SurfaceId)>) -> Self {
        Self { sdfs }
    }

    /// Whether there is no field.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.sdfs.is_empty()
    }

    /// The closest hit: (index, distance, unit outward normal).
    pub fn closest(&self, ray: &Ray) -> Option<(usize, f32, Vec3)> {
        let mut r = *ray;
        let mut best = None;
        for (i, (s, _)) in self.sdfs.iter().enumerate() {
            if let Some((t, n)) = s.intersect(&r) {
                r.t_max = t;
                best = Some((i, t, n));
            }
        }
        best
    }

    /// Whether any field blocks the segment.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.sdfs.iter().any(|(s, _)| s.hit_distance(ray).is_some())
    }
}

#[cfg(test)]
mod tests {
    use glam::{Quat, Vec2};

    use super::*;
    use crate::core::rng::{stream, uniform};
    use crate::core::sampling::uniform_sphere;

    fn bulb() -> Sdf {
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::splat(0.5),
            Quat::from_rotation_z(0.3),
            Vec3::ONE,
        );
        Sdf::new(
            SdfNode::new(SdfShape::Mandelbulb { power: 8.0, iterations: 8 }, m).unwrap(),
            DEFAULT_MAX_STEPS,
        )
    }

    #[test]
    fn only_similarities_place_a_field() {
        let s = SdfShape::Sphere { radius_m: 1.0 };
        assert!(SdfNode::new(s.clone(), Affine3A::from_scale(Vec3::new(1.0, 2.0, 1.0))).is_none());
        assert!(SdfNode::new(s.clone(), Affine3A::from_scale(Vec3::ZERO)).is_none());
        let n = SdfNode::new(
            s,
            Affine3A::from_scale_rotation_translation(Vec3::splat(2.0), Quat::from_rotation_x(1.0), Vec3::X),
        )
        .unwrap();
        // A sphere of radius 2 about (1, 0, 0): the exact distance.
        assert!((n.distance(Vec3::new(1.0, 5.0, 0.0)) - 3.0).abs() < 1e-5);
    }

    #[test]
    fn primitives_are_exact_distances_where_closed_forms_are_simple() {
        let b = SdfShape::Box { half_m: Vec3::new(1.0, 2.0, 3.0) };
        assert!((b.distance(Vec3::new(3.0, 0.0, 0.0)) - 2.0).abs() < 1e-6);
        assert!((b.distance(Vec3::new(2.0, 3.0, 0.0)) - 2f32.sqrt()).abs() < 1e-6);
        assert!((b.distance(Vec3::ZERO) + 1.0).abs() < 1e-6);
        let t = SdfShape::Torus { major_m: 2.0, minor_m: 0.5 };
        assert!((t.distance(Vec3::new(0.0, 2.0, 1.5)) - 1.0).abs() < 1e-6);
        assert!((t.distance(Vec3::ZERO) - 1.5).abs() < 1e-6);
        let c = SdfShape::Capsule { a: Vec3::ZERO, b: Vec3::Z, radius_m: 0.25 };
        assert!((c.distance(Vec3::new(1.0, 0.0, 0.5)) - 0.75).abs() < 1e-6);
        assert!((c.distance(Vec3::new(0.0, 0.0, 2.0)) - 0.75).abs() < 1e-6);
        let r = SdfShape::RoundBox { half_m: Vec3::ONE, rounding_m: 0.25 };
        // Along an axis the face is flat; towards a corner the rounding cuts (sqrt(3) - 1) 0.25.
        assert!((r.distance(Vec3::new(2.0, 0.0, 0.0)) - 1.0).abs() < 1e-6);
        let corner = Vec3::splat(0.75) + Vec3::splat(0.25 / 3f32.sqrt());
        assert!(r.distance(corner).abs() < 1e-6);
    }

    #[test]
    fn mandelbulb_lies_inside_its_box_and_within_its_lipschitz_bound() {
        for power in [2.0, 5.0, 16.0] {
            let b = SdfShape::Mandelbulb { power, iterations: 12 };
            for k in 0..10_000u64 {
                let mut r = stream(4, 0, k);
                let mut p = Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 4.0 - 2.0;
                p[k as usize % 3] = if k % 2 == 0 { -2.0 } else { 2.0 };
                assert!(b.distance(p) > 0.5, "power {power}, {p}: {}", b.distance(p));
            }
        }
        let shape = SdfShape::Mandelbulb { power: 8.0, iterations: 8 };
        let (mut worst, mut over, mut pairs) = (0.0f32, 0, 0);
        let mut inside = 0;
        for k in 0..100_000u64 {
            let mut r = stream(3, 0, k);
            // The power-8 bulb lies within 1.25 of the origin.
            let p = 1.25 * uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            assert!(shape.distance(p) > 0.01, "{p}: {}", shape.distance(p));
            // Pairs of nearby points around the bulb.
            let x = (Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 2.0 - 1.0) * 1.3;
            let y = x + 0.01 * uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            let (fx, fy) = (shape.distance(x), shape.distance(y));
            inside += usize::from(fx < 0.0);
            // Outside, where the rays march (inside, the estimate is no distance).
            if fx > 0.0 && fy > 0.0 {
                let q = (fx - fy).abs() / (x - y).length();
                worst = worst.max(q);
                pairs += 1;
                over += usize::from(q > MANDELBULB_LIPSCHITZ);
            }
        }
        assert!(inside > 1000, "{inside} points inside the bulb");
        eprintln!(
            "Mandelbulb: largest difference quotient outside {worst}; {over} of {pairs} above the bound"
        );
        // Not a strict bound: the estimate is only asymptotically a distance.
        assert!(over * 1000 < pairs, "{over} of {pairs} difference quotients above {MANDELBULB_LIPSCHITZ}");
    }

    #[test]
    fn secondary_rays_leave_the_surface_and_refracted_rays_find_the_exit() {
        let sphere =
            Sdf::new(SdfNode::new(SdfShape::Sphere { radius_m: 1.0 }, Affine3A::IDENTITY).unwrap(), 512);
        for k in 0..10_000u64 {
            let mut r = stream(5, 0, k);
            let n = uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            let o = -4.0 * n + 0.3 * uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            let Some((t, normal)) = sphere.intersect(&Ray::new(o, (n * 0.9 - o).normalize())) else {
                panic!("ray {k} misses")
            };
            let p = Ray::new(o, (n * 0.9 - o).normalize()).at(t);
            // Leaving outwards (reflected, any direction in the outer hemisphere): no hit.
            let mut d = uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            if d.dot(normal) < 0.0 {
                d = -d;
            }
            assert!(sphere.intersect(&Ray::spawn(p, normal, d)).is_none(), "ray {k} re-hits its surface");
            // Going in: the exit on the far side, at the chord length 2 |cos|.
            let chord = 2.0 * d.dot(normal).abs();
            let hit = sphere.intersect(&Ray::spawn(p, normal, -d));
            // A chord shorter than sqrt(8 eps) never goes eps deep: inside the accuracy band.
            if chord > 0.1 {
                let ray2 = Ray::spawn(p, normal, -d);
                let (t2, _) = hit.unwrap_or_else(|| {
                    panic!(
                        "ray {k}: no exit: cos {}, f(p) {}, f(o) {}, march {:?}, dl {}",
                        d.dot(normal),
                        sphere.distance(p),
                        sphere.distance(ray2.origin),
                        sphere.march(&ray2),
                        ray2.dir.length()
                    )
                });
                assert!((t2 - chord).abs() < 1e-3 / d.dot(normal).abs(), "ray {k}: exit {t2} vs {chord}");
            }
        }
    }

    #[test]
    fn over_relaxed_steps_never_jump_a_thin_wall() {
        // A slab 1 mm thick (a flat box) behind a sphere that pulls the steps long.
        let wall =
            SdfNode::new(SdfShape::Box { half_m: Vec3::new(2.0, 2.0, 0.0005) }, Affine3A::IDENTITY).unwrap();
        let ball = SdfNode::new(
            SdfShape::Sphere { radius_m: 0.2 },
            Affine3A::from_translation(Vec3::new(0.0, 3.0, 0.0)),
        )
        .unwrap();
        let both = SdfNode::new(
            SdfShape::SmoothUnion { children: vec![wall, ball], blend_m: 0.0 },
            Affine3A::IDENTITY,
        )
        .unwrap();
        let sdf = Sdf::new(both, 4096);
        for k in 0..10_000u64 {
            let mut r = stream(9, 0, k);
            let target = Vec3::new(uniform(&mut r) * 3.0 - 1.5, uniform(&mut r) * 3.0 - 1.5, 0.0);
            let o =
                Vec3::new(uniform(&mut r) * 6.0 - 3.0, uniform(&mut r) * 6.0 - 3.0, 1.0 + uniform(&mut r));
            let ray = Ray::new(o, (target - o).normalize());
            let (t, _) = sdf.intersect(&ray).unwrap_or_else(|| panic!("ray {k} misses the wall"));
            assert!(ray.at(t).z > 0.0 && ray.at(t).z < 0.0005 + sdf.accuracy_m(t), "ray {k}: {}", ray.at(t));
        }
        let _ = bulb();
    }

    #[test]
    fn the_bulb_is_traced_within_the_budget() {
        let b = bulb();
        let (lo, hi) = b.bounds();
        let (mut hits, mut stuck) = (0, 0);
        for k in 0..2000u64 {
            let mut r = stream(21, 0, k);
            let target = lo + (hi - lo) * Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r));
            let o = target + 5.0 * uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            match b.march(&Ray::new(o, (target - o).normalize())) {
                March::Hit(_) => hits += 1,
                March::Exhausted(..) => stuck += 1,
                March::Miss => {}
            }
        }
        assert!(hits > 100 && stuck < 20, "{hits} hits, {stuck} out of steps");
    }
}
