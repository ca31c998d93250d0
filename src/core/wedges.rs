//! The diffracting edges of a triangle mesh, geometry only: **wedges**, edges shared by two
//! triangles that are not coplanar, and **rims**, edges of a single triangle (the border of an
//! open surface such as a thin screen), taken as half-planes.
//!
//! Vertices are merged by position (OBJ files often repeat a vertex once per face), so a box
//! whose faces do not share vertex indices still has its twelve wedges. Each wedge is given
//! in the frame of the uniform theory of diffraction (\[Kouyoumjian1974\] in
//! docs/references.md): the edge from `start` to `end`, oriented so that the azimuth `phi`
//! about it, measured from face 0, sweeps the exterior (the air) from 0 to `n pi`, where face
//! n lies. The solid is taken to be the part of space inside the smaller dihedral angle
//! (a convex edge, `1 < n <= 2`): an inner corner (a concave edge, such as a room's) sees its
//! air on the smaller side, which this reading makes the solid, so a source in that air is
//! never on the exterior side and the edge never diffracts it.
//!
//! Edges shared by more than two triangles (non-manifold) are skipped, and so are wedges
//! whose exterior is not free near the edge ([`free_wedges`]): a building's bottom edges
//! standing on the ground, or the seam where a triangle meets a larger coplanar neighbour
//! (a T-junction, which looks like a rim).

use std::collections::HashMap;

use glam::{DVec3, Vec3};

use super::Accel;
use super::hit::SurfaceId;
use super::mesh::TriangleMesh;
use super::ray::Ray;

/// Dihedral angles within this many radians of flat (`pi`) are no wedge.
pub const FLAT_TOLERANCE_RAD: f64 = 1.0e-3;

/// A diffracting edge (see the module doc).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Wedge {
    /// The edge runs from `start` to `end`.
    pub start: DVec3,
    /// End of the edge.
    pub end: DVec3,
    /// Unit edge direction `(end - start) / length`: the azimuth about it from face 0
    /// increases into the exterior (right-handed).
    pub edge: DVec3,
    /// Length of the edge, metres.
    pub length: f64,
    /// Unit vectors perpendicular to the edge pointing from the edge into face 0 and face n
    /// (the same vector twice for a rim).
    pub face_dirs: [DVec3; 2],
    /// Unit normals of face 0 and face n pointing into the exterior.
    pub normals: [DVec3; 2],
    /// Exterior angle over pi, in (1, 2]: 2 for a rim (a half-plane), 1.5 for a right angle.
    pub n: f64,
    /// Surfaces of face 0 and face n (the same twice for a rim).
    pub surfaces: [SurfaceId; 2],
    /// The mesh triangles of face 0 and face n on this edge (the same twice for a rim).
    pub triangles: [u32; 2],
    /// True for a rim: an edge of a single triangle.
    pub rim: bool,
}

impl Wedge {
    /// Azimuth of `p` about the edge, from face 0 towards the exterior, in `[0, 2 pi)`, and
    /// the distance of `p` from the edge's line; `None` on the line.
    #[inline]
    pub fn azimuth(&self, p: DVec3) -> Option<(f64, f64)> {
        let d = p - self.start;
        let rho = d - d.dot(self.edge) * self.edge;
        let r = rho.length();
        if r.is_nan() || r <= 1.0e-9 {
            return None;
        }
        let x = rho.dot(self.face_dirs[0]);
        let y = rho.dot(self.edge.cross(self.face_dirs[0]));
        let mut phi = y.atan2(x);
        if phi < 0.0 {
            phi += std::f64::consts::TAU;
        }
        Some((phi, r))
    }

    /// True when azimuth `phi` is in the exterior (the air side): `phi` in `[0, n pi]`.
    #[inline]
    pub fn in_exterior(&self, phi: f64) -> bool {
        phi <= self.n * std::f64::consts::PI
    }

    /// True when `p` is in the exterior (or on a face): not behind both faces. The same as
    /// `in_exterior` of its azimuth, with two dot products (a rim has no inside).
    #[inline]
    pub fn outside(&self, p: DVec3) -> bool {
        let d = p - self.start;
        !(d.dot(self.normals[0]) < 0.0 && d.dot(self.normals[1]) < 0.0) || self.rim
    }

    /// The point at parameter `t` (metres from `start`) on the edge.
    #[inline]
    pub fn at(&self, t: f64) -> DVec3 {
        self.start + t * self.edge
    }

