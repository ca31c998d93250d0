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
}
