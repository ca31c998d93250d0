//! Stochastic diffraction of rays that pass near a free edge, for the late part: the ray is
//! bent about the edge by a random angle whose spread grows as the ray passes closer, by the
//! uncertainty relation (Heinisch and Chou 1971; Freniere, Gregory and Hassler 1999,
//! \[Freniere1999\] in docs/references.md; in room acoustics, Stephenson's
//! uncertainty-relation based diffraction). docs/acoustics.md (Edge diffraction) gives the
//! model, its test against the exact half-plane and its cost.
//!
//! A ray passing an edge at distance `a` (measured across the edge) is confined, seen from
//! the edge, to a slit of width about `a`: its transverse wavenumber is uncertain by
//! `1 / (2a)`, so the tangent of its deflection angle about the edge is normal with standard
//! deviation `tan sigma = 1 / (2 k a)`, `k` the wavenumber across the edge (`k sin(beta)`
//! for a ray at angle `beta` to the edge; the component along the edge is kept, as on
//! Keller's cone).
//!
//! A ray carries eight bands but has one direction, and each band's spread differs: the
//! angle is drawn from the energy-weighted mixture of the bands' distributions, and each
//! band's energy is then weighed by its own density over the mixture's. Every band's
//! expected energy in every direction is exactly its own distribution's, and the ray's total
//! energy is unchanged (as for the scattering choice in [`super::tracer`]).

use glam::{DVec3, Vec2, Vec3};

use super::tracer::SoundRay;
use crate::core::TriangleMesh;
use crate::core::near_segments::{NearSegments, Segment};
use crate::core::ray::Ray;
use crate::core::rng::{Rng64, uniform};
use crate::core::sampling::standard_normal;
use crate::core::wedges::Wedge;
use crate::scene::materials::{BAND_COUNT, OCTAVE_BANDS_HZ};

/// A ray is bent by an edge it passes within this many wavelengths of the lowest band (63
/// Hz: 0.54 m): there that band's spread is `tan sigma = 1 / (4 pi REACH)`, 39 degrees, and
/// each higher band's is half the one below (125 Hz: 22, 250 Hz: 11, 1 kHz: 2.8 degrees).
/// The smaller bends of rays passing farther away are left out. The reach is what the
/// bending costs: in a small room with many edges most flights pass within a metre of one
/// (docs/acoustics.md, Edge diffraction, gives the cost).
pub const REACH_WAVELENGTHS: f32 = 0.1;

/// Bands whose spread at a pass is under this go on straight, unbent and unweighed: their
/// bends would be within a few degrees, and leaving them out of the weighing keeps their
/// variance low (a ray's high bands then never trade energy with its low ones there).
pub const NARROW_DEGREES: f32 = 2.0;

/// Bends smaller than this keep the ray on its line (they move it by under 9 mm a metre);
/// the bands' weights still change. It saves a trace for most of the high bands' bends.
pub const STRAIGHT_DEGREES: f32 = 0.5;

/// An edge bends a band only where the edge and both its faces are at least this many of
/// the band's wavelengths long (measured across the edge, on the triangle that meets it):
/// the uncertainty relation is a half-plane's, and an obstacle much smaller than the
/// wavelength barely disturbs the sound (a 10 cm beam does not bend 125 Hz, 2.7 m). It
/// also keeps tessellated small parts (window frames, radiators) from bending every
/// passing ray.
pub const SIZE_WAVELENGTHS: f64 = 0.5;

/// Wedges flatter than this (exterior angle over pi; 1.1: faces turning by less than 18
/// degrees, as on a tessellated curve) bend nothing: they cast no shadow for the bending
/// to fill, and the half-plane's spread would overstate their diffraction.
pub const FLAT_N: f64 = 1.1;

/// The edges that bend rays, and the bands' wavenumbers.
pub struct RayDiffraction {
    edges: NearSegments,
    /// Per edge, the lowest band it bends ([`SIZE_WAVELENGTHS`]).
    first_band: Vec<u8>,
    /// Wavenumber per band, rad/m.
    k_per_m: [f32; BAND_COUNT],
    /// Flights before this many reflections are left alone: with the deterministic edge
    /// paths on, the direct sound's diffraction is theirs ([`super::diffraction`]).
    pub from_reflection: u32,
    /// Copies a launched ray's bends may make, all together ([`COPIES`]).
    pub copies: u32,
}

