//! Primary-sample-space Metropolis light transport (Kelemen, Szirmay-Kalos, Antal, Csonka
//! 2002) over the bidirectional estimator, in the form of pbrt-v4's `MLTIntegrator`
//! (src/pbrt/cpu/integrators.cpp; pbrt-v3 sec. 16.4): a path is a function of a vector of
//! uniform numbers (the primary sample), drawn by the very routines of [`super::bdpt`]; Markov
//! chains wander that unit hypercube, each proposal either a *large step* (a fresh vector,
//! probability `large_step_probability`) or a *small step* (each number moved by a normal of
//! standard deviation `sigma`, wrapped), accepted with probability `min(1, C(new) / C(old))`,
//! `C` the luminance. Each chain renders one path length (depth); its proposals pick one
//! bidirectional strategy `(s, t)` uniformly among the `depth + 2`, weighted by MIS and by
//! that count.
//!
//! The chains' stationary density is proportional to `C`; the image is scaled by its
//! integral `b`, estimated first by a *bootstrap*: `bootstrap` independent primary samples
//! of each depth, whose luminances also choose the chains' starting states (resampled in
//! proportion, which removes the start-up bias to first order).
//!
//! Deterministic: bootstrap sample `i` and chain `k` draw from their own counter-based
//! streams ([`crate::core::rng::stream`]), the bootstrap luminances are summed in index
//! order, and the chains' splats (both the proposal's and the current state's, weighted by
//! the acceptance probability: Veach's "expected values" splatting) are summed in fixed point
//! ([`super::splat`]), so the image is the same to the bit for any thread count and any split
//! of the bootstrap samples and chains over MPI ranks.

use std::time::Instant;

use glam::{Vec2, Vec3};
use rand::RngCore;
use rayon::prelude::*;
use serde::Deserialize;

use super::bdpt::{Vertex, camera_subpath, connect, light_subpath};
use super::film::luminance;
use super::sampler::Uniforms;
use super::splat::{SplatFilm, finish_scaled};
use super::{Camera, Film, RenderOutput, RenderScene, RenderSettings};
use crate::core::rng::{Rng64, stream, uniform};
use crate::dist::Cluster;

/// Random-stream domain of the bootstrap samples (and of the chains' primary samples, which
/// start from one of them).
pub const BOOTSTRAP_DOMAIN: u64 = 0x4d4c_5442; // "MLTB"
/// Random-stream domain of the chains' own choices (start, acceptance).
pub const CHAIN_DOMAIN: u64 = 0x4d4c_5443; // "MLTC"
/// Bootstrap samples a work unit (dealt to threads and ranks).
const BOOTSTRAP_BLOCK: u64 = 1024;
/// Most bootstrap samples over all depths (their luminances are held in memory).
const MAX_BOOTSTRAP_TOTAL: u64 = 1 << 26;

/// The primary-sample streams of a path: the camera subpath (strategy choice, film, lens,
/// walk), the light subpath and the connection. Interleaved in the vector, so that a longer
/// camera subpath does not shift the numbers of the light subpath (pbrt-v4 `MLTSampler`).
const CAMERA_STREAM: usize = 0;
const LIGHT_STREAM: usize = 1;
const CONNECT_STREAM: usize = 2;
const STREAMS: usize = 3;

/// The pssmlt integrator's options (flags `--mlt-*`, given as [`MltFlags`]); pbrt-v4's
/// defaults except the chains' length, which follows the samples per pixel.
#[derive(Deserialize, Debug, Clone, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct MltOptions {
    /// Independent Markov chains (the work is split over them; more chains, less start-up
    /// correlation but more start-up cost).
    pub chains: u32,
    /// Mutations per pixel, in total over the chains (`None`: the samples per pixel).
    pub mutations_per_pixel: Option<u32>,
    /// Probability of a large step (a fresh, independent primary sample).
    pub large_step_probability: f32,
    /// Standard deviation of a small step of each primary-sample number.
    pub sigma: f32,
    /// Bootstrap samples per path depth, which estimate the image's normalisation and choose
    /// the chains' starts.
    pub bootstrap: u32,
}

