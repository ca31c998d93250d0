//! The runtime world: a scene plus its acceleration structure. The one thing simulators read.

use glam::Vec3;

use super::check::{MeshReport, add_instances, analyze};
use super::error::SceneError;
use super::load::Scene;
use crate::core::TriangleMesh;
use crate::core::accel::instances::{flatten, transformed_box};
use crate::core::sdf::SdfSet;
use crate::core::shapes::ShapeSet;
use crate::core::{Accel, BuildQuality, InstanceSet, PrimitiveKind, accel::point_enclosed};

/// Closest a sound source or receiver, or a radio transmitter, may be to a surface, metres:
/// nearer, it sits on the surface and half its rays start behind it.
pub const MIN_SURFACE_CLEARANCE_M: f32 = 0.01;

/// Distance from `p` to the triangle `abc` (Ericson, Real-Time Collision Detection, 5.1.5).
fn triangle_distance(p: Vec3, [a, b, c]: [Vec3; 3]) -> f32 {
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return ap.length();
    }
    let bp = p - b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return bp.length();
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return (p - (a + ab * (d1 / (d1 - d3)))).length();
    }
    let cp = p - c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return cp.length();
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return (p - (a + ac * (d2 / (d2 - d6)))).length();
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && d4 - d3 >= 0.0 && d5 - d6 >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (p - (b + (c - b) * w)).length();
    }
    let denom = 1.0 / (va + vb + vc);
    (p - (a + ab * (vb * denom) + ac * (vc * denom))).length()
}

/// The world's triangles in one mesh: the scene's own triangles first (same indices), then
/// every instance's copies in world space with their per-instance surfaces
/// ([`crate::core::accel::instances::flatten`]), and an accelerator over them (spheres and
/// shapes kept). For the deterministic path engines (image sources, edge diffraction) whose
/// planes and wedges are indexed by triangle; the rays keep the two-level world accelerator.
pub struct FlatGeometry {
    /// The scene's mesh followed by the instances' world-space copies.
    pub mesh: TriangleMesh,
    /// A one-level accelerator over `mesh`, the spheres and the shapes.
    pub accel: Accel,
}

/// A scene ready for tracing.
pub struct World {
    /// The loaded scene.
    pub scene: Scene,
    /// The acceleration structure.
    pub accel: Accel,
    /// The mesh's topology and measures, the instances' copies included.
    pub report: MeshReport,
    /// The report of each instanced mesh in its own frame.
    pub instance_reports: Vec<MeshReport>,
}

impl World {
    /// The warning for a mesh whose edges are shared by more than two triangles (an internal
    /// sheet, which rays cross as a surface), naming the scene `scene_label`; `None` if none is.
    pub fn sheet_warning(&self, scene_label: &str) -> Option<String> {
        let n = self.report.over_shared_edges;
        (n > 0).then(|| {
            format!(
                "{scene_label}: {n} edges are shared by more than two triangles (an internal sheet); rays cross it as a surface"
            )
        })
    }

    /// Corners of a box holding the scene's mesh, instances and shapes; `None` for a scene
    /// without triangles.
    pub fn bounds(&self) -> Option<(Vec3, Vec3)> {
        let mut b = self.scene.mesh.bounds()?;
        let (lo, hi) = self.accel.instances.bounds();
        if lo.x <= hi.x {
            b = (b.0.min(lo), b.1.max(hi));
        }
        for (s, _) in &self.accel.shapes.shapes {
            let (lo, hi) = s.bounds();
            b = (b.0.min(lo), b.1.max(hi));
        }
        for (s, _) in &self.accel.sdfs.sdfs {
            let (lo, hi) = s.bounds();
            b = (b.0.min(lo), b.1.max(hi));
        }
        Some(b)
    }

    /// Builds the acceleration structure and the mesh report of `scene`.
    pub fn build(scene: Scene) -> Self {
        let quality = BuildQuality::default();
        let i = &scene.instances;
        let accel = Accel::build(&scene.mesh, scene.spheres.clone(), quality)
            .with_instances(InstanceSet::build(&i.meshes, &i.list, quality))
            .with_shapes(ShapeSet::new(scene.shapes.clone()))
            .with_sdfs(SdfSet::new(scene.sdfs.clone()));
        let instance_reports: Vec<MeshReport> = i.meshes.iter().map(analyze).collect();
        let report = add_instances(analyze(&scene.mesh), &i.meshes, &instance_reports, &i.list);
        Self { scene, accel, report, instance_reports }
    }