    /// The unit direction at azimuth `phi` (perpendicular to the edge).
    #[inline]
    pub fn direction_at(&self, phi: f64) -> DVec3 {
        let (s, c) = phi.sin_cos();
        self.face_dirs[0] * c + self.edge.cross(self.face_dirs[0]) * s
    }

    /// The point of the edge where a path from `a` to `b` meets it by Keller's law (equal
    /// angles with the edge on both sides): its parameter along the edge, in metres from
    /// `start`, when it lies on the segment; `None` when it does not or when `a` or `b` is on
    /// the edge's line.
    #[inline]
    pub fn keller_point(&self, a: DVec3, b: DVec3) -> Option<f64> {
        let (da, db) = (a - self.start, b - self.start);
        let (a_par, b_par) = (da.dot(self.edge), db.dot(self.edge));
        let a_perp = (da - a_par * self.edge).length();
        let b_perp = (db - b_par * self.edge).length();
        let sum = a_perp + b_perp;
        if !(a_perp > 1.0e-9 && b_perp > 1.0e-9 && sum.is_finite()) {
            return None;
        }
        let t = (a_par * b_perp + b_par * a_perp) / sum;
        (t >= 0.0 && t <= self.length).then_some(t)
    }
}

/// Key of a merged vertex: the position rounded to a grid of `tolerance`.
fn vertex_key(p: Vec3, tolerance: f64) -> Option<[i64; 3]> {
    let k = p.as_dvec3() / tolerance;
    if !k.is_finite() || k.abs().max_element() > 1.0e15 {
        return None;
    }
    Some([k.x.round() as i64, k.y.round() as i64, k.z.round() as i64])
}

/// The mesh's edges after merging vertices by position: the merged points, and for each
/// edge (smaller id, larger id) the triangles on it with their third vertex.
struct EdgeMap {
    points: Vec<DVec3>,
    edges: HashMap<(u32, u32), Vec<(usize, u32)>>,
    tolerance: f64,
}

impl EdgeMap {
    /// Degenerate triangles (zero area, or a non-finite corner) are left out. Vertices closer
    /// than `1e-6` of the mesh's extent (at least 1e-6 m) are merged.
    fn of(mesh: &TriangleMesh) -> Option<Self> {
        let (lo, hi) = mesh.bounds()?;
        let extent = f64::from((hi - lo).length());
        let tolerance = if extent.is_finite() { (extent * 1.0e-6).max(1.0e-6) } else { 1.0e-6 };
        // Merged vertex id of each position index.
        let mut ids: HashMap<[i64; 3], u32> = HashMap::new();
        let mut merged: Vec<Option<u32>> = Vec::with_capacity(mesh.positions.len());
        let mut points: Vec<DVec3> = Vec::new();
        for &p in &mesh.positions {
            merged.push(vertex_key(p, tolerance).map(|k| {
                *ids.entry(k).or_insert_with(|| {
                    points.push(p.as_dvec3());
                    (points.len() - 1) as u32
                })
            }));
        }
        let mut edges: HashMap<(u32, u32), Vec<(usize, u32)>> = HashMap::new();
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let v: Option<Vec<u32>> =
                tri.iter().map(|&i| merged.get(i as usize).copied().flatten()).collect();
            let Some(v) = v else { continue };
            if v[0] == v[1] || v[1] == v[2] || v[0] == v[2] {
                continue;
            }
            let (a, b, c) = (points[v[0] as usize], points[v[1] as usize], points[v[2] as usize]);
            let area2 = (b - a).cross(c - a).length();
            if area2.is_nan() || area2 <= 1.0e-12 {
                continue;
            }
            for k in 0..3 {
                let (p, q, r) = (v[k], v[(k + 1) % 3], v[(k + 2) % 3]);
                edges.entry((p.min(q), p.max(q))).or_default().push((t, r));
            }
        }
        Some(Self { points, edges, tolerance })
    }

    /// The unit direction perpendicular to edge `a`-`b` (unit `e`) towards vertex `third`.
    fn dir_to(&self, a: DVec3, e: DVec3, third: u32) -> DVec3 {
        let d = self.points[third as usize] - a;
        (d - d.dot(e) * e).normalize_or_zero()
    }
}

