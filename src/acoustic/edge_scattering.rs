//! The scattering that a finite surface adds by diffraction at its free edges, even where the
//! material itself scatters little: reflection-based scattering after Christensen and Rindel
//! (\[Christensen2005\] in docs/references.md), the method of ODEON, with Rindel's
//! attenuation of a reflection from a finite panel (\[Rindel1986\]).
//!
//! A reflection off a panel of width `a` only builds up fully above the frequency
//!
//! ```text
//! f_c = c a* / (2 (a cos theta)^2),   a* = 2 d1 d2 / (d1 + d2)
//! ```
//!
//! with `theta` the angle of incidence, `d1` the distance the sound came from (the previous
//! reflection or the source) and `d2` the distance it goes on (the next reflection or the
//! receiver). Below it the specular energy falls by `f / f_c`; the rest is diffracted by the
//! edges, which propsim counts as scattered. With the panel's two dimensions
//! (`a_1`, `a_2`: its extents along its principal axes) the specular share is
//! `K = min(1, f / f_c1) min(1, f / f_c2)`, the reflection-based scattering coefficient is
//! `s_r = 1 - K`, and it combines with the material's `s` as `1 - (1 - s)(1 - s_r)`.
//!
//! Only the planar regions of the mesh that end at a free edge whose exterior is the room's
//! air (a screen's rim, a pillar's or balcony's convex edge, the inner corner of an L-shaped
//! room) scatter so: a wall that meets other walls at the room's concave corners is mirrored
//! on by its neighbours and adds nothing (a closed box is unchanged). The rays do not know
//! where they go next, so `d2` is the room's mean free path `4 V / S` for them; the image
//! sources use the path's exact `d2`.

use glam::DVec3;

use crate::core::TriangleMesh;
use crate::core::wedges::{Wedge, planar_regions};
use crate::scene::materials::{BandValues, OCTAVE_BANDS_HZ};

/// The finite panels of a room: for each triangle the extents of its planar region when that
/// region ends at a free edge of the room.
#[derive(Clone, Debug, Default)]
pub struct EdgeScattering {
    /// Per triangle, an index into `panels`, or `u32::MAX` for none.
    panel_of_triangle: Vec<u32>,
    /// The two principal extents of each panel, metres (smaller first).
    panels: Vec<[f32; 2]>,
    /// Speed of sound, m/s.
    speed_m_s: f32,
    /// The distance to the next reflection assumed for rays: the mean free path, m.
    mean_free_path_m: f32,
}

impl EdgeScattering {
    /// The panels of `mesh` bounded by one of `edges` (the room's free edges, whose exterior
    /// is the room's air), for sound of speed `speed_m_s` in a room of mean free path
    /// `mean_free_path_m`. `None` when no panel qualifies.
    pub fn of(mesh: &TriangleMesh, edges: &[Wedge], speed_m_s: f64, mean_free_path_m: f64) -> Option<Self> {
        if edges.is_empty() {
            return None;
        }
        let regions = planar_regions(mesh);
        let count = regions.iter().map(|&r| r as usize + 1).max().unwrap_or(0);
        let mut free = vec![false; count];
        for w in edges {
            for &t in &w.triangles {
                if let Some(&r) = regions.get(t as usize) {
                    free[r as usize] = true;
                }
            }
        }
        let mut triangles_of: Vec<Vec<usize>> = vec![Vec::new(); count];
        for (t, &r) in regions.iter().enumerate() {
            if free[r as usize] {
                triangles_of[r as usize].push(t);
            }
        }
        let mut panel_of_region = vec![u32::MAX; count];
        let mut panels = Vec::new();
        for (r, triangles) in triangles_of.iter().enumerate() {
            if triangles.is_empty() {
                continue;
            }
            if let Some(extent) = principal_extents(mesh, triangles) {
                panel_of_region[r] = panels.len() as u32;
                panels.push(extent);
            }
        }
        if panels.is_empty() {
            return None;
        }
        let panel_of_triangle = regions.iter().map(|&r| panel_of_region[r as usize]).collect();
        Some(Self {
            panel_of_triangle,
            panels,
            speed_m_s: speed_m_s as f32,
            mean_free_path_m: mean_free_path_m as f32,
        })
    }

    /// The panel count (regions that scatter at their edges).
    pub fn panels(&self) -> usize {
        self.panels.len()
    }

    /// The scattering coefficients of a reflection on `triangle` with material scattering
    /// `material`, incidence cosine `cos_theta`, incoming distance `d1_m` and outgoing
    /// distance `d2_m` (`None`: the mean free path): `1 - (1 - s)(1 - s_r)` on a panel,
    /// `material` elsewhere.
    #[inline]
    pub fn scattering(
        &self,
        triangle: u32,
        material: &BandValues,
        cos_theta: f32,
        d1_m: f32,
        d2_m: Option<f32>,
    ) -> BandValues {
        let Some(&[a1, a2]) =
            self.panel_of_triangle.get(triangle as usize).and_then(|&p| self.panels.get(p as usize))
        else {
            return *material;
        };
        let d2 = d2_m.unwrap_or(self.mean_free_path_m);
        let (d1, c) = (d1_m.max(1.0e-3), cos_theta.abs().max(1.0e-3));
        let a_star = 2.0 * d1 * d2 / (d1 + d2);
        let fc = |a: f32| self.speed_m_s * a_star / (2.0 * (a * c) * (a * c));
        let (fc1, fc2) = (fc(a1), fc(a2));
        std::array::from_fn(|b| {
            let f = OCTAVE_BANDS_HZ[b];
            let kept = (f / fc1).min(1.0) * (f / fc2).min(1.0);
            let s_r = if kept.is_finite() { 1.0 - kept } else { 0.0 };
            1.0 - (1.0 - material[b]) * (1.0 - s_r)
        })
    }
}

