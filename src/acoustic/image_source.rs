//! The image-source method for the early specular reflections (Allen & Berkley 1979;
//! Borish 1984 for arbitrary polyhedra), with every path checked by tracing it back from the
//! receiver through the BVH (visibility and reflection points inside the actual faces).

use std::collections::HashMap;

use glam::Vec3;

use crate::core::{Accel, Ray, TriangleMesh};

/// The distinct planes of a mesh; coplanar triangles share one plane.
#[derive(Clone, Debug, Default)]
pub struct Planes {
    /// Unit normal and offset (`n . x = d`) of each plane.
    pub normal: Vec<Vec3>,
    pub offset: Vec<f32>,
    pub plane_of_triangle: Vec<u32>,
}

impl Planes {
    /// Groups triangles by plane (normal within ~1e-4 rad and offset within 0.1 mm).
    pub fn of(mesh: &TriangleMesh) -> Self {
        let mut planes = Planes::default();
        let mut index: HashMap<[i64; 4], u32> = HashMap::new();
        for t in 0..mesh.triangle_count() {
            let [a, b, c] = mesh.corners(t);
            let mut n = (b - a).cross(c - a).normalize_or_zero();
            // Canonical orientation: the largest component positive.
            let k = if n.x.abs() >= n.y.abs() && n.x.abs() >= n.z.abs() {
                n.x
            } else if n.y.abs() >= n.z.abs() {
                n.y
            } else {
                n.z
            };
            if k < 0.0 {
                n = -n;
            }
            let d = n.dot(a);
            let key = [
                (n.x * 1e4).round() as i64,
                (n.y * 1e4).round() as i64,
                (n.z * 1e4).round() as i64,
                (d * 1e4).round() as i64,
            ];
            let id = *index.entry(key).or_insert_with(|| {
                planes.normal.push(n);
                planes.offset.push(d);
                (planes.normal.len() - 1) as u32
            });
            planes.plane_of_triangle.push(id);
        }
        planes
    }

    pub fn len(&self) -> usize {
        self.normal.len()
    }

    pub fn is_empty(&self) -> bool {
        self.normal.is_empty()
    }

    /// Mirror image of `p` in plane `i`.
    pub fn mirror(&self, i: u32, p: Vec3) -> Vec3 {
        let n = self.normal[i as usize];
        p - 2.0 * (n.dot(p) - self.offset[i as usize]) * n
    }
}

/// An image source: the chain of planes of its reflections, first reflection first, and the
/// images of every order along the chain (`images[k]` is the image after `k + 1` reflections).
#[derive(Clone, Debug, PartialEq)]
pub struct ImageSource {
    pub planes: Vec<u32>,
    pub images: Vec<Vec3>,
}

/// All image sources of `source` up to `order` (no plane twice in a row).
pub fn image_sources(source: Vec3, planes: &Planes, order: u32) -> Vec<ImageSource> {
    let mut all = Vec::new();
    let mut frontier = vec![ImageSource { planes: Vec::new(), images: Vec::new() }];
    for _ in 0..order {
        let mut next = Vec::new();
        for parent in &frontier {
            let from = parent.images.last().copied().unwrap_or(source);
            for p in 0..planes.len() as u32 {
                if parent.planes.last() == Some(&p) {
                    continue;
                }
                let n = planes.normal[p as usize];
                if (n.dot(from) - planes.offset[p as usize]).abs() < 1e-6 {
                    continue;
                }
                let mut child = parent.clone();
                child.planes.push(p);
                child.images.push(planes.mirror(p, from));
                next.push(child);
            }
        }
        all.extend(next.iter().cloned());
        frontier = next;
    }
    all
}

/// A valid specular path from the source to the receiver.
#[derive(Clone, Debug, PartialEq)]
pub struct SpecularPath {
    pub length_m: f32,
    /// Surface id of each reflection, first reflection first.
    pub surfaces: Vec<u32>,
}

