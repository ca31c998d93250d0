//! Analytic shapes as area lights: a point uniform by area on the canonical shape
//! ([`crate::core::shapes::ShapeKind`]: unit sphere, cylinder, cone, disk, box) carried into
//! the world by the shape's affine transform, with the exact density that mapping gives.
//!
//! An affine map `x -> M x + t` scales the area element at a point whose canonical unit
//! normal is `n` by `J = |det M| |M^-T n|` (the area element of a transformed surface, the
//! factor `crate::core::shapes` integrates for the areas), and the world normal there is
//! `n_w = M^-T n / |M^-T n|`. Since
//! `M^T n_w = n / |M^-T n|`, the factor is `J = |det M| / |M^T n_w|`, so a point drawn with
//! canonical density `1 / A_c` (uniform on the canonical surface of area `A_c`) has world
//! density per area
//!
//! `p_A = |M^T n_w| / (A_c |det M|)`,
//!
//! a function of the world normal alone: sampling and multiple importance sampling read it the
//! same way, from the sampled normal or from a ray's hit normal. Under a similarity (a sphere,
//! a round cylinder) this is `1 / A`, uniform by world area; a stretched shape (an
//! ellipsoid) is sampled non-uniformly but with this exact density, which is what an unbiased
//! estimator and the MIS weights need (area sampling of shapes with its density converted to
//! solid angle for next-event estimation, as in pbrt-v4 ch. 6 and Veach 1997 ch. 9).
//! General quadrics have no closed-form area and are not lights (the scene loader refuses an
//! emissive one). A round sphere (a similarity) does not come here: it becomes an ordinary
//! sphere light, sampled within the cone it subtends ([`super::lights`]).
//!
//! Emission is one-sided Lambertian, from the side the outward (disk: +z) normal points to,
//! as for triangles and spheres ([`super::lights`]).

use std::f32::consts::{PI, TAU};

use glam::{Mat3, Vec2, Vec3};

use crate::core::sampling::uniform_sphere;
use crate::core::shapes::{Shape, ShapeKind};

/// The canonical shapes that can emit (those with a closed-form area).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EmitterKind {
    /// The unit sphere.
    Sphere,
    /// The closed unit cylinder (`z` from 0 to 1, both end disks).
    Cylinder,
    /// The closed unit cone (base disk at `z = 0`, apex at `z = 1`).
    Cone,
    /// The unit disk at `z = 0`, normal +z.
    Disk,
    /// The closed box `[-0.5, 0.5]^3`.
    Box,
}

impl EmitterKind {
    /// Area of the canonical surface, m^2: `4 pi`, `2 pi + 2 pi`, `pi sqrt 2 + pi`, `pi`, 6.
    pub fn canonical_area(self) -> f32 {
        match self {
            EmitterKind::Sphere | EmitterKind::Cylinder => 4.0 * PI,
            EmitterKind::Cone => PI * (1.0 + std::f32::consts::SQRT_2),
            EmitterKind::Disk => PI,
            EmitterKind::Box => 6.0,
        }
    }

