//! Source directivity: analytic first-order patterns per octave band, normalised to the
//! omnidirectional source's power (docs/acoustics.md, Directivity).
//!
//! A first-order pattern has the pressure (amplitude) gain `g(theta) = a + (1 - a) cos theta`
//! about its axis, `theta` the angle from the axis, and the energy gain `g^2`. Over the
//! sphere `integral g^2 dOmega = 4 pi (a^2 + (1 - a)^2 / 3)`, so the energy weight
//!
//! `w(theta) = g(theta)^2 / (a^2 + (1 - a)^2 / 3)`
//!
//! integrates to `4 pi`, the omnidirectional source's: a directional source of power P
//! radiates P in total, its late (diffuse) energy is the omni's, and only the direct sound
//! and the early reflections change. `w(0)` is the directivity factor Q (3 for the cardioid,
//! 4 for the hypercardioid, 3 for the figure-of-eight).

use std::sync::Arc;

use glam::Vec3;
use serde::Serialize;

use super::balloon::Balloon;

use crate::scene::desc::{AlphaDesc, PatternName};
use crate::scene::materials::{BAND_COUNT, BandValues};

/// The named patterns a scene file and the command line accept, as they spell them.
pub const PATTERN_NAMES: [&str; 6] =
    ["omni", "cardioid", "supercardioid", "hypercardioid", "figure-of-eight", "mix"];

/// The supercardioid's `a`: the first-order pattern with the largest front-to-back energy
/// ratio, `a = (sqrt 3 - 1) / 2` (docs/acoustics.md, Directivity).
pub const SUPERCARDIOID_A: f32 = 0.366_025_42;

/// The hypercardioid's `a`: the first-order pattern with the largest directivity factor
/// (Q = 4), `a = 1 / 4`.
pub const HYPERCARDIOID_A: f32 = 0.25;

/// A first-order pattern `a + (1 - a) cos theta` given by its omni share `a` in [0, 1]:
/// 1 omni, 1/2 cardioid, [`SUPERCARDIOID_A`], [`HYPERCARDIOID_A`], 0 figure-of-eight.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct FirstOrder {
    /// Omni share, in [0, 1].
    pub a: f32,
}

impl FirstOrder {
    /// Alike in every direction.
    pub const OMNI: Self = Self { a: 1.0 };
    /// Cardioid.
    pub const CARDIOID: Self = Self { a: 0.5 };
    /// Supercardioid.
    pub const SUPERCARDIOID: Self = Self { a: SUPERCARDIOID_A };
    /// Hypercardioid.
    pub const HYPERCARDIOID: Self = Self { a: HYPERCARDIOID_A };
    /// Figure of eight.
    pub const FIGURE_OF_EIGHT: Self = Self { a: 0.0 };

    /// The pressure gain at `cos_theta` from the axis, `a + (1 - a) cos theta` (negative in a
    /// rear lobe: the polarity flips there).
    #[inline]
    pub fn gain(self, cos_theta: f32) -> f32 {
        self.a + (1.0 - self.a) * cos_theta
    }

    /// The energy weight normalised to the sphere, `g^2 / (a^2 + (1 - a)^2 / 3)`: its mean over
    /// all directions is 1.
    #[inline]
    pub fn energy_weight(self, cos_theta: f32) -> f32 {
        let g = self.gain(cos_theta);
        g * g / self.mean_square()
    }

    /// The pressure gain normalised like [`Self::energy_weight`] (its square is that weight).
    #[inline]
    pub fn normalised_gain(self, cos_theta: f32) -> f32 {
        self.gain(cos_theta) / self.mean_square().sqrt()
    }

    /// `(1 / 4 pi) integral g^2 dOmega = a^2 + (1 - a)^2 / 3`.
    #[inline]
    pub fn mean_square(self) -> f32 {
        let b = 1.0 - self.a;
        self.a * self.a + b * b / 3.0
    }

    /// The directivity factor Q, the weight on the axis.
    pub fn directivity_factor(self) -> f32 {
        self.energy_weight(1.0)
    }
}

