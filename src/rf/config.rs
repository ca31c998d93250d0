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
/// Wall thickness of the thin-slab transmission model when none is given, metres.
pub const DEFAULT_WALL_THICKNESS_M: f64 = 0.2;
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
    pub transmission: bool,
    pub wall_thickness_m: Option<f64>,
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
    /// Walls as thin slabs that also transmit (`wall_thickness_m` thick).
    pub transmission: bool,
    pub wall_thickness_m: f64,
    pub max_path_m: f64,
    pub receivers: Vec<PointReceiver>,
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
        let wall_thickness_m =
            positive(o.wall_thickness_m.unwrap_or(DEFAULT_WALL_THICKNESS_M), "--wall-thickness-m")?;
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
            transmission: o.transmission,
            wall_thickness_m,
            max_path_m: MAX_PATH_M,
            receivers,
        })
    }
}
