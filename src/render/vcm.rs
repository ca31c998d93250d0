//! Vertex connection and merging (Georgiev, Krivanek, Davidovic and Slusallek 2012; the same
//! estimator as Hachisuka, Pantaleoni and Jensen's unified path sampling, 2012): BDPT's joins
//! ([`super::bdpt`]) and photon mapping's density estimates ("merges") in one estimator,
//! every strategy weighted by the balance heuristic. Merging samples what no join can: light
//! that reaches a diffuse surface through glass or a mirror and is seen through glass or a
//! mirror again (specular-diffuse-specular paths, such as a caustic seen in a mirror), which
//! BDPT finds only when the eye path happens to hit the light.
//!
//! Each iteration (one per sample per pixel, `--spp`):
//! 1. **Light pass.** `N` light subpaths (`--photons`, at least one a pixel) are traced and
//!    kept; their non-Dirac vertices after the light go into a hashed grid
//!    ([`super::point_grid`]) with this iteration's radius `r`.
//! 2. **Camera pass.** Each pixel traces a camera subpath, joins it to the light subpath of
//!    the same index in every way (BDPT; `t = 1` joins splat onto the film), and at each
//!    non-Dirac vertex merges it with every kept light vertex within `r`:
//!    `beta_eye f(wo, wi) beta_light / (N pi r^2)` times the merge's MIS weight.
//!    The weights count the merges as strategies of density `eta p_light(x)` over the join's
//!    that ends the eye path at `x`, `eta = N pi r^2` ([`super::bdpt::merge_weight`]).
//! 3. The radius shrinks as `r_i = r_0 i^((alpha - 1) / 2)` (Georgiev et al. 2012;
//!    SmallVCM's schedule, alpha 0.75), so the merges' bias vanishes as iterations grow while
//!    their variance stays bounded: the estimator is consistent.
//!
//! Determinism: light subpaths draw from streams keyed by (iteration, path), camera samples
//! from streams keyed by (iteration, pixel); the grid is built serially, so every pixel sums
//! its merges in one order; splats are fixed point. Under MPI every rank traces every light
//! subpath (the merges need them all), renders its own tiles, and the light images are summed
//! exactly ([`super::splat::finish`]), so rank 0's image is the single process's, bit for bit.

use std::f32::consts::PI;
use std::sync::{Mutex, PoisonError};
use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::bdpt::{
    Split, Vertex, VertexKind, camera_subpath, connect_all, light_subpath, merge_weight, specular_emission,
    splits_pixel,
};
use super::point_grid::PointGrid;
use super::splat::{HeldSplats, SplatFilm, finish};
use super::{Camera, Film, RenderOutput, RenderScene, RenderSettings, u2};
use crate::core::rng::{Rng64, stream};
use crate::dist::Cluster;

/// Random-stream domain of the light subpaths.
pub const LIGHT_DOMAIN: u64 = 0x5643_4c54; // "VCLT"
/// Random-stream domain of the camera samples.
pub const CAMERA_DOMAIN: u64 = 0x5643_4341; // "VCCA"
/// The radius reduction exponent alpha of `r_i = r_0 i^((alpha - 1) / 2)`: SmallVCM's default
/// (SmallVCM, with [Georgiev2012] in docs/references.md).
pub const ALPHA: f32 = 0.75;
/// The default initial merging radius as a fraction of the diagonal of the bounding box of
/// the first iteration's light vertices, at [`REFERENCE_LIGHT_PATHS`] light subpaths an
/// iteration; with `N` subpaths it is scaled by `sqrt(REFERENCE_LIGHT_PATHS / N)`, so that a
/// disc holds about as many light vertices whatever the resolution (and a merge costs about
/// the same), while the disc shrinks with the pixels.
pub const DEFAULT_RADIUS_FRACTION: f32 = 0.02;
/// See [`DEFAULT_RADIUS_FRACTION`]: the light subpaths of a 32 x 32 image.
pub const REFERENCE_LIGHT_PATHS: f32 = 1024.0;
/// The least cosine between the normals of a merged light vertex and the eye vertex: light
/// that landed on a surface across an edge or a corner is not merged (without this test the
/// top of the Cornell box's tall block, lit from the wall behind it, came out 20 % bright).
pub const MIN_NORMAL_COSINE: f32 = 0.8;
/// Light subpaths a work unit.
const BLOCK: u64 = 64;

