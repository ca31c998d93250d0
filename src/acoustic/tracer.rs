//! Stochastic ray tracing of sound energy: the acoustic payload of the shared launcher.
//! Each ray carries energy in eight octave bands; surfaces absorb and scatter it; sphere
//! receivers record what passes through them.

use glam::{Vec2, Vec3};

use crate::core::fixed::add_fixed;
use crate::core::hit::Hit;
use crate::core::launcher::{Bounce, Propagation};
use crate::core::ray::Ray;
use crate::core::rng::{Rng64, uniform};
use crate::core::sampling::{cosine_hemisphere, to_world};
use crate::core::sphere::Sphere;
use crate::scene::materials::{BAND_COUNT, BandValues};

/// Acoustic surface data per surface id.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceAcoustics {
    pub absorption: BandValues,
    pub scattering: BandValues,
}

/// What a ray carries: band energies after surface losses (air absorption is applied from
/// the total path length when the energy is recorded), and the order of its reflections
/// while all of them were specular (`None` once it was scattered).
#[derive(Clone, Debug, PartialEq)]
pub struct SoundRay {
    pub energy: BandValues,
    pub specular_order: Option<u32>,
}

/// Energy recorded by a receiver: `energy[b]` arrived in histogram bin `bin`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Detection {
    pub receiver: u32,
    pub bin: u32,
    pub energy: BandValues,
}

/// What a block of rays produces: detections in trace order, and the energy that escaped
/// the scene through holes (per band, air losses included, in fixed point of the launch
/// energy per ray so that sums are exact in any order: see [`crate::core::fixed`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TraceRecord {
    pub detections: Vec<Detection>,
    pub escaped: [u128; BAND_COUNT],
    pub rays_escaped: u64,
}

/// The acoustic [`Propagation`]: surface absorption and scattering, air absorption, sphere
/// receivers with the chord-length estimator.
pub struct SoundPropagation<'a> {
    pub surfaces: &'a [SurfaceAcoustics],
    pub receivers: &'a [Sphere],
    /// Energy per ray at launch, J (source energy / ray count).
    pub ray_energy_j: f32,
    /// Air energy attenuation per band, 1/m.
    pub air_per_m: BandValues,
    pub speed_of_sound_m_s: f32,
    pub bin_s: f32,
    pub bins: u32,
    /// Paths that stay specular up to this order are left to the image-source method (0 with
    /// image sources on: the direct sound; `None`: rays record everything).
    pub skip_specular_up_to: Option<u32>,
    /// A ray stops when every band is this far (as a factor) below its launch energy.
    pub stop_factor: f32,
    pub max_path_m: f32,
    /// The scene's bounding box, slightly enlarged: a ray that ends outside it escaped.
    pub scene_bounds: (Vec3, Vec3),
}

impl SoundPropagation<'_> {
    fn air_factor(&self, band: usize, path_m: f32) -> f32 {
        (-self.air_per_m[band] * path_m).exp()
    }
}

