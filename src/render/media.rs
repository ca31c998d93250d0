//! The participating media a path travels through (`volpath`, `raymarch`): homogeneous or
//! scaled by a density grid, filling the scene or the inside of a closed mesh, with
//! free flights by delta tracking and shadow-ray transmittance by ratio tracking.
//!
//! **Delta tracking** (\[Woodcock1965\] in docs/references.md) samples tentative collisions
//! with a majorant `sigma_bar >= sigma_t(x)`: here, in each cell of a coarse 16^3 grid over
//! the density grid's box, the largest density the cell can take times the largest channel's
//! extinction (grey local majorants, walked by a DDA as \[pbrt-v4\] sec. 14.2.1 does; the
//! exponential's memorylessness lets a flight restart at each cell border). At a tentative collision at `x` the path scatters with
//! probability `P_s = avg(sigma_s(x)) / (avg(sigma_s(x)) + avg(sigma_n(x)))`, the null
//! coefficient being `sigma_n = sigma_bar - sigma_t(x)` per channel, and otherwise flies on;
//! the throughput is multiplied by `sigma_s / (sigma_bar P_s)` or `sigma_n / (sigma_bar
//! (1 - P_s))`. Absorption is the part of the majorant neither event keeps. The channel
//! averages make it unbiased for chromatic media (the scheme of spectral tracking, Kutz et
//! al. 2017, with the averaged probabilities, as \[pbrt-v4\] sec. 14.2.2 weights by
//! throughput ratios): every channel's expectation is its own collision estimator.
//!
//! **Ratio tracking** (\[Novak2014\]) estimates the transmittance `exp(-integral sigma_t)`
//! of a shadow segment as the product of `sigma_n(x) / sigma_bar` over the tentative
//! collisions: unbiased, never zero before a channel is fully absorbed.
//!
//! A homogeneous medium keeps the closed forms of [`Medium`]: Beer-Lambert transmittance and
//! spectral-MIS free flights.

use std::sync::Arc;

use glam::Vec3;

use super::RenderScene;
use super::medium::{Flight, Medium};
use super::sampler::Sampler;
use crate::core::{Hit, Ray};
use crate::scene::World;
use crate::scene::density_grid::DensityGrid;

/// Tentative collisions a single free flight or transmittance estimate may take before it
/// gives up (weight 0): a guard against absurd inputs; a box of optical depth under ~10^5
/// never reaches it.
pub const MAX_COLLISIONS: u32 = 1 << 20;
/// Boundaries a ray may pass unchanged in a row (index-matched interfaces) before the path
/// is ended: a guard against a ray caught between coincident faces.
pub const MAX_CROSSINGS: u32 = 256;

/// One medium: the coefficients at density 1 and, if heterogeneous, its density grid.
#[derive(Clone, Debug, PartialEq)]
pub struct Volume {
    /// Coefficients per channel at density 1 and the phase function.
    pub medium: Medium,
    /// Density multiplying the coefficients (none: 1 everywhere).
    pub grid: Option<Arc<DensityGrid>>,
}

impl Volume {
    /// A homogeneous medium.
    pub fn homogeneous(medium: Medium) -> Self {
        Self { medium, grid: None }
    }

    /// The grey majorant of a grid medium, 1/m: the largest density times the largest
    /// channel's extinction.
    #[inline]
    pub fn majorant_per_m(&self) -> f32 {
        let d = self.grid.as_ref().map_or(1.0, |g| g.max_density);
        d * self.medium.sigma_t_per_m().max_element()
    }

    /// The density at `p` (1 for a homogeneous medium).
    #[inline]
    pub fn density(&self, p: Vec3) -> f32 {
        self.grid.as_ref().map_or(1.0, |g| g.density(p))
    }

    /// A free flight along `ray` (unit direction) towards a surface `t_max` away (infinite:
    /// none): the closed form for a homogeneous medium, delta tracking for a grid.
    pub fn sample_flight(&self, ray: &Ray, t_max: f32, sampler: &mut Sampler) -> Flight {
        let Some(grid) = &self.grid else {
            return self.medium.sample_flight(t_max, sampler.get_1d(), sampler.get_1d());
        };
        let mut flight = Flight { t: t_max, scattered: false, weight: Vec3::ONE };
        let Some((t0, t1)) = grid.clip(ray, t_max) else {
            return flight;
        };
        let (sigma_s, sigma_t) = (self.medium.sigma_s_per_m, self.medium.sigma_t_per_m());
        let complete = tentative_collisions(
            grid,
            ray,
            (t0, t1),
            sigma_t.max_element(),
            sampler,
            |t, d, sigma_bar, sampler| {
                let s = sigma_s * d;
                let n = (Vec3::splat(sigma_bar) - sigma_t * d).max(Vec3::ZERO);
                let (ps, pn) = (s.element_sum(), n.element_sum());
                if ps + pn <= 0.0 {
                    flight = Flight { t, scattered: false, weight: Vec3::ZERO };
                    return true;
                }
                let p_scatter = ps / (ps + pn);
                if sampler.get_1d() < p_scatter {
                    flight =
                        Flight { t, scattered: true, weight: flight.weight * s / (sigma_bar * p_scatter) };
                    return true;
                }
                flight.weight *= n / (sigma_bar * (1.0 - p_scatter));
                false
            },
        );
        if !complete {
            flight.weight = Vec3::ZERO;
        }
        flight
    }

