//! Volumetric ray marching (`--integrator raymarch`) through the same media as
//! [`super::volpath`] (a fog, `[[media]]`, density grids, media inside boundaries), for
//! comparison with it: the same path tracer at surfaces (light samples attenuated by the
//! fog's transmittance, BSDF samples joined by MIS), but the light scattered into each ray
//! segment is integrated by marching along it instead of by sampling free flights.
//!
//! Along a segment of length `d` the in-scattered radiance is
//! `integral_0^d T(t) sigma_s L_s(t) dt`, with `L_s` the single-scattered light from the
//! lights, `phase Li T_light` (the equation of transfer, \[pbrt-v4\] sec. 14.1 in
//! docs/references.md). The march takes points `t_k = (k + u) h` for `t_k < d`, one
//! uniform `u` per segment (a jittered start), each weighted by the step `h`: stratified
//! sampling, unbiased for any step (the last, partial stratum is reached with probability
//! equal to its share of a step), with no banding; the step only sets the variance. At
//! each point one light sample (no MIS: the march does not sample the phase function). The
//! surface behind is attenuated by `exp(-sigma_t d)`.
//!
//! In a density grid the march runs over the part of the segment inside the grid's box,
//! with the step taken from the majorant (`STEP_MEAN_FREE_PATHS / sigma_bar`), and the
//! transmittance to each point is the exponential of the optical depth summed along the march
//! (`sigma_t` at the first point times its distance, then the trapezoid rule between points):
//! exact for a constant density, otherwise biased by the step (second order for a smooth
//! density; the jitter does not remove the bias of the exponential). The shadow rays from the
//! points to the lights take the unbiased ratio-tracked transmittance of
//! [`super::media`], and so does a segment past the last bounce. What is left out: light scattered
//! more than once in the fog (a march scatters light from the lights only, not from
//! surfaces or the fog) and the background scattered by the fog, so raymarch agrees with
//! volpath when single scattering from the lights dominates (thin fog, black background,
//! or `max_depth` 1).

use glam::{Vec2, Vec3};

use super::RenderScene;
use super::media::{MAX_CROSSINGS, PathMedia, Volume};
use super::medium::Medium;
use super::path::emitted;
use super::sampler::Sampler;
use super::volpath::{light_in_medium, surface_bounce};
use crate::core::Ray;

/// The step, in mean free paths of the densest channel (`1 / max sigma_t`; in a grid, of
/// the majorant).
pub const STEP_MEAN_FREE_PATHS: f32 = 0.25;
/// At least this many steps a segment (the step shrinks on short segments).
pub const MIN_STEPS: f32 = 16.0;
/// At most this many steps a segment (the step grows on long segments).
pub const MAX_STEPS: f32 = 1024.0;
/// A segment that leaves the scene is marched until the transmittance of its most
/// transparent scattering channel falls to this (the light beyond is dropped: a bias of at
/// most this fraction of the in-scattered light).
pub const ESCAPE_TRANSMITTANCE: f32 = 1e-4;

/// The step along a segment of `length_m` in `fog`, metres:
/// `STEP_MEAN_FREE_PATHS / max sigma_t`, kept within `[length / MAX_STEPS, length / MIN_STEPS]`.
pub fn step_m(fog: &Medium, length_m: f32) -> f32 {
    step_for(fog.sigma_t_per_m().max_element(), length_m, None)
}

/// Most steps a segment takes with a step given by the user (`--raymarch-step`): a longer
/// segment takes longer steps.
pub const MAX_USER_STEPS: f32 = 65_536.0;

/// The step for a largest extinction (or majorant) `sigma_max_per_m` along `length_m`, or
/// the user's `step_m` (at least `length_m / MAX_USER_STEPS`).
fn step_for(sigma_max_per_m: f32, length_m: f32, step_m: Option<f32>) -> f32 {
    if let Some(h) = step_m {
        return h.max(length_m / MAX_USER_STEPS);
    }
    let mfp = STEP_MEAN_FREE_PATHS / sigma_max_per_m.max(f32::MIN_POSITIVE);
    mfp.min(length_m / MIN_STEPS).max(length_m / MAX_STEPS)
}

