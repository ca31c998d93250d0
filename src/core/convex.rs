//! Closed convex meshes (a shoebox, any convex polyhedral room): a ray that starts inside
//! leaves through the face plane it reaches first, so its closest hit is the smallest of a
//! few plane distances and one point-in-triangle test, with no triangle test at all.
//!
//! The exit distance of a ray `o + t d` through the plane `n . x = c` (outward unit normal
//! `n`) is `t = (c - n . o) / (n . d)` for the planes with `n . d > 0`; from inside every
//! such `t` is non-negative and the smallest is where the ray leaves the polyhedron
//! (\[Haines1991\] in docs/references.md; docs/performance.md).
//! The query reports that it does not apply (the caller then runs the triangle test) when
//! the origin is not inside every plane or the exit is at or before `t_min`.

use glam::{DVec3, Vec2, Vec3, Vec4};

/// Planes per chunk of the plane test (one SSE vector).
const CHUNK: usize = 4;
/// At most this many distinct face planes take the plane test.
pub const MAX_PLANES: usize = 4 * CHUNK;

/// The answer of [`ConvexRoom::exit`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Exit {
    /// The ray leaves through the triangle in flat slot `slot` at `t`, barycentrics `uv`.
    Hit {
        /// Flat slot of the triangle.
        slot: u32,
        /// Ray parameter of the exit.
        t: f32,
        /// Barycentric coordinates of the exit point.
        uv: Vec2,
    },
    /// The ray stays inside up to `t_max`.
    Miss,
    /// The plane test does not apply to this ray: run the triangle test.
    Unknown,
}

/// One triangle of a face plane: its slot and what gives its barycentric coordinates of a
/// point `p` of the plane, `u = (p - v0) . du`, `v = (p - v0) . dv`.
#[derive(Clone, Copy, Debug)]
struct Face {
    slot: u32,
    v0: Vec3,
    du: Vec3,
    dv: Vec3,
}

/// A closed convex mesh as its face planes (structure of arrays, padded with planes no ray
/// reaches) and the triangles of each plane.
#[derive(Clone, Debug)]
pub struct ConvexRoom {
    /// Outward normal x, y, z and offset `c` of each plane, [`CHUNK`] planes a vector.
    chunks: Vec<[Vec4; 4]>,
    /// Faces of plane `p` are `faces[first[p]..first[p + 1]]`.
    first: Vec<u32>,
    faces: Vec<Face>,
}

impl ConvexRoom {
    /// The plane form of the triangles (`(slot, corners)`), when they close a convex
    /// polyhedron of at most [`MAX_PLANES`] face planes: every edge is shared by exactly two
    /// triangles (same corner coordinates), every triangle has an area, and no corner lies
    /// outside any triangle's plane. `None` otherwise.
    pub fn new(triangles: &[(u32, [Vec3; 3])]) -> Option<Self> {
        if triangles.len() < 4 || !edges_closed(triangles) {
            return None;
        }
        let corners: Vec<DVec3> = triangles.iter().flat_map(|(_, c)| c.map(|v| v.as_dvec3())).collect();
        let centre = corners.iter().sum::<DVec3>() / corners.len() as f64;
        let size = corners.iter().map(|v| (*v - centre).abs().max_element()).fold(0.0, f64::max);
        let tolerance = 1e-6 * size.max(1e-30);
        // (outward normal, offset, faces)
        let mut planes: Vec<(DVec3, f64, Vec<Face>)> = Vec::new();
        for &(slot, [a, b, c]) in triangles {
            let (a, b, c) = (a.as_dvec3(), b.as_dvec3(), c.as_dvec3());
            let cross = (b - a).cross(c - a);
            let area2 = cross.length();
            if area2.is_nan() || area2 <= tolerance * tolerance {
                return None;
            }
            let mut n = cross / area2;
            if n.dot(centre - a) > 0.0 {
                n = -n;
            }
            let offset = n.dot(a);
            if corners.iter().any(|v| n.dot(*v) - offset > tolerance) {
                return None;
            }
            let face = face(slot, a, b, c)?;
            match planes.iter_mut().find(|(m, o, _)| m.dot(n) > 1.0 - 1e-9 && (o - offset).abs() <= tolerance)
            {
                Some((_, _, faces)) => faces.push(face),
                None => planes.push((n, offset, vec![face])),
            }
        }
        if planes.len() > MAX_PLANES {
            return None;
        }
        let chunks = planes.len().div_ceil(CHUNK);
        // Padding planes: n = 0, c = 1 (every point inside, no direction leaves).
        let mut room = Self {
            chunks: vec![[Vec4::ZERO, Vec4::ZERO, Vec4::ZERO, Vec4::ONE]; chunks],
            first: vec![0],
            faces: Vec::new(),
        };
        for (p, (n, offset, faces)) in planes.into_iter().enumerate() {
            let (k, lane) = (p / CHUNK, p % CHUNK);
            let n = n.as_vec3();
            let [nx, ny, nz, c] = &mut room.chunks[k];
            (nx[lane], ny[lane], nz[lane], c[lane]) = (n.x, n.y, n.z, offset as f32);
            room.faces.extend(faces);
            room.first.push(room.faces.len() as u32);
        }
        Some(room)
    }

