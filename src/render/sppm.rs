//! Stochastic progressive photon mapping (Hachisuka and Jensen 2009) and, with its visible
//! points fixed, progressive photon mapping (Hachisuka, Ogaki and Jensen 2008); the structure
//! of pbrt-v4's `SPPMIntegrator` (src/pbrt/cpu/integrators.cpp; pbrt-v3 sec. 16.2).
//!
//! Each iteration (one per sample per pixel, `--spp`, as pbrt-v4 reads `pixelsamples`):
//! 1. **Camera pass.** Every pixel traces one camera path through mirrors and glass to its
//!    first non-Dirac surface, the *visible point*, adding the emission it sees on the way and
//!    the direct light there (a light sample and a BSDF sample combined by MIS, as the path
//!    tracer does) to the pixel's direct light `Ld`.
//! 2. **Grid.** The visible points go into a hashed grid ([`super::photon_grid`]) with their
//!    pixel's current radius `r`. In the first iteration a *pilot* photon pass (streams of
//!    their own, not part of the estimate) counts the photons each visible point would
//!    gather; the pixels that count more than the median (or, without `--sppm-radius`, than
//!    [`DEFAULT_MEDIAN_PHOTONS`], the count the radius is scaled for the median pixel to
//!    expect) shrink their initial radius to expect that count ([`pilot_radii`] says why);
//!    the grid is then rebuilt.
//! 3. **Photon pass.** Photons leave the lights (chosen by power) and scatter as light-tracing
//!    paths do; from their second hit on (the first is direct light, already in `Ld`) every
//!    hit on a non-Dirac surface within `r` of a visible point adds `beta f(wo, wi)` to that
//!    pixel's `Phi` and one to its count `M`. Deposits that would make the whole path longer
//!    than `--max-depth` bounces are skipped, so the image converges to the path tracer's.
//! 4. **Update** (Hachisuka and Jensen 2009, eq. 7-9, alpha = 2/3):
//!    `N' = N + alpha M`, `r' = r sqrt(N' / (N + M))`, `tau' = (tau + beta_vp Phi) r'^2 / r^2`.
//!
//! The pixel's radiance after `I` iterations of `P` photons is
//! `Ld / I + tau / (I P pi r^2)`. The estimate is biased (the radius blurs the incident
//! light) and consistent: the bias falls as the radius shrinks.
//!
//! Determinism: camera paths draw from streams keyed by (pixel, iteration), photons from
//! streams keyed by (iteration, photon); `Phi` is summed in fixed point with atomic integer
//! adds (order-free) and `M` is an integer, so each pixel's update sees the same numbers on
//! any number of threads. Under MPI every rank traces every camera path (the visible points
//! must be everywhere for the grid), photon blocks are dealt round-robin, and `Phi` and `M`
//! are summed exactly over the ranks into every rank before the update, so every rank holds
//! the same state and rank 0's image is the single process's, bit for bit.
//!
//! Limits: the background is not a photon source (it lights visible points directly, through
//! their BSDF sample, but not by way of other surfaces), and glossy surfaces hold visible points as diffuse ones do (pbrt-v4 follows
//! glossy lobes further), so a near-mirror metal looks blurred by the radius.

use std::f32::consts::PI;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::bdpt::{Split, specular_emission, splits_pixel};
use super::light::importance_weight;
use super::path::{RR_START_DEPTH, Vertex, emitted, sample_direct};
use super::photon_grid::PhotonGrid;
use super::{Bsdf, Camera, Film, Frame, IntegratorKind, RenderOutput, RenderScene, RenderSettings, u2};
use crate::core::Ray;
use crate::core::fixed::{from_fixed, to_fixed};
use crate::core::rng::{Rng64, stream, uniform};
use crate::dist::Cluster;

