//! The `propsim` command line: argument parsing and dispatch. Each subcommand lives in its
//! own file; all report errors as one line naming the file and the problem.
//!
//! Under MPI every process runs the same command on its share of the work; only rank 0
//! prints ([`say!`], [`tell!`], progress bars) and writes outputs.

use std::sync::atomic::{AtomicBool, Ordering};

static SPEAKS: AtomicBool = AtomicBool::new(true);

/// Whether this process prints: a single process, or rank 0 of an MPI job.
pub fn speaks() -> bool {
    SPEAKS.load(Ordering::Relaxed)
}

/// `println!` on the process that speaks for the job, checked ([`crate::io::stdout`]).
macro_rules! say {
    ($($t:tt)*) => { if $crate::cli::speaks() { $crate::outln!($($t)*) } };
}

/// `eprintln!` on the process that speaks for the job.
macro_rules! tell {
    ($($t:tt)*) => { if $crate::cli::speaks() { $crate::errln!($($t)*) } };
}

/// Loads a scene with extra materials files, prints its warnings (root only) and builds its
/// world: the first step of every simulating command.
fn load_world(
    scene_path: &std::path::Path,
    options: &crate::scene::LoadOptions,
) -> anyhow::Result<crate::scene::World> {
    let scene = crate::scene::load(scene_path, options)?;
    for w in &scene.warnings {
        tell!("warning: {w}");
    }
    Ok(crate::scene::World::build(scene))
}

pub mod acoustic;
pub mod auralize;
pub mod bench_acoustic;
pub mod bench_render;
pub mod bench_trace;
pub mod info;
pub mod progress;
pub mod render;
pub mod rf;
pub mod run;

use crate::dist::Cluster;

use clap::{Arg, Parser, Subcommand};

/// propsim: one ray-tracing core for images, room acoustics and radio coverage.
#[derive(Parser, Debug)]
#[command(name = "propsim", version, about, long_about = None)]
#[command(mut_args = allow_negative_numbers, mut_subcommands = allow_negative_numbers_in)]
pub struct Cli {
    /// Worker threads (default: all cores).
    #[arg(long, global = true)]
    pub threads: Option<usize>,
    #[command(subcommand)]
    pub command: Command,
}

#[derive(Subcommand, Debug)]
pub enum Command {
    /// Geometry and material report: triangles, bounds, areas, volume, closedness, and
    /// whether every source and receiver is inside the room.
    Info(info::InfoArgs),
    /// The picture, the sound and the radio coverage of one scene in one directory, with a
    /// summary sheet (summary.png), a summary (summary.txt) and a manifest of every file
    /// written (manifest.json); a part that cannot run is skipped with a note saying why.
    Run(run::RunArgs),
    /// Room acoustics: impulse responses (WAV), energy histograms and ISO 3382-1 parameters
    /// for every source-receiver pair, plus Sabine and Eyring estimates.
    Acoustic(acoustic::AcousticArgs),
    /// Convolve a dry signal with an impulse response (mono, binaural or Ambisonic), or
    /// write a synthetic dry test signal with --make-dry.
    Auralize(auralize::AuralizeArgs),
    /// Render an image (PNG or EXR) of a scene with a chosen integrator.
    Render(render::RenderArgs),
    /// Radio coverage map (coverage.csv, coverage.png, coverage.json) and coherent point
    /// receivers, with ITU-R P.2040 materials.
    Rf(Box<rf::RfArgs>),
    /// Benchmarks.
    #[command(subcommand)]
    Bench(BenchCommand),
}

#[derive(Subcommand, Debug)]
pub enum BenchCommand {
    /// Trace a ray file (or generated rays) against a mesh: build time, closest-hit and
    /// occlusion Mrays/s, and a checksum of the hit triangle indices.
    Trace(bench_trace::TraceArgs),
    /// Render the classic Cornell box (256x256, depth 8) several times: samples/s, Mrays/s
    /// and wall time (median).
    Render(bench_render::BenchRenderArgs),
    /// Time the whole acoustic job (shoebox and BRAS CR2 by default): wall time and rays/s.
    Acoustic(bench_acoustic::BenchAcousticArgs),
    /// Radio coverage map speed: wall time and rays/s (street canyon, 1 m cells, depth 3).
    Rf(rf::BenchRfArgs),
}

/// Lets a flag that takes a value take a negative number (`--temperature-c -5`). Lists such
/// as `--receiver -1,2,3` are not numbers to clap: their flags also set `allow_hyphen_values`.
fn allow_negative_numbers(arg: Arg) -> Arg {
    let takes_value = arg.get_action().takes_values() && !arg.is_positional();
    arg.allow_negative_numbers(takes_value)
}

