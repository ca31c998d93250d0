//! `propsim render`: an image of a scene (PNG or EXR) with a chosen integrator.

use std::path::PathBuf;

use clap::Args;

use crate::dist::Cluster;
use crate::render::film::ImageFormat;
use crate::render::{RenderOptions, RenderPlan};
use crate::scene::World;

/// The scene `propsim render` uses when given none.
pub const DEFAULT_RENDER_SCENE: &str = "builtin:cornell_box_classic";
#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene file (.toml), bare OBJ (with its MTL), or builtin:NAME.
    #[arg(default_value = DEFAULT_RENDER_SCENE)]
    pub scene: PathBuf,
    /// Output image; the extension picks the format: .png (8-bit sRGB, exposed and tone
    /// mapped), .exr (linear float radiance, untouched by --exposure and --tone-map) or .npy
    /// (the same linear values as float32, height x width x 3).
    #[arg(short = 'o', long = "output", default_value = "out/render.png")]
    pub output: PathBuf,
    #[command(flatten)]
    pub options: RenderOptions,
    #[command(flatten)]
    pub load: crate::scene::LoadOptions,
}

/// The render's pre-flight ([`crate::render::job::plan`]), its warnings printed.
pub fn plan(args: &RenderArgs, world: &World) -> anyhow::Result<RenderPlan> {
    let plan = crate::render::job::plan(world, &args.options, &args.scene.display().to_string())?;
    for w in &plan.warnings {
        tell!("warning: {w}");
    }
    Ok(plan)
}

pub fn run(args: &RenderArgs, cluster: &Cluster) -> anyhow::Result<()> {
    // Check the output name before the (possibly long) render.
    ImageFormat::from_path(&args.output)?;
    if cluster.is_root() {
        crate::io::atomic::check_writable(&args.output, false)?;
    }
    let world = super::load_world(&args.scene, &args.load)?;
    let plan = plan(args, &world)?;
    crate::render::job::execute(&world, &plan, Some(&args.output), cluster, &super::progress::Terminal)?;
    Ok(())
}
