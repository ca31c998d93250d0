//! A look-at perspective camera (the gluLookAt convention) with an optional thin lens for
//! depth of field (pbrt-v4 sec. 5.2.3; Cook, Porter, Carpenter 1984).

use glam::{Vec2, Vec3};

use crate::core::Ray;
use crate::core::sampling::concentric_disk;
use crate::scene::desc::CameraDesc;

/// A perspective camera. Image-plane coordinates run from (0,0) at the top-left corner of the
/// image to (1,1) at the bottom-right.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// Camera position.
    pub eye: Vec3,
    /// Unit viewing direction.
    pub forward: Vec3,
    /// Unit vector to the right of the image.
    pub right: Vec3,
    /// Unit vector to the top of the image (`up` made orthogonal to `forward`).
    pub up: Vec3,
    /// `tan(fov_y / 2)`.
    pub tan_half_fov: f32,
    /// Width / height.
    pub aspect: f32,
    /// Lens radius in metres (0: pinhole).
    pub aperture_radius_m: f32,
    /// Distance to the plane in focus, metres.
    pub focus_distance_m: f32,
}

impl Camera {
    /// A camera at `eye` looking at `target` with `up` as the image's up direction and a
    /// vertical field of view of `fov_deg`; errors say which input is unusable.
    pub fn look_at(eye: Vec3, target: Vec3, up: Vec3, fov_deg: f32, aspect: f32) -> Result<Self, String> {
        for (name, v) in [("eye", eye), ("target", target), ("up", up)] {
            if !v.is_finite() {
                return Err(format!("camera {name} {v} is not finite"));
            }
        }
        let view = target - eye;
        if view.length() <= 1.0e-6 * (1.0 + eye.abs().max_element()) {
            return Err(format!("camera eye and target are the same point {eye}"));
        }
        let forward = view.normalize();
        let right = forward.cross(up);
        if up.length_squared() == 0.0 || right.length() <= 1.0e-6 * up.length() {
            return Err(format!("camera up {up} is zero or parallel to the viewing direction"));
        }
        if !(fov_deg.is_finite() && fov_deg > 0.0 && fov_deg < 179.0) {
            return Err(format!("field of view {fov_deg} degrees: must be in (0, 179)"));
        }
        if !(aspect.is_finite() && aspect > 0.0) {
            return Err(format!("aspect ratio {aspect} is not positive"));
        }
        let right = right.normalize();
        Ok(Self {
            eye,
            forward,
            right,
            up: right.cross(forward),
            tan_half_fov: (fov_deg.to_radians() * 0.5).tan(),
            aspect,
            aperture_radius_m: 0.0,
            focus_distance_m: view.length(),
        })
    }

    /// The camera a scene's `[camera]` describes.
    pub fn from_desc(d: &CameraDesc, aspect: f32) -> Result<Self, String> {
        let mut c =
            Self::look_at(Vec3::from(d.eye), Vec3::from(d.target), Vec3::from(d.up), d.fov_deg, aspect)?;
        c.set_lens(d.aperture_radius_m, d.focus_distance_m)?;
        Ok(c)
    }

    /// Sets the thin lens: radius `aperture_radius_m` (0 = pinhole) focused at `focus_distance_m`
    /// (default: the distance to the target).
    pub fn set_lens(&mut self, aperture_radius_m: f32, focus_distance_m: Option<f32>) -> Result<(), String> {
        if !(aperture_radius_m.is_finite() && aperture_radius_m >= 0.0) {
            return Err(format!("aperture radius {aperture_radius_m} m must be >= 0"));
        }
        if let Some(f) = focus_distance_m {
            if !(f.is_finite() && f > 0.0) {
                return Err(format!("focus distance {f} m must be > 0"));
            }
            self.focus_distance_m = f;
        }
        self.aperture_radius_m = aperture_radius_m;
        Ok(())
    }

    /// An automatic view of an axis-aligned box: from the front-left and a little above
    /// (looking along +y, tilted down), far enough that the bounding sphere fills the
    /// vertical field of view.
    pub fn auto_view(lo: Vec3, hi: Vec3, up: Vec3, fov_deg: f32) -> (Vec3, Vec3) {
        let center = 0.5 * (lo + hi);
        let radius = (0.5 * (hi - lo).length()).max(1.0e-3);
        let up = up.normalize_or(Vec3::Z);
        let (t, b) = crate::core::sampling::orthonormal_basis(up);
        // Mostly from -b (the "front"), a little from -t, and 30 % up.
        let dir = (-0.35 * t - b + 0.45 * up).normalize();
        let distance = radius / (fov_deg.to_radians() * 0.5).sin() * 1.05;
        (center + dir * distance, center)
    }

