//! `[[instances]]` of a scene file: placed copies of a mesh (an OBJ file, or an object of
//! the scene's own OBJ), each with a transform and optional material overrides. The copies
//! share one bottom-level BVH per mesh ([`crate::core::InstanceSet`]).
//!
//! The transform maps the mesh's coordinates (in propsim's Z-up metre frame) to the world:
//! `p_world = T R S p`, where `S` is `scale`, `R = R_axis R_euler` with `R_euler = Rz(z) Ry(y)
//! Rx(x)` (`rotate_euler_deg = [x, y, z]`: about the fixed x axis first, then y, then z, as
//! pbrt's `Rotate` statements in the order z, y, x), `R_axis` the right-handed rotation of
//! `rotate_deg` about `rotate_axis` (Rodrigues), and `T` is `translate`; or a full row-major
//! 4x4 `matrix` (column vectors, its last row `0 0 0 1`), as pbrt's `Transform`
//! (transposed: pbrt's is column-major) and Embree's instance transforms.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use glam::{Affine3A, Mat4, Quat, Vec3};
use serde::{Deserialize, Serialize};

use super::desc::{Point3, SceneDesc};
use super::error::SceneError;
use super::load::{Surface, UpAxis, to_propsim_frame};
use super::materials::MaterialLibrary;
use super::obj::{ObjScene, load_obj};
use crate::core::{Instance, SurfaceId, TriangleMesh};

/// One `[[instances]]` table.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct InstanceDesc {
    /// A name for messages and reports (default: its position in the list, `#N`).
    pub name: Option<String>,
    /// The mesh placed: an OBJ file relative to the scene file (a name ending in `.obj`), or
    /// an object (`o`) or group (`g`) of the scene's own OBJ, which then becomes a prototype:
    /// it is no longer part of the scene at its own place.
    pub mesh: String,
    /// Translation, metres.
    pub translate: Option<Point3>,
    /// Axis of the axis-angle rotation (need not be unit length).
    pub rotate_axis: Option<Point3>,
    /// Angle of the axis-angle rotation, degrees, right-handed about `rotate_axis`.
    pub rotate_deg: Option<f32>,
    /// Rotations about the fixed x, y and z axes, degrees, applied in that order.
    pub rotate_euler_deg: Option<Point3>,
    /// Scale factor: one number, or one per axis (negative mirrors).
    pub scale: Option<ScaleDesc>,
    /// A full transform, row-major 4x4 acting on column vectors (last row 0 0 0 1); excludes
    /// the other transform keys.
    pub matrix: Option<[[f32; 4]; 4]>,
    /// Material of every surface of the copy (overrides the mesh's own).
    pub material: Option<String>,
    /// Per-surface overrides: the mesh's `usemtl` name -> material name.
    #[serde(default)]
    pub materials: BTreeMap<String, String>,
}

/// `scale`: one factor, or one per axis.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(untagged)]
pub enum ScaleDesc {
    /// The same factor on every axis.
    Uniform(f32),
    /// One factor per axis.
    Axes(Point3),
}

/// The loaded instances of a scene.
#[derive(Clone, Debug, Default)]
pub struct SceneInstances {
    /// The distinct meshes, each in its own frame with its own surface names.
    pub meshes: Vec<TriangleMesh>,
    /// What each mesh is: the OBJ file or `object NAME`.
    pub mesh_names: Vec<String>,
    /// The placed copies, in file order.
    pub list: Vec<Instance>,
    /// Each copy's name (its `name`, else `#N`).
    pub names: Vec<String>,
}

impl SceneInstances {
    /// Whether the scene places no copy.
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }
}

/// How an instance is named in messages.
fn label(i: usize, d: &InstanceDesc) -> String {
    match &d.name {
        Some(n) => format!("instance \"{n}\""),
        None => format!("instance #{}", i + 1),
    }
}