/// The light subpaths of one iteration, kept for joins and merges.
struct LightPaths {
    /// Every subpath's vertices, one after another.
    vertices: Vec<Vertex>,
    /// Where each subpath starts in `vertices` (one more than the subpaths).
    starts: Vec<usize>,
    /// Where the subpath of each vertex starts in `vertices` (read once a merge candidate:
    /// one lookup rather than two).
    start_of: Vec<u32>,
}

impl LightPaths {
    fn path(&self, j: usize) -> &[Vertex] {
        &self.vertices[self.starts[j]..self.starts[j + 1]]
    }
}

/// Light subpaths per iteration: `--photons`, at least one a pixel (each pixel joins its
/// camera subpath to the subpath of its own index).
pub fn light_paths_per_iteration(settings: &RenderSettings) -> u64 {
    let pixels = u64::from(settings.width) * u64::from(settings.height);
    settings.photons.photons_per_iteration.unwrap_or(pixels).max(pixels)
}

/// Memory the light subpaths of one iteration may hold, bytes (every subpath at its longest).
pub fn light_path_bytes(settings: &RenderSettings) -> u64 {
    let per_vertex = (std::mem::size_of::<Vertex>() + 8 + 4 + 32) as u64;
    light_paths_per_iteration(settings)
        .saturating_mul(u64::from(settings.max_depth) + 1)
        .saturating_mul(per_vertex)
}

/// Traces light subpaths `range` of iteration `it`: their vertices and each one's length.
fn trace_light_paths(
    scene: &RenderScene,
    settings: &RenderSettings,
    it: u32,
    range: std::ops::Range<u64>,
    rays: &mut u64,
) -> (Vec<Vertex>, Vec<u32>) {
    let mut vertices = Vec::new();
    let mut lengths = Vec::with_capacity((range.end - range.start) as usize);
    let mut path = Vec::new();
    for j in range {
        let mut rng = stream(settings.seed, LIGHT_DOMAIN, (u64::from(it) << 40) | j);
        light_subpath(scene, settings.max_depth, &mut rng, &mut path, rays);
        lengths.push(path.len() as u32);
        vertices.extend_from_slice(&path);
    }
    (vertices, lengths)
}

/// Traces and gathers the light subpaths of iteration `it`.
fn light_pass(scene: &RenderScene, settings: &RenderSettings, it: u32, n: u64, rays: &mut u64) -> LightPaths {
    let traced: Vec<(Vec<Vertex>, Vec<u32>, u64)> = (0..n.div_ceil(BLOCK))
        .into_par_iter()
        .map(|b| {
            let mut r = 0;
            let (v, l) = trace_light_paths(scene, settings, it, b * BLOCK..((b + 1) * BLOCK).min(n), &mut r);
            (v, l, r)
        })
        .collect();
    let total: usize = traced.iter().map(|t| t.0.len()).sum();
    let mut paths = LightPaths {
        vertices: Vec::with_capacity(total),
        starts: Vec::with_capacity(n as usize + 1),
        start_of: Vec::with_capacity(total),
    };
    paths.starts.push(0);
    for (v, lengths, r) in traced {
        *rays += r;
        for len in lengths {
            let start = paths.starts[paths.starts.len() - 1];
            paths.start_of.extend(std::iter::repeat_n(start as u32, len as usize));
            paths.starts.push(start + len as usize);
        }
        paths.vertices.extend(v);
    }
    paths
}

/// Whether a light vertex may be merged with: a surface point after the light, not Dirac.
#[inline]
fn mergeable(v: &Vertex) -> bool {
    v.kind == VertexKind::Surface && !v.bsdf.is_delta()
}

