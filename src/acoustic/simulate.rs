//! One acoustic simulation: rays and image sources for every source, histograms and
//! parameters for every source-receiver pair.

use glam::Vec3;
use serde::Serialize;

use super::air::Air;
use super::diffraction::{edge_arrivals, room_edges};
use super::directions::{CELLS, DirectionBins};
use super::directivity::Directivity;
use super::edge_scattering::EdgeScattering;
use super::image_source::{Arrival, specular_arrivals_from};
use super::metrics::{BandMetrics, band_metrics_for_source, pair_warnings};
use super::ray_diffraction::RayDiffraction;
use super::room::reverberation_times;
use super::spatial::Listener;
use super::tracer::{SoundPropagation, Splitting, SurfaceAcoustics, TraceRecord};
use crate::core::fixed::from_fixed;
use crate::core::launcher::{Launch, LaunchPattern, launch_share};
use crate::core::specular::{Planes, affordable_order};
use crate::core::visibility::triangles_in_full_view;
use crate::core::{Sphere, TimeBins};
use crate::dist::Cluster;
use crate::scene::World;
use crate::scene::materials::{BAND_COUNT, OCTAVE_BANDS_HZ};

/// The longest decay simulated, s: a ray still alive after this long stops.
pub const MAX_SIMULATED_S: f64 = 60.0;

/// The default [`AcousticSettings::split_copies`].
pub const SPLIT_COPIES: u32 = 32;

/// A ray splits once it carries this many times the energy the room's statistical decay
/// leaves an average ray, into copies of four times that energy (docs/acoustics.md, Ray
/// splitting: of the settings tried, these three kept the showcase's decay curves smooth
/// and near the reference while adding least to BRAS CR2, whose late rays outlive Eyring's
/// decay and would otherwise split all the time).
pub const SPLIT_ABOVE: f32 = 16.0;
/// See [`SPLIT_ABOVE`].
pub const SPLIT_TO: f32 = 4.0;

/// Energy per band of one histogram bin.
pub type BandEnergies = [f64; BAND_COUNT];

/// A point source. Its energy (power times 1 s) sets the scale of the histograms.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SourceSpec {
    /// Name.
    pub name: String,
    /// Position, metres.
    pub position: [f32; 3],
    /// Acoustic power, W.
    pub power_w: f64,
    /// How the source radiates ([`Directivity::OMNI`]: alike in every direction); its power
    /// stays `power_w` whatever the pattern (docs/acoustics.md, Directivity).
    pub directivity: Directivity,
}

/// A sphere receiver; `radius_m: None` takes the default rule of [`default_receiver_radius_m`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReceiverSpec {
    /// Name.
    pub name: String,
    /// Centre, metres.
    pub position: [f32; 3],
    /// Sphere radius, metres.
    pub radius_m: Option<f32>,
    /// The listener's head (where it looks, which way is up) for the Ambisonic and binaural
    /// responses; the default looks along +x with +z up.
    #[serde(skip)]
    pub listener: Listener,
    /// How the receiver hears: a directional microphone's pattern per band, its squared gain
    /// weighting every arrival by the direction it comes from
    /// ([`Directivity::sensitivity`], 1 on the axis); [`Directivity::OMNI`] by default.
    pub directivity: Directivity,
}

