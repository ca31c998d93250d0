//! `propsim rf SCENE`: a radio coverage map (CSV, PNG, JSON summary) and coherent point
//! receivers; `propsim bench rf`: the ray rate on the street canyon.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use crate::dist::Cluster;
use crate::rf::{RfConfig, RfOptions, simulate};

#[derive(Args, Debug, Clone)]
pub struct RfArgs {
    /// Scene file (.toml), bare OBJ, or builtin:NAME.
    pub scene: PathBuf,
    #[command(flatten)]
    pub options: RfOptions,
    #[command(flatten)]
    pub load: crate::scene::LoadOptions,
    /// Output directory.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
}

/// Runs `propsim rf`: simulate, then write coverage.csv, coverage.png and coverage.json.
pub fn run(args: &RfArgs, cluster: &Cluster) -> anyhow::Result<()> {
    let world = super::load_world(&args.scene, &args.load)?;
    let scene_name = args.scene.display().to_string();
    let plan = crate::rf::job::plan(&world, &args.options, &scene_name)?;
    for w in &plan.warnings {
        tell!("warning: {w}");
    }
    // The output directory is checked before the (possibly long) simulation.
    if cluster.is_root() {
        crate::io::atomic::check_writable(&args.out, true)?;
    }
    let done = crate::rf::job::execute(
        &world,
        &plan,
        Some(&args.out),
        &scene_name,
        cluster,
        &super::progress::Terminal,
    )?;
    let Some(done) = done else { return Ok(()) };
    let config = &plan.config;
    let names: Vec<String> = done
        .files
        .iter()
        .filter_map(|f| f.file_name().map(|n| n.to_string_lossy().into_owned()))
        .filter(|n| !n.starts_with("coverage_") && !n.starts_with("pdp_"))
        .collect();
    say!("wrote {} in {}", names.join(", "), args.out.display());
    if config.transmitters.len() > 1 {
        say!(
            "wrote coverage_TX.png for each of {} transmitters; coverage.csv has best_server, best_rx_power_dbm, sinr_db (noise {:.2} dBm) and rx_power_dbm_TX",
            config.transmitters.len(),
            config.noise.noise_power_dbm
        );
    }
    if !config.receivers.is_empty() {
        say!("wrote a power-delay profile pdp_RECEIVER.png for each of {} receivers", config.receivers.len());
    }
    Ok(())
}

#[derive(Args, Debug)]
pub struct BenchRfArgs {
    /// Scene (default: the street canyon).
    #[arg(default_value = "builtin:street_canyon")]
    pub scene: PathBuf,
    /// Rays per run.
    #[arg(long, default_value_t = 10_000_000)]
    pub rays: u64,
    #[arg(long, default_value_t = 1.0)]
    pub cell_m: f64,
    #[arg(long, default_value_t = 3)]
    pub max_depth: u32,
    /// Timed runs; medians are reported.
    #[arg(long, default_value_t = 3)]
    pub repeat: usize,
    /// Extra materials file(s), as for `propsim rf`.
    #[arg(long = "materials")]
    pub materials: Vec<PathBuf>,
}

/// CPU time (user + system) of this process so far, seconds, from /proc (Linux); `None`
/// elsewhere.
fn process_cpu_seconds() -> Option<f64> {
    let stat = std::fs::read_to_string("/proc/self/stat").ok()?;
    // Fields after the command name (which is in parentheses and may hold spaces).
    let rest = &stat[stat.rfind(')')? + 2..];
    let f: Vec<&str> = rest.split_whitespace().collect();
    let ticks = f.get(11)?.parse::<f64>().ok()? + f.get(12)?.parse::<f64>().ok()?;
    // USER_HZ is 100 on every Linux platform Rust supports.
    Some(ticks / 100.0)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Runs the coverage map `repeat` times and prints the median wall time and rays/s.
pub fn bench(args: &BenchRfArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        (1..=1000).contains(&args.repeat),
        "--repeat {}: must be between 1 and 1000",
        args.repeat
    );
    let world = super::load_world(
        &args.scene,
        &crate::scene::LoadOptions { materials_files: args.materials.clone(), ..Default::default() },
    )?;
    let name = args.scene.display().to_string();
    let overrides = RfOptions {
        rays: Some(args.rays),
        cell_m: Some(args.cell_m),
        max_depth: Some(args.max_depth),
        no_receivers: true,
        ..RfOptions::default()
    };
    let mut config = RfConfig::from_scene(&world, &overrides).map_err(|e| anyhow::anyhow!("{name}: {e}"))?;
    config.transmitters.truncate(1);
    let mut walls = Vec::new();
    let mut cpus = Vec::new();
    let mut reached = 0;
    let mut segments = 0;
    for _ in 0..args.repeat {
        let t0 = Instant::now();
        let c0 = process_cpu_seconds();
        let r = simulate(&world, &config, &|_| {})?;
        walls.push(t0.elapsed().as_secs_f64());
        if let (Some(a), Some(b)) = (c0, process_cpu_seconds()) {
            cpus.push(b - a);
        }
        reached = r.coverage.paths.iter().filter(|&&p| p > 0).count();
        segments = r.transmitters.iter().map(|t| t.segments).sum::<u64>();
    }
    let wall = median(walls.clone());
    say!(
        "bench rf: {name}, {} x {} cells of {} m, {} rays, depth {}, {} threads",
        config.grid.nx,
        config.grid.ny,
        crate::io::tidy(config.grid.cell_m, 6),
        config.rays,
        config.max_depth,
        rayon::current_num_threads()
    );
    say!(
        "wall time {:.3} s (median of {}; runs {} s), {:.2} Mrays/s, {:.1} M ray segments/s ({} segments), {} cells reached",
        wall,
        args.repeat,
        walls.iter().map(|w| format!("{w:.3}")).collect::<Vec<_>>().join(", "),
        config.rays as f64 / wall / 1e6,
        segments as f64 / wall / 1e6,
        segments,
        reached
    );
    if !cpus.is_empty() {
        let cpu = median(cpus);
        say!(
            "cpu time {cpu:.2} s (median): {:.2} Mrays per CPU-second; {:.0} % of the threads' time \
             was ours (below 100 % when other processes share the cores)",
            config.rays as f64 / cpu / 1e6,
            100.0 * cpu / (wall * rayon::current_num_threads() as f64)
        );
    }
    Ok(())
}