    /// The primary ray through image point `film` in `[0,1]^2`, with `lens` in `[0,1)^2`
    /// choosing the point on the aperture (ignored by a pinhole).
    #[inline(always)]
    pub fn ray(&self, film: Vec2, lens: Vec2) -> Ray {
        let sx = (2.0 * film.x - 1.0) * self.tan_half_fov * self.aspect;
        let sy = (1.0 - 2.0 * film.y) * self.tan_half_fov;
        let dir = (self.forward + sx * self.right + sy * self.up).normalize();
        if self.aperture_radius_m <= 0.0 {
            return Ray::new(self.eye, dir);
        }
        // Thin lens: every ray through the same film point meets at the focal plane.
        let ft = self.focus_distance_m / dir.dot(self.forward);
        let focus = self.eye + dir * ft;
        let d = concentric_disk(lens) * self.aperture_radius_m;
        let origin = self.eye + d.x * self.right + d.y * self.up;
        Ray::new(origin, (focus - origin).normalize())
    }
}

/// A point on the lens sampled towards a scene point ([`Camera::sample_wi`]): what light
/// tracing needs to splat a vertex on the film (pbrt-v4 sec. 5.4, `SampleWi`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LensSample {
    /// The point on the lens (the eye for a pinhole), metres.
    pub point: Vec3,
    /// Unit direction from the scene point to the lens point.
    pub wi: Vec3,
    /// Distance from the scene point to the lens point, metres.
    pub distance_m: f32,
    /// Importance `We` of the ray from the lens point towards the scene point.
    pub importance: f32,
    /// Density of the lens point per solid angle at the scene point.
    pub pdf: f32,
    /// Image-plane position `[0,1)^2` of that ray.
    pub film: Vec2,
}

impl Camera {
    /// Area of the image rectangle at unit distance in front of the lens, m^2:
    /// `(2 tan(fov/2) aspect) (2 tan(fov/2))`.
    #[inline]
    pub fn image_area_at_unit_distance(&self) -> f32 {
        4.0 * self.tan_half_fov * self.tan_half_fov * self.aspect
    }

    /// Area of the lens, m^2: `pi r^2`, or 1 for a pinhole (pbrt-v4's convention, which makes
    /// the pinhole's importance and densities those of a unit-area lens point).
    #[inline]
    pub fn lens_area(&self) -> f32 {
        if self.aperture_radius_m > 0.0 {
            std::f32::consts::PI * self.aperture_radius_m * self.aperture_radius_m
        } else {
            1.0
        }
    }

    /// The image-plane position `[0,1)^2` reached by a ray leaving lens point `origin` along
    /// unit `dir` (through the focal plane for a thin lens), or `None` outside the image.
    pub fn film_point(&self, origin: Vec3, dir: Vec3) -> Option<Vec2> {
        let cos = dir.dot(self.forward);
        if cos <= 0.0 {
            return None;
        }
        // The direction from the lens centre to where the ray crosses the focal plane.
        let d = if self.aperture_radius_m > 0.0 {
            let focus = origin + dir * (self.focus_distance_m / cos);
            let to = focus - self.eye;
            to / to.dot(self.forward)
        } else {
            dir / cos
        };
        let fx = 0.5 * (d.dot(self.right) / (self.tan_half_fov * self.aspect) + 1.0);
        let fy = 0.5 * (1.0 - d.dot(self.up) / self.tan_half_fov);
        ((0.0..1.0).contains(&fx) && (0.0..1.0).contains(&fy)).then_some(Vec2::new(fx, fy))
    }

    /// The importance `We` of the ray leaving lens point `origin` along unit `dir` and the
    /// image point it reaches: `We = 1 / (A_image A_lens cos^4 theta)`, theta the angle between
    /// `dir` and the viewing direction (pbrt-v4 sec. 5.4.1, eq. 5.5): it makes the light
    /// tracer's splats, scaled by 1 / spp, estimate the same box-filtered pixel values as
    /// camera rays. `None` outside the image.
    pub fn importance(&self, origin: Vec3, dir: Vec3) -> Option<(f32, Vec2)> {
        let film = self.film_point(origin, dir)?;
        let cos = dir.dot(self.forward);
        let cos2 = cos * cos;
        Some((1.0 / (self.image_area_at_unit_distance() * self.lens_area() * cos2 * cos2), film))
    }

    /// The densities with which [`Camera::ray`], fed uniform film and lens points, produces a
    /// ray from `origin` along unit `dir`: per area on the lens (`1 / A_lens`) and per solid
    /// angle (`1 / (A_image cos^3 theta)`; pbrt-v4's `PDF_We`). Zero outside the image.
    pub fn pdf_we(&self, origin: Vec3, dir: Vec3) -> (f32, f32) {
        if self.film_point(origin, dir).is_none() {
            return (0.0, 0.0);
        }
        let cos = dir.dot(self.forward);
        (1.0 / self.lens_area(), 1.0 / (self.image_area_at_unit_distance() * cos * cos * cos))
    }

