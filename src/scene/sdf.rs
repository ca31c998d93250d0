//! `[[sdfs]]` of a scene file: solids given by signed distance functions
//! ([`crate::core::sdf`]), primitives or smooth combinations of nested `children`, each placed
//! with the transform keys of `[[instances]]` restricted to similarities, one material per
//! top-level entry.
//!
//! Each entry is checked as it loads: its parameters, and that sphere tracing converges on a
//! fixed set of probe rays (a field that exhausts its step budget on more than 1 % of them is
//! refused, naming the budget).

use std::path::Path;

use glam::{Vec2, Vec3};
use serde::{Deserialize, Serialize};

use super::desc::Point3;
use super::error::SceneError;
use super::instances::{InstanceDesc, ScaleDesc, transform_of};
use super::load::Surface;
use super::materials::MaterialLibrary;
use crate::core::TriangleMesh;
use crate::core::ray::Ray;
use crate::core::rng::{stream, uniform};
use crate::core::sampling::uniform_sphere;
use crate::core::sdf::{DEFAULT_MAX_STEPS, March, Sdf, SdfNode, SdfShape};

/// The kinds, as written in a scene file.
pub const KINDS: &str =
    "sphere, box, rounded_box, torus, capsule, mandelbulb, smooth_union or smooth_subtraction";
/// Probe rays traced per field at load time.
pub const PROBE_RAYS: u32 = 256;
/// Nesting limit of `children`.
const MAX_DEPTH: usize = 16;

/// One `[[sdfs]]` table, or one of its `children`.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SdfDesc {
    /// One of [`KINDS`].
    pub kind: String,
    /// Material name (top-level entries only; children share it).
    pub material: Option<String>,
    /// Translation, metres.
    pub translate: Option<Point3>,
    /// Axis of the axis-angle rotation.
    pub rotate_axis: Option<Point3>,
    /// Angle of the axis-angle rotation, degrees.
    pub rotate_deg: Option<f32>,
    /// Rotations about the fixed x, y and z axes, degrees, in that order.
    pub rotate_euler_deg: Option<Point3>,
    /// One factor (a distance must stay a distance: no per-axis scale).
    pub scale: Option<f32>,
    /// Sphere and capsule: radius, metres.
    pub radius_m: Option<f32>,
    /// Box and rounded box: full side lengths, metres.
    pub size_m: Option<Point3>,
    /// Rounded box: radius of the rounded edges, metres.
    pub rounding_m: Option<f32>,
    /// Torus: radius of the centre circle (in the xy plane), metres.
    pub major_radius_m: Option<f32>,
    /// Torus: radius of the tube, metres.
    pub minor_radius_m: Option<f32>,
    /// Capsule: one end of the axis, metres.
    pub from: Option<Point3>,
    /// Capsule: the other end.
    pub to: Option<Point3>,
    /// Mandelbulb: the exponent (default 8).
    pub power: Option<f32>,
    /// Mandelbulb: iterations of the map (default 8).
    pub iterations: Option<u32>,
    /// Smooth union and subtraction: width of the blend, metres (0: sharp).
    pub blend_m: Option<f32>,
    /// Smooth union and subtraction: the combined fields (subtraction: the first minus the
    /// others).
    #[serde(default)]
    pub children: Vec<SdfDesc>,
    /// Top-level only: budget of distance evaluations per ray (default 512).
    pub max_steps: Option<u32>,
}

/// A positive finite length.
fn positive(what: &str, v: Option<f32>) -> Result<f32, String> {
    match v {
        Some(v) if v.is_finite() && v > 0.0 => Ok(v),
        Some(v) => Err(format!("{what} = {v}: must be finite and > 0")),
        None => Err(format!("needs {what}")),
    }
}

