//! Named materials: acoustic (octave-band absorption and scattering), radio (ITU-R P.2040 or
//! explicit permittivity) and optical properties, from files or the built-in library.

use std::collections::BTreeMap;
use std::path::Path;

use glam::Vec3;
use serde::Deserialize;

use super::dispersion::Dispersion;
use super::error::SceneError;
use super::itu;

/// Octave-band centre frequencies of every acoustic quantity in propsim, Hz (IEC 61260).
pub const OCTAVE_BANDS_HZ: [f32; 8] = [63.0, 125.0, 250.0, 500.0, 1000.0, 2000.0, 4000.0, 8000.0];
/// Number of octave bands.
pub const BAND_COUNT: usize = OCTAVE_BANDS_HZ.len();
/// Scattering coefficient assumed when a material gives absorption but no scattering
/// (a flat, smooth surface; cf. ISO 17497-1 and Vorlaender, Auralization, sec. 11.5).
pub const DEFAULT_SCATTERING: f32 = 0.1;

/// Largest `alpha_r` of a directive scattering pattern (a lobe about 10 degrees wide at 1000).
pub const MAX_ALPHA_R: u32 = 1000;

/// A value per octave band, 63 Hz to 8 kHz.
pub type BandValues = [f32; BAND_COUNT];

/// Acoustic surface data on the full 63 Hz - 8 kHz octave grid.
#[derive(Clone, Debug, PartialEq)]
pub struct AcousticProps {
    /// Random-incidence absorption coefficient per band, in [0, 1].
    pub absorption: BandValues,
    /// Random-incidence scattering coefficient per band (ISO 17497-1), in [0, 1].
    pub scattering: BandValues,
    /// Bands the source gave; others were filled by the nearest-band rule.
    pub bands_given: std::ops::Range<usize>,
}

/// The lobe of a radio material's diffusely scattered power (Degli-Esposti et al. 2007, as in
/// Sionna RT; docs/radio.md, sec. 4).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
#[serde(tag = "pattern", rename_all = "snake_case")]
pub enum ScatteringPattern {
    /// `f_s = cos(theta_s) / pi`, the most diffuse surface.
    #[default]
    Lambertian,
    /// `f_s ~ ((1 + cos psi_R) / 2)^alpha_r` around the specular direction, `alpha_r >= 1`.
    Directive {
        /// Width parameter of the lobe, `>= 1`.
        alpha_r: u32,
    },
}

/// Radio diffuse reflection of a material (Sionna RT's `RadioMaterial` parameters): the
/// scattering coefficient `S` (a fraction `S^2` of the reflected power is scattered), the
/// cross-polarisation coefficient `K_x` and the pattern (docs/radio.md, sec. 4).
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct RadioScattering {
    /// `S` in [0, 1]; 0 (the default) is a purely specular surface.
    pub scattering_coefficient: f64,
    /// `K_x` in [0, 1]: the fraction of the scattered power moved to the other polarisation.
    pub xpd_coefficient: f64,
    /// Written as `"pattern": "lambertian"` or `"pattern": "directive", "alpha_r": N`.
    #[serde(flatten)]
    pub pattern: ScatteringPattern,
}

/// Radio data: an ITU-R P.2040-3 Table 3 material, or explicit constants.
#[derive(Clone, Debug, PartialEq)]
pub enum RadioProps {
    /// An ITU-R P.2040-3 Table 3 material, by name.
    Itu(String),
    /// Explicit constants.
    Explicit {
        /// Real relative permittivity.
        relative_permittivity: f64,
        /// Conductivity, S/m.
        conductivity_s_per_m: f64,
    },
}

impl std::fmt::Display for RadioProps {
    /// `ITU concrete`, or `eps_r 5.24, sigma 0.123 S/m`: how `propsim info` shows it.
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Itu(name) => write!(f, "ITU {name}"),
            Self::Explicit { relative_permittivity, conductivity_s_per_m } => write!(
                f,
                "eps_r {}, sigma {} S/m",
                crate::io::tidy(*relative_permittivity, 4),
                crate::io::tidy(*conductivity_s_per_m, 4)
            ),
        }
    }
}

/// How light interacts with a surface.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum OpticalKind {
    /// Lambertian diffuse.
    #[default]
    Diffuse,
    /// Metal (conductor) reflection.
    Metal,
    /// Dielectric (glass-like) reflection and refraction.
    Dielectric,
}

