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

use glam::DVec3;

use super::antenna::Antenna;
use super::fresnel::Complex;
use super::propagation::{FieldVec, LocalBasis, SurfacePhysics};
use crate::core::Accel;
use crate::core::specular::{Planes, SpecularPath, specular_paths};

/// The sum of the exact paths at one receiver.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PathSum {
    /// Valid paths found (line of sight counts as one).
    pub paths: usize,
    /// Reflections of each path, in the order found.
    pub path_orders: Vec<usize>,
    /// Length of each path, metres, in the same order.
    pub path_lengths_m: Vec<f64>,
    pub line_of_sight: bool,
    /// `|sum h|^2`, linear.
    pub coherent_gain: f64,
    /// `sum |h|^2`, linear.
    pub incoherent_gain: f64,
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
        }
    }
    out.coherent_gain = total.power();
    out
}

/// The field at the receiver of `path`: the antenna's field along the first leg, reflected
/// at each point with the Fresnel coefficients of its surface at its incidence angle, times
/// the free-space factor of the whole length; `None` when a surface has no radio data.
fn path_field(path: &SpecularPath, physics: &SurfacePhysics, antenna: &Antenna) -> Option<FieldVec> {
    let points = path.points();
    let d0 = (points[1] - points[0]).normalize();
    let mut e = FieldVec::real(antenna.polarization(d0) * antenna.gain(d0).sqrt());
    for (k, r) in path.reflections.iter().enumerate() {
        let dir = (points[k + 1] - points[k]).normalize();
        let basis = LocalBasis::new(dir, r.normal);
        let (r_te, r_tm, _) = physics.coefficients(r.surface, basis.cos_theta)?;
        e = basis.reflect(&e, r_te, r_tm);
    }
    let length = path.length_m;
    let lambda = physics.wavelength_m;
    let k = std::f64::consts::TAU / lambda;
    let amplitude = lambda / (4.0 * std::f64::consts::PI * length);
    Some(e.scale(Complex::cis(-k * length).scale(amplitude)))
}
