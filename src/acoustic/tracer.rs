//! Stochastic ray tracing of sound energy: the acoustic payload of the shared launcher.
//! Each ray carries energy in eight octave bands; surfaces absorb and scatter it; sphere
//! receivers record what passes through them.

use glam::{Vec2, Vec3, Vec4};

use super::directions::{CELLS, DirectionBins, cell_of};
use super::directivity::Directivity;
use super::edge_scattering::EdgeScattering;
use super::ray_diffraction::RayDiffraction;
use crate::core::TimeBins;
use crate::core::accel::Accel;
use crate::core::fixed::add_fixed;
use crate::core::hit::{Hit, PrimitiveKind};
use crate::core::launcher::{Bounce, Deflection, Propagation};
use crate::core::ray::Ray;
use crate::core::rng::{Rng64, uniform};
use crate::core::sampling::{cosine_hemisphere, to_world};
use crate::core::sphere::Sphere;
use crate::core::visibility::{PartsInView, part_of};
use crate::scene::materials::{BAND_COUNT, BandValues};

/// Acoustic surface data per surface id.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceAcoustics {
    /// Absorption coefficient per band.
    pub absorption: BandValues,
    /// Scattering coefficient per band.
    pub scattering: BandValues,
}

/// What a ray carries: band energies after surface losses (air absorption depends only on
/// the path length, so it is applied to the histogram bin by bin, not ray by ray), and the
/// order of its reflections while all of them were specular (`None` once it was scattered).
#[derive(Clone, Debug, PartialEq)]
pub struct SoundRay {
    /// Band energies after surface losses.
    pub energy: BandValues,
    /// Order of its reflections while all were specular (`None` once scattered).
    pub specular_order: Option<u32>,
    /// The ray's last reflection was diffuse: with diffuse rain on, that part of the sound
    /// reached the receivers by the rain, so this segment's crossings are not counted again.
    pub after_diffuse: bool,
    /// The edge (index + 1) that bent this ray since its last reflection, 0 for none
    /// ([`super::ray_diffraction`]: one bend between two reflections).
    pub bent_by: u32,
    /// Copies this ray may still be split into, all its later splits together (see
    /// [`Splitting`]); a split into k copies gives each a k-th of it.
    pub copies_left: u32,
    /// Copies this ray's bends near edges may still make, all of them together
    /// ([`super::ray_diffraction::RayDiffraction::copies`]); past that, a bend follows one of
    /// its parts, chosen by energy.
    pub bend_copies_left: u32,
}

/// Ray splitting against the room's expected decay (Booth 1985; docs/acoustics.md, Ray
/// splitting): a ray whose strongest band carries more than `above` times the energy an
/// average ray has left after the same path (the band's statistical decay) is split into k
/// equal copies, k = that ratio / `to` (rounded down), each with a k-th of its energy and its
/// own random stream. Rays on a rare path family that loses little (a flutter echo between
/// parallel hard walls) thus become many rays of ordinary energy, which part ways at their
/// next scattering, instead of one rare ray that makes a step in the decay curve. Every
/// band's expected deposit is unchanged (the copies together carry what the ray carried),
/// so the estimate stays unbiased; only its variance falls.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Splitting {
    /// Per band, the decay rate of an average ray's energy by surface losses, 1/m (Eyring's
    /// -ln(1 - a_mean) S / (4 V): air absorption is applied to the histogram, not the rays).
    pub decay_per_m: BandValues,
    /// The ratio to the expected energy above which a ray splits (> 1).
    pub above: f32,
    /// The ratio to the expected energy each copy starts with (at most `above` / 2, so
    /// that a split makes at least two copies).
    pub to: f32,
    /// Copies a launched ray may become at most, all splits together (it bounds the cost).
    pub copies: u32,
}

