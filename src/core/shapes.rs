//! Transformed analytic primitives: spheres (ellipsoids once transformed), cylinders, cones,
//! disks, boxes and general quadrics, each a canonical shape in its own frame placed by an
//! affine transform, as pbrt-v4's shapes with their `renderFromObject` (Pharr, Jakob,
//! Humphreys, Physically Based Rendering, 4th ed., ch. 6).
//!
//! A ray is carried into the shape's frame without renormalising the direction, so `t` is the
//! same in both; the canonical intersection is a closed-form root of a quadratic (or a plane),
//! the normal is the gradient of the implicit surface mapped back by the inverse transpose.
//! Areas: `|det M| |M^-T n| dA` integrated over the canonical surface, exact for planar faces
//! and under a similarity (`s^2` times the canonical area), else by Gauss-Legendre quadrature
//! in the parameter(s) the normal depends on.

use glam::{Affine3A, Mat3, Mat3A, Vec3, Vec3A};

use super::ray::Ray;

/// A canonical shape in its own frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShapeKind {
    /// The unit sphere `|p| = 1` (an ellipsoid once scaled per axis).
    Sphere,
    /// The closed unit cylinder: `x^2 + y^2 = 1` for `0 <= z <= 1`, with its two end disks.
    Cylinder,
    /// The closed unit cone: apex at `(0, 0, 1)`, base the unit disk at `z = 0`, with the base.
    Cone,
    /// The unit disk in the plane `z = 0` (one-sided normal +z).
    Disk,
    /// The closed box `[-0.5, 0.5]^3`.
    Box,
    /// The quadric `p^T A p + 2 b.p + c = 0` clipped to the box `lo..hi`; `a` holds the
    /// symmetric `A` as `[xx, yy, zz, xy, xz, yz]`.
    Quadric {
        /// `A`'s entries `[xx, yy, zz, xy, xz, yz]`.
        a: [f32; 6],
        /// The linear term.
        b: Vec3,
        /// The constant term.
        c: f32,
        /// Lower corner of the clip box.
        lo: Vec3,
        /// Upper corner of the clip box.
        hi: Vec3,
    },
}

/// A canonical shape placed in the world.
#[derive(Clone, Copy, Debug)]
pub struct Shape {
    /// The canonical shape.
    pub kind: ShapeKind,
    /// Object-to-world transform (invertible).
    pub object_to_world: Affine3A,
    world_to_object: Affine3A,
    normal_to_world: Mat3A,
}

/// Outward (gradient) normal in the shape's frame, unnormalised.
type LocalHit = (f32, Vec3);

/// The roots of `a t^2 + 2 b t + c = 0` in increasing order (the stable form: `q = -(b +
/// sign(b) sqrt(b^2 - a c))`, roots `q / a` and `c / q`), or `None`.
fn roots(a: f32, b: f32, c: f32) -> Option<(f32, f32)> {
    if a.abs() < 1e-12 * (b.abs() + c.abs()).max(1e-30) {
        if b == 0.0 {
            return None;
        }
        let t = -c / (2.0 * b);
        return Some((t, t));
    }
    let disc = b * b - a * c;
    if disc < 0.0 {
        return None;
    }
    let q = -(b + b.signum() * disc.sqrt());
    if q == 0.0 {
        return Some((0.0, 0.0));
    }
    let (t0, t1) = (q / a, c / q);
    Some(if t0 <= t1 { (t0, t1) } else { (t1, t0) })
}

impl Shape {
    /// `kind` placed by `object_to_world`; `None` when the transform is singular or not
    /// finite.
    pub fn new(kind: ShapeKind, object_to_world: Affine3A) -> Option<Self> {
        if !super::accel::Instance::transform_is_valid(&object_to_world) {
            return None;
        }
        Some(Self {
            kind,
            object_to_world,
            world_to_object: object_to_world.inverse(),
            normal_to_world: object_to_world.matrix3.inverse().transpose(),
        })
    }

    /// The nearest hit in `(t_min, t_max]`: distance and unit outward normal (world).
    pub fn intersect(&self, ray: &Ray) -> Option<(f32, Vec3)> {
        let o = self.world_to_object.transform_point3(ray.origin);
        let d = self.world_to_object.transform_vector3(ray.dir);
        let (t, n) = self.local_hit(o, d, ray.t_min, ray.t_max)?;
        Some((t, Vec3::from(self.normal_to_world * Vec3A::from(n)).normalize()))
    }

