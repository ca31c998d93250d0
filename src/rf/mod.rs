//! Radio coverage: shooting-and-bouncing rays from the shared launcher
//! ([`crate::core::launcher`]) with the exact Fresnel coefficients of ITU-R P.2040-3
//! materials, a coverage grid of average path gain per cell, and coherent point receivers by
//! the exact image method.
//!
//! ```no_run
//! use propsim::rf::{RfConfig, simulate};
//! use propsim::scene::{LoadOptions, World, load};
//! let world = World::build(load("rooms/street_canyon/scene.toml".as_ref(), &LoadOptions::default())?);
//! let config = RfConfig::from_scene(&world, &Default::default()).map_err(anyhow::Error::msg)?;
//! let result = simulate(&world, &config, &|_| {})?;
//! println!("{} cells reached", result.coverage.paths.iter().filter(|&&p| p > 0).count());
//! # Ok::<(), anyhow::Error>(())
//! ```

pub mod antenna;
pub mod coefficient_table;
pub mod config;
pub mod coverage;
pub mod diffraction;
pub mod fresnel;
pub mod job;
pub mod options;
pub mod output;
pub mod plot;
pub mod propagation;
pub mod receivers;

pub use antenna::{Antenna, Polarization};
pub use config::{ColourRange, NoiseSpec, RfConfig, Transmitter};
pub use coverage::{Coverage, CoverageAccumulator, GridSpec};
pub use options::RfOptions;

use glam::DVec3;

use crate::core::launcher::{self, Launch, LaunchPattern};
use crate::core::specular::{Planes, affordable_order};
use crate::dist::Cluster;
use crate::scene::World;
use crate::scene::itu::itu_lookup;
use crate::scene::materials::{RadioProps, RadioScattering, ScatteringPattern};
use fresnel::{C0, Complex, complex_permittivity};
use propagation::{RadioPropagation, SurfacePhysics};
use receivers::{PathSum, coherent_paths};

/// Free-space path loss `20 log10(4 pi d f / c)` in dB (Friis).
pub fn free_space_path_loss_db(distance_m: f64, freq_hz: f64) -> f64 {
    20.0 * (4.0 * std::f64::consts::PI * distance_m * freq_hz / C0).log10()
}

/// The complex permittivity of every surface of `world` at `freq_ghz`. Surfaces without
/// radio data, and ITU materials outside their frequency range (unless `extrapolate`), are
/// errors naming the surface.
pub fn surface_permittivities(
    world: &World,
    freq_ghz: f64,
    extrapolate: bool,
) -> Result<Vec<Option<Complex>>, String> {
    let used = world.scene.used_surfaces();
    let mut out = Vec::with_capacity(world.scene.surfaces.len());
    for (id, s) in world.scene.surfaces.iter().enumerate() {
        if !used.contains(&(id as u32)) {
            out.push(None);
            continue;
        }
        let radio = s.material.as_ref().and_then(|m| m.radio.as_ref()).ok_or_else(|| {
            format!(
                "surface \"{}\" has no radio properties: give its material itu = \"NAME\" or relative_permittivity and conductivity_s_per_m (--materials FILE)",
                s.name
            )
        })?;
        let eta = match radio {
            RadioProps::Itu(name) => {
                let (m, covered) = itu_lookup(name, freq_ghz).ok_or_else(|| {
                    format!("surface \"{}\": unknown ITU-R P.2040 material \"{name}\"", s.name)
                })?;
                if !covered && !extrapolate {
                    return Err(format!(
                        "surface \"{}\": ITU-R P.2040-3 gives {name} for {}-{} GHz only, not {freq_ghz} GHz (use --extrapolate to extend the fit)",
                        s.name, m.freq_min_ghz, m.freq_max_ghz
                    ));
                }
                complex_permittivity(
                    m.relative_permittivity(freq_ghz),
                    m.conductivity_s_per_m(freq_ghz),
                    freq_ghz * 1e9,
                )
            }
            RadioProps::Explicit { relative_permittivity, conductivity_s_per_m } => {
                complex_permittivity(*relative_permittivity, *conductivity_s_per_m, freq_ghz * 1e9)
            }
        };
        out.push(Some(eta));
    }
    Ok(out)
}

