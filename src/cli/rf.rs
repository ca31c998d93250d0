//! `propsim rf SCENE`: a radio coverage map (CSV, PNG, JSON summary) and coherent point
//! receivers; `propsim bench rf`: the ray rate on the street canyon.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context as _;
use clap::Args;

use crate::dist::Cluster;
use crate::rf::output::{
    best_servers, summary, write_coverage_csv, write_receiver_outputs, write_summary_json,
};
use crate::rf::plot::{PlotExtras, db_range, footprints, write_best_server_png, write_coverage_png};
use crate::rf::{Overrides, RfConfig, RfResult, simulate, simulate_on};
use crate::scene::World;

use crate::scene::parse_xy;

#[derive(Args, Debug, Clone)]
pub struct RfArgs {
    /// Scene file (.toml), bare OBJ, or builtin:NAME.
    pub scene: PathBuf,
    /// One transmitter at X,Y,Z instead of the scene's.
    #[arg(long, value_parser = super::parse_point, allow_hyphen_values = true)]
    pub tx: Option<[f32; 3]>,
    /// Carrier frequency, GHz (default: the scene's, else 3.5).
    #[arg(long)]
    pub freq_ghz: Option<f64>,
    /// Transmit power, dBm (default: the scene's, else 30).
    #[arg(long)]
    pub tx_power_dbm: Option<f64>,
    /// Transmit antenna: isotropic or dipole (half-wave, along z for vertical polarisation).
    #[arg(long)]
    pub antenna: Option<String>,
    /// vertical or horizontal.
    #[arg(long)]
    pub polarization: Option<String>,
    /// Dipole axis X,Y,Z (default: z for vertical, x for horizontal polarisation).
    #[arg(long, value_parser = super::parse_point, allow_hyphen_values = true)]
    pub orientation: Option<[f32; 3]>,
    /// Height of the coverage plane, m (default: the scene's, else 1.5).
    #[arg(long)]
    pub grid_height: Option<f64>,
    /// Cell size, m (default: the scene's, else 1).
    #[arg(long)]
    pub cell_m: Option<f64>,
    /// Grid corner X,Y (default: the scene's grid, else its horizontal extent).
    #[arg(long, value_parser = parse_xy, allow_hyphen_values = true)]
    pub grid_min: Option<[f64; 2]>,
    /// Opposite grid corner X,Y.
    #[arg(long, value_parser = parse_xy, allow_hyphen_values = true)]
    pub grid_max: Option<[f64; 2]>,
    /// Rays per transmitter (default: the scene's, else 10^6).
    #[arg(long)]
    pub rays: Option<u64>,
    /// Maximum number of reflections (and transmissions) per ray (default: the scene's, else 3).
    #[arg(long)]
    pub max_depth: Option<u32>,
    #[arg(long)]
    pub seed: Option<u64>,
    /// Extra materials file(s).
    #[arg(long = "materials")]
    pub materials: Vec<PathBuf>,
    #[command(flatten)]
    pub model: super::ModelArgs,
    /// Use ITU-R P.2040 fits outside their frequency ranges.
    #[arg(long)]
    pub extrapolate: bool,
    /// Walls are thin slabs that reflect and transmit (ITU-R P.2040-3 sec. 2.2.2.2): the
    /// default, so this flag changes nothing (kept for older command lines).
    #[arg(long, overrides_with = "no_transmission")]
    pub transmission: bool,
    /// Walls are opaque half-spaces that only reflect.
    #[arg(long, overrides_with = "transmission")]
    pub no_transmission: bool,
    /// No first-order edge diffraction (UTD, on by default: wedges between non-coplanar
    /// faces and rims of open surfaces, transmitter -> edge -> cell or receiver).
    #[arg(long)]
    pub no_diffraction: bool,
    /// Slab thickness of every wall, m (default: each material's thickness_m, else 0.1).
    #[arg(long)]
    pub wall_thickness_m: Option<f64>,
    /// Radio scattering coefficient S in [0, 1] of every surface (diffuse reflection; default:
    /// each material's scattering_coefficient, else 0).
    #[arg(long, allow_hyphen_values = true)]
    pub scattering_coefficient: Option<f64>,
    /// Write the channel frequency response at the point receivers (cfr.csv) over this
    /// bandwidth, MHz, centred on the carrier.
    #[arg(long)]
    pub cfr_bandwidth_mhz: Option<f64>,
    /// Frequency points of the channel frequency response (default 256).
    #[arg(long)]
    pub cfr_points: Option<u64>,
    /// Extra coherent point receiver X,Y,Z (repeatable).
    #[arg(long = "rx", value_parser = super::parse_point, allow_hyphen_values = true)]
    pub rx: Vec<[f32; 3]>,
    /// Skip the scene's point receivers.
    #[arg(long)]
    pub no_receivers: bool,
    /// Receiver noise figure of the SINR column, dB (default 7; several transmitters).
    #[arg(long, allow_hyphen_values = true)]
    pub noise_figure_db: Option<f64>,
    /// Receiver bandwidth of the SINR's thermal noise k T0 B F, MHz (default 20).
    #[arg(long, allow_hyphen_values = true)]
    pub bandwidth_mhz: Option<f64>,
    /// Bottom of the coverage pictures' colour scale, dB of path gain (default: the top
    /// minus 80 dB, or the lowest value if closer).
    #[arg(long, allow_hyphen_values = true)]
    pub vmin_db: Option<f64>,
    /// Top of the coverage pictures' colour scale, dB of path gain (default: the highest
    /// value rounded up to 5 dB).
    #[arg(long, allow_hyphen_values = true)]
    pub vmax_db: Option<f64>,
    /// Width of coverage.png, pixels.
    #[arg(long, default_value_t = 1000)]
    pub png_width: u32,
    /// Output directory.
    #[arg(long, default_value = "out")]
    pub out: PathBuf,
}