    /// The canonical intersection of `o + t d` on `(t_min, t_max]`.
    fn local_hit(&self, o: Vec3, d: Vec3, t_min: f32, t_max: f32) -> Option<LocalHit> {
        let mut best: Option<LocalHit> = None;
        let mut take = |t: f32, n: Vec3| {
            if t > t_min && t <= t_max && best.is_none_or(|(bt, _)| t < bt) {
                best = Some((t, n));
            }
        };
        let plane = |axis: usize, at: f32| -> Option<(f32, Vec3)> {
            (d[axis] != 0.0).then(|| {
                let t = (at - o[axis]) / d[axis];
                (t, o + t * d)
            })
        };
        match self.kind {
            ShapeKind::Sphere => {
                if let Some((t0, t1)) = roots(d.dot(d), o.dot(d), o.dot(o) - 1.0) {
                    for t in [t0, t1] {
                        take(t, o + t * d);
                    }
                }
            }
            ShapeKind::Cylinder => {
                let a = d.x * d.x + d.y * d.y;
                if let Some((t0, t1)) = roots(a, o.x * d.x + o.y * d.y, o.x * o.x + o.y * o.y - 1.0) {
                    for t in [t0, t1] {
                        let p = o + t * d;
                        if (0.0..=1.0).contains(&p.z) {
                            take(t, Vec3::new(p.x, p.y, 0.0));
                        }
                    }
                }
                for (z, n) in [(0.0, -Vec3::Z), (1.0, Vec3::Z)] {
                    if let Some((t, p)) = plane(2, z)
                        && p.x * p.x + p.y * p.y <= 1.0
                    {
                        take(t, n);
                    }
                }
            }
            ShapeKind::Cone => {
                let w = 1.0 - o.z;
                let a = d.x * d.x + d.y * d.y - d.z * d.z;
                let b = o.x * d.x + o.y * d.y + d.z * w;
                let c = o.x * o.x + o.y * o.y - w * w;
                if let Some((t0, t1)) = roots(a, b, c) {
                    for t in [t0, t1] {
                        let p = o + t * d;
                        if (0.0..=1.0).contains(&p.z) {
                            take(t, Vec3::new(p.x, p.y, 1.0 - p.z));
                        }
                    }
                }
                if let Some((t, p)) = plane(2, 0.0)
                    && p.x * p.x + p.y * p.y <= 1.0
                {
                    take(t, -Vec3::Z);
                }
            }
            ShapeKind::Disk => {
                if let Some((t, p)) = plane(2, 0.0)
                    && p.x * p.x + p.y * p.y <= 1.0
                {
                    take(t, Vec3::Z);
                }
            }
            ShapeKind::Box => {
                for axis in 0..3 {
                    for side in [-0.5f32, 0.5] {
                        if let Some((t, p)) = plane(axis, side) {
                            let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
                            if p[u].abs() <= 0.5 && p[v].abs() <= 0.5 {
                                let mut n = Vec3::ZERO;
                                n[axis] = side.signum();
                                take(t, n);
                            }
                        }
                    }
                }
            }
            ShapeKind::Quadric { a, b, c, lo, hi } => {
                let m = Mat3::from_cols(
                    Vec3::new(a[0], a[3], a[4]),
                    Vec3::new(a[3], a[1], a[5]),
                    Vec3::new(a[4], a[5], a[2]),
                );
                let grad = |p: Vec3| m * p + b;
                let (qa, qb) = (d.dot(m * d), d.dot(grad(o)));
                let qc = o.dot(m * o) + 2.0 * b.dot(o) + c;
                if let Some((t0, t1)) = roots(qa, qb, qc) {
                    for t in [t0, t1] {
                        let p = o + t * d;
                        if p.cmpge(lo).all() && p.cmple(hi).all() {
                            take(t, grad(p));
                        }
                    }
                }
            }
        }
        best
    }