/// Random-stream domain of the camera paths.
pub const CAMERA_DOMAIN: u64 = 0x5350_4341; // "SPCA"
/// Random-stream domain of the visible points' light samples.
pub const DIRECT_DOMAIN: u64 = 0x5350_4e45; // "SPNE"
/// Random-stream domain of the split pixels' camera rays through mirrors and glass.
pub const SPLIT_DOMAIN: u64 = 0x5350_5350; // "SPSP"
/// Random-stream domain of the photons.
pub const PHOTON_DOMAIN: u64 = 0x5048_4f54; // "PHOT"
/// Random-stream domain of the pilot photons (the initial radii, [`pilot_radii`]).
pub const PILOT_DOMAIN: u64 = 0x5049_4c54; // "PILT"
/// The radius reduction parameter alpha (the fraction of new photons kept), Hachisuka and
/// Jensen 2009 sec. 4.2 and pbrt-v4's value.
pub const ALPHA: f32 = 2.0 / 3.0;
/// The pilot pass's provisional radius, without `--sppm-radius`, as a fraction of the diagonal
/// of the bounding box of the first iteration's visible points.
pub const DEFAULT_RADIUS_FRACTION: f32 = 0.05;
/// Without `--sppm-radius`, the photons the median pixel expects an iteration within its
/// initial radius. Measured (docs/render.md, "Cost per sample and caustics"): on the Cornell
/// box and on rooms/caustics at 32x32, radii whose median pixel counted 35-80 photons gave the
/// lowest error at equal time, those with 2-20 up to three times the RMSE.
pub const DEFAULT_MEDIAN_PHOTONS: f32 = 50.0;
/// Without `--sppm-radius`, the most the initial radius grows past the provisional one
/// (photons too few to fill it).
pub const MAX_DEFAULT_GROWTH: f32 = 2.0;
/// The largest initial radius accepted, metres (1,000 km): beyond any scene, and small enough
/// that `N pi r^2` stays finite in single precision.
pub const MAX_RADIUS_M: f32 = 1.0e6;
/// Photons a work unit (dealt to threads and ranks).
const BLOCK: u64 = 256;
/// Most photons an iteration (photon streams are keyed by `iteration << 40 | photon`).
pub const MAX_PHOTONS_PER_ITERATION: u64 = 1 << 40;

/// Memory a photon-mapping render holds per pixel, bytes: the pixel's state (32), its camera
/// pass result and visible point (2 x 112), the photon tally (56) and the film (12).
pub const BYTES_PER_PIXEL: u64 = 324;

/// The photon-mapping settings of a render (`sppm`, `ppm`).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct PhotonSettings {
    /// Initial gather radius, metres (an upper bound the pilot pass may shrink); `None`: from
    /// the pilot's counts, [`DEFAULT_MEDIAN_PHOTONS`] for the median pixel, starting from
    /// [`DEFAULT_RADIUS_FRACTION`] of the diagonal of the visible points' bounding box.
    pub initial_radius_m: Option<f32>,
    /// Photons traced an iteration; `None`: one a pixel (pbrt-v4's default).
    pub photons_per_iteration: Option<u64>,
}

impl PhotonSettings {
    /// Checks the numbers; the error is one line naming the option.
    pub fn validate(&self) -> Result<(), String> {
        if let Some(r) = self.initial_radius_m
            && !(r.is_finite() && r > 0.0 && r <= MAX_RADIUS_M)
        {
            return Err(format!(
                "--sppm-radius {r}: must be a positive distance in metres, at most {MAX_RADIUS_M}"
            ));
        }
        if let Some(n) = self.photons_per_iteration
            && !(1..=MAX_PHOTONS_PER_ITERATION).contains(&n)
        {
            return Err(format!(
                "--photons {n}: must be between 1 and {MAX_PHOTONS_PER_ITERATION} an iteration"
            ));
        }
        Ok(())
    }
}

/// Where a camera path stopped to gather photons.
#[derive(Clone, Copy, Debug)]
pub struct VisiblePoint {
    /// Position, metres.
    pub p: Vec3,
    /// Shading frame.
    pub frame: Frame,
    /// Direction to the camera (local).
    pub wo: Vec3,
    /// The BSDF.
    pub bsdf: Bsdf,
    /// Throughput of the camera path up to the point.
    pub beta: Vec3,
    /// Bounces (mirror and glass) before the point.
    pub depth: u32,
}

/// A pixel's running estimate.
#[derive(Clone, Copy, Debug)]
struct PixelState {
    /// Sum of the direct light of every iteration.
    ld: Vec3,
    /// Gather radius, metres.
    radius: f32,
    /// Photons accumulated (the `N` of the update, fractional).
    n: f32,
    /// Flux accumulated within the radius, `tau`.
    tau: Vec3,
}

