//! Parts of triangles wholly in view of a point: no other primitive meets the solid spanned
//! by the part and the point (a tetrahedron), so every segment from the part to the point is
//! clear and a simulator can skip its shadow ray. Each triangle is cut into
//! [`SUBDIVISIONS`]^2 parts on a grid of its barycentric coordinates. The test is the
//! separating-axis theorem for two convex polyhedra (\[Gottschalk1996\] and \[Ericson2005\] in
//! docs/references.md; docs/performance.md): face normals of both and cross products of their
//! edges. Touching (a neighbour sharing an edge) is not meeting.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::mesh::TriangleMesh;
use super::sphere::Sphere;

/// Above this many triangle pairs per point the table is not made (it costs more than the
/// shadow rays it saves on any plausible run); the caller then traces every shadow ray.
pub const MAX_PAIRS_PER_POINT: usize = 1_000_000;

/// Parts of a triangle per side of its barycentric grid.
pub const SUBDIVISIONS: usize = 8;

/// Which parts of one triangle are wholly in view: bit [`part_of`] of the mask.
pub type PartsInView = u128;

/// The part of a triangle holding barycentric coordinates `(u, v)` (weights of the second and
/// third corners): row `i = floor(u m)`, column `j = floor(v m)`, lower or upper half of the
/// cell, bit `2 (i m + j) + upper`. `None` off the grid (rounding at an edge).
#[inline]
pub fn part_of(u: f32, v: f32) -> Option<u32> {
    let m = SUBDIVISIONS as f32;
    let (x, y) = (u * m, v * m);
    if !(x >= 0.0 && y >= 0.0) {
        return None;
    }
    let (i, j) = (x.floor(), y.floor());
    let upper = (x - i) + (y - j) > 1.0;
    let (i, j) = (i as usize, j as usize);
    if i + j + usize::from(upper) >= SUBDIVISIONS {
        return None;
    }
    Some((2 * (i * SUBDIVISIONS + j) + usize::from(upper)) as u32)
}

/// The corners of part `(i, j, upper)` of the triangle `[a, b, c]`.
fn part_corners([a, b, c]: &[DVec3; 3], i: usize, j: usize, upper: bool) -> [DVec3; 3] {
    let m = SUBDIVISIONS as f64;
    let at = |i: usize, j: usize| a + (i as f64 / m) * (b - *a) + (j as f64 / m) * (c - *a);
    if upper {
        [at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)]
    } else {
        [at(i, j), at(i + 1, j), at(i, j + 1)]
    }
}

/// For each triangle of `mesh`, the parts wholly in view of `point` (see the module doc);
/// `None` when the mesh is too large for the table. Conservative: a clear bit only means
/// "trace the ray". A sphere whose box meets a part's solid's box counts as in the way.
pub fn triangles_in_full_view(
    mesh: &TriangleMesh,
    spheres: &[Sphere],
    point: Vec3,
) -> Option<Vec<PartsInView>> {
    let n = mesh.triangle_count();
    if n.saturating_mul(n) > MAX_PAIRS_PER_POINT {
        return None;
    }
    let corners: Vec<[DVec3; 3]> = (0..n).map(|i| mesh.corners(i).map(|v| v.as_dvec3())).collect();
    let boxes: Vec<(DVec3, DVec3)> = corners.iter().map(|c| bounds(c)).collect();
    let size = boxes.iter().map(|(lo, hi)| lo.abs().max(hi.abs()).max_element()).fold(1.0, f64::max);
    let tolerance = 1e-7 * size;
    let p = point.as_dvec3();
    let in_view = |i: usize, part: &[DVec3; 3]| {
        let solid = [part[0], part[1], part[2], p];
        let (lo, hi) = bounds(&solid);
        let (lo, hi) = (lo - DVec3::splat(tolerance), hi + DVec3::splat(tolerance));
        let blocked_by_triangle = (0..n).any(|j| {
            j != i
                && boxes[j].0.cmple(hi).all()
                && boxes[j].1.cmpge(lo).all()
                && !separated(&solid, &corners[j], tolerance)
        });
        let blocked_by_sphere = spheres.iter().any(|s| {
            let (c, r) = (s.center.as_dvec3(), f64::from(s.radius_m));
            (c - DVec3::splat(r)).cmple(hi).all() && (c + DVec3::splat(r)).cmpge(lo).all()
        });
        !blocked_by_triangle && !blocked_by_sphere
    };
    let table = (0..n)
        .into_par_iter()
        .map(|i| {
            if in_view(i, &corners[i]) {
                return PartsInView::MAX;
            }
            let mut mask: PartsInView = 0;
            for cell_i in 0..SUBDIVISIONS {
                for cell_j in 0..SUBDIVISIONS - cell_i {
                    for upper in [false, true] {
                        if upper && cell_i + cell_j + 1 >= SUBDIVISIONS {
                            continue;
                        }
                        if in_view(i, &part_corners(&corners[i], cell_i, cell_j, upper)) {
                            mask |= 1 << (2 * (cell_i * SUBDIVISIONS + cell_j) + usize::from(upper));
                        }
                    }
                }
            }
            mask
        })
        .collect();
    Some(table)
}

