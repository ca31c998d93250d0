//! One acoustic job: the pre-flight ([`plan`]: from the user's [`AcousticOptions`] and the
//! scene to the checked sources, receivers and settings of a [`Plan`], before any ray is
//! traced), then the run ([`execute`]: simulate and write every file).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context as _;
use glam::Vec3;

use super::directivity::{Directivity, scene_directivities};
use super::options::MAX_ISM_ORDER;
use super::output::{summary_text, write_all};
use super::{AcousticOptions, AcousticResult, AcousticSettings, Air, ReceiverSpec, SourceSpec, simulate_on};
use crate::dist::Cluster;
use crate::io::report::Report;
use crate::scene::{World, place_inside};

/// What the acoustic part will simulate: its sources and receivers (the flags', the scene's,
/// or placed inside the room) and its settings, all checked.
#[derive(Clone, Debug)]
pub struct Plan {
    /// The sources to simulate.
    pub sources: Vec<SourceSpec>,
    /// The receivers to simulate.
    pub receivers: Vec<ReceiverSpec>,
    /// The simulation settings, defaults filled.
    pub settings: AcousticSettings,
    /// What was decided for the user (a source or receiver placed), one line each.
    pub notes: Vec<String>,
}

/// The acoustic part's pre-flight: everything that can be checked before tracing (a closed
/// room, acoustic data on every surface, usable sources and receivers, placed when none is
/// given, and the settings). The error is one line naming the scene `scene_label`.
pub fn plan(world: &World, options: &AcousticOptions, scene_label: &str) -> anyhow::Result<Plan> {
    let desc = world.scene.desc.acoustic.clone().unwrap_or_default();
    let (scene_sources, scene_receivers) = crate::acoustic::scene_points(world);
    let mut sources: Vec<SourceSpec> = if options.sources.is_empty() {
        scene_sources
    } else {
        options
            .sources
            .iter()
            .enumerate()
            .map(|(i, p)| SourceSpec {
                name: format!("S{}", i + 1),
                position: *p,
                power_w: 1.0,
                directivity: Directivity::OMNI,
            })
            .collect()
    };
    let mut receivers: Vec<ReceiverSpec> = if options.receivers.is_empty() {
        scene_receivers
            .into_iter()
            .map(|r| ReceiverSpec { radius_m: options.receiver_radius_m.or(r.radius_m), ..r })
            .collect()
    } else {
        options
            .receivers
            .iter()
            .enumerate()
            .map(|(i, p)| ReceiverSpec {
                name: format!("R{}", i + 1),
                position: *p,
                radius_m: options.receiver_radius_m,
                listener: Default::default(),
                directivity: Directivity::OMNI,
            })
            .collect()
    };
    crate::acoustic::check(world).map_err(|e| anyhow::anyhow!("{scene_label}: {e}"))?;
    // The scene's directivities were read by scene_points, which falls back to omni: refuse
    // an invalid one here, naming the file.
    scene_directivities(world).map_err(|e| anyhow::anyhow!("{scene_label}: {e}"))?;
    for r in world.scene.desc.acoustic.iter().flat_map(|a| &a.receivers) {
        crate::acoustic::simulate::scene_listener(r)
            .map_err(|e| anyhow::anyhow!("{scene_label}: receiver \"{}\": {e}", r.name))?;
    }
    let mut notes = Vec::new();
    if sources.is_empty() {
        let p = place_inside(world, Vec3::new(0.3, 0.35, 0.45), 0.5).with_context(|| {
            format!("{scene_label}: found no place for a source 0.5 m from every surface")
        })?;
        notes.push(format!("no source given; placed S1 at ({:.2}, {:.2}, {:.2})", p.x, p.y, p.z));
        sources.push(SourceSpec {
            name: "S1".into(),
            position: p.to_array(),
            power_w: 1.0,
            directivity: Directivity::OMNI,
        });
    }
    if receivers.is_empty() {
        let p = place_inside(world, Vec3::new(0.7, 0.6, 0.4), 0.5).with_context(|| {
            format!("{scene_label}: found no place for a receiver 0.5 m from every surface")
        })?;
        notes.push(format!("no receiver given; placed R1 at ({:.2}, {:.2}, {:.2})", p.x, p.y, p.z));
        receivers.push(ReceiverSpec {
            name: "R1".into(),
            position: p.to_array(),
            radius_m: options.receiver_radius_m,
            listener: Default::default(),
            directivity: Directivity::OMNI,
        });
    }
    match (&options.directivity, options.orientation) {
        (Some(name), axis) => {
            let d = Directivity::parse(name, options.directivity_alpha, axis)
                .map_err(|e| anyhow::anyhow!("--directivity {name}: {e}"))?;
            for s in &mut sources {
                s.directivity = d.clone();
            }
        }
        (None, axis) => {
            anyhow::ensure!(
                options.directivity_alpha.is_none(),
                "--directivity-alpha applies only with --directivity mix"
            );
            if let Some(axis) = axis {
                for s in &mut sources {
                    s.directivity = s
                        .directivity
                        .turned(glam::Vec3::from(axis))
                        .map_err(|e| anyhow::anyhow!("--orientation: {e}"))?;
                }
            }
        }
    }
    if let Some(axis) = options.receiver_orientation {
        for r in &mut receivers {
            let up = r.listener.up.as_vec3().to_array();
            r.listener = crate::acoustic::spatial::Listener::looking(axis, up)
                .map_err(|e| anyhow::anyhow!("--receiver-orientation: {e}"))?;
            r.directivity = r
                .directivity
                .turned(glam::Vec3::from(axis))
                .map_err(|e| anyhow::anyhow!("--receiver-orientation: {e}"))?;
        }
    }
    match &options.receiver_directivity {
        Some(name) => {
            for r in &mut receivers {
                let axis = Some(r.directivity.axis);
                r.directivity = Directivity::parse(name, options.receiver_directivity_alpha, axis)
                    .map_err(|e| anyhow::anyhow!("--receiver-directivity {name}: {e}"))?;
            }
        }
        None => anyhow::ensure!(
            options.receiver_directivity_alpha.is_none(),
            "--receiver-directivity-alpha applies only with --receiver-directivity mix"
        ),
    }
    let air = Air {
        temperature_c: options.temperature_c.or(desc.temperature_c.map(f64::from)).unwrap_or(20.0),
        relative_humidity_percent: options
            .humidity_percent
            .or(desc.relative_humidity_percent.map(f64::from))
            .unwrap_or(50.0),
        pressure_kpa: desc.pressure_kpa.map_or(101.325, f64::from),
    };
    let settings = AcousticSettings {
        rays: options.rays.or(desc.rays).unwrap_or(AcousticSettings::default().rays),
        seed: options.seed,
        max_time_s: options.max_time_s.or(desc.max_time_s.map(f64::from)),
        air,
        air_absorption: !options.no_air,
        diffuse_rain: !options.no_diffuse_rain,
        ism_order: options.ism_order,
        roulette_db: options.roulette_db.unwrap_or(AcousticSettings::default().roulette_db),
        diffraction: !options.no_diffraction,
        ray_diffraction: !options.no_diffraction && !options.no_ray_diffraction,
        split_copies: if options.no_splitting { 1 } else { AcousticSettings::default().split_copies },
        ambisonic_order: options.ambisonic_order,
        binaural: options.binaural || options.hrtf.is_some(),
        hrtf: options.hrtf.clone(),
        ..Default::default()
    };
    anyhow::ensure!(
        options.ism_order <= MAX_ISM_ORDER,
        "--ism-order {}: at most {MAX_ISM_ORDER}",
        options.ism_order
    );
    // A bad SOFA file is refused before any ray is traced (the table is kept for the writers).
    if let Some(path) = &options.hrtf {
        crate::acoustic::hrtf::load_sofa_cached(path).map_err(anyhow::Error::msg)?;
    }
    crate::acoustic::check_points(world, &sources, &receivers)
        .map_err(|e| anyhow::anyhow!("{scene_label}: {e}"))?;
    Ok(Plan { sources, receivers, settings, notes })
}

