//! The scene file (TOML): which OBJ, which materials, and what each simulator needs
//! (camera and lights, sound sources and receivers, transmitters and a coverage grid).
//! Plain serde data; unknown keys are errors so that typos do not pass silently.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::materials::MaterialSpec;

/// A point or vector as written in a scene file, metres.
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
    /// The camera of the images, if the scene sets one.
    pub camera: Option<CameraDesc>,
    /// Suggested render settings.
    pub render: Option<RenderDesc>,
    /// Point lights of the images.
    #[serde(default)]
    pub lights: Vec<PointLightDesc>,
    /// Analytic spheres.
    #[serde(default)]
    pub spheres: Vec<SphereDesc>,
    /// Transformed analytic shapes (`[[shapes]]`).
    #[serde(default)]
    pub shapes: Vec<super::shapes::ShapeDesc>,
    /// Signed distance fields (`[[sdfs]]`).
    #[serde(default)]
    pub sdfs: Vec<super::sdf::SdfDesc>,
    /// Placed copies of meshes (`[[instances]]`).
    #[serde(default)]
    pub instances: Vec<super::instances::InstanceDesc>,
    /// Participating media (`[[media]]`), seen by the `volpath` and `raymarch` integrators.
    #[serde(default)]
    pub media: Vec<super::media::MediumDesc>,
    /// Room-acoustics settings, sources and receivers.
    pub acoustic: Option<AcousticDesc>,
    /// Radio settings, transmitters, grid and receivers.
    pub rf: Option<RfDesc>,
}

/// A look-at camera (gluLookAt convention) with an optional thin lens.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct CameraDesc {
    /// Camera position, metres.
    pub eye: Point3,
    /// Point the camera looks at, metres.
    pub target: Point3,
    /// Up direction.
    #[serde(default = "default_up")]
    pub up: Point3,
    /// Vertical field of view, degrees.
    #[serde(default = "default_fov")]
    pub fov_deg: f32,
    /// Radius of the thin lens, metres (0: a pinhole).
    #[serde(default)]
    pub aperture_radius_m: f32,
    /// Distance to the plane in focus, metres.
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
    /// Image width, pixels.
    pub width: Option<u32>,
    /// Image height, pixels.
    pub height: Option<u32>,
    /// Samples per pixel.
    pub spp: Option<u32>,
    /// Maximum number of bounces.
    pub max_depth: Option<u32>,
    /// Integrator name.
    pub integrator: Option<String>,
    /// Radiance of rays that leave the scene (linear RGB).
    pub background: Option<Point3>,
    /// PNG exposure, stops (radiance x 2^EV before the tone map); EXR stays linear.
    pub exposure_ev: Option<f32>,
    /// PNG tone map: "aces" (default), "reinhard" or "none".
    pub tone_map: Option<String>,
    /// A homogeneous fog for `volpath` and `raymarch`: absorption coefficient per RGB channel, 1/m.
    pub fog_sigma_a: Option<Point3>,
    /// The fog's scattering coefficient per RGB channel, 1/m.
    pub fog_sigma_s: Option<Point3>,
    /// The fog's Henyey-Greenstein asymmetry, in (-1, 1).
    pub fog_g: Option<f32>,
}

/// A point light; `intensity` in W/sr per RGB channel.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PointLightDesc {
    /// Position, metres.
    pub position: Point3,
    /// Radiant intensity, W/sr per RGB channel.
    pub intensity: Point3,
}

/// An analytic sphere with a named material.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct SphereDesc {
    /// Centre, metres.
    pub center: Point3,
    /// Radius, metres.
    pub radius_m: f32,
    /// Material name.
    pub material: String,
}

/// Room-acoustics settings, sources and receivers.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct AcousticDesc {
    /// Air temperature, degrees Celsius.
    pub temperature_c: Option<f32>,
    /// Relative humidity, percent.
    pub relative_humidity_percent: Option<f32>,
    /// Atmospheric pressure, kPa.
    pub pressure_kpa: Option<f32>,
    /// Rays per source.
    pub rays: Option<u64>,
    /// Length of the histograms, seconds.
    pub max_time_s: Option<f32>,
    /// Sound sources.
    #[serde(default)]
    pub sources: Vec<PointDesc>,
    /// Receivers.
    #[serde(default)]
    pub receivers: Vec<PointDesc>,
}

/// A named point (sound source or receiver, radio point receiver).
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct PointDesc {
    /// Name.
    pub name: String,
    /// Position, metres.
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
    /// A measured directivity balloon, a SOFA file (relative to the scene file) in place of
    /// `directivity`; see `acoustic::balloon`.
    pub directivity_sofa: Option<String>,
    /// The direction a source faces (its pattern's axis), or a receiver looks (the front of
    /// its Ambisonic and binaural responses); +x when absent.
    pub orientation: Option<Point3>,
    /// The top of a receiver's head, or of a measured balloon (with `orientation`); +z when
    /// absent.
    pub up: Option<Point3>,
}

/// A source directivity pattern's name in a scene file.
#[derive(Clone, Copy, Debug, Deserialize, Serialize, PartialEq, Eq)]
#[serde(rename_all = "kebab-case")]
pub enum PatternName {
    /// Alike in every direction.
    Omni,
    /// Cardioid.
    Cardioid,
    /// Supercardioid.
    Supercardioid,
    /// Hypercardioid.
    Hypercardioid,
    /// Figure of eight.
    FigureOfEight,
    /// A first-order pattern set by `directivity_alpha`.
    Mix,
}

/// `directivity_alpha`: one value for every octave band, or eight.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(untagged)]
pub enum AlphaDesc {
    /// One value for every band.
    One(f32),
    /// One value per octave band.
    Bands([f32; 8]),
}

/// Radio settings, transmitters, coverage grid and point receivers.
#[derive(Clone, Debug, Default, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct RfDesc {
    /// Carrier frequency, GHz.
    pub freq_ghz: Option<f64>,
    /// Maximum number of reflections (and transmissions) per ray.
    pub max_depth: Option<u32>,
    /// Rays per transmitter.
    pub rays: Option<u64>,
    /// Transmitters.
    #[serde(default)]
    pub transmitters: Vec<TransmitterDesc>,
    /// Coverage grid.
    pub grid: Option<GridDesc>,
    /// Point receivers.
    #[serde(default)]
    pub receivers: Vec<PointDesc>,
}

/// A radio transmitter.
#[derive(Clone, Debug, Deserialize, Serialize, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct TransmitterDesc {
    /// Name.
    pub name: String,
    /// Position, metres.
    pub position: Point3,
    /// Carrier frequency, GHz (default: the `rf` section's).
    pub freq_ghz: Option<f64>,
    /// Transmit power, dBm.
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
    /// Height of the grid plane, metres.
    pub height_m: Option<f32>,
    /// Cell side, metres.
    pub cell_m: Option<f32>,
    /// Lower corner (x, y), metres.
    pub min: Option<[f32; 2]>,
    /// Upper corner (x, y), metres.
    pub max: Option<[f32; 2]>,
}