/// Whether [`simulate`] can run `config` in `world` (the pre-flight of `propsim run`): every
/// surface in use has radio constants at every transmitter's frequency. ([`RfConfig::from_scene`]
/// has already checked the transmitters, grid and settings.) The error is a one-line reason.
pub fn check(world: &World, config: &RfConfig) -> Result<(), String> {
    for tx in &config.transmitters {
        surface_permittivities(world, tx.freq_ghz, config.extrapolate)?;
    }
    Ok(())
}

/// Why the coverage grid of `config` cannot show the model of `world`, if it cannot: its plane
/// lies above or below the whole model, or its rectangle beside it. Both usually mean a model
/// whose up axis is not z (Blender's OBJ export is Y-up) or whose unit is not the metre.
pub fn grid_misses_model(world: &World, config: &RfConfig) -> Option<String> {
    let (lo, hi) = world.bounds()?;
    let g = &config.grid;
    let (x1, y1) = (g.min_m[0] + g.cell_m * g.nx as f64, g.min_m[1] + g.cell_m * g.ny as f64);
    let (lo, hi) = (lo.as_dvec3(), hi.as_dvec3());
    let t = |x: f64| crate::io::tidy(x, 4);
    let model = format!(
        "the model spans x {}..{}, y {}..{}, z {}..{} m",
        t(lo.x),
        t(hi.x),
        t(lo.y),
        t(hi.y),
        t(lo.z),
        t(hi.z)
    );
    if g.height_m < lo.z || g.height_m > hi.z {
        return Some(format!(
            "the coverage grid's plane z = {} m misses the model ({model}); if the model is Y-up, export it Z-up \
             or give --grid-height",
            t(g.height_m)
        ));
    }
    if x1 < lo.x || g.min_m[0] > hi.x || y1 < lo.y || g.min_m[1] > hi.y {
        return Some(format!(
            "the coverage grid x {}..{}, y {}..{} m lies beside the model ({model}) \
             (give --grid-min and --grid-max)",
            t(g.min_m[0]),
            t(x1),
            t(g.min_m[1]),
            t(y1)
        ));
    }
    None
}

/// The slab thickness of every surface of `world`, metres: `wall_thickness_m` when given
/// (`--wall-thickness-m`), else its material's `thickness_m`, else
/// [`config::DEFAULT_WALL_THICKNESS_M`] (0.1 m, as in Sionna RT).
pub fn surface_thicknesses(world: &World, wall_thickness_m: Option<f64>) -> Vec<f64> {
    world
        .scene
        .surfaces
        .iter()
        .map(|s| {
            wall_thickness_m
                .or_else(|| s.material.as_ref().and_then(|m| m.thickness_m))
                .unwrap_or(config::DEFAULT_WALL_THICKNESS_M)
        })
        .collect()
}

/// The diffuse reflection of every surface of `world` (docs/radio.md, sec. 4): its material's
/// `scattering_coefficient`, `xpd_coefficient` and pattern, with `S` replaced by
/// `scattering_coefficient` when given (`--scattering-coefficient`); `S = 0` when not given.
pub fn surface_scattering(world: &World, scattering_coefficient: Option<f64>) -> Vec<RadioScattering> {
    world
        .scene
        .surfaces
        .iter()
        .map(|s| {
            let mut sc = s.material.as_ref().and_then(|m| m.radio_scattering).unwrap_or_default();
            if let Some(v) = scattering_coefficient {
                sc.scattering_coefficient = v;
            }
            sc
        })
        .collect()
}

/// The radio constants a surface was simulated with.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct SurfaceRadio {
    /// Surface name.
    pub surface: String,
    /// Material name.
    pub material: Option<String>,
    /// Real part of the complex relative permittivity at the carrier.
    pub eta_re: f64,
    /// Imaginary part of the complex relative permittivity at the carrier.
    pub eta_im: f64,
    /// |Gamma| at normal incidence (half-space).
    pub normal_incidence_reflection: f64,
    /// Slab thickness, metres, when walls transmit (`null` when they are opaque).
    pub thickness_m: Option<f64>,
    /// |R| of the slab at normal incidence, when walls transmit.
    pub normal_incidence_slab_reflection: Option<f64>,
    /// |T| of the slab at normal incidence, when walls transmit.
    pub normal_incidence_slab_transmission: Option<f64>,
    /// Diffuse reflection: `S`, `K_x` and the pattern (docs/radio.md, sec. 4).
    pub scattering: RadioScattering,
}

