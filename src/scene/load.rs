//! Loading a scene: a TOML scene file or a bare OBJ, resolved against the material library.

use std::path::{Path, PathBuf};

use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::builtin;
use super::desc::SceneDesc;
use super::error::SceneError;
use super::instances::{LoadContext, SceneInstances, load_instances};
use super::materials::{Material, MaterialLibrary};
use super::obj::{MtlEntry, load_obj};
use crate::core::{Sphere, TriangleMesh};

/// One surface (material slot) of the scene: the name used in the geometry and its material.
#[derive(Clone, Debug)]
pub struct Surface {
    /// The OBJ `usemtl` name, or the material name for analytic spheres.
    pub name: String,
    /// The resolved material, or `None` when neither the library nor a materials file knows
    /// it (only allowed when the MTL defines it: such surfaces carry optical data only).
    pub material: Option<Material>,
    /// What the OBJ's MTL says about the surface, if anything.
    pub mtl: Option<MtlEntry>,
}

/// A loaded scene: geometry, surfaces with materials, and the description's other parts.
#[derive(Debug)]
pub struct Scene {
    /// The file the user named (scene TOML or OBJ).
    pub path: PathBuf,
    /// The OBJ file.
    pub obj_path: PathBuf,
    /// The triangles.
    pub mesh: TriangleMesh,
    /// Indexed by `SurfaceId`; triangle surfaces first, then one per sphere material.
    pub surfaces: Vec<Surface>,
    /// Analytic spheres.
    pub spheres: Vec<Sphere>,
    /// Placed copies of meshes (`[[instances]]`); their surfaces are among `surfaces`.
    pub instances: SceneInstances,
    /// Transformed analytic shapes (`[[shapes]]`) and their surfaces.
    pub shapes: Vec<(crate::core::shapes::Shape, u32)>,
    /// Signed distance fields (`[[sdfs]]`) and their surfaces.
    pub sdfs: Vec<(crate::core::sdf::Sdf, u32)>,
    /// Participating media (`[[media]]`).
    pub media: Vec<super::media::SceneMedium>,
    /// The scene description.
    pub desc: SceneDesc,
    /// The materials.
    pub library: MaterialLibrary,
    /// Non-fatal findings (dropped degenerate triangles, ...), one line each.
    pub warnings: Vec<String>,
}

impl Scene {
    /// Ids of the surfaces that some triangle uses: the mesh's and the instances'.
    pub fn used_surfaces(&self) -> std::collections::BTreeSet<u32> {
        let mut used: std::collections::BTreeSet<u32> =
            self.mesh.surface_of_triangle.iter().copied().collect();
        used.extend(self.shapes.iter().map(|(_, s)| *s));
        used.extend(self.sdfs.iter().map(|(_, s)| *s));
        for i in &self.instances.list {
            let local: std::collections::BTreeSet<u32> =
                self.instances.meshes[i.mesh as usize].surface_of_triangle.iter().copied().collect();
            used.extend(local.into_iter().filter_map(|l| i.surfaces.get(l as usize).copied()));
        }
        used
    }
}

/// What a user adds to a scene as it loads: extra materials files and how to read the
/// model's coordinates. The flags of every command that loads a scene, and the Python
/// module's keyword arguments. Positions given by the user or the scene file stay in
/// propsim's Z-up metre frame; `up_axis` and `scale` only move the OBJ into it.
#[derive(clap::Args, Clone, Debug, Default, PartialEq)]
pub struct LoadOptions {
    /// Extra materials file(s), applied after the scene's own files.
    #[arg(long = "materials", value_name = "FILE")]
    pub materials_files: Vec<PathBuf>,
    /// The OBJ's up axis: z (propsim's) or y (Blender's OBJ export default), rotated
    /// (x, y, z) -> (x, -z, y) at load time (default: the scene's up_axis, else z).
    #[arg(long = "up-axis", value_name = "y|z", value_parser = parse_up_axis)]
    pub up_axis: Option<UpAxis>,
    /// Factor on the OBJ's coordinates to make metres: 0.01 for centimetres, 0.0254 for
    /// inches (default: the scene's scale, else 1).
    #[arg(long, value_name = "FACTOR", value_parser = parse_scale)]
    pub scale: Option<f32>,
}

/// `--up-axis`'s value.
fn parse_up_axis(s: &str) -> Result<UpAxis, String> {
    s.parse()
}

/// `--scale`'s value: a finite positive number.
fn parse_scale(s: &str) -> Result<f32, String> {
    let v: f32 = s.trim().parse().map_err(|_| format!("\"{s}\" is not a number"))?;
    check_scale(v)
}