    /// The transmittance along `ray` (unit direction) over `[0, t_max]`: Beer-Lambert for a
    /// homogeneous medium, ratio tracking for a grid.
    pub fn transmittance(&self, ray: &Ray, t_max: f32, sampler: &mut Sampler) -> Vec3 {
        let Some(grid) = &self.grid else {
            return self.medium.transmittance(t_max);
        };
        let Some((t0, t1)) = grid.clip(ray, t_max) else {
            return Vec3::ONE;
        };
        let sigma_t = self.medium.sigma_t_per_m();
        let mut tr = Vec3::ONE;
        let complete = tentative_collisions(
            grid,
            ray,
            (t0, t1),
            sigma_t.max_element(),
            sampler,
            |_, d, sigma_bar, _| {
                tr *= (Vec3::ONE - sigma_t * (d / sigma_bar)).max(Vec3::ZERO);
                tr == Vec3::ZERO
            },
        );
        if !complete {
            tr = Vec3::ZERO;
        }
        tr
    }
}

/// The tentative collisions of delta and ratio tracking along `ray` over `[t0, t1]` in
/// `grid` (Woodcock et al. 1965; pbrt-v4 sec. 14.2.1): exponential steps at each majorant
/// cell's rate `majorant x sigma_max`, `visit(t, density, rate, sampler)` at each; `visit`
/// returns true to stop. Returns false when the walk gave up after [`MAX_COLLISIONS`]
/// collisions (the caller zeroes its estimate), else true.
fn tentative_collisions(
    grid: &DensityGrid,
    ray: &Ray,
    (t0, t1): (f32, f32),
    sigma_max: f32,
    sampler: &mut Sampler,
    mut visit: impl FnMut(f32, f32, f32, &mut Sampler) -> bool,
) -> bool {
    let mut collisions = 0u32;
    let mut complete = true;
    grid.majorant_segments(ray, t0, t1, |start, end, majorant| {
        let sigma_bar = majorant * sigma_max;
        if sigma_bar.is_nan() || sigma_bar <= 0.0 {
            return false;
        }
        let mut t = start;
        loop {
            collisions += 1;
            if collisions > MAX_COLLISIONS {
                complete = false;
                return true;
            }
            t -= (1.0 - sampler.get_1d()).max(f32::MIN_POSITIVE).ln() / sigma_bar;
            if t >= end {
                return false;
            }
            if visit(t, grid.density(ray.at(t)), sigma_bar, sampler) {
                return true;
            }
        }
    });
    complete
}

/// The media of a render scene: every medium, the one filling the scene (if any) and the
/// medium inside each surface that bounds one.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct SceneMedia {
    /// The media.
    pub volumes: Vec<Volume>,
    /// Index of the medium filling the scene outside every boundary.
    pub global: Option<usize>,
    /// By surface id: the medium inside it and whether rays pass it unchanged (an
    /// index-matched interface) rather than meeting its material.
    pub inside: Vec<Option<(usize, bool)>>,
}

impl SceneMedia {
    /// The media of a loaded world's `[[media]]`.
    pub fn of_world(world: &World) -> Self {
        let s = &world.scene;
        let mut media = SceneMedia { inside: vec![None; s.surfaces.len()], ..Self::default() };
        for (i, m) in s.media.iter().enumerate() {
            media.volumes.push(Volume {
                medium: Medium { sigma_a_per_m: m.sigma_a_per_m, sigma_s_per_m: m.sigma_s_per_m, g: m.g },
                grid: m.grid.clone(),
            });
            if m.boundary.is_empty() {
                media.global = Some(i);
            }
            for &surface in &m.boundary {
                if let Some(slot) = media.inside.get_mut(surface as usize) {
                    *slot = Some((i, m.interface));
                }
            }
        }
        media
    }

    /// True when the scene has no media of its own (a fog from the settings may still fill it).
    #[inline]
    pub fn is_empty(&self) -> bool {
        self.volumes.is_empty()
    }

