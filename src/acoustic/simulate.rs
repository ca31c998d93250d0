//! One acoustic simulation: rays and image sources for every source, histograms and
//! parameters for every source-receiver pair.

use glam::Vec3;
use serde::Serialize;

use super::air::Air;
use super::image_source::specular_arrivals;
use super::metrics::{BandMetrics, band_metrics};
use super::room::reverberation_times;
use super::tracer::{SoundPropagation, SurfaceAcoustics, TraceRecord};
use crate::core::fixed::{add_fixed, from_fixed};
use crate::core::launcher::{Launch, LaunchPattern, launch_share};
use crate::core::specular::{Planes, affordable_order};
use crate::core::{Sphere, TimeBins};
use crate::dist::Cluster;
use crate::scene::World;
use crate::scene::materials::{BAND_COUNT, OCTAVE_BANDS_HZ};

/// Energy per band of one histogram bin.
pub type BandEnergies = [f64; BAND_COUNT];

/// A point source. Its energy (power times 1 s) sets the scale of the histograms.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SourceSpec {
    pub name: String,
    pub position: [f32; 3],
    pub power_w: f64,
}

/// A sphere receiver; `radius_m: None` takes the default rule of [`default_receiver_radius_m`].
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct ReceiverSpec {
    pub name: String,
    pub position: [f32; 3],
    pub radius_m: Option<f32>,
}

/// Simulation settings.
#[derive(Clone, Debug, Serialize)]
pub struct AcousticSettings {
    /// Rays per source.
    pub rays: u64,
    pub seed: u64,
    /// Length of the histograms; default 1.2 x the longest Eyring time (0.2 s to 20 s): the
    /// decay has then fallen about 60 dB, so the truncated Schroeder integral is exact to
    /// well below the -35 dB that T30 needs.
    pub max_time_s: Option<f64>,
    /// Histogram bin width, seconds (1 ms).
    pub bin_s: f64,
    pub air: Air,
    /// Whether air absorption (ISO 9613-1) is applied.
    pub air_absorption: bool,
    /// Highest image-source order (0: direct sound only; rays do the rest).
    pub ism_order: u32,
    /// Image sources replace the rays' early specular paths; `false` traces everything with
    /// rays (used to test the ray estimator itself).
    pub use_image_sources: bool,
    /// A ray stops when every band has lost this many dB (at least 60).
    pub stop_db: f64,
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
            stop_db: 90.0,
        }
    }
}

/// Results of one source-receiver pair.
#[derive(Clone, Debug, Serialize)]
pub struct PairResult {
    pub source: String,
    pub receiver: String,
    pub distance_m: f64,
    /// Arrival time of the direct sound, s (straight-line distance / c).
    pub direct_s: f64,
    /// Energy fluence per bin and band, J/m^2 (the direct sound at distance d contributes
    /// E / (4 pi d^2) for source energy E).
    #[serde(skip)]
    pub histogram: Vec<BandEnergies>,
    pub metrics: [BandMetrics; BAND_COUNT],
    /// Image-source paths found (including the direct sound).
    pub specular_paths: usize,
}

/// Everything a simulation produces.
#[derive(Clone, Debug, Serialize)]
pub struct AcousticResult {
    pub bands_hz: [f32; BAND_COUNT],
    pub volume_m3: f64,
    pub surface_m2: f64,
    pub speed_of_sound_m_s: f64,
    pub sabine_s: [f64; BAND_COUNT],
    pub eyring_s: [f64; BAND_COUNT],
    pub max_time_s: f64,
    pub bin_s: f64,
    pub ism_order: u32,
    pub receiver_radii_m: Vec<f32>,
    pub pairs: Vec<PairResult>,
    /// Fraction of launched energy that escaped through holes in the mesh.
    pub escaped_energy_fraction: f64,
    pub settings: AcousticSettings,
}

