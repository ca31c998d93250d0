//! Simulation settings: the scene's `[rf]` table, overridden by command-line values.

use glam::DVec3;
use serde::Serialize;

use super::PointReceiver;
use super::antenna::{Antenna, Polarization};
use super::coverage::GridSpec;
use crate::scene::World;

/// Carrier frequency when neither the command line nor the scene gives one, GHz.
pub const DEFAULT_FREQ_GHZ: f64 = 3.5;
/// Transmit power when none is given, dBm.
pub const DEFAULT_POWER_DBM: f64 = 30.0;
/// Grid height when none is given, metres.
pub const DEFAULT_GRID_HEIGHT_M: f64 = 1.5;
/// Cell size when none is given, metres.
pub const DEFAULT_CELL_M: f64 = 1.0;
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

/// A transmitter ready to simulate.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Transmitter {
    pub name: String,
    pub position: DVec3,
    pub freq_ghz: f64,
    pub power_dbm: f64,
    pub antenna: Antenna,
}

/// Values given on the command line; each replaces the scene's.
#[derive(Clone, Debug, Default)]
pub struct Overrides {
    /// One transmitter here instead of the scene's.
    pub tx: Option<[f32; 3]>,
    pub freq_ghz: Option<f64>,
    pub tx_power_dbm: Option<f64>,
    /// "isotropic" or "dipole".
    pub antenna: Option<String>,
    pub polarization: Option<String>,
    /// Dipole axis.
    pub orientation: Option<[f32; 3]>,
    pub grid_height_m: Option<f64>,
    pub cell_m: Option<f64>,
    pub grid_min: Option<[f64; 2]>,
    pub grid_max: Option<[f64; 2]>,
    pub rays: Option<u64>,
    pub max_depth: Option<u32>,
    pub seed: Option<u64>,
    pub extrapolate: bool,
    /// Walls are opaque half-spaces that only reflect (transmission is on by default).
    pub no_transmission: bool,
    /// Slab thickness of every wall, metres, instead of the materials' `thickness_m`.
    pub wall_thickness_m: Option<f64>,
    /// Bandwidth of the channel frequency response at the point receivers, MHz.
    pub cfr_bandwidth_mhz: Option<f64>,
    /// Frequency points of the channel frequency response (default [`DEFAULT_CFR_POINTS`]).
    pub cfr_points: Option<u64>,
    /// Extra point receivers.
    pub receivers: Vec<[f32; 3]>,
    /// Ignore the scene's point receivers.
    pub no_receivers: bool,
}

/// Everything a simulation needs besides the world.
#[derive(Clone, Debug, Serialize)]
pub struct RfConfig {
    pub transmitters: Vec<Transmitter>,
    pub grid: GridSpec,
    pub rays: u64,
    pub max_depth: u32,
    pub seed: u64,
    pub extrapolate: bool,
    /// Walls as thin slabs that reflect and transmit (ITU-R P.2040-3 single layer), each
    /// of its material's thickness; otherwise opaque half-spaces that only reflect.
    pub transmission: bool,
    /// Slab thickness of every wall, metres, overriding the materials' (`--wall-thickness-m`).
    pub wall_thickness_m: Option<f64>,
    pub max_path_m: f64,
    pub receivers: Vec<PointReceiver>,
    /// The channel frequency response to write at the point receivers, if asked.
    pub cfr: Option<CfrSpec>,
}

/// Frequency points of a channel frequency response when only the bandwidth is given.
pub const DEFAULT_CFR_POINTS: usize = 256;

/// A band of `points` equally spaced frequencies, `bandwidth_hz` wide, centred on each
/// transmitter's carrier (the centres of `points` equal sub-bands).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct CfrSpec {
    pub bandwidth_hz: f64,
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
                        return Err(format!("{who}: orientation {o:?} is not a direction"));
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
    pub fn from_scene(world: &World, o: &Overrides) -> Result<Self, String> {
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
                let freq_ghz =
                    positive(o.freq_ghz.or(t.freq_ghz).or(scene_freq).unwrap_or(DEFAULT_FREQ_GHZ), &who)?;
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
        }
        let g = rf.grid.clone().unwrap_or_default();
        let height = o.grid_height_m.or(g.height_m.map(f64::from)).unwrap_or(DEFAULT_GRID_HEIGHT_M);
        let cell =
            positive(o.cell_m.or(g.cell_m.map(f64::from)).unwrap_or(DEFAULT_CELL_M), "cell size (--cell-m)")?;
        let bounds = world.scene.mesh.bounds();
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
            wall_thickness_m,
            max_path_m: MAX_PATH_M,
            receivers,
            cfr,
        })
    }
}
