//! One radio job: the pre-flight ([`plan`]: options and scene to a checked [`RfConfig`],
//! before any ray is traced), then the run ([`execute`]: simulate and write every file).

use std::path::{Path, PathBuf};

use anyhow::Context as _;

use super::output::{map_line, write_outputs};
use super::{RfConfig, RfOptions, RfResult, check, grid_misses_model, simulate_on};
use crate::dist::Cluster;
use crate::io::report::Report;
use crate::scene::World;

/// A checked radio job and what the user should hear before it runs.
#[derive(Clone, Debug)]
pub struct RfPlan {
    /// Transmitters, grid, receivers and settings, defaults filled and checked.
    pub config: RfConfig,
    /// Warnings, one line each, naming the scene (a grid that misses the model).
    pub warnings: Vec<String>,
}

/// The radio pre-flight: the configuration from the scene and `options`, with every surface's
/// radio data checked at every transmitter's frequency. The error is one line naming the
/// scene `scene_label`.
pub fn plan(world: &World, options: &RfOptions, scene_label: &str) -> anyhow::Result<RfPlan> {
    let config = RfConfig::from_scene(world, options)
        .and_then(|c| check(world, &c).map(|()| c))
        .map_err(|e| anyhow::anyhow!("{scene_label}: {e}"))?;
    let warnings =
        grid_misses_model(world, &config).map(|why| format!("{scene_label}: {why}")).into_iter().collect();
    Ok(RfPlan { config, warnings })
}

/// A finished radio job (on rank 0): the result and the files written.
#[derive(Debug)]
pub struct Finished {
    /// What was computed.
    pub result: RfResult,
    /// Every file written, in order (empty when no directory was given).
    pub files: Vec<PathBuf>,
}

/// Runs a checked [`RfPlan`] on this process's share of `cluster`; on rank 0 writes every
/// output into `out` (when given) and reports the map's summary line and the point receivers'
/// path gains. `None` on the other ranks.
pub fn execute(
    world: &World,
    plan: &RfPlan,
    out: Option<&Path>,
    scene_label: &str,
    cluster: &Cluster,
    report: &dyn Report,
) -> anyhow::Result<Option<Finished>> {
    let config = &plan.config;
    let counter = report.progress(config.rays * config.transmitters.len() as u64, "rays");
    let result =
        simulate_on(cluster, world, config, &|n| counter.inc(n)).with_context(|| scene_label.to_string())?;
    drop(counter);
    // Only rank 0 holds the map and writes.
    let Some(result) = result else { return Ok(None) };
    let Some(out) = out else { return Ok(Some(Finished { result, files: Vec::new() })) };
    let s = write_outputs(out, scene_label, world, config, &result)?;
    report.say(&format!(
        "{} ({:.2} Mrays/s)",
        map_line(scene_label, config, &s, result.seconds),
        s.rays_per_second / 1e6
    ));
    for r in &s.receivers {
        let f = |v: Option<f64>| v.map_or("none".to_string(), |v| format!("{v:.2} dB"));
        report.say(&format!(
            "  {} -> {}: {} paths, coherent {}, incoherent {}, grid cell {}",
            r.transmitter,
            r.name,
            r.paths,
            f(r.coherent_path_gain_db),
            f(r.incoherent_path_gain_db),
            f(r.grid_path_gain_db)
        ));
    }
    let files: Vec<PathBuf> = s.outputs.iter().map(PathBuf::from).collect();
    Ok(Some(Finished { result, files }))
}