/// Which axis of an OBJ points up. propsim is Z-up; Blender's OBJ exporter (and many other
/// tools) write Y-up files, which load lying on their side unless rotated.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum UpAxis {
    /// Y up: each vertex (x, y, z) becomes (x, -z, y), a right-handed rotation (the inverse of
    /// Blender's export), so faces keep their winding.
    Y,
    /// Z up, propsim's own frame: coordinates are used as they are.
    #[default]
    Z,
}

impl std::str::FromStr for UpAxis {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s.to_ascii_lowercase().as_str() {
            "y" => Ok(UpAxis::Y),
            "z" => Ok(UpAxis::Z),
            _ => Err(format!("\"{s}\": expected y or z")),
        }
    }
}

impl<'de> Deserialize<'de> for UpAxis {
    /// From the scene key: "y" or "z", with an error naming the key.
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(|e| serde::de::Error::custom(format!("up_axis = {e}")))
    }
}

/// Checks a model scale factor: finite and greater than zero.
pub fn check_scale(scale: f32) -> Result<f32, String> {
    if scale.is_finite() && scale > 0.0 {
        Ok(scale)
    } else {
        Err(format!("{scale} is not a scale factor: it must be a finite number greater than 0"))
    }
}

/// Puts model coordinates into propsim's Z-up metre frame: rotated for `up`, then multiplied
/// by `scale`.
pub fn to_propsim_frame(positions: &mut [Vec3], up: UpAxis, scale: f32) {
    for p in positions {
        let v = match up {
            UpAxis::Y => Vec3::new(p.x, -p.z, p.y),
            UpAxis::Z => *p,
        };
        *p = v * scale;
    }
}

fn is_toml(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case("toml"))
}

fn check_point(path: &Path, what: &str, p: [f32; 3]) -> Result<Vec3, SceneError> {
    let v = Vec3::from(p);
    if v.is_finite() {
        Ok(v)
    } else {
        Err(SceneError::invalid(path, format!("{what} has a non-finite position {v}")))
    }
}

