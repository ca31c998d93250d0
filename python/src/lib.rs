//! `propsim._propsim`: the Rust side of the Python module. Each function takes a scene and the
//! Python keyword options, turns them into the command line's words and parses them with clap,
//! as the command line does ([`Cli`], [`command`]), into the library's option types (`RenderOptions`,
//! `AcousticOptions`, `RfOptions`, `RunOptions`), so that the defaults, the checks and the
//! error messages are exactly the CLI's (clap's range checks and messages included, which a
//! serde route would not give); then it runs the library's jobs (`plan`, then `execute`) in
//! memory, the GIL released, their notes and warnings collected (`io::report::Collect`), and
//! returns a dict of numpy arrays and plain values. With `out=DIR` it also writes the files
//! the CLI writes.
//!
//! Every error, a panic included, reaches Python as `propsim.PropsimError` carrying the one
//! line the CLI would print after `error: `.

use std::panic::AssertUnwindSafe;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::anyhow;
use clap::Parser as _;
use numpy::IntoPyArray;
use pyo3::create_exception;
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::{PyBool, PyDict, PyList, PyString, PyTuple};

use propsim::dist::Cluster;
use propsim::io::report::Collect;
use propsim::scene::World;

create_exception!(
    _propsim,
    PropsimError,
    PyValueError,
    "A propsim error: bad options, a scene that does not load, a simulation that cannot run. \
     The message is the one line the command line prints."
);

/// The command line of one call: propsim's CLI (private to the binary) rebuilt around the
/// library's option types, with the same flags, defaults, checks and clap messages. The
/// scene is always given (the Python functions hold the CLI's default scenes).
#[derive(clap::Parser, Debug)]
#[command(name = "propsim")]
struct Cli {
    /// Worker threads (default: all cores).
    #[arg(long, global = true)]
    threads: Option<usize>,
    #[command(subcommand)]
    command: Command,
}

#[derive(clap::Subcommand, Debug)]
enum Command {
    Render(RenderArgs),
    Acoustic(AcousticArgs),
    Rf(Box<RfArgs>),
    Run(RunArgs),
}

#[derive(clap::Args, Debug)]
struct RenderArgs {
    scene: PathBuf,
    #[arg(short = 'o', long = "output", default_value = "out/render.png")]
    output: PathBuf,
    #[command(flatten)]
    options: propsim::render::RenderOptions,
    #[command(flatten)]
    load: propsim::scene::LoadOptions,
}

#[derive(clap::Args, Debug)]
struct AcousticArgs {
    scene: PathBuf,
    #[command(flatten)]
    options: propsim::acoustic::AcousticOptions,
    #[command(flatten)]
    load: propsim::scene::LoadOptions,
    #[arg(long, default_value = "out")]
    out: PathBuf,
}

#[derive(clap::Args, Debug)]
struct RfArgs {
    scene: PathBuf,
    #[command(flatten)]
    options: propsim::rf::RfOptions,
    #[command(flatten)]
    load: propsim::scene::LoadOptions,
    #[arg(long, default_value = "out")]
    out: PathBuf,
}

#[derive(clap::Args, Debug)]
struct RunArgs {
    scene: PathBuf,
    #[arg(long, default_value = "out")]
    out: PathBuf,
    #[command(flatten)]
    options: propsim::run::RunOptions,
    #[command(flatten)]
    load: propsim::scene::LoadOptions,
}

/// Which simulator a call is for: its subcommand, and where its output goes.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Sim {
    Render,
    Acoustic,
    Rf,
    Run,
}

impl Sim {
    fn command(self) -> &'static str {
        match self {
            Sim::Render => "render",
            Sim::Acoustic => "acoustic",
            Sim::Rf => "rf",
            Sim::Run => "run",
        }
    }
}

/// A parsed call: the command with every default filled in by clap, the thread count, and
/// whether files are to be written (`out` or, for the render, `output` given).
struct Call {
    command: Command,
    threads: Option<usize>,
    writes: bool,
}

fn error(message: impl Into<String>) -> PyErr {
    PropsimError::new_err(message.into())
}

/// The one line the CLI prints for `e` (after `error: `).
fn one_line(e: &anyhow::Error) -> String {
    format!("{e:#}").replace('\n', " ")
}

/// A numeric Python value (int, float or a numpy scalar), not a bool or a string.
fn is_number(v: &Bound<'_, PyAny>) -> bool {
    !v.is_instance_of::<PyBool>()
        && !v.is_instance_of::<PyString>()
        && v.hasattr("__float__").unwrap_or(false)
        && !v.hasattr("__len__").unwrap_or(false)
}

