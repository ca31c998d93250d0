//! The specular-path engine: every exact specular path from a source point to a receiver
//! point in a triangle mesh, by the image-source method (Allen & Berkley 1979 for the
//! rectangular room; Borish 1984 for arbitrary polyhedra), each path checked by tracing it
//! through the scene. Every simulator asks this one engine, so one room gives the same paths
//! whatever travels along them; the simulator then applies its own payload (energy and
//! surface losses for sound, complex fields and Fresnel coefficients for radio).
//!
//! 1. **Planes.** Coplanar triangles share a plane ([`Planes::of`]): normals (up to sign)
//!    within [`NORMAL_TOLERANCE`] per component and offsets within [`OFFSET_TOLERANCE_M`].
//! 2. **Images.** Mirroring the source in one plane after another (never the same plane twice
//!    in a row) gives one candidate image per plane sequence, up to an order that keeps the
//!    count of candidates within [`MAX_IMAGES`] ([`affordable_order`]), so large meshes
//!    stay affordable at a lower order.
//! 3. **Validation** (Borish 1984: an image is valid only if its path stays inside the
//!    actual faces and is visible): a candidate is unfolded back from the receiver (the
//!    reflection point on plane `k` lies on the line from image `k` to the point after it,
//!    and both must be on opposite sides of the plane, so the path reflects rather than
//!    passes through it), then each leg is traced from the receiver's end in the whole
//!    [`Accel`] (mesh and analytic spheres): nothing may be hit before the reflection point,
//!    and a triangle of the expected plane must hold the point (faces are closed: a point on
//!    an edge counts, whichever face a ray grazing that edge happens to meet); the last leg
//!    must reach the source unobstructed. Hits on the plane a leg starts from are skipped: a
//!    straight leg cannot meet its own plane again, and skipping it needs no offset that a
//!    grazing leg or a slightly non-coplanar triangle could defeat.
//!
//! Positions are f64 (images of high order far from the origin); rays are traced in the
//! mesh's f32.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::DVec3;
use rayon::prelude::*;

use super::accel::Accel;
use super::hit::{Hit, PrimitiveKind, SurfaceId};
use super::mesh::TriangleMesh;
use super::ray::Ray;

/// Two triangles lie in one plane when every component of their unit normals (up to sign)
/// differs by less than this (about 1e-4 rad)...
pub const NORMAL_TOLERANCE: f64 = 1.0e-4;
/// ... and their offsets `n . x` differ by less than this, metres: f32 corners of a scene a
/// few km across are 1e-4 m apart, and a millimetre is far below any wavelength simulated.
pub const OFFSET_TOLERANCE_M: f64 = 1.0e-3;
/// Largest number of candidate images (plane sequences, the direct path included) one search
/// may try; the order is lowered until the count fits ([`affordable_order`]).
pub const MAX_IMAGES: f64 = 2.0e6;
/// Highest reflection order searched, whatever the caller asks.
pub const MAX_ORDER: u32 = 64;
/// An image closer than this to a plane, metres, is not mirrored in it (it would mirror onto
/// itself: no path reflects there).
const IMAGE_ON_PLANE_M: f64 = 1.0e-6;
/// How far a traced hit may lie from the exact point it stands for, metres: the merging
/// tolerance plus f32 rounding of the coordinates and the leg's length.
fn reach(from: DVec3, to: DVec3) -> f64 {
    OFFSET_TOLERANCE_M + 1e-5 * (from.distance(to) + from.abs().max_element())
}

/// The legs at the source and the receiver stop this fraction of their length short of them.
const END_MARGIN: f64 = 1.0e-6;
/// Hits on a leg's own start plane skipped before the leg is declared unsure (and rejected).
const MAX_SKIPS: usize = 8;

/// A plane `normal . x = offset` with a unit normal.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Unit normal.
    pub normal: DVec3,
    /// Offset along the normal, metres.
    pub offset: f64,
}

impl Plane {
    /// Signed distance of `p` from the plane, along the normal.
    #[inline]
    pub fn distance(&self, p: DVec3) -> f64 {
        self.normal.dot(p) - self.offset
    }

    /// Mirror image of `p` in the plane.
    #[inline]
    pub fn mirror(&self, p: DVec3) -> DVec3 {
        p - 2.0 * self.distance(p) * self.normal
    }
}

/// Marks a triangle with no plane (zero area or non-finite corners).
const NO_PLANE: u32 = u32::MAX;

/// The distinct planes of a mesh; coplanar triangles, facing either way, share one.
#[derive(Clone, Debug, Default)]
pub struct Planes {
    planes: Vec<Plane>,
    plane_of_triangle: Vec<u32>,
}

/// A triangle's unit normal, canonically oriented (its largest component positive), offset
/// and area; `None` for a degenerate triangle.
fn triangle_plane(mesh: &TriangleMesh, t: usize) -> Option<(Plane, f64, DVec3)> {
    let [a, b, c] = mesh.corners(t).map(|v| v.as_dvec3());
    let cross = (b - a).cross(c - a);
    let twice_area = cross.length();
    if !(twice_area > 0.0 && twice_area.is_finite()) {
        return None;
    }
    let mut n = cross / twice_area;
    let m = n.abs();
    let largest = if m.x >= m.y && m.x >= m.z {
        n.x
    } else if m.y >= m.z {
        n.y
    } else {
        n.z
    };
    if largest < 0.0 {
        n = -n;
    }
    let centroid = (a + b + c) / 3.0;
    Some((Plane { normal: n, offset: n.dot(centroid) }, 0.5 * twice_area, centroid))
}