/// The extents of triangles `triangles` of `mesh` along the two principal axes of their area
/// in their plane, metres, smaller first; `None` when degenerate.
fn principal_extents(mesh: &TriangleMesh, triangles: &[usize]) -> Option<[f32; 2]> {
    let points: Vec<DVec3> = triangles.iter().flat_map(|&t| mesh.corners(t)).map(|v| v.as_dvec3()).collect();
    let &first = triangles.first()?;
    let [a, b, c] = mesh.corners(first).map(|v| v.as_dvec3());
    let normal = (b - a).cross(c - a).try_normalize()?;
    let u = (b - a).try_normalize()?;
    let v = normal.cross(u);
    // The area's second moments about its centroid, in the plane's (u, v) frame: a
    // triangle's `int x x^T dA = A / 12 (sum p_i p_i^T + (sum p_i)(sum p_i)^T)`.
    let tris: Vec<([DVec3; 3], f64)> = triangles
        .iter()
        .map(|&t| {
            let q = mesh.corners(t).map(|x| x.as_dvec3());
            (q, 0.5 * (q[1] - q[0]).cross(q[2] - q[0]).length())
        })
        .collect();
    let area: f64 = tris.iter().map(|t| t.1).sum();
    if area.is_nan() || area <= 0.0 {
        return None;
    }
    let mean = tris.iter().map(|(q, a)| (q[0] + q[1] + q[2]) / 3.0 * *a).sum::<DVec3>() / area;
    let (mut xx, mut xy, mut yy) = (0.0, 0.0, 0.0);
    for (q, a) in &tris {
        let p = q.map(|x| ((x - mean).dot(u), (x - mean).dot(v)));
        let (sx, sy) = (p[0].0 + p[1].0 + p[2].0, p[0].1 + p[1].1 + p[2].1);
        xx += a / 12.0 * (p.iter().map(|x| x.0 * x.0).sum::<f64>() + sx * sx);
        xy += a / 12.0 * (p.iter().map(|x| x.0 * x.1).sum::<f64>() + sx * sy);
        yy += a / 12.0 * (p.iter().map(|x| x.1 * x.1).sum::<f64>() + sy * sy);
    }
    // The principal axis angle of the 2 x 2 covariance.
    let angle = 0.5 * (2.0 * xy).atan2(xx - yy);
    let (s, co) = angle.sin_cos();
    let (axis1, axis2) = (u * co + v * s, v * co - u * s);
    let extent = |axis: DVec3| {
        let (lo, hi) = points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            let x = p.dot(axis);
            (lo.min(x), hi.max(x))
        });
        hi - lo
    };
    let (e1, e2) = (extent(axis1), extent(axis2));
    let (small, large) = (e1.min(e2), e1.max(e2));
    (small.is_finite() && small > 0.0).then_some([small as f32, large as f32])
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::materials::BAND_COUNT;
    use glam::Vec3;

    #[test]
    fn a_panel_scatters_below_its_characteristic_frequency_only() {
        // A 1 x 2 m panel, its rims the free edges; normal incidence, d1 = d2 = 4 m:
        // a* = 4 m, f_c = 343 * 4 / (2 a^2) = 686 Hz (a = 1) and 171.5 Hz (a = 2).
        let mut m = TriangleMesh::default();
        let s = m.surface_id("panel");
        m.push_quad(
            Vec3::ZERO,
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(2.0, 1.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            s,
        );
        let edges = crate::core::wedges::extract_wedges(&m);
        let es = EdgeScattering::of(&m, &edges, 343.0, 4.0).unwrap();
        assert_eq!(es.panels(), 1);
        let [a1, a2] = es.panels[0];
        assert!((a1 - 1.0).abs() < 1e-5 && (a2 - 2.0).abs() < 1e-5, "{a1} x {a2}");
        let out = es.scattering(0, &[0.1; BAND_COUNT], 1.0, 4.0, Some(4.0));
        for (b, &f) in OCTAVE_BANDS_HZ.iter().enumerate() {
            let kept = (f / 686.0).min(1.0) * (f / 171.5).min(1.0);
            let expect = 1.0 - 0.9 * kept;
            assert!((out[b] - expect).abs() < 1e-4, "{f} Hz: {} vs {expect}", out[b]);
        }
        // Above both frequencies nothing changes: the material's own 0.1.
        assert!((out[5] - 0.1).abs() < 1e-6);
        // Oblique incidence (60 degrees) raises f_c four times.
        let oblique = es.scattering(1, &[0.0; BAND_COUNT], 0.5, 4.0, Some(4.0));
        assert!((oblique[4] - (1.0 - 1000.0 / 2744.0)).abs() < 1e-4, "{}", oblique[4]);
    }

    #[test]
    fn a_mesh_without_free_edges_has_no_panels() {
        assert!(EdgeScattering::of(&TriangleMesh::default(), &[], 343.0, 4.0).is_none());
    }
}