/// The `--mlt-*` flags as a user gives them: `None` is a flag not given (its
/// [`MltOptions::default`] value then), so that a flag given with another integrator can be
/// refused by name ([`MltFlags::given`]) rather than silently ignored.
#[derive(clap::Args, Deserialize, Debug, Clone, PartialEq, Default)]
#[serde(default, deny_unknown_fields)]
pub struct MltFlags {
    /// pssmlt: independent Markov chains (the work is split over them; more chains, less
    /// start-up correlation but more start-up cost) (default: 1000).
    #[arg(long = "mlt-chains")]
    pub chains: Option<u32>,
    /// pssmlt: mutations per pixel, in total over the chains (default: the samples per pixel).
    #[arg(long = "mlt-mutations-per-pixel", value_name = "N")]
    pub mutations_per_pixel: Option<u32>,
    /// pssmlt: probability of a large step (a fresh, independent primary sample) (default:
    /// 0.3).
    #[arg(long = "mlt-large-step-probability")]
    pub large_step_probability: Option<f32>,
    /// pssmlt: standard deviation of a small step of each primary-sample number (default:
    /// 0.01).
    #[arg(long = "mlt-sigma")]
    pub sigma: Option<f32>,
    /// pssmlt: bootstrap samples per path depth, which estimate the image's normalisation
    /// and choose the chains' starts (default: 100000).
    #[arg(long = "mlt-bootstrap")]
    pub bootstrap: Option<u32>,
}

impl MltFlags {
    /// The flags given, in the order of `--help`.
    pub fn given(&self) -> Vec<&'static str> {
        [
            ("--mlt-chains", self.chains.is_some()),
            ("--mlt-mutations-per-pixel", self.mutations_per_pixel.is_some()),
            ("--mlt-large-step-probability", self.large_step_probability.is_some()),
            ("--mlt-sigma", self.sigma.is_some()),
            ("--mlt-bootstrap", self.bootstrap.is_some()),
        ]
        .into_iter()
        .filter_map(|(flag, given)| given.then_some(flag))
        .collect()
    }

    /// The options: each flag given, else its default.
    pub fn options(&self) -> MltOptions {
        let d = MltOptions::default();
        MltOptions {
            chains: self.chains.unwrap_or(d.chains),
            mutations_per_pixel: self.mutations_per_pixel.or(d.mutations_per_pixel),
            large_step_probability: self.large_step_probability.unwrap_or(d.large_step_probability),
            sigma: self.sigma.unwrap_or(d.sigma),
            bootstrap: self.bootstrap.unwrap_or(d.bootstrap),
        }
    }
}

impl Default for MltOptions {
    fn default() -> Self {
        Self {
            chains: 1000,
            mutations_per_pixel: None,
            large_step_probability: 0.3,
            sigma: 0.01,
            bootstrap: 100_000,
        }
    }
}

impl MltOptions {
    /// Checks the numbers for paths of at most `max_depth` bounces; the error is one line
    /// naming the flag.
    pub fn validate(&self, max_depth: u32) -> Result<(), String> {
        if !(1..=1_000_000).contains(&self.chains) {
            return Err(format!("--mlt-chains {}: must be between 1 and 1000000", self.chains));
        }
        if let Some(m) = self.mutations_per_pixel
            && !(1..=super::MAX_SPP).contains(&m)
        {
            return Err(format!("--mlt-mutations-per-pixel {m}: must be between 1 and {}", super::MAX_SPP));
        }
        let p = self.large_step_probability;
        if !(p.is_finite() && (0.0..=1.0).contains(&p)) {
            return Err(format!("--mlt-large-step-probability {p}: must be between 0 and 1"));
        }
        if !(self.sigma.is_finite() && self.sigma > 0.0 && self.sigma <= 1.0) {
            return Err(format!("--mlt-sigma {}: must be above 0 and at most 1", self.sigma));
        }
        if !(1..=1_000_000).contains(&self.bootstrap) {
            return Err(format!("--mlt-bootstrap {}: must be between 1 and 1000000", self.bootstrap));
        }
        let total = u64::from(self.bootstrap) * (u64::from(max_depth) + 1);
        if total > MAX_BOOTSTRAP_TOTAL {
            return Err(format!(
                "--mlt-bootstrap {} at max depth {max_depth}: {total} bootstrap samples, more than \
                 {MAX_BOOTSTRAP_TOTAL}; lower one of them",
                self.bootstrap
            ));
        }
        Ok(())
    }
}