/// Simulation settings.
#[derive(Clone, Debug, Serialize)]
pub struct AcousticSettings {
    /// Rays per source.
    pub rays: u64,
    /// Seed of the random number generator.
    pub seed: u64,
    /// Length of the histograms, s. `None` (the default): as long as the traced energy
    /// lasts, so every decay runs to its end (rays stop only by Russian roulette, see
    /// `roulette_db`), up to [`MAX_SIMULATED_S`].
    pub max_time_s: Option<f64>,
    /// Histogram bin width, seconds (1 ms).
    pub bin_s: f64,
    /// The air (temperature, humidity, pressure).
    pub air: Air,
    /// Whether air absorption (ISO 9613-1) is applied.
    pub air_absorption: bool,
    /// Highest image-source order (0: direct sound only; rays do the rest).
    pub ism_order: u32,
    /// Image sources replace the rays' early specular paths; `false` traces everything with
    /// rays (used to test the ray estimator itself).
    pub use_image_sources: bool,
    /// Diffuse rain: every reflection sends its diffusely scattered energy straight to the
    /// receivers in view (far less noise in diffuse rooms; `false` counts crossing rays only).
    pub diffuse_rain: bool,
    /// A ray plays Russian roulette once every band has lost this many dB (air included):
    /// weak rays survive with a probability proportional to their energy, so the decay's
    /// expected value is exact to its end while the tail costs little (20 to 120 dB).
    pub roulette_db: f64,
    /// Ray splitting (docs/acoustics.md, Ray splitting): a launched ray may become at most
    /// this many copies, each of a share of its energy, where it keeps far more energy than
    /// the room's average decay leaves (1: no splitting).
    pub split_copies: u32,
    /// Edge diffraction where the room has free edges: the direct sound's first-order edge
    /// paths ([`super::diffraction`]) and the scattering of finite panels
    /// ([`super::edge_scattering`]).
    pub diffraction: bool,
    /// Rays passing near free edges are bent ([`super::ray_diffraction`]): after their first
    /// reflection while `diffraction`'s edge paths (with image sources) cover the direct
    /// sound, from the source otherwise; never while a ray is still an image-source path.
    /// On by default (docs/acoustics.md, Edge diffraction: its cost and its noise).
    pub ray_diffraction: bool,
    /// Order of the Ambisonic impulse responses to make (1 to 3; 0: none). Any order, or
    /// `binaural`, keeps the directions of arrival ([`PairResult::directions`]).
    pub ambisonic_order: u32,
    /// Whether to make binaural impulse responses (the built-in spherical head, or `hrtf`).
    pub binaural: bool,
    /// A SOFA file of measured HRIRs for the binaural responses (`None`: the spherical head).
    pub hrtf: Option<std::path::PathBuf>,
}

/// Length of the direction bins, s: the directional energy is kept in bins of about 10 ms
/// for the first [`DIRECTION_EARLY_S`] and of [`DIRECTION_LATE_BIN_S`] after it
/// (docs/acoustics.md, Directions of arrival): fine where the early reflections' directions
/// change, coarse in the near-diffuse tail, so that the record the rays deposit into stays
/// small (with 10 ms bins throughout, BRAS CR2's 11 s decays made it 4 MB a receiver, and the
/// deposits' cache misses cost 20 % of the run).
pub const DIRECTION_BIN_S: f64 = 0.01;
/// See [`DIRECTION_BIN_S`].
pub const DIRECTION_EARLY_S: f64 = 0.2;
/// See [`DIRECTION_BIN_S`].
pub const DIRECTION_LATE_BIN_S: f64 = 0.1;

impl AcousticSettings {
    /// Whether the simulation keeps directions of arrival.
    pub fn keeps_directions(&self) -> bool {
        self.ambisonic_order > 0 || self.binaural
    }

    /// The direction bins in histogram bins ([`DIRECTION_BIN_S`]).
    pub fn direction_bins(&self) -> DirectionBins {
        let bins = |s: f64| ((s / self.bin_s).round() as usize).max(1);
        let fine = bins(DIRECTION_BIN_S);
        DirectionBins {
            fine,
            early: (bins(DIRECTION_EARLY_S) / fine).max(1),
            coarse: bins(DIRECTION_LATE_BIN_S),
        }
    }
}

impl Default for AcousticSettings {
    fn default() -> Self {
        Self {
            rays: 200_000,
            seed: 1,
            max_time_s: None,
            bin_s: 1e-3,
            air: Air::default(),
            air_absorption: true,
            ism_order: 2,
            use_image_sources: true,
            roulette_db: 30.0,
            diffuse_rain: true,
            split_copies: SPLIT_COPIES,
            diffraction: true,
            ray_diffraction: true,
            ambisonic_order: 0,
            binaural: false,
            hrtf: None,
        }
    }
}