/// The node of `d` (nested `depth` deep).
fn node_of(d: &SdfDesc, depth: usize) -> Result<SdfNode, String> {
    if depth > MAX_DEPTH {
        return Err(format!("children nest deeper than {MAX_DEPTH} levels"));
    }
    // Which parameter keys each kind takes.
    let given = [
        ("radius_m", d.radius_m.is_some()),
        ("size_m", d.size_m.is_some()),
        ("rounding_m", d.rounding_m.is_some()),
        ("major_radius_m", d.major_radius_m.is_some()),
        ("minor_radius_m", d.minor_radius_m.is_some()),
        ("from", d.from.is_some()),
        ("to", d.to.is_some()),
        ("power", d.power.is_some()),
        ("iterations", d.iterations.is_some()),
        ("blend_m", d.blend_m.is_some()),
        ("children", !d.children.is_empty()),
    ];
    let takes: &[&str] = match d.kind.as_str() {
        "sphere" => &["radius_m"],
        "box" => &["size_m"],
        "rounded_box" => &["size_m", "rounding_m"],
        "torus" => &["major_radius_m", "minor_radius_m"],
        "capsule" => &["from", "to", "radius_m"],
        "mandelbulb" => &["power", "iterations"],
        "smooth_union" | "smooth_subtraction" => &["blend_m", "children"],
        other => return Err(format!("unknown kind \"{other}\": expected {KINDS}")),
    };
    if let Some((key, _)) = given.iter().find(|(k, g)| *g && !takes.contains(k)) {
        return Err(format!("{key} is not a key of {} (it takes {})", d.kind, takes.join(", ")));
    }
    let half = |v: Option<Point3>| -> Result<Vec3, String> {
        let s = Vec3::from(v.ok_or("needs size_m")?);
        if !(s.is_finite() && s.min_element() > 0.0) {
            return Err(format!("size_m = {s}: each side must be finite and > 0"));
        }
        Ok(0.5 * s)
    };
    let shape = match d.kind.as_str() {
        "sphere" => SdfShape::Sphere { radius_m: positive("radius_m", d.radius_m)? },
        "box" => SdfShape::Box { half_m: half(d.size_m)? },
        "rounded_box" => {
            let half_m = half(d.size_m)?;
            let rounding_m = d.rounding_m.ok_or("needs rounding_m")?;
            if !(rounding_m.is_finite() && rounding_m >= 0.0 && rounding_m <= half_m.min_element()) {
                return Err(format!(
                    "rounding_m = {rounding_m}: must be 0 or more and at most half the smallest side ({})",
                    half_m.min_element()
                ));
            }
            SdfShape::RoundBox { half_m, rounding_m }
        }
        "torus" => SdfShape::Torus {
            major_m: positive("major_radius_m", d.major_radius_m)?,
            minor_m: positive("minor_radius_m", d.minor_radius_m)?,
        },
        "capsule" => {
            let (Some(a), Some(b)) = (d.from, d.to) else { return Err("needs from and to".into()) };
            let (a, b) = (Vec3::from(a), Vec3::from(b));
            if !(a.is_finite() && b.is_finite()) || a == b {
                return Err(format!("from {a} and to {b}: must be finite and distinct"));
            }
            SdfShape::Capsule { a, b, radius_m: positive("radius_m", d.radius_m)? }
        }
        "mandelbulb" => {
            let power = d.power.unwrap_or(8.0);
            let iterations = d.iterations.unwrap_or(8);
            if !(2.0..=16.0).contains(&power) {
                return Err(format!("power = {power}: must be between 2 and 16"));
            }
            if !(1..=64).contains(&iterations) {
                return Err(format!("iterations = {iterations}: must be between 1 and 64"));
            }
            SdfShape::Mandelbulb { power, iterations }
        }
        kind => {
            let blend_m = d.blend_m.unwrap_or(0.0);
            if !(blend_m.is_finite() && blend_m >= 0.0) {
                return Err(format!("blend_m = {blend_m}: must be finite and 0 or more"));
            }
            if d.children.len() < 2 {
                return Err(format!("{kind} needs at least two children ({} given)", d.children.len()));
            }
            let mut children = Vec::with_capacity(d.children.len());
            for (i, c) in d.children.iter().enumerate() {
                if c.material.is_some() || c.max_steps.is_some() {
                    return Err(format!(
                        "child #{} ({}): material and max_steps belong to the top level",
                        i + 1,
                        c.kind
                    ));
                }
                children
                    .push(node_of(c, depth + 1).map_err(|e| format!("child #{} ({}): {e}", i + 1, c.kind))?);
            }
            if kind == "smooth_union" {
                SdfShape::SmoothUnion { children, blend_m }
            } else {
                SdfShape::SmoothSubtraction { children, blend_m }
            }
        }
    };
    let placement = InstanceDesc {
        name: None,
        mesh: String::new(),
        translate: d.translate,
        rotate_axis: d.rotate_axis,
        rotate_deg: d.rotate_deg,
        rotate_euler_deg: d.rotate_euler_deg,
        scale: d.scale.map(ScaleDesc::Uniform),
        matrix: None,
        material: None,
        materials: Default::default(),
    };
    let m = transform_of(&placement)?;
    if d.scale.is_some_and(|s| s <= 0.0) {
        return Err(format!("scale = {}: must be > 0", d.scale.unwrap_or_default()));
    }
    SdfNode::new(shape, m).ok_or_else(|| "the transform is singular".into())
}