/// One number of the primary sample, with what undoes its last mutation.
#[derive(Clone, Copy, Debug, Default)]
struct PrimarySample {
    value: f32,
    /// The iteration that last changed it.
    modified: u64,
    backup: f32,
    backup_modified: u64,
}

/// The primary-sample vector of one Markov chain and its mutations (Kelemen et al. 2002;
/// pbrt-v4 `MLTSampler`): numbers are created and mutated lazily, when a path first reads
/// them in an iteration; a small step of a number left alone for `n` iterations moves it by
/// a normal of deviation `sigma sqrt(n)` (the sum of the `n` steps it missed).
pub struct MltSampler {
    x: Vec<PrimarySample>,
    rng: Rng64,
    sigma: f32,
    large_step_probability: f32,
    iteration: u64,
    last_large_step: u64,
    large_step: bool,
    stream: usize,
    index: usize,
}

impl MltSampler {
    /// A chain drawing from `rng`; its first iteration draws every number afresh.
    pub fn new(rng: Rng64, sigma: f32, large_step_probability: f32) -> Self {
        Self {
            x: Vec::new(),
            rng,
            sigma,
            large_step_probability,
            iteration: 0,
            last_large_step: 0,
            large_step: true,
            stream: 0,
            index: 0,
        }
    }

    /// Starts a proposal: a large step with the large-step probability, else a small one.
    pub fn start_iteration(&mut self) {
        self.iteration += 1;
        self.large_step = uniform(&mut self.rng) < self.large_step_probability;
    }

    /// Keeps the proposal.
    pub fn accept(&mut self) {
        if self.large_step {
            self.last_large_step = self.iteration;
        }
    }

    /// Undoes the proposal's mutations.
    pub fn reject(&mut self) {
        for x in &mut self.x {
            if x.modified == self.iteration {
                x.value = x.backup;
                x.modified = x.backup_modified;
            }
        }
        self.iteration -= 1;
    }

    /// Reads stream `stream` from its first number on.
    pub fn start_stream(&mut self, stream: usize) {
        self.stream = stream;
        self.index = 0;
    }

    /// Brings number `i` up to the current iteration.
    fn ensure_ready(&mut self, i: usize) {
        if i >= self.x.len() {
            self.x.resize(i + 1, PrimarySample::default());
        }
        let x = &mut self.x[i];
        // A number created after the last accepted large step, or not read since, takes that
        // large step's fresh value first.
        if x.modified < self.last_large_step {
            x.value = uniform(&mut self.rng);
            x.modified = self.last_large_step;
        }
        x.backup = x.value;
        x.backup_modified = x.modified;
        if self.large_step {
            x.value = uniform(&mut self.rng);
        } else {
            let steps = (self.iteration - x.modified) as f32;
            // Box-Muller: one standard normal from two uniforms.
            let (u1, u2) = (uniform(&mut self.rng), uniform(&mut self.rng));
            let normal = (-2.0 * (1.0 - u1).ln()).sqrt() * (std::f32::consts::TAU * u2).cos();
            let v = x.value + normal * self.sigma * steps.sqrt();
            x.value = (v - v.floor()).min(ONE_MINUS_EPSILON);
        }
        x.modified = self.iteration;
    }
}

/// The largest f32 below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

impl Uniforms for MltSampler {
    #[inline]
    fn next_1d(&mut self) -> f32 {
        let i = self.stream + STREAMS * self.index;
        self.index += 1;
        self.ensure_ready(i);
        self.x[i].value
    }
}