impl Propagation for SoundPropagation<'_> {
    type Payload = SoundRay;
    type Accum = TraceRecord;

    fn new_accum(&self) -> TraceRecord {
        TraceRecord::default()
    }

    fn merge(&self, into: &mut TraceRecord, other: TraceRecord) {
        into.detections.extend(other.detections);
        for (a, b) in into.escaped.iter_mut().zip(other.escaped) {
            *a = a.saturating_add(b);
        }
        into.rays_escaped += other.rays_escaped;
    }

    fn emit(&self, _: u64, _: Vec3) -> SoundRay {
        SoundRay { energy: [self.ray_energy_j; BAND_COUNT], specular_order: Some(0) }
    }

    /// Chord-length estimator: a ray crossing a receiver of volume V along a chord l adds
    /// E l / V (energy density times... integrated over time: J/m^2), whose expectation over
    /// rays is the energy fluence E_source / (4 pi d^2) of the direct sound for any radius
    /// and ray count (Vorlaender, Auralization, sec. 11.3; DESIGN.md sec. 3).
    fn segment(
        &self,
        acc: &mut TraceRecord,
        ray_state: &SoundRay,
        ray: &Ray,
        length_m: f32,
        path_before_m: f32,
        _: u32,
    ) {
        let end = ray.at(length_m);
        let outside = end.cmplt(self.scene_bounds.0).any() || end.cmpgt(self.scene_bounds.1).any();
        if length_m >= ray.t_max && outside {
            // Flew out of the scene's bounds without a hit: it left through a hole.
            acc.rays_escaped += 1;
            for b in 0..BAND_COUNT {
                let e = f64::from(ray_state.energy[b] * self.air_factor(b, path_before_m));
                add_fixed(&mut acc.escaped[b], e, f64::from(self.ray_energy_j));
            }
            return;
        }
        if let (Some(order), Some(limit)) = (ray_state.specular_order, self.skip_specular_up_to)
            && order <= limit
        {
            return;
        }
        let seg = Ray { t_max: length_m, ..*ray };
        for (i, s) in self.receivers.iter().enumerate() {
            let Some((t0, t1)) = s.roots(&seg) else { continue };
            let (a, b) = (t0.max(0.0), t1.min(length_m));
            if b <= a {
                continue;
            }
            let chord = b - a;
            let path_m = path_before_m + 0.5 * (a + b);
            let bin = (path_m / self.speed_of_sound_m_s / self.bin_s) as u32;
            if bin >= self.bins {
                continue;
            }
            let volume = 4.0 / 3.0 * std::f32::consts::PI * s.radius_m.powi(3);
            let mut energy = [0.0; BAND_COUNT];
            for (k, e) in energy.iter_mut().enumerate() {
                *e = ray_state.energy[k] * self.air_factor(k, path_m) * chord / volume;
            }
            acc.detections.push(Detection { receiver: i as u32, bin, energy });
        }
    }

    /// Absorption, then a random choice between Lambert scattering, with probability
    /// p = sum_b E_b s_b / sum_b E_b (the energy-weighted scattering coefficient), and specular
    /// reflection, with per-band weights s_b / p and (1 - s_b) / (1 - p). Each band's expected
    /// split is exactly s_b : (1 - s_b) (Vorlaender, Auralization, sec. 11.5), and the ray's
    /// total energy is the same on both branches, so band weights cannot grow without bound
    /// over many reflections (a plain mean of s_b lets them, which made rare rays carry
    /// -20 dB of energy into the late decay).
    fn interact(
        &self,
        _: &mut TraceRecord,
        ray_state: &mut SoundRay,
        hit: &Hit,
        incoming: Vec3,
        path_m: f32,
        rng: &mut Rng64,
    ) -> Bounce {
        let surface = &self.surfaces[hit.surface as usize];
        let total: f32 = ray_state.energy.iter().sum();
        let weighted: f32 = ray_state.energy.iter().zip(surface.scattering).map(|(e, s)| e * s).sum();
        let s_mean = if total > 0.0 { (weighted / total).clamp(0.0, 1.0) } else { 0.0 };
        let diffuse = uniform(rng) < s_mean;
        let mut alive = false;
        let threshold = self.ray_energy_j * self.stop_factor;
        for b in 0..BAND_COUNT {
            let split = if diffuse {
                surface.scattering[b] / s_mean
            } else {
                (1.0 - surface.scattering[b]) / (1.0 - s_mean)
            };
            ray_state.energy[b] *= (1.0 - surface.absorption[b]) * split;
            alive |= ray_state.energy[b] * self.air_factor(b, path_m) > threshold;
        }
        if !alive {
            return Bounce::Stop;
        }
        let n = hit.facing_normal();
        if diffuse {
            ray_state.specular_order = None;
            let local = cosine_hemisphere(Vec2::new(uniform(rng), uniform(rng)));
            Bounce::Continue(to_world(local, n).normalize())
        } else {
            ray_state.specular_order = ray_state.specular_order.map(|o| o + 1);
            Bounce::Continue((incoming - 2.0 * incoming.dot(n) * n).normalize())
        }
    }
}