/// Optical data (linear RGB).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OpticalProps {
    /// Kind of surface.
    pub kind: OpticalKind,
    /// Diffuse albedo, or metal reflectance at normal incidence.
    pub color: Vec3,
    /// Microfacet roughness in [0, 1] (metal, glossy).
    pub roughness: f32,
    /// Index of refraction (dielectric).
    pub ior: f32,
    /// Emitted radiance, W / (m^2 sr) per channel.
    pub emission: Vec3,
    /// How the index varies with wavelength (dielectrics only; `ior` is then `n_d`), seen by
    /// the spectral integrator; `None`: the same index at every wavelength.
    pub dispersion: Option<Dispersion>,
}

impl Default for OpticalProps {
    fn default() -> Self {
        Self {
            kind: OpticalKind::Diffuse,
            color: Vec3::splat(0.7),
            roughness: 0.0,
            ior: 1.5,
            emission: Vec3::ZERO,
            dispersion: None,
        }
    }
}

/// A resolved material.
#[derive(Clone, Debug, PartialEq)]
pub struct Material {
    /// Name.
    pub name: String,
    /// Description in words.
    pub description: String,
    /// Provenance of the data.
    pub source: String,
    /// Acoustic data, if any.
    pub acoustic: Option<AcousticProps>,
    /// Radio data, if any.
    pub radio: Option<RadioProps>,
    /// Thickness of a wall of this material, metres, for radio transmission through thin
    /// slabs (ITU-R P.2040-3 sec. 2.2.2.2); `None`: the simulator's default.
    pub thickness_m: Option<f64>,
    /// Radio diffuse reflection (`scattering_coefficient` and friends); `None`: not given
    /// (a specular surface, `S = 0`).
    pub radio_scattering: Option<RadioScattering>,
    /// `None` when the material says nothing about light (the OBJ's MTL then decides).
    pub optical: Option<OpticalProps>,
}

/// A single number or one value per band.
#[derive(Clone, Debug, Deserialize)]
#[serde(untagged)]
pub enum ScalarOrBands {
    /// One value for every band.
    Scalar(f32),
    /// One value per band.
    Bands(Vec<f32>),
}

/// One `[materials.NAME]` entry as written in a file.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialSpec {
    /// Description in words.
    pub description: Option<String>,
    /// Provenance of the data.
    pub source: Option<String>,
    /// Absorption per octave band: 6 values (125 Hz - 4 kHz), 8 values (63 Hz - 8 kHz), or as
    /// many as `bands_hz` lists.
    pub absorption: Option<ScalarOrBands>,
    /// Scattering coefficient: one value or one per band, as `absorption`.
    pub scattering: Option<ScalarOrBands>,
    /// Octave centres (Hz) the arrays refer to, when not the 6- or 8-band default.
    pub bands_hz: Option<Vec<f32>>,
    /// ITU-R P.2040-3 Table 3 material name.
    pub itu: Option<String>,
    /// Why the radio data were chosen (appended to `source`).
    pub radio_source: Option<String>,
    /// Real relative permittivity.
    pub relative_permittivity: Option<f64>,
    /// Conductivity, S/m.
    pub conductivity_s_per_m: Option<f64>,
    /// Wall thickness for radio transmission through thin slabs, metres (positive).
    pub thickness_m: Option<f64>,
    /// Radio scattering coefficient `S` in [0, 1] (not the acoustic `scattering`).
    pub scattering_coefficient: Option<f64>,
    /// Radio cross-polarisation coefficient `K_x` in [0, 1].
    pub xpd_coefficient: Option<f64>,
    /// `"lambertian"` (default) or `"directive"` (with `alpha_r`).
    pub scattering_pattern: Option<String>,
    /// Width parameter of the directive pattern, an integer >= 1.
    pub alpha_r: Option<i64>,
    /// Colour (linear RGB).
    pub color: Option<[f32; 3]>,
    /// Optical kind.
    pub kind: Option<OpticalKind>,
    /// Roughness.
    pub roughness: Option<f32>,
    /// Index of refraction.
    pub ior: Option<f32>,
    /// Emitted radiance (linear RGB).
    pub emission: Option<[f32; 3]>,
    /// Sellmeier coefficients `B_1..B_3` of a dispersive dielectric (with `sellmeier_c`).
    pub sellmeier_b: Option<[f64; 3]>,
    /// Sellmeier coefficients `C_1..C_3`, um^2 (with `sellmeier_b`).
    pub sellmeier_c: Option<[f64; 3]>,
    /// Abbe number `V_d` of a dispersive dielectric whose `ior` is `n_d` (Cauchy's law).
    pub abbe_number: Option<f64>,
}