/// The default [`RayDiffraction::copies`]: a bend that parts a ray's bands (some bent, some
/// straight) makes a copy for one part while the ray has copies left (each part takes half
/// of what is left); after that, the ray follows one part at even odds, with twice that
/// part's energy (unbiased per band; even odds bound every band's weight by 2, where odds by
/// energy share let a weak part come back ten times stronger). A copy keeps the bands'
/// variance low but costs a ray's whole later life; docs/acoustics.md (Edge diffraction)
/// gives the trade.
pub const COPIES: u32 = 2;

impl RayDiffraction {
    /// Rays near `wedges` (the room's free edges, [`super::diffraction::room_edges`], whose
    /// triangles index `mesh`), for sound at `speed_of_sound_m_s`; `None` when none of them
    /// is large enough to bend any band ([`SIZE_WAVELENGTHS`], [`FLAT_N`]).
    pub fn new(
        wedges: &[Wedge],
        mesh: &TriangleMesh,
        speed_of_sound_m_s: f64,
        from_reflection: u32,
    ) -> Option<Self> {
        let k_per_m = std::array::from_fn(|b| {
            (2.0 * std::f64::consts::PI * f64::from(OCTAVE_BANDS_HZ[b]) / speed_of_sound_m_s) as f32
        });
        let wavelength_m = |b: usize| speed_of_sound_m_s / f64::from(OCTAVE_BANDS_HZ[b]);
        let reach_63_m = f64::from(REACH_WAVELENGTHS) * wavelength_m(0);
        let narrow = f64::from(NARROW_DEGREES.to_radians().tan());
        let mut segments = Vec::new();
        let mut first_band = Vec::new();
        for w in wedges {
            let size_m = edge_size_m(w, mesh);
            let Some(first) = (0..BAND_COUNT).find(|&b| size_m >= SIZE_WAVELENGTHS * wavelength_m(b)) else {
                continue;
            };
            if w.n < FLAT_N {
                continue;
            }
            // Out to where the lowest band it bends turns narrow, at most the 63 Hz reach, and
            // no farther than the edge's own size: a ray that far from a small part does not
            // see a half-plane.
            let narrow_m = 1.0 / (2.0 * f64::from(k_per_m[first]) * narrow);
            segments.push(Segment {
                start: w.start.as_vec3(),
                dir: (w.end - w.start).normalize_or(DVec3::X).as_vec3(),
                length_m: w.length as f32,
                reach_m: reach_63_m.min(narrow_m).min(size_m) as f32,
            });
            first_band.push(first as u8);
        }
        if segments.is_empty() {
            return None;
        }
        Some(Self {
            edges: NearSegments::new(segments),
            first_band,
            k_per_m,
            from_reflection,
            copies: COPIES,
        })
    }

    /// The edges that bend rays (of those given to [`Self::new`]).
    pub fn edge_count(&self) -> usize {
        self.first_band.len()
    }

