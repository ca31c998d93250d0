//! `propsim run [SCENE]`: the picture, the sound and the radio coverage of one scene, side by
//! side in one directory, with a summary sheet and a manifest.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context as _;
use clap::{Args, Parser};
use image::{GenericImage, RgbImage};

use crate::dist::Cluster;
use crate::io::file_stem;
use crate::scene::{self, LoadOptions};

#[derive(Args, Debug)]
pub struct RunArgs {
    /// Scene file (.toml), bare OBJ, or builtin:NAME (default: the built-in showcase).
    #[arg(default_value = "builtin:showcase")]
    pub scene: PathBuf,
    /// Output directory.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// Extra materials file(s).
    #[arg(long = "materials")]
    pub materials: Vec<PathBuf>,
}

/// Runs one subcommand through the command-line layer, so `run` uses exactly the same
/// defaults and checks as the individual commands. Returns its wall time in seconds.
fn step(args: &[String], cluster: &Cluster) -> anyhow::Result<f64> {
    let t = Instant::now();
    let cli = super::Cli::try_parse_from(args).map_err(|e| anyhow::anyhow!("{}", e.to_string().trim()))?;
    super::dispatch(cli.command, cluster)?;
    Ok(t.elapsed().as_secs_f64())
}

/// Pastes `path` (scaled to fit, aspect kept) into the `cell` of a 2 x 2 sheet.
fn paste(sheet: &mut RgbImage, path: &Path, cell: (u32, u32), cell_size: (u32, u32)) -> anyhow::Result<()> {
    let img = image::open(path).with_context(|| format!("{}: cannot read", path.display()))?.to_rgb8();
    let scale = (f64::from(cell_size.0) / f64::from(img.width()))
        .min(f64::from(cell_size.1) / f64::from(img.height()));
    let (w, h) = ((f64::from(img.width()) * scale) as u32, (f64::from(img.height()) * scale) as u32);
    let small = image::imageops::resize(&img, w.max(1), h.max(1), image::imageops::FilterType::Triangle);
    let x = cell.0 * cell_size.0 + (cell_size.0 - small.width()) / 2;
    let y = cell.1 * cell_size.1 + (cell_size.1 - small.height()) / 2;
    sheet.copy_from(&small, x, y)?;
    Ok(())
}

pub fn run(args: &RunArgs, cluster: &Cluster) -> anyhow::Result<()> {
    let started = Instant::now();
    // Load once up front: a bad scene fails before any work, with the usual one-line error.
    let scene = scene::load(&args.scene, &LoadOptions { materials_files: args.materials.clone() })?;
    let desc = scene.desc.clone();
    if cluster.is_root() {
        crate::io::atomic::check_writable(&args.out, true)?;
        std::fs::create_dir_all(&args.out)
            .with_context(|| format!("{}: cannot create", args.out.display()))?;
    }
    let scene_arg = args.scene.display().to_string();
    let out = args.out.display().to_string();
    let seed = args.seed.to_string();
    let mut materials: Vec<String> = Vec::new();
    for m in &args.materials {
        materials.extend(["--materials".to_string(), m.display().to_string()]);
    }
    // `propsim CMD SCENE OUTPUT_FLAG OUTPUT --seed S [--materials F]...`
    let sub = |cmd: &str, out_flag: &str, out: &str| {
        let mut v: Vec<String> =
            ["propsim", cmd, &scene_arg, out_flag, out, "--seed", &seed].map(String::from).to_vec();
        v.extend(materials.iter().cloned());
        v
    };
    let render_png = args.out.join("render.png");
    let render_s = step(&sub("render", "-o", &render_png.display().to_string()), cluster)?;
    let acoustic_s = step(&sub("acoustic", "--out", &out), cluster)?;
    let rf_s = step(&sub("rf", "--out", &out), cluster)?;
    if !cluster.is_root() {
        return Ok(());
    }

    // The summary sheet: render, coverage map, first pair's impulse response and decay curves.
    let acoustic = desc.acoustic.clone().unwrap_or_default();
    let pair = match (acoustic.sources.first(), acoustic.receivers.first()) {
        (Some(src), Some(rcv)) => format!("{}_{}", file_stem(&src.name), file_stem(&rcv.name)),
        _ => "S1_R1".into(),
    };
    let cell = (900, 560);
    let mut sheet = RgbImage::from_pixel(cell.0 * 2, cell.1 * 2, image::Rgb([255, 255, 255]));
    let panels = [
        (render_png.clone(), (0, 0)),
        (args.out.join("coverage.png"), (1, 0)),
        (args.out.join(format!("ir_{pair}.png")), (0, 1)),
        (args.out.join(format!("decay_{pair}.png")), (1, 1)),
    ];
    for (path, at) in &panels {
        paste(&mut sheet, path, *at, cell)?;
    }
    let sheet_path = args.out.join("summary.png");
    let mut png = std::io::Cursor::new(Vec::new());
    sheet.write_to(&mut png, image::ImageFormat::Png)?;
    crate::io::atomic::write_bytes(&sheet_path, png.get_ref())?;

    let manifest_path = args.out.join("manifest.json");
    let manifest = serde_json::json!({
        "propsim_version": env!("CARGO_PKG_VERSION"),
        "scene": scene_arg,
        "seed": args.seed,
        "materials_files": args.materials,
        "threads": rayon::current_num_threads(),
        "processes": cluster.size(),
        "parameters": {
            "camera": desc.camera,
            "render": desc.render,
            "lights": desc.lights,
            "spheres": desc.spheres,
            "acoustic": desc.acoustic,
            "rf": desc.rf,
            "details": ["acoustic.json", "coverage.json"],
        },
        "timings_s": { "render": render_s, "acoustic": acoustic_s, "rf": rf_s, "total": started.elapsed().as_secs_f64() },
        "outputs": ["render.png", "metrics.csv", "histogram.csv", "acoustic.json", "coverage.csv", "coverage.png", "coverage.json", "summary.png", "manifest.json"],
    });
    crate::io::atomic::write_bytes(&manifest_path, serde_json::to_string_pretty(&manifest)?.as_bytes())?;
    say!(
        "run: render {render_s:.1} s, acoustic {acoustic_s:.1} s, radio {rf_s:.1} s; summary sheet {} and manifest {} ({:.1} s in all)",
        sheet_path.display(),
        manifest_path.display(),
        started.elapsed().as_secs_f64()
    );
    Ok(())
}