impl RfArgs {
    pub fn overrides(&self) -> Overrides {
        Overrides {
            tx: self.tx,
            freq_ghz: self.freq_ghz,
            tx_power_dbm: self.tx_power_dbm,
            antenna: self.antenna.clone(),
            polarization: self.polarization.clone(),
            orientation: self.orientation,
            grid_height_m: self.grid_height,
            cell_m: self.cell_m,
            grid_min: self.grid_min,
            grid_max: self.grid_max,
            rays: self.rays,
            max_depth: self.max_depth,
            seed: self.seed,
            extrapolate: self.extrapolate,
            no_transmission: self.no_transmission,
            no_diffraction: self.no_diffraction,
            wall_thickness_m: self.wall_thickness_m,
            scattering_coefficient: self.scattering_coefficient,
            cfr_bandwidth_mhz: self.cfr_bandwidth_mhz,
            cfr_points: self.cfr_points,
            receivers: self.rx.clone(),
            no_receivers: self.no_receivers,
            noise_figure_db: self.noise_figure_db,
            bandwidth_mhz: self.bandwidth_mhz,
            vmin_db: self.vmin_db,
            vmax_db: self.vmax_db,
        }
    }
}

/// The map's one-line summary: grid, cells reached, rays and time.
pub fn map_line(
    scene_label: &str,
    config: &RfConfig,
    s: &crate::rf::output::Summary,
    seconds: f64,
) -> String {
    format!(
        "{}: {} x {} cells of {} m at z = {} m, {} reached; {} rays/tx in {:.2} s",
        scene_label,
        config.grid.nx,
        config.grid.ny,
        crate::io::tidy(config.grid.cell_m, 6),
        crate::io::tidy(config.grid.height_m, 6),
        s.map.reached_cells,
        config.rays,
        seconds
    )
}

/// A progress bar on a terminal, a hidden one otherwise.
fn progress_bar(total: u64) -> Option<indicatif::ProgressBar> {
    Some(super::progress::bar(total, "rays"))
}