impl MaterialSpec {
    /// This entry with the keys `later` gives replaced, field by field. Keys that only make
    /// sense together go together: a later `absorption` or `bands_hz` brings its own
    /// `bands_hz` (or none), a later `itu` drops the earlier permittivity and conductivity, and
    /// a later permittivity or conductivity drops the earlier `itu`.
    pub fn merged_with(&self, later: &MaterialSpec) -> MaterialSpec {
        let mut m = self.clone();
        macro_rules! take {
            ($($field:ident),*) => { $(if later.$field.is_some() { m.$field = later.$field.clone(); })* };
        }
        if later.absorption.is_some() || later.bands_hz.is_some() {
            m.bands_hz = later.bands_hz.clone();
        }
        if later.itu.is_some() {
            (m.relative_permittivity, m.conductivity_s_per_m) = (None, None);
        }
        if later.relative_permittivity.is_some() || later.conductivity_s_per_m.is_some() {
            m.itu = None;
        }
        // A later dispersion law replaces the earlier one (and a Sellmeier law the `ior`).
        if later.sellmeier_b.is_some() || later.sellmeier_c.is_some() {
            (m.abbe_number, m.ior) = (None, None);
        }
        if later.abbe_number.is_some() {
            (m.sellmeier_b, m.sellmeier_c) = (None, None);
        }
        if later.itu.is_some()
            || later.relative_permittivity.is_some()
            || later.conductivity_s_per_m.is_some()
        {
            m.radio_source = None;
        }
        take!(
            description,
            source,
            absorption,
            scattering,
            itu,
            radio_source,
            relative_permittivity,
            conductivity_s_per_m,
            thickness_m,
            scattering_coefficient,
            xpd_coefficient,
            scattering_pattern,
            alpha_r,
            color,
            kind,
            roughness,
            ior,
            emission,
            sellmeier_b,
            sellmeier_c,
            abbe_number
        );
        m
    }
}

/// A materials file: `[materials.NAME]` tables.
#[derive(Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MaterialsFile {
    /// The entries, by name.
    #[serde(default)]
    pub materials: BTreeMap<String, MaterialSpec>,
}

/// Index range in [`OCTAVE_BANDS_HZ`] that `n` values (or explicit centres) refer to.
fn band_range(n: usize, bands_hz: Option<&[f32]>) -> Result<std::ops::Range<usize>, String> {
    if let Some(centres) = bands_hz {
        if centres.len() != n {
            return Err(format!("bands_hz has {} entries but the values have {n}", centres.len()));
        }
        let first = centres.first().ok_or("bands_hz is empty")?;
        let start = OCTAVE_BANDS_HZ
            .iter()
            .position(|&f| (f - first).abs() < 1.0)
            .ok_or_else(|| format!("{first} Hz is not an octave centre ({} Hz)", octave_list()))?;
        for (k, &f) in centres.iter().enumerate() {
            if OCTAVE_BANDS_HZ.get(start + k).is_none_or(|&c| (c - f).abs() >= 1.0) {
                return Err(format!("bands_hz must be consecutive octave centres from {} Hz", octave_list()));
            }
        }
        return Ok(start..start + n);
    }
    match n {
        6 => Ok(1..7),
        8 => Ok(0..8),
        _ => Err(format!(
            "expected 6 octave-band values (125 Hz - 4 kHz) or 8 (63 Hz - 8 kHz), got {n}; give bands_hz for other sets"
        )),
    }
}

/// Spreads values given on `range` over all bands: bands below the lowest given take its value,
/// bands above the highest take that one (the documented nearest-band rule).
fn fill_bands(values: &[f32], range: &std::ops::Range<usize>) -> BandValues {
    let mut out = [0.0; BAND_COUNT];
    for (i, o) in out.iter_mut().enumerate() {
        let k = i.clamp(range.start, range.end - 1) - range.start;
        *o = values[k];
    }
    out
}