/// The planar region of every triangle: triangles that share an edge and lie in one plane
/// (within [`FLAT_TOLERANCE_RAD`]) are in the same region, numbered from 0 in the order of
/// their first triangle; a degenerate triangle is a region of its own.
pub fn planar_regions(mesh: &TriangleMesh) -> Vec<u32> {
    let n = mesh.triangles.len();
    let mut parent: Vec<usize> = (0..n).collect();
    fn root(parent: &mut [usize], mut i: usize) -> usize {
        while parent[i] != i {
            parent[i] = parent[parent[i]];
            i = parent[i];
        }
        i
    }
    if let Some(map) = EdgeMap::of(mesh) {
        for (&(ia, ib), on) in &map.edges {
            if on.len() != 2 {
                continue;
            }
            let (a, b) = (map.points[ia as usize], map.points[ib as usize]);
            let e = (b - a).normalize_or_zero();
            let (t0, t1) = (map.dir_to(a, e, on[0].1), map.dir_to(a, e, on[1].1));
            if t0 == DVec3::ZERO || t1 == DVec3::ZERO {
                continue;
            }
            let interior = t0.dot(t1).clamp(-1.0, 1.0).acos();
            if (std::f64::consts::PI - interior).abs() < FLAT_TOLERANCE_RAD {
                let (x, y) = (root(&mut parent, on[0].0), root(&mut parent, on[1].0));
                // The smaller index becomes the root: the numbering does not depend on the
                // hash map's order.
                let (lo, hi) = (x.min(y), x.max(y));
                parent[hi] = lo;
            }
        }
    }
    let mut number = vec![u32::MAX; n];
    let mut next = 0;
    let mut out = vec![0u32; n];
    for (t, region) in out.iter_mut().enumerate() {
        let r = root(&mut parent, t);
        if number[r] == u32::MAX {
            number[r] = next;
            next += 1;
        }
        *region = number[r];
    }
    out
}

/// Every wedge and rim of `mesh` (see the module doc), in a deterministic order (by merged
/// vertex ids). Degenerate triangles (zero area, or a non-finite corner) and zero-length
/// edges are ignored. Vertices closer than `1e-6` of the mesh's extent (at least 1e-6 m)
/// are merged.
pub fn extract_wedges(mesh: &TriangleMesh) -> Vec<Wedge> {
    let Some(map) = EdgeMap::of(mesh) else {
        return Vec::new();
    };
    let EdgeMap { points, edges, tolerance } = &map;
    let tolerance = *tolerance;
    let mut keys: Vec<(u32, u32)> = edges.keys().copied().collect();
    keys.sort_unstable();
    let mut out = Vec::new();
    for key in keys {
        let on = &edges[&key];
        if on.len() > 2 {
            continue;
        }
        let (a, b) = (points[key.0 as usize], points[key.1 as usize]);
        let length = (b - a).length();
        if length.is_nan() || length <= tolerance {
            continue;
        }
        let e = (b - a) / length;
        let dir_to = |third: u32| map.dir_to(a, e, third);
        let surface = |t: usize| mesh.surface_of_triangle.get(t).copied().unwrap_or(0);
        if on.len() == 1 {
            let t0 = dir_to(on[0].1);
            if t0 == DVec3::ZERO {
                continue;
            }
            let s = surface(on[0].0);
            // Any orientation of the edge will do for a half-plane.
            out.push(Wedge {
                start: a,
                end: b,
                edge: e,
                length,
                face_dirs: [t0, t0],
                normals: [e.cross(t0), -e.cross(t0)],
                n: 2.0,
                surfaces: [s, s],
                triangles: [on[0].0 as u32; 2],
                rim: true,
            });
            continue;
        }
        let (t0, t1) = (dir_to(on[0].1), dir_to(on[1].1));
        if t0 == DVec3::ZERO || t1 == DVec3::ZERO {
            continue;
        }
        let interior = t0.dot(t1).clamp(-1.0, 1.0).acos();
        if (std::f64::consts::PI - interior).abs() < FLAT_TOLERANCE_RAD {
            continue;
        }
        // Orient the edge so that turning from face 0 about it goes into the exterior, away
        // from face 1: (edge x t0) . t1 < 0.
        let (start, end, edge) = if e.cross(t0).dot(t1) < 0.0 { (a, b, e) } else { (b, a, -e) };
        let n = 2.0 - interior / std::f64::consts::PI;
        let n_pi = n * std::f64::consts::PI;
        // Exterior normal of face n: the direction at azimuth n pi - pi / 2.
        let normal_n = t0 * (n_pi - std::f64::consts::FRAC_PI_2).cos()
            + edge.cross(t0) * (n_pi - std::f64::consts::FRAC_PI_2).sin();
        out.push(Wedge {
            start,
            end,
            edge,
            length,
            face_dirs: [t0, t1],
            normals: [edge.cross(t0), normal_n],
            n,
            surfaces: [surface(on[0].0), surface(on[1].0)],
            triangles: [on[0].0 as u32, on[1].0 as u32],
            rim: false,
        });
    }
    out
}