/// A source's or receiver's directivity: one first-order pattern per octave band about a
/// unit axis (the direction it faces, its on-axis direction), or a measured balloon
/// ([`Balloon`]) whose front is the axis and whose top is `up`.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Directivity {
    /// The pattern of each octave band (unused with a balloon).
    pub bands: [FirstOrder; BAND_COUNT],
    /// Unit vector, the pattern's axis (theta = 0): a balloon's front (its +x).
    pub axis: [f32; 3],
    /// Unit vector normal to `axis`: a balloon's top (its +z); +z, or +x when the axis is
    /// vertical, unless given.
    pub up: [f32; 3],
    /// A measured balloon, in place of the bands' patterns; reports show its file.
    #[serde(serialize_with = "serialize_balloon")]
    pub balloon: Option<Arc<Balloon>>,
}

fn serialize_balloon<S: serde::Serializer>(b: &Option<Arc<Balloon>>, s: S) -> Result<S::Ok, S::Error> {
    match b {
        Some(b) => s.serialize_some(&b.file),
        None => s.serialize_none(),
    }
}

/// A unit vector normal to the unit `axis`, as near `up` as can be (`up` projected off the
/// axis); +z or, for a vertical axis, +x when `up` is absent or along the axis.
fn normal_up(axis: Vec3, up: Option<Vec3>) -> Vec3 {
    let project = |u: Vec3| (u - u.dot(axis) * axis).try_normalize();
    up.and_then(project).or_else(|| project(Vec3::Z)).or_else(|| project(Vec3::X)).unwrap_or(Vec3::Y)
}

impl Default for Directivity {
    fn default() -> Self {
        Self::OMNI
    }
}

impl Directivity {
    /// The omnidirectional source: weight 1 everywhere.
    pub const OMNI: Self = Self {
        bands: [FirstOrder::OMNI; BAND_COUNT],
        axis: [1.0, 0.0, 0.0],
        up: [0.0, 0.0, 1.0],
        balloon: None,
    };

    /// One pattern in every band about `axis` (normalised here; a zero or non-finite axis is
    /// an error).
    pub fn uniform(pattern: FirstOrder, axis: Vec3) -> Result<Self, String> {
        Self::per_band([pattern; BAND_COUNT], axis)
    }

    /// A pattern per band about `axis`. Errors: an `a` outside [0, 1], or an axis that is
    /// zero or not finite.
    pub fn per_band(bands: [FirstOrder; BAND_COUNT], axis: Vec3) -> Result<Self, String> {
        if let Some(p) = bands.iter().find(|p| !(0.0..=1.0).contains(&p.a)) {
            return Err(format!("directivity_alpha {}: must be in [0, 1] (1 omni, 0 figure-of-eight)", p.a));
        }
        let len = axis.length();
        if !(len.is_finite() && len > 0.0) {
            return Err(format!(
                "orientation [{}, {}, {}]: must be a finite non-zero vector",
                axis.x, axis.y, axis.z
            ));
        }
        let axis = axis / len;
        Ok(Self { bands, axis: axis.to_array(), up: normal_up(axis, None).to_array(), balloon: None })
    }

    /// A measured balloon facing `axis` with its top towards `up` (projected normal to the
    /// axis; +z when absent). Errors: an axis that is zero or not finite.
    pub fn measured(balloon: Arc<Balloon>, axis: Vec3, up: Option<Vec3>) -> Result<Self, String> {
        let d = Self::uniform(FirstOrder::OMNI, axis)?;
        let axis = Vec3::from(d.axis);
        Ok(Self { up: normal_up(axis, up.filter(|u| u.is_finite())).to_array(), balloon: Some(balloon), ..d })
    }

    /// The same directivity facing `axis` (its top kept as near as can be). Errors: an axis
    /// that is zero or not finite.
    pub fn turned(&self, axis: Vec3) -> Result<Self, String> {
        let d = Self::per_band(self.bands, axis)?;
        let axis = Vec3::from(d.axis);
        Ok(Self {
            up: normal_up(axis, Some(Vec3::from(self.up))).to_array(),
            balloon: self.balloon.clone(),
            ..d
        })
    }

