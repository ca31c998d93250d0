//! Indexed triangle meshes whose triangles each carry a surface id.

use glam::Vec3;

use super::hit::SurfaceId;
use super::triangle::TriangleRt;

/// An indexed triangle mesh. Every triangle belongs to a named surface (an OBJ `usemtl` group);
/// `surface_names[id]` is that name.
#[derive(Clone, Debug, Default)]
pub struct TriangleMesh {
    /// Vertex positions, metres.
    pub positions: Vec<Vec3>,
    /// Vertex indices of each triangle.
    pub triangles: Vec<[u32; 3]>,
    /// One entry per triangle.
    pub surface_of_triangle: Vec<SurfaceId>,
    /// Name of each surface, by `SurfaceId`.
    pub surface_names: Vec<String>,
}

impl TriangleMesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.triangles.len()
    }

    /// The three corners of triangle `i`.
    #[inline]
    pub fn corners(&self, i: usize) -> [Vec3; 3] {
        let [a, b, c] = self.triangles[i];
        [self.positions[a as usize], self.positions[b as usize], self.positions[c as usize]]
    }

    /// Triangle `i` in intersection layout.
    pub fn triangle_rt(&self, i: usize) -> TriangleRt {
        let [a, b, c] = self.corners(i);
        TriangleRt::new(a, b, c)
    }

    /// Area of triangle `i`, square metres.
    pub fn triangle_area(&self, i: usize) -> f32 {
        let [a, b, c] = self.corners(i);
        0.5 * (b - a).cross(c - a).length()
    }

    /// Axis-aligned bounds `(min, max)` of the used vertices; `None` for an empty mesh.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut it = self.triangles.iter().flatten().map(|&i| self.positions[i as usize]);
        let first = it.next()?;
        Some(it.fold((first, first), |(lo, hi), p| (lo.min(p), hi.max(p))))
    }

    /// Id of the surface called `name`, adding it if new.
    pub fn surface_id(&mut self, name: &str) -> SurfaceId {
        match self.surface_names.iter().position(|n| n == name) {
            Some(i) => i as SurfaceId,
            None => {
                self.surface_names.push(name.to_string());
                (self.surface_names.len() - 1) as SurfaceId
            }
        }
    }

    /// Appends a triangle on surface `surface`, adding its vertices.
    pub fn push_triangle(&mut self, corners: [Vec3; 3], surface: SurfaceId) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&corners);
        self.triangles.push([base, base + 1, base + 2]);
        self.surface_of_triangle.push(surface);
    }

    /// Appends the two triangles of the planar quad `a b c d` (counter-clockwise).
    pub fn push_quad(&mut self, a: Vec3, b: Vec3, c: Vec3, d: Vec3, surface: SurfaceId) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&[a, b, c, d]);
        self.triangles.push([base, base + 1, base + 2]);
        self.triangles.push([base, base + 2, base + 3]);
        self.surface_of_triangle.extend([surface, surface]);
    }

    /// Appends a closed, outward-facing axis-aligned box split into `n` x `n` quads per face.
    /// Vertices on shared edges are computed identically by each face, so the box is closed
    /// to the last bit.
    pub fn push_box(&mut self, min: Vec3, max: Vec3, n: usize, surface: SurfaceId) {
        let n = n.max(1);
        let coord = |axis: usize, k: usize| -> f32 {
            match k {
                0 => min[axis],
                k if k == n => max[axis],
                k => min[axis] + (max[axis] - min[axis]) * (k as f32 / n as f32),
            }
        };
        // Each face: fixed axis and side, then the (u, v) axes ordered so u x v points outward.
        let faces: [(usize, usize, usize, usize); 6] =
            [(2, 0, 1, 0), (2, n, 0, 1), (1, 0, 0, 2), (1, n, 2, 0), (0, 0, 2, 1), (0, n, 1, 2)];
        for (fixed, side, ua, va) in faces {
            let base = self.positions.len() as u32;
            for j in 0..=n {
                for i in 0..=n {
                    let mut p = Vec3::ZERO;
                    p[fixed] = coord(fixed, side);
                    p[ua] = coord(ua, i);
                    p[va] = coord(va, j);
                    self.positions.push(p);
                }
            }
            let row = (n + 1) as u32;
            for j in 0..n as u32 {
                for i in 0..n as u32 {
                    let a = base + j * row + i;
                    let (b, c, d) = (a + 1, a + row + 1, a + row);
                    self.triangles.push([a, b, c]);
                    self.triangles.push([a, c, d]);
                    self.surface_of_triangle.extend([surface, surface]);
                }
            }
        }
    }

    /// Reverses every triangle's winding (turns an outward box into a room's inward walls).
    pub fn flip_winding(&mut self) {
        for t in &mut self.triangles {
            t.swap(1, 2);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn box_has_expected_area_and_outward_normals() {
        let mut m = TriangleMesh::default();
        let s = m.surface_id("wall");
        m.push_box(Vec3::ZERO, Vec3::new(2.0, 3.0, 4.0), 3, s);
        assert_eq!(m.triangle_count(), 6 * 9 * 2);
        let area: f32 = (0..m.triangle_count()).map(|i| m.triangle_area(i)).sum();
        assert!((area - 2.0 * (6.0 + 8.0 + 12.0)).abs() < 1e-3);
        let centre = Vec3::new(1.0, 1.5, 2.0);
        for i in 0..m.triangle_count() {
            let [a, b, c] = m.corners(i);
            let n = (b - a).cross(c - a);
            assert!(n.dot(a - centre) > 0.0, "triangle {i} faces inward");
        }
        assert_eq!(m.bounds(), Some((Vec3::ZERO, Vec3::new(2.0, 3.0, 4.0))));
    }

    #[test]
    fn surface_ids_are_reused_by_name() {
        let mut m = TriangleMesh::default();
        assert_eq!(m.surface_id("a"), 0);
        assert_eq!(m.surface_id("b"), 1);
        assert_eq!(m.surface_id("a"), 0);
    }
}