    /// A point uniform by area on the canonical surface and its unit outward normal, from `u`
    /// in `[0,1)^2`. For the shapes made of parts (cylinder, cone, box), `u.x` first picks the
    /// part in proportion to its area and is then stretched back to `[0,1)` within it.
    pub fn sample(self, u: Vec2) -> (Vec3, Vec3) {
        // A point on the unit disk at height z (radius sqrt(v): uniform by area).
        let disk = |v: f32, w: f32, z: f32| {
            let r = v.sqrt();
            let (s, c) = (TAU * w).sin_cos();
            Vec3::new(r * c, r * s, z)
        };
        match self {
            EmitterKind::Sphere => {
                let n = uniform_sphere(u);
                (n, n)
            }
            EmitterKind::Disk => (disk(u.x, u.y, 0.0), Vec3::Z),
            EmitterKind::Cylinder => {
                // Lateral 2 pi of 4 pi, then the two ends pi each.
                if u.x < 0.5 {
                    let (s, c) = (TAU * u.y).sin_cos();
                    (Vec3::new(c, s, 2.0 * u.x), Vec3::new(c, s, 0.0))
                } else if u.x < 0.75 {
                    (disk(stretch(u.x, 0.5, 0.75), u.y, 0.0), -Vec3::Z)
                } else {
                    (disk(stretch(u.x, 0.75, 1.0), u.y, 1.0), Vec3::Z)
                }
            }
            EmitterKind::Cone => {
                // Lateral pi sqrt 2 of pi (1 + sqrt 2); its element is sqrt 2 (1 - z) dz dphi,
                // so the distance from the apex, s = 1 - z, has density 2 s: s = sqrt(v).
                let lateral = std::f32::consts::SQRT_2 / (1.0 + std::f32::consts::SQRT_2);
                if u.x < lateral {
                    let s = stretch(u.x, 0.0, lateral).sqrt();
                    let (sn, c) = (TAU * u.y).sin_cos();
                    let n = Vec3::new(c, sn, 1.0) * std::f32::consts::FRAC_1_SQRT_2;
                    (Vec3::new(s * c, s * sn, 1.0 - s), n)
                } else {
                    (disk(stretch(u.x, lateral, 1.0), u.y, 0.0), -Vec3::Z)
                }
            }
            EmitterKind::Box => {
                // Six faces of area 1: face k = floor(6 u.x), axis k / 2, side by k's parity.
                let f = u.x * 6.0;
                let k = (f as usize).min(5);
                let v = (f - k as f32).clamp(0.0, 1.0);
                let (axis, side) = (k / 2, if k.is_multiple_of(2) { -0.5 } else { 0.5 });
                let mut p = Vec3::ZERO;
                p[axis] = side;
                p[(axis + 1) % 3] = v - 0.5;
                p[(axis + 2) % 3] = u.y - 0.5;
                let mut n = Vec3::ZERO;
                n[axis] = 2.0 * side;
                (p, n)
            }
        }
    }

    /// A point inside the canonical solid that stands for it (the sphere's and the box's
    /// centre, the centroid of the cylinder's and the cone's axis segment, the disk's centre).
    fn centre(self) -> Vec3 {
        match self {
            EmitterKind::Cylinder => Vec3::new(0.0, 0.0, 0.5),
            EmitterKind::Cone => Vec3::new(0.0, 0.0, 0.25),
            _ => Vec3::ZERO,
        }
    }
}

/// `x` in `[lo, hi)` mapped back to `[0, 1)`.
#[inline]
fn stretch(x: f32, lo: f32, hi: f32) -> f32 {
    ((x - lo) / (hi - lo)).clamp(0.0, 1.0 - f32::EPSILON / 2.0)
}

/// An emissive analytic shape: its canonical kind, its placement and its radiance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ShapeLight {
    /// The canonical shape.
    pub kind: EmitterKind,
    /// Linear part `M` of the object-to-world transform.
    pub linear: Mat3,
    /// Translation of the object-to-world transform, metres.
    pub translation: Vec3,
    /// `1 / (A_c |det M|)`: the world density per area is this times `|M^T n_w|`.
    inv_area_scale: f32,
    /// World surface area, m^2 ([`Shape::area_m2`]), for the light's power.
    pub area_m2: f32,
    /// Emitted radiance.
    pub le: Vec3,
}