/// The path of depth `depth` (bounces) that the sampler's primary sample gives: one
/// bidirectional strategy `(s, t)` chosen from its first number, its MIS-weighted
/// contribution times the number of strategies, and the film point it lands on (pbrt-v4
/// `MLTIntegrator::L`). Zero when the subpaths come out shorter than the strategy needs.
#[allow(clippy::too_many_arguments)]
pub fn path_contribution(
    scene: &RenderScene,
    camera_model: &Camera,
    depth: usize,
    sampler: &mut MltSampler,
    paths: &mut (Vec<Vertex>, Vec<Vertex>),
    rays: &mut u64,
) -> (Vec3, Vec2) {
    let (camera, light) = paths;
    sampler.start_stream(CAMERA_STREAM);
    let (s, t, strategies) = if depth == 0 {
        (0, 2, 1)
    } else {
        let n = depth + 2;
        let s = ((sampler.next_1d() * n as f32) as usize).min(n - 1);
        (s, n - s, n)
    };
    let n = strategies as f32;
    let fp = sampler.next_2d();
    // Read whether or not the camera has a lens, so the numbers keep their places.
    let lens = sampler.next_2d();
    let lens = if camera_model.aperture_radius_m > 0.0 { lens } else { Vec2::ZERO };
    let background = camera_subpath(scene, camera_model, fp, lens, t, sampler, camera, rays);
    if camera.len() != t {
        // A camera path that left the scene after t - 1 vertices sees the background: a path
        // of this depth that only the s = 0 strategy makes (the background is not sampled
        // from the lights), so it takes it unweighted.
        let escaped = s == 0 && camera.len() == t - 1 && background != Vec3::ZERO;
        return (if escaped { background * n } else { Vec3::ZERO }, fp);
    }
    sampler.start_stream(LIGHT_STREAM);
    light.clear();
    if s > 0 {
        light_subpath(scene, (s - 1) as u32, sampler, light, rays);
        if light.len() != s {
            return (Vec3::ZERO, fp);
        }
    }
    sampler.start_stream(CONNECT_STREAM);
    let u = sampler.next_2d();
    match connect(scene, camera_model, light, camera, s, t, u, 0.0, rays) {
        Some((l, splat)) => (l * n, splat.unwrap_or(fp)),
        None => (Vec3::ZERO, fp),
    }
}

/// The Metropolis target: the luminance of a contribution (0 for a non-finite or negative one).
#[inline]
fn target(l: Vec3) -> f32 {
    let c = luminance(l);
    if c.is_finite() && c > 0.0 { c } else { 0.0 }
}