/// One transmitter's share of a result.
#[derive(Clone, Debug)]
pub struct TransmitterResult {
    /// Transmitter name.
    pub name: String,
    /// Transmit power, mW.
    pub power_mw: f64,
    /// This transmitter's own map (path gain, linear, and ray crossings per cell).
    pub coverage: Coverage,
    /// The surfaces' radio constants at this transmitter's frequency (surfaces in use only).
    pub surfaces: Vec<SurfaceRadio>,
    /// Coherent paths at each receiver of the config, in order.
    pub receivers: Vec<PathSum>,
    /// Reflection order the receiver search used (may be below `max_depth` in large scenes).
    pub receiver_depth: u32,
    /// Wall time of the ray tracing, seconds.
    pub trace_seconds: f64,
    /// Ray segments traced for the map (launches, reflections, transmissions), all processes.
    pub segments: u64,
    /// The first-order diffracted power on the grid (already in `coverage`), when
    /// diffraction is on.
    pub diffraction: Option<diffraction::DiffractionMap>,
    /// Wall time of the diffraction (map and receivers), seconds.
    pub diffraction_seconds: f64,
}

/// A finished simulation.
#[derive(Clone, Debug)]
pub struct RfResult {
    /// Path gain summed over the transmitters (linear) and ray crossings per cell.
    pub coverage: Coverage,
    /// The propagation settings, in words.
    pub settings: PhysicsSettings,
    /// Received power per cell, mW, summed over the transmitters.
    pub rx_power_mw: Vec<f64>,
    /// Each transmitter's share.
    pub transmitters: Vec<TransmitterResult>,
    /// Name of every surface of the scene, by `SurfaceId` (for the paths' interactions).
    pub surface_names: Vec<String>,
    /// Wall time, seconds.
    pub seconds: f64,
}

impl RfResult {
    /// The path gain of every transmitter over the grid, linear, shape (transmitters, ny, nx):
    /// cell `(i, j)` (x index `i`) at `[t, j, i]`, 0 where nothing arrived; the layout of
    /// Sionna RT's `RadioMap.path_gain`. `coverage.npy` holds it.
    pub fn path_gain_array(&self) -> ndarray::Array3<f64> {
        let spec = self.coverage.spec;
        let mut a = ndarray::Array3::zeros((self.transmitters.len(), spec.ny, spec.nx));
        for (t, tr) in self.transmitters.iter().enumerate() {
            for (cell, &g) in tr.coverage.path_gain.iter().enumerate() {
                a[[t, cell / spec.nx, cell % spec.nx]] = g;
            }
        }
        a
    }

    /// The best server of `cell`: the transmitter with the highest received power there
    /// (the first one on a tie), `None` where no transmitter reaches the cell.
    pub fn best_server(&self, cell: usize, noise: &NoiseSpec) -> Option<BestServer> {
        let power = |t: &TransmitterResult| t.power_mw * t.coverage.path_gain[cell];
        let mut best: Option<(usize, f64)> = None;
        for (i, t) in self.transmitters.iter().enumerate() {
            let p = power(t);
            if p > 0.0 && best.is_none_or(|(_, b)| p > b) {
                best = Some((i, p));
            }
        }
        let (index, power_mw) = best?;
        let interference_mw: f64 =
            self.transmitters.iter().enumerate().filter(|&(i, _)| i != index).map(|(_, t)| power(t)).sum();
        Some(BestServer { index, power_mw, sinr: power_mw / (interference_mw + noise.power_mw()) })
    }
}

/// The strongest transmitter at a cell and its signal to interference plus noise ratio.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BestServer {
    /// Index of the transmitter in the config.
    pub index: usize,
    /// Its received power, mW.
    pub power_mw: f64,
    /// `P_best / (sum of the other transmitters' P + N)`, linear: every other transmitter
    /// counts as a co-channel interferer, `N = k T0 B F` ([`NoiseSpec`]).
    pub sinr: f64,
}

/// What a map was computed with, in words: the picture's title and `coverage.json` say it.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PhysicsSettings {
    /// Rays per transmitter.
    pub rays_per_transmitter: u64,
    /// Maximum number of reflections (and transmissions) per ray.
    pub max_depth: u32,
    /// ITU-R P.2040 fits used outside their frequency ranges (`--extrapolate`).
    pub extrapolate: bool,
    /// `on (THICKNESS, SOURCE)` or `off (opaque walls)`.
    pub transmission: String,
    /// `on (first order, UTD, N wedges)` or `off (--no-diffraction)`.
    pub diffraction: String,
    /// `off (S = 0)` or `on (S = ..., PATTERN, SOURCE)`: diffuse reflection (sec. 4).
    pub diffuse_reflection: String,
}