impl ShapeLight {
    /// `shape` emitting radiance `le`; `None` for a quadric (no closed-form area) or a shape
    /// of no area.
    pub fn new(shape: &Shape, le: Vec3) -> Option<Self> {
        let kind = match shape.kind {
            ShapeKind::Sphere => EmitterKind::Sphere,
            ShapeKind::Cylinder => EmitterKind::Cylinder,
            ShapeKind::Cone => EmitterKind::Cone,
            ShapeKind::Disk => EmitterKind::Disk,
            ShapeKind::Box => EmitterKind::Box,
            ShapeKind::Quadric { .. } => return None,
        };
        let linear = Mat3::from(shape.object_to_world.matrix3);
        let det = linear.determinant().abs();
        let area_m2 = shape.area_m2()? as f32;
        if !(det > 0.0 && area_m2 > 0.0 && area_m2.is_finite()) {
            return None;
        }
        Some(Self {
            kind,
            linear,
            translation: Vec3::from(shape.object_to_world.translation),
            inv_area_scale: 1.0 / (kind.canonical_area() * det),
            area_m2,
            le,
        })
    }

    /// Density per unit world area of [`ShapeLight::sample_area`] at a point of unit world
    /// normal `n` (see the module comment).
    #[inline]
    pub fn pdf_area(&self, n: Vec3) -> f32 {
        (self.linear.transpose() * n).length() * self.inv_area_scale
    }

    /// A point on the shape from `u` in `[0,1)^2`: the point and its unit outward world
    /// normal; its density per unit world area is [`ShapeLight::pdf_area`] of that normal.
    pub fn sample_area(&self, u: Vec2) -> (Vec3, Vec3) {
        let (p, n) = self.kind.sample(u);
        let q = self.linear * p + self.translation;
        // M^-T n = cof(M) n / det M, where cof(M)'s columns are b x c, c x a, a x b for M's
        // columns a, b, c: no inverse is stored.
        let (a, b, c) = (self.linear.x_axis, self.linear.y_axis, self.linear.z_axis);
        let m = b.cross(c) * n.x + c.cross(a) * n.y + a.cross(b) * n.z;
        let nw = m.normalize_or_zero() * self.linear.determinant().signum();
        (q, nw)
    }

    /// A point standing for the shape in point-light approximations.
    pub fn centre(&self) -> Vec3 {
        self.linear * self.kind.centre() + self.translation
    }