/// Hash-grid cell of a plane over its normal's x and y and its offset (z adds little: a unit
/// normal's z follows from x and y up to sign), cells four times the tolerances wide: a plane
/// within tolerance of another lies in its cell or, along each coordinate in the outer
/// quarter of its cell, in the neighbouring cell on that side.
fn plane_cell(p: &Plane) -> ([i64; 3], [i64; 3]) {
    let scaled = [
        p.normal.x / (4.0 * NORMAL_TOLERANCE),
        p.normal.y / (4.0 * NORMAL_TOLERANCE),
        p.offset / (4.0 * OFFSET_TOLERANCE_M),
    ];
    let cell = scaled.map(|s| s.round() as i64);
    let lean = std::array::from_fn(|i| {
        let r = scaled[i] - cell[i] as f64;
        if r > 0.25 {
            1
        } else if r < -0.25 {
            -1
        } else {
            0
        }
    });
    (cell, lean)
}

/// Whether the canonical orientation (largest normal component positive) is ambiguous: two
/// components so close in size that a nearly equal plane may have been flipped the other way.
fn orientation_ambiguous(n: DVec3) -> bool {
    let m = n.abs();
    let largest = m.max_element();
    [m.x, m.y, m.z].iter().filter(|&&c| c > largest - 2.0 * NORMAL_TOLERANCE).count() > 1
}

/// A multiply-rotate hash (after rustc's FxHasher) for the integer keys of the plane grid:
/// several times faster than the default SipHash, which guards against adversarial keys
/// that a mesh's planes are not.
#[derive(Default)]
struct CellHasher(u64);

impl Hasher for CellHasher {
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }

    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(5) ^ x).wrapping_mul(0x517c_c1b7_2722_0a95);
    }

    fn write_i64(&mut self, x: i64) {
        self.write_u64(x as u64);
    }

    fn write_usize(&mut self, x: usize) {
        self.write_u64(x as u64);
    }

    fn finish(&self) -> u64 {
        self.0
    }
}

fn same_plane(p: &Plane, q: &Plane) -> bool {
    (p.normal - q.normal).abs().max_element() < NORMAL_TOLERANCE
        && (p.offset - q.offset).abs() < OFFSET_TOLERANCE_M
}

impl Planes {
    /// Groups the triangles of `mesh` by plane: a triangle joins the first plane found within
    /// [`NORMAL_TOLERANCE`] and [`OFFSET_TOLERANCE_M`] of its own (either orientation), and
    /// each plane is then refitted as its triangles' area-weighted mean. Planes are numbered
    /// in the order of their first triangle.
    pub fn of(mesh: &TriangleMesh) -> Self {
        // Each cell holds a chain of planes, first found first: (head, tail) here, the links
        // in `next_in_cell`.
        let mut cells: HashMap<[i64; 3], (u32, u32), BuildHasherDefault<CellHasher>> = HashMap::default();
        let mut next_in_cell: Vec<u32> = Vec::new();
        let mut first: Vec<Plane> = Vec::new();
        let mut plane_of_triangle = Vec::with_capacity(mesh.triangle_count());
        for t in 0..mesh.triangle_count() {
            let Some((plane, _, _)) = triangle_plane(mesh, t) else {
                plane_of_triangle.push(NO_PLANE);
                continue;
            };
            let flipped = Plane { normal: -plane.normal, offset: -plane.offset };
            let orientations = if orientation_ambiguous(plane.normal) { 2 } else { 1 };
            let mut found = None;
            'search: for candidate in [plane, flipped].into_iter().take(orientations) {
                let (cell, lean) = plane_cell(&candidate);
                for corner in 0..8 {
                    if (0..3).any(|i| corner >> i & 1 == 1 && lean[i] == 0) {
                        continue;
                    }
                    let key: [i64; 3] =
                        std::array::from_fn(|i| cell[i] + if corner >> i & 1 == 1 { lean[i] } else { 0 });
                    let mut id = cells.get(&key).map_or(NO_PLANE, |c| c.0);
                    while id != NO_PLANE {
                        if same_plane(&candidate, &first[id as usize]) {
                            found = Some(id);
                            break 'search;
                        }
                        id = next_in_cell[id as usize];
                    }
                }
            }
            let id = found.unwrap_or_else(|| {
                let id = first.len() as u32;
                first.push(plane);
                next_in_cell.push(NO_PLANE);
                let chain = cells.entry(plane_cell(&plane).0).or_insert((id, id));
                if chain.1 != id {
                    next_in_cell[chain.1 as usize] = id;
                    chain.1 = id;
                }
                id
            });
            plane_of_triangle.push(id);
        }
        drop(cells);
        // Refit: the area-weighted mean normal (each triangle's turned to its plane's side),
        // then the mean offset along it.
        let mut normal_sum = vec![DVec3::ZERO; first.len()];
        let mut offset_sum = vec![(0.0, 0.0); first.len()];
        for (t, &id) in plane_of_triangle.iter().enumerate() {
            if let Some((p, area, _)) = triangle_plane(mesh, t).filter(|_| id != NO_PLANE) {
                let side = if p.normal.dot(first[id as usize].normal) >= 0.0 { 1.0 } else { -1.0 };
                normal_sum[id as usize] += side * area * p.normal;
            }
        }
        let normals: Vec<DVec3> =
            normal_sum.iter().zip(&first).map(|(s, p)| s.try_normalize().unwrap_or(p.normal)).collect();
        for (t, &id) in plane_of_triangle.iter().enumerate() {
            if let Some((_, area, centroid)) = triangle_plane(mesh, t).filter(|_| id != NO_PLANE) {
                let s = &mut offset_sum[id as usize];
                s.0 += area * normals[id as usize].dot(centroid);
                s.1 += area;
            }
        }
        let planes = normals
            .iter()
            .zip(&offset_sum)
            .map(|(&normal, &(sum, area))| Plane { normal, offset: sum / area })
            .collect();
        Self { planes, plane_of_triangle }
    }

    /// Number of planes.
    pub fn len(&self) -> usize {
        self.planes.len()
    }

    /// Whether there is no plane.
    pub fn is_empty(&self) -> bool {
        self.planes.is_empty()
    }

    /// Every plane, by index.
    pub fn planes(&self) -> &[Plane] {
        &self.planes
    }

    /// The plane of mesh triangle `triangle`; `None` for a degenerate or unknown triangle.
    pub fn plane_of_triangle(&self, triangle: u32) -> Option<u32> {
        self.plane_of_triangle.get(triangle as usize).copied().filter(|&p| p != NO_PLANE)
    }
}