/// One value as a command-line word: a number or string as `str()` gives it, a path by
/// `os.fspath`, a sequence of numbers (a point, `(1, 2, 3)`) joined with commas.
fn word(v: &Bound<'_, PyAny>) -> PyResult<String> {
    if v.is_instance_of::<PyString>() {
        return v.extract();
    }
    if v.hasattr("__fspath__")? {
        return v.call_method0("__fspath__")?.str()?.extract();
    }
    if !is_number(v)
        && let Ok(items) = v.try_iter()
    {
        let parts =
            items.map(|i| i.and_then(|i| i.str()?.extract::<String>())).collect::<PyResult<Vec<_>>>()?;
        return Ok(parts.join(","));
    }
    v.str()?.extract()
}

/// Whether `v` stands for several values of a repeatable flag: a list or tuple whose items
/// are not all numbers (`[(1, 2, 3), (4, 5, 6)]`, `["a.toml", "b.toml"]`). A sequence of
/// numbers is one point.
fn is_many(v: &Bound<'_, PyAny>) -> bool {
    if v.is_instance_of::<PyString>() || v.hasattr("__fspath__").unwrap_or(false) || is_number(v) {
        return false;
    }
    let Ok(items) = v.try_iter() else { return false };
    let items: Vec<_> = items.flatten().collect();
    !items.iter().all(is_number)
}

/// The Python options as the command line's words: `rays=1000` is `--rays=1000`,
/// `no_air=True` is `--no-air` (`False` and `None` are left out), `tx=(1, 2, 3)` is
/// `--tx=1,2,3` and `sources=[(1, 2, 3), (4, 5, 6)]` is `--source=1,2,3 --source=4,5,6`.
/// `out=DIR` writes where the CLI writes (`DIR/render.png` for the render); without it
/// nothing is written (but `propsim.run`, whose default is `out="out"`, always writes).
///
/// This is the one place that knows how Python options map to the CLI (with [`Cli`] and
/// [`command`]).
fn words(sim: Sim, scene: &str, options: &Bound<'_, PyDict>) -> PyResult<(Vec<String>, bool)> {
    let mut v = vec!["propsim".to_string(), sim.command().to_string(), scene.to_string()];
    let mut writes = sim == Sim::Run;
    for (key, value) in options.iter() {
        let key: String = key.extract()?;
        // None, like an empty list of points, leaves the flag out: the default.
        if value.is_none()
            || ((value.is_instance_of::<PyList>() || value.is_instance_of::<PyTuple>()) && value.len()? == 0)
        {
            continue;
        }
        // The Python names of the repeatable flags are plurals.
        let flag = match (sim, key.as_str()) {
            (Sim::Acoustic, "sources") => "source".to_string(),
            (Sim::Acoustic, "receivers") => "receiver".to_string(),
            (Sim::Render, "out") => {
                writes = true;
                let dir = word(&value)?;
                v.push(format!("--output={}", Path::new(&dir).join("render.png").display()));
                continue;
            }
            (Sim::Render, "output") | (_, "out") => {
                writes = true;
                key.replace('_', "-")
            }
            _ => key.replace('_', "-"),
        };
        if value.is_instance_of::<PyBool>() {
            if value.extract::<bool>()? {
                v.push(format!("--{flag}"));
            }
        } else if is_many(&value) {
            for item in value.try_iter()? {
                v.push(format!("--{flag}={}", word(&item?)?));
            }
        } else {
            v.push(format!("--{flag}={}", word(&value)?));
        }
    }
    if sim == Sim::Render && options.contains("out")? && options.contains("output")? {
        return Err(error("give out (a directory) or output (a file), not both"));
    }
    Ok((v, writes))
}

/// Parses the options with the CLI's parser; a usage error is the CLI's first line.
fn command(sim: Sim, scene: &str, options: &Bound<'_, PyDict>) -> PyResult<Call> {
    let (v, writes) = words(sim, scene, options)?;
    let cli = Cli::try_parse_from(&v).map_err(|e| {
        if let Some(message) = unknown_option(&e) {
            return error(message);
        }
        let text = e.render().to_string();
        let first = text.lines().map(str::trim).find(|l| !l.is_empty()).unwrap_or("invalid arguments");
        error(first.strip_prefix("error:").unwrap_or(first).trim())
    })?;
    Ok(Call { command: cli.command, threads: cli.threads, writes })
}

