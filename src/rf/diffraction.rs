//! First-order edge diffraction by the uniform theory of diffraction (UTD): the path
//! transmitter -> a point Q of a wedge's edge -> receiver, with Q given by Keller's law (the
//! path makes equal angles with the edge on both sides), the Kouyoumjian-Pathak diffraction
//! coefficient (\[Kouyoumjian1974\] in docs/references.md) and, for wedges of finite
//! conductivity, the Fresnel reflection coefficients of the two faces in its reflection
//! terms (\[Luebbers1984\]; Sionna RT does the same since 1.2). No reflection comes before or
//! after the diffraction. The wedges are the core's ([`crate::core::wedges`]): edges between
//! two non-coplanar triangles and rims of open surfaces (half-planes), with a free exterior.
//!
//! The diffracted field at R of the incident field `E_i` at Q (docs/radio.md, sec. 5) is
//!
//! ```text
//! E_d = -(D_s (E_i . b') b + D_h (E_i . f') f) sqrt(s' / (s (s + s'))) e^{-jks}
//! f' = -(e x s_in) / sin beta0,  b' = s_in x f',  f = (e x s_out) / sin beta0,  b = s_out x f
//! D_{s,h} = -e^{-j pi/4} / (2 n sqrt(2 pi k) sin beta0) [
//!       cot((pi + (phi - phi')) / 2n) F(kL a+(phi - phi')) + cot((pi - (phi - phi')) / 2n) F(kL a-(phi - phi'))
//!     + R_0 cot((pi - (phi + phi')) / 2n) F(kL a-(phi + phi')) + R_n cot((pi + (phi + phi')) / 2n) F(kL a+(phi + phi')) ]
//! L = s s' sin^2 beta0 / (s + s')
//! ```
//!
//! with `s' = |Q - T|`, `s = |R - Q|`, `e` the edge, `R_0` and `R_n` the TE (soft) or TM (hard)
//! reflection coefficients of face 0 for the incident ray and of face n for the diffracted
//! ray (-1 and +1 on a perfect conductor: Kouyoumjian and Pathak's coefficient).
//!
//! On a coverage map the diffracted power `|E_d|^2` at each cell's centre (a point sample,
//! not the cell average the rays give) is added to the cell's path gain: an incoherent sum,
//! as for the ray paths. The edge is lit from the transmitter where sample points every
//! [`EDGE_SAMPLE_M`] along it (at most [`MAX_EDGE_SAMPLES`]) are in view; each cell's path
//! from Q is traced. At point receivers the diffracted paths join the coherent sum, each
//! with its own ray traced both ways.

use glam::DVec3;
use rayon::prelude::*;

use super::antenna::Antenna;
use super::coverage::GridSpec;
use super::fresnel::{C0, Complex};
use super::propagation::{FieldVec, SurfacePhysics};
use super::receivers::{Interaction, PathRecord};
use crate::core::Accel;
use crate::core::utd::WedgeTerms;
use crate::core::wedges::{Wedge, clear_of_edge as clear};

/// Spacing of the points along an edge tested for being in view of the transmitter, metres.
pub const EDGE_SAMPLE_M: f64 = 0.25;
/// At most this many points per edge.
pub const MAX_EDGE_SAMPLES: usize = 1024;

/// The reflection coefficients (TE, TM) that weigh the reflection terms of a wedge.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaceReflection {
    /// TE reflection coefficient.
    pub te: Complex,
    /// TM reflection coefficient.
    pub tm: Complex,
}

impl FaceReflection {
    /// A perfect conductor: `R_TE = -1`, `R_TM = +1` (Kouyoumjian and Pathak's coefficient).
    pub const PERFECT_CONDUCTOR: Self = Self { te: Complex::new(-1.0, 0.0), tm: Complex::ONE };
}

/// The soft (TE, `E` along the edge-fixed `b`) and hard (TM) diffraction coefficients of a
/// wedge of exterior angle `n pi` for a source at azimuth `phi_p` and an observer at `phi`
/// (radians from face 0), wavenumber `k`, distance parameter `l` and `sin beta0`, with the
/// faces' reflection coefficients `r0` and `rn` (see the module doc).
#[allow(clippy::too_many_arguments)]
pub fn coefficients(
    n: f64,
    phi: f64,
    phi_p: f64,
    k: f64,
    l: f64,
    sin_beta0: f64,
    r0: FaceReflection,
    rn: FaceReflection,
) -> (Complex, Complex) {
    let terms = WedgeTerms::new(n, phi, phi_p, k, l, sin_beta0);
    (terms.coefficient(r0.te, rn.te), terms.coefficient(r0.tm, rn.tm))
}