/// [`DEFAULT_RADIUS_FRACTION`] of the diagonal of the light vertices' bounding box, scaled
/// for `n` light subpaths an iteration (1 mm when there are none or they coincide).
fn default_radius(paths: &LightPaths, n: u64) -> f32 {
    let (lo, hi) = paths
        .vertices
        .iter()
        .filter(|v| mergeable(v))
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), v| (lo.min(v.p), hi.max(v.p)));
    let d = (hi - lo).length();
    let scale = (REFERENCE_LIGHT_PATHS / n.max(1) as f32).sqrt();
    if d.is_finite() && d > 0.0 { DEFAULT_RADIUS_FRACTION * d * scale } else { 1e-3 }
}

/// What one iteration's camera pass reads.
struct Iteration<'a> {
    paths: &'a LightPaths,
    grid: &'a PointGrid,
    /// `N pi r^2`.
    eta: f32,
    /// `1 / (N pi r^2)`, the merges' kernel normalisation.
    norm: f32,
}

/// One camera sample of pixel `(x, y)`: joins with its light subpath (holding the `t = 1`
/// splats in `splats`) and merges with every kept light vertex near its vertices.
#[allow(clippy::too_many_arguments)]
fn sample(
    scene: &RenderScene,
    camera_model: &Camera,
    s: &RenderSettings,
    (x, y, split): (u32, u32, Split),
    iteration: &Iteration,
    rng: &mut Rng64,
    camera: &mut Vec<Vertex>,
    splats: &mut HeldSplats,
    rays: &mut u64,
) -> Vec3 {
    let o = u2(rng);
    let lens = if camera_model.aperture_radius_m > 0.0 { u2(rng) } else { Vec2::ZERO };
    let fp = Vec2::new((x as f32 + o.x) / s.width as f32, (y as f32 + o.y) / s.height as f32);
    let max_depth = s.max_depth as usize;
    let mut l = camera_subpath(scene, camera_model, fp, lens, max_depth + 2, rng, camera, rays);
    let paths = iteration.paths;
    let own = paths.path(y as usize * s.width as usize + x as usize);
    l += connect_all(scene, camera_model, s.max_depth, own, camera, iteration.eta, split, rng, splats, rays);
    for t in 2..=camera.len() {
        let z = &camera[t - 1];
        if z.delta || z.bsdf.is_delta() {
            continue;
        }
        let (wo, mut merged) = (z.wo_local, Vec3::ZERO);
        iteration.grid.for_each_within(z.p, |id| {
            let i = id as usize;
            let start = paths.start_of[i] as usize;
            let m = i - start;
            if m + t > max_depth + 2 {
                return;
            }
            let photon = &paths.vertices[i];
            // Light on another surface (across an edge or a corner) is not this surface's.
            if photon.n.dot(z.n) < MIN_NORMAL_COSINE {
                return;
            }
            let f = z.bsdf.eval(wo, z.frame.to_local(photon.wo));
            if f == Vec3::ZERO {
                return;
            }
            let w = merge_weight(scene, &paths.vertices[start..=i], camera, t, iteration.eta);
            merged += photon.beta * f * w;
        });
        l += z.beta * merged * iteration.norm;
    }
    if split != Split::Off {
        l += specular_emission(scene, camera_model, s, (x, y, split), rng, rays);
    }
    l
}

