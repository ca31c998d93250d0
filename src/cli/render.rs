//! `propsim render`: an image of a scene (PNG or EXR) with a chosen integrator.

use std::path::{Path, PathBuf};

use anyhow::{Context, anyhow};
use clap::Args;
use glam::Vec3;

use crate::dist::Cluster;
use crate::render::film::{Display, ImageFormat};
use crate::render::{Camera, IntegratorKind, RenderOutput, RenderScene, RenderSettings, render_on};
use crate::scene::{self, World};

/// The scene `propsim render` uses when given none.
pub const DEFAULT_RENDER_SCENE: &str = "builtin:cornell_box_classic";
/// Image size when neither the scene nor the command line gives one.
pub const DEFAULT_SIZE: (u32, u32) = (640, 480);
/// Memory a render holds per pixel, bytes: film and tile results (12 bytes of float RGB each)
/// and the 8-bit image written from them (16384 x 16384 peaked at 6.4 GB).
pub const BYTES_PER_PIXEL: u64 = 28;
/// Vertical field of view of the automatic camera outside a model, degrees.
pub const AUTO_FOV_DEG: f32 = crate::render::AUTO_FOV_DEG;

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
    /// Image width in pixels (default: the scene's, else 640).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels (default: the scene's, else 480).
    #[arg(long)]
    pub height: Option<u32>,
    /// Samples per pixel (default: the scene's, else 64).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Maximum bounces; 1 = direct light only (default: the scene's, else 8).
    #[arg(long = "max-depth")]
    pub max_depth: Option<u32>,
    /// raycast, whitted, distributed or path (default: the scene's, else path).
    #[arg(long)]
    pub integrator: Option<String>,
    /// Random seed: the same seed gives the same image for any thread count.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Camera position X,Y,Z (default: the scene's camera, else an automatic view).
    #[arg(long, value_parser = super::parse_point, allow_hyphen_values = true)]
    pub eye: Option<[f32; 3]>,
    /// Point looked at, X,Y,Z.
    #[arg(long, value_parser = super::parse_point, allow_hyphen_values = true)]
    pub target: Option<[f32; 3]>,
    /// Up direction, X,Y,Z (default 0,0,1).
    #[arg(long, value_parser = super::parse_point, allow_hyphen_values = true)]
    pub up: Option<[f32; 3]>,
    /// Vertical field of view, degrees.
    #[arg(long = "fov-deg")]
    pub fov_deg: Option<f32>,
    /// PNG exposure in stops: radiance x 2^EV before the tone map (default: the scene's, else
    /// 0). EXR output stays linear.
    #[arg(long = "exposure", value_name = "EV")]
    pub exposure_ev: Option<f32>,
    /// PNG tone map: aces (filmic, the default), reinhard (on luminance) or none (clip at 1).
    #[arg(long = "tone-map", value_name = "aces|reinhard|none")]
    pub tone_map: Option<String>,
    /// Largest luminance of each sample's indirect light (path and distributed integrators):
    /// removes fireflies at the cost of bias (some light is lost). Default: no clamp.
    #[arg(long = "clamp-indirect", value_name = "LUMINANCE")]
    pub clamp_indirect: Option<f32>,
    /// Extra materials file(s).
    #[arg(long = "materials")]
    pub materials: Vec<PathBuf>,
    #[command(flatten)]
    pub model: super::ModelArgs,
}

/// The settings the scene suggests, overridden by the flags.
pub fn settings(args: &RenderArgs, world: &World) -> anyhow::Result<RenderSettings> {
    let desc = world.scene.desc.render.clone().unwrap_or_default();
    let integrator_name = args.integrator.clone().or(desc.integrator).unwrap_or_else(|| "path".into());
    let integrator: IntegratorKind =
        integrator_name.parse().map_err(|e: String| anyhow!("--integrator: {e}"))?;
    let d = RenderSettings::default();
    let tone_map = match args.tone_map.clone().or(desc.tone_map) {
        Some(name) => name.parse().map_err(|e: String| anyhow!("--tone-map: {e}"))?,
        None => d.display.tone_map,
    };
    let exposure_ev = args.exposure_ev.or(desc.exposure_ev).unwrap_or(d.display.exposure_ev);
    let display = Display { exposure_ev, tone_map };
    display.validate().map_err(|e| anyhow!("--exposure: {e}"))?;
    let s = RenderSettings {
        width: args.width.or(desc.width).unwrap_or(DEFAULT_SIZE.0),
        height: args.height.or(desc.height).unwrap_or(DEFAULT_SIZE.1),
        spp: args.spp.or(desc.spp).unwrap_or(d.spp),
        max_depth: args.max_depth.or(desc.max_depth).unwrap_or(d.max_depth),
        integrator,
        seed: args.seed,
        background: None,
        display,
        clamp_indirect: args.clamp_indirect,
    };
    s.validate().map_err(|e| anyhow!("{e}"))?;
    Ok(s)
}

/// The camera: the scene's `[camera]` or the automatic one ([`crate::render::auto_camera`]:
/// inside a closed room, else outside the bounds), then the flags.
pub fn camera(args: &RenderArgs, world: &World, aspect: f32) -> anyhow::Result<Camera> {
    let (eye, target, up, fov, lens) = match &world.scene.desc.camera {
        Some(c) => (
            Vec3::from(c.eye),
            Vec3::from(c.target),
            Vec3::from(c.up),
            c.fov_deg,
            (c.aperture_radius_m, c.focus_distance_m),
        ),
        None => {
            let up = args.up.map_or(Vec3::Z, Vec3::from);
            let v = crate::render::auto_camera(world, up, args.fov_deg);
            (v.eye, v.target, up, v.fov_deg, (0.0, None))
        }
    };
    let eye = args.eye.map_or(eye, Vec3::from);
    let target = args.target.map_or(target, Vec3::from);
    let up = args.up.map_or(up, Vec3::from);
    let fov = args.fov_deg.unwrap_or(fov);
    let mut cam = Camera::look_at(eye, target, up, fov, aspect).map_err(|e| anyhow!("{e}"))?;
    cam.set_lens(lens.0, lens.1).map_err(|e| anyhow!("{e}"))?;
    Ok(cam)
}

/// The render part's pre-flight: the settings and camera, and whether the image fits in
/// memory. The error is one line.
pub fn plan(args: &RenderArgs, world: &World) -> anyhow::Result<(RenderSettings, Camera)> {
    let s = settings(args, world).with_context(|| args.scene.display().to_string())?;
    let pixels = u64::from(s.width) * u64::from(s.height);
    crate::io::memory::check_fits(
        &format!("a {}x{} render", s.width, s.height),
        pixels * BYTES_PER_PIXEL + world.accel.mesh.memory_bytes() as u64,
    )?;
    let cam = camera(args, world, s.width as f32 / s.height as f32)
        .with_context(|| args.scene.display().to_string())?;
    if s.integrator != IntegratorKind::Raycast
        && let Some(why) = crate::render::unlit_reason(world)
    {
        tell!("warning: {}: {why}", args.scene.display());
    }
    Ok((s, cam))
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
    let (s, cam) = plan(args, &world)?;
    execute(&world, &s, &cam, &args.output, cluster)?;
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