    /// Bends `sound`, flying along `ray` for `length_m`, at the edge it passes closest to,
    /// or `None` if it passes none within reach (or was already bent since its last
    /// reflection). The bands whose spread there is under [`NARROW_DEGREES`] go on straight,
    /// unchanged; the others are bent together (module docs), as a copy of the ray when the
    /// straight part is not empty.
    pub fn deflect(
        &self,
        sound: &SoundRay,
        ray: &Ray,
        length_m: f32,
        reflections: u32,
        rng: &mut Rng64,
    ) -> Option<Bent> {
        if reflections < self.from_reflection || sound.bent_by != 0 {
            return None;
        }
        let pass = self.edges.closest_pass(ray, length_m)?;
        // Each band's spread (the tangent's standard deviation).
        let spread: [f64; BAND_COUNT] = std::array::from_fn(|b| {
            1.0 / (2.0 * f64::from(self.k_per_m[b]) * f64::from(pass.sin_beta) * f64::from(pass.distance_m))
        });
        let narrow = f64::from(NARROW_DEGREES.to_radians().tan());
        let first = usize::from(self.first_band[pass.segment]);
        let wide: [f32; BAND_COUNT] =
            std::array::from_fn(|b| if b >= first && spread[b] >= narrow { sound.energy[b] } else { 0.0 });
        let total: f32 = wide.iter().sum();
        if total.is_nan() || total <= 0.0 {
            return None;
        }
        // A band by its share of the energy, then a tangent from its distribution.
        let pick = uniform(rng) * total;
        let mut band = BAND_COUNT - 1;
        let mut acc = 0.0;
        for (b, e) in wide.iter().enumerate() {
            acc += e;
            if pick < acc {
                band = b;
                break;
            }
        }
        let tangent = spread[band] * f64::from(standard_normal(Vec2::new(uniform(rng), uniform(rng))));
        // Each band's density at that tangent (the common 1 / sqrt(2 pi) left out).
        let density: [f64; BAND_COUNT] =
            std::array::from_fn(|b| (-0.5 * (tangent / spread[b]).powi(2)).exp() / spread[b]);
        let mixture: f64 =
            wide.iter().zip(&density).map(|(e, p)| f64::from(*e) * p).sum::<f64>() / f64::from(total);
        if mixture.is_nan() || mixture <= 0.0 {
            return None;
        }
        let energy = std::array::from_fn(|b| (f64::from(wide[b]) * density[b] / mixture) as f32);
        // Turn the direction about the edge by atan(tangent): the part along it is kept.
        let e = self.edges.segments()[pass.segment].dir;
        let along = ray.dir.dot(e) * e;
        let across = ray.dir - along;
        let angle = tangent.atan() as f32;
        let (sin, cos) = angle.sin_cos();
        let dir = (angle.abs() >= STRAIGHT_DEGREES.to_radians())
            .then(|| (along + cos * across + sin * e.cross(across)).normalize());
        let part = |energy| SoundRay {
            energy,
            specular_order: None,
            after_diffuse: false,
            bent_by: pass.segment as u32 + 1,
            copies_left: sound.copies_left,
            bend_copies_left: sound.bend_copies_left,
        };
        let narrow: [f32; BAND_COUNT] = std::array::from_fn(|b| sound.energy[b] - wide[b]);
        if dir.is_none() {
            // Both parts keep the line: one ray carries them.
            let whole = std::array::from_fn(|b| energy[b] + narrow[b]);
            return Some(Bent { at_m: pass.at_m, dir, bent: part(whole), straight: None });
        }
        // The straight part is the ray as it was, but for the bands that left it.
        let straight = SoundRay {
            specular_order: sound.specular_order,
            after_diffuse: sound.after_diffuse,
            ..part(narrow)
        };
        let straight_j: f32 = narrow.iter().sum();
        if straight_j <= 0.0 {
            return Some(Bent { at_m: pass.at_m, dir, bent: part(energy), straight: None });
        }
        if sound.bend_copies_left >= 2 {
            // Both parts go on, each with half the copies left.
            let half = sound.bend_copies_left / 2;
            let bent = SoundRay { bend_copies_left: half, ..part(energy) };
            let straight = SoundRay { bend_copies_left: sound.bend_copies_left - half, ..straight };
            return Some(Bent { at_m: pass.at_m, dir, bent, straight: Some(straight) });
        }
        // One part, at even odds, carrying twice its energy.
        if uniform(rng) < 0.5 {
            let bent = SoundRay { energy: energy.map(|e| 2.0 * e), ..part(energy) };
            Some(Bent { at_m: pass.at_m, dir, bent, straight: None })
        } else {
            let kept = SoundRay { energy: narrow.map(|e| 2.0 * e), ..straight };
            Some(Bent { at_m: pass.at_m, dir: None, bent: kept, straight: None })
        }
    }
}

/// The smallest of `wedge`'s length and its faces' depths across it (each face's depth: how
/// far its triangle on the edge reaches from the edge's line), metres.
fn edge_size_m(wedge: &Wedge, mesh: &TriangleMesh) -> f64 {
    let mut size_m = wedge.length;
    for (face, dir) in wedge.triangles.iter().zip(wedge.face_dirs) {
        if (*face as usize) >= mesh.triangle_count() {
            return 0.0;
        }
        let depth_m = mesh
            .corners(*face as usize)
            .iter()
            .map(|c| (c.as_dvec3() - wedge.start).dot(dir))
            .fold(0.0, f64::max);
        size_m = size_m.min(depth_m);
    }
    size_m
}