/// The highest order up to `max_order` (and [`MAX_ORDER`]) whose candidate images over
/// `planes` planes number at most [`MAX_IMAGES`]: `1 + P + P (P - 1) + P (P - 1)^2 + ...`
/// (the direct path, then each order's sequences with no plane twice in a row). Whole orders
/// only, so that no plane is favoured within an order.
pub fn affordable_order(planes: usize, max_order: u32) -> u32 {
    let max_order = max_order.min(MAX_ORDER);
    let p = planes as f64;
    let (mut total, mut level) = (1.0, 1.0);
    for order in 1..=max_order {
        level *= if order == 1 { p } else { p - 1.0 };
        if total + level > MAX_IMAGES {
            return order - 1;
        }
        total += level;
    }
    max_order
}

/// One reflection of a specular path.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Reflection {
    /// Index of the plane in [`Planes`].
    pub plane: u32,
    /// The mesh triangle the path meets there, and its surface.
    pub triangle: u32,
    /// The triangle's surface.
    pub surface: SurfaceId,
    /// The exact reflection point, on the plane.
    pub point: DVec3,
    /// Unit normal of the plane, on the side the path is on.
    pub normal: DVec3,
    /// Cosine of the angle of incidence (between the incoming leg and the normal), in (0, 1].
    pub cos_incidence: f64,
}

/// A valid specular path from a source to a receiver.
#[derive(Clone, Debug, PartialEq)]
pub struct SpecularPath {
    /// Source position, metres.
    pub source: DVec3,
    /// Receiver position, metres.
    pub receiver: DVec3,
    /// The reflections, first (nearest the source) first; empty for the direct path.
    pub reflections: Vec<Reflection>,
    /// Total length, metres.
    pub length_m: f64,
}

impl SpecularPath {
    /// Number of reflections.
    pub fn order(&self) -> usize {
        self.reflections.len()
    }

    /// The vertices: the source, each reflection point, the receiver.
    pub fn points(&self) -> Vec<DVec3> {
        let mut p = Vec::with_capacity(self.reflections.len() + 2);
        p.push(self.source);
        p.extend(self.reflections.iter().map(|r| r.point));
        p.push(self.receiver);
        p
    }

    /// The surface of each reflection, first reflection first.
    pub fn surfaces(&self) -> impl Iterator<Item = SurfaceId> + '_ {
        self.reflections.iter().map(|r| r.surface)
    }
}

/// Every valid specular path from `source` to `receiver` with at most `max_order`
/// reflections (lowered to [`affordable_order`] over `planes`): the direct path first if it
/// is free, then the reflected paths in depth-first order of their plane sequences (planes
/// in index order). The result does not depend on the thread count.
pub fn specular_paths(
    accel: &Accel,
    planes: &Planes,
    source: DVec3,
    receiver: DVec3,
    max_order: u32,
) -> Vec<SpecularPath> {
    if !(source.as_vec3().is_finite() && receiver.as_vec3().is_finite()) {
        return Vec::new();
    }
    let order = affordable_order(planes.len(), max_order);
    let search = Search { accel, planes, receiver };
    let mut out: Vec<SpecularPath> = search.validate(&[], &[source], &mut Vec::new()).into_iter().collect();
    if order == 0 {
        return out;
    }
    let by_first: Vec<Vec<SpecularPath>> = (0..planes.len() as u32)
        .into_par_iter()
        .map(|first| {
            let mut found = Vec::new();
            let mut state = State {
                seq: Vec::with_capacity(order as usize),
                images: vec![source],
                points: Vec::with_capacity(order as usize + 2),
            };
            search.descend(first, order - 1, &mut state, &mut found);
            found
        })
        .collect();
    out.extend(by_first.into_iter().flatten());
    out
}

struct Search<'a> {
    accel: &'a Accel,
    planes: &'a Planes,
    receiver: DVec3,
}

/// The sequence being explored: its planes, the images (`images[0]` the source, `images[k]`
/// after `k` reflections), and scratch room for the unfolded points.
struct State {
    seq: Vec<u32>,
    images: Vec<DVec3>,
    points: Vec<DVec3>,
}

/// What a traced leg met first.
enum Seen {
    Nothing,
    Hit(Hit),
    /// Too many hits on the start plane: rejected rather than guessed.
    Unsure,
}