fn coefficient_bands(
    what: &str,
    v: &ScalarOrBands,
    range: Option<&std::ops::Range<usize>>,
    bands_hz: Option<&[f32]>,
) -> Result<(BandValues, std::ops::Range<usize>), String> {
    let (values, range) = match v {
        ScalarOrBands::Scalar(x) => (vec![*x], 0..1),
        ScalarOrBands::Bands(vs) => {
            let r = match range {
                Some(r) if r.len() == vs.len() => r.clone(),
                _ => band_range(vs.len(), bands_hz).map_err(|e| format!("{what}: {e}"))?,
            };
            (vs.clone(), r)
        }
    };
    if let Some(bad) = values.iter().find(|x| !(0.0..=1.0).contains(*x)) {
        return Err(format!("{what} value {bad} is outside [0, 1]"));
    }
    if let ScalarOrBands::Scalar(x) = v {
        return Ok(([*x; BAND_COUNT], 0..BAND_COUNT));
    }
    Ok((fill_bands(&values, &range), range))
}

impl MaterialSpec {
    /// The radio diffuse-reflection keys, checked: `None` when none is given.
    fn radio_scattering(&self) -> Result<Option<RadioScattering>, String> {
        if self.scattering_coefficient.is_none()
            && self.xpd_coefficient.is_none()
            && self.scattering_pattern.is_none()
            && self.alpha_r.is_none()
        {
            return Ok(None);
        }
        let unit = |v: Option<f64>, key: &str| match v {
            None => Ok(0.0),
            Some(x) if (0.0..=1.0).contains(&x) => Ok(x),
            Some(x) => Err(format!("{key} {x}: must be a number in [0, 1]")),
        };
        let scattering_coefficient = unit(self.scattering_coefficient, "scattering_coefficient")?;
        let xpd_coefficient = unit(self.xpd_coefficient, "xpd_coefficient")?;
        let pattern = match (self.scattering_pattern.as_deref(), self.alpha_r) {
            (None | Some("lambertian"), None) => ScatteringPattern::Lambertian,
            (None | Some("lambertian"), Some(_)) => {
                return Err("alpha_r needs scattering_pattern = \"directive\"".into());
            }
            (Some("directive"), a) => {
                let alpha_r = a.unwrap_or(1);
                if !(1..=i64::from(MAX_ALPHA_R)).contains(&alpha_r) {
                    return Err(format!("alpha_r {alpha_r}: must be an integer from 1 to {MAX_ALPHA_R}"));
                }
                ScatteringPattern::Directive { alpha_r: alpha_r as u32 }
            }
            (Some(other), _) => {
                return Err(format!(
                    "scattering_pattern \"{other}\": expected \"lambertian\" or \"directive\""
                ));
            }
        };
        Ok(Some(RadioScattering { scattering_coefficient, xpd_coefficient, pattern }))
    }

    /// The dispersion keys, checked, and the index at the d line they imply (Sellmeier; `None`
    /// for Cauchy, whose `n_d` is `ior`). Only a dielectric disperses; the Sellmeier law gives
    /// its own `n_d`, so it takes no `ior` and no `abbe_number`.
    fn dispersion(&self, kind: OpticalKind) -> Result<(Option<Dispersion>, Option<f32>), String> {
        let key = match (self.sellmeier_b, self.sellmeier_c, self.abbe_number) {
            (None, None, None) => return Ok((None, None)),
            (Some(_), _, _) => "sellmeier_b",
            (_, Some(_), _) => "sellmeier_c",
            _ => "abbe_number",
        };
        if kind != OpticalKind::Dielectric {
            return Err(format!("{key} needs kind = \"dielectric\" (only glass disperses)"));
        }
        match (self.sellmeier_b, self.sellmeier_c, self.abbe_number) {
            (Some(b), Some(c), None) => {
                if self.ior.is_some() {
                    return Err(
                        "give either ior or sellmeier_b/sellmeier_c (the Sellmeier law sets n_d)".into()
                    );
                }
                let law = Dispersion::sellmeier(b, c)?;
                Ok((Some(law), Some(law.index_at(super::dispersion::D_LINE_NM) as f32)))
            }
            (None, None, Some(v)) => {
                let n_d = f64::from(self.ior.unwrap_or(OpticalProps::default().ior));
                Ok((Some(Dispersion::from_abbe(n_d, v)?), None))
            }
            (Some(_), None, None) => Err("sellmeier_b needs sellmeier_c".into()),
            (None, Some(_), None) => Err("sellmeier_c needs sellmeier_b".into()),
            _ => Err("give either sellmeier_b/sellmeier_c or abbe_number, not both".into()),
        }
    }