/// The wedges of `wedges` whose exterior is free near the edge: at a quarter, half and three
/// quarters of its length, a chain of short chords on a small circle about the edge, sweeping
/// the exterior from near face 0 to near face n, crosses nothing of `accel`. A wedge standing
/// on another surface (a building's bottom edge on the ground) or a seam inside a larger
/// surface fails.
pub fn free_wedges(accel: &Accel, wedges: &[Wedge]) -> Vec<Wedge> {
    wedges.iter().filter(|w| exterior_is_free(accel, w)).copied().collect()
}

fn exterior_is_free(accel: &Accel, w: &Wedge) -> bool {
    // Radius of the probe circle: small against the edge, large against f32 rounding.
    let scale = w.start.abs().max(w.end.abs()).max_element().max(1.0);
    let radius = (0.05 * w.length).min(0.05).max(scale * 2.0e-5);
    const CHORDS: usize = 8;
    let sweep = w.n * std::f64::consts::PI;
    // Stay a little off the faces themselves.
    let margin = (0.05 * sweep / CHORDS as f64).min(0.02);
    for frac in [0.25, 0.5, 0.75] {
        let centre = w.at(frac * w.length);
        let point = |k: usize| {
            let phi = margin + (sweep - 2.0 * margin) * (k as f64 / CHORDS as f64);
            centre + radius * w.direction_at(phi)
        };
        for k in 0..CHORDS {
            let (p, q) = (point(k), point(k + 1));
            let d = q - p;
            let len = d.length();
            if len.is_nan() || len <= 0.0 {
                continue;
            }
            let ray = Ray::segment(p.as_vec3(), (d / len).as_vec3(), len as f32);
            if accel.occluded(&ray) {
                return false;
            }
        }
    }
    true
}

/// The distance a visibility ray stops short of an edge point, metres, near `p`.
fn edge_offset(p: DVec3) -> f64 {
    1.0e-3 + 2.0e-6 * p.abs().max_element()
}

