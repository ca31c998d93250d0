//! `propsim run`: the picture, the sound and the radio coverage of one scene, side by
//! side in one directory, with a summary sheet, a summary text and a manifest.
//!
//! The scene is loaded once and each part (render, acoustic, rf) is checked before any work
//! starts: a part that cannot run is skipped with one `note:` line saying why and what would
//! enable it, and the others run. A part that fails while running becomes a note too. The
//! summary (summary.png, summary.txt) and the manifest (manifest.json, every file written and
//! its size) are always written. The exit status is non-zero only for bad input (a scene that
//! does not load, bad flags or render settings, an output directory that cannot be written)
//! or when no part ran.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context as _;
use image::{GenericImage, RgbImage};
use serde::Deserialize;

use crate::dist::Cluster;
use crate::io::report::Report;
use crate::scene::World;

/// One part of `propsim run`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Part {
    /// The picture.
    Render,
    /// The room acoustics.
    Acoustic,
    /// The radio coverage.
    Rf,
}

impl Part {
    /// The three parts, in the order they run.
    pub const ALL: [Part; 3] = [Part::Render, Part::Acoustic, Part::Rf];

    /// The part's name, as `--only` takes it.
    pub fn name(self) -> &'static str {
        match self {
            Part::Render => "render",
            Part::Acoustic => "acoustic",
            Part::Rf => "rf",
        }
    }
}

/// One name of `--only`, with the accepted names in the error.
fn parse_part(s: &str) -> Result<Part, String> {
    <Part as clap::ValueEnum>::from_str(s, true)
        .map_err(|_| format!("\"{s}\": expected render, acoustic or rf"))
}

/// Image width of `--quick` at most, pixels (the scene's aspect ratio kept).
pub const QUICK_WIDTH: u32 = 160;
/// Samples per pixel of `--quick`.
pub const QUICK_SPP: u32 = 4;
/// Acoustic rays per source of `--quick`.
pub const QUICK_ACOUSTIC_RAYS: u64 = 2_000;
/// Image-source order of `--quick` (order 2 takes seconds in rooms of many planes).
pub const QUICK_ISM_ORDER: u32 = 1;
/// Radio rays per transmitter of `--quick`.
pub const QUICK_RF_RAYS: u64 = 20_000;

/// What a user may set for `propsim run`; `None` means "the scene's value, else the part's
/// default" (`--quick` changes those defaults).
#[derive(clap::Args, Deserialize, Debug, Clone, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct RunOptions {
    /// Random seed of every part: the same seed gives the same files for any thread or
    /// process count.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// The parts to run, a comma list of render, acoustic and rf (default: all three).
    #[arg(long, value_parser = parse_part, value_delimiter = ',', num_args = 1)]
    pub only: Vec<Part>,
    /// Radio transmitter at X,Y,Z instead of the scene's (the rf part needs one).
    #[arg(long, value_parser = crate::scene::parse_point, allow_hyphen_values = true)]
    pub tx: Option<[f32; 3]>,
    /// Radio: use ITU-R P.2040 fits outside their frequency ranges.
    #[arg(long)]
    pub extrapolate: bool,
    /// Small settings for a quick look: images at most 160 pixels wide at 4 spp, 2000 acoustic
    /// rays per source with first-order image sources, 20000 radio rays per transmitter (the
    /// flags below override these).
    #[arg(long)]
    pub quick: bool,
    /// Image width, pixels (default: the scene's, else 640).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height, pixels (default: the scene's, else 480).
    #[arg(long)]
    pub height: Option<u32>,
    /// Samples per pixel of the render (default: the scene's, else 64).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Acoustic rays per source (default: the scene's, else 200000).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1_000_000_000))]
    pub rays: Option<u64>,
    /// Radio rays per transmitter (default: the scene's, else 10^6).
    #[arg(long, value_parser = clap::value_parser!(u64).range(1..=crate::rf::config::MAX_RAYS))]
    pub rf_rays: Option<u64>,
}

impl Default for RunOptions {
    fn default() -> Self {
        Self {
            seed: 1,
            only: Vec::new(),
            tx: None,
            extrapolate: false,
            quick: false,
            width: None,
            height: None,
            spp: None,
            rays: None,
            rf_rays: None,
        }
    }
}

