//! The light image: contributions that light paths (light tracing, BDPT's `t = 1`
//! strategies) splat onto arbitrary pixels, summed in fixed point
//! ([`crate::core::fixed`]) so that the total is the same to the last bit whatever the
//! order of the splats: any thread count, any split of the paths over MPI ranks (whose
//! films are added by exact integer sums, [`crate::dist::Cluster::sum_u128`]).

use std::time::Instant;

use glam::{Vec2, Vec3};

use super::{Film, RenderOutput};
use crate::core::fixed::{from_fixed, to_fixed};
use crate::dist::Cluster;

/// The unit of the fixed-point sums: radiance 1. Values keep 2^-64 of it (about 5e-20) and
/// a pixel's sum saturates at about 1.8e19, beyond any physical radiance.
const UNIT: f64 = 1.0;

/// A `width` x `height` film of fixed-point RGB sums.
#[derive(Clone, Debug, PartialEq)]
pub struct SplatFilm {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// Three fixed-point sums a pixel, row-major from the top left.
    pub sums: Vec<u128>,
}

impl SplatFilm {
    /// An empty (black) film.
    pub fn new(width: u32, height: u32) -> Self {
        Self { width, height, sums: vec![0; 3 * width as usize * height as usize] }
    }

    /// Adds `value` at image point `film` in `[0,1)^2` (box filter: the pixel it falls in).
    /// Negative, NaN and infinite channels add nothing.
    #[inline]
    pub fn add(&mut self, film: Vec2, value: Vec3) {
        if !value.is_finite() {
            return;
        }
        let i = self.index(film);
        for (k, v) in value.to_array().into_iter().enumerate() {
            self.sums[i + k] = self.sums[i + k].saturating_add(to_fixed(f64::from(v), UNIT));
        }
    }

    /// Where in `sums` the pixel of image point `film` starts.
    #[inline]
    fn index(&self, film: Vec2) -> usize {
        let x = ((film.x * self.width as f32) as u32).min(self.width - 1);
        let y = ((film.y * self.height as f32) as u32).min(self.height - 1);
        3 * (y as usize * self.width as usize + x as usize)
    }

    /// Adds another film's sums (exact, so the order of merging does not matter).
    pub fn merge(mut self, other: &SplatFilm) -> Self {
        for (a, b) in self.sums.iter_mut().zip(&other.sums) {
            *a = a.saturating_add(*b);
        }
        self
    }

    /// Pixel `i`'s sum times `scale`.
    #[inline]
    pub fn pixel(&self, i: usize, scale: f64) -> Vec3 {
        let c = |k: usize| (from_fixed(self.sums[3 * i + k], UNIT) * scale) as f32;
        Vec3::new(c(0), c(1), c(2))
    }
}

/// Splats a [`HeldSplats`] holds before it adds them to its film.
const HELD_SPLATS: usize = 64;

/// Splats held back, then added to a [`SplatFilm`] in one run ([`HeldSplats::add_to`]): they
/// land on scattered pixels, mostly out of cache, and added one at a time between rays each
/// waits for memory, while in a run the accesses overlap. The sums are exact, so holding
/// them back changes no bit of the image.
#[derive(Clone, Debug, Default)]
pub struct HeldSplats {
    held: Vec<(Vec2, Vec3)>,
    /// The held splats' places in the film's sums and fixed-point values ([`Self::add_to`]).
    fixed: Vec<(usize, [u128; 3])>,
}

impl HeldSplats {
    /// Holds `value` for image point `film` (see [`SplatFilm::add`]).
    #[inline]
    pub fn push(&mut self, film: Vec2, value: Vec3) {
        self.held.push((film, value));
    }

    /// Adds the held splats to `film` once [`HELD_SPLATS`] or more are held (callers check
    /// after each sample, and call [`Self::add_to`] at the end of their work).
    #[inline]
    pub fn add_to_when_full(&mut self, film: &mut SplatFilm) {
        if self.held.len() >= HELD_SPLATS {
            self.add_to(film);
        }
    }

