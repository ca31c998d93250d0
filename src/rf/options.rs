//! The radio simulation's options as a user gives them: the flags of `propsim rf`, the
//! keyword arguments of the Python module's `rf()`, one type with one set of defaults. Each
//! option given replaces the scene's `[rf]` value; those left out keep it (see
//! [`super::RfConfig::from_scene`]).

use serde::Deserialize;

/// Width of coverage.png, pixels, unless the user sets one.
pub const DEFAULT_PNG_WIDTH: u32 = 1000;

/// What a user may set for one radio run; `None` keeps the scene's value, else the built-in
/// default.
#[derive(clap::Args, Deserialize, Debug, Clone, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct RfOptions {
    /// One transmitter at X,Y,Z instead of the scene's.
    #[arg(long, value_parser = crate::scene::parse_point, allow_hyphen_values = true)]
    pub tx: Option<[f32; 3]>,
    /// Carrier frequency, GHz (default: the scene's, else 3.5).
    #[arg(long)]
    pub freq_ghz: Option<f64>,
    /// Transmit power, dBm (default: the scene's, else 30).
    #[arg(long)]
    pub tx_power_dbm: Option<f64>,
    /// Transmit antenna: isotropic or dipole (half-wave, along z for vertical polarisation).
    #[arg(long)]
    pub antenna: Option<String>,
    /// vertical or horizontal.
    #[arg(long)]
    pub polarization: Option<String>,
    /// Dipole axis X,Y,Z (default: z for vertical, x for horizontal polarisation).
    #[arg(long, value_parser = crate::scene::parse_point, allow_hyphen_values = true)]
    pub orientation: Option<[f32; 3]>,
    /// Height of the coverage plane, m (default: the scene's, else 1.5).
    #[arg(long = "grid-height")]
    #[serde(rename = "grid_height")]
    pub grid_height_m: Option<f64>,
    /// Cell size, m (default: the scene's, else 1).
    #[arg(long)]
    pub cell_m: Option<f64>,
    /// Grid corner X,Y (default: the scene's grid, else its horizontal extent).
    #[arg(long, value_parser = crate::scene::parse_xy, allow_hyphen_values = true)]
    pub grid_min: Option<[f64; 2]>,
    /// Opposite grid corner X,Y.
    #[arg(long, value_parser = crate::scene::parse_xy, allow_hyphen_values = true)]
    pub grid_max: Option<[f64; 2]>,
    /// Rays per transmitter (default: the scene's, else 10^6).
    #[arg(long)]
    pub rays: Option<u64>,
    /// Maximum number of reflections (and transmissions) per ray (default: the scene's, else 3).
    #[arg(long)]
    pub max_depth: Option<u32>,
    #[arg(long)]
    pub seed: Option<u64>,
    /// Use ITU-R P.2040 fits outside their frequency ranges.
    #[arg(long)]
    pub extrapolate: bool,
    /// Walls are thin slabs that reflect and transmit (ITU-R P.2040-3 sec. 2.2.2.2): the
    /// default, so this flag changes nothing (kept for older command lines).
    #[arg(long, overrides_with = "no_transmission")]
    pub transmission: bool,
    /// Walls are opaque half-spaces that only reflect.
    #[arg(long, overrides_with = "transmission")]
    pub no_transmission: bool,
    /// No first-order edge diffraction (UTD, on by default: wedges between non-coplanar
    /// faces and rims of open surfaces, transmitter -> edge -> cell or receiver).
    #[arg(long)]
    pub no_diffraction: bool,
    /// Slab thickness of every wall, m (default: each material's thickness_m, else 0.1).
    #[arg(long)]
    pub wall_thickness_m: Option<f64>,
    /// Radio scattering coefficient S in [0, 1] of every surface (diffuse reflection; default:
    /// each material's scattering_coefficient, else 0).
    #[arg(long, allow_hyphen_values = true)]
    pub scattering_coefficient: Option<f64>,
    /// Write the channel frequency response at the point receivers (cfr.csv) over this
    /// bandwidth, MHz, centred on the carrier.
    #[arg(long)]
    pub cfr_bandwidth_mhz: Option<f64>,
    /// Frequency points of the channel frequency response (default 256).
    #[arg(long)]
    pub cfr_points: Option<u64>,
    /// Extra coherent point receiver X,Y,Z (repeatable).
    #[arg(long = "rx", value_parser = crate::scene::parse_point, allow_hyphen_values = true)]
    #[serde(rename = "rx")]
    pub receivers: Vec<[f32; 3]>,
    /// Skip the scene's point receivers.
    #[arg(long)]
    pub no_receivers: bool,
    /// Receiver noise figure of the SINR column, dB (default 7; several transmitters).
    #[arg(long, allow_hyphen_values = true)]
    pub noise_figure_db: Option<f64>,
    /// Receiver bandwidth of the SINR's thermal noise k T0 B F, MHz (default 20).
    #[arg(long, allow_hyphen_values = true)]
    pub bandwidth_mhz: Option<f64>,
    /// Bottom of the coverage pictures' colour scale, dB of path gain (default: the top
    /// minus 80 dB, or the lowest value if closer).
    #[arg(long, allow_hyphen_values = true)]
    pub vmin_db: Option<f64>,
    /// Top of the coverage pictures' colour scale, dB of path gain (default: the highest
    /// value rounded up to 5 dB).
    #[arg(long, allow_hyphen_values = true)]
    pub vmax_db: Option<f64>,
    /// Width of coverage.png, pixels.
    #[arg(long, default_value_t = DEFAULT_PNG_WIDTH)]
    pub png_width: u32,
}

impl Default for RfOptions {
    fn default() -> Self {
        Self {
            tx: None,
            freq_ghz: None,
            tx_power_dbm: None,
            antenna: None,
            polarization: None,
            orientation: None,
            grid_height_m: None,
            cell_m: None,
            grid_min: None,
            grid_max: None,
            rays: None,
            max_depth: None,
            seed: None,
            extrapolate: false,
            transmission: false,
            no_transmission: false,
            no_diffraction: false,
            wall_thickness_m: None,
            scattering_coefficient: None,
            cfr_bandwidth_mhz: None,
            cfr_points: None,
            receivers: Vec::new(),
            no_receivers: false,
            noise_figure_db: None,
            bandwidth_mhz: None,
            vmin_db: None,
            vmax_db: None,
            png_width: DEFAULT_PNG_WIDTH,
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
        options: RfOptions,
    }

    #[test]
    fn the_command_line_and_the_library_share_one_set_of_defaults() {
        let parsed = Cmd::try_parse_from(["rf"]).expect("no flags parse");
        assert_eq!(parsed.options, RfOptions::default());
        let from_json: RfOptions = serde_json::from_str("{}").expect("empty options parse");
        assert_eq!(from_json, RfOptions::default());
        let named: RfOptions =
            serde_json::from_str(r#"{"grid_height": 2, "rx": [[1, 2, 3]]}"#).expect("parse");
        assert_eq!(named.grid_height_m, Some(2.0));
        assert_eq!(named.receivers, vec![[1.0, 2.0, 3.0]]);
    }
}