/// A ray bent at an edge ([`RayDiffraction::deflect`]).
pub struct Bent {
    /// Where along the ray, metres.
    pub at_m: f32,
    /// The bent part's new direction (`None`: its bend is under [`STRAIGHT_DEGREES`] and it
    /// keeps the line).
    pub dir: Option<Vec3>,
    /// The bent part: the wide bands, weighed.
    pub bent: SoundRay,
    /// The part that goes on straight, unchanged (the narrow bands), if any.
    pub straight: Option<SoundRay>,
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rng::stream;

    fn one_edge() -> RayDiffraction {
        let edge =
            Segment { start: Vec3::new(0.0, 0.0, -10.0), dir: Vec3::Z, length_m: 20.0, reach_m: 100.0 };
        RayDiffraction {
            edges: NearSegments::new(vec![edge]),
            first_band: vec![0],
            copies: COPIES,
            k_per_m: std::array::from_fn(|b| 2.0 * std::f32::consts::PI * OCTAVE_BANDS_HZ[b] / 343.0),
            from_reflection: 0,
        }
    }

    fn sound(energy: [f32; BAND_COUNT]) -> SoundRay {
        SoundRay {
            energy,
            specular_order: Some(0),
            after_diffuse: false,
            bent_by: 0,
            copies_left: 1,
            bend_copies_left: COPIES,
        }
    }

    #[test]
    fn each_band_spreads_as_the_uncertainty_relation_says_and_keeps_its_energy() {
        // Rays across the edge at 0.05 m: the mean of each band's weighted tangent^2 is its
        // spread^2 = 1 / (2 k a)^2, and the mean weight is 1 (energy kept per band). (Bends
        // under half a degree keep the line; they add under 0.1 % to the highest band's.)
        let rd = one_edge();
        let ray = Ray::new(Vec3::new(-5.0, 0.05, 0.0), Vec3::X);
        let n = 200_000;
        let mut weight = [0.0f64; BAND_COUNT];
        let mut tan2 = [0.0f64; BAND_COUNT];
        for i in 0..n {
            let mut rng = stream(3, 0, i);
            let b = rd.deflect(&sound([1.0; BAND_COUNT]), &ray, 10.0, 0, &mut rng).unwrap();
            let (at, dir, bent) = (b.at_m, b.dir.unwrap_or(ray.dir), b.bent);
            assert!(b.straight.is_none(), "every band is wide 0.05 m from the edge");
            assert!((at - 5.0).abs() < 1e-4 && (dir.length() - 1.0).abs() < 1e-5 && dir.z.abs() < 1e-6);
            assert!((bent.energy.iter().sum::<f32>() - 8.0).abs() < 1e-3, "the total is kept");
            let t = f64::from(dir.y / dir.x);
            for b in 0..BAND_COUNT {
                weight[b] += f64::from(bent.energy[b]);
                tan2[b] += f64::from(bent.energy[b]) * t * t;
            }
        }
        for b in 0..BAND_COUNT {
            let expect = 1.0 / (2.0 * f64::from(rd.k_per_m[b]) * 0.05);
            let (w, s) = (weight[b] / n as f64, (tan2[b] / weight[b]).sqrt());
            assert!((w - 1.0).abs() < 0.03, "band {b}: mean weight {w}");
            assert!((s / expect - 1.0).abs() < 0.05, "band {b}: spread {s} vs {expect}");
        }
    }