/// What became of one part.
#[derive(Clone, Debug, PartialEq)]
enum Outcome {
    /// Not asked for (`--only`).
    NotSelected,
    /// The pre-flight check found a reason it cannot run.
    Skipped(String),
    /// It started and failed.
    Failed(String),
    /// It ran, in this many seconds.
    Ran(f64),
}

impl Outcome {
    fn word(&self) -> &'static str {
        match self {
            Outcome::NotSelected => "not selected",
            Outcome::Skipped(_) => "skipped",
            Outcome::Failed(_) => "failed",
            Outcome::Ran(_) => "ran",
        }
    }

    fn reason(&self) -> Option<&str> {
        match self {
            Outcome::Skipped(r) | Outcome::Failed(r) => Some(r),
            _ => None,
        }
    }

    fn seconds(&self) -> Option<f64> {
        match self {
            Outcome::Ran(s) => Some(*s),
            _ => None,
        }
    }
}

/// The reason a part is skipped, with what would enable it when the reason does not say.
fn skip_reason(part: Part, reason: &str) -> String {
    if part == Part::Acoustic && reason.contains(crate::acoustic::NO_AIR) {
        format!(
            "{reason} (an open or outdoor scene has no room acoustics: close the mesh to enable it; --only render,rf leaves the part out)"
        )
    } else {
        reason.to_string()
    }
}

/// Reports the one line that says a part is skipped or failed.
fn note(report: &dyn Report, part: Part, outcome: &Outcome) {
    if let Some(reason) = outcome.reason() {
        report.note(&format!("{} part {}: {reason}", part.name(), outcome.word()));
    }
}

/// Image size of `--quick`: the scene's (else the default) scaled down to [`QUICK_WIDTH`].
fn quick_size(world: &World) -> (u32, u32) {
    let desc = world.scene.desc.render.clone().unwrap_or_default();
    let w = desc.width.unwrap_or(crate::render::options::DEFAULT_SIZE.0).max(1);
    let h = desc.height.unwrap_or(crate::render::options::DEFAULT_SIZE.1).max(1);
    if w <= QUICK_WIDTH {
        return (w, h);
    }
    let scaled = (f64::from(h) * f64::from(QUICK_WIDTH) / f64::from(w)).round() as u32;
    (QUICK_WIDTH, scaled.max(1))
}

/// Pastes `img` (scaled to fit, aspect kept) into the `cell` of a 2 x 2 sheet.
fn paste(
    sheet: &mut RgbImage,
    img: &RgbImage,
    cell: (u32, u32),
    cell_size: (u32, u32),
) -> anyhow::Result<()> {
    let scale = (f64::from(cell_size.0) / f64::from(img.width()))
        .min(f64::from(cell_size.1) / f64::from(img.height()));
    let (w, h) = ((f64::from(img.width()) * scale) as u32, (f64::from(img.height()) * scale) as u32);
    let small = image::imageops::resize(img, w.max(1), h.max(1), image::imageops::FilterType::Triangle);
    let x = cell.0 * cell_size.0 + (cell_size.0 - small.width()) / 2;
    let y = cell.1 * cell_size.1 + (cell_size.1 - small.height()) / 2;
    sheet.copy_from(&small, x, y)?;
    Ok(())
}

/// Splits `text` into lines of at most `width` characters at spaces.
fn wrap(text: &str, width: usize) -> Vec<String> {
    let mut lines = vec![String::new()];
    for word in text.split_whitespace() {
        let last = lines.last_mut().map_or(0, |l| l.chars().count());
        if last > 0 && last + 1 + word.chars().count() > width {
            lines.push(String::new());
        }
        if let Some(l) = lines.last_mut() {
            if !l.is_empty() {
                l.push(' ');
            }
            l.push_str(word);
        }
    }
    lines
}