/// Writes `coverage.csv`, `coverage.png` and `coverage.json` into `out`; with several
/// transmitters also `coverage_TX.png` per transmitter and `best_server.png`; with point
/// receivers `paths.csv`, a `pdp_RECEIVER.png` each and (if asked) `cfr.csv`.
pub fn write_outputs<'a>(
    out: &std::path::Path,
    scene_name: &str,
    world: &World,
    config: &'a RfConfig,
    result: &'a RfResult,
    png_width: u32,
) -> anyhow::Result<crate::rf::output::Summary<'a>> {
    std::fs::create_dir_all(out).with_context(|| format!("{}: cannot create directory", out.display()))?;
    let csv = out.join("coverage.csv");
    let png = out.join("coverage.png");
    let json = out.join("coverage.json");
    let npy = out.join("coverage.npy");
    let feet = footprints(&world.scene.mesh, config.grid.height_m);
    let txs: Vec<(f64, f64)> = config.transmitters.iter().map(|t| (t.position.x, t.position.y)).collect();
    let names: Vec<String> = config.transmitters.iter().map(|t| t.name.clone()).collect();
    let subtitle = result.settings.line();
    let title = |what: &str, freq_ghz: f64| {
        format!("{scene_name} | {what} at {freq_ghz:.3} GHz | h = {} m", config.grid.height_m)
    };
    let t0 = &config.transmitters[0];
    let all_title = if names.len() == 1 {
        title(&t0.name, t0.freq_ghz)
    } else if config.transmitters.iter().all(|t| t.freq_ghz == t0.freq_ghz) {
        title(&format!("{} transmitters (sum)", names.len()), t0.freq_ghz)
    } else {
        format!("{scene_name} | {} transmitters (sum) | h = {} m", names.len(), config.grid.height_m)
    };
    let extras = PlotExtras {
        title: &all_title,
        subtitle: &subtitle,
        footprints: &feet,
        transmitters: &txs,
        transmitter_names: &names,
    };
    // One colour scale for every map, from the combined one, so the pictures compare.
    let range = db_range(&result.coverage, &config.colour_range);
    // The table and the picture at once: each is mostly one thread's formatting or drawing.
    let (table, picture) = rayon::join(
        || write_coverage_csv(&csv, config, result),
        || write_coverage_png(&png, &result.coverage, range, &extras, png_width),
    );
    table?;
    picture?;
    crate::io::npy::write_npy(&npy, &result.path_gain_array())?;
    let mut pictures = vec![png];
    if names.len() > 1 {
        let mut stems = std::collections::BTreeSet::new();
        for (i, (t, tr)) in config.transmitters.iter().zip(&result.transmitters).enumerate() {
            let mut stem = crate::io::file_stem(&t.name);
            if !stems.insert(stem.clone()) {
                stem = format!("{stem}_{}", i + 1);
                stems.insert(stem.clone());
            }
            let p = out.join(format!("coverage_{stem}.png"));
            let t_title = title(&t.name, t.freq_ghz);
            write_coverage_png(
                &p,
                &tr.coverage,
                range,
                &PlotExtras { title: &t_title, ..extras },
                png_width,
            )?;
            pictures.push(p);
        }
        let best: Vec<Option<usize>> =
            best_servers(config, result).into_iter().map(|b| b.map(|b| b.index)).collect();
        let p = out.join("best_server.png");
        let b_title = format!(
            "{scene_name} | best server of {} transmitters | h = {} m",
            names.len(),
            config.grid.height_m
        );
        write_best_server_png(
            &p,
            config.grid,
            &best,
            &names,
            &PlotExtras { title: &b_title, ..extras },
            png_width,
        )?;
        pictures.push(p);
    }
    let receiver_files = write_receiver_outputs(out, config, result)?;
    let outputs = [&csv, &npy]
        .into_iter()
        .chain(&pictures)
        .chain(std::iter::once(&json))
        .chain(&receiver_files)
        .map(|p| p.display().to_string())
        .collect();
    let s = summary(scene_name, config, result, outputs);
    write_summary_json(&json, &s)?;
    Ok(s)
}

/// Narrowest coverage picture, pixels: the margins, colour bar and a map 100 pixels wide.
pub const MIN_PNG_WIDTH: u32 = 300;
/// Widest coverage picture, pixels.
pub const MAX_PNG_WIDTH: u32 = 8192;