    /// Checks and resolves the entry called `name`.
    pub fn resolve(&self, name: &str) -> Result<Material, String> {
        let bands_hz = self.bands_hz.as_deref();
        let acoustic = match (&self.absorption, &self.scattering) {
            (None, None) => None,
            (None, Some(_)) => return Err("scattering is given without absorption".into()),
            (Some(a), s) => {
                let (absorption, range) = coefficient_bands("absorption", a, None, bands_hz)?;
                let scattering = match s {
                    Some(s) => coefficient_bands("scattering", s, Some(&range), bands_hz)?.0,
                    None => [DEFAULT_SCATTERING; BAND_COUNT],
                };
                Some(AcousticProps { absorption, scattering, bands_given: range })
            }
        };
        let radio = match (&self.itu, self.relative_permittivity, self.conductivity_s_per_m) {
            (Some(_), Some(_), _) | (Some(_), _, Some(_)) => {
                return Err("give either itu or relative_permittivity/conductivity_s_per_m, not both".into());
            }
            (Some(n), None, None) => {
                let names = itu::itu_names();
                if !names.contains(&n.as_str()) {
                    return Err(format!(
                        "unknown ITU-R P.2040 material \"{n}\" (known: {})",
                        names.join(", ")
                    ));
                }
                Some(RadioProps::Itu(n.clone()))
            }
            (None, Some(eps), sigma) => {
                let sigma = sigma.unwrap_or(0.0);
                if !(eps.is_finite() && eps >= 1.0 && sigma.is_finite() && sigma >= 0.0) {
                    return Err("relative_permittivity must be >= 1 and conductivity_s_per_m >= 0".into());
                }
                Some(RadioProps::Explicit { relative_permittivity: eps, conductivity_s_per_m: sigma })
            }
            (None, None, Some(_)) => {
                return Err("conductivity_s_per_m needs relative_permittivity".into());
            }
            (None, None, None) => None,
        };
        if let Some(t) = self.thickness_m
            && !(t.is_finite() && t > 0.0)
        {
            return Err(format!("thickness_m {t}: must be a positive number of metres"));
        }
        let radio_scattering = self.radio_scattering()?;
        let optical_given = self.color.is_some()
            || self.kind.is_some()
            || self.emission.is_some()
            || self.ior.is_some()
            || self.roughness.is_some()
            || self.sellmeier_b.is_some()
            || self.sellmeier_c.is_some()
            || self.abbe_number.is_some();
        let optical = if optical_given {
            let d = OpticalProps::default();
            let color = self.color.map_or(d.color, Vec3::from);
            let emission = self.emission.map_or(Vec3::ZERO, Vec3::from);
            let roughness = self.roughness.unwrap_or(d.roughness);
            let kind = self.kind.unwrap_or_default();
            let (dispersion, ior) = self.dispersion(kind)?;
            let ior = ior.unwrap_or(self.ior.unwrap_or(d.ior));
            if !color.is_finite() || color.min_element() < 0.0 || color.max_element() > 1.0 {
                return Err("color components must be in [0, 1]".into());
            }
            if !emission.is_finite() || emission.min_element() < 0.0 {
                return Err("emission must be finite and non-negative".into());
            }
            if !(0.0..=1.0).contains(&roughness) {
                return Err("roughness must be in [0, 1]".into());
            }
            if !(ior.is_finite() && ior >= 1.0) {
                return Err("ior must be >= 1".into());
            }
            Some(OpticalProps { kind, color, roughness, ior, emission, dispersion })
        } else {
            None
        };
        Ok(Material {
            name: name.to_string(),
            description: self.description.clone().unwrap_or_default(),
            source: match (&self.source, &self.radio_source) {
                (Some(s), Some(r)) => format!("{s}; radio: {r}"),
                (s, r) => s.clone().or_else(|| r.clone()).unwrap_or_default(),
            },
            acoustic,
            radio,
            thickness_m: self.thickness_m,
            radio_scattering,
            optical,
        })
    }
}