    /// Adds every held splat to `film` (as [`SplatFilm::add`] does) and lets them go: first
    /// every place and fixed-point value, then the sums in a loop of a few instructions a
    /// splat, so that many of the sums' cache misses are in flight at once.
    pub fn add_to(&mut self, film: &mut SplatFilm) {
        self.fixed.clear();
        self.fixed.extend(
            self.held
                .iter()
                .filter(|(_, v)| v.is_finite())
                .map(|&(p, v)| (film.index(p), v.to_array().map(|c| to_fixed(f64::from(c), UNIT)))),
        );
        for &(i, f) in &self.fixed {
            for (sum, v) in film.sums[i..i + 3].iter_mut().zip(f) {
                *sum = sum.saturating_add(v);
            }
        }
        self.held.clear();
    }
}

/// Ends a render that splats: gathers the pixels each process computed (`film`, zero where
/// another process owns the pixel) and adds up the light images of every process exactly;
/// the root gets `film + splats / spp` (the light image is an estimate over `spp` light paths
/// a pixel), the others `None`.
pub(super) fn finish(
    cluster: &Cluster,
    film: Film,
    splats: SplatFilm,
    spp: u32,
    rays: u64,
    start: Instant,
) -> Option<RenderOutput> {
    let samples = u64::from(film.width) * u64::from(film.height) * u64::from(spp);
    finish_scaled(cluster, film, splats, 1.0 / f64::from(spp), samples, rays, start)
}

/// [`finish`] with the light image scaled by `scale`, reporting `samples` samples.
pub(super) fn finish_scaled(
    cluster: &Cluster,
    mut film: Film,
    mut splats: SplatFilm,
    scale: f64,
    samples: u64,
    mut rays: u64,
    start: Instant,
) -> Option<RenderOutput> {
    if cluster.size() > 1 {
        let mut channels: Vec<f32> = film.pixels.iter().flat_map(|p| p.to_array()).collect();
        cluster.gather_disjoint_f32(&mut channels);
        cluster.sum_u128(&mut splats.sums);
        let mut total_rays = [rays];
        cluster.sum_u64(&mut total_rays);
        if !cluster.is_root() {
            return None;
        }
        for (p, c) in film.pixels.iter_mut().zip(channels.chunks_exact(3)) {
            *p = Vec3::new(c[0], c[1], c[2]);
        }
        rays = total_rays[0];
    }
    for (i, p) in film.pixels.iter_mut().enumerate() {
        *p += splats.pixel(i, scale);
    }
    Some(RenderOutput {
        film,
        samples,
        rays,
        photons: 0,
        seconds: start.elapsed().as_secs_f64(),
        notes: Vec::new(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splats_sum_the_same_in_any_order() {
        let values: Vec<(Vec2, Vec3)> = (0..500)
            .map(|i| {
                let t = i as f32;
                (Vec2::new((t * 0.37).fract(), (t * 0.61).fract()), Vec3::new(t.sin().abs(), 1e-6 * t, 3e4))
            })
            .collect();
        let mut a = SplatFilm::new(4, 3);
        let mut b = SplatFilm::new(4, 3);
        for &(f, v) in &values {
            a.add(f, v);
        }
        let (first, second) = values.split_at(123);
        let mut c = SplatFilm::new(4, 3);
        for &(f, v) in second.iter().rev() {
            b.add(f, v);
        }
        for &(f, v) in first {
            c.add(f, v);
        }
        assert_eq!(a, b.merge(&c));
        let total: f64 = (0..12).map(|i| f64::from(a.pixel(i, 1.0).z)).sum();
        assert!((total - 500.0 * 3e4).abs() < 1e-3);
        a.add(Vec2::ZERO, Vec3::new(f32::NAN, 1.0, f32::INFINITY));
        assert!(a.pixel(0, 1.0).is_finite());
    }
}