/// One camera path of pixel `(x, y)` in `iteration`: its direct light and visible point. With
/// `fixed_path` (PPM) the path's numbers come from iteration 0 every time, so the visible
/// point does not move; the light samples stay fresh. In a `split` pixel the emitters seen
/// by way of Dirac bounces alone are left out: [`super::bdpt::specular_emission`] takes them,
/// [`super::bdpt::SPECULAR_SPLIT`] camera rays an iteration.
#[allow(clippy::too_many_arguments)]
pub fn camera_path(
    scene: &RenderScene,
    camera: &Camera,
    s: &RenderSettings,
    (x, y): (u32, u32),
    iteration: u32,
    fixed_path: bool,
    split: bool,
    rays: &mut u64,
) -> (Vec3, Option<VisiblePoint>) {
    let pixels = u64::from(s.width) * u64::from(s.height);
    let pixel = u64::from(y) * u64::from(s.width) + u64::from(x);
    let index = |it: u32| u64::from(it) * pixels + pixel;
    let mut rng = stream(s.seed, CAMERA_DOMAIN, index(if fixed_path { 0 } else { iteration }));
    let mut direct_rng = stream(s.seed, DIRECT_DOMAIN, index(iteration));
    let o = u2(&mut rng);
    let film = Vec2::new((x as f32 + o.x) / s.width as f32, (y as f32 + o.y) / s.height as f32);
    let lens = if camera.aperture_radius_m > 0.0 { u2(&mut rng) } else { Vec2::ZERO };
    let mut ray = camera.ray(film, lens);
    let mut beta = Vec3::ONE;
    let mut ld = Vec3::ZERO;
    let mut depth = 0u32;
    loop {
        *rays += 1;
        let Some(hit) = scene.intersect(&ray) else {
            ld += beta * scene.background;
            return (ld, None);
        };
        // Only Dirac vertices came before: emitters seen are taken in full.
        if !split {
            ld += beta * scene.emitted(&hit);
        }
        if depth >= s.max_depth {
            return (ld, None);
        }
        let bsdf = scene.surfaces[hit.surface as usize].bsdf;
        let frame = Frame::new(hit.normal);
        let wo = frame.to_local(-ray.dir);
        if !bsdf.is_delta() {
            // Direct light as the path tracer takes it: a light sample and a BSDF sample
            // weighted by the power heuristic (a light sample alone has heavy tails where
            // emitters meet the surface: +4 % in the white furnace at 18k samples).
            let v = Vertex { hit: &hit, frame, wo, bsdf };
            let (u_light, u_bsdf) = (u2(&mut direct_rng), u2(&mut direct_rng));
            ld += beta * sample_direct(scene, &v, u_light, rays, true);
            if let Some(bs) = bsdf.sample(wo, u_bsdf, 0.0) {
                *rays += 1;
                let dir = frame.to_world(bs.wi);
                let b = beta * bs.weight();
                match scene.intersect(&Ray::spawn(hit.point, hit.normal, dir)) {
                    Some(next) => ld += emitted(scene, &next, dir, b, (bs.specular, bs.pdf, hit.point)),
                    None => ld += b * scene.background,
                }
            }
            return (ld, Some(VisiblePoint { p: hit.point, frame, wo, bsdf, beta, depth }));
        }
        let (u, uc, u_rr) = (u2(&mut rng), uniform(&mut rng), uniform(&mut rng));
        let Some(bs) = bsdf.sample(wo, u, uc) else { return (ld, None) };
        beta *= bs.weight();
        depth += 1;
        if depth >= RR_START_DEPTH {
            let q = beta.max_element().min(1.0);
            if q <= 0.0 || u_rr >= q {
                return (ld, None);
            }
            beta /= q;
        } else if beta == Vec3::ZERO {
            return (ld, None);
        }
        ray = Ray::spawn(hit.point, hit.normal, frame.to_world(bs.wi));
    }
}

/// The photon statistics of one iteration: per pixel, `Phi` as fixed-point sums (each of the
/// 128-bit values in two 64-bit words, the low 32 bits and the rest, so that atomic adds are
/// exact) and the count `M`.
struct Tally {
    /// Low and high words of each pixel's three channels.
    phi: Vec<[AtomicU64; 6]>,
    /// Photons deposited a pixel.
    m: Vec<AtomicU64>,
    /// The fixed-point unit, the lights' total power (the order of one photon's `beta`).
    unit: f64,
}

impl Tally {
    fn new(pixels: usize, unit: f64) -> Self {
        Self {
            phi: (0..pixels).map(|_| std::array::from_fn(|_| AtomicU64::new(0))).collect(),
            m: (0..pixels).map(|_| AtomicU64::new(0)).collect(),
            unit,
        }
    }