    /// `dir` in the balloon's frame: (front, left, top) components.
    #[inline]
    fn local(&self, dir: Vec3) -> Vec3 {
        let (x, z) = (Vec3::from(self.axis), Vec3::from(self.up));
        Vec3::new(dir.dot(x), dir.dot(z.cross(x)), dir.dot(z))
    }

    /// Checks a directivity built field by field: every `a` in [0, 1] and a finite unit axis.
    pub fn validate(&self) -> Result<(), String> {
        let axis = Vec3::from(self.axis);
        if !(axis.is_finite() && (axis.length() - 1.0).abs() < 1e-3) {
            return Err(format!(
                "directivity axis [{}, {}, {}]: must be a unit vector",
                axis.x, axis.y, axis.z
            ));
        }
        if self.balloon.is_some() {
            let up = Vec3::from(self.up);
            if !(up.is_finite() && (up.length() - 1.0).abs() < 1e-3 && up.dot(axis).abs() < 1e-3) {
                return Err(format!(
                    "directivity up [{}, {}, {}]: must be a unit vector normal to the axis",
                    up.x, up.y, up.z
                ));
            }
        }
        Self::per_band(self.bands, axis).map(|_| ())
    }

    /// Whether every band is omnidirectional (then rays and image sources skip the weights).
    pub fn is_omni(&self) -> bool {
        self.balloon.is_none() && self.bands.iter().all(|p| p.a == 1.0)
    }

    /// The energy weight of each band towards the unit direction `dir` (mean 1 over the
    /// sphere in every band).
    #[inline]
    pub fn energy_weights(&self, dir: Vec3) -> BandValues {
        if let Some(b) = &self.balloon {
            return b.energy_weights(self.local(dir));
        }
        let c = dir.dot(Vec3::from(self.axis)).clamp(-1.0, 1.0);
        self.bands.map(|p| p.energy_weight(c))
    }

    /// A receiver's energy sensitivity per band to sound arriving from the unit direction
    /// `dir` (pointing from the receiver towards where the sound comes from): the pattern's
    /// squared pressure gain, 1 on its axis, as a microphone's free-field response is
    /// normalised. Its mean over the sphere (the diffuse-field sensitivity) is
    /// `a^2 + (1 - a)^2 / 3`: 1/3 for the cardioid.
    #[inline]
    pub fn sensitivity(&self, dir: Vec3) -> BandValues {
        if let Some(b) = &self.balloon {
            return b.sensitivity(self.local(dir));
        }
        let c = dir.dot(Vec3::from(self.axis)).clamp(-1.0, 1.0);
        self.bands.map(|p| {
            let g = p.gain(c);
            g * g
        })
    }

    /// The scene file's description of one source: `directivity` (a name of
    /// [`PATTERN_NAMES`]; omni when absent), `directivity_alpha` (the `a` of "mix", one value
    /// or one per band; an error with any other pattern) and `orientation` (the axis; +x when
    /// absent). Errors are one line without the file name (the caller adds it).
    pub fn from_desc(
        name: Option<PatternName>,
        alpha: Option<&AlphaDesc>,
        orientation: Option<[f32; 3]>,
    ) -> Result<Self, String> {
        let axis = Vec3::from(orientation.unwrap_or([1.0, 0.0, 0.0]));
        let fixed = |p: FirstOrder| -> Result<Self, String> {
            if alpha.is_some() {
                return Err("directivity_alpha applies only to directivity = \"mix\"".into());
            }
            Self::uniform(p, axis)
        };
        match name.unwrap_or(PatternName::Omni) {
            PatternName::Omni => fixed(FirstOrder::OMNI),
            PatternName::Cardioid => fixed(FirstOrder::CARDIOID),
            PatternName::Supercardioid => fixed(FirstOrder::SUPERCARDIOID),
            PatternName::Hypercardioid => fixed(FirstOrder::HYPERCARDIOID),
            PatternName::FigureOfEight => fixed(FirstOrder::FIGURE_OF_EIGHT),
            PatternName::Mix => match alpha {
                None => Err("directivity = \"mix\" needs directivity_alpha (one value or eight, one per octave band, each in [0, 1])".into()),
                Some(AlphaDesc::One(a)) => Self::uniform(FirstOrder { a: *a }, axis),
                Some(AlphaDesc::Bands(a)) => Self::per_band(a.map(|a| FirstOrder { a }), axis),
            },
        }
    }

