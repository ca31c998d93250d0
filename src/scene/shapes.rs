//! `[[shapes]]` of a scene file: transformed analytic primitives ([`crate::core::shapes`]),
//! placed with the transform keys of `[[instances]]` and given one material. A shape with an
//! emissive material is an area light of the renderer ([`crate::render::shape_light`]),
//! except a quadric, which is refused.

use std::path::Path;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::desc::Point3;
use super::error::SceneError;
use super::instances::{InstanceDesc, ScaleDesc, transform_of};
use super::load::Surface;
use super::materials::MaterialLibrary;
use crate::core::TriangleMesh;
use crate::core::shapes::{Shape, ShapeKind};

/// One `[[shapes]]` table.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct ShapeDesc {
    /// "sphere" (unit radius), "cylinder" (radius 1, z from 0 to 1, closed), "cone" (base
    /// radius 1 at z = 0, apex at z = 1, closed), "disk" (radius 1 at z = 0), "box" (side 1,
    /// centred) or "quadric".
    pub kind: String,
    /// Material name.
    pub material: String,
    /// Translation, metres.
    pub translate: Option<Point3>,
    /// Axis of the axis-angle rotation.
    pub rotate_axis: Option<Point3>,
    /// Angle of the axis-angle rotation, degrees.
    pub rotate_deg: Option<f32>,
    /// Rotations about the fixed x, y and z axes, degrees, in that order.
    pub rotate_euler_deg: Option<Point3>,
    /// One factor, or one per axis.
    pub scale: Option<ScaleDesc>,
    /// A full row-major 4x4 transform (last row 0 0 0 1).
    pub matrix: Option<[[f32; 4]; 4]>,
    /// Quadric only: `[xx, yy, zz, xy, xz, yz, x, y, z, c]` of `p^T A p + 2 b.p + c = 0`.
    pub coefficients: Option<[f32; 10]>,
    /// Quadric only: the clip box's lower corner (in the shape's frame).
    pub clip_min: Option<Point3>,
    /// Quadric only: the clip box's upper corner.
    pub clip_max: Option<Point3>,
}

/// The shapes of `descs`, their surfaces `shape:MATERIAL` added to `mesh` and `surfaces`.
pub(crate) fn load_shapes(
    path: &Path,
    descs: &[ShapeDesc],
    library: &MaterialLibrary,
    mesh: &mut TriangleMesh,
    surfaces: &mut Vec<Surface>,
) -> Result<Vec<(Shape, u32)>, SceneError> {
    let mut out = Vec::with_capacity(descs.len());
    for (i, d) in descs.iter().enumerate() {
        let bad = |what: String| SceneError::invalid(path, format!("shape #{} ({}): {what}", i + 1, d.kind));
        let kind = match d.kind.as_str() {
            "sphere" => ShapeKind::Sphere,
            "cylinder" => ShapeKind::Cylinder,
            "cone" => ShapeKind::Cone,
            "disk" => ShapeKind::Disk,
            "box" => ShapeKind::Box,
            "quadric" => {
                let (Some(k), Some(lo), Some(hi)) = (d.coefficients, d.clip_min, d.clip_max) else {
                    return Err(bad("a quadric needs coefficients, clip_min and clip_max".into()));
                };
                let (lo, hi) = (Vec3::from(lo), Vec3::from(hi));
                let finite = k.iter().all(|v| v.is_finite()) && lo.is_finite() && hi.is_finite();
                if !finite || lo.cmpgt(hi).any() {
                    return Err(bad("coefficients and clip box must be finite, clip_min <= clip_max".into()));
                }
                ShapeKind::Quadric {
                    a: [k[0], k[1], k[2], k[3], k[4], k[5]],
                    b: Vec3::new(k[6], k[7], k[8]),
                    c: k[9],
                    lo,
                    hi,
                }
            }
            other => {
                return Err(bad(format!(
                    "unknown kind \"{other}\": expected sphere, cylinder, cone, disk, box or quadric"
                )));
            }
        };
        if kind != ShapeKind::Sphere && !matches!(kind, ShapeKind::Quadric { .. }) && d.coefficients.is_some()
        {
            return Err(bad("coefficients are for quadrics only".into()));
        }
        let placement = InstanceDesc {
            name: None,
            mesh: String::new(),
            translate: d.translate,
            rotate_axis: d.rotate_axis,
            rotate_deg: d.rotate_deg,
            rotate_euler_deg: d.rotate_euler_deg,
            scale: d.scale.clone(),
            matrix: d.matrix,
            material: None,
            materials: Default::default(),
        };
        let m = transform_of(&placement).map_err(bad)?;
        let shape = Shape::new(kind, m).ok_or_else(|| bad("the transform is singular".into()))?;
        let material = library.get(&d.material).cloned().ok_or_else(|| {
            let near = library.nearest_names(&d.material, 3).join(", ");
            bad(format!("unknown material \"{}\" (nearest known: {near})", d.material))
        })?;
        let emits = material.optical.as_ref().is_some_and(|o| o.emission.max_element() > 0.0);
        if emits && matches!(kind, ShapeKind::Quadric { .. }) {
            return Err(bad(format!(
                "material \"{}\" emits light, but a quadric has no closed-form area to sample, so it cannot be a light (use a sphere, cylinder, cone, disk or box)",
                d.material
            )));
        }
        let name = format!("shape:{}", d.material);
        let id = mesh.surface_id(&name);
        if id as usize == surfaces.len() {
            surfaces.push(Surface { name, material: Some(material), mtl: None });
        }
        out.push((shape, id));
    }
    Ok(out)
}