    /// Samples a point on the lens (uniform on the aperture disk with `u`; the eye for a
    /// pinhole) as seen from scene point `p`: the connection a light tracer makes to the
    /// camera. `None` when the ray from the lens point to `p` misses the image.
    pub fn sample_wi(&self, p: Vec3, u: Vec2) -> Option<LensSample> {
        let point = if self.aperture_radius_m > 0.0 {
            let d = concentric_disk(u) * self.aperture_radius_m;
            self.eye + d.x * self.right + d.y * self.up
        } else {
            self.eye
        };
        let to = point - p;
        let distance_m = to.length();
        if distance_m <= 0.0 {
            return None;
        }
        let wi = to / distance_m;
        let (importance, film) = self.importance(point, -wi)?;
        let cos_lens = wi.dot(self.forward).abs();
        let pdf = distance_m * distance_m / (cos_lens * self.lens_area());
        Some(LensSample { point, wi, distance_m, importance, pdf, film })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn centre_ray_looks_at_target_and_corners_span_the_fov() {
        let c = Camera::look_at(Vec3::ZERO, Vec3::new(0.0, 5.0, 0.0), Vec3::Z, 90.0, 2.0).unwrap();
        let r = c.ray(Vec2::splat(0.5), Vec2::ZERO);
        assert!((r.dir - Vec3::Y).length() < 1e-6);
        // Top edge centre: 45 degrees up; right edge centre: atan(2) to the right (+x).
        let top = c.ray(Vec2::new(0.5, 0.0), Vec2::ZERO).dir;
        assert!((top.z - 45f32.to_radians().sin()).abs() < 1e-5);
        let right = c.ray(Vec2::new(1.0, 0.5), Vec2::ZERO).dir;
        assert!((right.x - 2f32.atan().sin()).abs() < 1e-5);
    }

    #[test]
    fn thin_lens_rays_meet_on_the_focal_plane() {
        let mut c = Camera::look_at(Vec3::ZERO, Vec3::new(0.0, 5.0, 0.0), Vec3::Z, 40.0, 1.0).unwrap();
        c.set_lens(0.1, Some(3.0)).unwrap();
        let film = Vec2::new(0.3, 0.6);
        let a = c.ray(film, Vec2::new(0.1, 0.2));
        let b = c.ray(film, Vec2::new(0.9, 0.7));
        let pa = a.at((3.0 - a.origin.y) / a.dir.y);
        let pb = b.at((3.0 - b.origin.y) / b.dir.y);
        assert!((pa - pb).length() < 1e-5);
        assert!((a.origin - b.origin).length() > 0.01);
    }

    #[test]
    fn bad_cameras_are_rejected() {
        assert!(Camera::look_at(Vec3::ONE, Vec3::ONE, Vec3::Z, 40.0, 1.0).is_err());
        assert!(Camera::look_at(Vec3::ZERO, Vec3::Z, Vec3::Z, 40.0, 1.0).is_err());
        assert!(Camera::look_at(Vec3::ZERO, Vec3::X, Vec3::Z, 0.0, 1.0).is_err());
        assert!(Camera::look_at(Vec3::new(f32::NAN, 0.0, 0.0), Vec3::X, Vec3::Z, 40.0, 1.0).is_err());
    }

    /// `We` integrates to one over the image for every lens point (pbrt-v4's normalisation),
    /// and `film_point` inverts `ray`.
    #[test]
    fn importance_integrates_to_one_and_film_points_invert_rays() {
        for radius in [0.0f32, 0.05] {
            let mut c = Camera::look_at(Vec3::ZERO, Vec3::new(0.0, 5.0, 0.0), Vec3::Z, 50.0, 1.5).unwrap();
            c.set_lens(radius, Some(2.0)).unwrap();
            // Integral of We cos over the sphere of directions, by uniform sphere sampling.
            let mut rng = crate::core::rng::stream(3, 0, 0);
            let n = 400_000;
            let mut sum = 0.0f64;
            let origin = c.eye + 0.3 * radius * c.right;
            for _ in 0..n {
                let u = Vec2::new(crate::core::rng::uniform(&mut rng), crate::core::rng::uniform(&mut rng));
                let d = crate::core::sampling::uniform_sphere(u);
                if let Some((we, _)) = c.importance(origin, d) {
                    sum += f64::from(we * d.dot(c.forward)) * 4.0 * std::f64::consts::PI;
                }
            }
            let integral = sum / f64::from(n) * f64::from(c.lens_area());
            assert!((integral - 1.0).abs() < 0.02, "radius {radius}: {integral}");
            for (fx, fy) in [(0.1f32, 0.2f32), (0.5, 0.5), (0.9, 0.7)] {
                let r = c.ray(Vec2::new(fx, fy), Vec2::new(0.3, 0.8));
                let f = c.film_point(r.origin, r.dir).unwrap();
                assert!((f - Vec2::new(fx, fy)).length() < 1e-4, "{f} vs {fx},{fy}");
                let s = c.sample_wi(r.at(3.0), Vec2::new(0.3, 0.8)).unwrap();
                assert!((s.film - Vec2::new(fx, fy)).length() < 1e-4);
            }
        }
    }
}