impl PhysicsSettings {
    /// The settings of `config` over `world` (the surfaces in use give the thicknesses).
    pub fn of(world: &World, config: &RfConfig) -> Self {
        let wedges = if config.diffraction { scene_wedges(world).len() } else { 0 };
        Self::with_wedges(world, config, wedges)
    }

    /// [`PhysicsSettings::of`] with the number of diffracting wedges already counted.
    fn with_wedges(world: &World, config: &RfConfig, wedges: usize) -> Self {
        Self {
            rays_per_transmitter: config.rays,
            max_depth: config.max_depth,
            extrapolate: config.extrapolate,
            transmission: transmission_text(world, config),
            diffraction: if config.diffraction {
                format!("on (first order, UTD, {wedges} wedges)")
            } else {
                "off (--no-diffraction)".into()
            },
            diffuse_reflection: diffuse_text(world, config),
        }
    }

    /// One line for a picture's title.
    pub fn line(&self) -> String {
        format!(
            "{} rays/tx, depth {} | transmission {} | diffraction {} | diffuse {} | extrapolate {}",
            self.rays_per_transmitter,
            self.max_depth,
            self.transmission,
            self.diffraction,
            self.diffuse_reflection,
            if self.extrapolate { "on" } else { "off" }
        )
    }
}

/// The diffracting wedges of `world`: every wedge and rim of its mesh, instances included
/// (flattened, [`World::flat_geometry`]), with a free exterior ([`crate::core::wedges`]).
pub fn scene_wedges(world: &World) -> Vec<crate::core::wedges::Wedge> {
    match world.flat_geometry() {
        Some(flat) => wedges_in(&flat.accel, &flat.mesh),
        None => wedges_in(&world.accel, &world.scene.mesh),
    }
}

/// The wedges and rims of `mesh` with a free exterior in the scene traced by `accel`.
fn wedges_in(
    accel: &crate::core::Accel,
    mesh: &crate::core::TriangleMesh,
) -> Vec<crate::core::wedges::Wedge> {
    crate::core::wedges::free_wedges(accel, &crate::core::wedges::extract_wedges(mesh))
}

/// `on (0.1 m slabs, default)` and the like: the walls' thickness and where it comes from.
fn transmission_text(world: &World, config: &RfConfig) -> String {
    if !config.transmission {
        return "off (opaque walls)".into();
    }
    let used = world.scene.used_surfaces();
    let given: Vec<Option<f64>> = used
        .iter()
        .filter_map(|&id| world.scene.surfaces.get(id as usize))
        .map(|s| s.material.as_ref().and_then(|m| m.thickness_m))
        .collect();
    let source = if config.wall_thickness_m.is_some() {
        "--wall-thickness-m"
    } else if given.iter().all(Option::is_none) {
        "default"
    } else if given.iter().all(Option::is_some) {
        "materials' thickness_m"
    } else {
        "materials' thickness_m, else 0.1 m default"
    };
    let thicknesses: Vec<f64> = surface_thicknesses(world, config.wall_thickness_m)
        .into_iter()
        .enumerate()
        .filter(|(id, _)| used.contains(&(*id as u32)))
        .map(|(_, d)| d)
        .collect();
    let lo = thicknesses.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = thicknesses.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let d = config.wall_thickness_m.unwrap_or(config::DEFAULT_WALL_THICKNESS_M);
    if !lo.is_finite() || lo == hi {
        format!("on ({} m slabs, {source})", if lo.is_finite() { lo } else { d })
    } else {
        format!("on ({lo}-{hi} m slabs, {source})")
    }
}

