//! The acoustic simulation's options as a user gives them: the flags of `propsim acoustic`,
//! the keyword arguments of the Python module's `acoustic()`, one type with one set of
//! defaults (the scene file's `[acoustic]` table fills what they leave out).

use serde::Deserialize;

use super::AcousticSettings;

/// What a user may set for one acoustic run. Every field has the command line's default;
/// `None` means "the scene's value, else the built-in default" (see [`super::plan`]).
#[derive(clap::Args, Deserialize, Debug, Clone, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct AcousticOptions {
    /// Source position X,Y,Z (repeatable); replaces the scene's sources.
    #[arg(long = "source", value_parser = crate::scene::parse_point, allow_hyphen_values = true)]
    pub sources: Vec<[f32; 3]>,
    /// Receiver position X,Y,Z (repeatable); replaces the scene's receivers.
    #[arg(long = "receiver", value_parser = crate::scene::parse_point, allow_hyphen_values = true)]
    pub receivers: Vec<[f32; 3]>,
    /// Rays per source (default: the scene's, else 200000).
    #[arg(long)]
    pub rays: Option<u64>,
    /// Random seed: the same seed gives the same results for any thread or process count.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Histogram length, s (default: as long as the traced energy lasts, so every decay runs
    /// to its end; a warning says when a decay given a limit did not reach 35 dB).
    #[arg(long)]
    pub max_time_s: Option<f64>,
    /// Highest image-source order for the early specular reflections (0 to 6).
    #[arg(long, default_value_t = 2)]
    pub ism_order: u32,
    /// Receiver radius, m (default: a rule from room volume and ray count).
    #[arg(long)]
    pub receiver_radius_m: Option<f32>,
    /// Switch off air absorption.
    #[arg(long)]
    pub no_air: bool,
    /// Switch off diffuse rain (receivers then count only the rays that cross them).
    #[arg(long)]
    pub no_diffuse_rain: bool,
    /// Switch off ray splitting (rays far stronger than the room's average decay leaves
    /// them are otherwise split into copies, which smooths the late decay).
    #[arg(long)]
    pub no_splitting: bool,
    /// Switch off edge diffraction (on by default wherever the room has free edges: the
    /// first-order diffraction of the direct sound, the rays' diffraction near edges and the
    /// scattering of finite surfaces; docs/acoustics.md, Edge diffraction).
    #[arg(long)]
    pub no_diffraction: bool,
    /// Bend rays that pass near free edges (stochastic diffraction for the late part;
    /// docs/acoustics.md, Edge diffraction). On by default since it became cheap; the flag
    /// is kept so that scripts which ask for it still work.
    #[arg(long, conflicts_with = "no_ray_diffraction")]
    pub ray_diffraction: bool,
    /// Do not bend rays near free edges (the edge paths and panel scattering stay on; see
    /// --no-diffraction for all of it).
    #[arg(long)]
    pub no_ray_diffraction: bool,
    /// Level below launch, dB, from which rays play Russian roulette (default 30; 20 to 120):
    /// higher is smoother late decay for more time.
    #[arg(long)]
    pub roulette_db: Option<f64>,
    /// Air temperature, C (default: the scene's, else 20).
    #[arg(long)]
    pub temperature_c: Option<f64>,
    /// Relative humidity, % (default: the scene's, else 50).
    #[arg(long)]
    pub humidity_percent: Option<f64>,
    /// Directivity of every source, replacing the scene's: omni, cardioid, supercardioid,
    /// hypercardioid, figure-of-eight, mix (with --directivity-alpha), or a measured balloon
    /// FILE.sofa; normalised to the source's power (docs/acoustics.md, Directivity).
    #[arg(long, value_name = "PATTERN")]
    pub directivity: Option<String>,
    /// The omni share a of --directivity mix, a + (1 - a) cos(theta), in [0, 1].
    #[arg(long, value_name = "A")]
    pub directivity_alpha: Option<f32>,
    /// The direction X,Y,Z every source faces (its pattern's axis), replacing the scene's
    /// (default: the scene's orientation, else +x).
    #[arg(long, value_parser = crate::scene::parse_point, allow_hyphen_values = true)]
    pub orientation: Option<[f32; 3]>,
    /// Directivity of every receiver (a directional microphone), replacing the scene's: the
    /// names of --directivity, or a balloon FILE.sofa; its squared gain, 1 on the axis,
    /// weights each arrival.
    #[arg(long, value_name = "PATTERN")]
    pub receiver_directivity: Option<String>,
    /// The omni share a of --receiver-directivity mix, in [0, 1].
    #[arg(long, value_name = "A")]
    pub receiver_directivity_alpha: Option<f32>,
    /// The direction X,Y,Z every receiver faces, replacing the scene's: its pattern's axis and
    /// the way its head looks for the binaural and Ambisonic responses (default: the
    /// scene's orientation, else +x).
    #[arg(long, value_parser = crate::scene::parse_point, allow_hyphen_values = true)]
    pub receiver_orientation: Option<[f32; 3]>,
    /// Also write Ambisonic impulse responses ambix_SOURCE_RECEIVER.wav of this order (1 to
    /// 3; ACN, SN3D; 0: none).
    #[arg(long, default_value_t = 0, value_parser = clap::value_parser!(u32).range(0..=3))]
    pub ambisonic_order: u32,
    /// Also write binaural impulse responses brir_SOURCE_RECEIVER.wav (built-in spherical
    /// head, Duda and Martens 1998).
    #[arg(long)]
    pub binaural: bool,
    /// Binaural responses from this SOFA file's measured HRIRs instead of the spherical head
    /// (implies --binaural; per band gains and delays, docs/acoustics.md).
    #[arg(long, value_name = "FILE.sofa")]
    pub hrtf: Option<std::path::PathBuf>,
}

/// Highest image-source order: the number of image sources grows as (planes)^order.
pub const MAX_ISM_ORDER: u32 = 6;

impl Default for AcousticOptions {
    fn default() -> Self {
        let d = AcousticSettings::default();
        Self {
            sources: Vec::new(),
            receivers: Vec::new(),
            rays: None,
            seed: d.seed,
            max_time_s: None,
            ism_order: d.ism_order,
            receiver_radius_m: None,
            no_air: false,
            no_diffuse_rain: false,
            no_splitting: false,
            no_diffraction: false,
            ray_diffraction: false,
            no_ray_diffraction: false,
            roulette_db: None,
            temperature_c: None,
            humidity_percent: None,
            directivity: None,
            directivity_alpha: None,
            orientation: None,
            receiver_directivity: None,
            receiver_directivity_alpha: None,
            receiver_orientation: None,
            ambisonic_order: 0,
            binaural: false,
            hrtf: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cmd {
        #[command(flatten)]
        options: AcousticOptions,
    }

    #[test]
    fn the_command_line_and_the_library_share_one_set_of_defaults() {
        let parsed = Cmd::try_parse_from(["acoustic"]).expect("no flags parse");
        assert_eq!(parsed.options, AcousticOptions::default());
        let from_json: AcousticOptions = serde_json::from_str("{}").expect("empty options parse");
        assert_eq!(from_json, AcousticOptions::default());
    }

    #[test]
    fn unknown_options_are_refused_by_name() {
        let e = serde_json::from_str::<AcousticOptions>(r#"{"rayz": 10}"#).unwrap_err().to_string();
        assert!(e.contains("rayz"), "{e}");
    }
}