    /// Radiant intensity towards unit `dir` in point-light approximations: a disk's
    /// `Le A cos`, else `Le A / 4` (a convex body's mean projected area is a quarter of its
    /// surface, Cauchy's formula).
    pub fn intensity_towards(&self, dir: Vec3) -> Vec3 {
        match self.kind {
            EmitterKind::Disk => {
                let (_, n) = self.sample_area(Vec2::ZERO);
                self.le * (self.area_m2 * n.dot(dir).max(0.0))
            }
            _ => self.le * (0.25 * self.area_m2),
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::{Affine3A, Quat};

    use super::*;
    use crate::core::Ray;
    use crate::core::rng::{stream, uniform};

    fn kinds() -> [ShapeKind; 5] {
        [ShapeKind::Sphere, ShapeKind::Cylinder, ShapeKind::Cone, ShapeKind::Disk, ShapeKind::Box]
    }

    /// Every sampled point lies on the shape (a ray from outside along the normal hits it
    /// there with the same normal), and `1 / p_A` averages to the world area (the area
    /// estimator `E[1 / p_A] = A`, against the closed-form/quadrature area).
    #[test]
    fn samples_lie_on_the_shape_and_the_density_integrates_to_one() {
        let m = Affine3A::from_scale_rotation_translation(
            Vec3::new(1.5, 0.7, 2.0),
            Quat::from_axis_angle(Vec3::new(1.0, 2.0, 3.0).normalize(), 0.8),
            Vec3::new(0.3, -0.2, 0.5),
        );
        for kind in kinds() {
            let shape = Shape::new(kind, m).unwrap();
            let light = ShapeLight::new(&shape, Vec3::ONE).unwrap();
            let area = shape.area_m2().unwrap();
            let n = 200_000u64;
            let (mut sum, mut on) = (0.0f64, 0);
            for k in 0..n {
                let mut r = stream(5, 0, k);
                let (q, nw) = light.sample_area(Vec2::new(uniform(&mut r), uniform(&mut r)));
                sum += 1.0 / f64::from(light.pdf_area(nw));
                let ray = Ray::new(q + nw * 0.01, -nw);
                if let Some((t, hn)) = shape.intersect(&ray)
                    && (t - 0.01).abs() < 1e-4
                    && hn.dot(nw) > 0.999
                {
                    on += 1;
                }
            }
            let est = sum / n as f64;
            assert!((est - area).abs() < 0.01 * area, "{kind:?}: {est} vs {area}");
            // Points within 0.01 of a rim or an edge may hit the neighbouring face.
            assert!(on * 100 >= n * 97, "{kind:?}: {on} of {n} on the surface");
        }
    }

    /// The canonical samples are uniform by area: their first and second moments are those
    /// of the uniform density on each surface (closed forms: a sphere's `E[x^2] = 1/3`; a
    /// cube's `(2 * 1/4 + 4 * 1/12) / 6 = 5/36`; a cylinder's lateral half with `E[x^2] =
    /// 1/2` and its caps with `1/4`; a cone's lateral part, whose distance from the apex has
    /// density `2 s`, `E[s] = 2/3`, `E[s^2] = 1/2`).
    #[test]
    fn canonical_samples_have_the_moments_of_the_uniform_density() {
        let wl = std::f32::consts::SQRT_2 / (1.0 + std::f32::consts::SQRT_2);
        let cases = [
            (EmitterKind::Sphere, Vec3::ZERO, Vec3::splat(1.0 / 3.0)),
            (EmitterKind::Disk, Vec3::ZERO, Vec3::new(0.25, 0.25, 0.0)),
            (EmitterKind::Box, Vec3::ZERO, Vec3::splat(5.0 / 36.0)),
            (EmitterKind::Cylinder, Vec3::new(0.0, 0.0, 0.5), Vec3::new(0.375, 0.375, 5.0 / 12.0)),
            (EmitterKind::Cone, Vec3::new(0.0, 0.0, wl / 3.0), Vec3::new(0.25, 0.25, wl / 6.0)),
        ];
        for (kind, mean, square) in cases {
            let n = 200_000u64;
            let (mut m, mut q) = (Vec3::ZERO, Vec3::ZERO);
            for k in 0..n {
                let mut r = stream(9, 0, k);
                let (p, normal) = kind.sample(Vec2::new(uniform(&mut r), uniform(&mut r)));
                assert!((normal.length() - 1.0).abs() < 1e-5, "{kind:?}");
                m += p / n as f32;
                q += p * p / n as f32;
            }
            assert!((m - mean).abs().max_element() < 4e-3, "{kind:?}: mean {m} vs {mean}");
            assert!((q - square).abs().max_element() < 4e-3, "{kind:?}: mean square {q} vs {square}");
        }
    }

    /// Under a similarity the density is uniform: `1 / A` everywhere.
    #[test]
    fn a_similarity_samples_uniformly_by_area() {
        let m =
            Affine3A::from_scale_rotation_translation(Vec3::splat(2.0), Quat::from_rotation_y(0.4), Vec3::X);
        for kind in kinds() {
            let shape = Shape::new(kind, m).unwrap();
            let light = ShapeLight::new(&shape, Vec3::ONE).unwrap();
            let want = 1.0 / shape.area_m2().unwrap() as f32;
            for k in 0..1000u64 {
                let mut r = stream(6, 0, k);
                let (_, nw) = light.sample_area(Vec2::new(uniform(&mut r), uniform(&mut r)));
                assert!((light.pdf_area(nw) - want).abs() < 1e-5 * want, "{kind:?}");
            }
        }
        let quadric =
            ShapeKind::Quadric { a: [1.0; 6], b: Vec3::ZERO, c: -1.0, lo: -Vec3::ONE, hi: Vec3::ONE };
        assert!(ShapeLight::new(&Shape::new(quadric, Affine3A::IDENTITY).unwrap(), Vec3::ONE).is_none());
    }
}