/// Renders by PSSMLT on this process's share of `cluster` (bootstrap blocks and chains dealt
/// round-robin; every process sums the bootstrap luminances, exactly, to start its chains);
/// rank 0 returns the image.
pub fn render_on(
    cluster: &Cluster,
    scene: &RenderScene,
    camera: &Camera,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Option<RenderOutput> {
    let start = Instant::now();
    let o = &settings.mlt;
    let share = cluster.share();
    let (w, h) = (settings.width, settings.height);
    let depths = u64::from(settings.max_depth) + 1;
    let total_bootstrap = u64::from(o.bootstrap) * depths;
    let mpp = o.mutations_per_pixel.unwrap_or(settings.spp);
    let (sigma, lsp) = (o.sigma, o.large_step_probability);
    // Bootstrap: the luminance of sample i (depth i mod depths), as f32 bits, zero where
    // another process computes it, summed exactly over the processes.
    let blocks: Vec<u64> =
        (0..total_bootstrap.div_ceil(BOOTSTRAP_BLOCK)).filter(|b| share.owns(*b)).collect();
    let done: Vec<(u64, Vec<u64>, u64)> = blocks
        .par_iter()
        .map(|&b| {
            let (first, end) = (b * BOOTSTRAP_BLOCK, ((b + 1) * BOOTSTRAP_BLOCK).min(total_bootstrap));
            let mut paths = (Vec::new(), Vec::new());
            let mut rays = 0;
            let weights = (first..end)
                .map(|i| {
                    let mut sampler = MltSampler::new(stream(settings.seed, BOOTSTRAP_DOMAIN, i), sigma, lsp);
                    let depth = (i % depths) as usize;
                    let (l, _) = path_contribution(scene, camera, depth, &mut sampler, &mut paths, &mut rays);
                    u64::from(target(l).to_bits())
                })
                .collect();
            (first, weights, rays)
        })
        .collect();
    let mut weights = vec![0u64; total_bootstrap as usize];
    let mut rays = 0u64;
    for (first, ws, r) in done {
        weights[first as usize..first as usize + ws.len()].copy_from_slice(&ws);
        rays += r;
    }
    cluster.sum_u64_everywhere(&mut weights);
    let mut cdf = Vec::with_capacity(weights.len());
    let mut total = 0.0f64;
    for &bits in &weights {
        total += f64::from(f32::from_bits(bits as u32));
        cdf.push(total);
    }
    drop(weights);
    // The integral of the luminance over the primary samples of all depths.
    let b = total / f64::from(o.bootstrap);
    let pixels = u64::from(w) * u64::from(h);
    let mutations = pixels * u64::from(mpp);
    let chains = u64::from(o.chains);
    let chain_range = |k: u64| {
        let at = |k: u64| (u128::from(mutations) * u128::from(k) / u128::from(chains)) as u64;
        (at(k), at(k + 1))
    };
    let mine: Vec<u64> = (0..chains).filter(|k| share.owns(*k)).collect();
    let min_len = (mine.len() / (8 * rayon::current_num_threads())).max(1);
    let (splats, chain_rays) = mine
        .par_iter()
        .with_min_len(min_len)
        .fold(
            || (SplatFilm::new(w, h), 0u64),
            |(mut film, mut rays), &k| {
                let (first, end) = chain_range(k);
                if total > 0.0 && end > first {
                    run_chain(scene, camera, settings, k, end - first, &cdf, &mut film, &mut rays);
                }
                progress(end / u64::from(mpp) - first / u64::from(mpp));
                (film, rays)
            },
        )
        .reduce(|| (SplatFilm::new(w, h), 0), |(a, ra), (b, rb)| (a.merge(&b), ra + rb));
    // Each mutation splats an estimate of the image over its integral b: pixel = sum b / mpp.
    let scale = b / f64::from(mpp);
    finish_scaled(cluster, Film::new(w, h), splats, scale, mutations, rays + chain_rays, start)
}

/// Runs chain `k` for `mutations` steps, splatting onto `film`.
#[allow(clippy::too_many_arguments)]
fn run_chain(
    scene: &RenderScene,
    camera: &Camera,
    settings: &RenderSettings,
    k: u64,
    mutations: u64,
    cdf: &[f64],
    film: &mut SplatFilm,
    rays: &mut u64,
) {
    let o = &settings.mlt;
    let depths = u64::from(settings.max_depth) + 1;
    let mut rng = stream(settings.seed, CHAIN_DOMAIN, k);
    // The caller runs chains only when the bootstrap found light (a positive total).
    let Some(&total) = cdf.last() else { return };
    // The start: a bootstrap sample chosen in proportion to its luminance.
    let u = (f64::from(rng.next_u32()) + 0.5) / 4_294_967_296.0 * total;
    let index = cdf.partition_point(|&c| c <= u).min(cdf.len() - 1) as u64;
    let depth = (index % depths) as usize;
    let mut sampler =
        MltSampler::new(stream(settings.seed, BOOTSTRAP_DOMAIN, index), o.sigma, o.large_step_probability);
    let mut paths = (Vec::new(), Vec::new());
    let (mut l, mut p) = path_contribution(scene, camera, depth, &mut sampler, &mut paths, rays);
    let mut c = target(l);
    for _ in 0..mutations {
        sampler.start_iteration();
        let (l_new, p_new) = path_contribution(scene, camera, depth, &mut sampler, &mut paths, rays);
        let c_new = target(l_new);
        let accept = if c > 0.0 {
            (c_new / c).min(1.0)
        } else if c_new > 0.0 {
            1.0
        } else {
            0.0
        };
        if accept > 0.0 {
            film.add(p_new, l_new * (accept / c_new));
        }
        if accept < 1.0 && c > 0.0 {
            film.add(p, l * ((1.0 - accept) / c));
        }
        if uniform(&mut rng) < accept {
            (l, p, c) = (l_new, p_new, c_new);
            sampler.accept();
        } else {
            sampler.reject();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_steps_stay_close_and_rejections_restore_the_sample() {
        let mut s = MltSampler::new(stream(1, 2, 3), 0.01, 0.0);
        s.start_stream(LIGHT_STREAM);
        let first: Vec<f32> = (0..8).map(|_| s.next_1d()).collect();
        assert!(first.iter().all(|v| (0.0..1.0).contains(v)));
        for _ in 0..50 {
            s.start_iteration();
            s.start_stream(LIGHT_STREAM);
            let moved: Vec<f32> = (0..8).map(|_| s.next_1d()).collect();
            for (a, b) in first.iter().zip(&moved) {
                let d = (a - b).abs();
                // Wrapped distance below 8 sigma.
                assert!(d.min(1.0 - d) < 0.08, "{a} {b}");
            }
            s.reject();
        }
        s.start_iteration();
        s.start_stream(LIGHT_STREAM);
        let _ = s.next_1d();
        s.reject();
        s.start_iteration();
        s.start_stream(CAMERA_STREAM);
        // The camera stream's numbers are new ones, not the light stream's.
        let cam = s.next_1d();
        assert!((0.0..1.0).contains(&cam));
        s.reject();
        // After the rejections, a read of the unmodified values returns them: a large step
        // with probability 0 and sigma tiny is near the start.
        let mut t = MltSampler::new(stream(1, 2, 3), 1e-6, 0.0);
        t.start_stream(LIGHT_STREAM);
        let a = t.next_1d();
        t.start_iteration();
        t.start_stream(LIGHT_STREAM);
        let _ = t.next_1d();
        t.reject();
        assert_eq!(t.x[LIGHT_STREAM].value, a);
    }

    #[test]
    fn large_steps_are_uniform_and_small_steps_have_the_right_spread() {
        let mut s = MltSampler::new(stream(4, 5, 6), 0.05, 1.0);
        let n = 20_000;
        let mut mean = 0.0f64;
        for _ in 0..n {
            s.start_iteration();
            s.start_stream(0);
            mean += f64::from(s.next_1d());
            s.accept();
        }
        assert!((mean / f64::from(n) - 0.5).abs() < 0.01, "{mean}");
        // Small steps: the wrapped difference has standard deviation sigma.
        let mut s = MltSampler::new(stream(7, 8, 9), 0.05, 0.0);
        s.start_stream(0);
        let mut prev = s.next_1d();
        let mut sq = 0.0f64;
        for _ in 0..n {
            s.start_iteration();
            s.start_stream(0);
            let v = s.next_1d();
            let mut d = v - prev;
            d -= d.round();
            sq += f64::from(d * d);
            prev = v;
            s.accept();
        }
        let sd = (sq / f64::from(n)).sqrt();
        assert!((sd - 0.05).abs() < 0.003, "{sd}");
    }

    #[test]
    fn bad_options_are_refused_by_name() {
        for (o, flag) in [
            (MltOptions { chains: 0, ..MltOptions::default() }, "--mlt-chains"),
            (MltOptions { sigma: 0.0, ..MltOptions::default() }, "--mlt-sigma"),
            (MltOptions { large_step_probability: 1.5, ..MltOptions::default() }, "--mlt-large-step"),
            (MltOptions { bootstrap: 0, ..MltOptions::default() }, "--mlt-bootstrap"),
            (MltOptions { mutations_per_pixel: Some(0), ..MltOptions::default() }, "--mlt-mutations"),
        ] {
            assert!(o.validate(8).unwrap_err().starts_with(flag), "{flag}");
        }
        assert!(MltOptions::default().validate(8).is_ok());
        assert!(MltOptions::default().validate(1024).unwrap_err().starts_with("--mlt-bootstrap"));
    }
}