/// The faces' reflection coefficients for `physics`, `None` as an absorber (0).
fn face_reflection(physics: &SurfacePhysics, surface: u32, cos_theta: f64) -> FaceReflection {
    match physics.coefficients(surface, cos_theta.clamp(0.0, 1.0)) {
        Some((te, tm, _)) => {
            let f = physics.specular_factor(surface);
            FaceReflection { te: te.scale(f), tm: tm.scale(f) }
        }
        None => FaceReflection { te: Complex::ZERO, tm: Complex::ZERO },
    }
}

/// The field at `rx` of the path `tx` -> `q` -> `rx` diffracted by `wedge` at its edge point
/// `q`, for a transmitter with `antenna` (geometry only: no test of what is in the way);
/// `None` when either end is not in the wedge's exterior, on its edge's line, or the path
/// runs along the edge. `reflection` gives the faces' (TE, TM) reflection coefficients for
/// face 0 and face n from the cosines of the incident ray on face 0 and of the diffracted ray
/// on face n.
pub fn diffracted_field_with(
    wedge: &Wedge,
    reflection: impl Fn(usize, f64) -> FaceReflection,
    wavelength_m: f64,
    antenna: &Antenna,
    tx: DVec3,
    q: DVec3,
    rx: DVec3,
) -> Option<FieldVec> {
    let (phi_p, _) = wedge.azimuth(tx)?;
    let (phi, _) = wedge.azimuth(rx)?;
    if !(wedge.in_exterior(phi_p) && wedge.in_exterior(phi)) {
        return None;
    }
    let (incident, outgoing) = (q - tx, rx - q);
    let (s_p, s) = (incident.length(), outgoing.length());
    if !(s_p > 0.0 && s > 0.0 && s_p.is_finite() && s.is_finite() && wavelength_m > 0.0) {
        return None;
    }
    let (s_in, s_out) = (incident / s_p, outgoing / s);
    let cross_in = wedge.edge.cross(s_in);
    let sin_beta0 = cross_in.length();
    let cross_out = wedge.edge.cross(s_out);
    let sin_out = cross_out.length();
    if !(sin_beta0 > 1.0e-6 && sin_out > 1.0e-6) {
        return None;
    }
    let k = std::f64::consts::TAU / wavelength_m;
    let l = s * s_p / (s + s_p) * sin_beta0 * sin_beta0;
    let r0 = reflection(0, s_in.dot(wedge.normals[0]).abs());
    let rn = reflection(1, s_out.dot(wedge.normals[1]).abs());
    let (d_soft, d_hard) = coefficients(wedge.n, phi, phi_p, k, l, sin_beta0, r0, rn);
    let e_in = FieldVec::real(antenna.polarization(s_in) * antenna.gain(s_in).sqrt())
        .scale(Complex::cis(-k * s_p).scale(wavelength_m / (4.0 * std::f64::consts::PI * s_p)));
    let f_in = -cross_in / sin_beta0;
    let b_in = s_in.cross(f_in);
    let f_out = cross_out / sin_out;
    let b_out = s_out.cross(f_out);
    let spread = (s_p / (s * (s + s_p))).sqrt();
    let e_d = FieldVec::from_component(-(d_soft * e_in.along(b_in)), b_out)
        .add(&FieldVec::from_component(-(d_hard * e_in.along(f_in)), f_out));
    Some(e_d.scale(Complex::cis(-k * s).scale(spread)))
}

/// [`diffracted_field_with`] with the faces' reflection coefficients of `physics` (Luebbers'
/// finite conductivity).
pub fn diffracted_field(
    wedge: &Wedge,
    physics: &SurfacePhysics,
    antenna: &Antenna,
    tx: DVec3,
    q: DVec3,
    rx: DVec3,
) -> Option<FieldVec> {
    diffracted_field_with(
        wedge,
        |face, cos| face_reflection(physics, wedge.surfaces[face], cos),
        physics.wavelength_m,
        antenna,
        tx,
        q,
        rx,
    )
}

/// The parts of a wedge's edge in view of a transmitter: one flag per interval of
/// `length / samples.len()`, tested at its midpoint.
struct LitEdge<'w> {
    wedge: &'w Wedge,
    lit: Vec<bool>,
}

impl LitEdge<'_> {
    #[inline]
    fn is_lit(&self, t: f64) -> bool {
        let m = self.lit.len();
        let i = ((t / self.wedge.length) * m as f64).floor();
        let i = if i < 0.0 { 0 } else { (i as usize).min(m - 1) };
        self.lit[i]
    }
}

