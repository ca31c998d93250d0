//! Coherent point receivers: the exact specular paths from a transmitter to a point, found
//! by the image method (Allen & Berkley 1979 for rooms; the classic two-ray and multi-ray
//! models of radio propagation), each validated by tracing it through the scene, and summed
//! with their phase.
//!
//! Every sequence of up to `max_depth` distinct planes of the mesh gives one candidate image
//! source; the path from it to the receiver is unfolded back through the planes and kept only
//! if every leg reaches the next reflection point on that plane (inside one of its triangles,
//! unobstructed) and the last leg is free. The field of a path of length `L` is
//! `h = (lambda / 4 pi L) e^{-j 2 pi L / lambda} (prod of reflection dyads) e_tx sqrt(G_tx)`,
//! a complex vector; the coherent path gain is `|sum h|^2` (an isotropic receiver taking all
//! polarisations), the incoherent one `sum |h|^2`.

use std::collections::BTreeMap;

use glam::DVec3;

use super::antenna::Antenna;
use super::fresnel::Complex;
use super::propagation::{FieldVec, LocalBasis, SurfacePhysics};
use crate::core::{Accel, Ray, TriangleMesh};

/// A plane `n . x = d` of the mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    pub normal: DVec3,
    pub offset: f64,
}

/// The distinct planes of a mesh's triangles (coplanar triangles, facing either way, share
/// one), in a deterministic order.
pub fn distinct_planes(mesh: &TriangleMesh) -> Vec<Plane> {
    let mut map: BTreeMap<(i64, i64, i64, i64), Plane> = BTreeMap::new();
    for i in 0..mesh.triangle_count() {
        let [a, b, c] = mesh.corners(i).map(|v| v.as_dvec3());
        let n = (b - a).cross(c - a);
        if n.length_squared() == 0.0 {
            continue;
        }
        let mut n = n.normalize();
        let first = if n.x.abs() > 1e-9 {
            n.x
        } else if n.y.abs() > 1e-9 {
            n.y
        } else {
            n.z
        };
        if first < 0.0 {
            n = -n;
        }
        let d = n.dot((a + b + c) / 3.0);
        let key = (
            (n.x * 1e4).round() as i64,
            (n.y * 1e4).round() as i64,
            (n.z * 1e4).round() as i64,
            (d * 1e3).round() as i64,
        );
        map.entry(key).or_insert(Plane { normal: n, offset: d });
    }
    map.into_values().collect()
}

/// The sum of the exact paths at one receiver.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PathSum {
    /// Valid paths found (line of sight counts as one).
    pub paths: usize,
    /// Reflections of each path, in the order found.
    pub path_orders: Vec<usize>,
    pub line_of_sight: bool,
    /// `|sum h|^2`, linear.
    pub coherent_gain: f64,
    /// `sum |h|^2`, linear.
    pub incoherent_gain: f64,
}

/// Mirror image of `p` in `plane`.
fn mirror(p: DVec3, plane: &Plane) -> DVec3 {
    p - 2.0 * (plane.normal.dot(p) - plane.offset) * plane.normal
}

/// Legs leaving a reflection point ignore hits closer than this, metres: the exact point and
/// the f32 triangle disagree by about 1e-7 of the triangle's coordinates (1e-4 m on a
/// 5 km ground), more than [`Ray::spawn`]'s offset from the point.
const LEG_START_M: f32 = 2.0e-3;

/// Largest number of plane sequences the search may try per receiver.
pub const MAX_SEQUENCES: f64 = 2.0e6;

/// The deepest order up to `max_depth` whose sequence count stays within [`MAX_SEQUENCES`].
pub fn affordable_depth(planes: usize, max_depth: u32) -> u32 {
    let mut depth = 0;
    let mut total = 1.0;
    let mut level = 1.0;
    while depth < max_depth {
        level *= (planes.max(2) - 1) as f64;
        if total + level > MAX_SEQUENCES {
            break;
        }
        total += level;
        depth += 1;
    }
    depth
}