/// A white panel with `title` and `text` (wrapped): the summary sheet's cell for a part that
/// did not run.
fn text_panel(title: &str, text: &str, size: (u32, u32)) -> anyhow::Result<RgbImage> {
    use plotters::prelude::*;
    crate::io::plot::register_font();
    let mut buf = vec![255u8; (size.0 * size.1 * 3) as usize];
    {
        let root = BitMapBackend::with_buffer(&mut buf, size).into_drawing_area();
        root.fill(&WHITE)?;
        root.draw(&Text::new(title.to_string(), (30, 40), ("sans-serif", 26).into_font().color(&BLACK)))?;
        let font = ("sans-serif", 17).into_font().color(&RGBColor(60, 60, 60));
        for (k, line) in wrap(text, 90).into_iter().enumerate() {
            root.draw(&Text::new(line, (30, 90 + 26 * k as i32), font.clone()))?;
        }
        root.present()?;
    }
    RgbImage::from_raw(size.0, size.1, buf).context("summary sheet: panel size")
}

/// The sheet's cell for `part`: the picture at `path` when the part ran and wrote it, else a
/// panel saying why there is none.
fn panel(part: Part, outcome: &Outcome, path: Option<&Path>, size: (u32, u32)) -> anyhow::Result<RgbImage> {
    if let (Outcome::Ran(_), Some(p)) = (outcome, path) {
        return Ok(image::open(p).with_context(|| format!("{}: cannot read", p.display()))?.to_rgb8());
    }
    let why = match outcome {
        Outcome::NotSelected => "not selected (--only)".to_string(),
        Outcome::Ran(_) => "no picture written".to_string(),
        other => other.reason().unwrap_or_default().to_string(),
    };
    text_panel(&format!("{} part {}", part.name(), outcome.word()), &why, size)
}

/// The files a part wrote (on rank 0), in the order it wrote them.
#[derive(Default)]
struct Written {
    files: Vec<PathBuf>,
}

impl Written {
    /// The first file written whose name starts with `prefix` and ends with `suffix`.
    fn find(&self, prefix: &str, suffix: &str) -> Option<&Path> {
        self.files
            .iter()
            .find(|p| {
                p.file_name()
                    .and_then(|n| n.to_str())
                    .is_some_and(|n| n.starts_with(prefix) && n.ends_with(suffix))
            })
            .map(PathBuf::as_path)
    }
}

