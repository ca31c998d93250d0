//! Simulation settings: the scene's `[rf]` table, overridden by command-line values.

use glam::DVec3;
use serde::Serialize;

use super::PointReceiver;
use super::antenna::{Antenna, Polarization};
use super::coverage::GridSpec;
use super::options::RfOptions;
use crate::scene::World;

/// Carrier frequency when neither the command line nor the scene gives one, GHz.
pub const DEFAULT_FREQ_GHZ: f64 = 3.5;
/// Transmit power when none is given, dBm.
pub const DEFAULT_POWER_DBM: f64 = 30.0;
/// Largest transmit power, and the smallest's magnitude, dBm (100 dBm is 10 MW).
pub const MAX_POWER_DBM: f64 = 100.0;
/// Grid height when none is given, metres.
pub const DEFAULT_GRID_HEIGHT_M: f64 = 1.5;
/// Cell size when none is given, metres.
pub const DEFAULT_CELL_M: f64 = 1.0;
/// Farthest the coverage plane may lie above the highest or below the lowest surface, m.
pub const GRID_HEIGHT_MARGIN_M: f64 = 1000.0;
/// Rays per transmitter when none are given.
pub const DEFAULT_RAYS: u64 = 1_000_000;
/// Interactions per ray when none are given.
pub const DEFAULT_MAX_DEPTH: u32 = 3;
/// Most rays per transmitter.
pub const MAX_RAYS: u64 = 10_000_000_000;
/// Wall thickness of the thin-slab transmission model when neither the material
/// (`thickness_m`) nor `--wall-thickness-m` gives one, metres: Sionna RT's default
/// `RadioMaterial` thickness (docs/radio.md, sec. 1).
pub const DEFAULT_WALL_THICKNESS_M: f64 = 0.1;
/// Most frequency points of a channel frequency response.
pub const MAX_CFR_POINTS: usize = 1_000_000;
/// Longest ray path, metres (rays leaving an open scene end here).
pub const MAX_PATH_M: f64 = 100_000.0;
/// Receiver noise figure when none is given, dB (docs/radio.md, "Several transmitters").
pub const DEFAULT_NOISE_FIGURE_DB: f64 = 7.0;
/// Receiver bandwidth of the SINR's thermal noise when none is given, MHz.
pub const DEFAULT_BANDWIDTH_MHZ: f64 = 20.0;
/// Reference temperature of the thermal noise `k T0 B F`, kelvin (the noise figure's).
pub const NOISE_TEMPERATURE_K: f64 = 290.0;
/// Boltzmann's constant, J/K (exact in the 2019 SI).
pub const BOLTZMANN_J_PER_K: f64 = 1.380_649e-23;

/// Narrowest coverage picture, pixels: the margins, colour bar and a map 100 pixels wide.
pub const MIN_PNG_WIDTH: u32 = 300;
/// Widest coverage picture, pixels.
pub const MAX_PNG_WIDTH: u32 = 8192;

/// A transmitter ready to simulate.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Transmitter {
    /// Name.
    pub name: String,
    /// Position, metres.
    pub position: DVec3,
    /// Carrier frequency, GHz.
    pub freq_ghz: f64,
    /// Transmit power, dBm.
    pub power_dbm: f64,
    /// Antenna pattern.
    pub antenna: Antenna,
}

/// Everything a simulation needs besides the world.
#[derive(Clone, Debug, Serialize)]
pub struct RfConfig {
    /// Transmitters.
    pub transmitters: Vec<Transmitter>,
    /// Coverage grid.
    pub grid: GridSpec,
    /// Rays per transmitter.
    pub rays: u64,
    /// Maximum number of reflections (and transmissions) per ray.
    pub max_depth: u32,
    /// Seed of the random number generator.
    pub seed: u64,
    /// Use ITU-R P.2040 fits outside their frequency ranges.
    pub extrapolate: bool,
    /// Walls as thin slabs that reflect and transmit (ITU-R P.2040-3 single layer), each
    /// of its material's thickness; otherwise opaque half-spaces that only reflect.
    pub transmission: bool,
    /// First-order edge diffraction (UTD) from each transmitter to the grid and the point
    /// receivers ([`crate::rf::diffraction`]); on unless `--no-diffraction`.
    pub diffraction: bool,
    /// Slab thickness of every wall, metres, overriding the materials' (`--wall-thickness-m`).
    pub wall_thickness_m: Option<f64>,
    /// Scattering coefficient `S` of every surface, overriding the materials'
    /// (`--scattering-coefficient`; diffuse reflection, docs/radio.md, sec. 4).
    pub scattering_coefficient: Option<f64>,
    /// Longest ray path, metres.
    pub max_path_m: f64,
    /// Point receivers.
    pub receivers: Vec<PointReceiver>,
    /// The channel frequency response to write at the point receivers, if asked.
    pub cfr: Option<CfrSpec>,
    /// The receiver noise of the SINR column (several transmitters).
    pub noise: NoiseSpec,
    /// The coverage pictures' colour scale.
    pub colour_range: ColourRange,
    /// Width of coverage.png, pixels.
    pub png_width: u32,
}

