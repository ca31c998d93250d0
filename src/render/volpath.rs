//! Volumetric path tracing (`--integrator volpath`): the path tracer of [`super::path`] with
//! free flights between surfaces through the medium the path is in (a global fog or
//! `[[media]]` entry, or the medium inside a closed boundary mesh; [`super::media`]). A
//! flight ends in the medium by [`Volume::sample_flight`] (closed form when homogeneous,
//! delta tracking in a density grid); there the path takes a light sample (weighted by the
//! phase function and the transmittance to the light) and a phase-function sample, joined by
//! MIS with the power heuristic as at surfaces; light samples from surfaces are attenuated by
//! the transmittance too (Beer-Lambert, or ratio tracking through grids and across
//! index-matched boundaries). Index-matched boundaries pass the ray unchanged and switch the
//! medium; they are no bounce. The structure of pbrt-v4's `VolPathIntegrator` (sec. 14.2).

use glam::{Vec2, Vec3};

use super::media::{MAX_CROSSINGS, PathMedia, Volume};
use super::medium::Medium;
use super::path::{RR_START_DEPTH, Vertex, emitted, sample_direct_through, sample_direct_with};
use super::sampler::Sampler;
use super::{Frame, RenderScene, power_heuristic};
use crate::core::{Hit, Ray};

/// The radiance along camera ray `ray` through `fog` (outside the scene's own media; `None`
/// and no media: the plain path tracer's estimate), with at most `max_depth` bounces,
/// scatterings in the medium included. The camera ray starts in the bounded medium
/// `camera_medium` ([`super::media::SceneMedia::enclosing`] the eye), else the outer one.
pub fn li(
    scene: &RenderScene,
    mut ray: Ray,
    max_depth: u32,
    sampler: &mut Sampler,
    rays: &mut u64,
    fog: Option<&Medium>,
    camera_medium: Option<usize>,
) -> Vec3 {
    let fog_volume = fog.map(|m| Volume::homogeneous(*m));
    let media = PathMedia::new(&scene.media, fog_volume.as_ref());
    let mut current = media.start(camera_medium);
    let mut l = Vec3::ZERO;
    let mut beta = Vec3::ONE;
    let mut specular = true;
    let mut prev_pdf = 0.0f32;
    let mut prev_point = ray.origin;
    let mut depth = 0u32;
    let mut crossings = 0u32;
    loop {
        *rays += 1;
        let hit = scene.intersect(&ray);
        if let Some(m) = current {
            let t_max = hit.map_or(f32::INFINITY, |h| h.t);
            let flight = m.sample_flight(&ray, t_max, sampler);
            beta *= flight.weight;
            if flight.scattered {
                if depth >= max_depth || beta == Vec3::ZERO {
                    break;
                }
                sampler.start_bounce(depth);
                let (u_light, u_phase) = (sampler.get_2d(), sampler.get_2d());
                depth += 1;
                let p = ray.at(flight.t);
                l += beta * light_in_medium(scene, &media, m, p, ray.dir, u_light, true, sampler, rays);
                let wi = m.medium.sample_phase(ray.dir, u_phase);
                specular = false;
                prev_pdf = m.medium.phase(ray.dir, wi);
                prev_point = p;
                ray = Ray::new(p, wi);
                crossings = 0;
                if !roulette(&mut beta, depth, sampler) {
                    break;
                }
                continue;
            }
            if beta == Vec3::ZERO {
                break;
            }
        }
        let Some(hit) = hit else {
            l += beta * scene.background;
            break;
        };
        if media.is_interface(&hit) {
            // An index-matched boundary: the ray goes on unchanged in the other medium.
            crossings += 1;
            if crossings > MAX_CROSSINGS {
                break;
            }
            current = media.after(current, &hit, ray.dir);
            ray = Ray::spawn(hit.point, hit.normal, ray.dir);
            continue;
        }
        crossings = 0;
        l += emitted(scene, &hit, ray.dir, beta, (specular, prev_pdf, prev_point));
        if depth >= max_depth {
            break;
        }
        let (light, next) =
            surface_bounce(scene, &media, current, &hit, &ray, &mut beta, &mut depth, sampler, rays);
        l += light;
        let Some((next, bsdf_pdf, bsdf_specular)) = next else {
            break;
        };
        (specular, prev_pdf, prev_point) = (bsdf_specular, bsdf_pdf, hit.point);
        current = media.after(current, &hit, next.dir);
        ray = next;
    }
    l
}

