//! Ray casting (Appel 1968): primary visibility and local shading only, no shadows and no
//! secondary rays. Diffuse surfaces are Lambertian; metals and glass get a normalised
//! Blinn-Phong highlight (Blinn 1977) with exponent `2 / alpha^2 - 2` (Walter et al. 2007).
//! Lights are the scene's lights taken as points; a scene without lights is lit by a
//! headlight at the eye.

use std::f32::consts::{FRAC_1_PI, PI};

use glam::Vec3;

use super::RenderScene;
use super::bsdf::Bsdf;
use crate::core::Ray;

/// Local shading at the first hit of `ray`.
pub fn li(scene: &RenderScene, ray: &Ray, rays: &mut u64) -> Vec3 {
    *rays += 1;
    let Some(hit) = scene.intersect(ray) else {
        return scene.background;
    };
    let optics = &scene.surfaces[hit.surface as usize];
    let mut l = scene.emitted(&hit);
    let n = hit.facing_normal();
    let v = -ray.dir;
    let (kd, ks, shininess) = match optics.bsdf {
        Bsdf::Lambert { albedo } => (albedo, Vec3::ZERO, 0.0),
        Bsdf::Metal { f0, alpha } => (Vec3::ZERO, f0, 2.0 / alpha.max(0.05).powi(2) - 2.0),
        Bsdf::Dielectric { tint, .. } => (0.1 * tint, Vec3::splat(0.5), 500.0),
    };
    let shade = |wl: Vec3, e: Vec3| -> Vec3 {
        let cos = n.dot(wl);
        if cos <= 0.0 {
            return Vec3::ZERO;
        }
        let h = (wl + v).normalize_or_zero();
        let spec = (shininess + 8.0) / (8.0 * PI) * n.dot(h).max(0.0).powf(shininess);
        (kd * FRAC_1_PI + ks * spec) * e * cos
    };
    if scene.lights.is_empty() {
        // Headlight of unit radiance: a white surface facing the eye shows its albedo.
        l += shade(v, Vec3::splat(PI));
        return l;
    }
    for light in &scene.lights.lights {
        let centre = light.center();
        let (pos, intensity) = light.as_point((hit.point - centre).normalize_or_zero());
        let to = pos - hit.point;
        let d2 = to.length_squared();
        if d2 > 0.0 {
            l += shade(to / d2.sqrt(), intensity / d2);
        }
    }
    l
}