    #[test]
    fn a_slanted_ray_keeps_its_part_along_the_edge() {
        let rd = one_edge();
        let dir = Vec3::new(1.0, 0.0, 1.0).normalize();
        let ray = Ray::new(Vec3::new(-2.0, 0.2, -2.0), dir);
        let mut rng = stream(1, 0, 0);
        let b = rd.deflect(&sound([1.0; BAND_COUNT]), &ray, 10.0, 0, &mut rng).unwrap();
        assert!((b.dir.unwrap_or(dir).z - dir.z).abs() < 1e-6);
        // 2 m from the edge the bands from 500 Hz up are narrow (spread 1.6 degrees at 500
        // Hz) and go on straight, unweighed.
        let far = Ray::new(Vec3::new(-2.0, 2.0, 0.0), Vec3::X);
        let b = rd.deflect(&sound([1.0; BAND_COUNT]), &far, 10.0, 0, &mut rng).unwrap();
        let straight = b.straight.unwrap();
        assert_eq!(straight.energy, [0.0, 0.0, 0.0, 1.0, 1.0, 1.0, 1.0, 1.0]);
        assert!(b.bent.energy[3..].iter().all(|e| *e == 0.0));
        assert!((b.bent.energy.iter().sum::<f32>() - 3.0).abs() < 1e-4);
        // Once bent, not again before a reflection; nor before `from_reflection`.
        let bent = SoundRay { bent_by: 1, ..sound([1.0; BAND_COUNT]) };
        assert!(rd.deflect(&bent, &ray, 10.0, 0, &mut rng).is_none());
        let later = RayDiffraction { from_reflection: 1, ..one_edge() };
        assert!(later.deflect(&sound([1.0; BAND_COUNT]), &ray, 10.0, 0, &mut rng).is_none());
    }
    /// The free edges of `mesh` and the bending built on them.
    fn bending_of(mesh: &TriangleMesh) -> Option<RayDiffraction> {
        use crate::core::accel::{Accel, BuildQuality};
        use crate::core::wedges::{extract_wedges, free_wedges};
        let accel = Accel::build(mesh, Vec::new(), BuildQuality::default());
        RayDiffraction::new(&free_wedges(&accel, &extract_wedges(mesh)), mesh, 343.0, 0)
    }

    #[test]
    fn a_beam_small_against_the_wavelength_bends_only_the_high_bands() {
        // A beam 10 cm x 20 cm x 4 m: its long edges' faces are 10 and 20 cm deep, half a
        // wavelength of 1.7 kHz at 10 cm, so only 2 kHz and up bend, and only within 10 cm.
        let mut mesh = TriangleMesh::default();
        let s = mesh.surface_id("beam");
        mesh.push_box(Vec3::new(0.0, 0.0, -2.0), Vec3::new(0.1, 0.2, 2.0), 1, s);
        let rd = bending_of(&mesh).unwrap();
        assert_eq!(rd.edge_count(), 12, "four long edges and eight ends (10 and 20 cm)");
        // A ray along x, 5 cm beside the edge at x = 0.1, y = 0.2 (between its faces' planes).
        let ray = Ray::new(Vec3::new(-3.0, 0.25, 0.0), Vec3::X);
        let mut rng = stream(4, 0, 0);
        let b = rd.deflect(&sound([1.0; BAND_COUNT]), &ray, 6.0, 0, &mut rng).unwrap();
        let bands_bent: Vec<bool> = (0..BAND_COUNT).map(|i| b.bent.energy[i] != 0.0).collect();
        assert_eq!(bands_bent, [false, false, false, false, false, true, true, true], "{:?}", b.bent.energy);
        assert_eq!(b.straight.map(|s| s.energy), Some([1.0, 1.0, 1.0, 1.0, 1.0, 0.0, 0.0, 0.0]));
        // 15 cm beside it, beyond the beam's own size: no bend.
        let far = Ray::new(Vec3::new(-3.0, 0.35, 0.0), Vec3::X);
        assert!(rd.deflect(&sound([1.0; BAND_COUNT]), &far, 6.0, 0, &mut rng).is_none());
        // A big box's edges bend every band, out to the 63 Hz reach (0.54 m).
        let mut big = TriangleMesh::default();
        let s = big.surface_id("block");
        big.push_box(Vec3::new(0.0, 0.0, -5.0), Vec3::new(4.0, 4.0, 5.0), 1, s);
        let rd = bending_of(&big).unwrap();
        let ray = Ray::new(Vec3::new(-3.0, 4.5, 0.0), Vec3::X);
        let b = rd.deflect(&sound([1.0; BAND_COUNT]), &ray, 10.0, 0, &mut rng).unwrap();
        assert!(b.bent.energy[0] > 0.0 && b.bent.energy[1] > 0.0, "{:?}", b.bent.energy);
    }