/// The transform of `d` (see the module comment), or why there is none.
pub fn transform_of(d: &InstanceDesc) -> Result<Affine3A, String> {
    let m = if let Some(rows) = d.matrix {
        if d.translate.is_some()
            || d.rotate_axis.is_some()
            || d.rotate_deg.is_some()
            || d.rotate_euler_deg.is_some()
            || d.scale.is_some()
        {
            return Err(
                "matrix excludes translate, rotate_axis, rotate_deg, rotate_euler_deg and scale".into()
            );
        }
        if rows.iter().flatten().any(|v| !v.is_finite()) {
            return Err("matrix has a non-finite entry".into());
        }
        if rows[3] != [0.0, 0.0, 0.0, 1.0] {
            return Err(format!(
                "matrix's last row is {:?}: it must be [0, 0, 0, 1] (affine transforms only)",
                rows[3]
            ));
        }
        Affine3A::from_mat4(Mat4::from_cols_array_2d(&rows).transpose())
    } else {
        let scale = match d.scale {
            None => Vec3::ONE,
            Some(ScaleDesc::Uniform(s)) => Vec3::splat(s),
            Some(ScaleDesc::Axes(a)) => Vec3::from(a),
        };
        if !scale.is_finite() {
            return Err(format!("scale {scale} is not finite"));
        }
        let [x, y, z] = d.rotate_euler_deg.unwrap_or([0.0; 3]).map(f32::to_radians);
        let euler = Quat::from_rotation_z(z) * Quat::from_rotation_y(y) * Quat::from_rotation_x(x);
        let axis_angle = match (d.rotate_axis, d.rotate_deg) {
            (None, None) => Quat::IDENTITY,
            (Some(axis), Some(deg)) => {
                let axis = Vec3::from(axis);
                if !axis.is_finite() || axis.length_squared() == 0.0 || !deg.is_finite() {
                    return Err(format!(
                        "rotate_axis {axis} and rotate_deg {deg}: the axis must be finite and non-zero, the angle finite"
                    ));
                }
                Quat::from_axis_angle(axis.normalize(), deg.to_radians())
            }
            _ => return Err("rotate_axis and rotate_deg go together".into()),
        };
        let translate = Vec3::from(d.translate.unwrap_or([0.0; 3]));
        if !translate.is_finite() || !(euler.is_finite()) {
            return Err("translate and rotate_euler_deg must be finite".into());
        }
        Affine3A::from_translation(translate)
            * Affine3A::from_quat(axis_angle * euler)
            * Affine3A::from_scale(scale)
    };
    if !m.is_finite() {
        return Err("the transform is not finite".into());
    }
    let det = m.matrix3.determinant();
    if !det.is_finite() {
        return Err(format!("the transform's determinant {det} is not finite: its scale is too large"));
    }
    if !Instance::transform_is_valid(&m) {
        return Err(format!(
            "the transform is singular (determinant {}): it would flatten the mesh",
            m.matrix3.determinant()
        ));
    }
    Ok(m)
}

/// The triangles of the scene OBJ's objects named `name`, with their own vertices and
/// surface names; `None` when no object has that name.
fn object_mesh(obj: &ObjScene, mesh: &TriangleMesh, name: &str) -> Option<TriangleMesh> {
    let ids: Vec<u32> =
        (obj.object_names.iter().enumerate()).filter(|(_, n)| *n == name).map(|(i, _)| i as u32).collect();
    if ids.is_empty() {
        return None;
    }
    let mut out = TriangleMesh::default();
    let mut remap: HashMap<u32, u32> = HashMap::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if !ids.contains(&obj.object_of_triangle[t]) {
            continue;
        }
        let v = tri.map(|i| {
            *remap.entry(i).or_insert_with(|| {
                out.positions.push(mesh.positions[i as usize]);
                (out.positions.len() - 1) as u32
            })
        });
        let s = out.surface_id(&mesh.surface_names[mesh.surface_of_triangle[t] as usize]);
        out.triangles.push(v);
        out.surface_of_triangle.push(s);
    }
    Some(out)
}

/// Everything [`load_instances`] needs from the scene being loaded.
pub(crate) struct LoadContext<'a> {
    /// The scene file.
    pub path: &'a Path,
    /// The scene's description.
    pub desc: &'a SceneDesc,
    /// The scene OBJ as read (object names per triangle).
    pub obj: &'a ObjScene,
    /// The OBJ files' frame.
    pub up: UpAxis,
    /// The OBJ files' scale to metres.
    pub scale: f32,
    /// The materials.
    pub library: &'a MaterialLibrary,
}

