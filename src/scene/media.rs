//! Participating media of a scene file (`[[media]]`): a named medium with absorption and
//! scattering coefficients per RGB channel and a Henyey-Greenstein asymmetry, homogeneous or
//! scaled by a density grid ([`DensityGrid`]), filling either the inside of the closed mesh
//! whose `usemtl` name is its `boundary`, or (without one) the whole scene. The renderer's
//! `volpath` and `raymarch` see them (docs/render.md, "Participating media").

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::density_grid::DensityGrid;
use super::desc::Point3;
use super::error::SceneError;
use super::load::Surface;

/// Largest accepted coefficient, 1/m (a mean free path of a micrometre).
pub const MAX_COEFFICIENT_PER_M: f32 = 1e6;

/// A `[[media]]` entry as written.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct MediumDesc {
    /// Name (for messages).
    pub name: String,
    /// Absorption coefficient per RGB channel at density 1, 1/m.
    #[serde(default)]
    pub sigma_a: Point3,
    /// Scattering coefficient per RGB channel at density 1, 1/m.
    #[serde(default)]
    pub sigma_s: Point3,
    /// Henyey-Greenstein asymmetry in (-1, 1).
    #[serde(default)]
    pub g: f32,
    /// The `usemtl` name of the closed mesh the medium fills; none: the whole scene.
    pub boundary: Option<String>,
    /// Whether the boundary only marks the medium (index-matched: rays pass it unchanged, the
    /// default) or keeps its material (glass around the medium).
    pub interface: Option<bool>,
    /// A density grid file, relative to the scene file (text, or `.raw` with `grid_dims`).
    pub grid: Option<String>,
    /// Voxels along x, y, z of a raw grid.
    pub grid_dims: Option<[u32; 3]>,
    /// Lower corner of the grid's box, metres.
    pub bounds_min: Option<Point3>,
    /// Upper corner of the grid's box, metres.
    pub bounds_max: Option<Point3>,
    /// Factor on every density of the grid (default 1).
    pub density_scale: Option<f32>,
}

/// A loaded medium.
#[derive(Clone, Debug, PartialEq)]
pub struct SceneMedium {
    /// Name.
    pub name: String,
    /// Absorption coefficient per channel at density 1, 1/m.
    pub sigma_a_per_m: Vec3,
    /// Scattering coefficient per channel at density 1, 1/m.
    pub sigma_s_per_m: Vec3,
    /// Henyey-Greenstein asymmetry.
    pub g: f32,
    /// Surface ids of the boundary (empty: the medium fills the scene).
    pub boundary: Vec<u32>,
    /// Whether rays pass the boundary unchanged.
    pub interface: bool,
    /// The density grid (none: density 1 everywhere).
    pub grid: Option<Arc<DensityGrid>>,
}

/// Loads the `[[media]]` of the scene file `path` against its surfaces; each error is one
/// line naming the file (the scene's, or the grid's) and the medium.
pub fn load_media(
    path: &Path,
    descs: &[MediumDesc],
    surfaces: &[Surface],
) -> Result<Vec<SceneMedium>, SceneError> {
    let dir = path.parent().unwrap_or(Path::new("."));
    let mut out: Vec<SceneMedium> = Vec::with_capacity(descs.len());
    for d in descs {
        let bad = |m: String| SceneError::invalid(path, format!("medium \"{}\": {m}", d.name));
        let ok = |v: Vec3| v.is_finite() && v.min_element() >= 0.0 && v.max_element() < MAX_COEFFICIENT_PER_M;
        let (sigma_a, sigma_s) = (Vec3::from(d.sigma_a), Vec3::from(d.sigma_s));
        if !ok(sigma_a) || !ok(sigma_s) {
            return Err(bad(format!(
                "sigma_a {sigma_a} and sigma_s {sigma_s} 1/m: each must be in [0, {MAX_COEFFICIENT_PER_M})"
            )));
        }
        if !(d.g.is_finite() && d.g.abs() < 0.999) {
            return Err(bad(format!("g {}: must be in (-0.999, 0.999)", d.g)));
        }
        let boundary: Vec<u32> = match &d.boundary {
            None => Vec::new(),
            Some(name) => {
                let ids: Vec<u32> =
                    (0..surfaces.len() as u32).filter(|&i| surfaces[i as usize].name == *name).collect();
                if ids.is_empty() {
                    return Err(bad(format!("boundary \"{name}\" is no usemtl name of the scene")));
                }
                ids
            }
        };
        if let Some(other) = out.iter().find(|m| {
            (m.boundary.is_empty() && boundary.is_empty()) || m.boundary.iter().any(|s| boundary.contains(s))
        }) {
            return Err(bad(format!(
                "{} as medium \"{}\" already does",
                if boundary.is_empty() { "fills the whole scene" } else { "has the same boundary" },
                other.name
            )));
        }
        let grid = match &d.grid {
            None => {
                if d.bounds_min.is_some()
                    || d.bounds_max.is_some()
                    || d.grid_dims.is_some()
                    || d.density_scale.is_some()
                {
                    return Err(
                        bad("bounds_min, bounds_max, grid_dims and density_scale need a grid".into()),
                    );
                }
                None
            }
            Some(file) => {
                let (Some(lo), Some(hi)) = (d.bounds_min, d.bounds_max) else {
                    return Err(bad("a grid needs bounds_min and bounds_max".into()));
                };
                let grid = DensityGrid::load(
                    &dir.join(file),
                    d.grid_dims,
                    d.density_scale.unwrap_or(1.0),
                    Vec3::from(lo),
                    Vec3::from(hi),
                )
                .map_err(|e| SceneError::invalid(path, format!("medium \"{}\": {e}", d.name)))?;
                Some(Arc::new(grid))
            }
        };
        out.push(SceneMedium {
            name: d.name.clone(),
            sigma_a_per_m: sigma_a,
            sigma_s_per_m: sigma_s,
            g: d.g,
            boundary,
            interface: d.interface.unwrap_or(true),
            grid,
        });
    }
    Ok(out)
}