    /// The scene with its instances flattened into one mesh ([`FlatGeometry`]); `None` for a
    /// scene without instances, whose mesh and accelerator are already flat (so such scenes
    /// keep exactly their code path).
    pub fn flat_geometry(&self) -> Option<FlatGeometry> {
        let inst = &self.scene.instances;
        if inst.list.is_empty() {
            return None;
        }
        let copies = flatten(&inst.meshes, &inst.list);
        let mut mesh = self.scene.mesh.clone();
        let base = mesh.positions.len() as u32;
        mesh.positions.extend(&copies.positions);
        mesh.triangles.extend(copies.triangles.iter().map(|t| t.map(|i| base + i)));
        mesh.surface_of_triangle.extend(&copies.surface_of_triangle);
        let accel = Accel::build(&mesh, self.scene.spheres.clone(), BuildQuality::default())
            .with_shapes(ShapeSet::new(self.scene.shapes.clone()))
            .with_sdfs(SdfSet::new(self.scene.sdfs.clone()));
        Some(FlatGeometry { mesh, accel })
    }

    /// Whether `p` lies in the room's air, by crossing parity against the closed, non-planar
    /// components (loose panels and zero-thickness partitions inside the room would flip the
    /// parity); `None` for a scene that encloses no air (open or outdoor).
    pub fn is_inside(&self, p: Vec3) -> Option<bool> {
        self.report.air_volume_m3?;
        let r = &self.report;
        Some(point_enclosed(&self.accel, p, |instance, h| {
            let (r, t) = match (h.kind, instance) {
                (PrimitiveKind::Triangle, None) => (r, h.primitive),
                (PrimitiveKind::Instance, Some(i)) => {
                    (&self.instance_reports[self.accel.instances.mesh_of(i) as usize], h.primitive)
                }
                _ => return false,
            };
            let c = &r.components[r.component_of_triangle[t as usize] as usize];
            c.closed && !c.planar
        }))
    }

    /// Distance from `p` to the nearest surface (triangle, sphere or instance), metres;
    /// infinite for an empty scene. Linear in the triangle count (instances whose box lies
    /// farther than the nearest surface found are skipped): meant for a handful of points.
    pub fn surface_distance_m(&self, p: Vec3) -> f32 {
        let mesh = &self.scene.mesh;
        let triangles = (0..mesh.triangle_count()).map(|t| triangle_distance(p, mesh.corners(t)));
        let spheres = self.scene.spheres.iter().map(|s| ((p - s.center).length() - s.radius_m).abs());
        let mut best = triangles.chain(spheres).fold(f32::INFINITY, f32::min);
        // Instances whose box comes nearer than the best so far, triangle by triangle.
        let inst = &self.scene.instances;
        for i in &inst.list {
            let m = &inst.meshes[i.mesh as usize];
            let Some((lo, hi)) = m.bounds() else { continue };
            let (wlo, whi) = transformed_box(&i.object_to_world, lo, hi);
            if (p - p.clamp(wlo, whi)).length() >= best {
                continue;
            }
            for t in 0..m.triangle_count() {
                let corners = m.corners(t).map(|c| i.object_to_world.transform_point3(c));
                best = best.min(triangle_distance(p, corners));
            }
        }
        best
    }

    /// Errors when `p` (a `what`, e.g. `source "S1"`) is closer than
    /// [`MIN_SURFACE_CLEARANCE_M`] to a surface.
    pub fn check_clearance(&self, what: &str, p: Vec3) -> Result<(), String> {
        let d = self.surface_distance_m(p);
        if d < MIN_SURFACE_CLEARANCE_M {
            return Err(format!(
                "{what} at ({}, {}, {}) is {d:.4} m from a surface: it must be at least {MIN_SURFACE_CLEARANCE_M} m away",
                p.x, p.y, p.z
            ));
        }
        Ok(())
    }

    /// Errors when an acoustic source or receiver of the scene lies outside a closed room.
    pub fn check_acoustic_points(&self) -> Result<(), SceneError> {
        let Some(a) = &self.scene.desc.acoustic else {
            return Ok(());
        };
        for (kind, list) in [("source", &a.sources), ("receiver", &a.receivers)] {
            for p in list {
                let pos = Vec3::from(p.position);
                if self.is_inside(pos) == Some(false) {
                    return Err(SceneError::invalid(
                        &self.scene.path,
                        format!(
                            "acoustic {kind} \"{}\" at ({}, {}, {}) is outside the room",
                            p.name, pos.x, pos.y, pos.z
                        ),
                    ));
                }
            }
        }
        Ok(())
    }
}