    /// Surface area, square metres (see the module comment). `None` for a quadric, whose
    /// area has no closed form in general.
    pub fn area_m2(&self) -> Option<f64> {
        use std::f64::consts::PI;
        let m = self.object_to_world.matrix3;
        let det = f64::from(m.determinant()).abs();
        let nt = self.normal_to_world;
        // |det M| |M^-T n| for a unit canonical normal n: the area factor at that normal.
        let factor = |n: Vec3| det * f64::from((nt * Vec3A::from(n.normalize())).length());
        // Gauss-Legendre over an angle: int_0^2pi g(phi) dphi, 64 panels of 4 nodes.
        let around = |g: &dyn Fn(f64) -> f64| {
            const X: [f64; 4] = [
                -0.861_136_311_594_053,
                -0.339_981_043_584_856,
                0.339_981_043_584_856,
                0.861_136_311_594_053,
            ];
            const W: [f64; 4] =
                [0.347_854_845_137_454, 0.652_145_154_862_546, 0.652_145_154_862_546, 0.347_854_845_137_454];
            let panels = 64;
            let h = 2.0 * PI / panels as f64;
            (0..panels)
                .map(|k| {
                    let mid = (k as f64 + 0.5) * h;
                    X.iter().zip(W).map(|(x, w)| w * g(mid + 0.5 * h * x)).sum::<f64>() * 0.5 * h
                })
                .sum::<f64>()
        };
        let ring = |z: f64, phi: f64| Vec3::new(phi.cos() as f32, phi.sin() as f32, z as f32);
        Some(match self.kind {
            ShapeKind::Disk => factor(Vec3::Z) * PI,
            ShapeKind::Box => [Vec3::X, Vec3::Y, Vec3::Z].iter().map(|&n| 2.0 * factor(n)).sum(),
            ShapeKind::Cylinder => around(&|phi| factor(ring(0.0, phi))) + 2.0 * factor(Vec3::Z) * PI,
            ShapeKind::Cone => {
                // Lateral element sqrt(2) (1 - z) dphi dz with normal (cos, sin, 1)/sqrt(2).
                around(&|phi| factor(ring(1.0, phi))) * 2f64.sqrt() * 0.5 + factor(Vec3::Z) * PI
            }
            ShapeKind::Sphere => {
                // Element sin(theta) dtheta dphi with normal p; theta by 64-point midpoint-free
                // Gauss-Legendre as well (cos(theta) = x in [-1, 1], element dx dphi).
                const X: [f64; 4] = [
                    -0.861_136_311_594_053,
                    -0.339_981_043_584_856,
                    0.339_981_043_584_856,
                    0.861_136_311_594_053,
                ];
                const W: [f64; 4] = [
                    0.347_854_845_137_454,
                    0.652_145_154_862_546,
                    0.652_145_154_862_546,
                    0.347_854_845_137_454,
                ];
                let panels = 64;
                let h = 2.0 / panels as f64;
                (0..panels)
                    .map(|k| {
                        let mid = -1.0 + (k as f64 + 0.5) * h;
                        X.iter()
                            .zip(W)
                            .map(|(x, w)| {
                                let cz = mid + 0.5 * h * x;
                                let s = (1.0 - cz * cz).max(0.0).sqrt();
                                w * around(&|phi| {
                                    factor(Vec3::new(
                                        (s * phi.cos()) as f32,
                                        (s * phi.sin()) as f32,
                                        cz as f32,
                                    ))
                                })
                            })
                            .sum::<f64>()
                            * 0.5
                            * h
                    })
                    .sum()
            }
            ShapeKind::Quadric { .. } => return None,
        })
    }

    /// World bounds `(lo, hi)`: the transformed box of the canonical bounds.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let (lo, hi) = match self.kind {
            ShapeKind::Sphere => (Vec3::splat(-1.0), Vec3::ONE),
            ShapeKind::Cylinder | ShapeKind::Cone => (Vec3::new(-1.0, -1.0, 0.0), Vec3::ONE),
            ShapeKind::Disk => (Vec3::new(-1.0, -1.0, 0.0), Vec3::new(1.0, 1.0, 0.0)),
            ShapeKind::Box => (Vec3::splat(-0.5), Vec3::splat(0.5)),
            ShapeKind::Quadric { lo, hi, .. } => (lo, hi),
        };
        super::accel::instances::transformed_box(&self.object_to_world, lo, hi)
    }
}

/// The placed shapes of a scene, each with its surface; tested one after the other behind a
/// box test (scenes hold a handful).
#[derive(Default)]
pub struct ShapeSet {
    /// The shapes and their surfaces.
    pub shapes: Vec<(Shape, super::hit::SurfaceId)>,
    /// World box of each shape.
    boxes: Vec<(Vec3, Vec3)>,
}

impl ShapeSet {
    /// A set of `shapes`.
    pub fn new(shapes: Vec<(Shape, super::hit::SurfaceId)>) -> Self {
        let boxes = shapes.iter().map(|(s, _)| s.bounds()).collect();
        Self { shapes, boxes }
    }