/// The radiance along camera ray `ray` through `fog` and the scene's media (neither: the
/// path tracer's estimate), with at most `max_depth` bounces; a march along a segment counts
/// as one bounce. The camera ray starts in `camera_medium` as in [`super::volpath::li`];
/// `step_m` overrides the default step ([`step_m`]).
#[allow(clippy::too_many_arguments)]
pub fn li(
    scene: &RenderScene,
    mut ray: Ray,
    max_depth: u32,
    sampler: &mut Sampler,
    rays: &mut u64,
    fog: Option<&Medium>,
    camera_medium: Option<usize>,
    step_m: Option<f32>,
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
            if depth < max_depth {
                let (light, tr) = march(scene, &media, m, &ray, t_max, step_m, sampler, rays);
                l += beta * light;
                beta *= tr;
            } else {
                beta *= m.transmittance(&ray, t_max, sampler);
            }
        }
        let Some(hit) = hit else {
            l += beta * scene.background;
            break;
        };
        if media.is_interface(&hit) {
            crossings += 1;
            if crossings > MAX_CROSSINGS || beta == Vec3::ZERO {
                break;
            }
            current = media.after(current, &hit, ray.dir);
            ray = Ray::spawn(hit.point, hit.normal, ray.dir);
            continue;
        }
        crossings = 0;
        l += emitted(scene, &hit, ray.dir, beta, (specular, prev_pdf, prev_point));
        if depth >= max_depth || beta == Vec3::ZERO {
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

/// The light from the lights scattered once into `ray` over `[0, t_max)` (infinite: the ray
/// leaves the scene), by the jittered march of the module documentation, and the
/// transmittance over the segment.
#[allow(clippy::too_many_arguments)]
fn march<'a>(
    scene: &RenderScene,
    media: &PathMedia<'a>,
    m: &'a Volume,
    ray: &Ray,
    t_max: f32,
    step_m: Option<f32>,
    sampler: &mut Sampler,
    rays: &mut u64,
) -> (Vec3, Vec3) {
    let Some(grid) = &m.grid else {
        let light = march_homogeneous(scene, media, m, ray, t_max, step_m, sampler, rays);
        return (light, m.medium.transmittance(t_max));
    };
    let Some((t0, t1)) = grid.clip(ray, t_max) else {
        return (Vec3::ZERO, Vec3::ONE);
    };
    let (sigma_s, sigma_t) = (m.medium.sigma_s_per_m, m.medium.sigma_t_per_m());
    let length_m = t1 - t0;
    let h = step_for(m.majorant_per_m(), length_m, step_m);
    let mut sum = Vec3::ZERO;
    // The optical depth at the current point, per channel at density 1 (times sigma_t).
    let mut t = t0 + sampler.get_1d() * h;
    let mut density = if t < t1 { grid.density(ray.at(t)) } else { 0.0 };
    let mut depth = density * (t - t0);
    let mut last = (t0, 0.0f32);
    while t < t1 {
        if density > 0.0 && sigma_s != Vec3::ZERO {
            let u = Vec2::new(sampler.get_1d(), sampler.get_1d());
            let tr = (-sigma_t * depth).exp();
            sum +=
                tr * density * light_in_medium(scene, media, m, ray.at(t), ray.dir, u, false, sampler, rays);
        }
        last = (t, density);
        t += h;
        if t < t1 {
            let next = grid.density(ray.at(t));
            depth += 0.5 * h * (density + next);
            density = next;
        }
    }
    if last.0 > t0 {
        depth += last.1 * (t1 - last.0);
    } else {
        // No point fell inside (a segment shorter than the jitter): the depth is unknown
        // from the march; take the midpoint's density.
        depth = grid.density(ray.at(0.5 * (t0 + t1))) * length_m;
    }
    (sigma_s * sum * h, (-sigma_t * depth).exp())
}

/// [`march`] in a homogeneous medium (the transmittance closed form).
#[allow(clippy::too_many_arguments)]
fn march_homogeneous<'a>(
    scene: &RenderScene,
    media: &PathMedia<'a>,
    m: &'a Volume,
    ray: &Ray,
    t_max: f32,
    step_m: Option<f32>,
    sampler: &mut Sampler,
    rays: &mut u64,
) -> Vec3 {
    let medium = &m.medium;
    let sigma_t = medium.sigma_t_per_m();
    let length_m = if t_max.is_finite() {
        t_max
    } else {
        // The most transparent channel that scatters (sigma_t >= sigma_s > 0 there).
        let thinnest = (0..3)
            .filter(|&c| medium.sigma_s_per_m[c] > 0.0)
            .map(|c| sigma_t[c])
            .fold(f32::INFINITY, f32::min);
        -ESCAPE_TRANSMITTANCE.ln() / thinnest
    };
    if medium.sigma_s_per_m == Vec3::ZERO || !(length_m > 0.0 && length_m.is_finite()) {
        return Vec3::ZERO;
    }
    let h = step_for(sigma_t.max_element(), length_m, step_m);
    let mut sum = Vec3::ZERO;
    let mut t = sampler.get_1d() * h;
    while t < length_m {
        let u = Vec2::new(sampler.get_1d(), sampler.get_1d());
        sum += medium.transmittance(t)
            * light_in_medium(scene, media, m, ray.at(t), ray.dir, u, false, sampler, rays);
        t += h;
    }
    medium.sigma_s_per_m * sum * h
}