/// An unknown keyword named as Python spells it, with clap's nearest option as a suggestion:
/// `unknown option 'rayz' (--rayz); did you mean 'rays'?`.
fn unknown_option(e: &clap::Error) -> Option<String> {
    use clap::error::{ContextKind, ContextValue, ErrorKind};
    if e.kind() != ErrorKind::UnknownArgument {
        return None;
    }
    let text = |v: &ContextValue| match v {
        ContextValue::String(s) => Some(s.clone()),
        ContextValue::Strings(v) => v.first().cloned(),
        _ => None,
    };
    let flag = text(e.get(ContextKind::InvalidArg)?)?;
    let flag = flag.split('=').next().unwrap_or(&flag).to_string();
    let keyword = |f: &str| f.trim_start_matches('-').replace('-', "_");
    let mut m = format!("unknown option '{}' ({flag})", keyword(&flag));
    if let Some(s) = e.get(ContextKind::SuggestedArg).and_then(text) {
        m.push_str(&format!("; did you mean '{}'?", keyword(&s)));
    }
    Some(m)
}

/// Runs `f` without the GIL on `threads` worker threads (default: rayon's global pool, all
/// cores), turning its error or panic into a `PropsimError`.
fn detached<T: Send>(
    py: Python<'_>,
    threads: Option<usize>,
    f: impl FnOnce() -> anyhow::Result<T> + Send,
) -> PyResult<T> {
    let outcome = py.detach(|| {
        std::panic::catch_unwind(AssertUnwindSafe(|| match threads {
            None => f(),
            Some(n) => {
                anyhow::ensure!((1..=4096).contains(&n), "--threads {n}: must be between 1 and 4096");
                rayon::ThreadPoolBuilder::new().num_threads(n).build()?.install(f)
            }
        }))
    });
    match outcome {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(error(one_line(&e))),
        Err(panic) => {
            let what = panic
                .downcast_ref::<String>()
                .cloned()
                .or_else(|| panic.downcast_ref::<&str>().map(|s| s.to_string()))
                .unwrap_or_default();
            Err(error(format!("internal error: {what}")))
        }
    }
}

/// Loads a scene as the CLI does (extra materials, the model's frame) and builds its world;
/// the scene's warnings are returned instead of printed.
fn load_world(scene: &Path, options: &propsim::scene::LoadOptions) -> anyhow::Result<(World, Vec<String>)> {
    let scene = propsim::scene::load(scene, options)?;
    let warnings = scene.warnings.clone();
    Ok((World::build(scene), warnings))
}

/// A JSON value as Python objects (dicts, lists, floats; `null` as `None`).
fn json_to_py<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyAny>> {
    let text = serde_json::to_string(value).map_err(|e| error(format!("internal error: {e}")))?;
    py.import("json")?.call_method1("loads", (text,))
}

/// A JSON object as a Python dict, to which the arrays are then added.
fn json_dict<'py>(py: Python<'py>, value: &serde_json::Value) -> PyResult<Bound<'py, PyDict>> {
    Ok(json_to_py(py, value)?.cast_into::<PyDict>()?)
}

fn to_json(value: &impl serde::Serialize) -> anyhow::Result<serde_json::Value> {
    Ok(serde_json::to_value(value)?)
}

/// Files written, as strings.
fn paths(files: &[PathBuf]) -> Vec<String> {
    files.iter().map(|p| p.display().to_string()).collect()
}

/// What a job reported (the CLI's `note:` and `warning:` lines), with `first` before them.
fn reported(report: &Collect, first: Vec<String>) -> (Vec<String>, Vec<String>) {
    let take = |m: &std::sync::Mutex<Vec<String>>| m.lock().map(|v| v.clone()).unwrap_or_default();
    let mut warnings = first;
    warnings.extend(take(&report.warnings));
    (take(&report.notes), warnings)
}