/// Results of one source-receiver pair.
#[derive(Clone, Debug, Serialize)]
pub struct PairResult {
    /// Source name.
    pub source: String,
    /// Receiver name.
    pub receiver: String,
    /// Source-receiver distance, metres.
    pub distance_m: f64,
    /// Arrival time of the direct sound, s (straight-line distance / c).
    pub direct_s: f64,
    /// Energy fluence per bin and band, J/m^2 (the direct sound at distance d contributes
    /// E / (4 pi d^2) for source energy E).
    #[serde(skip)]
    pub histogram: Vec<BandEnergies>,
    /// Room-acoustic metrics per band.
    pub metrics: [BandMetrics; BAND_COUNT],
    /// Image-source paths found (including the direct sound).
    pub specular_paths: usize,
    /// First-order edge-diffracted paths found ([`super::diffraction`]).
    pub diffracted_paths: usize,
    /// Deposits at the receiver recorded in the histogram (ray crossings and diffuse rain).
    pub detections: u64,
    /// The receiver's head (the frame of its Ambisonic and binaural responses).
    #[serde(skip)]
    pub listener: Listener,
    /// Directions of arrival (empty unless [`AcousticSettings::keeps_directions`]): the rays'
    /// energy fluence per direction bin ([`AcousticSettings::direction_bins`]), direction
    /// cell ([`super::directions`]) and band, J/m^2, at index `bin * CELLS + cell`, before air
    /// absorption (it is used for the share of each direction in a bin, which air absorption,
    /// a function of time alone, does not change).
    #[serde(skip)]
    pub directions: Vec<BandEnergies>,
    /// The image-source arrivals (the direct sound first), energies times the source power,
    /// J/m^2, each with its exact direction of arrival.
    #[serde(skip)]
    pub image_sources: Vec<Arrival>,
    /// What the numbers of this pair cannot be trusted for (near source, few detections, a
    /// decay cut short), one sentence each.
    pub warnings: Vec<String>,
}

/// Everything a simulation produces.
#[derive(Clone, Debug, Serialize)]
pub struct AcousticResult {
    /// Octave band centres, Hz.
    pub bands_hz: [f32; BAND_COUNT],
    /// Volume of air, m^3.
    pub volume_m3: f64,
    /// Surface area, m^2.
    pub surface_m2: f64,
    /// Speed of sound, m/s.
    pub speed_of_sound_m_s: f64,
    /// Sabine reverberation time per band, seconds.
    pub sabine_s: [f64; BAND_COUNT],
    /// Eyring reverberation time per band, seconds.
    pub eyring_s: [f64; BAND_COUNT],
    /// Length of the longest histogram, s.
    pub max_time_s: f64,
    /// Histogram bin width, seconds.
    pub bin_s: f64,
    /// Highest image-source order.
    pub ism_order: u32,
    /// Radius of each receiver sphere, metres.
    pub receiver_radii_m: Vec<f32>,
    /// Results of each source-receiver pair.
    pub pairs: Vec<PairResult>,
    /// Ray segments traced (launches and reflections), all sources together.
    pub segments: u64,
    /// Fraction of launched energy that escaped through holes in the mesh.
    pub escaped_energy_fraction: f64,
    /// The settings used.
    pub settings: AcousticSettings,
}

impl AcousticResult {
    /// Every pair's energy histogram as one array of shape (pairs, bands, bins): energy
    /// fluence, J/m^2, per bin of `bin_s` seconds, pairs in the order of `pairs` and bands of
    /// `bands_hz`; a pair whose histogram is shorter than the longest is padded with zeros.
    /// `histogram.npy` holds it.
    pub fn histogram_array(&self) -> ndarray::Array3<f64> {
        let bins = self.pairs.iter().map(|p| p.histogram.len()).max().unwrap_or(0);
        let mut a = ndarray::Array3::zeros((self.pairs.len(), BAND_COUNT, bins));
        for (i, p) in self.pairs.iter().enumerate() {
            for (k, bin) in p.histogram.iter().enumerate() {
                for (b, &e) in bin.iter().enumerate() {
                    a[[i, b, k]] = e;
                }
            }
        }
        a
    }
}

/// The scene file's acoustic sources and receivers, with 1 W where a source gives no power
/// and the default radius rule where a receiver gives none.
pub fn scene_points(world: &World) -> (Vec<SourceSpec>, Vec<ReceiverSpec>) {
    let Some(desc) = &world.scene.desc.acoustic else {
        return (Vec::new(), Vec::new());
    };
    let base_dir = world.scene.path.parent().unwrap_or(std::path::Path::new("."));
    let sources = desc
        .sources
        .iter()
        .map(|p| SourceSpec {
            name: p.name.clone(),
            position: p.position,
            power_w: f64::from(p.power_w.unwrap_or(1.0)),
            // An invalid description is refused by [`super::plan`]
            // ([`super::directivity::scene_directivities`]); here it falls back to omni.
            directivity: super::directivity::from_point(p, base_dir).unwrap_or_default(),
        })
        .collect();
    let receivers = desc
        .receivers
        .iter()
        .map(|p| ReceiverSpec {
            name: p.name.clone(),
            position: p.position,
            radius_m: p.radius_m,
            // An invalid head is refused by [`super::plan`]; here it falls back to the default.
            listener: scene_listener(p).unwrap_or_default(),
            directivity: super::directivity::from_point(p, base_dir).unwrap_or_default(),
        })
        .collect();
    (sources, receivers)
}