    #[inline]
    fn add(&self, pixel: usize, phi: Vec3) {
        if !phi.is_finite() {
            return;
        }
        let words = &self.phi[pixel];
        for (k, v) in phi.to_array().into_iter().enumerate() {
            // At most 2^20 units a deposit, so the high words cannot wrap before 2^44 deposits.
            let f = to_fixed(f64::from(v).min(self.unit * 1_048_576.0), self.unit);
            words[2 * k].fetch_add((f & 0xffff_ffff) as u64, Ordering::Relaxed);
            words[2 * k + 1].fetch_add((f >> 32) as u64, Ordering::Relaxed);
        }
        self.m[pixel].fetch_add(1, Ordering::Relaxed);
    }

    /// The sums as 128-bit fixed point (three a pixel) and the counts.
    fn into_sums(self) -> (Vec<u128>, Vec<u64>) {
        let phi = self
            .phi
            .into_iter()
            .flat_map(|w| {
                let w = w.map(AtomicU64::into_inner);
                (0..3).map(move |k| u128::from(w[2 * k]) + (u128::from(w[2 * k + 1]) << 32))
            })
            .collect();
        (phi, self.m.into_iter().map(AtomicU64::into_inner).collect())
    }
}

/// Traces photon `rng`'s path and deposits it on the visible points within their radius.
#[allow(clippy::too_many_arguments)]
fn trace_photon(
    scene: &RenderScene,
    grid: &PhotonGrid,
    points: &[Option<VisiblePoint>],
    max_depth: u32,
    rng: &mut Rng64,
    tally: &Tally,
    rays: &mut u64,
) {
    let Some((index, pmf)) = scene.lights.choose(uniform(rng)) else { return };
    let light = &scene.lights.lights[index];
    let (u_pos, u_dir) = (u2(rng), u2(rng));
    let Some(e) = light.sample_le(u_pos, u_dir) else { return };
    let on_surface = e.normal != Vec3::ZERO;
    let cos = if on_surface { e.normal.dot(e.dir).abs() } else { 1.0 };
    let mut beta = e.le * (cos / (pmf * e.pdf_pos * e.pdf_dir));
    let mut ray = if on_surface { Ray::spawn(e.point, e.normal, e.dir) } else { Ray::new(e.point, e.dir) };
    // `hits` counts the photon's surface hits: the light of hit k reaches a visible point
    // after k - 1 bounces, so gathering it there makes a path of k + depth(vp) bounces.
    for hits in 1..=max_depth {
        *rays += 1;
        let Some(hit) = scene.intersect(&ray) else { break };
        let bsdf = scene.surfaces[hit.surface as usize].bsdf;
        if hits >= 2 && !bsdf.is_delta() {
            let wi_world = -ray.dir;
            grid.for_each_within(hit.point, |id| {
                let i = id as usize;
                let Some(vp) = &points[i] else { return };
                if vp.depth + hits > max_depth {
                    return;
                }
                let f = vp.bsdf.eval(vp.wo, vp.frame.to_local(wi_world));
                if f != Vec3::ZERO {
                    tally.add(i, beta * f);
                }
            });
        }
        if hits == max_depth {
            break;
        }
        let frame = Frame::new(hit.normal);
        let wo = frame.to_local(-ray.dir);
        let (u, uc, u_rr) = (u2(rng), uniform(rng), uniform(rng));
        let Some(s) = bsdf.sample(wo, u, uc) else { break };
        let new_beta = beta * importance_weight(&bsdf, wo, &s);
        // Russian roulette on the throughput's change (pbrt-v4): photons keep about the same
        // power, which keeps the density estimate's variance low.
        let q = (1.0 - new_beta.max_element() / beta.max_element()).max(0.0);
        // A NaN ratio (a zero throughput) ends the photon too.
        if q.is_nan() || q >= 1.0 || u_rr < q {
            break;
        }
        beta = new_beta / (1.0 - q);
        ray = Ray::spawn(hit.point, hit.normal, frame.to_world(s.wi));
    }
}

/// One photon pass: what it needs to trace and deposit.
struct PhotonPass<'a> {
    scene: &'a RenderScene<'a>,
    grid: &'a PhotonGrid,
    points: &'a [Option<VisiblePoint>],
    settings: &'a RenderSettings,
    photons: u64,
    unit: f64,
}