/// Thermal noise at a receiver, `N = k T0 B F` (`T0` = 290 K): what the SINR adds to the
/// other transmitters' power.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct NoiseSpec {
    /// Receiver noise figure, dB.
    pub noise_figure_db: f64,
    /// Noise bandwidth, Hz.
    pub bandwidth_hz: f64,
    /// Noise temperature `T0`, kelvin.
    pub temperature_k: f64,
    /// `10 log10(k T0 B F / 1 mW)`.
    pub noise_power_dbm: f64,
}

impl NoiseSpec {
    /// Noise of figure `noise_figure_db` (dB) over `bandwidth_hz` (Hz).
    pub fn new(noise_figure_db: f64, bandwidth_hz: f64) -> Self {
        let watts = BOLTZMANN_J_PER_K * NOISE_TEMPERATURE_K * bandwidth_hz;
        Self {
            noise_figure_db,
            bandwidth_hz,
            temperature_k: NOISE_TEMPERATURE_K,
            noise_power_dbm: 10.0 * (watts * 1e3).log10() + noise_figure_db,
        }
    }

    /// The noise power, mW.
    pub fn power_mw(&self) -> f64 {
        10f64.powf(self.noise_power_dbm / 10.0)
    }
}

/// The colour scale of the coverage pictures, dB of path gain: each end given
/// (`--vmin-db`, `--vmax-db`) or automatic (`None`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct ColourRange {
    /// Lower end, dB (`None`: automatic).
    pub vmin_db: Option<f64>,
    /// Upper end, dB (`None`: automatic).
    pub vmax_db: Option<f64>,
}

/// Span of the automatic colour scale, dB.
pub const AUTO_RANGE_DB: f64 = 80.0;

impl ColourRange {
    /// Checks the given ends: finite, and `vmin < vmax` when both are given.
    pub fn new(vmin_db: Option<f64>, vmax_db: Option<f64>) -> Result<Self, String> {
        for (v, flag) in [(vmin_db, "--vmin-db"), (vmax_db, "--vmax-db")] {
            if let Some(v) = v.filter(|v| !v.is_finite()) {
                return Err(format!("{flag} {v}: must be a finite number of dB"));
            }
        }
        if let (Some(lo), Some(hi)) = (vmin_db, vmax_db)
            && lo >= hi
        {
            return Err(format!("--vmin-db {lo} must be below --vmax-db {hi}"));
        }
        Ok(Self { vmin_db, vmax_db })
    }

    /// The range to draw, given the map's highest and lowest reached values (dB; `None` for
    /// an empty map). Automatic: from the highest value rounded up to 5 dB down
    /// [`AUTO_RANGE_DB`], or to the lowest rounded down to 5 dB if closer. A given end
    /// replaces the automatic one; when the other automatic end would then fall on the wrong
    /// side, the range is [`AUTO_RANGE_DB`] wide from the given end.
    pub fn resolve(&self, extent_db: Option<(f64, f64)>) -> Option<(f64, f64)> {
        let auto = extent_db.map(|(lo, hi)| {
            let hi = (hi / 5.0).ceil() * 5.0;
            let lo = ((lo.max(hi - AUTO_RANGE_DB)) / 5.0).floor() * 5.0;
            (lo, if hi > lo { hi } else { lo + 5.0 })
        });
        match (self.vmin_db, self.vmax_db, auto) {
            (Some(lo), Some(hi), _) => Some((lo, hi)),
            (Some(lo), None, Some((_, hi))) if hi > lo => Some((lo, hi)),
            (Some(lo), None, _) => Some((lo, lo + AUTO_RANGE_DB)),
            (None, Some(hi), Some((lo, _))) if lo < hi => Some((lo, hi)),
            (None, Some(hi), _) => Some((hi - AUTO_RANGE_DB, hi)),
            (None, None, auto) => auto,
        }
    }
}