/// Materials by name. A later entry of a name already present overrides only the keys it
/// gives ([`MaterialSpec::merged_with`]).
#[derive(Clone, Debug, Default)]
pub struct MaterialLibrary {
    /// The resolved materials, by name.
    pub materials: BTreeMap<String, Material>,
    /// Each material as written, merged entry by entry: what a later entry is merged into.
    specs: BTreeMap<String, MaterialSpec>,
}

/// The built-in library's source text (provenance noted per entry).
pub const BUILTIN_LIBRARY_TOML: &str = include_str!("library.toml");

impl MaterialLibrary {
    /// The built-in library.
    pub fn builtin() -> Self {
        let mut lib = Self::default();
        lib.add_toml(Path::new("<built-in library>"), BUILTIN_LIBRARY_TOML)
            .expect("the built-in material library is valid (tested)");
        lib
    }

    /// Adds every entry of a materials TOML text; `path` is used in error messages.
    pub fn add_toml(&mut self, path: &Path, text: &str) -> Result<(), SceneError> {
        let file: MaterialsFile = toml::from_str(text).map_err(|e| SceneError::toml(path, text, &e))?;
        self.add_specs(path, &file.materials)
    }

    /// Adds resolved entries; errors name the file and the material.
    pub fn add_specs(
        &mut self,
        path: &Path,
        specs: &BTreeMap<String, MaterialSpec>,
    ) -> Result<(), SceneError> {
        for (name, spec) in specs {
            let merged = match self.specs.get(name) {
                Some(earlier) => earlier.merged_with(spec),
                None => spec.clone(),
            };
            let m = merged
                .resolve(name)
                .map_err(|e| SceneError::invalid(path, format!("material \"{name}\": {e}")))?;
            self.materials.insert(name.clone(), m);
            self.specs.insert(name.clone(), merged);
        }
        Ok(())
    }

    /// Reads and adds a materials file.
    pub fn add_file(&mut self, path: &Path) -> Result<(), SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError::io(path, &e))?;
        self.add_toml(path, &text)
    }

    /// The material named `name`, if any.
    pub fn get(&self, name: &str) -> Option<&Material> {
        self.materials.get(name)
    }

    /// Up to `k` known names closest to `name` (case-insensitive Jaro-Winkler).
    pub fn nearest_names(&self, name: &str, k: usize) -> Vec<String> {
        let lower = name.to_lowercase();
        let mut scored: Vec<(f64, &String)> =
            self.materials.keys().map(|n| (strsim::jaro_winkler(&lower, &n.to_lowercase()), n)).collect();
        scored.sort_by(|a, b| b.0.total_cmp(&a.0).then_with(|| a.1.cmp(b.1)));
        scored.into_iter().take(k).map(|(_, n)| n.clone()).collect()
    }
}