/// What rays deposit: per receiver, the energy per histogram bin and band (before air
/// absorption) and the number of detections. A block of rays sums its own deposits in f64 in
/// trace order (`block`); blocks are merged into fixed point (`fixed`, in units of the launch
/// energy per ray), which is exact in any order, so every split of the rays over threads and
/// processes gives the same histograms to the last bit (see [`crate::core::fixed`]).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TraceRecord {
    /// The current block's deposits in f64, per receiver, bin and band.
    pub block: Vec<Vec<[f64; BAND_COUNT]>>,
    /// The merged deposits in fixed point, per receiver, bin and band.
    pub fixed: Vec<Vec<[u128; BAND_COUNT]>>,
    /// Detections per receiver.
    pub detections: Vec<u64>,
    /// Escaped energy per band, air losses included, in fixed point of the launch energy.
    pub escaped: [u128; BAND_COUNT],
    /// Rays that escaped the scene.
    pub rays_escaped: u64,
    /// Straight flights traced (a ray's launch and every reflection start one).
    pub segments: u64,
    /// Directions of arrival (with [`SoundPropagation::directions`] on): per receiver, the
    /// energy per direction bin, direction cell ([`super::directions`]) and band, at index
    /// `direction_bin * CELLS + cell`; the block's f64 sums and the fixed-point total, merged
    /// like the histograms (so just as independent of threads and processes).
    /// (The block's sums are f32: half the memory, so the record stays in cache; directions
    /// are used as shares of a bin's energy, which f32 sums of a block keep to 1e-6.)
    pub dir_block: Vec<Vec<[f32; BAND_COUNT]>>,
    /// Directions of arrival in fixed point (see `dir_block`).
    pub dir_fixed: Vec<Vec<[u128; BAND_COUNT]>>,
}

impl TraceRecord {
    /// Adds `energy` to receiver `receiver`'s bin `bin` of this block, and to its direction
    /// slot `direction` (`Some(direction_bin * CELLS + cell)`) when directions are kept.
    #[inline]
    fn deposit(&mut self, receiver: usize, bin: usize, energy: &BandValues, direction: Option<usize>) {
        let hist = &mut self.block[receiver];
        if hist.len() <= bin {
            hist.resize(bin + 1, [0.0; BAND_COUNT]);
        }
        for (h, e) in hist[bin].iter_mut().zip(energy) {
            *h += f64::from(*e);
        }
        self.detections[receiver] += 1;
        if let Some(slot) = direction {
            let dirs = &mut self.dir_block[receiver];
            if dirs.len() <= slot {
                dirs.resize((slot / CELLS + 1) * CELLS, [0.0; BAND_COUNT]);
            }
            for (h, e) in dirs[slot].iter_mut().zip(energy) {
                *h += *e;
            }
        }
    }

    /// The number of bins any receiver reached.
    pub fn bins(&self) -> usize {
        self.fixed.iter().map(Vec::len).max().unwrap_or(0)
    }
}

/// The acoustic [`Propagation`]: surface absorption and scattering, sphere receivers with
/// the chord-length estimator, and Russian roulette once a ray is weak.
pub struct SoundPropagation<'a> {
    /// Acoustic data per surface id.
    pub surfaces: &'a [SurfaceAcoustics],
    /// Receiver spheres.
    pub receivers: &'a [Sphere],
    /// Energy per ray at launch, J (source energy / ray count).
    pub ray_energy_j: f32,
    /// Air energy attenuation per band, 1/m: used for the escaped energy.
    pub air_per_m: BandValues,
    /// Histogram time bins: a detection after l metres falls in bin floor(l / c / bin_s);
    /// arrivals past the last bin are dropped.
    pub bins: TimeBins,
    /// Paths that stay specular up to this order are left to the image-source method (0 with
    /// image sources on: the direct sound; `None`: rays record everything).
    pub skip_specular_up_to: Option<u32>,
    /// Once a ray's strongest band (with an upper bound of its air loss) falls below this
    /// fraction of its launch energy, it plays Russian roulette at every reflection.
    pub roulette_factor: f32,
    /// The scene's bounding box, slightly enlarged: a ray that ends outside it escaped.
    pub scene_bounds: (Vec3, Vec3),
    /// Diffuse rain (next-event estimation): at every reflection the diffusely scattered
    /// energy is sent straight to every receiver in view, tested for occlusion in this
    /// scene. `None`: receivers count only the rays that cross them.
    pub diffuse_rain: Option<&'a Accel>,
    /// Ray splitting; `None`: rays never split.
    pub splitting: Option<Splitting>,
    /// Per receiver, the triangles wholly in its view ([`crate::core::visibility::triangles_in_full_view`]): rain
    /// from them needs no occlusion ray. Empty (or `None` for a receiver): trace them all.
    pub rain_in_view: &'a [Option<Vec<PartsInView>>],
    /// The source's directivity: each ray's band energies are weighted by the pattern's
    /// normalised energy weight in its launch direction (docs/acoustics.md, Directivity).
    /// `None`: omnidirectional.
    pub directivity: Option<Directivity>,
    /// Directions of arrival: `Some(bins)` keeps each receiver's energy per direction cell in
    /// those time bins ([`TraceRecord::dir_fixed`]); `None` keeps none (no cost).
    pub directions: Option<DirectionBins>,
    /// The finite panels that scatter by diffraction at their free edges
    /// ([`super::edge_scattering`]); `None`: only the materials scatter.
    pub edge_scattering: Option<&'a EdgeScattering>,
    /// Per receiver, its directivity (`None` or missing: omni): every deposit is weighted by
    /// its sensitivity to the direction the sound comes from.
    pub receiver_directivity: &'a [Option<Directivity>],
    /// Rays passing near free edges are bent ([`super::ray_diffraction`]); `None`: never.
    pub ray_diffraction: Option<&'a RayDiffraction>,
}