/// Frequency points of a channel frequency response when only the bandwidth is given.
pub const DEFAULT_CFR_POINTS: usize = 256;

/// A band of `points` equally spaced frequencies, `bandwidth_hz` wide, centred on each
/// transmitter's carrier (the centres of `points` equal sub-bands).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CfrSpec {
    /// Width of the band, Hz.
    pub bandwidth_hz: f64,
    /// Number of frequencies.
    pub points: usize,
}

impl CfrSpec {
    /// Offset of point `i` from the carrier, Hz: `B ((i + 1/2) / N - 1/2)`.
    pub fn offset_hz(&self, i: usize) -> f64 {
        self.bandwidth_hz * ((i as f64 + 0.5) / self.points as f64 - 0.5)
    }
}

fn antenna_from(
    kind: Option<&str>,
    pol: Option<&str>,
    orientation: Option<[f32; 3]>,
    who: &str,
) -> Result<Antenna, String> {
    let polarization: Polarization = pol.unwrap_or("vertical").parse().map_err(|e| format!("{who}: {e}"))?;
    match kind.unwrap_or("isotropic").to_ascii_lowercase().as_str() {
        "isotropic" => Ok(Antenna::Isotropic { polarization }),
        "dipole" | "half_wave_dipole" => {
            let axis = match orientation {
                Some(o) => {
                    let v = glam::Vec3::from(o).as_dvec3();
                    if !(v.is_finite() && v.length() > 1e-9) {
                        return Err(format!("{who}: orientation {} is not a direction", crate::io::point(o)));
                    }
                    v.normalize()
                }
                None if polarization == Polarization::Horizontal => DVec3::X,
                None => DVec3::Z,
            };
            Ok(Antenna::Dipole { axis })
        }
        other => Err(format!("{who}: antenna \"{other}\": expected isotropic or dipole")),
    }
}

fn positive(v: f64, what: &str) -> Result<f64, String> {
    if v.is_finite() && v > 0.0 { Ok(v) } else { Err(format!("{what} {v}: must be a positive number")) }
}