fn bounds(points: &[DVec3]) -> (DVec3, DVec3) {
    let lo = points.iter().fold(DVec3::INFINITY, |a, b| a.min(*b));
    let hi = points.iter().fold(DVec3::NEG_INFINITY, |a, b| a.max(*b));
    (lo, hi)
}

/// Whether the tetrahedron `solid` and the triangle `tri` are apart, or only touch (their
/// projections overlap by at most `tolerance` on some axis). Any NaN gives "not apart".
fn separated(solid: &[DVec3; 4], tri: &[DVec3; 3], tolerance: f64) -> bool {
    let [a, b, c, d] = *solid;
    let solid_edges = [b - a, c - a, d - a, c - b, d - b, d - c];
    let tri_edges = [tri[1] - tri[0], tri[2] - tri[1], tri[0] - tri[2]];
    let solid_faces =
        [(b - a).cross(c - a), (b - a).cross(d - a), (c - a).cross(d - a), (c - b).cross(d - b)];
    let apart_on = |axis: DVec3| {
        let length = axis.length();
        if length.is_nan() || length <= 1e-12 * size_of(solid) {
            return false;
        }
        let axis = axis / length;
        let (s_lo, s_hi) = interval(solid.iter(), axis);
        let (t_lo, t_hi) = interval(tri.iter(), axis);
        s_hi <= t_lo + tolerance || t_hi <= s_lo + tolerance
    };
    if solid_faces.iter().any(|&n| apart_on(n)) || apart_on(tri_edges[0].cross(tri_edges[1])) {
        return true;
    }
    solid_edges.iter().any(|&e| tri_edges.iter().any(|&f| apart_on(e.cross(f))))
}

/// The squared scale of `solid` (for the degenerate-axis test of cross products).
fn size_of(solid: &[DVec3; 4]) -> f64 {
    let (lo, hi) = bounds(solid);
    (hi - lo).length_squared()
}