    #[test]
    fn a_nearly_flat_crease_bends_nothing() {
        // Two 4 m panels meeting at 170 degrees (a crease of 10 degrees: n = 1.056 on its
        // convex side).
        let mut mesh = TriangleMesh::default();
        let s = mesh.surface_id("panel");
        let bend = 10f32.to_radians();
        let (a, b) = (Vec3::new(-4.0, 0.0, 0.0), Vec3::new(4.0 * bend.cos(), 4.0 * bend.sin(), 0.0));
        let z = Vec3::Z * 4.0;
        mesh.push_quad(a, Vec3::ZERO, Vec3::ZERO + z, a + z, s);
        mesh.push_quad(Vec3::ZERO, b, b + z, Vec3::ZERO + z, s);
        let accel = crate::core::accel::Accel::build(&mesh, Vec::new(), Default::default());
        let wedges = crate::core::wedges::free_wedges(&accel, &crate::core::wedges::extract_wedges(&mesh));
        let crease: Vec<&Wedge> = wedges.iter().filter(|w| w.n < FLAT_N).collect();
        assert_eq!(crease.len(), 1, "the crease is found as a wedge, on one side");
        let rd = RayDiffraction::new(&wedges, &mesh, 343.0, 0).unwrap();
        // The panels' rims still bend; a ray passing just over the crease does not.
        assert_eq!(rd.edge_count(), wedges.len() - 1);
        let over = Ray::new(Vec3::new(-1.0, 0.05, 2.0), Vec3::X);
        let mut rng = stream(2, 0, 0);
        assert!(rd.deflect(&sound([1.0; BAND_COUNT]), &over, 2.0, 0, &mut rng).is_none());
    }

    #[test]
    fn without_copies_a_bend_follows_one_part_and_keeps_each_band_in_expectation() {
        // 2 m from the edge the bands from 500 Hz up are narrow: with no copies left, the
        // ray follows the bent part (63-250 Hz) or the straight one at even odds, with twice
        // its energy; each band's mean over many bends is its energy before, and no band
        // ever carries more than twice it.
        let rd = one_edge();
        let far = Ray::new(Vec3::new(-2.0, 2.0, 0.0), Vec3::X);
        let before = [4.0, 2.0, 1.0, 1.0, 0.5, 0.5, 0.25, 0.25];
        let n = 100_000;
        let (mut mean, mut turned, mut chosen) = ([0.0f64; BAND_COUNT], 0, 0);
        for i in 0..n {
            let mut rng = stream(8, 0, i);
            let ray = SoundRay { bend_copies_left: 1, ..sound(before) };
            let b = rd.deflect(&ray, &far, 10.0, 0, &mut rng).unwrap();
            assert!(b.straight.is_none(), "no copy without copies left");
            let total: f32 = b.bent.energy.iter().sum();
            let (low, high) = (b.bent.energy[0] > 0.0, b.bent.energy[3] > 0.0);
            // A bend under half a degree keeps the line: one ray carries both parts, as
            // they were (no choice to make).
            let expect = match (low, high) {
                (true, true) => 9.5,
                (true, false) => 14.0,
                _ => 5.0,
            };
            assert!(!(low && high) || b.dir.is_none(), "both parts on one ray only on the line");
            assert!((total - expect).abs() < 1e-3, "twice the part's 7 or 2.5 J, or 9.5 J: {total}");
            if low != high {
                chosen += 1;
                turned += usize::from(low);
            }
            for (m, e) in mean.iter_mut().zip(b.bent.energy) {
                *m += f64::from(e) / n as f64;
            }
            // The narrow bands are never weighed: left out, doubled, or kept as they were.
            let factor = if low && high { 1.0 } else { 2.0 };
            assert!(b.bent.energy[3..].iter().zip(&before[3..]).all(|(e, b)| *e == 0.0 || *e == factor * b));
        }
        for (b, (m, e)) in mean.iter().zip(before).enumerate() {
            assert!((m / f64::from(e) - 1.0).abs() < 0.03, "band {b}: mean {m} vs {e}");
        }
        let share = turned as f64 / chosen as f64;
        assert!(chosen > n / 2 && (share - 0.5).abs() < 0.01, "followed the bent part {share} of {chosen}");
    }
}