/// How many of [`PROBE_RAYS`] rays, from a sphere around the field's box towards random
/// points in it, run out of steps before deciding.
pub fn unconverged_probes(sdf: &Sdf) -> u32 {
    let (lo, hi) = sdf.bounds();
    let (centre, radius) = (0.5 * (lo + hi), (hi - lo).length().max(1e-6));
    (0..PROBE_RAYS)
        .filter(|&k| {
            let mut r = stream(0x5df, 0, u64::from(k));
            let target = lo + (hi - lo) * Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r));
            let o = centre + radius * uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            let ray = Ray::new(o, (target - o).normalize());
            matches!(sdf.march(&ray), March::Exhausted(..))
        })
        .count() as u32
}

/// The fields of `descs`, their surfaces `sdf:MATERIAL` added to `mesh` and `surfaces`.
pub(crate) fn load_sdfs(
    path: &Path,
    descs: &[SdfDesc],
    library: &MaterialLibrary,
    mesh: &mut TriangleMesh,
    surfaces: &mut Vec<Surface>,
) -> Result<Vec<(Sdf, u32)>, SceneError> {
    let mut out = Vec::with_capacity(descs.len());
    for (i, d) in descs.iter().enumerate() {
        let bad = |what: String| SceneError::invalid(path, format!("sdf #{} ({}): {what}", i + 1, d.kind));
        let name = d.material.as_deref().ok_or_else(|| bad("needs a material".into()))?;
        let root = node_of(d, 0).map_err(bad)?;
        let max_steps = d.max_steps.unwrap_or(DEFAULT_MAX_STEPS);
        if !(1..=1_000_000).contains(&max_steps) {
            return Err(bad(format!("max_steps = {max_steps}: must be between 1 and 1000000")));
        }
        let sdf = Sdf::new(root, max_steps);
        let (lo, hi) = sdf.bounds();
        if !(lo.is_finite() && hi.is_finite()) {
            return Err(bad("its bounds are not finite".into()));
        }
        let stuck = unconverged_probes(&sdf);
        if stuck * 100 > PROBE_RAYS {
            return Err(bad(format!(
                "sphere tracing does not converge: {stuck} of {PROBE_RAYS} probe rays ran out of max_steps = {max_steps} distance evaluations (raise max_steps, or lower iterations)"
            )));
        }
        let material = library.get(name).cloned().ok_or_else(|| {
            let near = library.nearest_names(name, 3).join(", ");
            bad(format!("unknown material \"{name}\" (nearest known: {near})"))
        })?;
        if material.optical.as_ref().is_some_and(|o| o.emission.max_element() > 0.0) {
            return Err(bad(format!(
                "material \"{name}\" emits light: signed distance fields are not lights"
            )));
        }
        let surface = format!("sdf:{name}");
        let id = mesh.surface_id(&surface);
        if id as usize == surfaces.len() {
            surfaces.push(Surface { name: surface, material: Some(material), mtl: None });
        }
        out.push((sdf, id));
    }
    Ok(out)
}