/// The listener of a scene-file receiver: `orientation` the direction it looks (+x when
/// absent), `up` the top of its head (+z when absent). The error is one line.
pub fn scene_listener(p: &crate::scene::desc::PointDesc) -> Result<Listener, String> {
    Listener::looking(p.orientation.unwrap_or([1.0, 0.0, 0.0]), p.up.unwrap_or([0.0, 0.0, 1.0]))
}

/// Default receiver radius: about a hundred ray detections per 1 ms bin once the sound field
/// is diffuse, r = sqrt(100 V / (pi N c dt)), within 0.05 m to 0.5 m. (With ten, the
/// specular shoebox of docs/acoustics.md gave T30 1.015, 1.028 and 1.054 s for three seeds
/// at 10^6 rays; with a hundred 1.009 to 1.019 s, the exact value being 1.014 s.)
pub fn default_receiver_radius_m(volume_m3: f64, rays: u64, speed_m_s: f64, bin_s: f64) -> f32 {
    let r = (100.0 * volume_m3 / (std::f64::consts::PI * rays.max(1) as f64 * speed_m_s * bin_s)).sqrt();
    r.clamp(0.05, 0.5) as f32
}

/// The acoustic data of every surface, or an error listing the surfaces that have none.
pub fn surface_acoustics(world: &World) -> Result<Vec<SurfaceAcoustics>, String> {
    let mut missing = Vec::new();
    let surfaces: Vec<SurfaceAcoustics> = world
        .scene
        .surfaces
        .iter()
        .map(|s| match s.material.as_ref().and_then(|m| m.acoustic.as_ref()) {
            Some(a) => SurfaceAcoustics { absorption: a.absorption, scattering: a.scattering },
            None => {
                missing.push(s.name.clone());
                SurfaceAcoustics { absorption: [0.0; BAND_COUNT], scattering: [0.0; BAND_COUNT] }
            }
        })
        .collect();
    if !missing.is_empty() {
        return Err(format!(
            "surfaces without acoustic data (absorption): {}; map them to library materials in [surfaces] or give a materials file",
            missing.join(", ")
        ));
    }
    Ok(surfaces)
}

/// The room's air volume, m^3, without the spheres inside it, and those spheres (they take
/// up air and add their surface); an error when the mesh encloses no air or the spheres fill it.
fn air_volume(world: &World) -> Result<(f64, Vec<&Sphere>), String> {
    let mesh_air_m3 = world.report.air_volume_m3.ok_or(NO_AIR)?;
    let spheres_in_air: Vec<&Sphere> =
        world.scene.spheres.iter().filter(|s| world.is_inside(s.center) != Some(false)).collect();
    let volume_m3 = mesh_air_m3
        - spheres_in_air
            .iter()
            .map(|s| 4.0 / 3.0 * std::f64::consts::PI * f64::from(s.radius_m).powi(3))
            .sum::<f64>();
    if volume_m3.is_nan() || volume_m3 <= 0.0 {
        return Err(format!("the spheres fill the room's {mesh_air_m3:.3} m^3 of air"));
    }
    Ok((volume_m3, spheres_in_air))
}

/// Why room acoustics cannot run on a mesh that encloses no volume (an open or outdoor scene).
pub const NO_AIR: &str = "the scene encloses no air: room acoustics needs a closed room";

/// Whether room acoustics can run in `world` at all, before any source or receiver is
/// known: a closed room with air beside its spheres, and acoustic data on every surface.
/// The error is a one-line reason.
pub fn check(world: &World) -> Result<(), String> {
    air_volume(world)?;
    surface_acoustics(world)?;
    Ok(())
}