/// Renders by VCM on this process's share of `cluster` (16x16 tiles dealt round-robin, as
/// `bdpt` does); rank 0 returns the image.
pub fn render_on(
    cluster: &Cluster,
    scene: &RenderScene,
    camera: &Camera,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Option<RenderOutput> {
    let start = Instant::now();
    let share = cluster.share();
    let (w, h) = (settings.width, settings.height);
    let pixels = w as usize * h as usize;
    let n = light_paths_per_iteration(settings);
    let mine = super::owned_tiles(&share, w, h);
    let min_len = (mine.len() / (8 * rayon::current_num_threads())).max(1);
    let mut sums = vec![Vec3::ZERO; pixels];
    // Which pixels split off the light seen through mirrors and glass (a fixed choice).
    let split: Vec<Split> = (0..pixels)
        .into_par_iter()
        .map(|i| {
            let splits = splits_pixel(scene, camera, settings, i as u32 % w, i as u32 / w);
            if splits { Split::Specular } else { Split::Off }
        })
        .collect();
    let films: Vec<Mutex<SplatFilm>> =
        (0..rayon::current_num_threads().max(1)).map(|_| Mutex::new(SplatFilm::new(w, h))).collect();
    let (mut rays, mut r0) = (0u64, settings.photons.initial_radius_m);
    for it in 0..settings.spp {
        // 1. Light pass: every rank traces every subpath (only the root counts the rays).
        let mut light_rays = 0;
        let paths = light_pass(scene, settings, it, n, &mut light_rays);
        if cluster.is_root() {
            rays += light_rays;
        }
        let r_first = *r0.get_or_insert_with(|| default_radius(&paths, n));
        let r = r_first * ((it + 1) as f32).powf(0.5 * (ALPHA - 1.0));
        let area = PI * r * r;
        let eta = n as f32 * area;
        let points: Vec<(u32, Vec3)> = paths
            .vertices
            .iter()
            .enumerate()
            .filter(|(_, v)| mergeable(v))
            .map(|(i, v)| (i as u32, v.p))
            .collect();
        let grid = PointGrid::build(&points, r);
        drop(points);
        let iteration = Iteration { paths: &paths, grid: &grid, eta, norm: 1.0 / eta };
        // 2. Camera pass over this rank's tiles.
        // Each worker thread splats into its own film, kept over the iterations (the sums are
        // fixed point, so which thread adds a splat does not change the image).
        let done: Vec<((u32, u32), Vec<Vec3>, u64)> = mine
            .par_iter()
            .with_min_len(min_len)
            .map(|&(x0, y0)| {
                let slot = rayon::current_thread_index().unwrap_or(0) % films.len();
                let mut film = films[slot].lock().unwrap_or_else(PoisonError::into_inner);
                let mut camera_path = Vec::new();
                let mut held = HeldSplats::default();
                let mut rays = 0;
                let px = super::tile_pixels(x0, y0, w, h)
                    .map(|i| {
                        let key = u64::from(it) * pixels as u64 + i as u64;
                        let mut rng = stream(settings.seed, CAMERA_DOMAIN, key);
                        let (x, y) = (i as u32 % w, i as u32 / w);
                        let l = sample(
                            scene,
                            camera,
                            settings,
                            (x, y, split[i]),
                            &iteration,
                            &mut rng,
                            &mut camera_path,
                            &mut held,
                            &mut rays,
                        );
                        held.add_to_when_full(&mut film);
                        if l.is_finite() { l } else { Vec3::ZERO }
                    })
                    .collect();
                held.add_to(&mut film);
                ((x0, y0), px, rays)
            })
            .collect();
        for ((x0, y0), px, r) in done {
            rays += r;
            for (i, p) in super::tile_pixels(x0, y0, w, h).zip(px) {
                sums[i] += p;
            }
        }
        let done = |k: u32| pixels as u64 * u64::from(k) / u64::from(settings.spp);
        progress(done(it + 1) - done(it));
    }
    let mut film = Film::new(w, h);
    let inv = 1.0 / settings.spp as f32;
    for (p, s) in film.pixels.iter_mut().zip(&sums) {
        *p = *s * inv;
    }
    let splats = films
        .into_iter()
        .map(|f| f.into_inner().unwrap_or_else(PoisonError::into_inner))
        .fold(SplatFilm::new(w, h), |a, b| a.merge(&b));
    let mut out = finish(cluster, film, splats, settings.spp, rays, start)?;
    out.photons = n * u64::from(settings.spp);
    Some(out)
}