/// Traces image source `img` back from `receiver`: each leg must reach the right plane inside
/// one of its triangles, and the last leg must see the source. `None` if the path is invalid.
pub fn trace_path(
    accel: &Accel,
    planes: &Planes,
    img: &ImageSource,
    source: Vec3,
    receiver: Vec3,
) -> Option<SpecularPath> {
    let order = img.planes.len();
    let length_m = img.images.last().map_or((source - receiver).length(), |i| (*i - receiver).length());
    let mut surfaces = vec![0; order];
    let mut from = receiver;
    let mut from_normal: Option<Vec3> = None;
    for k in (0..order).rev() {
        let target = img.images[k];
        let to = target - from;
        let dist = to.length();
        let dir = to / dist;
        let mut ray = match from_normal {
            None => Ray::new(from, dir),
            Some(n) => Ray::spawn(from, n, dir),
        };
        ray.t_max = dist;
        let hit = accel.mesh.closest_hit(&ray)?;
        if planes.plane_of_triangle[hit.primitive as usize] != img.planes[k] {
            return None;
        }
        surfaces[k] = hit.surface;
        from = hit.point;
        from_normal = Some(hit.normal);
    }
    let last = match from_normal {
        None => {
            let to = source - from;
            Ray::segment(from, to.normalize_or_zero(), to.length())
        }
        Some(n) => Ray::spawn_to(from, n, source),
    };
    if accel.mesh.occluded(&last) {
        return None;
    }
    Some(SpecularPath { length_m, surfaces })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::BuildQuality;

    #[test]
    fn shoebox_images_match_the_lattice() {
        let mut mesh = TriangleMesh::default();
        let s = mesh.surface_id("wall");
        mesh.push_box(Vec3::ZERO, Vec3::new(10.0, 8.0, 3.0), 2, s);
        let planes = Planes::of(&mesh);
        assert_eq!(planes.len(), 6);
        let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
        let (src, rcv) = (Vec3::new(2.0, 3.0, 1.5), Vec3::new(7.0, 5.0, 1.2));
        let images = image_sources(src, &planes, 2);
        assert_eq!(images.len(), 6 + 6 * 5);
        let valid: Vec<SpecularPath> =
            images.iter().filter_map(|i| trace_path(&accel, &planes, i, src, rcv)).collect();
        // Allen & Berkley's lattice: 6 first-order images; of order 2, the 6 ordered pairs of
        // parallel walls are all valid, while each of the 12 corner images (two perpendicular
        // walls) is reached by one of its two orderings only: 6 + 6 + 12 = 24.
        assert_eq!(valid.len(), 24);
        // The floor image: (2, 3, -1.5) -> length |(5, 2, 2.7)|.
        let floor = Vec3::new(5.0, 2.0, 2.7).length();
        assert!(valid.iter().any(|p| p.surfaces.len() == 1 && (p.length_m - floor).abs() < 1e-4));
    }

    #[test]
    fn an_occluding_wall_invalidates_paths() {
        // L-shaped corridor: a partition hides the receiver; the direct path and the
        // reflections off the far side are blocked.
        let mut mesh = TriangleMesh::default();
        let s = mesh.surface_id("wall");
        mesh.push_box(Vec3::ZERO, Vec3::new(10.0, 10.0, 3.0), 1, s);
        let wall = mesh.surface_id("partition");
        let start = mesh.triangle_count();
        mesh.push_box(Vec3::new(4.9, 0.0, 0.0), Vec3::new(5.1, 8.0, 3.0), 1, wall);
        for t in &mut mesh.triangles[start..] {
            t.swap(1, 2);
        }
        let planes = Planes::of(&mesh);
        let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
        let (src, rcv) = (Vec3::new(2.0, 2.0, 1.5), Vec3::new(8.0, 2.0, 1.5));
        let direct = ImageSource { planes: vec![], images: vec![] };
        assert!(trace_path(&accel, &planes, &direct, src, rcv).is_none());
        let images = image_sources(src, &planes, 2);
        let valid: Vec<SpecularPath> =
            images.iter().filter_map(|i| trace_path(&accel, &planes, i, src, rcv)).collect();
        // Only paths over the partition's end (via the y = 10 wall) survive.
        assert!(!valid.is_empty());
        assert!(valid.iter().all(|p| p.length_m > 6.0));
    }
}