fn interval<'a>(points: impl Iterator<Item = &'a DVec3>, axis: DVec3) -> (f64, f64) {
    points.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
        let x = p.dot(axis);
        (lo.min(x), hi.max(x))
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::accel::{Accel, BuildQuality};
    use crate::core::ray::Ray;
    use crate::core::rng::{stream, uniform};
    use crate::core::sampling::uniform_triangle;
    use glam::Vec2;

    /// A box room with a smaller box standing on its floor (an obstacle).
    fn room_with_obstacle() -> TriangleMesh {
        let mut mesh = TriangleMesh::default();
        let s = mesh.surface_id("wall");
        mesh.push_box(Vec3::new(-4.0, -3.0, 0.0), Vec3::new(5.0, 4.0, 3.0), 2, s);
        mesh.flip_winding();
        mesh.push_box(Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 2.0, 1.2), 1, s);
        mesh
    }

    #[test]
    fn a_triangle_in_full_view_has_every_point_in_view_and_the_table_is_not_empty() {
        let mesh = room_with_obstacle();
        let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
        let receiver = Vec3::new(-2.5, 2.3, 1.5);
        let table = triangles_in_full_view(&mesh, &[], receiver).unwrap();
        let visible = table.iter().filter(|&&v| v == PartsInView::MAX).count();
        // Most of the room's inner faces see the receiver whole; the obstacle's far faces do
        // not, and some are seen in part.
        assert!(visible > mesh.triangle_count() / 2, "{visible} of {}", mesh.triangle_count());
        assert!(visible < mesh.triangle_count());
        assert!(table.iter().any(|&v| v != 0 && v != PartsInView::MAX));
        let mut rng = stream(3, 0, 0);
        let mut checked = 0;
        for (i, &mask) in table.iter().enumerate() {
            let [a, b, c] = mesh.corners(i);
            let n = (b - a).cross(c - a).normalize();
            for _ in 0..200 {
                let uv = uniform_triangle(Vec2::new(uniform(&mut rng), uniform(&mut rng)));
                let in_view = part_of(uv.x, uv.y).is_some_and(|k| mask >> k & 1 == 1);
                let x = a + uv.x * (b - a) + uv.y * (c - a);
                // (Rain skips a receiver in the plane of the face.)
                let cos = n.dot((receiver - x).normalize());
                if cos.abs() < 1e-3 {
                    continue;
                }
                let side = if cos > 0.0 { n } else { -n };
                let ray = Ray::spawn_to(x, side, receiver);
                if in_view {
                    assert!(!accel.occluded(&ray), "triangle {i} said in view, point {x} blocked");
                    checked += 1;
                }
            }
        }
        assert!(checked > 1000);
    }

    #[test]
    fn a_triangle_behind_an_obstacle_or_a_sphere_is_not_in_full_view() {
        let mesh = room_with_obstacle();
        let receiver = Vec3::new(-2.5, 1.0, 0.6);
        let table = triangles_in_full_view(&mesh, &[], receiver).unwrap();
        // The room's wall at x = 5 behind the obstacle (seen from the receiver, at the
        // obstacle's height) is partly hidden: every triangle of that wall containing the
        // point (5, 1, 0.6) must be marked not in view.
        for (i, &mask) in table.iter().enumerate() {
            let [a, b, c] = mesh.corners(i);
            let in_view = mask == PartsInView::MAX;
            if [a, b, c].iter().all(|v| v.x == 5.0)
                && crate::core::TriangleRt::new(a, b, c)
                    .intersect(&Ray::new(Vec3::new(4.0, 1.0, 0.6), Vec3::X))
                    .is_some()
            {
                assert!(!in_view, "triangle {i} behind the obstacle");
            }
        }
        // A sphere in the middle of the room hides (conservatively) what is behind it.
        let sphere = Sphere::new(Vec3::new(-1.0, 1.0, 0.6), 0.3, 0);
        let with = triangles_in_full_view(&mesh, &[sphere], receiver).unwrap();
        let parts = |t: &[PartsInView]| t.iter().map(|m| m.count_ones()).sum::<u32>();
        assert!(parts(&with) < parts(&table));
    }

    #[test]
    fn the_parts_tile_the_triangle_and_part_of_finds_them() {
        let tri = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let mut area = 0.0;
        let mut rng = stream(9, 0, 0);
        for i in 0..SUBDIVISIONS {
            for j in 0..SUBDIVISIONS - i {
                for upper in [false, true] {
                    if upper && i + j + 1 >= SUBDIVISIONS {
                        continue;
                    }
                    let [a, b, c] = part_corners(&tri, i, j, upper);
                    area += 0.5 * (b - a).cross(c - a).length();
                    // A point inside the part (here u = x, v = y) maps to its bit.
                    let w = uniform_triangle(Vec2::new(uniform(&mut rng), uniform(&mut rng))).as_dvec2();
                    let q = a + w.x * (b - a) + w.y * (c - a);
                    let bit = 2 * (i * SUBDIVISIONS + j) + usize::from(upper);
                    assert_eq!(part_of(q.x as f32, q.y as f32), Some(bit as u32), "{q}");
                }
            }
        }
        assert!((area - 0.5).abs() < 1e-12, "{area}");
        assert_eq!(part_of(-0.1, 0.2), None);
        assert_eq!(part_of(0.7, 0.7), None);
    }

    #[test]
    fn touching_is_not_meeting_but_crossing_is() {
        let solid = [DVec3::ZERO, DVec3::X, DVec3::Y, DVec3::new(0.2, 0.2, 1.0)];
        // A triangle sharing the edge (0,0,0)-(1,0,0), on the other side of the plane y = 0.
        let neighbour = [DVec3::ZERO, DVec3::X, DVec3::new(0.5, -1.0, 0.3)];
        assert!(separated(&solid, &neighbour, 1e-9));
        // A triangle piercing the solid.
        let piercing = [DVec3::new(0.2, 0.2, -1.0), DVec3::new(0.3, 0.2, 2.0), DVec3::new(0.2, 0.3, 2.0)];
        assert!(!separated(&solid, &piercing, 1e-9));
        // Far away.
        let far = [DVec3::splat(5.0), DVec3::splat(6.0), DVec3::new(5.0, 6.0, 5.0)];
        assert!(separated(&solid, &far, 1e-9));
    }
}
