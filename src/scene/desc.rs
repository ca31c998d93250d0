//! The scene file (TOML): which OBJ, which materials, and what each simulator needs
//! (camera and lights, sound sources and receivers, transmitters and a coverage grid).
//! Plain serde data; unknown keys are errors so that typos do not pass silently.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::materials::MaterialSpec;

pub type Point3 = [f32; 3];

/// A whole scene file.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneDesc {
    /// The OBJ file, relative to the scene file.
    pub obj: Option<String>,
    /// The OBJ's up axis, "z" (propsim's, the default) or "y" (Blender's OBJ export): a Y-up
    /// model is rotated to Z-up at load time. Positions in this file are always Z-up.
    pub up_axis: Option<super::load::UpAxis>,
    /// Factor on the OBJ's coordinates to make metres (0.01 for centimetres, 0.0254 for
    /// inches); must be finite and > 0. Positions in this file are always metres.
    pub scale: Option<f32>,
    /// Extra materials files, relative to the scene file, applied in order.
    #[serde(default)]
    pub materials_files: Vec<String>,
    /// OBJ `usemtl` name -> material name.
    #[serde(default)]
    pub surfaces: BTreeMap<String, String>,
    /// Inline materials; they override the library and the materials files.
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialSpec>,
    pub camera: Option<CameraDesc>,
    pub render: Option<RenderDesc>,
    #[serde(default)]
    pub lights: Vec<PointLightDesc>,
    #[serde(default)]
    pub spheres: Vec<SphereDesc>,
    pub acoustic: Option<AcousticDesc>,
    pub rf: Option<RfDesc>,
}

/// A look-at camera (gluLookAt convention) with an optional thin lens.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    pub eye: Point3,
    pub target: Point3,
    #[serde(default = "default_up")]
    pub up: Point3,
    #[serde(default = "default_fov")]
    pub fov_deg: f32,
    #[serde(default)]
    pub aperture_radius_m: f32,
    pub focus_distance_m: Option<f32>,
}

fn default_up() -> Point3 {
    [0.0, 0.0, 1.0]
}

fn default_fov() -> f32 {
    40.0
}

/// Render settings a scene may suggest; command-line flags override them.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RenderDesc {
    pub width: Option<u32>,
    pub height: Option<u32>,
    pub spp: Option<u32>,
    pub max_depth: Option<u32>,
    pub integrator: Option<String>,
    pub background: Option<Point3>,
    /// PNG exposure, stops (radiance x 2^EV before the tone map); EXR stays linear.
    pub exposure_ev: Option<f32>,
    /// PNG tone map: "aces" (default), "reinhard" or "none".
    pub tone_map: Option<String>,
}

/// A point light; `intensity` in W/sr per RGB channel.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PointLightDesc {
    pub position: Point3,
    pub intensity: Point3,
}

/// An analytic sphere with a named material.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SphereDesc {
    pub center: Point3,
    pub radius_m: f32,
    pub material: String,
}

/// Room-acoustics settings, sources and receivers.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AcousticDesc {
    pub temperature_c: Option<f32>,
    pub relative_humidity_percent: Option<f32>,
    pub pressure_kpa: Option<f32>,
    pub rays: Option<u64>,
    pub max_time_s: Option<f32>,
    #[serde(default)]
    pub sources: Vec<PointDesc>,
    #[serde(default)]
    pub receivers: Vec<PointDesc>,
}

/// A named point (sound source or receiver, radio point receiver).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PointDesc {
    pub name: String,
    pub position: Point3,
    /// Receiver sphere radius, metres.
    pub radius_m: Option<f32>,
    /// Source sound power, watts.
    pub power_w: Option<f32>,
    /// Source directivity pattern (acoustic sources; omni when absent); see
    /// `acoustic::directivity`.
    pub directivity: Option<PatternName>,
    /// The omni share `a` of `directivity = "mix"`, `a + (1 - a) cos theta`: one value, or
    /// eight, one per octave band 63 Hz to 8 kHz.
    pub directivity_alpha: Option<AlphaDesc>,
    /// The direction a source faces (its pattern's axis), or a receiver looks (the front of
    /// its Ambisonic and binaural responses); +x when absent.
    pub orientation: Option<Point3>,
    /// The top of a receiver's head (with `orientation`); +z when absent.
    pub up: Option<Point3>,
}

/// A source directivity pattern's name in a scene file.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum PatternName {
    Omni,
    Cardioid,
    Supercardioid,
    Hypercardioid,
    FigureOfEight,
    Mix,
}

/// `directivity_alpha`: one value for every octave band, or eight.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(untagged)]
pub enum AlphaDesc {
    One(f32),
    Bands([f32; 8]),
}

/// Radio settings, transmitters, coverage grid and point receivers.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RfDesc {
    pub freq_ghz: Option<f64>,
    pub max_depth: Option<u32>,
    pub rays: Option<u64>,
    #[serde(default)]
    pub transmitters: Vec<TransmitterDesc>,
    pub grid: Option<GridDesc>,
    #[serde(default)]
    pub receivers: Vec<PointDesc>,
}

/// A radio transmitter.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TransmitterDesc {
    pub name: String,
    pub position: Point3,
    pub freq_ghz: Option<f64>,
    pub power_dbm: Option<f64>,
    /// "isotropic" or "dipole".
    pub antenna: Option<String>,
    /// Dipole axis (unit vector); default +z.
    pub orientation: Option<Point3>,
    /// "vertical" or "horizontal".
    pub polarization: Option<String>,
}

/// A horizontal coverage grid.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct GridDesc {
    pub height_m: Option<f32>,
    pub cell_m: Option<f32>,
    pub min: Option<[f32; 2]>,
    pub max: Option<[f32; 2]>,
}