/// The edge of `wedge` in view of `tx` (`None` when `tx` is not in its exterior or sees none
/// of it).
fn lit_edge<'w>(accel: &Accel, wedge: &'w Wedge, tx: DVec3) -> Option<LitEdge<'w>> {
    let (phi_p, _) = wedge.azimuth(tx)?;
    if !wedge.in_exterior(phi_p) {
        return None;
    }
    let m = ((wedge.length / EDGE_SAMPLE_M).ceil() as usize).clamp(1, MAX_EDGE_SAMPLES);
    let lit: Vec<bool> =
        (0..m).map(|i| clear(accel, wedge.at(wedge.length * (i as f64 + 0.5) / m as f64), tx)).collect();
    lit.iter().any(|&b| b).then_some(LitEdge { wedge, lit })
}

/// The diffracted power of one transmitter over a grid (see the module doc).
#[derive(Clone, Debug, PartialEq)]
pub struct DiffractionMap {
    /// Path gain of the diffracted paths at each cell's centre, linear (power sum).
    pub path_gain: Vec<f64>,
    /// Diffracted paths reaching each cell's centre.
    pub paths: Vec<u32>,
    /// Wedges whose edge the transmitter sees.
    pub lit_wedges: usize,
}

impl DiffractionMap {
    /// Cells with at least one diffracted path.
    pub fn cells(&self) -> usize {
        self.paths.iter().filter(|&&p| p > 0).count()
    }
}

/// The first-order diffracted power from `tx` (with `antenna`) at the centre of every cell of
/// `grid`, over the wedges `wedges` of the scene traced by `accel`. Cells are computed in
/// parallel, each summing its wedges in order: the map is the same for any thread count.
pub fn coverage(
    accel: &Accel,
    wedges: &[Wedge],
    physics: &SurfacePhysics,
    antenna: &Antenna,
    tx: DVec3,
    grid: &GridSpec,
) -> DiffractionMap {
    let lit: Vec<LitEdge> = wedges.par_iter().filter_map(|w| lit_edge(accel, w, tx)).collect();
    let cells: Vec<(f64, u32)> = (0..grid.cells())
        .into_par_iter()
        .with_min_len(64)
        .map(|cell| {
            let [x, y] = grid.centre(cell);
            let rx = DVec3::new(x, y, grid.height_m);
            let mut gain = 0.0;
            let mut paths = 0;
            for edge in &lit {
                let w = edge.wedge;
                if !w.outside(rx) {
                    continue;
                }
                let Some(t) = w.keller_point(tx, rx) else { continue };
                if !edge.is_lit(t) {
                    continue;
                }
                let q = w.at(t);
                if !clear(accel, q, rx) {
                    continue;
                }
                if let Some(e) = diffracted_field(w, physics, antenna, tx, q, rx) {
                    let p = e.power();
                    if p.is_finite() {
                        gain += p;
                        paths += 1;
                    }
                }
            }
            (gain, paths)
        })
        .collect();
    let (path_gain, paths) = cells.into_iter().unzip();
    DiffractionMap { path_gain, paths, lit_wedges: lit.len() }
}

/// The first-order diffracted paths from `tx` to `rx`, one per wedge whose Keller point is in
/// view of both ends (each traced), in the order of `wedges`.
pub fn paths(
    accel: &Accel,
    wedges: &[Wedge],
    physics: &SurfacePhysics,
    antenna: &Antenna,
    tx: DVec3,
    rx: DVec3,
) -> Vec<PathRecord> {
    let mut out = Vec::new();
    for w in wedges {
        let Some(t) = w.keller_point(tx, rx) else { continue };
        let q = w.at(t);
        let Some(h) = diffracted_field(w, physics, antenna, tx, q, rx) else { continue };
        if !(h.power().is_finite() && clear(accel, q, tx) && clear(accel, q, rx)) {
            continue;
        }
        let length_m = (q - tx).length() + (rx - q).length();
        let departure = (q - tx).normalize();
        let travel = (rx - q).normalize();
        out.push(PathRecord {
            length_m,
            delay_s: length_m / C0,
            field: h,
            amplitude: h.along(antenna.polarization(travel)),
            departure,
            arrival: -travel,
            interactions: vec![Interaction::Diffraction { surfaces: w.surfaces }],
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn boundaries_give_finite_coefficients() {
        // Observer on the shadow boundary of a half-plane (phi = pi + phi').
        let pec = FaceReflection::PERFECT_CONDUCTOR;
        let (s, h) = coefficients(2.0, std::f64::consts::PI + 0.5, 0.5, 73.0, 10.0, 1.0, pec, pec);
        assert!(s.abs().is_finite() && h.abs().is_finite());
        let (s2, _) = coefficients(2.0, std::f64::consts::PI + 0.5 + 1e-9, 0.5, 73.0, 10.0, 1.0, pec, pec);
        assert!(s2.abs().is_finite());
    }
}