/// The octave centres for people to read: `63, 125, ..., 8000`.
fn octave_list() -> String {
    crate::io::number_list(&OCTAVE_BANDS_HZ.map(f64::from))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(text: &str) -> Result<Material, String> {
        let file: MaterialsFile = toml::from_str(text).map_err(|e| e.to_string())?;
        let (name, s) = file.materials.iter().next().unwrap();
        s.resolve(name)
    }

    #[test]
    fn six_bands_map_to_125_through_4k_and_fill_the_edges() {
        let m = spec(
            "[materials.concrete]\nabsorption = [0.02, 0.03, 0.03, 0.03, 0.04, 0.07]\n\
             scattering = [0.1, 0.1, 0.1, 0.1, 0.1, 0.1]\nitu = \"concrete\"\n",
        )
        .unwrap();
        let a = m.acoustic.unwrap();
        assert_eq!(a.absorption, [0.02, 0.02, 0.03, 0.03, 0.03, 0.04, 0.07, 0.07]);
        assert_eq!(a.bands_given, 1..7);
        assert_eq!(m.radio, Some(RadioProps::Itu("concrete".into())));
        assert_eq!(m.optical, None);
    }

    #[test]
    fn a_later_entry_overrides_only_the_keys_it_gives() {
        let mut lib = MaterialLibrary::builtin();
        let before = lib.materials["concrete_rough"].clone();
        let path = Path::new("mine.toml");
        // Radio only: the acoustic and optical data stay.
        lib.add_toml(path, "[materials.concrete_rough]\nitu = \"glass\"\n").unwrap();
        let after = &lib.materials["concrete_rough"];
        assert_eq!(after.acoustic, before.acoustic);
        assert_eq!(after.optical, before.optical);
        assert_ne!(after.radio, before.radio);
        // Explicit permittivity replaces the ITU class; absorption keeps the radio data.
        lib.add_toml(
            path,
            "[materials.concrete_rough]\nrelative_permittivity = 4.0\nconductivity_s_per_m = 0.01\n",
        )
        .unwrap();
        let explicit = lib.materials["concrete_rough"].radio.clone();
        lib.add_toml(path, "[materials.concrete_rough]\nabsorption = 0.5\n").unwrap();
        let last = &lib.materials["concrete_rough"];
        assert_eq!(last.radio, explicit);
        assert_eq!(last.acoustic.as_ref().map(|a| a.absorption), Some([0.5; BAND_COUNT]));
        // The earlier scattering stays with the new absorption.
        assert_eq!(
            last.acoustic.as_ref().map(|a| a.scattering),
            before.acoustic.as_ref().map(|a| a.scattering)
        );
        // A new name is added whole.
        lib.add_toml(path, "[materials.brand_new]\nabsorption = 0.3\n").unwrap();
        assert!(lib.materials["brand_new"].radio.is_none());
    }

    #[test]
    fn explicit_bands_and_scalar_scattering() {
        let m = spec("[materials.x]\nabsorption = [0.5, 0.6]\nbands_hz = [1000, 2000]\nscattering = 0.3\n")
            .unwrap();
        let a = m.acoustic.unwrap();
        assert_eq!(a.absorption, [0.5, 0.5, 0.5, 0.5, 0.5, 0.6, 0.6, 0.6]);
        assert_eq!(a.scattering, [0.3; 8]);
        let m = spec("[materials.x]\nabsorption = 0.2\n").unwrap();
        assert_eq!(m.acoustic.unwrap().scattering, [DEFAULT_SCATTERING; 8]);
    }

    #[test]
    fn rejects_bad_values() {
        assert!(spec("[materials.x]\nabsorption = [0.1, 0.2, 0.3]\n").unwrap_err().contains("expected 6"));
        assert!(spec("[materials.x]\nabsorption = 1.5\n").unwrap_err().contains("outside [0, 1]"));
        assert!(spec("[materials.x]\nitu = \"cheese\"\n").unwrap_err().contains("unknown ITU"));
        assert!(
            spec("[materials.x]\nabsorption = [0.1,0.1,0.1,0.1,0.1,0.1]\nscattering = [0.1, 0.1]\n").is_err()
        );
        assert!(spec("[materials.x]\ncolor = [2, 0, 0]\n").is_err());
        assert!(spec("[materials.x]\nbogus = 1\n").unwrap_err().contains("unknown field"));
        for bad in ["0", "-0.1", "nan", "inf"] {
            let e = spec(&format!("[materials.x]\nitu = \"concrete\"\nthickness_m = {bad}\n")).unwrap_err();
            assert!(e.contains("thickness_m") && e.contains("positive"), "{bad}: {e}");
        }
        let m = spec("[materials.x]\nitu = \"concrete\"\nthickness_m = 0.25\n").unwrap();
        assert_eq!(m.thickness_m, Some(0.25));
    }

    #[test]
    fn radio_scattering_keys_are_checked_and_distinct_from_the_acoustic_ones() {
        let m = spec("[materials.x]\nitu = \"concrete\"\n").unwrap();
        assert_eq!(m.radio_scattering, None);
        let m =
            spec("[materials.x]\nitu = \"concrete\"\nscattering_coefficient = 0.4\nxpd_coefficient = 0.1\n")
                .unwrap();
        let want = RadioScattering {
            scattering_coefficient: 0.4,
            xpd_coefficient: 0.1,
            pattern: ScatteringPattern::Lambertian,
        };
        assert_eq!(m.radio_scattering, Some(want));
        assert_eq!(m.acoustic, None);
        let m = spec(
            "[materials.x]\nscattering_coefficient = 1\nscattering_pattern = \"directive\"\nalpha_r = 4\n",
        )
        .unwrap();
        assert_eq!(m.radio_scattering.unwrap().pattern, ScatteringPattern::Directive { alpha_r: 4 });
        for (bad, key) in [
            ("scattering_coefficient = 1.5", "scattering_coefficient"),
            ("scattering_coefficient = -0.1", "scattering_coefficient"),
            ("scattering_coefficient = nan", "scattering_coefficient"),
            ("xpd_coefficient = 2", "xpd_coefficient"),
            ("scattering_pattern = \"directive\"\nalpha_r = 0", "alpha_r"),
            ("alpha_r = 3", "alpha_r"),
            ("scattering_pattern = \"glossy\"", "scattering_pattern"),
        ] {
            let e = spec(&format!("[materials.x]\nitu = \"concrete\"\n{bad}\n")).unwrap_err();
            assert!(e.contains(key) && !e.contains('\n'), "{bad}: {e}");
        }
    }

    #[test]
    fn dispersion_keys_give_a_law_on_glass_only() {
        let m = spec(
            "[materials.bk7]\nkind = \"dielectric\"\nsellmeier_b = [1.03961212, 0.231792344, 1.01046945]\n\
             sellmeier_c = [0.00600069867, 0.0200179144, 103.560653]\n",
        )
        .unwrap();
        let o = m.optical.unwrap();
        // The Sellmeier law sets n_d (BK7: 1.5168) for the RGB integrators.
        assert!((o.ior - 1.5168).abs() < 1e-4, "{}", o.ior);
        assert!(matches!(o.dispersion, Some(Dispersion::Sellmeier { .. })));
        let m = spec("[materials.crown]\nkind = \"dielectric\"\nior = 1.52\nabbe_number = 58.6\n").unwrap();
        let law = m.optical.unwrap().dispersion.unwrap();
        assert!((law.abbe_number() - 58.6).abs() < 1e-9 && m.optical.unwrap().ior == 1.52);
        for (bad, needle) in [
            ("abbe_number = 40", "dielectric"),
            ("kind = \"metal\"\nabbe_number = 40", "dielectric"),
            (
                "kind = \"dielectric\"\nabbe_number = 40\nsellmeier_b = [1, 0, 0]\nsellmeier_c = [0, 0, 0]",
                "not both",
            ),
            (
                "kind = \"dielectric\"\nior = 1.5\nsellmeier_b = [1, 0, 0]\nsellmeier_c = [0, 0, 0]",
                "either ior",
            ),
            ("kind = \"dielectric\"\nsellmeier_c = [0, 0, 0]", "needs sellmeier_b"),
        ] {
            let e = spec(&format!("[materials.x]\n{bad}\n")).unwrap_err();
            assert!(e.contains(needle) && !e.contains('\n'), "{bad}: {e}");
        }
    }

    #[test]
    fn builtin_library_is_valid_and_large_enough() {
        let lib = MaterialLibrary::builtin();
        let acoustic: Vec<&Material> = lib.materials.values().filter(|m| m.acoustic.is_some()).collect();
        assert!(acoustic.len() >= 30, "only {} acoustic materials", acoustic.len());
        for m in &acoustic {
            assert!(!m.source.trim().is_empty(), "{} has no provenance", m.name);
        }
        for name in itu::itu_names() {
            let m = lib.get(name).unwrap_or_else(|| panic!("built-in library lacks ITU material {name}"));
            assert_eq!(m.radio, Some(RadioProps::Itu(name.to_string())));
        }
        // Every entry serves all three views.
        for m in lib.materials.values() {
            assert!(
                m.acoustic.is_some() && m.radio.is_some() && m.optical.is_some(),
                "{} lacks acoustic, radio or optical data",
                m.name
            );
        }
        // A radio class chosen as a stand-in says why.
        assert!(lib.materials["curtain_light"].source.contains("radio: ITU-R P.2040-3 Table 3 class"));
    }

    #[test]
    fn nearest_names_suggest_close_spellings() {
        let lib = MaterialLibrary::builtin();
        assert_eq!(lib.nearest_names("concret", 1), vec!["concrete".to_string()]);
    }
}