/// The surface vertex `hit` (reached along `ray` in the medium `current`) of a path through
/// `media`, for volpath and raymarch alike: a light sample attenuated by the transmittance
/// to the light, then a BSDF sample and Russian roulette, as in [`super::path::trace`].
/// Returns the light the vertex adds and, unless the path ends there, the next ray with its
/// BSDF density and whether it was specular; `beta` and `depth` are updated.
#[allow(clippy::too_many_arguments)]
pub(super) fn surface_bounce<'a>(
    scene: &RenderScene,
    media: &PathMedia<'a>,
    current: Option<&'a Volume>,
    hit: &Hit,
    ray: &Ray,
    beta: &mut Vec3,
    depth: &mut u32,
    sampler: &mut Sampler,
    rays: &mut u64,
) -> (Vec3, Option<(Ray, f32, bool)>) {
    sampler.start_bounce(*depth);
    let (u_light, u_bsdf) = (sampler.get_2d(), sampler.get_2d());
    *depth += 1;
    let bsdf = scene.surfaces[hit.surface as usize].bsdf;
    let frame = Frame::new(hit.normal);
    let wo = frame.to_local(-ray.dir);
    let mut light = Vec3::ZERO;
    if !bsdf.is_delta() {
        let v = Vertex { hit, frame, wo, bsdf };
        light = if media.simple() {
            // Only a homogeneous fog (or nothing): Beer-Lambert along a plain shadow ray.
            let tr = |d: f32| current.map_or(Vec3::ONE, |m| m.medium.transmittance(d));
            *beta * sample_direct_through(scene, &v, u_light, rays, true, tr)
        } else {
            *beta
                * sample_direct_with(scene, &v, u_light, rays, true, |ls, rays| {
                    let shadow = match ls.shadow_normal {
                        Some(m) => Ray::between(hit.point, hit.normal, ls.shadow_point, m),
                        None => Ray::spawn_to(hit.point, hit.normal, ls.shadow_point),
                    };
                    let start = media.after(current, hit, shadow.dir);
                    media.shadow_transmittance(scene, start, shadow, sampler, rays)
                })
        };
    }
    let u_lobe = if bsdf.has_lobes() { sampler.get_1d() } else { 0.0 };
    let Some(s) = bsdf.sample(wo, u_bsdf, u_lobe) else {
        return (light, None);
    };
    *beta *= s.weight();
    let next = Ray::spawn(hit.point, hit.normal, frame.to_world(s.wi));
    if !roulette(beta, *depth, sampler) {
        return (light, None);
    }
    (light, Some((next, s.pdf, s.specular)))
}

/// Russian roulette from [`RR_START_DEPTH`] on (survival max(beta), at most 1); false when
/// the path ends.
#[inline]
pub(super) fn roulette(beta: &mut Vec3, depth: u32, sampler: &mut Sampler) -> bool {
    if depth < RR_START_DEPTH {
        return *beta != Vec3::ZERO;
    }
    let q = beta.max_element().min(1.0);
    if q <= 0.0 || sampler.get_1d() >= q {
        return false;
    }
    *beta /= q;
    true
}

/// Direct light at a scattering point `p` of the medium `m`, for light travelling along
/// `dir`: `phase Li T / pdf`, weighted against phase sampling by the power heuristic when
/// `mis` (volpath samples the phase function too; raymarch does not, so its weight is 1).
#[allow(clippy::too_many_arguments)]
pub(super) fn light_in_medium<'a>(
    scene: &RenderScene,
    media: &PathMedia<'a>,
    m: &'a Volume,
    p: Vec3,
    dir: Vec3,
    u: Vec2,
    mis: bool,
    sampler: &mut Sampler,
    rays: &mut u64,
) -> Vec3 {
    let Some((index, pmf, ux)) = scene.lights.choose_reusing(u.x) else {
        return Vec3::ZERO;
    };
    let Some(ls) = scene.lights.lights[index].sample(p, Vec2::new(ux, u.y)) else {
        return Vec3::ZERO;
    };
    let phase = m.medium.phase(dir, ls.wi);
    if phase <= 0.0 || ls.li == Vec3::ZERO {
        return Vec3::ZERO;
    }
    *rays += 1;
    // A point in the air has no surface to leave: the shadow ray starts at it and stops
    // short of the light's surface.
    let to = ls.shadow_point - p;
    let d = to.length();
    if d.is_nan() || d <= 0.0 {
        return Vec3::ZERO;
    }
    let shadow = Ray::segment(p, to / d, d - (1e-4 * d).max(1e-5));
    let tr = if media.simple() {
        if scene.accel.occluded(&shadow) {
            return Vec3::ZERO;
        }
        m.medium.transmittance(ls.distance)
    } else {
        media.shadow_transmittance(scene, Some(m), shadow, sampler, rays)
    };
    if tr == Vec3::ZERO {
        return Vec3::ZERO;
    }
    if ls.delta {
        return phase * ls.li * tr / pmf;
    }
    let light_pdf = ls.pdf * pmf;
    let weight = if mis { power_heuristic(light_pdf, phase) } else { 1.0 };
    phase * ls.li * tr * (weight / light_pdf)
}
