//! `propsim bench render`: rendering speed (any integrator) on the classic Cornell box at 256x256, depth 8,
//! the configuration quoted for Mitsuba 3 in issue 3.

use clap::Args;

use crate::render::{Camera, IntegratorKind, RenderScene, RenderSettings, render, scene_camera};
use crate::scene::{self, LoadOptions, World};

#[derive(Args, Debug)]
pub struct BenchRenderArgs {
    /// Scene to render (default: the classic Cornell box).
    #[arg(default_value = "builtin:cornell_box_classic")]
    pub scene: std::path::PathBuf,
    /// Samples per pixel of each timed run.
    #[arg(long, default_value_t = 64)]
    pub spp: u32,
    #[arg(long, default_value_t = 256)]
    pub width: u32,
    #[arg(long, default_value_t = 256)]
    pub height: u32,
    #[arg(long = "max-depth", default_value_t = 8)]
    pub max_depth: u32,
    /// raycast, whitted, distributed, path, light, bdpt, sppm or ppm (spp = iterations, one
    /// photon a pixel an iteration), vcm (spp = iterations, one light subpath a pixel),
    /// radiosity, or pssmlt (spp = mutations per pixel).
    #[arg(long, default_value = "path")]
    pub integrator: String,
    /// Timed runs; the median is reported.
    #[arg(long, default_value_t = 5)]
    pub repeat: usize,
}

pub fn run(args: &BenchRenderArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        (1..=1000).contains(&args.repeat),
        "--repeat {}: must be between 1 and 1000",
        args.repeat
    );
    let integrator: IntegratorKind = args.integrator.parse().map_err(|e: String| anyhow::anyhow!("{e}"))?;
    let world = World::build(scene::load(&args.scene, &LoadOptions::default())?);
    let settings = RenderSettings {
        width: args.width,
        height: args.height,
        spp: args.spp,
        max_depth: args.max_depth,
        integrator,
        seed: 0,
        background: None,
        display: Default::default(),
        clamp_indirect: None,
        raymarch_step_m: None,
        photons: Default::default(),
        radiosity: Default::default(),
        mlt: Default::default(),
        fog: None,
    };
    settings.validate().map_err(|e| anyhow::anyhow!("{e}"))?;
    crate::io::memory::check_fits(
        &format!("a {}x{} render", args.width, args.height),
        u64::from(args.width) * u64::from(args.height) * crate::render::options::BYTES_PER_PIXEL,
    )?;
    let cam: Camera =
        scene_camera(&world, args.width as f32 / args.height as f32).map_err(|e| anyhow::anyhow!("{e}"))?;
    let rs = RenderScene::new(&world);
    // One warm-up run (page faults, thread pool start), then the timed runs.
    let warm = RenderSettings { spp: 1, ..settings.clone() };
    render(&rs, &cam, &warm, &|_| {}).map_err(|e| anyhow::anyhow!("{e}"))?;
    let mut runs = Vec::new();
    for _ in 0..args.repeat {
        let out = render(&rs, &cam, &settings, &|_| {}).map_err(|e| anyhow::anyhow!("{e}"))?;
        runs.push((out.seconds, out.samples, out.rays, out.film.mean(), out.photons));
    }
    runs.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (secs, samples, rays, mean, photons) = runs[runs.len() / 2];
    crate::outln!(
        "bench render: {} {}x{} spp {} max depth {} {} threads",
        args.scene.display(),
        args.width,
        args.height,
        args.spp,
        args.max_depth,
        rayon::current_num_threads()
    );
    crate::outln!("  integrator    {}", integrator.name());
    crate::outln!("  wall time     {secs:.3} s (median of {})", args.repeat);
    crate::outln!("  samples/s     {:.2} M", samples as f64 / secs / 1e6);
    if photons > 0 {
        crate::outln!("  photons/s     {:.2} M", photons as f64 / secs / 1e6);
    }
    crate::outln!(
        "  rays/s        {:.2} Mrays/s ({:.2} rays per sample)",
        rays as f64 / secs / 1e6,
        rays as f64 / samples as f64
    );
    crate::outln!("  image mean    {:.4} {:.4} {:.4}", mean.x, mean.y, mean.z);
    Ok(())
}