/// Runs every selected part of `options` on the loaded `world` (its scene named
/// `scene_label`, loaded with the extra `materials_files`) into the directory `out`, on this
/// process's share of `cluster`. Parts that cannot run are skipped with a note on `report`.
/// Returns the manifest (on rank 0; `None` on the others). The error is bad input, or no part
/// could run (the summary and manifest are written even then).
pub fn run(
    world: &World,
    options: &RunOptions,
    scene_label: &str,
    materials_files: &[PathBuf],
    out: &Path,
    cluster: &Cluster,
    report: &dyn Report,
) -> anyhow::Result<Option<serde_json::Value>> {
    let started = Instant::now();
    let desc = world.scene.desc.clone();
    if cluster.is_root() {
        crate::io::atomic::check_writable(out, true)?;
    }
    let selected = |p: Part| options.only.is_empty() || options.only.contains(&p);
    let mut outcomes = [Outcome::NotSelected, Outcome::NotSelected, Outcome::NotSelected];

    // Pre-flight of every selected part, before any work. The render needs only the mesh:
    // a render that cannot be planned is bad input (its settings or camera).
    let render_png = out.join("render.png");
    let render_plan = if selected(Part::Render) {
        let (qw, qh) = quick_size(world);
        let quick = |v: u32| options.quick.then_some(v);
        let render_options = crate::render::RenderOptions {
            width: options.width.or(quick(qw)),
            height: options.height.or(quick(qh)),
            spp: options.spp.or(quick(QUICK_SPP)),
            seed: options.seed,
            ..Default::default()
        };
        let plan = crate::render::job::plan(world, &render_options, scene_label)?;
        for w in &plan.warnings {
            report.warning(w);
        }
        Some(plan)
    } else {
        None
    };
    let acoustic_plan = if selected(Part::Acoustic) {
        let d = crate::acoustic::AcousticOptions::default();
        let acoustic_options = crate::acoustic::AcousticOptions {
            rays: options.rays.or(options.quick.then_some(QUICK_ACOUSTIC_RAYS)),
            ism_order: if options.quick { QUICK_ISM_ORDER } else { d.ism_order },
            seed: options.seed,
            ..d
        };
        match crate::acoustic::plan(world, &acoustic_options, scene_label) {
            Ok(p) => {
                for n in &p.notes {
                    report.note(&format!("acoustic part: {n}"));
                }
                Some(p)
            }
            Err(e) => {
                outcomes[1] = Outcome::Skipped(skip_reason(Part::Acoustic, &format!("{e:#}")));
                note(report, Part::Acoustic, &outcomes[1]);
                None
            }
        }
    } else {
        None
    };
    let rf_plan = if selected(Part::Rf) {
        let rf_options = crate::rf::RfOptions {
            rays: options.rf_rays.or(options.quick.then_some(QUICK_RF_RAYS)),
            tx: options.tx,
            extrapolate: options.extrapolate,
            seed: Some(options.seed),
            ..Default::default()
        };
        match crate::rf::job::plan(world, &rf_options, scene_label) {
            Ok(p) => {
                for w in &p.warnings {
                    report.warning(w);
                }
                Some(p)
            }
            Err(e) => {
                outcomes[2] = Outcome::Skipped(skip_reason(Part::Rf, &format!("{e:#}")));
                note(report, Part::Rf, &outcomes[2]);
                None
            }
        }
    } else {
        None
    };

    // Bad input has been refused by now: from here on the summary and manifest are written.
    if cluster.is_root() {
        std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create", out.display()))?;
    }

    // The parts that can run, each failure a note.
    let mut written = [Written::default(), Written::default(), Written::default()];
    if let Some(plan) = &render_plan {
        let t = Instant::now();
        match crate::render::job::execute(world, plan, Some(&render_png), cluster, report) {
            Ok(wrote) => {
                if wrote.is_some() {
                    written[0].files.push(render_png.clone());
                }
                outcomes[0] = Outcome::Ran(t.elapsed().as_secs_f64());
            }
            Err(e) => {
                outcomes[0] = Outcome::Failed(format!("{e:#}"));
                note(report, Part::Render, &outcomes[0]);
            }
        }
    }
    if let Some(plan) = &acoustic_plan {
        let t = Instant::now();
        match crate::acoustic::execute(world, plan, Some(out), scene_label, cluster, report, t) {
            Ok(done) => {
                written[1].files = done.map(|d| d.files).unwrap_or_default();
                outcomes[1] = Outcome::Ran(t.elapsed().as_secs_f64());
            }
            Err(e) => {
                outcomes[1] = Outcome::Failed(format!("{e:#}"));
                note(report, Part::Acoustic, &outcomes[1]);
            }
        }
    }
    if let Some(plan) = &rf_plan {
        let t = Instant::now();
        match crate::rf::job::execute(world, plan, Some(out), scene_label, cluster, report) {
            Ok(done) => {
                written[2].files = done.map(|d| d.files).unwrap_or_default();
                outcomes[2] = Outcome::Ran(t.elapsed().as_secs_f64());
            }
            Err(e) => {
                outcomes[2] = Outcome::Failed(format!("{e:#}"));
                note(report, Part::Rf, &outcomes[2]);
            }
        }
    }
    let ran = outcomes.iter().any(|o| matches!(o, Outcome::Ran(_)));
    if !cluster.is_root() {
        return Ok(None);
    }

    // The summary sheet: render, coverage map, first pair's impulse response and decay
    // curves; a part that did not run shows why.
    let cell = (900, 560);
    let mut sheet = RgbImage::from_pixel(cell.0 * 2, cell.1 * 2, image::Rgb([255, 255, 255]));
    let panels = [
        (Part::Render, written[0].find("render", ".png"), (0, 0)),
        (Part::Rf, written[2].find("coverage", ".png"), (1, 0)),
        (Part::Acoustic, written[1].find("ir_", ".png"), (0, 1)),
        (Part::Acoustic, written[1].find("decay_", ".png"), (1, 1)),
    ];
    for (part, path, at) in panels {
        let i = Part::ALL.iter().position(|p| *p == part).unwrap_or(0);
        paste(&mut sheet, &panel(part, &outcomes[i], path, cell)?, at, cell)?;
    }
    let sheet_path = out.join("summary.png");
    let mut png = std::io::Cursor::new(Vec::new());
    sheet.write_to(&mut png, image::ImageFormat::Png)?;
    crate::io::atomic::write_bytes(&sheet_path, png.get_ref())?;

    // The summary text: which parts ran and why the others did not (no timings, so that it is
    // the same for any number of processes; they are in the manifest).
    let text_path = out.join("summary.txt");
    let mut text = format!("propsim run {scene_label}\n");
    for (part, (o, w)) in Part::ALL.iter().zip(outcomes.iter().zip(&written)) {
        let _ = write!(text, "{}: {}", part.name(), o.word());
        if let Some(r) = o.reason() {
            let _ = write!(text, ": {r}");
        }
        if matches!(o, Outcome::Ran(_)) {
            let _ = write!(text, " ({} files)", w.files.len());
        }
        text.push('\n');
    }
    crate::io::atomic::write_bytes(&text_path, text.as_bytes())?;

    // The manifest: every file written (but itself) with its size, relative to --out.
    let mut files: Vec<PathBuf> = written.iter().flat_map(|w| w.files.iter().cloned()).collect();
    files.extend([sheet_path.clone(), text_path.clone()]);
    let mut outputs = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for f in &files {
        let rel = f.strip_prefix(out).unwrap_or(f).display().to_string();
        if !seen.insert(rel.clone()) {
            continue;
        }
        let bytes = std::fs::metadata(f).with_context(|| format!("{}: cannot read", f.display()))?.len();
        outputs.push(serde_json::json!({ "path": rel, "bytes": bytes }));
    }
    let parts: serde_json::Map<String, serde_json::Value> = Part::ALL
        .iter()
        .zip(&outcomes)
        .map(|(p, o)| (p.name().to_string(), serde_json::json!({ "status": o.word(), "reason": o.reason() })))
        .collect();
    let details: Vec<&str> = [(1, "acoustic.json"), (2, "coverage.json")]
        .into_iter()
        .filter(|(i, _)| matches!(outcomes[*i], Outcome::Ran(_)))
        .map(|(_, f)| f)
        .collect();
    let manifest_path = out.join("manifest.json");
    let manifest = serde_json::json!({
        "propsim_version": env!("CARGO_PKG_VERSION"),
        "scene": scene_label,
        "seed": options.seed,
        "materials_files": materials_files,
        "threads": rayon::current_num_threads(),
        "processes": cluster.size(),
        "parts": parts,
        "parameters": {
            "quick": options.quick,
            "tx": options.tx,
            "extrapolate": options.extrapolate,
            "camera": desc.camera,
            "render": render_plan.as_ref().map(|p| &p.settings).map(|s| serde_json::json!({
                "width": s.width, "height": s.height, "spp": s.spp, "max_depth": s.max_depth,
                "integrator": s.integrator.name(),
            })),
            "lights": desc.lights,
            "spheres": desc.spheres,
            "acoustic": desc.acoustic,
            "acoustic_rays": acoustic_plan.as_ref().map(|p| p.settings.rays),
            "rf": desc.rf,
            "rf_rays": rf_plan.as_ref().map(|p| p.config.rays),
            "details": details,
        },
        "timings_s": {
            "render": outcomes[0].seconds(),
            "acoustic": outcomes[1].seconds(),
            "rf": outcomes[2].seconds(),
            "total": started.elapsed().as_secs_f64(),
        },
        "outputs": outputs,
    });
    crate::io::atomic::write_bytes(&manifest_path, crate::io::json::to_pretty(&manifest)?.as_bytes())?;
    let said: Vec<String> = Part::ALL
        .iter()
        .zip(&outcomes)
        .map(|(p, o)| match o {
            Outcome::Ran(s) => format!("{} {s:.1} s", p.name()),
            other => format!("{} {}", p.name(), other.word()),
        })
        .collect();
    report.say(&format!(
        "run: {}; summary sheet {}, summary {} and manifest {} ({} files, {:.1} s in all)",
        said.join(", "),
        sheet_path.display(),
        text_path.display(),
        manifest_path.display(),
        outputs.len() + 1,
        started.elapsed().as_secs_f64()
    ));
    anyhow::ensure!(
        ran,
        "{scene_label}: no part could run (see the notes); wrote {} and {}",
        text_path.display(),
        manifest_path.display()
    );
    Ok(Some(manifest))
}
