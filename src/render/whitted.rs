//! Whitted ray tracing (Whitted 1980, "An improved illumination model for shaded display"):
//! shadow rays to point lights, perfect mirror reflection, refraction by Snell's law weighted
//! by the exact Fresnel equations, total internal reflection, and a maximum depth.
//!
//! Area lights (emissive triangles and spheres) are approximated by point lights at their
//! centre with the radiant intensity of a Lambertian emitter (`Le A cos` for a triangle,
//! `Le pi r^2` for a sphere), so shadows are hard. Glossy metals reflect the mirror direction
//! weighted by Fresnel (Whitted's `k_s S` term) and show GGX highlights from the lights.
//! Deterministic: no random numbers.

use glam::Vec3;

use super::bsdf::{Bsdf, fresnel_dielectric, fresnel_schlick, reflect_local, refract_local};
use super::{Frame, RenderScene};
use crate::core::{Hit, Ray};

/// Direct light at `hit` from every light taken as a point, with shadow rays: `f |cos| I / d^2`.
pub fn direct_from_points(
    scene: &RenderScene,
    hit: &Hit,
    frame: &Frame,
    wo: Vec3,
    bsdf: &Bsdf,
    rays: &mut u64,
    shadows: bool,
) -> Vec3 {
    let mut l = Vec3::ZERO;
    for light in &scene.lights.lights {
        let centre = light.center();
        let dir = (hit.point - centre).normalize_or_zero();
        let (pos, intensity) = light.as_point(dir);
        let to = pos - hit.point;
        let d2 = to.length_squared();
        if d2 == 0.0 || intensity == Vec3::ZERO {
            continue;
        }
        let wi = frame.to_local(to / d2.sqrt());
        let f = bsdf.eval(wo, wi) * wi.z.abs();
        if f == Vec3::ZERO {
            continue;
        }
        if shadows {
            *rays += 1;
            if scene.occluded(hit, pos) {
                continue;
            }
        }
        l += f * intensity / d2;
    }
    l
}

/// Radiance along `ray` at recursion depth `depth`.
pub fn li(scene: &RenderScene, ray: &Ray, depth: u32, max_depth: u32, rays: &mut u64) -> Vec3 {
    *rays += 1;
    let Some(hit) = scene.intersect(ray) else {
        return scene.background;
    };
    let optics = &scene.surfaces[hit.surface as usize];
    let mut l = scene.emitted(&hit);
    let frame = Frame::new(hit.normal);
    let wo = frame.to_local(-ray.dir);
    let bsdf = optics.bsdf;
    let recurse = depth < max_depth;
    let trace = |wi: Vec3, rays: &mut u64| {
        let r = Ray::spawn(hit.point, hit.normal, frame.to_world(wi));
        li(scene, &r, depth + 1, max_depth, rays)
    };
    match bsdf {
        Bsdf::Lambert { .. } => l += direct_from_points(scene, &hit, &frame, wo, &bsdf, rays, true),
        Bsdf::Metal { f0, .. } => {
            if !bsdf.is_delta() {
                l += direct_from_points(scene, &hit, &frame, wo, &bsdf, rays, true);
            }
            if recurse {
                l += fresnel_schlick(f0, wo.z) * trace(reflect_local(wo), rays);
            }
        }
        Bsdf::Dielectric { eta, tint } => {
            if recurse {
                let r = fresnel_dielectric(wo.z, eta);
                l += r * trace(reflect_local(wo), rays);
                if let Some((wt, eta_used)) = refract_local(wo, eta) {
                    l += tint * ((1.0 - r) / (eta_used * eta_used)) * trace(wt, rays);
                }
            }
        }
    }
    l
}
