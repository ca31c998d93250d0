//! Analytic spheres: the renderer's spheres and the receivers of both launchers.

use glam::{Vec2, Vec3};

use super::hit::SurfaceId;
use super::ray::Ray;

/// A sphere with a surface (material slot).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre, metres.
    pub center: Vec3,
    /// Radius, metres.
    pub radius_m: f32,
    /// Its surface (material slot).
    pub surface: SurfaceId,
}

impl Sphere {
    /// A sphere of `center`, `radius_m` and `surface`.
    pub fn new(center: Vec3, radius_m: f32, surface: SurfaceId) -> Self {
        Self { center, radius_m, surface }
    }

    /// Both roots `t0 <= t1` of `|o + t d - c| = r` for a unit direction `d`, or `None` when
    /// the line misses. Uses the numerically stable form of Hearn & Baker / Ray Tracing Gems
    /// ch. 7 (subtract the projection before squaring).
    #[inline]
    pub fn roots(&self, ray: &Ray) -> Option<(f32, f32)> {
        let d = ray.dir;
        let a = d.length_squared();
        let f = ray.origin - self.center;
        let b = -f.dot(d);
        let closest = f + (b / a) * d;
        let r2 = self.radius_m * self.radius_m;
        let disc = a * (r2 - closest.length_squared());
        if disc < 0.0 {
            return None;
        }
        let sqrt_disc = disc.sqrt();
        let q = b + b.signum() * sqrt_disc;
        let c = f.length_squared() - r2;
        if q == 0.0 {
            return Some((0.0, 0.0));
        }
        let (t0, t1) = (c / q, q / a);
        Some(if t0 <= t1 { (t0, t1) } else { (t1, t0) })
    }

    /// Nearest intersection in `(t_min, t_max]`: distance, outward unit normal, and the
    /// spherical coordinates of the hit as (azimuth / 2 pi, polar / pi).
    pub fn intersect(&self, ray: &Ray) -> Option<(f32, Vec3, Vec2)> {
        let (t0, t1) = self.roots(ray)?;
        let t = if t0 > ray.t_min && t0 <= ray.t_max {
            t0
        } else if t1 > ray.t_min && t1 <= ray.t_max {
            t1
        } else {
            return None;
        };
        let n = ((ray.at(t) - self.center) / self.radius_m).normalize_or_zero();
        let phi = n.y.atan2(n.x).rem_euclid(std::f32::consts::TAU);
        let theta = n.z.clamp(-1.0, 1.0).acos();
        Some((t, n, Vec2::new(phi / std::f32::consts::TAU, theta / std::f32::consts::PI)))
    }

    /// Length of the ray segment `[t_min, t_max]` inside the sphere (metres for unit `dir`).
    pub fn chord_length(&self, ray: &Ray) -> f32 {
        match self.roots(ray) {
            Some((t0, t1)) => (t1.min(ray.t_max) - t0.max(ray.t_min)).max(0.0),
            None => 0.0,
        }
    }

    /// Whether `p` lies inside or on the sphere.
    pub fn contains(&self, p: Vec3) -> bool {
        (p - self.center).length_squared() <= self.radius_m * self.radius_m
    }

    /// Lower corner of its bounding box.
    pub fn aabb_min(&self) -> Vec3 {
        self.center - Vec3::splat(self.radius_m)
    }

    /// Upper corner of its bounding box.
    pub fn aabb_max(&self) -> Vec3 {
        self.center + Vec3::splat(self.radius_m)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_front_at_closed_form_distance() {
        let s = Sphere::new(Vec3::new(0.0, 0.0, 10.0), 2.0, 0);
        let (t, n, _) = s.intersect(&Ray::new(Vec3::ZERO, Vec3::Z)).expect("hit");
        assert!((t - 8.0).abs() < 1e-5);
        assert!((n + Vec3::Z).length() < 1e-5);
        // Off-axis: x = 1 -> t = 10 - sqrt(4 - 1).
        let (t, _, _) = s.intersect(&Ray::new(Vec3::new(1.0, 0.0, 0.0), Vec3::Z)).unwrap();
        assert!((t - (10.0 - 3f32.sqrt())).abs() < 1e-5);
    }

    #[test]
    fn from_inside_hits_far_side_and_misses_when_offset() {
        let s = Sphere::new(Vec3::ZERO, 1.0, 0);
        let (t, n, _) = s.intersect(&Ray::new(Vec3::ZERO, Vec3::X)).unwrap();
        assert!((t - 1.0).abs() < 1e-6 && (n - Vec3::X).length() < 1e-6);
        assert!(s.intersect(&Ray::new(Vec3::new(0.0, 1.5, 0.0), Vec3::X)).is_none());
        assert!(s.intersect(&Ray::new(Vec3::new(3.0, 0.0, 0.0), Vec3::X)).is_none());
    }

    #[test]
    fn far_away_small_sphere_is_stable() {
        // Catastrophic cancellation case of the naive quadratic.
        let s = Sphere::new(Vec3::new(0.0, 0.0, 1.0e4), 0.01, 0);
        let (t, _, _) = s.intersect(&Ray::new(Vec3::ZERO, Vec3::Z)).expect("hit");
        assert!((t - (1.0e4 - 0.01)).abs() < 2e-3);
    }

    #[test]
    fn chord_length_matches_geometry() {
        let s = Sphere::new(Vec3::ZERO, 1.0, 0);
        let ray = Ray::new(Vec3::new(-5.0, 0.6, 0.0), Vec3::X);
        assert!((s.chord_length(&ray) - 2.0 * 0.8).abs() < 1e-5);
        let stop_inside = Ray::segment(Vec3::new(-5.0, 0.0, 0.0), Vec3::X, 5.0);
        assert!((s.chord_length(&stop_inside) - 1.0).abs() < 1e-5);
        assert_eq!(s.chord_length(&Ray::new(Vec3::new(-5.0, 2.0, 0.0), Vec3::X)), 0.0);
    }
}
