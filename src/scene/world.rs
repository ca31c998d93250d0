//! The runtime world: a scene plus its acceleration structure. The one thing simulators read.

use glam::Vec3;

use super::check::{MeshReport, analyze};
use super::error::SceneError;
use super::load::Scene;
use crate::core::{Accel, BuildQuality, accel::point_enclosed};

/// A scene ready for tracing.
pub struct World {
    pub scene: Scene,
    pub accel: Accel,
    pub report: MeshReport,
}

impl World {
    pub fn build(scene: Scene) -> Self {
        let accel = Accel::build(&scene.mesh, scene.spheres.clone(), BuildQuality::default());
        let report = analyze(&scene.mesh);
        Self { scene, accel, report }
    }

    /// Whether `p` lies in the room's air, by crossing parity against the closed, non-planar
    /// components (loose panels and zero-thickness partitions inside the room would flip the
    /// parity); `None` for a scene that encloses no air (open or outdoor).
    pub fn is_inside(&self, p: Vec3) -> Option<bool> {
        self.report.air_volume_m3?;
        let r = &self.report;
        Some(point_enclosed(&self.accel, p, |t| {
            let c = &r.components[r.component_of_triangle[t as usize] as usize];
            c.closed && !c.planar
        }))
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
