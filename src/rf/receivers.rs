//! Coherent point receivers: the exact specular paths from a transmitter to a point, found
//! by the image method (Allen & Berkley 1979 for rooms; the classic two-ray and multi-ray
//! models of radio propagation), each validated by tracing it through the scene, and summed
//! with their phase.
//!
//! The paths come from the core's specular-path engine ([`crate::core::specular`], the same
//! paths the acoustic image sources use): every sequence of up to `max_depth` planes of the
//! mesh, kept only if every leg reaches the next reflection point inside a triangle of that
//! plane, unobstructed by the mesh or a sphere. The field of a path of length `L` is
//! `h = (lambda / 4 pi L) e^{-j 2 pi L / lambda} (prod of reflection dyads) e_tx sqrt(G_tx)`,
//! a complex vector; the coherent path gain is `|sum h|^2` (an isotropic receiver taking all
//! polarisations), the incoherent one `sum |h|^2`.
//!
//! Each path is also kept as a [`PathRecord`] for the channel impulse response: its delay
//! `tau = L / c`, its complex amplitude `a = e_rx . h` at a receiver polarised like the
//! transmitter's antenna, its angles of departure and arrival and its interactions
//! (docs/radio.md, sec. 3).

use glam::DVec3;

use super::antenna::Antenna;
use super::fresnel::{C0, Complex};
use super::propagation::{FieldVec, LocalBasis, SurfacePhysics};
use crate::core::Accel;
use crate::core::specular::{Planes, SpecularPath, specular_paths};

/// The sum of the exact paths at one receiver.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PathSum {
    /// Valid paths found (line of sight counts as one).
    pub paths: usize,
    /// Interactions of each path (its reflections; 1 for an edge diffraction), in the order
    /// found.
    pub path_orders: Vec<usize>,
    /// Length of each path, metres, in the same order.
    pub path_lengths_m: Vec<f64>,
    /// Whether the direct path is unobstructed.
    pub line_of_sight: bool,
    /// `|sum h|^2`, linear.
    pub coherent_gain: f64,
    /// `sum |h|^2`, linear.
    pub incoherent_gain: f64,
    /// Every path, in the order found.
    pub records: Vec<PathRecord>,
}

/// What a path does at one of its points.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Interaction {
    /// A specular reflection on this surface (`SurfaceId`).
    Reflection {
        /// The surface (`SurfaceId`).
        surface: u32,
    },
    /// A first-order edge diffraction on the wedge between these surfaces (face 0, face n;
    /// the same twice on a rim), see [`crate::rf::diffraction`].
    Diffraction {
        /// The surfaces of face 0 and face n (`SurfaceId`).
        surfaces: [u32; 2],
    },
}

/// One path of a channel impulse response (docs/radio.md, sec. 3).
#[derive(Clone, Debug, PartialEq)]
pub struct PathRecord {
    /// Length, metres.
    pub length_m: f64,
    /// Propagation delay `L / c0`, seconds.
    pub delay_s: f64,
    /// The field vector `h` at the receiver (phase at the carrier included).
    pub field: FieldVec,
    /// The complex amplitude `a = e_rx . h`, with `e_rx` the transmitter antenna's
    /// polarisation in the direction the wave travels at the receiver (a co-polarised
    /// isotropic receiver); `|a|^2` is the path's gain.
    pub amplitude: Complex,
    /// Unit direction in which the path leaves the transmitter.
    pub departure: DVec3,
    /// Unit direction from the receiver towards the point the path arrives from.
    pub arrival: DVec3,
    /// The interactions, first (nearest the transmitter) first.
    pub interactions: Vec<Interaction>,
}

impl PathRecord {
    /// Path gain `|a|^2`, linear.
    pub fn gain(&self) -> f64 {
        self.amplitude.norm_sqr()
    }
}