/// Runs `propsim rf`: simulate, then write coverage.csv, coverage.png and coverage.json.
pub fn run(args: &RfArgs, cluster: &Cluster) -> anyhow::Result<()> {
    anyhow::ensure!(
        (MIN_PNG_WIDTH..=MAX_PNG_WIDTH).contains(&args.png_width),
        "--png-width {}: must be between {MIN_PNG_WIDTH} and {MAX_PNG_WIDTH} pixels",
        args.png_width
    );
    let world = super::load_world(&args.scene, &args.materials, &args.model)?;
    let scene_name = args.scene.display().to_string();
    let config =
        RfConfig::from_scene(&world, &args.overrides()).map_err(|e| anyhow::anyhow!("{scene_name}: {e}"))?;
    if let Some(why) = crate::rf::grid_misses_model(&world, &config) {
        tell!("warning: {scene_name}: {why}");
    }
    // The output directory is checked before the (possibly long) simulation.
    if cluster.is_root() {
        crate::io::atomic::check_writable(&args.out, true)?;
    }
    let pb = progress_bar(config.rays * config.transmitters.len() as u64);
    let result = simulate_on(cluster, &world, &config, &|n| {
        if let Some(pb) = &pb {
            pb.inc(n);
        }
    })
    .with_context(|| scene_name.clone())?;
    if let Some(pb) = &pb {
        pb.finish_and_clear();
    }
    // Only rank 0 holds the map and writes.
    let Some(result) = result else { return Ok(()) };
    let s = write_outputs(&args.out, &scene_name, &world, &config, &result, args.png_width)?;
    let (csv, png, json) =
        (args.out.join("coverage.csv"), args.out.join("coverage.png"), args.out.join("coverage.json"));
    say!("{} ({:.2} Mrays/s)", map_line(&scene_name, &config, &s, result.seconds), s.rays_per_second / 1e6);
    for r in &s.receivers {
        let f = |v: Option<f64>| v.map_or("none".to_string(), |v| format!("{v:.2} dB"));
        say!(
            "  {} -> {}: {} paths, coherent {}, incoherent {}, grid cell {}",
            r.transmitter,
            r.name,
            r.paths,
            f(r.coherent_path_gain_db),
            f(r.incoherent_path_gain_db),
            f(r.grid_path_gain_db)
        );
    }
    say!(
        "wrote {}, {}, {}, {}",
        csv.display(),
        args.out.join("coverage.npy").display(),
        png.display(),
        json.display()
    );
    if config.transmitters.len() > 1 {
        say!(
            "wrote coverage_TX.png for each of {} transmitters and best_server.png in {}; coverage.csv has best_server, best_rx_power_dbm, sinr_db (noise {:.2} dBm) and rx_power_dbm_TX",
            config.transmitters.len(),
            args.out.display(),
            config.noise.noise_power_dbm
        );
    }
    if !config.receivers.is_empty() {
        let cfr = if config.cfr.is_some() { ", cfr.csv, cfr.npy" } else { "" };
        say!(
            "wrote paths.csv, paths.npy, {} power-delay profile(s) pdp_*.png{cfr} in {}",
            config.receivers.len(),
            args.out.display()
        );
    }
    Ok(())
}

#[derive(Args, Debug)]
pub struct BenchRfArgs {
    /// Scene (default: the street canyon).
    #[arg(default_value = "rooms/street_canyon/scene.toml")]
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
    let world = super::load_world(&args.scene, &args.materials, &super::ModelArgs::default())?;
    let name = args.scene.display().to_string();
    let overrides = Overrides {
        rays: Some(args.rays),
        cell_m: Some(args.cell_m),
        max_depth: Some(args.max_depth),
        no_receivers: true,
        ..Overrides::default()
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
        "wall time {:.3} s (median of {}; runs {:?}), {:.2} Mrays/s, {:.1} M ray segments/s ({} segments), {} cells reached",
        wall,
        args.repeat,
        walls.iter().map(|w| (w * 1000.0).round() / 1000.0).collect::<Vec<_>>(),
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
