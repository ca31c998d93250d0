//! First-order edge diffraction of the direct sound, for the deterministic early part: the
//! path source -> a point Q of a free edge -> receiver, with Q given by Keller's law, weighed
//! by the uniform theory of diffraction's coefficient of the wedge (Kouyoumjian and Pathak,
//! \[Kouyoumjian1974\] in docs/references.md; for sound, Tsingos et al. 2001,
//! \[Tsingos2001\]), averaged in energy over each octave band. docs/acoustics.md (Edge
//! diffraction) gives why UTD and not BTM, and how well it matches the exact half-plane.
//!
//! The diffracted pressure at the receiver, for a source whose free-field pressure is
//! `e^{-jkr} / r`, is
//!
//! ```text
//! p_d = e^{-jks'} / s' * D(k) * sqrt(s' / (s (s + s'))) * e^{-jks}
//! ```
//!
//! with `s' = |Q - S|`, `s = |R - Q|` and `D` the wedge's coefficient ([`crate::core::utd`])
//! whose two reflection terms carry the faces' pressure reflection factors `sqrt(1 - a)` (1
//! on a rigid face). Its energy per joule, `<|p_d|^2> / (4 pi)` over the band, joins the
//! image sources at the arrival time `(s + s') / c`, with the air's attenuation over
//! `s + s'` and the source's directivity towards Q.
//!
//! Where the receiver also hears the direct sound and the two paths differ by less than two
//! periods of the band's width, the two are summed coherently: the cross term
//! `<2 Re(p p_d*)> / (4 pi)` goes to the diffracted arrival (to the direct sound where that
//! would make the diffracted energy negative), so the total is continuous across the shadow
//! boundary, where the direct sound stops and the diffraction takes over at half its
//! pressure.

use glam::{DVec3, Vec3};

use super::directivity::Directivity;
use super::image_source::Arrival;
use super::tracer::SurfaceAcoustics;
use crate::core::complex::Complex;
use crate::core::utd::WedgeTerms;
use crate::core::wedges::{Wedge, clear_of_edge, extract_wedges, free_wedges};
use crate::core::{Accel, TriangleMesh};
use crate::scene::World;
use crate::scene::materials::{BAND_COUNT, BandValues, OCTAVE_BANDS_HZ};

/// The free edges of the room in `world` that sound can diffract at: the core's free wedges
/// ([`crate::core::wedges::free_wedges`]) whose exterior, just off the middle of the edge, is
/// the room's air. A closed room's own corners are concave seen from its air and have none.
/// `accel` and `mesh` are the world's own, or its [`crate::scene::FlatGeometry`] when it has
/// instances (the wedges then index the flattened mesh's triangles).
pub fn room_edges(world: &World, accel: &Accel, mesh: &TriangleMesh) -> Vec<Wedge> {
    free_wedges(accel, &extract_wedges(mesh))
        .into_iter()
        .filter(|w| {
            let mid = w.at(0.5 * w.length);
            let probe =
                mid + (0.01f64).min(0.1 * w.length) * w.direction_at(0.5 * w.n * std::f64::consts::PI);
            world.is_inside(probe.as_vec3()) != Some(false)
        })
        .collect()
}

/// Frequencies sampled per octave band for its energy average.
pub const FREQUENCIES_PER_BAND: usize = 16;

/// Above this many periods of the band's width in the path difference, the direct and the
/// diffracted sound are taken as incoherent (their cross term averages out over the band).
pub const COHERENT_PERIODS: f64 = 2.0;

/// The frequencies at which band `band`'s energy is averaged, Hz: the centres (in log) of
/// [`FREQUENCIES_PER_BAND`] equal parts of the octave.
pub fn band_frequencies_hz(band: usize) -> [f64; FREQUENCIES_PER_BAND] {
    let centre = f64::from(OCTAVE_BANDS_HZ[band.min(BAND_COUNT - 1)]);
    std::array::from_fn(|i| centre * 2f64.powf((i as f64 + 0.5) / FREQUENCIES_PER_BAND as f64 - 0.5))
}

/// A diffracted path with its complex pressure per band and sampled frequency (for the
/// coherent sum with the direct sound).
struct EdgePath {
    arrival: Arrival,
    pressure: [[Complex; FREQUENCIES_PER_BAND]; BAND_COUNT],
}