impl Propagation for SoundPropagation<'_> {
    type Payload = SoundRay;
    type Accum = TraceRecord;

    fn new_accum(&self) -> TraceRecord {
        let n = self.receivers.len();
        TraceRecord {
            block: vec![Vec::new(); n],
            fixed: vec![Vec::new(); n],
            dir_block: vec![Vec::new(); n],
            dir_fixed: vec![Vec::new(); n],
            detections: vec![0; n],
            ..TraceRecord::default()
        }
    }

    fn merge(&self, into: &mut TraceRecord, other: TraceRecord) {
        let unit = f64::from(self.ray_energy_j);
        for (r, (block, fixed)) in other.block.iter().zip(&other.fixed).enumerate() {
            let total = &mut into.fixed[r];
            if total.len() < block.len().max(fixed.len()) {
                total.resize(block.len().max(fixed.len()), [0; BAND_COUNT]);
            }
            for (t, e) in total.iter_mut().zip(block) {
                for (slot, v) in t.iter_mut().zip(e) {
                    add_fixed(slot, *v, unit);
                }
            }
            for (t, e) in total.iter_mut().zip(fixed) {
                for (slot, v) in t.iter_mut().zip(e) {
                    *slot = slot.saturating_add(*v);
                }
            }
            into.detections[r] += other.detections[r];
        }
        for (r, (block, fixed)) in other.dir_block.iter().zip(&other.dir_fixed).enumerate() {
            let total = &mut into.dir_fixed[r];
            if total.len() < block.len().max(fixed.len()) {
                total.resize(block.len().max(fixed.len()), [0; BAND_COUNT]);
            }
            for (t, e) in total.iter_mut().zip(block) {
                for (slot, v) in t.iter_mut().zip(e) {
                    if *v != 0.0 {
                        add_fixed(slot, f64::from(*v), unit);
                    }
                }
            }
            for (t, e) in total.iter_mut().zip(fixed) {
                for (slot, v) in t.iter_mut().zip(e) {
                    *slot = slot.saturating_add(*v);
                }
            }
        }
        for (a, b) in into.escaped.iter_mut().zip(other.escaped) {
            *a = a.saturating_add(b);
        }
        into.rays_escaped += other.rays_escaped;
        into.segments += other.segments;
    }

    /// A ray of `ray_energy_j` per band, weighted by the directivity's normalised energy
    /// weight towards `dir` (the launch directions stay the source's even lattice, so the
    /// weights sample the pattern deterministically and average to 1 over the rays).
    fn emit(&self, _: u64, dir: Vec3) -> SoundRay {
        let energy = match &self.directivity {
            Some(d) => d.energy_weights(dir).map(|w| w * self.ray_energy_j),
            None => [self.ray_energy_j; BAND_COUNT],
        };
        SoundRay {
            energy,
            specular_order: Some(0),
            after_diffuse: false,
            bent_by: 0,
            copies_left: self.splitting.map_or(1, |s| s.copies),
            bend_copies_left: self.ray_diffraction.map_or(0, |r| r.copies),
        }
    }

    /// [`Splitting`]: k = ratio / `to` copies when the ray's strongest band is `ratio` times
    /// its expected energy after `path_m`, ratio > `above`; fewer if the ray may not make
    /// that many, and none that would start below the Russian-roulette threshold (a copy
    /// would only play roulette at once).
    #[inline(always)]
    fn split(&self, ray: &mut SoundRay, path_m: f32) -> u32 {
        let Some(s) = &self.splitting else { return 1 };
        if ray.copies_left < 2 {
            return 1;
        }
        let (mut ratio, mut level) = (0.0f32, 0.0f32);
        for b in 0..BAND_COUNT {
            let expected = self.ray_energy_j * (-s.decay_per_m[b] * path_m).exp();
            ratio = ratio.max(ray.energy[b] / expected);
            level = level.max(ray.energy[b]);
        }
        if ratio.is_nan() || ratio <= s.above {
            return 1;
        }
        let above_roulette = level / (self.ray_energy_j * self.roulette_factor);
        let k = (ratio / s.to).min(above_roulette).min(ray.copies_left as f32) as u32;
        if k < 2 {
            return 1;
        }
        let share = 1.0 / k as f32;
        for e in &mut ray.energy {
            *e *= share;
        }
        ray.copies_left /= k;
        k
    }

    /// Stochastic diffraction near free edges ([`super::ray_diffraction`]). A ray that is
    /// still an image-source path is not bent: the image sources count that path's whole
    /// energy, so its bent part would be counted twice.
    #[inline(always)]
    fn deflect(
        &self,
        sound: &SoundRay,
        ray: &Ray,
        length_m: f32,
        reflections: u32,
        rng: &mut Rng64,
    ) -> Option<Deflection<SoundRay>> {
        if let (Some(order), Some(limit)) = (sound.specular_order, self.skip_specular_up_to)
            && order <= limit
        {
            return None;
        }
        let b = self.ray_diffraction?.deflect(sound, ray, length_m, reflections, rng)?;
        Some(Deflection { at_m: b.at_m, dir: b.dir, payload: b.bent, straight: b.straight })
    }

    /// Chord-length estimator: a ray crossing a receiver of volume V along a chord l adds
    /// E l / V (energy density times... integrated over time: J/m^2), whose expectation over
    /// rays is the energy fluence E_source / (4 pi d^2) of the direct sound for any radius
    /// and ray count (Vorlaender, Auralization, sec. 11.3; docs/acoustics.md). Inlined into
    /// the launcher's AVX2 loop, where the eight bands are one vector.
    #[inline(always)]
    fn segment(
        &self,
        acc: &mut TraceRecord,
        ray_state: &SoundRay,
        ray: &Ray,
        length_m: f32,
        path_before_m: f32,
        _: u32,
    ) {
        acc.segments += 1;
        if length_m >= ray.t_max {
            let end = ray.at(length_m);
            if end.cmplt(self.scene_bounds.0).any() || end.cmpgt(self.scene_bounds.1).any() {
                // Flew out of the scene's bounds without a hit: it left through a hole.
                acc.rays_escaped += 1;
                for b in 0..BAND_COUNT {
                    let air = (-self.air_per_m[b] * path_before_m).exp();
                    let e = f64::from(ray_state.energy[b] * air);
                    add_fixed(&mut acc.escaped[b], e, f64::from(self.ray_energy_j));
                }
                return;
            }
        }
        if let (Some(order), Some(limit)) = (ray_state.specular_order, self.skip_specular_up_to)
            && order <= limit
        {
            return;
        }
        if ray_state.after_diffuse && self.diffuse_rain.is_some() {
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
            let Some(bin) = self.bins.bin_of_path(f64::from(path_m)) else { continue };
            let per_volume = chord / (4.0 / 3.0 * std::f32::consts::PI * s.radius_m.powi(3));
            let mut energy = ray_state.energy.map(|e| e * per_volume);
            if let Some(Some(d)) = self.receiver_directivity.get(i) {
                let w = d.sensitivity(-ray.dir);
                energy = std::array::from_fn(|b| energy[b] * w[b]);
            }
            // The sound comes from where the ray came from.
            let direction = self.directions.map(|d| d.of(bin) * CELLS + cell_of(-ray.dir));
            acc.deposit(i, bin, &energy, direction);
        }
    }

    /// Absorption, then a random choice between Lambert scattering, with probability
    /// p = sum_b E_b s_b / sum_b E_b (the energy-weighted scattering coefficient), and specular
    /// reflection, with per-band weights s_b / p and (1 - s_b) / (1 - p). Each band's expected
    /// split is exactly s_b : (1 - s_b) (Vorlaender, Auralization, sec. 11.5), and the ray's
    /// total energy is the same on both branches, so band weights cannot grow without bound
    /// over many reflections (a plain mean of s_b lets them, which made rare rays carry
    /// -20 dB of energy into the late decay).
    ///
    /// Then Russian roulette (Arvo and Kirk 1990): once the ray's strongest band is below
    /// `roulette_factor` of its launch energy (air losses left out: the least absorbed band
    /// loses well under 1 dB over any decay, so they would not change the test), it
    /// survives with probability q = that level / threshold and is scaled by 1 / q. The
    /// expected energy of every band is unchanged, so the decay is traced to its end without
    /// a cut-off, while the weak tail costs a few reflections a ray.
    #[inline(always)]
    fn interact(
        &self,
        acc: &mut TraceRecord,
        ray_state: &mut SoundRay,
        hit: &Hit,
        incoming: Vec3,
        path_m: f32,
        rng: &mut Rng64,
    ) -> Bounce {
        let surface = &self.surfaces[hit.surface as usize];
        let on_panel;
        let s = match (self.edge_scattering, hit.kind) {
            (Some(es), PrimitiveKind::Triangle) => {
                on_panel = es.scattering(
                    hit.primitive,
                    &surface.scattering,
                    incoming.dot(hit.normal).abs(),
                    hit.t,
                    None,
                );
                &on_panel
            }
            _ => &surface.scattering,
        };
        let a = &surface.absorption;
        // The eight bands as two 4-lane vectors; the sums add in a fixed order.
        let (e_lo, e_hi) = halves(&ray_state.energy);
        let (s_lo, s_hi) = halves(s);
        let (keep_lo, keep_hi) = halves(a);
        let (keep_lo, keep_hi) = (Vec4::ONE - keep_lo, Vec4::ONE - keep_hi);
        let (scattered_lo, scattered_hi) = (e_lo * s_lo, e_hi * s_hi);
        let (total, weighted) = (sum_halves(e_lo, e_hi), sum_halves(scattered_lo, scattered_hi));
        if weighted > 0.0
            && let Some(accel) = self.diffuse_rain
        {
            let scattered = join(scattered_lo, scattered_hi);
            self.rain(accel, acc, hit, &scattered, a, path_m);
        }
        let s_mean = if total > 0.0 { (weighted / total).clamp(0.0, 1.0) } else { 0.0 };
        let diffuse = s_mean > 0.0 && uniform(rng) < s_mean;
        let (mut lo, mut hi) = if diffuse {
            let k = Vec4::splat(1.0 / s_mean);
            (scattered_lo * keep_lo * k, scattered_hi * keep_hi * k)
        } else {
            let k = Vec4::splat(1.0 / (1.0 - s_mean));
            ((e_lo - scattered_lo) * keep_lo * k, (e_hi - scattered_hi) * keep_hi * k)
        };
        let level = lo.max(hi).max_element();
        let threshold = self.ray_energy_j * self.roulette_factor;
        // (A NaN level fails both tests and stops the ray.)
        if level.is_nan() || level < threshold {
            let survival = level / threshold;
            if survival.is_nan() || uniform(rng) >= survival {
                return Bounce::Stop;
            }
            let boost = Vec4::splat(1.0 / survival);
            (lo, hi) = (lo * boost, hi * boost);
        }
        ray_state.energy = join(lo, hi);
        ray_state.after_diffuse = diffuse;
        ray_state.bent_by = 0;
        if diffuse {
            ray_state.specular_order = None;
            let local = cosine_hemisphere(Vec2::new(uniform(rng), uniform(rng)));
            return Bounce::Continue(to_world(local, hit.facing_normal()).normalize());
        }
        ray_state.specular_order = match hit.kind {
            // A curved mirror has no image source, nor has a shape, a field or an instance (the image
            // sources see the scene's own mesh): the rays keep what they find.
            PrimitiveKind::Sphere | PrimitiveKind::Shape | PrimitiveKind::Sdf | PrimitiveKind::Instance => {
                None
            }
            PrimitiveKind::Triangle => ray_state.specular_order.map(|o| o + 1),
        };
        // The mirror direction is the same for either orientation of the normal.
        let n = hit.normal;
        Bounce::Continue((incoming - 2.0 * incoming.dot(n) * n).normalize())
    }
}