/// Whether every source and receiver is usable: a finite position inside the room, clear of
/// its surfaces and outside its spheres. The error is a one-line reason naming the point.
pub fn check_points(world: &World, sources: &[SourceSpec], receivers: &[ReceiverSpec]) -> Result<(), String> {
    for (kind, name, p) in sources
        .iter()
        .map(|s| ("source", &s.name, s.position))
        .chain(receivers.iter().map(|r| ("receiver", &r.name, r.position)))
    {
        let v = Vec3::from(p);
        if !v.is_finite() {
            return Err(format!("{kind} \"{name}\" has a non-finite position"));
        }
        if world.is_inside(v) == Some(false) {
            return Err(format!("{kind} \"{name}\" at ({}, {}, {}) is outside the room", v.x, v.y, v.z));
        }
        world.check_clearance(&format!("{kind} \"{name}\""), v)?;
        if let Some(s) = world.scene.spheres.iter().find(|s| s.contains(v)) {
            return Err(format!(
                "{kind} \"{name}\" at ({}, {}, {}) is inside the sphere of material \"{}\" at ({}, {}, {})",
                v.x,
                v.y,
                v.z,
                world.scene.surfaces.get(s.surface as usize).map_or("?", |x| x.name.as_str()),
                s.center.x,
                s.center.y,
                s.center.z
            ));
        }
    }
    Ok(())
}