/// `propsim render SCENE [options]` in memory: the image as linear radiance.
#[pyfunction]
fn render<'py>(py: Python<'py>, scene: &str, options: &Bound<'py, PyDict>) -> PyResult<Bound<'py, PyDict>> {
    let call = command(Sim::Render, scene, options)?;
    let Command::Render(args) = call.command else { return Err(error("internal error: not a render")) };
    let writes = call.writes;
    let (image, info) = detached(py, call.threads, move || {
        let output = writes.then_some(args.output.as_path());
        // Checked before the (possibly long) render, as the CLI does.
        if let Some(o) = output {
            propsim::render::film::ImageFormat::from_path(o)?;
            propsim::io::atomic::check_writable(o, false)?;
        }
        let (world, warnings) = load_world(&args.scene, &args.load)?;
        let label = args.scene.display().to_string();
        let plan = propsim::render::job::plan(&world, &args.options, &label)?;
        let report = Collect::default();
        let out = propsim::render::job::execute(&world, &plan, output, &Cluster::solo(), &report)?
            .ok_or_else(|| anyhow!("internal error: a single process returned no image"))?;
        let (_, mut warnings) = reported(&report, warnings);
        warnings.splice(0..0, plan.warnings.iter().cloned());
        let (s, cam) = (&plan.settings, &plan.camera);
        let info = serde_json::json!({
            "scene": label,
            "settings": {
                "width": s.width,
                "height": s.height,
                "spp": s.spp,
                "max_depth": s.max_depth,
                "integrator": s.integrator.name(),
                "seed": s.seed,
                "exposure_ev": s.display.exposure_ev,
                "tone_map": s.display.tone_map.name(),
                "clamp_indirect": s.clamp_indirect,
            },
            "camera": {
                "eye": cam.eye.to_array(),
                "forward": cam.forward.to_array(),
                "up": cam.up.to_array(),
                "fov_deg": 2.0 * cam.tan_half_fov.atan().to_degrees(),
            },
            "seconds": out.seconds,
            "samples": out.samples,
            "rays": out.rays,
            "warnings": warnings,
            "files": output.map(|o| vec![o.display().to_string()]).unwrap_or_default(),
        });
        Ok((out.film.to_array(), info))
    })?;
    let d = json_dict(py, &info)?;
    d.set_item("image", image.into_pyarray(py))?;
    Ok(d)
}

/// `propsim acoustic SCENE [options]` in memory: histograms, ISO 3382-1 parameters and the
/// impulse responses the WAV files hold.
#[pyfunction]
fn acoustic<'py>(py: Python<'py>, scene: &str, options: &Bound<'py, PyDict>) -> PyResult<Bound<'py, PyDict>> {
    let call = command(Sim::Acoustic, scene, options)?;
    let Command::Acoustic(args) = call.command else { return Err(error("internal error: not acoustic")) };
    let writes = call.writes;
    let (result, irs, info) = detached(py, call.threads, move || {
        let started = Instant::now();
        let (world, mut warnings) = load_world(&args.scene, &args.load)?;
        let label = args.scene.display().to_string();
        warnings.extend(world.sheet_warning(&label));
        let plan = propsim::acoustic::plan(&world, &args.options, &label)?;
        let out = writes.then_some(args.out.as_path());
        if let Some(o) = out {
            propsim::io::atomic::check_writable(o, true)?;
        }
        let report = Collect::default();
        let done =
            propsim::acoustic::execute(&world, &plan, out, &label, &Cluster::solo(), &report, started)?
                .ok_or_else(|| anyhow!("internal error: a single process returned no result"))?;
        let (_, warnings) = reported(&report, warnings);
        let result = done.result;
        let seed = plan.settings.seed;
        // The impulse responses of the WAV files, with their seeds.
        let irs: Vec<Vec<f32>> = result
            .pairs
            .iter()
            .enumerate()
            .map(|(i, p)| {
                propsim::acoustic::impulse_response::synthesize(
                    &p.histogram,
                    result.bin_s,
                    result.volume_m3,
                    result.speed_of_sound_m_s,
                    seed ^ (i as u64) << 20,
                )
            })
            .collect();
        let mut info = to_json(&result)?;
        let extra = serde_json::json!({
            "scene": label,
            "sources": plan.sources,
            "receivers": plan.receivers,
            "notes": plan.notes,
            "metric_names": &propsim::acoustic::output::METRICS_COLUMNS[3..],
            "sample_rate_hz": propsim::acoustic::impulse_response::SAMPLE_RATE_HZ,
            "seconds": started.elapsed().as_secs_f64(),
            "warnings": warnings,
            "files": paths(&done.files),
        });
        if let (Some(o), serde_json::Value::Object(e)) = (info.as_object_mut(), extra) {
            o.extend(e);
        }
        Ok((result, irs, info))
    })?;
    let d = json_dict(py, &info)?;
    d.set_item("histogram", result.histogram_array().into_pyarray(py))?;
    d.set_item("metrics", propsim::acoustic::output::metrics_array(&result).into_pyarray(py))?;
    let irs = PyList::new(py, irs.into_iter().map(|ir| ir.into_pyarray(py)))?;
    d.set_item("impulse_responses", irs)?;
    Ok(d)
}