/// Default receiver radius: about ten ray detections per 1 ms bin once the sound field is
/// diffuse, r = sqrt(10 V / (pi N c dt)), within 0.05 m to 0.5 m.
pub fn default_receiver_radius_m(volume_m3: f64, rays: u64, speed_m_s: f64, bin_s: f64) -> f32 {
    let r = (10.0 * volume_m3 / (std::f64::consts::PI * rays.max(1) as f64 * speed_m_s * bin_s)).sqrt();
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
    if settings.stop_db < 60.0 || !settings.stop_db.is_finite() {
        return Err(format!("stop level {} dB: must be at least 60 dB", settings.stop_db));
    }
    let scene = &world.scene;
    let report = &world.report;
    let volume_m3 =
        report.air_volume_m3.ok_or("the scene encloses no air: room acoustics needs a closed room")?;
    let surfaces = surface_acoustics(world)?;
    let c = settings.air.speed_of_sound_m_s();
    let air_per_m =
        if settings.air_absorption { settings.air.energy_coefficient_per_m() } else { [0.0; BAND_COUNT] };
    let absorption: Vec<_> = surfaces.iter().map(|s| s.absorption).collect();
    let areas = &report.area_by_surface_m2[..surfaces.len().min(report.area_by_surface_m2.len())];
    let (sabine_s, eyring_s) =
        reverberation_times(volume_m3, areas, &absorption[..areas.len()], &air_per_m, c);
    let longest = eyring_s.iter().copied().filter(|t| t.is_finite()).fold(0.0f64, f64::max);
    let max_time_s = settings.max_time_s.unwrap_or((1.2 * longest).clamp(0.2, 20.0));
    if !(max_time_s > 0.0 && max_time_s <= 60.0) {
        return Err(format!("maximum time {max_time_s} s: must be in (0, 60]"));
    }
    let bins = (max_time_s / settings.bin_s).ceil() as usize;

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
    }
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
    let planes = if settings.use_image_sources && settings.ism_order > 0 {
        Planes::of(&scene.mesh)
    } else {
        Planes::default()
    };
    let ism_order =
        if settings.use_image_sources { affordable_order(planes.len(), settings.ism_order) } else { 0 };
    let mut pairs = Vec::new();
    let mut escaped = 0.0;
    for (si, source) in sources.iter().enumerate() {
        if !(source.power_w.is_finite() && source.power_w > 0.0) {
            return Err(format!("source \"{}\" power {} W: must be > 0", source.name, source.power_w));
        }
        let prop = SoundPropagation {
            surfaces: &surfaces,
            receivers: &spheres,
            ray_energy_j: (1.0 / settings.rays as f64) as f32,
            air_per_m,
            speed_of_sound_m_s: c as f32,
            bin_s: settings.bin_s as f32,
            bins: bins as u32,
            skip_specular_up_to: settings.use_image_sources.then_some(ism_order),
            stop_factor: 10f64.powf(-settings.stop_db / 10.0) as f32,
            max_path_m: (max_time_s * c) as f32,
            scene_bounds: (lo - margin, hi + margin),
        };
        let launch_spec = Launch {
            origin: Vec3::from(source.position),
            rays: settings.rays,
            seed: settings.seed,
            domain: si as u64,
            pattern: LaunchPattern::Fibonacci,
            max_reflections: u32::MAX,
            max_path_m: prop.max_path_m,
        };
        let record: TraceRecord = launch_share(&world.accel, &prop, &launch_spec, cluster.share(), progress);
        // Fixed-point sums (of the energy per ray) are exact in any order, so every split
        // of the rays over processes and threads gives the same histograms to the last bit.
        let unit = f64::from(prop.ray_energy_j);
        let mut fixed = vec![0u128; receivers.len() * bins * BAND_COUNT];
        for d in &record.detections {
            let at = (d.receiver as usize * bins + d.bin as usize) * BAND_COUNT;
            for (slot, e) in fixed[at..at + BAND_COUNT].iter_mut().zip(d.energy) {
                add_fixed(slot, f64::from(e), unit);
            }
        }
        drop(record.detections);
        let mut escaped_fixed = record.escaped.to_vec();
        cluster.sum_u128(&mut fixed);
        cluster.sum_u128(&mut escaped_fixed);
        if !cluster.is_root() {
            continue;
        }
        escaped += escaped_fixed.iter().map(|&e| from_fixed(e, unit)).sum::<f64>() / BAND_COUNT as f64;
        let mut histograms: Vec<Vec<BandEnergies>> = fixed
            .chunks_exact(bins * BAND_COUNT)
            .map(|r| {
                r.chunks_exact(BAND_COUNT).map(|b| std::array::from_fn(|k| from_fixed(b[k], unit))).collect()
            })
            .collect();
        drop(fixed);
        // Image sources (the direct sound is order 0).
        let src = Vec3::from(source.position);
        let time_bins = TimeBins { speed_m_s: c, bin_s: settings.bin_s, bins };
        for (ri, r) in receivers.iter().enumerate() {
            let rcv = Vec3::from(r.position);
            let paths = if settings.use_image_sources {
                specular_arrivals(&world.accel, &planes, &surfaces, &air_per_m, src, rcv, ism_order)
            } else {
                Vec::new()
            };
            for p in &paths {
                let Some(bin) = time_bins.bin_of_path(p.length_m) else { continue };
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
                *m = band_metrics(&band, settings.bin_s, direct_s);
            }
            pairs.push(PairResult {
                source: source.name.clone(),
                receiver: r.name.clone(),
                distance_m,
                direct_s,
                histogram: hist,
                metrics,
                specular_paths: paths.len(),
            });
        }
    }
    if !cluster.is_root() {
        return Ok(None);
    }
    Ok(Some(AcousticResult {
        bands_hz: OCTAVE_BANDS_HZ,
        volume_m3,
        surface_m2: report.total_area_m2,
        speed_of_sound_m_s: c,
        sabine_s,
        eyring_s,
        max_time_s,
        bin_s: settings.bin_s,
        ism_order,
        receiver_radii_m: spheres.iter().map(|s| s.radius_m).collect(),
        pairs,
        escaped_energy_fraction: escaped / sources.len() as f64,
        settings: settings.clone(),
    }))
}