/// [`allow_negative_numbers`] for every flag of `cmd` and of its subcommands, at any depth.
fn allow_negative_numbers_in(cmd: clap::Command) -> clap::Command {
    cmd.mut_args(allow_negative_numbers).mut_subcommands(allow_negative_numbers_in)
}

/// The `propsim` command: parses the process's arguments, runs the command as this process's
/// share of the job (one process, or one rank under MPI) and returns the exit status; every
/// error is one line on standard error.
pub fn command_line() -> std::process::ExitCode {
    use std::process::ExitCode;
    // `propsim ... | head` ends quietly, like other Unix tools, instead of panicking on EPIPE.
    sigpipe::reset();
    let cli = match Cli::try_parse() {
        Ok(cli) => cli,
        // Usage errors as clap writes them: the problem, a "did you mean" tip where there is
        // one, and the usage line; help and version print as usual.
        Err(e) if e.use_stderr() => {
            let _ = e.print();
            return ExitCode::from(2);
        }
        Err(e) => e.exit(),
    };
    // One process, or this process's place in an MPI job (`--features mpi`).
    let cluster = match crate::dist::Cluster::from_environment() {
        Ok(c) => c,
        Err(e) => {
            crate::errln!("error: {}", format!("{e:#}").replace('\n', " "));
            return ExitCode::FAILURE;
        }
    };
    let result = run(cli, &cluster);
    // Standard output is checked too: a full disk behind `> file` is an error like any other;
    // a reader that went away (`| head`, with SIGPIPE ignored by the parent) ends us quietly.
    let result = match (result, crate::io::stdout::finish()) {
        (Err(e), _) => Err(e),
        (Ok(()), Err(e)) if e.kind() == std::io::ErrorKind::BrokenPipe => return ExitCode::SUCCESS,
        (Ok(()), Err(e)) => Err(anyhow::anyhow!("cannot write standard output: {e}")),
        (Ok(()), Ok(())) => Ok(()),
    };
    match result {
        Ok(()) => {
            if cluster.is_root() && cluster.size() > 1 {
                let c = cluster.reduce_cost();
                crate::errln!(
                    "mpi: {} processes; rank 0 waited {:.3} s for the others and reduced {:.2} MB in {:.3} s",
                    cluster.size(),
                    c.wait_s,
                    c.bytes as f64 / 1e6,
                    c.reduce_s
                );
            }
            ExitCode::SUCCESS
        }
        Err(e) => {
            // Every process of a job sees the same inputs and fails alike: rank 0 reports.
            if cluster.is_root() {
                crate::errln!("error: {}", format!("{e:#}").replace('\n', " "));
            }
            ExitCode::FAILURE
        }
    }
}

/// Runs the command line as one process of `cluster`; the error, if any, is for `main` to
/// print on one line (on rank 0).
pub fn run(cli: Cli, cluster: &Cluster) -> anyhow::Result<()> {
    SPEAKS.store(cluster.is_root(), Ordering::Relaxed);
    let threads = match cli.threads {
        Some(n) => {
            anyhow::ensure!((1..=4096).contains(&n), "--threads {n}: must be between 1 and 4096");
            Some(n)
        }
        // Processes of one job on one machine share its cores instead of each taking all.
        None => (cluster.size() > 1).then(|| cluster.default_threads()),
    };
    if let Some(n) = threads {
        rayon::ThreadPoolBuilder::new().num_threads(n).build_global()?;
    }
    dispatch(cli.command, cluster)
}

/// Runs one command (without touching the thread pool, so `run` can call it again).
pub fn dispatch(command: Command, cluster: &Cluster) -> anyhow::Result<()> {
    match command {
        Command::Acoustic(args) => acoustic::run(&args, cluster),
        Command::Render(args) => render::run(&args, cluster),
        Command::Rf(args) => rf::run(&args, cluster),
        Command::Run(args) => run::run(&args, cluster),
        // Reports and benchmarks are not split: rank 0 does them alone.
        _ if !cluster.is_root() => Ok(()),
        Command::Info(args) => info::run(&args),
        Command::Auralize(args) => auralize::run(&args),
        Command::Bench(BenchCommand::Trace(args)) => bench_trace::run(&args),
        Command::Bench(BenchCommand::Acoustic(args)) => bench_acoustic::run(&args),
        Command::Bench(BenchCommand::Render(args)) => bench_render::run(&args),
        Command::Bench(BenchCommand::Rf(args)) => rf::bench(&args),
    }
}

pub use crate::scene::parse_point;

/// The scene used when a command is given none.
pub const DEFAULT_SCENE: &str = "builtin:bras_cr2";

#[cfg(test)]
mod tests;