/// The diffracted arrival over `wedge` from `source` to `receiver`, `None` when either is
/// not in the wedge's exterior, Keller's point is off the edge, or something blocks a leg.
fn edge_path(
    accel: &Accel,
    wedge: &Wedge,
    surfaces: &[SurfaceAcoustics],
    air_per_m: &BandValues,
    speed_m_s: f64,
    (source, directivity): (DVec3, &Directivity),
    receiver: DVec3,
) -> Option<EdgePath> {
    let (phi_p, _) = wedge.azimuth(source)?;
    let (phi, _) = wedge.azimuth(receiver)?;
    if !(wedge.in_exterior(phi_p) && wedge.in_exterior(phi)) {
        return None;
    }
    let q = wedge.at(wedge.keller_point(source, receiver)?);
    let (incident, outgoing) = (q - source, receiver - q);
    let (s_p, s) = (incident.length(), outgoing.length());
    if !(s_p > 1.0e-6 && s > 1.0e-6 && s_p.is_finite() && s.is_finite()) {
        return None;
    }
    let sin_beta0 = wedge.edge.cross(incident / s_p).length();
    if sin_beta0.is_nan() || sin_beta0 <= 1.0e-6 {
        return None;
    }
    if !(clear_of_edge(accel, q, source) && clear_of_edge(accel, q, receiver)) {
        return None;
    }
    let length_m = s_p + s;
    let l = s * s_p / length_m * sin_beta0 * sin_beta0;
    let spread = (s_p / (s * length_m)).sqrt() / s_p;
    let emitted = incident / s_p;
    let weight = directivity.energy_weights(emitted.as_vec3());
    let reflection = |face: usize, b: usize| {
        let a = surfaces.get(wedge.surfaces[face] as usize).map_or(1.0, |x| f64::from(x.absorption[b]));
        Complex::new((1.0 - a).clamp(0.0, 1.0).sqrt(), 0.0)
    };
    let mut pressure = [[Complex::ZERO; FREQUENCIES_PER_BAND]; BAND_COUNT];
    let mut energy = [0.0; BAND_COUNT];
    for (b, (p_band, e)) in pressure.iter_mut().zip(&mut energy).enumerate() {
        let (r0, rn) = (reflection(0, b), reflection(1, b));
        let amplitude =
            f64::from(weight[b]).sqrt() * (-0.5 * f64::from(air_per_m[b]) * length_m).exp() * spread;
        let mut sum = 0.0;
        for (p, f) in p_band.iter_mut().zip(band_frequencies_hz(b)) {
            let k = std::f64::consts::TAU * f / speed_m_s;
            let d = WedgeTerms::new(wedge.n, phi, phi_p, k, l, sin_beta0).coefficient(r0, rn);
            *p = (d * Complex::cis(-k * length_m)).scale(amplitude);
            sum += p.norm_sqr();
        }
        *e = sum / (FREQUENCIES_PER_BAND as f64 * 4.0 * std::f64::consts::PI);
    }
    if !energy.iter().all(|e| e.is_finite()) {
        return None;
    }
    let incoming = (q - receiver) / s;
    Some(EdgePath {
        arrival: Arrival {
            length_m,
            order: 1,
            energy,
            emitted: emitted.to_array(),
            incoming: incoming.to_array(),
            diffracted: true,
        },
        pressure,
    })
}

/// The first-order diffracted arrivals over `wedges` (the free edges of the room,
/// [`crate::core::wedges::free_wedges`]) from a source to a receiver, energies per joule of
/// source energy as for image sources ([`Arrival::energy`]), in the wedges' order. `direct`
/// is the direct sound when the receiver hears it: its energy takes its share of the
/// coherent cross terms (see the module doc). `surfaces` gives the faces' absorption,
/// `air_per_m` the air's energy attenuation per band.
#[allow(clippy::too_many_arguments)]
pub fn edge_arrivals(
    accel: &Accel,
    wedges: &[Wedge],
    surfaces: &[SurfaceAcoustics],
    air_per_m: &BandValues,
    speed_m_s: f64,
    (source, directivity): (Vec3, &Directivity),
    receiver: Vec3,
    mut direct: Option<&mut Arrival>,
) -> Vec<Arrival> {
    let (src, rcv) = (source.as_dvec3(), receiver.as_dvec3());
    let mut out = Vec::new();
    for wedge in wedges {
        let Some(mut path) = edge_path(accel, wedge, surfaces, air_per_m, speed_m_s, (src, directivity), rcv)
        else {
            continue;
        };
        if let Some(direct) = direct.as_deref_mut() {
            add_cross_terms(direct, &mut path, speed_m_s);
        }
        out.push(path.arrival);
    }
    out
}

/// Moves the cross terms of the coherent sum of `direct` and `path` into their energies
/// (see the module doc).
fn add_cross_terms(direct: &mut Arrival, path: &mut EdgePath, speed_m_s: f64) {
    let r = direct.length_m;
    let difference_m = path.arrival.length_m - r;
    for b in 0..BAND_COUNT {
        let f = band_frequencies_hz(b);
        let width_hz = f[FREQUENCIES_PER_BAND - 1] - f[0];
        if difference_m * width_hz / speed_m_s > COHERENT_PERIODS || direct.energy[b] <= 0.0 {
            continue;
        }
        // The direct pressure's modulus from its energy (which carries the directivity and
        // the air), its phase from its length.
        let modulus = (direct.energy[b] * 4.0 * std::f64::consts::PI).sqrt();
        let mut cross = 0.0;
        for (p_d, f) in path.pressure[b].iter().zip(f) {
            let k = std::f64::consts::TAU * f / speed_m_s;
            let p = Complex::cis(-k * r).scale(modulus);
            cross += 2.0 * (p * p_d.conj()).re;
        }
        cross /= FREQUENCIES_PER_BAND as f64 * 4.0 * std::f64::consts::PI;
        let diffracted = path.arrival.energy[b] + cross;
        if diffracted >= 0.0 {
            path.arrival.energy[b] = diffracted;
        } else {
            path.arrival.energy[b] = 0.0;
            direct.energy[b] = (direct.energy[b] + diffracted).max(0.0);
        }
    }
}