/// Loads the scene's `[[instances]]`: each distinct mesh once, every copy's transform and
/// surfaces (new surfaces are appended to `mesh.surface_names` and `surfaces`). Objects of
/// the scene OBJ that are placed become prototypes and leave `mesh`.
pub(crate) fn load_instances(
    cx: &LoadContext<'_>,
    mesh: &mut TriangleMesh,
    surfaces: &mut Vec<Surface>,
    warnings: &mut Vec<String>,
) -> Result<SceneInstances, SceneError> {
    let mut out = SceneInstances::default();
    if cx.desc.instances.is_empty() {
        return Ok(out);
    }
    let base_dir = cx.path.parent().unwrap_or(Path::new("."));
    let invalid = |i: usize, d: &InstanceDesc, what: String| {
        SceneError::invalid(cx.path, format!("{}: {what}", label(i, d)))
    };
    // Mesh key -> (index, MTL entries of its file).
    let mut index_of: HashMap<String, usize> = HashMap::new();
    let mut mtl_of: Vec<BTreeMap<String, super::obj::MtlEntry>> = Vec::new();
    let mut prototypes: Vec<String> = Vec::new();
    for (i, d) in cx.desc.instances.iter().enumerate() {
        let transform = transform_of(d).map_err(|e| invalid(i, d, e))?;
        let is_file = Path::new(&d.mesh).extension().map(|e| e.to_ascii_lowercase());
        let key = match is_file.as_deref().and_then(|e| e.to_str()) {
            Some("obj") => format!("file {}", d.mesh),
            Some("toml") => {
                return Err(invalid(
                    i,
                    d,
                    format!(
                        "mesh = \"{}\" is a scene file: instances place OBJ meshes, and instances do not nest",
                        d.mesh
                    ),
                ));
            }
            _ => format!("object {}", d.mesh),
        };
        let m = match index_of.get(&key) {
            Some(&m) => m,
            None => {
                let (loaded, mtl) = if key.starts_with("file ") {
                    let file = base_dir.join(&d.mesh);
                    if !file.is_file() {
                        return Err(invalid(i, d, format!("mesh file {} not found", file.display())));
                    }
                    let o = load_obj(&file)?;
                    if o.degenerate_dropped > 0 {
                        warnings.push(format!(
                            "{}: dropped {} degenerate (zero-area) triangles",
                            file.display(),
                            o.degenerate_dropped
                        ));
                    }
                    let mut m = o.mesh;
                    if cx.up != UpAxis::Z || cx.scale != 1.0 {
                        to_propsim_frame(&mut m.positions, cx.up, cx.scale);
                    }
                    (m, o.mtl)
                } else {
                    let m = object_mesh(cx.obj, mesh, &d.mesh).ok_or_else(|| {
                        let mut names: Vec<&str> =
                            cx.obj.object_names.iter().map(String::as_str).filter(|n| !n.is_empty()).collect();
                        names.dedup();
                        names.truncate(12);
                        invalid(
                            i,
                            d,
                            format!(
                                "unknown mesh \"{}\": not an .obj file, and the scene's OBJ has no object or group of that name (it has: {})",
                                d.mesh,
                                if names.is_empty() { "none".to_string() } else { names.join(", ") }
                            ),
                        )
                    })?;
                    prototypes.push(d.mesh.clone());
                    (m, cx.obj.mtl.clone())
                };
                if loaded.triangle_count() == 0 {
                    return Err(invalid(i, d, format!("mesh \"{}\" has no usable triangles", d.mesh)));
                }
                out.meshes.push(loaded);
                out.mesh_names.push(key.clone());
                mtl_of.push(mtl);
                index_of.insert(key, out.meshes.len() - 1);
                out.meshes.len() - 1
            }
        };
        let local = &out.meshes[m];
        for name in d.materials.keys() {
            if !local.surface_names.contains(name) {
                return Err(invalid(
                    i,
                    d,
                    format!(
                        "materials maps \"{name}\" but mesh \"{}\" has no such usemtl (it has: {})",
                        d.mesh,
                        local.surface_names.join(", ")
                    ),
                ));
            }
        }
        let mut ids: Vec<SurfaceId> = Vec::with_capacity(local.surface_names.len());
        for name in &local.surface_names {
            let overridden = d.materials.get(name).or(d.material.as_ref());
            let material_name = overridden.or_else(|| cx.desc.surfaces.get(name)).unwrap_or(name);
            let global = match overridden {
                Some(mat) => format!("{name} as {mat}"),
                None => name.clone(),
            };
            let id = mesh.surface_id(&global);
            if id as usize == surfaces.len() {
                let material = cx.library.get(material_name).cloned();
                let mtl = if overridden.is_some() { None } else { mtl_of[m].get(name).cloned() };
                if material.is_none() && mtl.is_none() {
                    let near = cx.library.nearest_names(material_name, 3).join(", ");
                    return Err(invalid(
                        i,
                        d,
                        format!("unknown material \"{material_name}\" (nearest known: {near})"),
                    ));
                }
                surfaces.push(Surface { name: global, material, mtl });
            }
            ids.push(id);
        }
        out.list.push(Instance { mesh: m as u32, object_to_world: transform, surfaces: ids });
        out.names.push(d.name.clone().unwrap_or_else(|| format!("#{}", i + 1)));
    }
    if !prototypes.is_empty() {
        remove_objects(mesh, cx.obj, &prototypes);
        if mesh.triangle_count() == 0 {
            return Err(SceneError::invalid(
                cx.path,
                "the scene's OBJ has no geometry of its own besides the instanced objects (prototypes); keep at least a floor or walls in it",
            ));
        }
    }
    Ok(out)
}