    /// The pattern named `name` (one of [`PATTERN_NAMES`], "mix" with `alpha`) about `axis`,
    /// or a measured balloon when `name` is a file ending in `.sofa`, as the command line
    /// gives it; the error lists the valid names.
    pub fn parse(name: &str, alpha: Option<f32>, axis: Option<[f32; 3]>) -> Result<Self, String> {
        if name.to_ascii_lowercase().ends_with(".sofa") {
            if alpha.is_some() {
                return Err("a directivity alpha applies only to the pattern \"mix\"".into());
            }
            let balloon = super::balloon::load_sofa_cached(std::path::Path::new(name))?;
            return Self::measured(balloon, Vec3::from(axis.unwrap_or([1.0, 0.0, 0.0])), None);
        }
        let pattern = match name {
            "omni" => PatternName::Omni,
            "cardioid" => PatternName::Cardioid,
            "supercardioid" => PatternName::Supercardioid,
            "hypercardioid" => PatternName::Hypercardioid,
            "figure-of-eight" => PatternName::FigureOfEight,
            "mix" => PatternName::Mix,
            _ => {
                return Err(format!(
                    "unknown directivity \"{name}\": expected one of {}",
                    PATTERN_NAMES.join(", ")
                ));
            }
        };
        Self::from_desc(Some(pattern), alpha.map(AlphaDesc::One).as_ref(), axis)
    }
}

/// The directivity a scene file gives one point: a measured balloon (`directivity_sofa`,
/// relative to `base_dir`, the scene file's folder) or a pattern ([`Directivity::from_desc`]).
/// Errors are one line without the scene file's name (the caller adds it).
pub fn from_point(
    p: &crate::scene::desc::PointDesc,
    base_dir: &std::path::Path,
) -> Result<Directivity, String> {
    let Some(file) = &p.directivity_sofa else {
        return Directivity::from_desc(p.directivity, p.directivity_alpha.as_ref(), p.orientation);
    };
    if p.directivity.is_some() || p.directivity_alpha.is_some() {
        return Err("give either directivity or directivity_sofa, not both".into());
    }
    let balloon = super::balloon::load_sofa_cached(&base_dir.join(file))?;
    Directivity::measured(balloon, Vec3::from(p.orientation.unwrap_or([1.0, 0.0, 0.0])), p.up.map(Vec3::from))
}