/// True when nothing of `accel` lies between the edge point `q` and `p` (the ends left out,
/// by a millimetre or so, so that the edge's own faces do not block its paths).
pub fn clear_of_edge(accel: &Accel, q: DVec3, p: DVec3) -> bool {
    let d = p - q;
    let len = d.length();
    if !(len.is_finite() && len > 0.0) {
        return false;
    }
    let eps = edge_offset(q).max(edge_offset(p));
    if len <= 2.0 * eps {
        return true;
    }
    let ray =
        Ray { origin: q.as_vec3(), dir: (d / len).as_vec3(), t_min: eps as f32, t_max: (len - eps) as f32 };
    !accel.occluded(&ray)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::BuildQuality;

    #[test]
    fn a_box_has_twelve_right_angled_wedges_and_no_rims() {
        let mut m = TriangleMesh::default();
        let s = m.surface_id("wall");
        m.push_box(Vec3::ZERO, Vec3::new(2.0, 3.0, 4.0), 2, s);
        let w = extract_wedges(&m);
        assert_eq!(w.len(), 12 * 2, "each box edge is split in two by the 2 x 2 faces");
        for x in &w {
            assert!(!x.rim);
            assert!((x.n - 1.5).abs() < 1e-9, "n = {}", x.n);
            // The exterior directions leave the box.
            let mid = x.at(0.5 * x.length);
            let out = mid + 0.01 * x.direction_at(0.75 * std::f64::consts::PI);
            let inside =
                out.x > 0.0 && out.x < 2.0 && out.y > 0.0 && out.y < 3.0 && out.z > 0.0 && out.z < 4.0;
            assert!(!inside);
            // The cheap exterior test agrees with the azimuth.
            for k in 0..64 {
                let a = std::f64::consts::TAU * (k as f64 + 0.5) / 64.0;
                let p = mid + 0.5 * x.direction_at(a) + 0.3 * x.edge;
                assert_eq!(x.outside(p), x.in_exterior(x.azimuth(p).unwrap().0), "azimuth {a}");
            }
            // Face n lies at azimuth n pi.
            let face_n = x.direction_at(x.n * std::f64::consts::PI);
            assert!(face_n.dot(x.face_dirs[1]) > 1.0 - 1e-9);
            assert!(x.normals[1].dot(x.face_dirs[1]).abs() < 1e-9);
        }
        let accel = Accel::build(&m, Vec::new(), BuildQuality::default());
        assert_eq!(free_wedges(&accel, &w).len(), w.len());
    }

    #[test]
    fn a_quad_has_four_rims_and_duplicated_vertices_merge() {
        let mut m = TriangleMesh::default();
        let s = m.surface_id("screen");
        // push_triangle repeats the shared vertices: they merge by position.
        let (a, b, c, d) = (Vec3::ZERO, Vec3::X, Vec3::new(1.0, 1.0, 0.0), Vec3::Y);
        m.push_triangle([a, b, c], s);
        m.push_triangle([a, c, d], s);
        let w = extract_wedges(&m);
        assert_eq!(w.len(), 4);
        assert!(w.iter().all(|x| x.rim && x.n == 2.0));
    }

    #[test]
    fn a_box_on_the_ground_loses_its_bottom_edges() {
        let mut m = TriangleMesh::default();
        let s = m.surface_id("wall");
        m.push_box(Vec3::ZERO, Vec3::new(2.0, 3.0, 4.0), 1, s);
        let g = m.surface_id("ground");
        m.push_quad(
            Vec3::new(-10.0, -10.0, 0.0),
            Vec3::new(10.0, -10.0, 0.0),
            Vec3::new(10.0, 10.0, 0.0),
            Vec3::new(-10.0, 10.0, 0.0),
            g,
        );
        let all = extract_wedges(&m);
        let accel = Accel::build(&m, Vec::new(), BuildQuality::default());
        let free = free_wedges(&accel, &all);
        // 12 box edges + 4 ground rims, of which the 4 bottom edges are buried.
        assert_eq!(all.len(), 16);
        assert_eq!(free.len(), 12);
        assert_eq!(free.iter().filter(|w| w.rim).count(), 4, "the ground's rims are free");
        assert!(free.iter().filter(|w| !w.rim).all(|w| w.start.z > 0.0 || w.end.z > 0.0));
    }

    #[test]
    fn keller_point_has_equal_angles() {
        let w = Wedge {
            start: DVec3::ZERO,
            end: DVec3::new(0.0, 0.0, 10.0),
            edge: DVec3::Z,
            length: 10.0,
            face_dirs: [DVec3::X, DVec3::X],
            normals: [DVec3::Y, -DVec3::Y],
            n: 2.0,
            surfaces: [0, 0],
            triangles: [0, 0],
            rim: true,
        };
        let (a, b) = (DVec3::new(3.0, 4.0, 1.0), DVec3::new(-1.0, -2.0, 7.0));
        let t = w.keller_point(a, b).unwrap();
        let q = w.at(t);
        let ca = (q - a).normalize().dot(DVec3::Z);
        let cb = (b - q).normalize().dot(DVec3::Z);
        assert!((ca - cb).abs() < 1e-12);
        assert_eq!(w.keller_point(a, DVec3::new(0.0, 0.0, 5.0)), None);
        assert_eq!(w.keller_point(DVec3::new(1.0, 0.0, 20.0), DVec3::new(1.0, 0.0, 30.0)), None);
        assert_eq!(w.keller_point(DVec3::NAN, b), None);
    }

    #[test]
    fn degenerate_input_gives_no_wedge_and_no_panic() {
        let mut m = TriangleMesh::default();
        let s = m.surface_id("x");
        m.push_triangle([Vec3::ZERO, Vec3::X, Vec3::new(2.0, 0.0, 0.0)], s);
        m.push_triangle([Vec3::ZERO, Vec3::ZERO, Vec3::Y], s);
        m.push_triangle([Vec3::NAN, Vec3::X, Vec3::Y], s);
        assert!(extract_wedges(&m).is_empty());
        assert!(extract_wedges(&TriangleMesh::default()).is_empty());
    }
}