/// Azimuth (from +x towards +y, in (-180, 180]) and zenith (from +z, in [0, 180]) of the
/// unit vector `d`, degrees: the angle convention of Sionna RT and 3GPP TR 38.901 sec. 7.1
/// (docs/radio.md, sec. 3).
pub fn azimuth_zenith_deg(d: DVec3) -> (f64, f64) {
    let azimuth = d.y.atan2(d.x).to_degrees();
    // atan2 gives -180 for y = -0: the same direction as +180.
    (if azimuth <= -180.0 { azimuth + 360.0 } else { azimuth }, d.z.clamp(-1.0, 1.0).acos().to_degrees())
}

/// Sums the specular paths of up to `max_depth` reflections (lowered in large meshes, see
/// [`crate::core::specular::affordable_order`]) from `tx` (with `antenna`) to `rx`.
pub fn coherent_paths(
    accel: &Accel,
    planes: &Planes,
    physics: &SurfacePhysics,
    antenna: &Antenna,
    tx: DVec3,
    rx: DVec3,
    max_depth: u32,
) -> PathSum {
    let mut out = PathSum::default();
    let mut total = FieldVec::default();
    for path in specular_paths(accel, planes, tx, rx, max_depth) {
        if let Some(h) = path_field(&path, physics, antenna) {
            out.paths += 1;
            out.path_orders.push(path.order());
            out.path_lengths_m.push(path.length_m);
            out.line_of_sight |= path.order() == 0;
            out.incoherent_gain += h.power();
            total = total.add(&h);
            let points = path.points();
            let n = points.len();
            let departure = (points[1] - points[0]).normalize();
            let travel = (points[n - 1] - points[n - 2]).normalize();
            let e_rx = antenna.polarization(travel);
            out.records.push(PathRecord {
                length_m: path.length_m,
                delay_s: path.length_m / C0,
                field: h,
                amplitude: h.along(e_rx),
                departure,
                arrival: -travel,
                interactions: path
                    .reflections
                    .iter()
                    .map(|r| Interaction::Reflection { surface: r.surface })
                    .collect(),
            });
        }
    }
    out.coherent_gain = total.power();
    out
}

/// The field at the receiver of `path`: the antenna's field along the first leg, reflected
/// at each point with the Fresnel coefficients of its surface at its incidence angle (times
/// `sqrt(1 - S^2)` on a scattering surface), times
/// the free-space factor of the whole length; `None` when a surface has no radio data.
fn path_field(path: &SpecularPath, physics: &SurfacePhysics, antenna: &Antenna) -> Option<FieldVec> {
    let points = path.points();
    let d0 = (points[1] - points[0]).normalize();
    let mut e = FieldVec::real(antenna.polarization(d0) * antenna.gain(d0).sqrt());
    for (k, r) in path.reflections.iter().enumerate() {
        let dir = (points[k + 1] - points[k]).normalize();
        let basis = LocalBasis::new(dir, r.normal);
        let (r_te, r_tm, _) = physics.exact_coefficients(r.surface, basis.cos_theta)?;
        // A scattering surface keeps sqrt(1 - S^2) of the specular amplitude (sec. 4).
        let reduction = physics.specular_factor(r.surface);
        e = basis.reflect(&e, r_te.scale(reduction), r_tm.scale(reduction));
    }
    let length = path.length_m;
    let lambda = physics.wavelength_m;
    let k = std::f64::consts::TAU / lambda;
    let amplitude = lambda / (4.0 * std::f64::consts::PI * length);
    Some(e.scale(Complex::cis(-k * length).scale(amplitude)))
}

/// The channel frequency response at `offset_hz` from the carrier,
/// `H(f_c + offset) = sum_k a_k exp(-j 2 pi offset tau_k)`: the amplitudes `a_k` already hold
/// the carrier's phase `exp(-j 2 pi f_c tau_k)`, and are taken as constant over the band
/// (docs/radio.md, sec. 3).
pub fn frequency_response(records: &[PathRecord], offset_hz: f64) -> Complex {
    records.iter().fold(Complex::ZERO, |h, r| {
        h + r.amplitude * Complex::cis(-std::f64::consts::TAU * offset_hz * r.delay_s)
    })
}
