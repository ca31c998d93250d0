//! `propsim acoustic`: impulse responses, histograms and ISO 3382-1 parameters of a room.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use crate::acoustic::AcousticOptions;
use crate::dist::Cluster;
use crate::scene::World;

#[derive(Args, Debug)]
pub struct AcousticArgs {
    /// Scene file (.toml), bare OBJ, or builtin:NAME.
    #[arg(default_value = super::DEFAULT_SCENE)]
    pub scene: PathBuf,
    #[command(flatten)]
    pub options: AcousticOptions,
    #[command(flatten)]
    pub load: crate::scene::LoadOptions,
    /// Output directory.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
}

pub fn run(args: &AcousticArgs, cluster: &Cluster) -> anyhow::Result<()> {
    let started = Instant::now();
    let world = super::load_world(&args.scene, &args.load)?;
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
    let report = super::progress::Terminal;
    let done =
        crate::acoustic::execute(&world, &plan, Some(&args.out), &scene_label, cluster, &report, started)?;
    if let Some(done) = done {
        say!(
            "wrote {} files to {} ({} rays/source, {:.2} s)",
            done.files.len(),
            args.out.display(),
            plan.settings.rays,
            started.elapsed().as_secs_f64()
        );
    }
    Ok(())
}

/// Warns when edges are shared by more than two triangles (rays cross such a sheet).
pub fn warn_internal_sheets(world: &World, scene_label: &str) {
    if let Some(w) = world.sheet_warning(scene_label) {
        tell!("warning: {w}");
    }
}