/// Loads a scene file (`.toml`), a bare OBJ, or a built-in scene (`builtin:NAME`).
pub fn load(path: &Path, options: &LoadOptions) -> Result<Scene, SceneError> {
    if let Some(name) = builtin::builtin_name(path) {
        let (_dir, main) = builtin::materialize(name)?;
        let mut scene = load(&main, options)?;
        scene.path = path.to_path_buf();
        scene.obj_path = Path::new(&format!("{}{name}", builtin::BUILTIN_PREFIX))
            .join(scene.obj_path.file_name().unwrap_or_default());
        return Ok(scene);
    }
    if !path.exists() {
        return Err(SceneError::NotFound { path: path.to_path_buf() });
    }
    let (desc, obj_path) = if is_toml(path) {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError::io(path, &e))?;
        let desc: SceneDesc = toml::from_str(&text).map_err(|e| SceneError::toml(path, &text, &e))?;
        let obj = desc.obj.clone().ok_or_else(|| {
            SceneError::invalid(path, "the scene names no geometry: add obj = \"FILE.obj\"")
        })?;
        let dir = path.parent().unwrap_or(Path::new("."));
        (desc, dir.join(obj))
    } else {
        (SceneDesc::default(), path.to_path_buf())
    };
    let base_dir = path.parent().unwrap_or(Path::new(".")).to_path_buf();

    let mut library = MaterialLibrary::builtin();
    for f in &desc.materials_files {
        library.add_file(&base_dir.join(f))?;
    }
    for f in &options.materials_files {
        library.add_file(f)?;
    }
    library.add_specs(path, &desc.materials)?;

    let mut obj = load_obj(&obj_path)?;
    let mut warnings = Vec::new();
    if obj.degenerate_dropped > 0 {
        warnings.push(format!(
            "{}: dropped {} degenerate (zero-area) triangles",
            obj_path.display(),
            obj.degenerate_dropped
        ));
    }
    let mut mesh = std::mem::take(&mut obj.mesh);
    if mesh.triangle_count() == 0 {
        return Err(SceneError::invalid(&obj_path, "the scene is empty: no usable triangles"));
    }
    // The model into propsim's frame; positions in the scene file are already in it.
    if let Some(s) = desc.scale {
        check_scale(s).map_err(|e| SceneError::invalid(path, format!("scale = {e}")))?;
    }
    let up = options.up_axis.or(desc.up_axis).unwrap_or_default();
    let scale = options.scale.or(desc.scale).unwrap_or(1.0);
    if up != UpAxis::Z || scale != 1.0 {
        to_propsim_frame(&mut mesh.positions, up, scale);
        if !mesh.positions.iter().all(|p| p.is_finite()) {
            return Err(SceneError::invalid(
                &obj_path,
                format!("scaled by {scale} the model has coordinates too large for 32-bit floats"),
            ));
        }
        if (0..mesh.triangle_count()).all(|t| mesh.triangle_area(t) <= 0.0) {
            return Err(SceneError::invalid(
                &obj_path,
                format!("scaled by {scale} the model shrinks to nothing: every triangle has zero area"),
            ));
        }
    }

    // Resolve every surface name.
    for (name, target) in &desc.surfaces {
        if !mesh.surface_names.contains(name) {
            warnings.push(format!(
                "{}: [surfaces] maps \"{name}\" but the OBJ has no such usemtl",
                path.display()
            ));
        }
        if library.get(target).is_none() {
            let near = library.nearest_names(target, 3).join(", ");
            return Err(SceneError::invalid(
                path,
                format!(
                    "[surfaces] maps \"{name}\" to unknown material \"{target}\" (nearest known: {near})"
                ),
            ));
        }
    }
    let mut surfaces = Vec::new();
    let mut unknown = Vec::new();
    for name in &mesh.surface_names {
        let material_name = desc.surfaces.get(name).unwrap_or(name);
        let material = library.get(material_name).cloned();
        let mtl = obj.mtl.get(name).cloned();
        if material.is_none() && mtl.is_none() {
            unknown.push(name.clone());
        }
        surfaces.push(Surface { name: name.clone(), material, mtl });
    }
    if !unknown.is_empty() {
        let detail: Vec<String> = unknown
            .iter()
            .map(|n| format!("\"{n}\" (nearest known: {})", library.nearest_names(n, 3).join(", ")))
            .collect();
        return Err(SceneError::invalid(
            &obj_path,
            format!(
                "unknown material names: {}; define them in a materials file (--materials) or the scene's [materials]",
                detail.join("; ")
            ),
        ));
    }

    // Analytic spheres get one surface per material name.
    let mut spheres = Vec::new();
    for (i, s) in desc.spheres.iter().enumerate() {
        let center = check_point(path, &format!("sphere {}", i + 1), s.center)?;
        if !(s.radius_m.is_finite() && s.radius_m > 0.0) {
            return Err(SceneError::invalid(
                path,
                format!("sphere {} has radius {} (must be > 0)", i + 1, s.radius_m),
            ));
        }
        let material = library.get(&s.material).cloned().ok_or_else(|| {
            let near = library.nearest_names(&s.material, 3).join(", ");
            SceneError::invalid(
                path,
                format!("sphere {} uses unknown material \"{}\" (nearest known: {near})", i + 1, s.material),
            )
        })?;
        let id = mesh.surface_id(&format!("sphere:{}", s.material));
        if id as usize == surfaces.len() {
            surfaces.push(Surface {
                name: format!("sphere:{}", s.material),
                material: Some(material),
                mtl: None,
            });
        }
        spheres.push(Sphere::new(center, s.radius_m, id));
    }

    let instances = load_instances(
        &LoadContext { path, desc: &desc, obj: &obj, up, scale, library: &library },
        &mut mesh,
        &mut surfaces,
        &mut warnings,
    )?;

    let shapes = super::shapes::load_shapes(path, &desc.shapes, &library, &mut mesh, &mut surfaces)?;
    let sdfs = super::sdf::load_sdfs(path, &desc.sdfs, &library, &mut mesh, &mut surfaces)?;
    let media = super::media::load_media(path, &desc.media, &surfaces)?;

    // Positions given in the description must be finite.
    if let Some(c) = &desc.camera {
        check_point(path, "camera eye", c.eye)?;
        check_point(path, "camera target", c.target)?;
    }
    for (i, l) in desc.lights.iter().enumerate() {
        check_point(path, "light", l.position)?;
        let w = Vec3::from(l.intensity);
        if !(w.is_finite() && w.min_element() >= 0.0) {
            return Err(SceneError::invalid(
                path,
                format!("light {} has intensity {w} W/sr: each channel must be finite and 0 or more", i + 1),
            ));
        }
    }
    if let Some(a) = &desc.acoustic {
        for p in a.sources.iter().chain(&a.receivers) {
            check_point(path, &format!("acoustic point \"{}\"", p.name), p.position)?;
        }
    }
    if let Some(r) = &desc.rf {
        for t in &r.transmitters {
            check_point(path, &format!("transmitter \"{}\"", t.name), t.position)?;
        }
    }

    Ok(Scene {
        path: path.to_path_buf(),
        obj_path,
        mesh,
        surfaces,
        spheres,
        instances,
        shapes,
        sdfs,
        media,
        desc,
        library,
        warnings,
    })
}