/// `off (S = 0)`, or `on (S = 0.3, lambertian, --scattering-coefficient)` and the like: the
/// surfaces' scattering coefficients in use, their patterns and where `S` comes from.
fn diffuse_text(world: &World, config: &RfConfig) -> String {
    let used = world.scene.used_surfaces();
    let all = surface_scattering(world, config.scattering_coefficient);
    let in_use: Vec<RadioScattering> =
        all.iter().enumerate().filter(|(id, _)| used.contains(&(*id as u32))).map(|(_, s)| *s).collect();
    let lo = in_use.iter().map(|s| s.scattering_coefficient).fold(f64::INFINITY, f64::min);
    let hi = in_use.iter().map(|s| s.scattering_coefficient).fold(f64::NEG_INFINITY, f64::max);
    if hi.is_nan() || hi <= 0.0 {
        return "off (S = 0)".into();
    }
    let source = if config.scattering_coefficient.is_some() {
        "--scattering-coefficient"
    } else {
        "materials' scattering_coefficient"
    };
    let mut patterns: Vec<String> = in_use
        .iter()
        .filter(|s| s.scattering_coefficient > 0.0)
        .map(|s| match s.pattern {
            ScatteringPattern::Lambertian => "lambertian".to_string(),
            ScatteringPattern::Directive { alpha_r } => format!("directive alpha_r {alpha_r}"),
        })
        .collect();
    patterns.sort();
    patterns.dedup();
    let s = if lo == hi { format!("S = {hi}") } else { format!("S = {lo}-{hi}") };
    format!("on ({s}, {}, {source})", patterns.join("/"))
}

