//! `propsim render`: an image of a scene (PNG or EXR) with a chosen integrator.

use std::path::{Path, PathBuf};

use anyhow::anyhow;
use clap::Args;

use crate::dist::Cluster;
use crate::render::film::ImageFormat;
use crate::render::{
    Camera, RenderOptions, RenderOutput, RenderPlan, RenderScene, RenderSettings, render_on,
};
use crate::scene::{self, World};

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
    /// Extra materials file(s).
    #[arg(long = "materials")]
    pub materials: Vec<PathBuf>,
    #[command(flatten)]
    pub model: super::ModelArgs,
}

/// The render's pre-flight ([`crate::render::options::plan`]), its warnings printed.
pub fn plan(args: &RenderArgs, world: &World) -> anyhow::Result<RenderPlan> {
    let plan = crate::render::options::plan(world, &args.options, &args.scene.display().to_string())?;
    for w in &plan.warnings {
        tell!("warning: {w}");
    }
    Ok(plan)
}

/// Renders with a checked plan and (on rank 0) writes the image to `output` and prints one
/// line; returns whether this process wrote it.
pub fn execute(
    world: &World,
    s: &RenderSettings,
    cam: &Camera,
    output: &Path,
    cluster: &Cluster,
) -> anyhow::Result<bool> {
    let rs = RenderScene::new(world);
    let bar = super::progress::bar(u64::from(s.width) * u64::from(s.height), "rendering");
    let out = render_on(cluster, &rs, cam, s, &|n| bar.inc(n)).map_err(|e| anyhow!("{e}"))?;
    bar.finish_and_clear();
    // Only rank 0 holds the image and writes.
    let Some(out) = out else { return Ok(false) };
    out.film.write_with(output, &s.display)?;
    say!("{}", summary(output, s, &out));
    Ok(true)
}

pub fn run(args: &RenderArgs, cluster: &Cluster) -> anyhow::Result<()> {
    // Check the output name before the (possibly long) render.
    ImageFormat::from_path(&args.output)?;
    if cluster.is_root() {
        crate::io::atomic::check_writable(&args.output, false)?;
    }
    let options = super::load_options(&args.materials, &args.model);
    let scene = scene::load(&args.scene, &options)?;
    for w in &scene.warnings {
        tell!("warning: {w}");
    }
    let world = World::build(scene);
    let plan = plan(args, &world)?;
    execute(&world, &plan.settings, &plan.camera, &args.output, cluster)?;
    Ok(())
}

/// One line: what was written and how fast.
pub fn summary(path: &Path, s: &RenderSettings, out: &RenderOutput) -> String {
    format!(
        "wrote {}: {}x{}, {} spp, {}, max depth {}, {:.2} s, {:.2} M samples/s, {:.2} Mrays/s",
        path.display(),
        s.width,
        s.height,
        s.spp,
        s.integrator.name(),
        s.max_depth,
        out.seconds,
        out.samples as f64 / out.seconds / 1e6,
        out.rays as f64 / out.seconds / 1e6
    )
}