impl RfConfig {
    /// The scene's radio settings with `o` applied; errors are one line.
    pub fn from_scene(world: &World, o: &RfOptions) -> Result<Self, String> {
        if !(MIN_PNG_WIDTH..=MAX_PNG_WIDTH).contains(&o.png_width) {
            return Err(format!(
                "--png-width {}: must be between {MIN_PNG_WIDTH} and {MAX_PNG_WIDTH} pixels",
                o.png_width
            ));
        }
        let rf = world.scene.desc.rf.clone().unwrap_or_default();
        let scene_freq = rf.freq_ghz;
        let mut transmitters = Vec::new();
        if let Some(p) = o.tx {
            let freq_ghz = positive(o.freq_ghz.or(scene_freq).unwrap_or(DEFAULT_FREQ_GHZ), "--freq-ghz")?;
            transmitters.push(Transmitter {
                name: "tx".into(),
                position: glam::Vec3::from(p).as_dvec3(),
                freq_ghz,
                power_dbm: o.tx_power_dbm.unwrap_or(DEFAULT_POWER_DBM),
                antenna: antenna_from(
                    o.antenna.as_deref(),
                    o.polarization.as_deref(),
                    o.orientation,
                    "--tx",
                )?,
            });
        } else {
            for t in &rf.transmitters {
                let who = format!("transmitter \"{}\"", t.name);
                let freq_ghz = positive(
                    o.freq_ghz.or(t.freq_ghz).or(scene_freq).unwrap_or(DEFAULT_FREQ_GHZ),
                    &format!("{who}: frequency (--freq-ghz)"),
                )?;
                let kind = o.antenna.as_deref().or(t.antenna.as_deref());
                let pol = o.polarization.as_deref().or(t.polarization.as_deref());
                transmitters.push(Transmitter {
                    name: t.name.clone(),
                    position: glam::Vec3::from(t.position).as_dvec3(),
                    freq_ghz,
                    power_dbm: o.tx_power_dbm.or(t.power_dbm).unwrap_or(DEFAULT_POWER_DBM),
                    antenna: antenna_from(kind, pol, o.orientation.or(t.orientation), &who)?,
                });
            }
        }
        if transmitters.is_empty() {
            return Err(
                "no transmitter: the scene has no [[rf.transmitters]]; give one with --tx X,Y,Z".into()
            );
        }
        for t in &transmitters {
            if !t.position.is_finite() || !t.power_dbm.is_finite() {
                return Err(format!("transmitter \"{}\": position and power must be finite", t.name));
            }
            if !(-MAX_POWER_DBM..=MAX_POWER_DBM).contains(&t.power_dbm) {
                return Err(format!(
                    "transmitter \"{}\": power {} dBm (--tx-power-dbm): must be between -{MAX_POWER_DBM} and {MAX_POWER_DBM} dBm",
                    t.name, t.power_dbm
                ));
            }
            world.check_clearance(&format!("transmitter \"{}\"", t.name), t.position.as_vec3())?;
        }
        let g = rf.grid.clone().unwrap_or_default();
        let height = o.grid_height_m.or(g.height_m.map(f64::from)).unwrap_or(DEFAULT_GRID_HEIGHT_M);
        let cell =
            positive(o.cell_m.or(g.cell_m.map(f64::from)).unwrap_or(DEFAULT_CELL_M), "cell size (--cell-m)")?;
        let bounds = world.bounds();
        let from_bounds = |i: usize, hi: bool| {
            bounds.map(|(lo, up)| f64::from(if hi { up[i] } else { lo[i] })).unwrap_or(if hi {
                1.0
            } else {
                -1.0
            })
        };
        let min = o
            .grid_min
            .or(g.min.map(|m| [f64::from(m[0]), f64::from(m[1])]))
            .unwrap_or([from_bounds(0, false), from_bounds(1, false)]);
        let max = o
            .grid_max
            .or(g.max.map(|m| [f64::from(m[0]), f64::from(m[1])]))
            .unwrap_or([from_bounds(0, true), from_bounds(1, true)]);
        if let Some((lo, hi)) = bounds
            && !(height >= f64::from(lo.z) - GRID_HEIGHT_MARGIN_M
                && height <= f64::from(hi.z) + GRID_HEIGHT_MARGIN_M)
        {
            return Err(format!(
                "grid height {height} m (--grid-height): must be within {GRID_HEIGHT_MARGIN_M} m of the scene's heights ({} to {} m)",
                lo.z, hi.z
            ));
        }
        let grid = GridSpec::covering(min, max, cell, height)?;
        let rays = o.rays.or(rf.rays).unwrap_or(DEFAULT_RAYS);
        // Bounded so that no cell's 32.32 fixed-point sum can overflow.
        if rays == 0 || rays > MAX_RAYS {
            return Err(format!("--rays {rays}: must be between 1 and {MAX_RAYS}"));
        }
        let max_depth = o.max_depth.or(rf.max_depth).unwrap_or(DEFAULT_MAX_DEPTH);
        if max_depth > 64 {
            return Err(format!("--max-depth {max_depth}: must be at most 64"));
        }
        let wall_thickness_m = match o.wall_thickness_m {
            Some(t) => Some(positive(t, "--wall-thickness-m")?),
            None => None,
        };
        if let Some(v) = o.scattering_coefficient
            && !(0.0..=1.0).contains(&v)
        {
            return Err(format!("--scattering-coefficient {v}: must be a number in [0, 1]"));
        }
        let cfr = match (o.cfr_bandwidth_mhz, o.cfr_points) {
            (None, None) => None,
            (None, Some(_)) => return Err("--cfr-points needs --cfr-bandwidth-mhz".into()),
            (Some(b), n) => {
                let bandwidth_hz = positive(b, "--cfr-bandwidth-mhz")? * 1e6;
                let points = n.unwrap_or(DEFAULT_CFR_POINTS as u64);
                if points == 0 || points > MAX_CFR_POINTS as u64 {
                    return Err(format!("--cfr-points {points}: must be between 1 and {MAX_CFR_POINTS}"));
                }
                Some(CfrSpec { bandwidth_hz, points: points as usize })
            }
        };
        let mut names = std::collections::BTreeSet::new();
        for t in &transmitters {
            if !names.insert(t.name.as_str()) {
                return Err(format!(
                    "transmitter name \"{}\" is used twice: names must be unique (they name coverage.csv's columns)",
                    t.name
                ));
            }
        }
        let noise_figure_db = o.noise_figure_db.unwrap_or(DEFAULT_NOISE_FIGURE_DB);
        if !noise_figure_db.is_finite() || noise_figure_db < 0.0 {
            return Err(format!("--noise-figure-db {noise_figure_db}: must be a number of dB, 0 or more"));
        }
        let bandwidth_mhz = positive(o.bandwidth_mhz.unwrap_or(DEFAULT_BANDWIDTH_MHZ), "--bandwidth-mhz")?;
        let noise = NoiseSpec::new(noise_figure_db, bandwidth_mhz * 1e6);
        let colour_range = ColourRange::new(o.vmin_db, o.vmax_db)?;
        let mut receivers: Vec<PointReceiver> = if o.no_receivers {
            Vec::new()
        } else {
            rf.receivers
                .iter()
                .map(|r| PointReceiver {
                    name: r.name.clone(),
                    position: glam::Vec3::from(r.position).as_dvec3(),
                })
                .collect()
        };
        for (i, p) in o.receivers.iter().enumerate() {
            receivers.push(PointReceiver {
                name: format!("rx{}", i + 1),
                position: glam::Vec3::from(*p).as_dvec3(),
            });
        }
        Ok(Self {
            transmitters,
            grid,
            rays,
            max_depth,
            seed: o.seed.unwrap_or(1),
            extrapolate: o.extrapolate,
            transmission: !o.no_transmission,
            diffraction: !o.no_diffraction,
            wall_thickness_m,
            scattering_coefficient: o.scattering_coefficient,
            max_path_m: MAX_PATH_M,
            receivers,
            cfr,
            noise,
            colour_range,
            png_width: o.png_width,
        })
    }
}