/// Removes the triangles of the objects named in `names` from `mesh` (and the vertices only
/// they used).
fn remove_objects(mesh: &mut TriangleMesh, obj: &ObjScene, names: &[String]) {
    let drop: Vec<bool> = obj.object_names.iter().map(|n| names.contains(n)).collect();
    let mut kept =
        TriangleMesh { surface_names: std::mem::take(&mut mesh.surface_names), ..Default::default() };
    let mut remap: HashMap<u32, u32> = HashMap::new();
    for (t, tri) in mesh.triangles.iter().enumerate() {
        if drop[obj.object_of_triangle[t] as usize] {
            continue;
        }
        let v = tri.map(|i| {
            *remap.entry(i).or_insert_with(|| {
                kept.positions.push(mesh.positions[i as usize]);
                (kept.positions.len() - 1) as u32
            })
        });
        kept.triangles.push(v);
        kept.surface_of_triangle.push(mesh.surface_of_triangle[t]);
    }
    *mesh = kept;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn desc(toml_text: &str) -> InstanceDesc {
        toml::from_str(&format!("mesh = \"m\"\n{toml_text}")).unwrap()
    }

    #[test]
    fn transform_keys_compose_in_the_documented_order() {
        let d = desc("translate = [1, 2, 3]\nrotate_euler_deg = [90, 0, 90]\nscale = [2, 1, 1]");
        let m = transform_of(&d).unwrap();
        // x: scaled to (2,0,0), about x: unchanged, about z by 90: (0,2,0), then translated.
        assert!((m.transform_point3(Vec3::X) - Vec3::new(1.0, 4.0, 3.0)).length() < 1e-5);
        // y: about x by 90 -> z, about z: unchanged.
        assert!((m.transform_vector3(Vec3::Y) - Vec3::Z).length() < 1e-5);
        let d = desc("rotate_axis = [0, 0, 2]\nrotate_deg = 90\nscale = 3");
        let m = transform_of(&d).unwrap();
        assert!((m.transform_vector3(Vec3::X) - Vec3::new(0.0, 3.0, 0.0)).length() < 1e-5);
        let d = desc("matrix = [[1, 0, 0, 5], [0, 2, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]");
        let m = transform_of(&d).unwrap();
        assert!((m.transform_point3(Vec3::ONE) - Vec3::new(6.0, 2.0, 1.0)).length() < 1e-6);
    }

    #[test]
    fn bad_transforms_are_refused() {
        for (text, want) in [
            ("scale = [1, 0, 1]", "singular"),
            ("matrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 1, 1]]", "last row"),
            ("matrix = [[1, 0, 0, 0], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]", "singular"),
            (
                "translate = [1, 0, 0]\nmatrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]",
                "excludes",
            ),
            ("rotate_deg = 10", "go together"),
            ("rotate_axis = [0, 0, 0]\nrotate_deg = 10", "non-zero"),
            ("scale = 1e30", "not finite"),
        ] {
            let e = transform_of(&desc(text)).unwrap_err();
            assert!(e.contains(want), "{text}: {e}");
        }
        let mut d = desc("");
        d.translate = Some([f32::NAN, 0.0, 0.0]);
        assert!(transform_of(&d).is_err());
    }
}