impl PhotonPass<'_> {
    /// Traces this rank's blocks of `iteration`'s photons from streams of `domain` and returns
    /// every pixel's `Phi` (fixed point) and `M`, summed over the ranks, and the rays traced.
    fn run(&self, cluster: &Cluster, domain: u64, iteration: u32) -> (Vec<u128>, Vec<u64>, u64) {
        let tally = Tally::new(self.points.len(), self.unit);
        let mine: Vec<u64> = cluster.share().units(self.photons.div_ceil(BLOCK)).collect();
        let s = self.settings;
        let rays: u64 = mine
            .par_iter()
            .map(|&block| {
                let mut r = 0;
                for j in block * BLOCK..((block + 1) * BLOCK).min(self.photons) {
                    let mut rng = stream(s.seed, domain, (u64::from(iteration) << 40) | j);
                    trace_photon(self.scene, self.grid, self.points, s.max_depth, &mut rng, &tally, &mut r);
                }
                r
            })
            .sum();
        let (mut phi, mut m) = tally.into_sums();
        cluster.sum_u128_everywhere(&mut phi);
        cluster.sum_u64_everywhere(&mut m);
        (phi, m, rays)
    }
}

/// Sets the initial radii from the pilot's counts `m0`, gathered within the radii `state`
/// holds. A pixel counting more than the target (below) has its `r^2` scaled by
/// target / count, so that it expects the target count an iteration at the density it
/// measured, as a k-nearest-neighbour photon map chooses its radius (Jensen 2001), but only
/// ever shrinking. The target is the median count `m_med` over the pixels that counted any
/// when the radius was given (`scale_all` false); by default (`scale_all`) every pixel is
/// first scaled so that the median one expects [`DEFAULT_MEDIAN_PHOTONS`] (growing at most
/// [`MAX_DEFAULT_GROWTH`] times), and the target is that count.
///
/// Why: about a visible point of photon density `rho`, over a disc of radius `r`, the density
/// estimate's variance goes as `rho / r^2` and its squared bias as `(r^2 rho / w^2)^2`, where
/// `w` is the width over which the light changes; the mean squared error is least at
/// `r^6 ~ w^4 / rho` (the trade Kaplanyan and Dachsbacher 2013 solve per pixel). Where the
/// density is high because light is focused (a caustic), the same flux on a spot of width `w`
/// makes `rho ~ 1 / w^2`, so the best radius goes as `rho^(-1/2)`: the scaling here. Without
/// it the bright parts of the image keep the blur of the initial radius (SPPM's radius falls
/// at the same rate everywhere, whatever the density) while the dim parts would want a larger
/// one. Pixels sparser than the target keep the radius, so it stays an upper bound.
fn pilot_radii(state: &mut [PixelState], m0: &[u64], scale_all: bool) {
    // (A pixel without a visible point counts none.)
    let mut counted: Vec<u64> = m0.iter().copied().filter(|&m| m > 0).collect();
    let m_med = if counted.is_empty() {
        0.0
    } else {
        counted.sort_unstable();
        counted[counted.len() / 2] as f32
    };
    // The factor on every pixel's r^2 (by default: for the median pixel to expect the
    // default count, growing at most MAX_DEFAULT_GROWTH times), so the counts expected at the
    // new radii are `m s2`.
    let s2 = match (scale_all, m_med > 0.0) {
        (false, _) => 1.0,
        (true, true) => (DEFAULT_MEDIAN_PHOTONS / m_med).min(MAX_DEFAULT_GROWTH * MAX_DEFAULT_GROWTH),
        (true, false) => MAX_DEFAULT_GROWTH * MAX_DEFAULT_GROWTH,
    };
    let target = m_med * s2;
    for (p, &m) in state.iter_mut().zip(m0) {
        p.radius *= s2.sqrt();
        let expected = m as f32 * s2;
        if target > 0.0 && expected > target {
            p.radius *= (target / expected).sqrt();
        }
    }
}