/// Sums the specular paths of up to `max_depth` reflections from `tx` (with `antenna`) to
/// `rx`.
pub fn coherent_paths(
    accel: &Accel,
    planes: &[Plane],
    physics: &SurfacePhysics,
    antenna: &Antenna,
    tx: DVec3,
    rx: DVec3,
    max_depth: u32,
) -> PathSum {
    let mut out = PathSum::default();
    let mut total = FieldVec::default();
    let mut seq = Vec::with_capacity(max_depth as usize);
    let mut images = vec![tx];
    let mut visit = |seq: &[usize], images: &[DVec3]| {
        if let Some(h) = path_field(accel, planes, physics, antenna, seq, images, rx) {
            out.paths += 1;
            out.path_orders.push(seq.len());
            out.line_of_sight |= seq.is_empty();
            out.incoherent_gain += h.power();
            total = total.add(&h);
        }
    };
    search(planes, max_depth, &mut seq, &mut images, &mut visit);
    out.coherent_gain = total.power();
    out
}

fn search(
    planes: &[Plane],
    depth_left: u32,
    seq: &mut Vec<usize>,
    images: &mut Vec<DVec3>,
    visit: &mut impl FnMut(&[usize], &[DVec3]),
) {
    visit(seq, images);
    if depth_left == 0 {
        return;
    }
    let Some(&last_image) = images.last() else { return };
    for (j, plane) in planes.iter().enumerate() {
        if seq.last() == Some(&j) || (plane.normal.dot(last_image) - plane.offset).abs() < 1e-6 {
            continue;
        }
        seq.push(j);
        images.push(mirror(last_image, plane));
        search(planes, depth_left - 1, seq, images, visit);
        seq.pop();
        images.pop();
    }
}

/// The field at `rx` of the path through the planes `seq` (images of the source in
/// `images`), or `None` when the path does not exist in the scene.
fn path_field(
    accel: &Accel,
    planes: &[Plane],
    physics: &SurfacePhysics,
    antenna: &Antenna,
    seq: &[usize],
    images: &[DVec3],
    rx: DVec3,
) -> Option<FieldVec> {
    // Unfold backwards: the reflection point on plane k lies on the line from image k to
    // the point after it.
    let mut points = vec![DVec3::ZERO; seq.len()];
    let mut target = rx;
    for k in (0..seq.len()).rev() {
        let plane = &planes[seq[k]];
        let image = images[k + 1];
        let da = plane.normal.dot(image) - plane.offset;
        let db = plane.normal.dot(target) - plane.offset;
        if da * db >= 0.0 {
            return None;
        }
        let p = image + (target - image) * (da / (da - db));
        points[k] = p;
        target = p;
    }
    // Walk forwards, checking each leg in the scene and applying the reflections.
    let tx = images[0];
    let first = points.first().copied().unwrap_or(rx);
    let d0 = (first - tx).normalize();
    let mut e = FieldVec::real(antenna.polarization(d0) * antenna.gain(d0).sqrt());
    let mut length = 0.0;
    let mut from = tx;
    let mut on_surface = false;
    for (k, &p) in points.iter().enumerate() {
        let leg = p - from;
        let dist = leg.length();
        let dir = leg / dist;
        let mut ray = Ray::new(from.as_vec3(), dir.as_vec3());
        if on_surface {
            ray.t_min = LEG_START_M;
        }
        let hit = accel.mesh.closest_hit(&ray)?;
        let plane = &planes[seq[k]];
        let tol = 1e-3 + 1e-5 * (dist + from.abs().max_element());
        let reached = hit.point.as_dvec3().distance(p) < tol;
        if !reached || hit.normal.as_dvec3().dot(plane.normal).abs() < 0.9999 {
            return None;
        }
        let basis = LocalBasis::new(dir, plane.normal);
        let (r_te, r_tm, _) = physics.coefficients(hit.surface, basis.cos_theta)?;
        e = basis.reflect(&e, r_te, r_tm);
        length += dist;
        from = p;
        on_surface = true;
    }
    let leg = rx - from;
    let dist = leg.length();
    if dist == 0.0 {
        return None;
    }
    let mut last = Ray::segment(from.as_vec3(), (leg / dist).as_vec3(), (dist * (1.0 - 1e-6)) as f32);
    if on_surface {
        last.t_min = LEG_START_M;
    }
    if accel.mesh.occluded(&last) {
        return None;
    }
    length += dist;
    let lambda = physics.wavelength_m;
    let k = std::f64::consts::TAU / lambda;
    let amplitude = lambda / (4.0 * std::f64::consts::PI * length);
    Some(e.scale(Complex::cis(-k * length).scale(amplitude)))
}
