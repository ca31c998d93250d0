//! `propsim acoustic`: impulse responses, histograms and ISO 3382-1 parameters of a room.

use std::path::{Path, PathBuf};
use std::time::Instant;

use clap::Args;

use crate::acoustic::output::summary_text;
use crate::acoustic::{AcousticOptions, Plan, simulate_on};
use crate::dist::Cluster;
use crate::scene::World;

#[derive(Args, Debug)]
pub struct AcousticArgs {
    /// Scene file (.toml), bare OBJ, or builtin:NAME.
    #[arg(default_value = super::DEFAULT_SCENE)]
    pub scene: PathBuf,
    #[command(flatten)]
    pub options: AcousticOptions,
    /// Extra materials file(s).
    #[arg(long = "materials")]
    pub materials: Vec<PathBuf>,
    #[command(flatten)]
    pub model: super::ModelArgs,
    /// Output directory.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
}

/// Runs a checked [`Plan`] and (on rank 0) writes every output into `out`, printing the
/// summary; returns the files written (`None` on the other ranks). `started` is when the job
/// began, for the wall time in acoustic.json.
pub fn execute(
    world: &World,
    plan: &Plan,
    out: &Path,
    scene_label: &str,
    cluster: &Cluster,
    started: Instant,
) -> anyhow::Result<Option<Vec<PathBuf>>> {
    let Plan { sources, receivers, settings, .. } = plan;
    let bar = super::progress::bar(settings.rays * sources.len() as u64, "rays");
    let result = simulate_on(cluster, world, sources, receivers, settings, &|n| bar.inc(n))
        .map_err(|e| anyhow::anyhow!("{scene_label}: {e}"))?;
    bar.finish_and_clear();
    // Only rank 0 holds the result and writes.
    let Some(result) = result else { return Ok(None) };
    let traced_s = started.elapsed().as_secs_f64();
    let written = crate::acoustic::output::write_all(
        out,
        world,
        plan,
        &result,
        scene_label,
        cluster,
        traced_s,
        started,
    )?;
    say!("{}", summary_text(&result).trim_end());
    for p in &result.pairs {
        for w in &p.warnings {
            tell!("warning: {} -> {}: {w}", p.source, p.receiver);
        }
    }
    say!(
        "wrote {} files to {} ({} rays/source, {:.2} s)",
        written.len(),
        out.display(),
        settings.rays,
        started.elapsed().as_secs_f64()
    );
    Ok(Some(written))
}

pub fn run(args: &AcousticArgs, cluster: &Cluster) -> anyhow::Result<()> {
    let started = Instant::now();
    let world = super::load_world(&args.scene, &args.materials, &args.model)?;
    let scene_label = args.scene.display().to_string();
    warn_internal_sheets(&world, &scene_label);
    let plan = crate::acoustic::plan(&world, &args.options, &scene_label)?;
    for n in &plan.notes {
        tell!("note: {n}");
    }
    // The output directory is checked before the (possibly long) simulation.
    if cluster.is_root() {
        crate::io::atomic::check_writable(&args.out, true)?;
    }
    execute(&world, &plan, &args.out, &scene_label, cluster, started)?;
    Ok(())
}

/// Warns when edges are shared by more than two triangles (rays cross such a sheet).
pub fn warn_internal_sheets(world: &World, scene_label: &str) {
    if world.report.over_shared_edges > 0 {
        tell!(
            "warning: {scene_label}: {} edges are shared by more than two triangles (an internal sheet); rays cross it as a surface",
            world.report.over_shared_edges
        );
    }
}