    /// Where the ray `origin + t dir` leaves the room on `(t_min, t_max]`.
    #[inline(always)]
    pub fn exit(&self, origin: Vec3, dir: Vec3, t_min: f32, t_max: f32) -> Exit {
        let (ox, oy, oz) = (Vec4::splat(origin.x), Vec4::splat(origin.y), Vec4::splat(origin.z));
        let (dx, dy, dz) = (Vec4::splat(dir.x), Vec4::splat(dir.y), Vec4::splat(dir.z));
        let mut ts = [Vec4::INFINITY; MAX_PLANES / CHUNK];
        let mut nearest = Vec4::INFINITY;
        let mut outside = false;
        for (t, [nx, ny, nz, c]) in ts.iter_mut().zip(&self.chunks) {
            let gap = *c - (*nx * ox + *ny * oy + *nz * oz);
            let speed = *nx * dx + *ny * dy + *nz * dz;
            outside |= gap.cmplt(Vec4::ZERO).any();
            *t = Vec4::select(speed.cmpgt(Vec4::ZERO), gap / speed, Vec4::INFINITY);
            nearest = nearest.min(*t);
        }
        let best_t = nearest.min_element();
        // The first plane at that distance.
        let mut best = usize::MAX;
        for (k, t) in ts.iter().enumerate().take(self.chunks.len()) {
            let at = t.cmpeq(Vec4::splat(best_t)).bitmask();
            if at != 0 {
                best = k * CHUNK + at.trailing_zeros() as usize;
                break;
            }
        }
        if outside || best == usize::MAX || best_t.is_nan() || best_t <= t_min {
            return Exit::Unknown;
        }
        if best_t > t_max {
            return Exit::Miss;
        }
        let point = origin + best_t * dir;
        let (Some(&from), Some(&to)) = (self.first.get(best), self.first.get(best + 1)) else {
            return Exit::Unknown;
        };
        let faces = self.faces.get(from as usize..to as usize).unwrap_or_default();
        // The face holding the point; off every face by rounding (an edge), the nearest one.
        let mut pick = (f32::NEG_INFINITY, 0, Vec2::ZERO);
        for f in faces {
            let q = point - f.v0;
            let uv = Vec2::new(q.dot(f.du), q.dot(f.dv));
            let inside = uv.x.min(uv.y).min(1.0 - uv.x - uv.y);
            if inside > pick.0 {
                pick = (inside, f.slot, uv);
                if inside >= 0.0 {
                    break;
                }
            }
        }
        Exit::Hit { slot: pick.1, t: best_t, uv: pick.2 }
    }
}