/// Renders with `sppm` (or `ppm`, whose visible points stay put) on this process's share of
/// `cluster`; rank 0 returns the image. `spp` iterations of the configured photon count.
pub fn render_on(
    cluster: &Cluster,
    scene: &RenderScene,
    camera: &Camera,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Option<RenderOutput> {
    let start = Instant::now();
    let (w, h) = (settings.width, settings.height);
    let pixels = w as usize * h as usize;
    let iterations = settings.spp;
    let fixed_path = settings.integrator == IntegratorKind::Ppm;
    let photons = settings.photons.photons_per_iteration.unwrap_or(pixels as u64);
    let unit = scene.lights.lights.iter().map(|l| f64::from(l.power().max_element())).sum::<f64>().max(1e-30);
    let mut state: Vec<PixelState> =
        vec![PixelState { ld: Vec3::ZERO, radius: 0.0, n: 0.0, tau: Vec3::ZERO }; pixels];
    let mut rays = 0u64;
    // Which pixels take the light seen through mirrors and glass by extra camera rays.
    let split: Vec<bool> = (0..pixels)
        .into_par_iter()
        .map(|i| splits_pixel(scene, camera, settings, i as u32 % w, i as u32 / w))
        .collect();
    for it in 0..iterations {
        // 1. Camera pass: every rank traces every pixel (only the root counts the rays).
        let camera_out: Vec<(Vec3, Option<VisiblePoint>, u64)> = (0..pixels)
            .into_par_iter()
            .with_min_len(64)
            .map(|i| {
                let mut r = 0;
                let (x, y) = (i as u32 % w, i as u32 / w);
                let (mut ld, vp) =
                    camera_path(scene, camera, settings, (x, y), it, fixed_path, split[i], &mut r);
                if split[i] {
                    let mut rng =
                        stream(settings.seed, SPLIT_DOMAIN, u64::from(it) * pixels as u64 + i as u64);
                    ld +=
                        specular_emission(scene, camera, settings, (x, y, Split::Specular), &mut rng, &mut r);
                }
                (ld, vp, r)
            })
            .collect();
        if cluster.is_root() {
            rays += camera_out.iter().map(|c| c.2).sum::<u64>();
        }
        if it == 0 {
            // By default a provisional radius the pilot then scales (`pilot_radii`).
            let r0 = settings.photons.initial_radius_m.unwrap_or_else(|| default_radius(&camera_out));
            state.iter_mut().for_each(|p| p.radius = r0);
        }
        let points: Vec<Option<VisiblePoint>> = camera_out.iter().map(|c| c.1).collect();
        for (p, c) in state.iter_mut().zip(&camera_out) {
            p.ld += c.0;
        }
        drop(camera_out);
        // 2. Grid.
        let grid_of = |state: &[PixelState]| {
            let gridded: Vec<(u32, Vec3, f32)> = points
                .iter()
                .enumerate()
                .filter_map(|(i, vp)| vp.map(|v| (i as u32, v.p, state[i].radius)))
                .collect();
            PhotonGrid::build(&gridded)
        };
        let mut grid = grid_of(&state);
        if it == 0 {
            // The pilot: its counts shrink the radius where photons crowd (see `pilot_radii`).
            let pass = PhotonPass { scene, grid: &grid, points: &points, settings, photons, unit };
            let (_, m0, r) = pass.run(cluster, PILOT_DOMAIN, 0);
            rays += r;
            pilot_radii(&mut state, &m0, settings.photons.initial_radius_m.is_none());
            grid = grid_of(&state);
        }
        // 3. Photon pass over this rank's blocks.
        let pass = PhotonPass { scene, grid: &grid, points: &points, settings, photons, unit };
        let (phi, m, r) = pass.run(cluster, PHOTON_DOMAIN, it);
        rays += r;
        // 4. Update.
        state.par_iter_mut().zip(points.par_iter()).enumerate().for_each(|(i, (p, vp))| {
            let (Some(vp), mi) = (vp, m[i]) else { return };
            if mi == 0 {
                return;
            }
            let phi = Vec3::from_array(std::array::from_fn(|k| from_fixed(phi[3 * i + k], unit) as f32));
            let m = mi as f32;
            let n_new = p.n + ALPHA * m;
            let r_new = p.radius * (n_new / (p.n + m)).sqrt();
            p.tau = (p.tau + vp.beta * phi) * (r_new * r_new / (p.radius * p.radius));
            p.n = n_new;
            p.radius = r_new;
        });
        let done = |k: u32| pixels as u64 * u64::from(k) / u64::from(iterations);
        progress(done(it + 1) - done(it));
    }
    let mut total_rays = [rays];
    cluster.sum_u64(&mut total_rays);
    if !cluster.is_root() {
        return None;
    }
    let emitted = f64::from(iterations) * photons as f64;
    let mut film = Film::new(w, h);
    for (px, p) in film.pixels.iter_mut().zip(&state) {
        let area = f64::from(PI) * f64::from(p.radius) * f64::from(p.radius);
        let indirect = if area > 0.0 { p.tau * (1.0 / (emitted * area)) as f32 } else { Vec3::ZERO };
        *px = p.ld / iterations as f32 + indirect;
    }
    Some(RenderOutput {
        film,
        samples: pixels as u64 * u64::from(iterations),
        rays: total_rays[0],
        photons: emitted as u64,
        seconds: start.elapsed().as_secs_f64(),
        notes: Vec::new(),
    })
}

/// [`DEFAULT_RADIUS_FRACTION`] of the diagonal of the visible points' bounding box (1 mm
/// when there are none or they coincide).
fn default_radius(camera_out: &[(Vec3, Option<VisiblePoint>, u64)]) -> f32 {
    let (lo, hi) = camera_out
        .iter()
        .filter_map(|c| c.1.map(|v| v.p))
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(lo, hi), p| (lo.min(p), hi.max(p)));
    let d = (hi - lo).length();
    if d.is_finite() && d > 0.0 { DEFAULT_RADIUS_FRACTION * d } else { 1e-3 }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The pilot leaves the pixels at or under the median count (of those that counted any)
    /// alone and scales the others' `r^2` by median / count, so each expects the median count
    /// at the density it measured.
    #[test]
    fn pilot_shrinks_only_the_crowded_pixels_to_the_median_count() {
        let m0 = [0, 4, 8, 16, 32, 400];
        let mut state = vec![PixelState { ld: Vec3::ZERO, radius: 0.1, n: 0.0, tau: Vec3::ZERO }; m0.len()];
        pilot_radii(&mut state, &m0, false);
        // Counted: 4, 8, 16, 32, 400; the median is 16.
        for (p, &m) in state.iter().zip(&m0) {
            let expected_r2 = if m > 16 { 0.01 * 16.0 / m as f32 } else { 0.01 };
            assert!((p.radius * p.radius / expected_r2 - 1.0).abs() < 1e-5, "{m}: {}", p.radius);
            // The photons expected within the new radius, at the measured density.
            let expected = m as f32 * p.radius * p.radius / 0.01;
            assert!(expected <= 16.0 * (1.0 + 1e-5), "{m}: {expected}");
        }
        let mut none = state.clone();
        pilot_radii(&mut none, &[0; 6], false);
        assert!(none.iter().zip(&state).all(|(a, b)| a.radius == b.radius));
    }

    /// Without a radius given, every pixel is scaled so that the median one expects
    /// DEFAULT_MEDIAN_PHOTONS, then the crowded ones shrink to that count; with too few
    /// photons the radius grows by MAX_DEFAULT_GROWTH at most.
    #[test]
    fn default_radius_makes_the_median_pixel_expect_the_default_count() {
        let m0 = [0, 5, 10, 20];
        let mut state = vec![PixelState { ld: Vec3::ZERO, radius: 0.1, n: 0.0, tau: Vec3::ZERO }; m0.len()];
        pilot_radii(&mut state, &m0, true);
        // The median count is 10 (of 5, 10, 20): r^2 would scale by 50 / 10 = 5, capped
        // at 2^2 = 4, so the median pixel expects 40, the target.
        let (s2, target) = (4.0f32, 40.0f32);
        for (p, &m) in state.iter().zip(&m0) {
            let expected = m as f32 * s2;
            let r2 = 0.01 * s2 * if expected > target { target / expected } else { 1.0 };
            assert!((p.radius * p.radius / r2 - 1.0).abs() < 1e-5, "{m}: {}", p.radius);
        }
        // Plenty of photons: the median (100) is brought down to 50.
        let m0 = [100, 100, 400];
        let mut state = vec![PixelState { ld: Vec3::ZERO, radius: 0.1, n: 0.0, tau: Vec3::ZERO }; m0.len()];
        pilot_radii(&mut state, &m0, true);
        for (p, &m) in state.iter().zip(&m0) {
            let expected_count = m as f32 * p.radius * p.radius / 0.01;
            assert!((expected_count - DEFAULT_MEDIAN_PHOTONS).abs() < 1e-3, "{m}: {expected_count}");
        }
    }
}