    /// Whether there is no shape.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.shapes.is_empty()
    }

    /// Indices of the shapes whose box the segment may cross (slab test, padded).
    fn candidates<'a>(&'a self, ray: &'a Ray) -> impl Iterator<Item = usize> + 'a {
        let inv = ray.dir.recip();
        self.boxes.iter().enumerate().filter_map(move |(i, (lo, hi))| {
            let pad = 1e-4 * (1.0 + lo.abs().max(hi.abs()).max_element());
            let (a, b) = ((*lo - pad - ray.origin) * inv, (*hi + pad - ray.origin) * inv);
            let (near, far) = (a.min(b).max_element(), a.max(b).min_element());
            // NaN (a zero direction component on a slab plane) keeps the shape.
            (!(near > far || far < ray.t_min || near > ray.t_max)).then_some(i)
        })
    }

    /// The closest shape hit: (index, distance, unit outward normal).
    pub fn closest(&self, ray: &Ray) -> Option<(usize, f32, Vec3)> {
        let mut r = *ray;
        let mut best = None;
        for i in self.candidates(ray) {
            if let Some((t, n)) = self.shapes[i].0.intersect(&r) {
                r.t_max = t;
                best = Some((i, t, n));
            }
        }
        best
    }

    /// Whether any shape blocks the segment.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.candidates(ray).any(|i| self.shapes[i].0.intersect(ray).is_some())
    }
}

#[cfg(test)]
mod tests {
    use glam::{Quat, Vec2};

    use super::*;
    use crate::core::accel::{BuildQuality, MeshBvh};
    use crate::core::mesh::TriangleMesh;
    use crate::core::rng::{stream, uniform};
    use crate::core::sampling::uniform_sphere;

    /// A ring of `n` points at height `z` and radius `r`.
    fn ring(r: f32, z: f32, n: usize) -> Vec<Vec3> {
        (0..n)
            .map(|i| {
                let a = std::f32::consts::TAU * i as f32 / n as f32;
                Vec3::new(r * a.cos(), r * a.sin(), z)
            })
            .collect()
    }

    /// A surface of revolution through the profile `(radius, z)` (first and last points on
    /// the axis close it), `n` segments around.
    fn revolve(profile: &[(f32, f32)], n: usize) -> TriangleMesh {
        let mut m = TriangleMesh::default();
        let s = m.surface_id("s");
        let rings: Vec<Vec<Vec3>> = profile.iter().map(|&(r, z)| ring(r, z, n)).collect();
        for k in 0..rings.len() - 1 {
            for i in 0..n {
                let i2 = (i + 1) % n;
                let (a, b, c, d) = (rings[k][i], rings[k][i2], rings[k + 1][i2], rings[k + 1][i]);
                m.push_triangle([a, b, c], s);
                m.push_triangle([a, c, d], s);
            }
        }
        m
    }