/// `propsim rf SCENE [options]` in memory: the coverage map per transmitter and, with point
/// receivers, their paths and channel frequency response.
#[pyfunction]
fn rf<'py>(py: Python<'py>, scene: &str, options: &Bound<'py, PyDict>) -> PyResult<Bound<'py, PyDict>> {
    let call = command(Sim::Rf, scene, options)?;
    let Command::Rf(args) = call.command else { return Err(error("internal error: not rf")) };
    let writes = call.writes;
    let (config, result, info) = detached(py, call.threads, move || {
        let (world, warnings) = load_world(&args.scene, &args.load)?;
        let label = args.scene.display().to_string();
        let plan = propsim::rf::job::plan(&world, &args.options, &label)?;
        let out = writes.then_some(args.out.as_path());
        if let Some(o) = out {
            propsim::io::atomic::check_writable(o, true)?;
        }
        let report = Collect::default();
        let done = propsim::rf::job::execute(&world, &plan, out, &label, &Cluster::solo(), &report)?
            .ok_or_else(|| anyhow!("internal error: a single process returned no result"))?;
        let (_, mut warnings) = reported(&report, warnings);
        warnings.splice(0..0, plan.warnings.iter().cloned());
        let config = plan.config;
        let result = done.result;
        let summary = propsim::rf::output::summary(&label, &config, &result, paths(&done.files));
        let g = config.grid;
        let info = serde_json::json!({
            "scene": label,
            "grid": {
                "min_m": g.min_m,
                "cell_m": g.cell_m,
                "nx": g.nx,
                "ny": g.ny,
                "height_m": g.height_m,
            },
            "transmitters": config.transmitters.iter().map(|t| &t.name).collect::<Vec<_>>(),
            "receivers": config.receivers.iter().map(|r| &r.name).collect::<Vec<_>>(),
            "summary": to_json(&summary)?,
            "paths_columns": propsim::rf::output::PATHS_NPY_COLUMNS,
            "seconds": result.seconds,
            "warnings": warnings,
            "files": paths(&done.files),
        });
        Ok((config, result, info))
    })?;
    let d = json_dict(py, &info)?;
    let g = config.grid;
    let centres = |n: usize, lo: f64| (0..n).map(|i| lo + (i as f64 + 0.5) * g.cell_m).collect::<Vec<f64>>();
    d.set_item("x_m", centres(g.nx, g.min_m[0]).into_pyarray(py))?;
    d.set_item("y_m", centres(g.ny, g.min_m[1]).into_pyarray(py))?;
    d.set_item("path_gain", result.path_gain_array().into_pyarray(py))?;
    if !config.receivers.is_empty() {
        d.set_item("paths", propsim::rf::output::paths_array(&config, &result).into_pyarray(py))?;
        if let Some(spec) = &config.cfr {
            let offsets: Vec<f64> = (0..spec.points).map(|i| spec.offset_hz(i)).collect();
            d.set_item("cfr_offsets_hz", offsets.into_pyarray(py))?;
            d.set_item("cfr", propsim::rf::output::cfr_array(&config, &result, spec).into_pyarray(py))?;
        }
    }
    Ok(d)
}

/// `propsim run SCENE [options]`: the combined job, writing its files; returns the manifest
/// (with the notes and warnings the CLI would print added as `notes` and `warnings`).
#[pyfunction]
fn run<'py>(py: Python<'py>, scene: &str, options: &Bound<'py, PyDict>) -> PyResult<Bound<'py, PyAny>> {
    let call = command(Sim::Run, scene, options)?;
    let Command::Run(args) = call.command else { return Err(error("internal error: not run")) };
    let manifest = detached(py, call.threads, move || {
        let (world, mut warnings) = load_world(&args.scene, &args.load)?;
        let label = args.scene.display().to_string();
        warnings.extend(world.sheet_warning(&label));
        let report = Collect::default();
        let manifest = propsim::run::run(
            &world,
            &args.options,
            &label,
            &args.load.materials_files,
            &args.out,
            &Cluster::solo(),
            &report,
        )?
        .ok_or_else(|| anyhow!("internal error: a single process returned no manifest"))?;
        let (notes, warnings) = reported(&report, warnings);
        let mut manifest = manifest;
        if let Some(m) = manifest.as_object_mut() {
            m.insert("notes".into(), notes.into());
            m.insert("warnings".into(), warnings.into());
        }
        Ok(manifest)
    })?;
    json_to_py(py, &manifest)
}

/// The version (propsim's and this module's are released together).
fn propsim_version() -> String {
    env!("CARGO_PKG_VERSION").to_string()
}

/// The extension module: four functions, the error type and the library's version.
#[pymodule]
fn _propsim(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add("PropsimError", m.py().get_type::<PropsimError>())?;
    m.add("__version__", propsim_version())?;
    m.add_function(wrap_pyfunction!(render, m)?)?;
    m.add_function(wrap_pyfunction!(acoustic, m)?)?;
    m.add_function(wrap_pyfunction!(rf, m)?)?;
    m.add_function(wrap_pyfunction!(run, m)?)?;
    Ok(())
}
