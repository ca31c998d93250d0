//! Light tracing (particle tracing): paths start on the lights and every vertex that can
//! scatter towards the camera is joined to a point on its lens and splatted onto the film
//! through the camera's importance (pbrt-v4's `LightPathIntegrator`, src/pbrt/cpu/integrators.cpp; Veach 1997,
//! sec. 10.2, the `t = 1` strategies of bidirectional path tracing without the others).
//!
//! One light path per camera sample (`width x height x spp` paths), each from its own random
//! stream keyed by its index; the splats are summed in fixed point ([`super::splat`]), so the
//! image is bit-identical for any thread count and any split of the paths over MPI ranks.
//! Like every light tracer it cannot see surfaces through a perfect mirror or glass (a
//! camera connection needs a non-Dirac BSDF at the vertex), nor the background.

use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use super::splat::{SplatFilm, finish};
use super::{Bsdf, Camera, Film, Frame, RenderOutput, RenderScene, RenderSettings, u2};
use crate::core::Ray;
use crate::core::rng::{Rng64, stream, uniform};
use crate::dist::Cluster;

/// Random-stream domain of the light paths.
pub const LIGHT_DOMAIN: u64 = 0x4c49_4748; // "LIGH"
/// Light paths a work unit (dealt to threads and ranks).
const BLOCK: u64 = 4096;

/// The throughput factor of a BSDF sample on a path carrying importance from the lights:
/// `f |cos| / pdf`, without the `1 / eta^2` radiance compression of refraction (the adjoint
/// BSDF; pbrt-v4 sec. 9.5.2, `TransportMode::Importance`; Veach 1997, sec. 5.2).
#[inline]
pub fn importance_weight(bsdf: &Bsdf, wo: Vec3, s: &super::bsdf::BsdfSample) -> Vec3 {
    let w = s.weight();
    match *bsdf {
        Bsdf::Dielectric { eta, .. } if s.wi.z * wo.z < 0.0 => {
            let e = if wo.z >= 0.0 { eta } else { 1.0 / eta };
            w * (e * e)
        }
        _ => w,
    }
}

/// Traces one light path with at most `max_depth` scattering vertices and splats its
/// contributions (unscaled: the film's sums are divided by spp at the end).
pub fn trace(
    scene: &RenderScene,
    camera: &Camera,
    max_depth: u32,
    rng: &mut Rng64,
    film: &mut SplatFilm,
    rays: &mut u64,
) {
    let Some((index, pmf)) = scene.lights.choose(uniform(rng)) else { return };
    let light = &scene.lights.lights[index];
    let (u_pos, u_dir) = (u2(rng), u2(rng));
    let Some(e) = light.sample_le(u_pos, u_dir) else { return };
    let on_surface = e.normal != Vec3::ZERO;
    // The light seen directly (path length 0): area lights only, a point cannot be seen.
    if on_surface && let Some(c) = camera.sample_wi(e.point, u2(rng)) {
        let le = light.le_towards(e.normal, c.wi);
        if le != Vec3::ZERO {
            *rays += 1;
            if !scene.accel.occluded(&Ray::spawn_to(e.point, e.normal, c.point)) {
                let l = le * (e.normal.dot(c.wi).abs() * c.importance / (pmf * e.pdf_pos * c.pdf));
                film.add(c.film, l);
            }
        }
    }
    let cos = if on_surface { e.normal.dot(e.dir).abs() } else { 1.0 };
    let mut beta = e.le * (cos / (pmf * e.pdf_pos * e.pdf_dir));
    let mut ray = if on_surface { Ray::spawn(e.point, e.normal, e.dir) } else { Ray::new(e.point, e.dir) };
    let mut depth = 0u32;
    while depth < max_depth {
        *rays += 1;
        let Some(hit) = scene.intersect(&ray) else { break };
        depth += 1;
        let bsdf = scene.surfaces[hit.surface as usize].bsdf;
        let frame = Frame::new(hit.normal);
        let wo = frame.to_local(-ray.dir);
        let u_lens = u2(rng);
        if !bsdf.is_delta()
            && let Some(c) = camera.sample_wi(hit.point, u_lens)
        {
            let wi = frame.to_local(c.wi);
            // The adjoint of these BSDFs (Lambert, GGX metal) is the BSDF itself.
            let f = bsdf.eval(wo, wi);
            if f != Vec3::ZERO {
                *rays += 1;
                if !scene.occluded(&hit, c.point) {
                    film.add(c.film, beta * f * (wi.z.abs() * c.importance / c.pdf));
                }
            }
        }
        let (u, uc, u_rr) = (u2(rng), uniform(rng), uniform(rng));
        let Some(s) = bsdf.sample(wo, u, uc) else { break };
        beta *= importance_weight(&bsdf, wo, &s);
        if depth >= super::path::RR_START_DEPTH {
            let q = beta.max_element().min(1.0);
            if q <= 0.0 || u_rr >= q {
                break;
            }
            beta /= q;
        } else if beta == Vec3::ZERO {
            break;
        }
        ray = Ray::spawn(hit.point, hit.normal, frame.to_world(s.wi));
    }
}

/// Renders by light tracing on this process's share of `cluster` (blocks of [`BLOCK`] paths
/// dealt round-robin); rank 0 returns the image.
pub fn render_on(
    cluster: &Cluster,
    scene: &RenderScene,
    camera: &Camera,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Option<RenderOutput> {
    let start = Instant::now();
    let share = cluster.share();
    let (w, h, spp) = (settings.width, settings.height, settings.spp);
    let paths = u64::from(w) * u64::from(h) * u64::from(spp);
    let mine: Vec<u64> = (0..paths.div_ceil(BLOCK)).filter(|b| share.owns(*b)).collect();
    let min_len = (mine.len() / (8 * rayon::current_num_threads())).max(1);
    let (splats, rays) = mine
        .par_iter()
        .with_min_len(min_len)
        .fold(
            || (SplatFilm::new(w, h), 0u64),
            |(mut film, mut rays), &block| {
                let (first, end) = (block * BLOCK, ((block + 1) * BLOCK).min(paths));
                for i in first..end {
                    let mut rng = stream(settings.seed, LIGHT_DOMAIN, i);
                    trace(scene, camera, settings.max_depth, &mut rng, &mut film, &mut rays);
                }
                progress(end / u64::from(spp) - first / u64::from(spp));
                (film, rays)
            },
        )
        .reduce(|| (SplatFilm::new(w, h), 0), |(a, ra), (b, rb)| (a.merge(&b), ra + rb));
    finish(cluster, Film::new(w, h), splats, spp, rays, start)
}