#[cfg(test)]
mod colour_range_tests {
    use super::*;

    #[test]
    fn colour_range_is_automatic_or_given_and_checked() {
        let auto = ColourRange::default();
        // 80 dB down from the top rounded up to 5 dB, or the bottom if closer.
        assert_eq!(auto.resolve(Some((-143.2, -61.3))), Some((-140.0, -60.0)));
        assert_eq!(auto.resolve(Some((-90.2, -61.3))), Some((-95.0, -60.0)));
        assert_eq!(auto.resolve(None), None);
        let both = ColourRange::new(Some(-120.0), Some(-40.0)).unwrap();
        assert_eq!(both.resolve(Some((-90.0, -60.0))), Some((-120.0, -40.0)));
        assert_eq!(both.resolve(None), Some((-120.0, -40.0)));
        let lo = ColourRange::new(Some(-100.0), None).unwrap();
        assert_eq!(lo.resolve(Some((-143.2, -61.3))), Some((-100.0, -60.0)));
        assert_eq!(lo.resolve(Some((-143.2, -101.3))), Some((-100.0, -20.0)));
        let hi = ColourRange::new(None, Some(-70.0)).unwrap();
        assert_eq!(hi.resolve(Some((-143.2, -61.3))), Some((-140.0, -70.0)));
        assert_eq!(hi.resolve(Some((-43.2, -21.3))), Some((-150.0, -70.0)));
        assert!(ColourRange::new(Some(f64::NAN), None).is_err());
        assert!(ColourRange::new(None, Some(f64::INFINITY)).is_err());
        assert!(ColourRange::new(Some(-50.0), Some(-50.0)).is_err());
    }

    #[test]
    fn thermal_noise_is_k_t0_b_f() {
        // -174 dBm/Hz at 290 K: 20 MHz adds 73.01 dB, a 7 dB noise figure 7 dB.
        let n = NoiseSpec::new(7.0, 20e6);
        assert!((n.noise_power_dbm - (-173.975 + 73.010 + 7.0)).abs() < 1e-3, "{}", n.noise_power_dbm);
    }
}