    /// A fine tessellation of each canonical shape, and the shape.
    fn cases() -> Vec<(ShapeKind, TriangleMesh, f64)> {
        use std::f32::consts::PI;
        let n = 1024;
        let sphere: Vec<(f32, f32)> =
            (0..=512).map(|j| ((PI * j as f32 / 512.0).sin(), -(PI * j as f32 / 512.0).cos())).collect();
        let cylinder = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)];
        let cone = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)];
        let disk = [(0.0, 0.0), (1.0, 0.0)];
        // Hyperboloid of one sheet x^2 + y^2 - z^2 = 1 on |z| <= 1 (open).
        let hyper: Vec<(f32, f32)> = (0..=256)
            .map(|j| {
                let z = -1.0 + 2.0 * j as f32 / 256.0;
                ((1.0 + z * z).sqrt(), z)
            })
            .collect();
        let mut cube = TriangleMesh::default();
        let s = cube.surface_id("s");
        cube.push_box(Vec3::splat(-0.5), Vec3::splat(0.5), 1, s);
        let quadric = ShapeKind::Quadric {
            a: [1.0, 1.0, -1.0, 0.0, 0.0, 0.0],
            b: Vec3::ZERO,
            c: -1.0,
            lo: Vec3::new(-2.0, -2.0, -1.0),
            hi: Vec3::new(2.0, 2.0, 1.0),
        };
        vec![
            (ShapeKind::Sphere, revolve(&sphere, n), 4.0 * std::f64::consts::PI),
            (ShapeKind::Cylinder, revolve(&cylinder, n), 4.0 * std::f64::consts::PI),
            (ShapeKind::Cone, revolve(&cone, n), std::f64::consts::PI * (1.0 + 2f64.sqrt())),
            (ShapeKind::Disk, revolve(&disk, n), std::f64::consts::PI),
            (ShapeKind::Box, cube, 6.0),
            (quadric, revolve(&hyper, n), f64::NAN),
        ]
    }

    #[test]
    fn canonical_areas_are_the_closed_forms() {
        for (kind, _, area) in cases() {
            let s = Shape::new(kind, Affine3A::IDENTITY).unwrap();
            match s.area_m2() {
                Some(a) => assert!((a - area).abs() < 1e-9 * area.max(1.0) + 1e-6, "{kind:?}: {a} vs {area}"),
                None => assert!(area.is_nan()),
            }
            // Under a similarity the area scales by s^2.
            let m = Affine3A::from_scale_rotation_translation(
                Vec3::splat(3.0),
                Quat::from_rotation_x(0.7),
                Vec3::ONE,
            );
            if let Some(a) = Shape::new(kind, m).unwrap().area_m2() {
                assert!((a - 9.0 * area).abs() < 1e-4 * area, "{kind:?}");
            }
        }
        // A spheroid (a = b = 2, c = 1): 2 pi a^2 (1 + (1 - e^2)/e atanh(e)), e^2 = 1 - c^2/a^2.
        let s = Shape::new(ShapeKind::Sphere, Affine3A::from_scale(Vec3::new(2.0, 2.0, 1.0))).unwrap();
        let e = (1.0f64 - 0.25).sqrt();
        let want = 2.0 * std::f64::consts::PI * 4.0 * (1.0 + (1.0 - e * e) / e * e.atanh());
        assert!((s.area_m2().unwrap() - want).abs() < 1e-6 * want, "{:?} vs {want}", s.area_m2());
        // A box stretched to 1 x 2 x 3: 2 (2 + 3 + 6).
        let b = Shape::new(ShapeKind::Box, Affine3A::from_scale(Vec3::new(1.0, 2.0, 3.0))).unwrap();
        assert!((b.area_m2().unwrap() - 22.0).abs() < 1e-5);
        // A cylinder of radius 2 and height 3: 2 pi r h + 2 pi r^2.
        let c = Shape::new(ShapeKind::Cylinder, Affine3A::from_scale(Vec3::new(2.0, 2.0, 3.0))).unwrap();
        assert!((c.area_m2().unwrap() - (12.0 + 8.0) * std::f64::consts::PI).abs() < 1e-4);
        assert!(Shape::new(ShapeKind::Sphere, Affine3A::from_scale(Vec3::new(1.0, 0.0, 1.0))).is_none());
    }

    #[test]
    fn transformed_shapes_match_a_fine_tessellation_on_random_rays() {
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::new(1.5, 0.7, 2.0),
            Quat::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 0.8),
            Vec3::new(0.3, -0.2, 0.5),
        );
        for (kind, mut mesh, _) in cases() {
            for p in &mut mesh.positions {
                *p = m.transform_point3(*p);
            }
            let bvh = MeshBvh::build(&mesh, BuildQuality::default());
            let shape = Shape::new(kind, m).unwrap();
            let (lo, hi) = shape.bounds();
            let (mut agree, mut hits, mut total) = (0, 0, 0);
            for k in 0..100_000u64 {
                let mut r = stream(31, 0, k);
                let target = lo + (hi - lo) * Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r));
                let o = target + 8.0 * uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
                let ray = Ray::new(o, (target - o).normalize());
                let (a, b) = (shape.intersect(&ray), bvh.closest_hit(&ray));
                total += 1;
                match (a, b) {
                    (Some((ta, na)), Some(hb)) => {
                        hits += 1;
                        if (ta - hb.t).abs() < 2e-3 && na.dot(hb.normal).abs() > 0.99 {
                            agree += 1;
                        }
                    }
                    (None, None) => agree += 1,
                    _ => {}
                }
            }
            // Disagreements only along silhouettes and rims, where the facets cut inside the
            // curve by up to (pi / n)^2 / 2 of the radius.
            assert!(agree * 1000 >= total * 998, "{kind:?}: {agree} of {total} agree ({hits} hits)");
            assert!(hits > 10_000, "{kind:?}: {hits} hits");
        }
    }
}