    /// The bounded medium whose boundary encloses `p` (none: outside every boundary), by the
    /// parity of the boundary faces a ray from `p` crosses (in a fixed, skew direction, so
    /// that it meets no edge of an axis-aligned mesh). Media do not nest: the first with an
    /// odd count is taken. For the camera, once a render.
    pub fn enclosing(&self, scene: &RenderScene, p: Vec3) -> Option<usize> {
        if self.inside.iter().all(Option::is_none) {
            return None;
        }
        let mut odd = vec![false; self.volumes.len()];
        let dir = Vec3::new(0.5377, 0.3461, 0.7692).normalize();
        let mut ray = Ray::new(p, dir);
        for _ in 0..4 * MAX_CROSSINGS {
            let Some(hit) = scene.intersect(&ray) else {
                break;
            };
            if let Some((k, _)) = self.inside_of(hit.surface) {
                odd[k] = !odd[k];
            }
            ray = Ray::spawn(hit.point, hit.normal, dir);
        }
        odd.iter().position(|&o| o)
    }

    /// The medium inside `surface` and whether it is an interface.
    #[inline]
    pub fn inside_of(&self, surface: u32) -> Option<(usize, bool)> {
        self.inside.get(surface as usize).copied().flatten()
    }
}

/// The media one path sees: the scene's, and outside every boundary the scene's global
/// medium or else the settings' fog.
#[derive(Clone, Copy)]
pub struct PathMedia<'a> {
    /// The scene's media.
    pub scene: &'a SceneMedia,
    /// The medium outside every boundary (where the camera is).
    pub outer: Option<&'a Volume>,
}

impl<'a> PathMedia<'a> {
    /// The media of `scene` with `fog` (a homogeneous volume made by the caller) outside
    /// when the scene has no global medium.
    pub fn new(scene: &'a SceneMedia, fog: Option<&'a Volume>) -> Self {
        Self { scene, outer: scene.global.map(|i| &scene.volumes[i]).or(fog) }
    }

    /// The medium a camera ray starts in: the bounded medium `camera` (from
    /// [`SceneMedia::enclosing`]), else the outer one.
    #[inline]
    pub fn start(&self, camera: Option<usize>) -> Option<&'a Volume> {
        camera.and_then(|k| self.scene.volumes.get(k)).or(self.outer)
    }

    /// True when no medium is heterogeneous or bounded (the closed forms and plain shadow
    /// rays serve).
    #[inline]
    pub fn simple(&self) -> bool {
        self.scene.is_empty()
    }

    /// The medium a ray leaving `hit` along `dir` travels in, given the medium `current` it
    /// arrived in: inside a boundary when `dir` points against its outward normal, outside
    /// it otherwise; unchanged at other surfaces.
    #[inline]
    pub fn after(&self, current: Option<&'a Volume>, hit: &Hit, dir: Vec3) -> Option<&'a Volume> {
        match self.scene.inside_of(hit.surface) {
            Some((i, _)) if dir.dot(hit.normal) < 0.0 => Some(&self.scene.volumes[i]),
            Some(_) => self.outer,
            None => current,
        }
    }

    /// Whether `hit`'s surface is an index-matched interface (rays pass it unchanged).
    #[inline]
    pub fn is_interface(&self, hit: &Hit) -> bool {
        self.scene.inside_of(hit.surface).is_some_and(|(_, interface)| interface)
    }

    /// The transmittance along the shadow segment `ray` (its `t_max` short of the light)
    /// starting in `start`: each stretch between interfaces in its own medium, zero when a
    /// surface that is not an interface blocks it. Counts the extra rays into `rays`.
    pub fn shadow_transmittance(
        &self,
        scene: &RenderScene,
        start: Option<&'a Volume>,
        mut ray: Ray,
        sampler: &mut Sampler,
        rays: &mut u64,
    ) -> Vec3 {
        let mut tr = Vec3::ONE;
        let mut current = start;
        for _ in 0..MAX_CROSSINGS {
            let hit = scene.intersect(&ray);
            let t_end = hit.map_or(ray.t_max, |h| h.t);
            if let Some(m) = current {
                tr *= m.transmittance(&ray, t_end, sampler);
                if tr == Vec3::ZERO {
                    return tr;
                }
            }
            let Some(h) = hit else {
                return tr;
            };
            if !self.is_interface(&h) {
                return Vec3::ZERO;
            }
            current = self.after(current, &h, ray.dir);
            let mut next = Ray::spawn(h.point, h.normal, ray.dir);
            next.t_max = (ray.t_max - h.t).max(0.0);
            ray = next;
            *rays += 1;
        }
        Vec3::ZERO
    }
}