/// A finished acoustic job (on rank 0): the result and the files written.
#[derive(Debug)]
pub struct Finished {
    /// What was computed.
    pub result: AcousticResult,
    /// Every file written, in order (empty when no directory was given).
    pub files: Vec<PathBuf>,
}

/// Runs a checked [`Plan`] on this process's share of `cluster`; on rank 0, writes every
/// output into `out` (when given) and reports the summary table and the pairs' warnings.
/// `None` on the other ranks. `started` is when the job began, for acoustic.json's times.
pub fn execute(
    world: &World,
    plan: &Plan,
    out: Option<&Path>,
    scene_label: &str,
    cluster: &Cluster,
    report: &dyn Report,
    started: Instant,
) -> anyhow::Result<Option<Finished>> {
    let Plan { sources, receivers, settings, .. } = plan;
    let counter = report.progress(settings.rays * sources.len() as u64, "rays");
    let result = simulate_on(cluster, world, sources, receivers, settings, &|n| counter.inc(n))
        .map_err(|e| anyhow::anyhow!("{scene_label}: {e}"))?;
    drop(counter);
    // Only rank 0 holds the result and writes.
    let Some(result) = result else { return Ok(None) };
    let files = match out {
        Some(out) => write_all(out, world, plan, &result, scene_label, cluster, started)?,
        None => Vec::new(),
    };
    report.say(summary_text(&result).trim_end());
    for p in &result.pairs {
        for w in &p.warnings {
            report.warning(&format!("{} -> {}: {w}", p.source, p.receiver));
        }
    }
    Ok(Some(Finished { result, files }))
}