/// Runs every transmitter of `config` over `world`; `progress` gets the number of rays done.
pub fn simulate(
    world: &World,
    config: &RfConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> anyhow::Result<RfResult> {
    simulate_on(&Cluster::solo(), world, config, progress)?
        .ok_or_else(|| anyhow::anyhow!("a single process returned no result"))
}

/// [`simulate`] as one process of `cluster`: each launches its share of every transmitter's
/// rays, the cells' fixed-point sums are added exactly on rank 0, and rank 0 alone computes
/// the coherent receivers and returns the result (`None` elsewhere). The result is the same
/// for any number of processes.
pub fn simulate_on(
    cluster: &Cluster,
    world: &World,
    config: &RfConfig,
    progress: &(dyn Fn(u64) + Sync),
) -> anyhow::Result<Option<RfResult>> {
    let start = std::time::Instant::now();
    let mut coverage = Coverage::empty(config.grid);
    let mut rx_power_mw = vec![0.0; config.grid.cells()];
    let mut transmitters = Vec::new();
    // The specular paths and the wedges index triangles: with instances they work on the
    // scene flattened into one mesh with its own accelerator ([`World::flat_geometry`]);
    // without, on the world itself. The rays keep the world's two-level accelerator.
    let flat = if cluster.is_root() && (config.diffraction || !config.receivers.is_empty()) {
        world.flat_geometry()
    } else {
        None
    };
    let (paths_accel, paths_mesh) =
        flat.as_ref().map_or((&world.accel, &world.scene.mesh), |f| (&f.accel, &f.mesh));
    let planes = if config.receivers.is_empty() { Planes::default() } else { Planes::of(paths_mesh) };
    // Diffraction is computed by the root alone, after the rays' sums are reduced.
    let wedges =
        if config.diffraction && cluster.is_root() { wedges_in(paths_accel, paths_mesh) } else { Vec::new() };
    for (ti, tx) in config.transmitters.iter().enumerate() {
        let eta =
            surface_permittivities(world, tx.freq_ghz, config.extrapolate).map_err(anyhow::Error::msg)?;
        let wavelength_m = C0 / (tx.freq_ghz * 1e9);
        let physics = SurfacePhysics {
            eta,
            slab_thickness_m: config
                .transmission
                .then(|| surface_thicknesses(world, config.wall_thickness_m)),
            wavelength_m,
            scattering: surface_scattering(world, config.scattering_coefficient),
            table: None,
        }
        .tabulated();
        let t0 = std::time::Instant::now();
        let mut tx_cov = None;
        let mut segments = [0u64];
        if config.rays > 0 {
            let grid = CoverageAccumulator::new(config.grid);
            let prop = RadioPropagation { antenna: tx.antenna, physics: &physics, grid: &grid };
            let launch = Launch {
                origin: tx.position.as_vec3(),
                rays: config.rays,
                seed: config.seed,
                domain: ti as u64,
                pattern: LaunchPattern::Fibonacci,
                max_reflections: config.max_depth,
                max_path_m: config.max_path_m as f32,
            };
            segments[0] =
                launcher::launch_share(&world.accel, &prop, &launch, cluster.share(), progress).segments;
            cluster.sum_u64(&mut segments);
            let mut totals = grid.totals();
            cluster.sum_u64(&mut totals.sum);
            cluster.sum_u32(&mut totals.paths);
            tx_cov = Some(totals.finish(config.rays, wavelength_m));
        }
        if !cluster.is_root() {
            continue;
        }
        let trace_seconds = t0.elapsed().as_secs_f64();
        let t1 = std::time::Instant::now();
        let diffracted = config.diffraction.then(|| {
            diffraction::coverage(&world.accel, &wedges, &physics, &tx.antenna, tx.position, &config.grid)
        });
        if let Some(d) = &diffracted {
            let c = tx_cov.get_or_insert_with(|| Coverage::empty(config.grid));
            for (g, dg) in c.path_gain.iter_mut().zip(&d.path_gain) {
                *g += dg;
            }
        }
        let p_mw = 10f64.powf(tx.power_dbm / 10.0);
        if let Some(c) = &tx_cov {
            for (acc, g) in rx_power_mw.iter_mut().zip(&c.path_gain) {
                *acc += p_mw * g;
            }
            coverage.add(c);
        }
        let receiver_depth = affordable_order(planes.len(), config.max_depth);
        let receivers = config
            .receivers
            .iter()
            .map(|r| {
                let mut sum = coherent_paths(
                    paths_accel,
                    &planes,
                    &physics,
                    &tx.antenna,
                    tx.position,
                    r.position,
                    receiver_depth,
                );
                if config.diffraction {
                    let d = diffraction::paths(
                        &world.accel,
                        &wedges,
                        &physics,
                        &tx.antenna,
                        tx.position,
                        r.position,
                    );
                    add_paths(&mut sum, d);
                }
                sum
            })
            .collect();
        let diffraction_seconds = if config.diffraction { t1.elapsed().as_secs_f64() } else { 0.0 };
        let surfaces = world
            .scene
            .surfaces
            .iter()
            .zip(&physics.eta)
            .enumerate()
            .filter_map(|(id, (s, eta))| {
                let thickness = physics.slab_thickness_m.as_ref().and_then(|t| t.get(id).copied());
                eta.map(|e| {
                    let slab = thickness.map(|d| fresnel::slab(e, 1.0, d, wavelength_m));
                    SurfaceRadio {
                        surface: s.name.clone(),
                        material: s.material.as_ref().map(|m| m.name.clone()),
                        eta_re: e.re,
                        eta_im: e.im,
                        normal_incidence_reflection: fresnel::reflection(e, 1.0).0.abs(),
                        thickness_m: thickness,
                        normal_incidence_slab_reflection: slab.map(|c| c.r_te.abs()),
                        normal_incidence_slab_transmission: slab.map(|c| c.t_te.abs()),
                        scattering: physics.scattering(id as u32),
                    }
                })
            })
            .collect();
        transmitters.push(TransmitterResult {
            name: tx.name.clone(),
            power_mw: p_mw,
            coverage: tx_cov.unwrap_or_else(|| Coverage::empty(config.grid)),
            surfaces,
            receivers,
            receiver_depth,
            trace_seconds,
            segments: segments[0],
            diffraction: diffracted,
            diffraction_seconds,
        });
    }
    if !cluster.is_root() {
        return Ok(None);
    }
    let surface_names = world.scene.surfaces.iter().map(|s| s.name.clone()).collect();
    Ok(Some(RfResult {
        coverage,
        settings: PhysicsSettings::with_wedges(world, config, wedges.len()),
        rx_power_mw,
        transmitters,
        surface_names,
        seconds: start.elapsed().as_secs_f64(),
    }))
}

/// Adds the paths `records` (diffracted, one interaction each) to the coherent sum `sum`.
fn add_paths(sum: &mut PathSum, records: Vec<receivers::PathRecord>) {
    if records.is_empty() {
        return;
    }
    for r in records {
        sum.paths += 1;
        sum.path_orders.push(r.interactions.len());
        sum.path_lengths_m.push(r.length_m);
        sum.incoherent_gain += r.field.power();
        sum.records.push(r);
    }
    let total = sum.records.iter().fold(propagation::FieldVec::default(), |t, r| t.add(&r.field));
    sum.coherent_gain = total.power();
}

/// A point receiver of the coherent mode.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PointReceiver {
    /// Name.
    pub name: String,
    /// Position, metres.
    pub position: DVec3,
}
