//! `propsim run [SCENE]`: the picture, the sound and the radio coverage of one scene, side by
//! side in one directory ([`crate::run`]).

use std::path::PathBuf;

use clap::Args;

use crate::dist::Cluster;
use crate::run::RunOptions;

#[derive(Args, Debug)]
pub struct RunArgs {
    /// Scene file (.toml), bare OBJ, or builtin:NAME (default: the built-in showcase).
    #[arg(default_value = "builtin:showcase")]
    pub scene: PathBuf,
    /// Output directory.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    #[command(flatten)]
    pub options: RunOptions,
    #[command(flatten)]
    pub load: crate::scene::LoadOptions,
}

pub fn run(args: &RunArgs, cluster: &Cluster) -> anyhow::Result<()> {
    // Load once up front: a bad scene fails before any work, with the usual one-line error.
    let world = super::load_world(&args.scene, &args.load)?;
    let scene_label = args.scene.display().to_string();
    super::acoustic::warn_internal_sheets(&world, &scene_label);
    crate::run::run(
        &world,
        &args.options,
        &scene_label,
        &args.load.materials_files,
        &args.out,
        cluster,
        &super::progress::Terminal,
    )?;
    Ok(())
}