/// The face record of triangle `slot` with corners `a`, `b`, `c`: the dual vectors of its
/// edges, so that `(p - a) . du` and `(p - a) . dv` are the weights of `b` and `c`.
fn face(slot: u32, a: DVec3, b: DVec3, c: DVec3) -> Option<Face> {
    let (e1, e2) = (b - a, c - a);
    let (g11, g12, g22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let det = g11 * g22 - g12 * g12;
    if det.is_nan() || det <= 0.0 {
        return None;
    }
    let du = (g22 * e1 - g12 * e2) / det;
    let dv = (g11 * e2 - g12 * e1) / det;
    Some(Face { slot, v0: a.as_vec3(), du: du.as_vec3(), dv: dv.as_vec3() })
}

/// Whether every edge (by its corners' exact coordinates) belongs to exactly two triangles.
fn edges_closed(triangles: &[(u32, [Vec3; 3])]) -> bool {
    let key = |v: Vec3| v.to_array().map(f32::to_bits);
    let mut edges: Vec<([u32; 3], [u32; 3])> = triangles
        .iter()
        .flat_map(|(_, c)| {
            [(c[0], c[1]), (c[1], c[2]), (c[2], c[0])].map(|(p, q)| {
                let (p, q) = (key(p), key(q));
                if p <= q { (p, q) } else { (q, p) }
            })
        })
        .collect();
    edges.sort_unstable();
    edges.chunk_by(|x, y| x == y).all(|run| run.len() == 2 && run[0].0 != run[0].1)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::TriangleMesh;
    use crate::core::ray::Ray;

    fn boxed(min: Vec3, max: Vec3) -> Vec<(u32, [Vec3; 3])> {
        let mut mesh = TriangleMesh::default();
        let s = mesh.surface_id("wall");
        mesh.push_box(min, max, 1, s);
        (0..mesh.triangle_count()).map(|i| (i as u32, mesh.corners(i))).collect()
    }

    #[test]
    fn a_box_is_a_convex_room_and_rays_leave_where_the_triangles_say() {
        let tris = boxed(Vec3::new(-3.0, -4.0, 0.0), Vec3::new(7.0, 4.0, 3.0));
        let room = ConvexRoom::new(&tris).expect("a closed box is convex");
        let mut rng = crate::core::rng::stream(5, 0, 0);
        for _ in 0..10_000 {
            let u = crate::core::rng::uniform;
            let o = Vec3::new(-3.0 + 10.0 * u(&mut rng), -4.0 + 8.0 * u(&mut rng), 3.0 * u(&mut rng));
            let d = crate::core::sampling::uniform_sphere(Vec2::new(u(&mut rng), u(&mut rng)));
            // The reference: every triangle tested.
            let reference = tris
                .iter()
                .filter_map(|(slot, [a, b, c])| {
                    crate::core::TriangleRt::new(*a, *b, *c)
                        .intersect(&Ray::new(o, d))
                        .map(|(t, uv)| (t, *slot, uv))
                })
                .min_by(|a, b| a.0.total_cmp(&b.0));
            let Exit::Hit { slot, t, uv } = room.exit(o, d, 0.0, f32::INFINITY) else {
                panic!("no exit from {o} along {d}")
            };
            let (rt, rslot, ruv) = reference.expect("a ray inside a box hits it");
            assert!((t - rt).abs() <= 1e-4 * rt.max(1.0), "{t} vs {rt}");
            let p = o + t * d;
            let [a, b, c] = tris[slot as usize].1;
            let q = (1.0 - uv.x - uv.y) * a + uv.x * b + uv.y * c;
            assert!((p - q).length() < 1e-4, "{p} vs {q}");
            if rslot != slot {
                // Only on a shared edge can two triangles both hold the point.
                assert!(ruv.x.min(ruv.y).min(1.0 - ruv.x - ruv.y) < 1e-4, "{rslot} vs {slot}");
            }
            assert_eq!(room.exit(o, d, 0.0, 0.5 * rt), Exit::Miss);
        }
        // From outside the plane test does not apply.
        assert_eq!(room.exit(Vec3::new(20.0, 0.0, 1.0), Vec3::NEG_X, 0.0, f32::INFINITY), Exit::Unknown);
    }

    #[test]
    fn open_or_concave_meshes_are_not_convex_rooms() {
        let mut tris = boxed(Vec3::ZERO, Vec3::ONE);
        assert!(ConvexRoom::new(&tris).is_some());
        // Without its last triangle the box is open.
        tris.pop();
        assert!(ConvexRoom::new(&tris).is_none());
        // Two boxes side by side: closed, but the union is not one convex polyhedron.
        let mut two = boxed(Vec3::ZERO, Vec3::ONE);
        two.extend(boxed(Vec3::new(2.0, 0.0, 0.0), Vec3::new(3.0, 1.0, 1.0)));
        assert!(ConvexRoom::new(&two).is_none());
        // A closed cube whose top is a pyramid pointing inwards: concave.
        let mut dented = boxed(Vec3::ZERO, Vec3::ONE);
        assert!(dented[2].1.iter().chain(&dented[3].1).all(|v| v.z == 1.0), "triangles 2, 3 are the top");
        dented.drain(2..4);
        let apex = Vec3::splat(0.5);
        let top = [Vec3::new(0.0, 0.0, 1.0), Vec3::new(1.0, 0.0, 1.0), Vec3::ONE, Vec3::new(0.0, 1.0, 1.0)];
        for k in 0..4 {
            dented.push((20 + k as u32, [top[k], top[(k + 1) % 4], apex]));
        }
        assert!(edges_closed(&dented));
        assert!(ConvexRoom::new(&dented).is_none());
    }
}