impl Search<'_> {
    /// Appends `plane` to the sequence, validates it, and explores `depth_left` more orders.
    fn descend(&self, plane: u32, depth_left: u32, state: &mut State, found: &mut Vec<SpecularPath>) {
        let Some(&from) = state.images.last() else { return };
        let p = self.planes.planes[plane as usize];
        if p.distance(from).abs() < IMAGE_ON_PLANE_M {
            return;
        }
        state.seq.push(plane);
        state.images.push(p.mirror(from));
        if let Some(path) = self.validate(&state.seq, &state.images, &mut state.points) {
            found.push(path);
        }
        if depth_left > 0 {
            for next in 0..self.planes.len() as u32 {
                if next != plane {
                    self.descend(next, depth_left - 1, state, found);
                }
            }
        }
        state.seq.pop();
        state.images.pop();
    }

    /// The path through the planes `seq` (images of the source in `images`), or `None` when
    /// it does not exist in the scene.
    fn validate(&self, seq: &[u32], images: &[DVec3], points: &mut Vec<DVec3>) -> Option<SpecularPath> {
        let n = seq.len();
        let source = *images.first()?;
        // Unfold from the receiver: points[k] is the k-th vertex (0 the source, n + 1 the
        // receiver); the reflection on plane seq[k - 1] is where the line from its image to
        // the next vertex crosses the plane.
        points.clear();
        points.resize(n + 2, source);
        points[n + 1] = self.receiver;
        for k in (1..=n).rev() {
            let plane = &self.planes.planes[seq[k - 1] as usize];
            let image = images[k];
            let next = points[k + 1];
            let (da, db) = (plane.distance(image), plane.distance(next));
            if (da * db).is_nan() || da * db >= 0.0 {
                return None;
            }
            points[k] = image + (next - image) * (da / (da - db));
        }
        let length_m: f64 = points.windows(2).map(|w| w[0].distance(w[1])).sum();
        if !(length_m > 0.0 && length_m.is_finite()) {
            return None;
        }
        // Trace back from the receiver: the leg from vertex k + 1 must first meet plane
        // seq[k - 1] at vertex k.
        let mut reflections = Vec::new();
        for k in (1..=n).rev() {
            let (from, to) = (points[k + 1], points[k]);
            let start = (k < n).then(|| seq[k]);
            let mut ray = self.leg(from, to, start)?;
            if k == n {
                ray.t_min = (END_MARGIN * from.distance(to)) as f32;
            }
            let want = seq[k - 1];
            // Up to the merging tolerance and f32 rounding, the closest hit must not come
            // before the reflection point: that would be an obstruction.
            let (dist, reach) = (from.distance(to), reach(from, to));
            let seen = self.first_hit(ray, start);
            let hit = match seen {
                Seen::Unsure => return None,
                Seen::Hit(h) if f64::from(h.t) < dist - reach => return None,
                Seen::Hit(h)
                    if h.kind == PrimitiveKind::Triangle
                        && self.planes.plane_of_triangle(h.primitive) == Some(want)
                        && h.point.as_dvec3().distance(to) <= reach =>
                {
                    h
                }
                // The leg reaches the point free but meets another face there, or passes it:
                // the point is outside the plane's polygons, or on an edge, where a ray
                // grazing the corner may meet either face or neither. Polygons are closed:
                // the reflection stands if a triangle of the plane holds the point.
                _ => self.triangle_at(to, want, reach)?,
            };
            let plane = &self.planes.planes[want as usize];
            let normal = if plane.distance(from) >= 0.0 { plane.normal } else { -plane.normal };
            let incoming = (to - points[k - 1]).normalize();
            reflections.push(Reflection {
                plane: want,
                triangle: hit.primitive,
                surface: hit.surface,
                point: to,
                normal,
                cos_incidence: incoming.dot(normal).abs().min(1.0),
            });
        }
        // The last leg, to the source, must be free. Like the first, it stops short of its
        // end point by END_MARGIN, so that a source or receiver on a surface is treated alike.
        let (from, start) = if n == 0 { (self.receiver, None) } else { (points[1], Some(seq[0])) };
        let mut last = self.leg(from, source, start)?;
        let origin = last.origin.as_dvec3();
        last.t_max = (source.distance(origin) * (1.0 - END_MARGIN)) as f32;
        if n == 0 {
            last.t_min = (END_MARGIN * length_m) as f32;
        }
        if self.accel.occluded(&last) && !matches!(self.first_hit(last, start), Seen::Nothing) {
            return None;
        }
        reflections.reverse();
        Some(SpecularPath { source, receiver: self.receiver, reflections, length_m })
    }

    /// The unbounded ray from `from` towards `to`, pushed off plane `start` if it leaves one;
    /// `None` for coincident points.
    fn leg(&self, from: DVec3, to: DVec3, start: Option<u32>) -> Option<Ray> {
        let dir = (to - from).try_normalize()?.as_vec3();
        let origin = from.as_vec3();
        Some(match start {
            None => Ray::new(origin, dir),
            Some(p) => Ray::spawn(origin, self.planes.planes[p as usize].normal.as_vec3(), dir),
        })
    }

    /// A hit on a triangle of plane `plane` at `point` (the lowest-numbered if several), by a
    /// probe along the normal through it, `reach` either side.
    fn triangle_at(&self, point: DVec3, plane: u32, reach: f64) -> Option<Hit> {
        let n = self.planes.planes[plane as usize].normal;
        let probe = Ray::segment((point + n * reach).as_vec3(), (-n).as_vec3(), (2.0 * reach) as f32);
        let mut best: Option<Hit> = None;
        self.accel.mesh.for_each_hit(&probe, |h| {
            if self.planes.plane_of_triangle(h.primitive) == Some(plane)
                && best.is_none_or(|b| h.primitive < b.primitive)
            {
                best = Some(h);
            }
        });
        best
    }

    /// The closest hit of `ray` in the whole scene, skipping hits on plane `skip`.
    fn first_hit(&self, mut ray: Ray, skip: Option<u32>) -> Seen {
        for _ in 0..MAX_SKIPS {
            let Some(hit) = self.accel.closest_hit(&ray) else { return Seen::Nothing };
            let on_skip = hit.kind == PrimitiveKind::Triangle
                && skip.is_some()
                && self.planes.plane_of_triangle(hit.primitive) == skip;
            if !on_skip {
                return Seen::Hit(hit);
            }
            ray.t_min = hit.t;
        }
        Seen::Unsure
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;

    use super::*;
    use crate::core::{BuildQuality, Sphere};

    /// A closed box room `[0, size]`, each face split into 2 x 2 quads (coplanar triangles
    /// that must share one plane), on surface 0.
    fn shoebox(size: DVec3) -> TriangleMesh {
        let mut mesh = TriangleMesh::default();
        let s = mesh.surface_id("wall");
        mesh.push_box(Vec3::ZERO, size.as_vec3(), 2, s);
        mesh.flip_winding();
        mesh
    }

    /// A lattice path: order, length and vertices.
    type Expected = (usize, f64, Vec<DVec3>);

    /// Allen & Berkley's image sources of a box `[0, L]` up to `max_order`: along each axis
    /// the image coordinate is `(1 - 2q) s + 2 n L` after `|2n - q|` reflections (q = 0, 1).
    /// Every one is a valid path in the (convex) box; its vertices are the points where the
    /// straight line from the image to the receiver crosses the planes `x = k L`, folded back
    /// into the box.
    fn lattice(s: DVec3, r: DVec3, size: DVec3, max_order: usize) -> Vec<Expected> {
        let axis = |a: usize| -> Vec<(f64, usize)> {
            let mut out = Vec::new();
            for q in 0..2i64 {
                for n in -(max_order as i64)..=max_order as i64 {
                    let order = (2 * n - q).unsigned_abs() as usize;
                    if order <= max_order {
                        out.push(((1 - 2 * q) as f64 * s[a] + 2.0 * n as f64 * size[a], order));
                    }
                }
            }
            out
        };
        let fold = |p: DVec3| {
            DVec3::from_array(std::array::from_fn(|a| {
                let m = p[a].rem_euclid(2.0 * size[a]);
                if m > size[a] { 2.0 * size[a] - m } else { m }
            }))
        };
        let mut out = Vec::new();
        for (x, ox) in axis(0) {
            for (y, oy) in axis(1) {
                for (z, oz) in axis(2) {
                    let order = ox + oy + oz;
                    if order > max_order {
                        continue;
                    }
                    let image = DVec3::new(x, y, z);
                    let mut ts = Vec::new();
                    for a in 0..3 {
                        let (lo, hi) = (image[a].min(r[a]), image[a].max(r[a]));
                        let first = (lo / size[a]).ceil() as i64;
                        for k in first..=(hi / size[a]).floor() as i64 {
                            ts.push((k as f64 * size[a] - image[a]) / (r[a] - image[a]));
                        }
                    }
                    ts.sort_by(f64::total_cmp);
                    assert_eq!(ts.len(), order);
                    let mut points = vec![s];
                    points.extend(ts.iter().map(|&t| fold(image + t * (r - image))));
                    points.push(r);
                    out.push((order, image.distance(r), points));
                }
            }
        }
        out
    }

    fn sorted(mut v: Vec<Expected>) -> Vec<Expected> {
        v.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        v
    }

    fn found(paths: &[SpecularPath]) -> Vec<Expected> {
        sorted(paths.iter().map(|p| (p.order(), p.length_m, p.points())).collect())
    }

    /// Same paths: each expected one matched by a distinct found one of the same order,
    /// length and vertices (to 1e-9 m).
    fn assert_same(got: &[Expected], want: &[Expected]) {
        assert_eq!(got.len(), want.len(), "path count");
        let mut used = vec![false; got.len()];
        for w in want {
            let same = |g: &Expected| {
                g.0 == w.0
                    && (g.1 - w.1).abs() < 1e-9
                    && g.2.iter().zip(&w.2).all(|(a, b)| a.distance(*b) < 1e-9)
            };
            let Some(i) = (0..got.len()).find(|&i| !used[i] && same(&got[i])) else {
                panic!("no path of order {} and length {} with vertices {:?}", w.0, w.1, w.2);
            };
            used[i] = true;
        }
    }

    /// Whether the segment `a b` passes through the open box `(lo, hi)` (slab clipping).
    fn crosses_box(a: DVec3, b: DVec3, lo: DVec3, hi: DVec3) -> bool {
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for k in 0..3 {
            let d = b[k] - a[k];
            if d == 0.0 {
                if a[k] <= lo[k] || a[k] >= hi[k] {
                    return false;
                }
                continue;
            }
            let (u, v) = ((lo[k] - a[k]) / d, (hi[k] - a[k]) / d);
            t0 = t0.max(u.min(v));
            t1 = t1.min(u.max(v));
        }
        t1 - t0 > 1e-9
    }

    const SIZE: DVec3 = DVec3::new(7.25, 5.125, 3.5);

    #[test]
    fn shoebox_paths_are_allen_and_berkleys_images() {
        let mesh = shoebox(SIZE);
        let planes = Planes::of(&mesh);
        assert_eq!(planes.len(), 6);
        let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
        let s = DVec3::new(1.75, 3.875, 1.125);
        for r in [DVec3::new(5.625, 1.3125, 2.375), DVec3::new(3.0625, 2.5, 0.625)] {
            let want = sorted(lattice(s, r, SIZE, 3));
            // 1 + 6 + 18 + 38 images of orders 0 to 3.
            assert_eq!(want.len(), 63);
            let paths = specular_paths(&accel, &planes, s, r, 3);
            assert_same(&found(&paths), &want);
            // The geometry of each reflection: on a triangle of its plane, the normal facing
            // the path, the incidence cosine that of the leg arriving there.
            for p in &paths {
                let points = p.points();
                for (k, f) in p.reflections.iter().enumerate() {
                    assert_eq!(planes.plane_of_triangle(f.triangle), Some(f.plane));
                    let plane = planes.planes()[f.plane as usize];
                    assert!(plane.distance(f.point).abs() < 1e-12);
                    let incoming = (points[k + 1] - points[k]).normalize();
                    assert!(incoming.dot(f.normal) < 0.0);
                    assert!((f.cos_incidence + incoming.dot(f.normal)).abs() < 1e-12);
                    assert_eq!(f.surface, 0);
                }
            }
        }
        // The first floor image (1.75, 3.875, -1.125): cos = (1.125 + 0.625) / L.
        let r = DVec3::new(3.0625, 2.5, 0.625);
        let floor = specular_paths(&accel, &planes, s, r, 1)
            .into_iter()
            .find(|p| p.order() == 1 && p.reflections[0].normal == DVec3::Z)
            .unwrap();
        let length = DVec3::new(3.0625 - 1.75, 2.5 - 3.875, 0.625 + 1.125).length();
        assert!((floor.length_m - length).abs() < 1e-12);
        assert!((floor.reflections[0].cos_incidence - 1.75 / length).abs() < 1e-12);
    }

    #[test]
    fn paths_through_an_obstacle_are_rejected() {
        // A floating pillar in the shoebox: the room's lattice paths that cross it are
        // rejected, the others kept, and its own faces reflect.
        let mut mesh = shoebox(SIZE);
        let pillar = mesh.surface_id("pillar");
        let (lo, hi) = (DVec3::new(3.25, 2.0, 0.75), DVec3::new(4.0, 3.25, 2.5));
        mesh.push_box(lo.as_vec3(), hi.as_vec3(), 1, pillar);
        let planes = Planes::of(&mesh);
        assert_eq!(planes.len(), 12);
        let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
        let s = DVec3::new(1.25, 2.75, 1.5);
        for r in [DVec3::new(6.25, 2.5, 1.375), DVec3::new(2.0, 3.0, 1.625)] {
            let all = lattice(s, r, SIZE, 3);
            let want: Vec<Expected> = all
                .iter()
                .filter(|e| e.2.windows(2).all(|w| !crosses_box(w[0], w[1], lo, hi)))
                .cloned()
                .collect();
            let paths = specular_paths(&accel, &planes, s, r, 3);
            let on_walls: Vec<SpecularPath> =
                paths.iter().filter(|p| p.surfaces().all(|x| x == 0)).cloned().collect();
            assert_same(&found(&on_walls), &sorted(want.clone()));
            // No path at all crosses the pillar.
            for p in &paths {
                assert!(p.points().windows(2).all(|w| !crosses_box(w[0], w[1], lo, hi)));
            }
            if r.x > hi.x {
                // Behind the pillar: the direct path and others are hidden.
                assert!(want.len() < all.len() && want.iter().all(|e| e.0 > 0));
            } else {
                // In front: the pillar's face x = 3.25 reflects the image (5.25, 2.75, 1.5).
                let image = DVec3::new(2.0 * lo.x - s.x, s.y, s.z);
                let face =
                    paths.iter().find(|p| p.order() == 1 && p.reflections[0].surface == pillar).unwrap();
                assert!((face.length_m - image.distance(r)).abs() < 1e-9);
            }
        }
    }

    #[test]
    fn a_sphere_blocks_the_paths_through_it() {
        let mesh = shoebox(SIZE);
        let planes = Planes::of(&mesh);
        let (s, r) = (DVec3::new(1.75, 3.875, 1.125), DVec3::new(5.625, 1.3125, 2.375));
        let (centre, radius) = ((s + r) / 2.0, 0.5);
        let accel = Accel::build(
            &mesh,
            vec![Sphere::new(centre.as_vec3(), radius as f32, 7)],
            BuildQuality::default(),
        );
        // Distance from the centre to the segment a b.
        let miss = |a: DVec3, b: DVec3| {
            let t = ((centre - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            (a + t * (b - a)).distance(centre)
        };
        let all = lattice(s, r, SIZE, 3);
        for e in &all {
            for w in e.2.windows(2) {
                // No leg grazes the sphere: the expectation is unambiguous.
                assert!((miss(w[0], w[1]) - radius).abs() > 1e-3);
            }
        }
        let want: Vec<Expected> =
            all.iter().filter(|e| e.2.windows(2).all(|w| miss(w[0], w[1]) > radius)).cloned().collect();
        assert!(want.len() < all.len());
        assert!(want.iter().all(|e| e.0 > 0), "the direct path passes through the centre");
        assert_same(&found(&specular_paths(&accel, &planes, s, r, 3)), &sorted(want));
    }

    /// The L-shaped room `[0,8]x[0,4] u [0,4]x[0,8]`, 3 m high, with its long walls and the
    /// floor and ceiling split into several quads.
    fn l_room() -> TriangleMesh {
        let mut m = TriangleMesh::default();
        let s = m.surface_id("wall");
        let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        let wall = |m: &mut TriangleMesh, a: (f32, f32), b: (f32, f32)| {
            m.push_quad(v(a.0, a.1, 0.0), v(b.0, b.1, 0.0), v(b.0, b.1, 3.0), v(a.0, a.1, 3.0), s);
        };
        for (a, b) in [
            ((0.0, 0.0), (4.0, 0.0)),
            ((4.0, 0.0), (8.0, 0.0)),
            ((8.0, 0.0), (8.0, 4.0)),
            ((8.0, 4.0), (4.0, 4.0)),
            ((4.0, 4.0), (4.0, 8.0)),
            ((4.0, 8.0), (0.0, 8.0)),
            ((0.0, 8.0), (0.0, 4.0)),
            ((0.0, 4.0), (0.0, 0.0)),
        ] {
            wall(&mut m, a, b);
        }
        for z in [0.0, 3.0] {
            for (x0, y0) in [(0.0, 0.0), (4.0, 0.0), (0.0, 4.0)] {
                m.push_quad(
                    v(x0, y0, z),
                    v(x0 + 4.0, y0, z),
                    v(x0 + 4.0, y0 + 4.0, z),
                    v(x0, y0 + 4.0, z),
                    s,
                );
            }
        }
        m
    }

    /// The L room's paths by analytic geometry: each plane is an axis and a coordinate with
    /// the polygon it holds; a candidate is valid when its unfolded reflection points lie in
    /// their polygons and no leg enters the missing quadrant `(4,8)x(4,8)`. Also returns how
    /// many candidates each test rejected (outside a polygon, hidden).
    fn l_room_reference(s: DVec3, r: DVec3, max_order: usize) -> (Vec<(usize, f64)>, usize, usize) {
        let in_l = |x: f64, y: f64| {
            (0.0..=8.0).contains(&x) && (0.0..=4.0).contains(&y)
                || (0.0..=4.0).contains(&x) && (0.0..=8.0).contains(&y)
        };
        let span = |lo: f64, hi: f64| move |c: f64| (lo..=hi).contains(&c);
        // (axis, coordinate, inside test on the point).
        type Inside = Box<dyn Fn(DVec3) -> bool>;
        let (sx, sy) = (span(0.0, 8.0), span(0.0, 4.0));
        let (hx, hy, vy, low_z) = (span(4.0, 8.0), span(4.0, 8.0), span(0.0, 8.0), span(0.0, 3.0));
        let planes: Vec<(usize, f64, Inside)> = vec![
            (1, 0.0, Box::new(move |p: DVec3| sx(p.x) && low_z(p.z))),
            (0, 8.0, Box::new(move |p: DVec3| sy(p.y) && low_z(p.z))),
            (1, 4.0, Box::new(move |p: DVec3| hx(p.x) && low_z(p.z))),
            (0, 4.0, Box::new(move |p: DVec3| hy(p.y) && low_z(p.z))),
            (1, 8.0, Box::new(move |p: DVec3| span(0.0, 4.0)(p.x) && low_z(p.z))),
            (0, 0.0, Box::new(move |p: DVec3| vy(p.y) && low_z(p.z))),
            (2, 0.0, Box::new(move |p: DVec3| in_l(p.x, p.y))),
            (2, 3.0, Box::new(move |p: DVec3| in_l(p.x, p.y))),
        ];
        let hidden =
            |a: DVec3, b: DVec3| crosses_box(a, b, DVec3::new(4.0, 4.0, -1.0), DVec3::new(8.0, 8.0, 4.0));
        let (mut valid, mut outside, mut blocked) = (Vec::new(), 0, 0);
        let mut stack: Vec<Vec<usize>> = vec![vec![]];
        while let Some(seq) = stack.pop() {
            if seq.len() < max_order {
                for j in 0..planes.len() {
                    if seq.last() != Some(&j) {
                        let mut next = seq.clone();
                        next.push(j);
                        stack.push(next);
                    }
                }
            }
            let mut images = vec![s];
            for &j in &seq {
                let (a, c, _) = &planes[j];
                let mut i = *images.last().unwrap();
                i[*a] = 2.0 * c - i[*a];
                images.push(i);
            }
            let mut points = vec![r];
            let mut ok = true;
            for k in (0..seq.len()).rev() {
                let (a, c, inside) = &planes[seq[k]];
                let (image, next) = (images[k + 1], *points.last().unwrap());
                let (da, db) = (image[*a] - c, next[*a] - c);
                if da * db >= 0.0 {
                    ok = false;
                    break;
                }
                let p = image + (next - image) * (da / (da - db));
                if !inside(p) {
                    outside += 1;
                    ok = false;
                    break;
                }
                points.push(p);
            }
            if !ok {
                continue;
            }
            points.push(s);
            if points.windows(2).any(|w| hidden(w[0], w[1])) {
                blocked += 1;
                continue;
            }
            valid.push((seq.len(), images.last().unwrap().distance(r)));
        }
        valid.sort_by(|a, b| a.1.total_cmp(&b.1));
        (valid, outside, blocked)
    }

    #[test]
    fn an_l_shaped_room_rejects_the_invalid_images() {
        let mesh = l_room();
        let planes = Planes::of(&mesh);
        assert_eq!(planes.len(), 8);
        let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
        let s = DVec3::new(6.3, 1.7, 1.4);
        for (r, around_the_corner) in [(DVec3::new(1.9, 6.6, 1.1), true), (DVec3::new(2.2, 2.9, 1.7), false)]
        {
            let (want, outside, blocked) = l_room_reference(s, r, 3);
            assert!(outside > 0 && blocked > 0, "{outside} outside, {blocked} hidden");
            let paths = specular_paths(&accel, &planes, s, r, 3);
            let mut got: Vec<(usize, f64)> = paths.iter().map(|p| (p.order(), p.length_m)).collect();
            got.sort_by(|a, b| a.1.total_cmp(&b.1));
            assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(&want) {
                assert_eq!(g.0, w.0);
                assert!((g.1 - w.1).abs() < 1e-9, "{} against {}", g.1, w.1);
            }
            assert_eq!(got.first().map(|g| g.0 == 0), Some(!around_the_corner));
        }
    }

    #[test]
    fn the_image_budget_lowers_the_order_in_large_meshes() {
        // 1 + P + P (P - 1) + ... images: P = 6 affords order 3 (187), P = 1000 order 2
        // (1,000,001), P = 1415 order 1 (order 2 would be 2,002,226), P = 2e6 order 0.
        assert_eq!(affordable_order(6, 3), 3);
        assert_eq!(affordable_order(1000, 5), 2);
        assert_eq!(affordable_order(1414, 5), 2);
        assert_eq!(affordable_order(1415, 5), 1);
        assert_eq!(affordable_order(2_000_000, 3), 0);
        assert_eq!(affordable_order(0, 7), 7);
        assert_eq!(affordable_order(2, 1000), MAX_ORDER);
        // The shoebox plus 1500 small tilted triangles outside it, each in its own plane:
        // order 3 is asked, order 1 is searched, so only the lattice up to order 1 is found.
        let mut mesh = shoebox(SIZE);
        let junk = mesh.surface_id("junk");
        let mut rng = crate::core::rng::stream(1, 2, 3);
        for _ in 0..1500 {
            let mut u = || crate::core::rng::uniform(&mut rng);
            let o = Vec3::new(20.0 + 10.0 * u(), 10.0 * u(), 10.0 * u());
            mesh.push_triangle([o, o + Vec3::new(u(), u(), u()), o + Vec3::new(u(), u(), u())], junk);
        }
        let planes = Planes::of(&mesh);
        assert!(planes.len() >= 1415, "{}", planes.len());
        let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
        let (s, r) = (DVec3::new(1.75, 3.875, 1.125), DVec3::new(5.625, 1.3125, 2.375));
        assert_same(&found(&specular_paths(&accel, &planes, s, r, 3)), &sorted(lattice(s, r, SIZE, 1)));
    }

    #[test]
    fn two_parallel_planes_give_two_paths_per_order_up_to_the_cap() {
        // Floor z = 0 and ceiling z = 3, 40 m square: the images along z are
        // (1 - 2q) z_s + 6 n after |2n - q| reflections, two per order, all valid.
        let mut mesh = TriangleMesh::default();
        let s = mesh.surface_id("slab");
        for z in [0.0, 3.0] {
            let c = |x: f32, y: f32| Vec3::new(x, y, z);
            mesh.push_quad(c(-20.0, -20.0), c(20.0, -20.0), c(20.0, 20.0), c(-20.0, 20.0), s);
        }
        let planes = Planes::of(&mesh);
        assert_eq!(planes.len(), 2);
        let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
        let (src, rcv) = (DVec3::new(0.0, 0.0, 1.0), DVec3::new(1.0, 0.5, 2.0));
        let paths = specular_paths(&accel, &planes, src, rcv, 1000);
        assert_eq!(paths.len(), 1 + 2 * MAX_ORDER as usize);
        let mut want: Vec<(usize, f64)> = Vec::new();
        for q in 0..2i64 {
            for n in -64..=64i64 {
                let order = (2 * n - q).unsigned_abs() as usize;
                if order <= MAX_ORDER as usize {
                    let z = (1 - 2 * q) as f64 * src.z + 6.0 * n as f64;
                    want.push((order, DVec3::new(0.0, 0.0, z).distance(DVec3::new(1.0, 0.5, rcv.z))));
                }
            }
        }
        want.sort_by(|a, b| a.1.total_cmp(&b.1));
        let mut got: Vec<(usize, f64)> = paths.iter().map(|p| (p.order(), p.length_m)).collect();
        got.sort_by(|a, b| a.1.total_cmp(&b.1));
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            assert_eq!(g.0, w.0);
            assert!((g.1 - w.1).abs() < 1e-9 * w.1, "{} against {}", g.1, w.1);
        }
    }

    #[test]
    fn planes_merge_within_the_tolerances_only() {
        let mut mesh = TriangleMesh::default();
        let s = mesh.surface_id("x");
        let tri = |mesh: &mut TriangleMesh, z: [f32; 3], flip: bool| {
            let mut c = [Vec3::new(0.0, 0.0, z[0]), Vec3::new(1.0, 0.0, z[1]), Vec3::new(0.0, 1.0, z[2])];
            if flip {
                c.swap(1, 2);
            }
            mesh.push_triangle(c, s);
        };
        // 0: z = 2.9 mm; 1: z = 3.1 mm facing down (same plane across a hash-cell edge);
        // 2: z = 5 mm (another plane); 3: tilted by 5e-5 (same as 0); 4: tilted by 3e-4.
        tri(&mut mesh, [0.0029; 3], false);
        tri(&mut mesh, [0.0031; 3], true);
        tri(&mut mesh, [0.005; 3], false);
        tri(&mut mesh, [0.0029, 0.0029 + 5e-5, 0.0029], false);
        tri(&mut mesh, [0.0029, 0.0029 + 3e-4, 0.0029], false);
        // 5: degenerate.
        mesh.push_triangle([Vec3::ZERO, Vec3::X, Vec3::X * 2.0], s);
        // 6, 7: the plane x - y = 0.5, whose normal (1, -1, 0) / sqrt 2 is canonically
        // oriented by its x; 7 is tilted by 2e-5 so that its y is the larger, and is stored
        // flipped, yet it is the same plane.
        let (p, z) = (Vec3::new(0.5, 0.0, 0.0), Vec3::new(0.5, 0.0, 1.0));
        mesh.push_triangle([p, Vec3::new(1.5, 1.0, 0.0), z], s);
        mesh.push_triangle([p, Vec3::new(1.5, 0.99996, 0.0), z], s);
        let planes = Planes::of(&mesh);
        let ids: Vec<Option<u32>> = (0..8).map(|t| planes.plane_of_triangle(t)).collect();
        assert_eq!(ids, [Some(0), Some(0), Some(1), Some(0), Some(2), None, Some(3), Some(3)]);
        assert_eq!(planes.len(), 4);
        let diagonal = planes.planes()[3];
        let expect = DVec3::new(1.0, -1.0, 0.0).normalize();
        assert!(diagonal.normal.distance(expect) < 2e-5 && (diagonal.offset - 0.5 * expect.x).abs() < 1e-5);
        assert_eq!(planes.plane_of_triangle(99), None);
        // Plane 0 is the area-weighted mean of its three triangles, normal +z.
        let p = planes.planes()[0];
        assert!(p.normal.z > 0.999_999 && (p.offset - 0.003).abs() < 1e-4);
    }

    #[test]
    fn degenerate_inputs_give_no_path_and_no_panic() {
        let mesh = shoebox(SIZE);
        let planes = Planes::of(&mesh);
        let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
        let inside = DVec3::new(1.0, 2.0, 1.5);
        assert!(specular_paths(&accel, &planes, DVec3::NAN, inside, 3).is_empty());
        assert!(specular_paths(&accel, &planes, inside, DVec3::splat(f64::INFINITY), 3).is_empty());
        assert!(specular_paths(&accel, &planes, inside, DVec3::splat(1e300), 3).is_empty());
        // Source at the receiver: no direct path of length zero, but the echoes are there.
        let echoes = specular_paths(&accel, &planes, inside, inside, 1);
        assert_eq!(echoes.len(), 6);
        assert!(echoes.iter().all(|p| p.order() == 1 && p.length_m > 0.0));
        // A receiver on a wall reflects nothing off that wall.
        let on_floor = DVec3::new(3.0, 2.0, 0.0);
        let paths = specular_paths(&accel, &planes, inside, on_floor, 1);
        assert!(paths.iter().all(|p| p.reflections.iter().all(|f| f.normal != DVec3::Z)));
        // No planes, no mesh: the direct path only.
        let empty = Accel::build(&TriangleMesh::default(), Vec::new(), BuildQuality::default());
        let paths = specular_paths(&empty, &Planes::default(), inside, on_floor, 5);
        assert_eq!(paths.len(), 1);
        assert!((paths[0].length_m - inside.distance(on_floor)).abs() < 1e-12);
    }
}