/// The directivity of every acoustic source, then every receiver, of `world`'s scene file, in
/// their order; an error names the point (the caller adds the file name).
pub fn scene_directivities(world: &crate::scene::World) -> Result<Vec<Directivity>, String> {
    let Some(desc) = &world.scene.desc.acoustic else { return Ok(Vec::new()) };
    let base_dir = world.scene.path.parent().unwrap_or(std::path::Path::new("."));
    let sources = desc.sources.iter().map(|p| ("source", p));
    sources
        .chain(desc.receivers.iter().map(|p| ("receiver", p)))
        .map(|(kind, p)| from_point(p, base_dir).map_err(|e| format!("{kind} \"{}\": {e}", p.name)))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    const ALL: [FirstOrder; 5] = [
        FirstOrder::OMNI,
        FirstOrder::CARDIOID,
        FirstOrder::SUPERCARDIOID,
        FirstOrder::HYPERCARDIOID,
        FirstOrder::FIGURE_OF_EIGHT,
    ];

    #[test]
    fn every_pattern_integrates_to_four_pi() {
        // Midpoint rule in cos(theta) (the weight depends on theta alone, dOmega = 2 pi dcos):
        // a quadratic in cos(theta), integrated exactly up to rounding.
        for p in ALL.into_iter().chain((0..=10).map(|i| FirstOrder { a: i as f32 / 10.0 })) {
            let n = 20_000;
            let integral: f64 = (0..n)
                .map(|i| {
                    let c = -1.0 + (i as f64 + 0.5) * 2.0 / n as f64;
                    2.0 * std::f64::consts::PI * f64::from(p.energy_weight(c as f32)) * 2.0 / n as f64
                })
                .sum();
            assert!((integral / (4.0 * std::f64::consts::PI) - 1.0).abs() < 1e-4, "a = {}: {integral}", p.a);
        }
    }

    #[test]
    fn directivity_factors_and_nulls_match_the_closed_forms() {
        // Q = 1 / (a^2 + (1 - a)^2 / 3): omni 1, cardioid 3, hypercardioid 4, figure-of-eight 3,
        // supercardioid 1 / (a^2 + (1 - a)^2 / 3) with a = (sqrt 3 - 1) / 2: 3.732 (2 + sqrt 3).
        let q = |p: FirstOrder| p.directivity_factor();
        assert!((q(FirstOrder::OMNI) - 1.0).abs() < 1e-6);
        assert!((q(FirstOrder::CARDIOID) - 3.0).abs() < 1e-5);
        assert!((q(FirstOrder::HYPERCARDIOID) - 4.0).abs() < 1e-5);
        assert!((q(FirstOrder::FIGURE_OF_EIGHT) - 3.0).abs() < 1e-5);
        assert!((q(FirstOrder::SUPERCARDIOID) - (2.0 + 3f32.sqrt())).abs() < 1e-4);
        assert_eq!(FirstOrder::CARDIOID.energy_weight(-1.0), 0.0);
        assert_eq!(FirstOrder::FIGURE_OF_EIGHT.energy_weight(0.0), 0.0);
        // The hypercardioid's null at cos theta = -a / (1 - a) = -1/3.
        assert!(FirstOrder::HYPERCARDIOID.energy_weight(-1.0 / 3.0) < 1e-12);
    }

    #[test]
    fn the_supercardioid_maximises_the_front_to_back_ratio() {
        // Front-to-back energy ratio of the first-order patterns: the supercardioid's a is
        // where it peaks (a grid of a in 0.001 steps).
        let ratio = |a: f32| {
            let (b, c) = (1.0 - a, 1.0 / 3.0);
            // Front hemisphere: integral_0^1 (a + b x)^2 dx; back: integral_-1^0.
            let front = a * a + a * b + b * b * c;
            let back = a * a - a * b + b * b * c;
            front / back
        };
        let best =
            (1..1000).map(|i| i as f32 / 1000.0).max_by(|x, y| ratio(*x).total_cmp(&ratio(*y))).unwrap();
        assert!((best - SUPERCARDIOID_A).abs() < 2e-3, "{best}");
    }

    #[test]
    fn weights_follow_the_axis_and_names_parse() {
        let d = Directivity::parse("cardioid", None, Some([0.0, 0.0, 2.0])).unwrap();
        let front = d.energy_weights(Vec3::Z);
        let back = d.energy_weights(-Vec3::Z);
        let side = d.energy_weights(Vec3::X);
        for b in 0..BAND_COUNT {
            assert!((front[b] - 3.0).abs() < 1e-5);
            assert_eq!(back[b], 0.0);
            assert!((side[b] - 0.75).abs() < 1e-5);
        }
        let e = Directivity::parse("shotgun", None, None).unwrap_err();
        assert!(!e.contains('\n') && PATTERN_NAMES.iter().all(|n| e.contains(n)), "{e}");
        assert!(Directivity::parse("mix", Some(1.5), None).is_err());
        assert!(Directivity::parse("mix", None, None).is_err());
        assert!(Directivity::parse("cardioid", None, Some([0.0, 0.0, 0.0])).is_err());
        assert!(Directivity::parse("cardioid", None, Some([f32::NAN, 0.0, 1.0])).is_err());
        assert!(Directivity::parse("cardioid", Some(0.5), None).is_err());
        let mix = Directivity::parse("mix", Some(0.5), None).unwrap();
        assert_eq!(mix.bands, [FirstOrder::CARDIOID; BAND_COUNT]);
    }
}