impl SoundPropagation<'_> {
    /// Diffuse rain (Schroeder, Physically based real-time auralization of interactive
    /// virtual environments, 2011, sec. 4.3; Heinz 1993): the energy `scattered[b] (1 - a_b)`
    /// that leaves the hit point diffusely radiates by Lambert's law, so a receiver sphere of
    /// radius r whose centre is at distance d in direction cos(theta) from the normal receives
    /// E cos(theta) Omega / pi, Omega = 2 pi (1 - cos(gamma)), sin(gamma) = r / d, spread over
    /// its cross-section pi r^2: the fluence E cos(theta) 2 (1 - cos(gamma)) / (pi r^2),
    /// E cos(theta) / (pi d^2) for a small receiver, exactly what the crossing rays of the
    /// diffuse branch would add in expectation. It arrives after the path plus d.
    fn rain(
        &self,
        accel: &Accel,
        acc: &mut TraceRecord,
        hit: &Hit,
        scattered: &BandValues,
        absorption: &BandValues,
        path_m: f32,
    ) {
        let n = hit.facing_normal();
        for (i, s) in self.receivers.iter().enumerate() {
            let to = s.center - hit.point;
            let d = to.length();
            if d <= s.radius_m {
                continue;
            }
            let cos_theta = n.dot(to) / d;
            if cos_theta <= 0.0 {
                continue;
            }
            let sin_gamma = s.radius_m / d;
            let one_minus_cos_gamma = sin_gamma * sin_gamma / (1.0 + (1.0 - sin_gamma * sin_gamma).sqrt());
            let fluence_per_j =
                cos_theta * 2.0 * one_minus_cos_gamma / (std::f32::consts::PI * s.radius_m * s.radius_m);
            let in_view = hit.kind == PrimitiveKind::Triangle
                && self
                    .rain_in_view
                    .get(i)
                    .and_then(Option::as_ref)
                    .and_then(|t| t.get(hit.primitive as usize))
                    .zip(part_of(hit.barycentric.x, hit.barycentric.y))
                    .is_some_and(|(mask, part)| mask >> part & 1 == 1);
            if !in_view {
                let mut shadow = Ray::spawn_to(hit.point, hit.normal, s.center);
                shadow.t_max = (shadow.t_max - s.radius_m).max(0.0);
                if accel.occluded(&shadow) {
                    continue;
                }
            }
            let Some(bin) = self.bins.bin_of_path(f64::from(path_m + d)) else { continue };
            let mut energy = [0.0; BAND_COUNT];
            for b in 0..BAND_COUNT {
                energy[b] = scattered[b] * (1.0 - absorption[b]) * fluence_per_j;
            }
            if let Some(Some(dir)) = self.receiver_directivity.get(i) {
                let w = dir.sensitivity(-to / d);
                energy = std::array::from_fn(|b| energy[b] * w[b]);
            }
            // The rain comes from the hit point.
            let direction = self.directions.map(|d| d.of(bin) * CELLS + cell_of(-to));
            acc.deposit(i, bin, &energy, direction);
        }
    }
}

/// Bands 0-3 and 4-7 of `v`.
#[inline(always)]
fn halves(v: &BandValues) -> (Vec4, Vec4) {
    (Vec4::new(v[0], v[1], v[2], v[3]), Vec4::new(v[4], v[5], v[6], v[7]))
}

/// The eight bands of two halves.
#[inline(always)]
fn join(lo: Vec4, hi: Vec4) -> BandValues {
    let (l, h) = (lo.to_array(), hi.to_array());
    [l[0], l[1], l[2], l[3], h[0], h[1], h[2], h[3]]
}

/// The sum of eight band values in a fixed order: ((v0 + v4) + (v2 + v6)) + ((v1 + v5) +
/// (v3 + v7)).
#[inline(always)]
fn sum_halves(lo: Vec4, hi: Vec4) -> f32 {
    let pairs = lo + hi;
    (pairs.x + pairs.z) + (pairs.y + pairs.w)
}