/// Runs the simulation. Errors are one-line messages about the scene or settings.
pub fn simulate(
    world: &World,
    sources: &[SourceSpec],
    receivers: &[ReceiverSpec],
    settings: &AcousticSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<AcousticResult, String> {
    simulate_on(&Cluster::solo(), world, sources, receivers, settings, progress)?
        .ok_or_else(|| "a single process returned no result".into())
}

/// [`simulate`] as one process of `cluster`: each traces its share of every source's rays,
/// the histograms are summed exactly on rank 0, and rank 0 alone adds the image sources and
/// returns the result (`None` elsewhere). The result is the same for any number of processes.
pub fn simulate_on(
    cluster: &Cluster,
    world: &World,
    sources: &[SourceSpec],
    receivers: &[ReceiverSpec],
    settings: &AcousticSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Option<AcousticResult>, String> {
    settings.air.validate()?;
    if sources.is_empty() || receivers.is_empty() {
        return Err("room acoustics needs at least one source and one receiver".into());
    }
    if !(1..=1_000_000_000).contains(&settings.rays) {
        return Err(format!("{} rays: must be between 1 and 10^9", settings.rays));
    }
    if !(settings.bin_s > 0.0 && settings.bin_s <= 0.1) {
        return Err(format!("histogram bin {} s: must be in (0, 0.1]", settings.bin_s));
    }
    if settings.ambisonic_order > 3 {
        return Err(format!("Ambisonic order {}: must be 1 to 3 (0: none)", settings.ambisonic_order));
    }
    if !(20.0..=120.0).contains(&settings.roulette_db) {
        return Err(format!("roulette level {} dB: must be between 20 and 120 dB", settings.roulette_db));
    }
    let scene = &world.scene;
    let report = &world.report;
    let (volume_m3, spheres_in_air) = air_volume(world)?;
    let surfaces = surface_acoustics(world)?;
    let c = settings.air.speed_of_sound_m_s();
    let air_per_m =
        if settings.air_absorption { settings.air.energy_coefficient_per_m() } else { [0.0; BAND_COUNT] };
    let absorption: Vec<_> = surfaces.iter().map(|s| s.absorption).collect();
    let mut areas = report.area_by_surface_m2.clone();
    areas.resize(surfaces.len(), 0.0);
    for s in &spheres_in_air {
        if let Some(a) = areas.get_mut(s.surface as usize) {
            *a += 4.0 * std::f64::consts::PI * f64::from(s.radius_m).powi(2);
        }
    }
    let (sabine_s, eyring_s) = reverberation_times(volume_m3, &areas, &absorption, &air_per_m, c);
    // Copies part ways only where a surface scatters: in a purely specular room they would
    // retrace their ray's path (and there a ray's energy follows its direction's reflection
    // rate, so many would split).
    let scatters = surfaces.iter().any(|s| s.scattering.iter().any(|&x| x > 0.0));
    let splitting = (settings.split_copies > 1 && scatters).then(|| {
        let total_area: f64 = areas.iter().sum();
        let per_reflection_m = total_area / (4.0 * volume_m3);
        Splitting {
            decay_per_m: std::array::from_fn(|b| {
                let a: f64 = areas.iter().zip(&absorption).map(|(s, a)| s * f64::from(a[b])).sum();
                let mean = (a / total_area).min(1.0 - 1e-6);
                (-(1.0 - mean).ln() * per_reflection_m) as f32
            }),
            above: SPLIT_ABOVE,
            to: SPLIT_TO,
            copies: settings.split_copies,
        }
    });
    let limit_s = settings.max_time_s.unwrap_or(MAX_SIMULATED_S);
    if !(limit_s > 0.0 && limit_s <= MAX_SIMULATED_S) {
        return Err(format!("maximum time {limit_s} s: must be in (0, {MAX_SIMULATED_S}]"));
    }
    let bin_limit = (limit_s / settings.bin_s).ceil() as usize;
    let time_bins = TimeBins { speed_m_s: c, bin_s: settings.bin_s, bins: bin_limit };

    check_points(world, sources, receivers)?;
    let radius_default = default_receiver_radius_m(volume_m3, settings.rays, c, settings.bin_s);
    let mut spheres = Vec::new();
    for r in receivers {
        let radius = r.radius_m.unwrap_or(radius_default);
        if !(radius.is_finite() && radius > 0.0 && radius < 100.0) {
            return Err(format!("receiver \"{}\" radius {radius} m: must be in (0, 100)", r.name));
        }
        spheres.push(Sphere::new(Vec3::from(r.position), radius, 0));
    }

    let (lo, hi) = scene.mesh.bounds().ok_or("the scene is empty")?;
    let margin = Vec3::splat(1e-3 * (1.0 + (hi - lo).max_element()));
    // The deterministic engines (image sources, edges) index planes and wedges by triangle:
    // with instances they work on the scene flattened into one mesh, with its own
    // accelerator; without, on the world itself (the same code path as ever).
    let flat = world.flat_geometry();
    let (paths_accel, paths_mesh) =
        flat.as_ref().map_or((&world.accel, &scene.mesh), |f| (&f.accel, &f.mesh));
    let planes = if settings.use_image_sources && settings.ism_order > 0 {
        Planes::of(paths_mesh)
    } else {
        Planes::default()
    };
    let ism_order =
        if settings.use_image_sources { affordable_order(planes.len(), settings.ism_order) } else { 0 };
    // The free edges that diffract (none in a closed box: its edges are concave seen from
    // the air), and the finite panels they bound, which scatter by diffraction.
    let edges = if settings.diffraction || settings.ray_diffraction {
        room_edges(world, paths_accel, paths_mesh)
    } else {
        Vec::new()
    };
    let wedges = if settings.diffraction { edges.clone() } else { Vec::new() };
    let mean_free_path_m = 4.0 * volume_m3 / areas.iter().sum::<f64>();
    let edge_scattering = EdgeScattering::of(paths_mesh, &wedges, c, mean_free_path_m);
    let edge_paths = settings.diffraction && settings.use_image_sources;
    let ray_diffraction = if settings.ray_diffraction {
        RayDiffraction::new(&edges, paths_mesh, c, u32::from(edge_paths))
    } else {
        None
    };
    // Which triangles each receiver sees whole: their rain needs no occlusion ray.
    let rain_in_view: Vec<Option<Vec<crate::core::visibility::PartsInView>>> = if settings.diffuse_rain {
        spheres.iter().map(|r| triangles_in_full_view(&scene.mesh, &scene.spheres, r.center)).collect()
    } else {
        Vec::new()
    };
    // The receivers' directivities (`None`: omni, no weights to apply).
    let receiver_directivity: Vec<Option<Directivity>> = receivers
        .iter()
        .map(|r| {
            r.directivity.validate().map_err(|e| format!("receiver \"{}\": {e}", r.name))?;
            Ok((!r.directivity.is_omni()).then(|| r.directivity.clone()))
        })
        .collect::<Result<_, String>>()?;
    let mut pairs = Vec::new();
    let mut escaped = 0.0;
    let mut segments = 0u64;
    for (si, source) in sources.iter().enumerate() {
        if !(source.power_w.is_finite() && source.power_w > 0.0) {
            return Err(format!("source \"{}\" power {} W: must be > 0", source.name, source.power_w));
        }
        source.directivity.validate().map_err(|e| format!("source \"{}\": {e}", source.name))?;
        let directivity = (!source.directivity.is_omni()).then(|| source.directivity.clone());
        let prop = SoundPropagation {
            surfaces: &surfaces,
            receivers: &spheres,
            ray_energy_j: (1.0 / settings.rays as f64) as f32,
            air_per_m,
            bins: time_bins,
            skip_specular_up_to: settings.use_image_sources.then_some(ism_order),
            roulette_factor: 10f64.powf(-settings.roulette_db / 10.0) as f32,
            scene_bounds: (lo - margin, hi + margin),
            diffuse_rain: settings.diffuse_rain.then_some(&world.accel),
            splitting,
            rain_in_view: &rain_in_view,
            directivity,
            directions: settings.keeps_directions().then(|| settings.direction_bins()),
            edge_scattering: edge_scattering.as_ref(),
            receiver_directivity: &receiver_directivity,
            ray_diffraction: ray_diffraction.as_ref(),
        };
        let launch_spec = Launch {
            origin: Vec3::from(source.position),
            rays: settings.rays,
            seed: settings.seed,
            domain: si as u64,
            pattern: LaunchPattern::Fibonacci,
            max_reflections: u32::MAX,
            max_path_m: (limit_s * c) as f32,
        };
        let record: TraceRecord = launch_share(&world.accel, &prop, &launch_spec, cluster.share(), progress);
        // Image-source paths (the direct sound is order 0), found on rank 0 only.
        let src = Vec3::from(source.position);
        let paths_of: Vec<Vec<_>> = if cluster.is_root() && settings.use_image_sources {
            receivers
                .iter()
                .map(|r| {
                    let rcv = Vec3::from(r.position);
                    let mut arrivals = specular_arrivals_from(
                        paths_accel,
                        &planes,
                        &surfaces,
                        edge_scattering.as_ref(),
                        &air_per_m,
                        (src, &source.directivity),
                        rcv,
                        ism_order,
                    );
                    let sensitivity = |arrivals: &mut Vec<Arrival>| {
                        if !r.directivity.is_omni() {
                            for a in arrivals {
                                let w = r.directivity.sensitivity(glam::DVec3::from(a.incoming).as_vec3());
                                a.energy = std::array::from_fn(|b| a.energy[b] * f64::from(w[b]));
                            }
                        }
                    };
                    if !wedges.is_empty() && settings.use_image_sources {
                        let direct = arrivals.iter_mut().find(|a| a.order == 0);
                        let diffracted = edge_arrivals(
                            paths_accel,
                            &wedges,
                            &surfaces,
                            &air_per_m,
                            c,
                            (src, &source.directivity),
                            rcv,
                            direct,
                        );
                        arrivals.extend(diffracted);
                    }
                    // (After the coherent sums of the direct and diffracted sound, whose
                    // directions nearly agree wherever their cross term matters.)
                    sensitivity(&mut arrivals);
                    arrivals
                })
                .collect()
        } else {
            vec![Vec::new(); receivers.len()]
        };
        let image_bins = paths_of
            .iter()
            .flatten()
            .filter_map(|p| time_bins.bin_of_path(p.length_m))
            .map(|b| b + 1)
            .max()
            .unwrap_or(0);
        // The histogram reaches the last arrival of any process, ray or image source: every
        // process must know that length before the sums.
        let last = cluster.max_u64_everywhere((record.bins() as u64).max(image_bins as u64));
        let bins = (last as usize).min(bin_limit).max(1);
        let unit = f64::from(prop.ray_energy_j);
        let mut fixed = vec![0u128; receivers.len() * bins * BAND_COUNT];
        for (r, hist) in record.fixed.iter().enumerate() {
            for (k, e) in hist.iter().enumerate().take(bins) {
                let at = (r * bins + k) * BAND_COUNT;
                fixed[at..at + BAND_COUNT].copy_from_slice(e);
            }
        }
        let mut detections = record.detections.clone();
        drop(record.fixed);
        // The directions, summed like the histograms over the bins every process shares.
        let dir_bins = if settings.keeps_directions() { settings.direction_bins().count(bins) } else { 0 };
        let mut dir_fixed = vec![0u128; receivers.len() * dir_bins * CELLS * BAND_COUNT];
        for (r, dirs) in record.dir_fixed.iter().enumerate() {
            for (k, e) in dirs.iter().enumerate().take(dir_bins * CELLS) {
                let at = (r * dir_bins * CELLS + k) * BAND_COUNT;
                dir_fixed[at..at + BAND_COUNT].copy_from_slice(e);
            }
        }
        drop(record.dir_fixed);
        cluster.sum_u128(&mut dir_fixed);
        let mut counts = [record.segments, record.rays_escaped];
        cluster.sum_u64(&mut counts);
        segments += counts[0];
        let mut escaped_fixed = record.escaped.to_vec();
        cluster.sum_u128(&mut fixed);
        cluster.sum_u128(&mut escaped_fixed);
        cluster.sum_u64(&mut detections);
        if !cluster.is_root() {
            continue;
        }
        escaped += escaped_fixed.iter().map(|&e| from_fixed(e, unit)).sum::<f64>() / BAND_COUNT as f64;
        // Air absorption depends on the path length alone: it is applied bin by bin at the
        // bin's middle (within exp(+-m c dt / 2) of each arrival's own path, 0.4 % at 8 kHz,
        // and exact on average over a bin to second order).
        let air_of_bin: Vec<BandEnergies> = (0..bins)
            .map(|k| {
                let l = (k as f64 + 0.5) * settings.bin_s * c;
                std::array::from_fn(|b| (-f64::from(air_per_m[b]) * l).exp())
            })
            .collect();
        let mut histograms: Vec<Vec<BandEnergies>> = fixed
            .chunks_exact(bins * BAND_COUNT)
            .map(|r| {
                r.chunks_exact(BAND_COUNT)
                    .zip(&air_of_bin)
                    .map(|(b, air)| std::array::from_fn(|k| from_fixed(b[k], unit) * air[k]))
                    .collect()
            })
            .collect();
        drop(fixed);
        let bins_here = TimeBins { bins, ..time_bins };
        for (ri, r) in receivers.iter().enumerate() {
            let rcv = Vec3::from(r.position);
            let paths = &paths_of[ri];
            for p in paths {
                let Some(bin) = bins_here.bin_of_path(p.length_m) else { continue };
                for (h, e) in histograms[ri][bin].iter_mut().zip(p.energy) {
                    *h += e;
                }
            }
            let hist: Vec<BandEnergies> =
                histograms[ri].iter().map(|h| h.map(|e| e * source.power_w)).collect();
            let distance_m = f64::from((rcv - src).length());
            let direct_s = distance_m / c;
            let mut metrics = [BandMetrics::default(); BAND_COUNT];
            for (b, m) in metrics.iter_mut().enumerate() {
                let band: Vec<f64> = hist.iter().map(|h| h[b]).collect();
                *m = band_metrics_for_source(&band, settings.bin_s, direct_s, source.power_w);
            }
            // Detections are judged over the range T30 uses (to -35 dB at 1 kHz), or the
            // whole histogram when there is no T30.
            let span_s =
                metrics[4].t30_s.map_or(hist.len() as f64 * settings.bin_s - direct_s, |t| t * 35.0 / 60.0);
            let mut warnings = pair_warnings(distance_m, detections[ri], span_s);
            let short: Vec<String> = metrics
                .iter()
                .zip(OCTAVE_BANDS_HZ)
                .filter(|(m, _)| m.t30_s.is_none())
                .map(|(_, hz)| format!("{hz} Hz"))
                .collect();
            if !short.is_empty() {
                warnings.push(format!(
                    "the decay did not reach 35 dB at {} ({}): no T30 there",
                    short.join(", "),
                    match settings.max_time_s {
                        Some(t) => format!("--max-time-s {t} cut it off"),
                        None => "too few rays or too much noise".to_string(),
                    }
                ));
            }
            let directions: Vec<BandEnergies> = dir_fixed
                [ri * dir_bins * CELLS * BAND_COUNT..(ri + 1) * dir_bins * CELLS * BAND_COUNT]
                .chunks_exact(BAND_COUNT)
                .map(|e| std::array::from_fn(|b| from_fixed(e[b], unit) * source.power_w))
                .collect();
            let image_sources = paths
                .iter()
                .map(|p| Arrival { energy: p.energy.map(|e| e * source.power_w), ..p.clone() })
                .collect();
            pairs.push(PairResult {
                listener: r.listener,
                directions,
                image_sources,
                source: source.name.clone(),
                receiver: r.name.clone(),
                distance_m,
                direct_s,
                histogram: hist,
                metrics,
                specular_paths: paths.iter().filter(|a| !a.diffracted).count(),
                diffracted_paths: paths.iter().filter(|a| a.diffracted).count(),
                detections: detections[ri],
                warnings,
            });
        }
    }
    if !cluster.is_root() {
        return Ok(None);
    }
    Ok(Some(AcousticResult {
        bands_hz: OCTAVE_BANDS_HZ,
        volume_m3,
        surface_m2: areas.iter().sum(),
        speed_of_sound_m_s: c,
        sabine_s,
        eyring_s,
        max_time_s: pairs.iter().map(|p| p.histogram.len()).max().unwrap_or(0) as f64 * settings.bin_s,
        bin_s: settings.bin_s,
        ism_order,
        receiver_radii_m: spheres.iter().map(|s| s.radius_m).collect(),
        pairs,
        segments,
        escaped_energy_fraction: escaped / sources.len() as f64,
        settings: settings.clone(),
    }))
}
