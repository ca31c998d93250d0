//! Writers for the radio outputs: `coverage.csv`, the JSON summary, and at the point
//! receivers the channel impulse responses (`paths.csv`, a power-delay profile per receiver)
//! and frequency responses (`cfr.csv`); the PNGs are drawn in [`super::plot`]. No physics
//! here: the quantities are defined in [`super::receivers`] and docs/radio.md, sec. 3.

use std::path::Path;

use anyhow::Context as _;

use rayon::prelude::*;
use serde::Serialize;

use super::config::CfrSpec;
use super::plot::{PlotExtras, db_range, footprints, write_best_server_png, write_coverage_png};
use super::receivers::{Interaction, PathRecord, azimuth_zenith_deg, frequency_response};
use super::{RfConfig, RfResult};
use crate::scene::World;

/// What `path_gain_db` means, repeated in the JSON summary and the README.
pub const ESTIMATOR: &str = "path_gain_db is the average path gain over the cell, 10 log10 g with \
g = (1/A) integral |h|^2 dA: the power (incoherent) sum of the ray paths crossing the cell at the \
grid height, each ray carrying P_tx G_tx(dir) / N times its product of |Gamma|^2 and counted with \
1/|cos theta|, times lambda^2 / (4 pi) / P_tx (isotropic receiver; transmitter gain included); \
summed over transmitters. With diffraction on, g also holds the power of the first-order \
diffracted paths (UTD, transmitter -> edge -> cell centre, a point value at the cell's centre; \
docs/radio.md, sec. 5). rx_power_dbm = 10 log10(sum over transmitters of P_tx g). paths = ray \
crossings of the cell (diffracted paths not counted: a shadowed cell may have a value and 0 \
crossings). Empty values: no ray and no diffracted path reached the cell.";

/// What the columns added with several transmitters mean, repeated in the JSON summary.
pub const SERVERS: &str = "With several transmitters: best_server = the transmitter with the \
highest received power P_t = P_tx,t g_t in the cell (the first on a tie), best_rx_power_dbm its \
P_t, sinr_db = 10 log10(P_best / (sum of the other transmitters' P_t + N)), every other transmitter \
counting as a co-channel interferer, with the thermal noise N = k T0 B F (T0 = 290 K, \
noise.bandwidth_hz B, noise.noise_figure_db F; noise.noise_power_dbm); rx_power_dbm_NAME = one \
transmitter's P_t. Empty values: no ray of that transmitter (or of any, for the best server) \
reached the cell.";

/// The CSV columns, exactly, for one transmitter; several add [`server_columns`].
pub const CSV_COLUMNS: [&str; 6] = ["x_m", "y_m", "z_m", "path_gain_db", "rx_power_dbm", "paths"];

/// The columns `coverage.csv` adds after [`CSV_COLUMNS`] for the transmitters `names`: none
/// for one transmitter; for several `best_server`, `best_rx_power_dbm`, `sinr_db` and
/// `rx_power_dbm_NAME` per transmitter, in order.
pub fn server_columns(names: &[String]) -> Vec<String> {
    if names.len() < 2 {
        return Vec::new();
    }
    let mut v: Vec<String> = ["best_server", "best_rx_power_dbm", "sinr_db"].map(String::from).to_vec();
    v.extend(names.iter().map(|n| format!("rx_power_dbm_{n}")));
    v
}

/// The best server of every cell (`None` where no transmitter reaches it).
pub fn best_servers(config: &RfConfig, result: &RfResult) -> Vec<Option<super::BestServer>> {
    (0..result.coverage.spec.cells()).map(|c| result.best_server(c, &config.noise)).collect()
}

fn db(v: f64) -> String {
    if v > 0.0 { format!("{:.3}", 10.0 * v.log10()) } else { String::new() }
}

/// Writes `coverage.csv`: one row per cell centre, x fastest; unreached cells have empty
/// `path_gain_db` and `rx_power_dbm`. With several transmitters the row goes on with the
/// [`server_columns`] ([`SERVERS`]).
pub fn write_coverage_csv(path: &Path, config: &RfConfig, result: &RfResult) -> anyhow::Result<()> {
    crate::io::atomic::write_atomically(path, |out| {
        let mut w = csv::Writer::from_writer(out);
        let names: Vec<String> = result.transmitters.iter().map(|t| t.name.clone()).collect();
        let servers = server_columns(&names);
        w.write_record(CSV_COLUMNS.iter().map(|c| c.to_string()).chain(servers.iter().cloned()))?;
        let cov = &result.coverage;
        let z = format!("{:.3}", cov.spec.height_m);
        // The rows are formatted in parallel (most of the time goes to formatting numbers),
        // then written in order.
        let row = |i: usize| {
            let mut row = Vec::with_capacity(CSV_COLUMNS.len() + servers.len());
            let [x, y] = cov.spec.centre(i);
            let reached = cov.path_gain[i] > 0.0;
            row.extend([
                format!("{x:.3}"),
                format!("{y:.3}"),
                z.clone(),
                db(cov.path_gain[i]),
                if reached { db(result.rx_power_mw[i]) } else { String::new() },
                cov.paths[i].to_string(),
            ]);
            if !servers.is_empty() {
                match result.best_server(i, &config.noise) {
                    Some(b) => row.extend([names[b.index].clone(), db(b.power_mw), db(b.sinr)]),
                    None => row.extend([String::new(), String::new(), String::new()]),
                }
                row.extend(result.transmitters.iter().map(|t| db(t.power_mw * t.coverage.path_gain[i])));
            }
            row
        };
        let rows: Vec<Vec<String>> = (0..cov.spec.cells()).into_par_iter().map(row).collect();
        for row in rows {
            w.write_record(&row)?;
        }
        w.flush()?;
        Ok(())
    })
}

/// One point receiver's line in the summary.
#[derive(Serialize, Debug)]
pub struct ReceiverSummary {
    pub transmitter: String,
    pub name: String,
    pub position: [f64; 3],
    /// Exact specular paths found (image method, up to `max_order` reflections).
    pub paths: usize,
    pub max_order: u32,
    pub line_of_sight: bool,
    /// `10 log10 |sum h|^2` (phase kept), dB; null when no path.
    pub coherent_path_gain_db: Option<f64>,
    /// `10 log10 sum |h|^2`, dB.
    pub incoherent_path_gain_db: Option<f64>,
    /// Transmit power plus the coherent path gain, dBm.
    pub coherent_rx_power_dbm: Option<f64>,
    /// This transmitter's own coverage map in the cell holding the receiver.
    pub grid_path_gain_db: Option<f64>,
}

/// The radio constants used for one transmitter.
#[derive(Serialize, Debug)]
pub struct TransmitterSurfaces {
    pub transmitter: String,
    pub freq_ghz: f64,
    pub surfaces: Vec<super::SurfaceRadio>,
}

/// Statistics of the map.
#[derive(Serialize, Debug)]
pub struct MapStats {
    pub cells: usize,
    pub reached_cells: usize,
    pub max_path_gain_db: Option<f64>,
    pub min_path_gain_db: Option<f64>,
    pub median_path_gain_db: Option<f64>,
    pub total_ray_crossings: u64,
}

/// One transmitter's own map.
#[derive(Serialize, Debug)]
pub struct TransmitterMap {
    pub transmitter: String,
    pub map: MapStats,
    /// Cells where this transmitter is the best server (several transmitters only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub best_server_cells: Option<usize>,
    /// Cells reached by at least one diffracted path, and the wedges whose edge this
    /// transmitter sees (diffraction on only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub diffracted_cells: Option<usize>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub lit_wedges: Option<usize>,
    /// Wall time of the diffraction (map and receivers), seconds.
    pub diffraction_seconds: f64,
}

/// The JSON summary: every parameter, the estimator, timings and receivers.
#[derive(Serialize, Debug)]
pub struct Summary<'a> {
    pub propsim_version: &'static str,
    pub scene: String,
    pub estimator: &'static str,
    /// The best-server and SINR columns' definition (several transmitters only).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub servers: Option<&'static str>,
    /// Rays, depth, extrapolation, transmission (with the walls' thickness and its source)
    /// and diffraction, in words.
    pub physics: super::PhysicsSettings,
    pub config: &'a RfConfig,
    /// The colour scale of the coverage pictures, dB of path gain (`null`: empty map).
    pub colour_range_db: Option<[f64; 2]>,
    pub threads: usize,
    pub seconds: f64,
    pub rays_per_second: f64,
    /// Ray segments traced for the maps (launches, reflections, transmissions), and per
    /// second of tracing.
    pub segments: u64,
    pub segments_per_second: f64,
    /// The combined map (all transmitters).
    pub map: MapStats,
    /// Each transmitter's own map.
    pub transmitter_maps: Vec<TransmitterMap>,
    /// Per transmitter: the surfaces' complex permittivities at its carrier.
    pub surfaces: Vec<TransmitterSurfaces>,
    pub receivers: Vec<ReceiverSummary>,
    pub outputs: Vec<String>,
}

fn opt_db(v: f64) -> Option<f64> {
    (v > 0.0).then(|| (1e4 * 10.0 * v.log10()).round() / 1e4)
}

/// The statistics of one map.
pub fn map_stats(cov: &super::Coverage) -> MapStats {
    let mut reached: Vec<f64> = cov.path_gain.iter().copied().filter(|&g| g > 0.0).collect();
    reached.sort_by(f64::total_cmp);
    MapStats {
        cells: cov.spec.cells(),
        reached_cells: reached.len(),
        max_path_gain_db: reached.last().copied().and_then(opt_db),
        min_path_gain_db: reached.first().copied().and_then(opt_db),
        median_path_gain_db: reached.get(reached.len() / 2).copied().and_then(opt_db),
        total_ray_crossings: cov.paths.iter().map(|&p| u64::from(p)).sum(),
    }
}

/// Builds the summary of a run.
pub fn summary<'a>(
    scene: &str,
    config: &'a RfConfig,
    result: &RfResult,
    outputs: Vec<String>,
) -> Summary<'a> {
    let cov = &result.coverage;
    let map = map_stats(cov);
    let several = result.transmitters.len() > 1;
    let mut served = vec![0usize; result.transmitters.len()];
    if several {
        for b in best_servers(config, result).into_iter().flatten() {
            served[b.index] += 1;
        }
    }
    let transmitter_maps = result
        .transmitters
        .iter()
        .zip(&served)
        .map(|(t, &n)| TransmitterMap {
            transmitter: t.name.clone(),
            map: map_stats(&t.coverage),
            best_server_cells: several.then_some(n),
            diffracted_cells: t.diffraction.as_ref().map(|d| d.cells()),
            lit_wedges: t.diffraction.as_ref().map(|d| d.lit_wedges),
            diffraction_seconds: t.diffraction_seconds,
        })
        .collect();
    let mut receivers = Vec::new();
    for (t, tr) in config.transmitters.iter().zip(&result.transmitters) {
        for (r, ps) in config.receivers.iter().zip(&tr.receivers) {
            let cell = cov.spec.cell_of(r.position.x, r.position.y);
            receivers.push(ReceiverSummary {
                transmitter: t.name.clone(),
                name: r.name.clone(),
                position: r.position.to_array(),
                paths: ps.paths,
                max_order: tr.receiver_depth,
                line_of_sight: ps.line_of_sight,
                coherent_path_gain_db: opt_db(ps.coherent_gain),
                incoherent_path_gain_db: opt_db(ps.incoherent_gain),
                coherent_rx_power_dbm: opt_db(ps.coherent_gain).map(|g| g + t.power_dbm),
                grid_path_gain_db: cell.and_then(|c| opt_db(tr.coverage.path_gain[c])),
            });
        }
    }
    let trace: f64 = result.transmitters.iter().map(|t| t.trace_seconds).sum();
    Summary {
        propsim_version: env!("CARGO_PKG_VERSION"),
        scene: scene.to_string(),
        estimator: ESTIMATOR,
        servers: several.then_some(SERVERS),
        physics: result.settings.clone(),
        config,
        colour_range_db: super::plot::db_range(cov, &config.colour_range).map(|(lo, hi)| [lo, hi]),
        threads: rayon::current_num_threads(),
        seconds: result.seconds,
        rays_per_second: if trace > 0.0 {
            (config.rays * config.transmitters.len() as u64) as f64 / trace
        } else {
            0.0
        },
        segments: result.transmitters.iter().map(|t| t.segments).sum(),
        segments_per_second: if trace > 0.0 {
            result.transmitters.iter().map(|t| t.segments).sum::<u64>() as f64 / trace
        } else {
            0.0
        },
        map,
        transmitter_maps,
        surfaces: config
            .transmitters
            .iter()
            .zip(&result.transmitters)
            .map(|(t, r)| TransmitterSurfaces {
                transmitter: t.name.clone(),
                freq_ghz: t.freq_ghz,
                surfaces: r.surfaces.clone(),
            })
            .collect(),
        receivers,
        outputs,
    }
}

/// Writes the summary as pretty JSON.
pub fn write_summary_json(path: &Path, summary: &Summary) -> anyhow::Result<()> {
    let text = serde_json::to_string_pretty(summary)?;
    crate::io::atomic::write_bytes(path, (text + "\n").as_bytes())
}

/// The columns of `paths.csv`, exactly.
pub const PATHS_CSV_COLUMNS: [&str; 12] = [
    "transmitter",
    "receiver",
    "path",
    "delay_s",
    "amplitude_re",
    "amplitude_im",
    "gain_db",
    "aod_azimuth_deg",
    "aod_zenith_deg",
    "aoa_azimuth_deg",
    "aoa_zenith_deg",
    "interactions",
];

/// The columns of `cfr.csv`, exactly.
pub const CFR_CSV_COLUMNS: [&str; 6] = ["transmitter", "receiver", "freq_hz", "re", "im", "gain_db"];

/// A path's interactions as written in `paths.csv`: `LOS` for the direct path, else
/// `R:SURFACE` per reflection and `D:SURFACE` (`D:SURFACE0|SURFACEN` on a wedge between two
/// surfaces) per edge diffraction, first first, separated by `;`.
pub fn interactions_text(interactions: &[Interaction], surface_names: &[String]) -> String {
    if interactions.is_empty() {
        return "LOS".into();
    }
    let name = |s: u32| surface_names.get(s as usize).map_or_else(|| format!("#{s}"), Clone::clone);
    interactions
        .iter()
        .map(|i| match *i {
            Interaction::Reflection { surface } => format!("R:{}", name(surface)),
            Interaction::Diffraction { surfaces: [a, b] } if a == b => format!("D:{}", name(a)),
            Interaction::Diffraction { surfaces: [a, b] } => format!("D:{}|{}", name(a), name(b)),
        })
        .collect::<Vec<_>>()
        .join(";")
}

/// The paths of one receiver for one transmitter, by increasing delay (ties: the order found).
pub fn paths_by_delay(records: &[PathRecord]) -> Vec<&PathRecord> {
    let mut v: Vec<&PathRecord> = records.iter().collect();
    v.sort_by(|a, b| a.delay_s.total_cmp(&b.delay_s));
    v
}

fn gain_db_text(g: f64) -> String {
    if g > 0.0 { format!("{:.6}", 10.0 * g.log10()) } else { String::new() }
}

/// Writes `paths.csv`: one row per path of every (transmitter, receiver) pair, numbered from 0
/// by increasing delay. Delays and amplitudes are written exactly (the shortest decimal
/// exponent form that reads back to the same f64), gains and angles to 1e-6; a path of zero amplitude has an empty `gain_db`.
pub fn write_paths_csv(path: &Path, config: &RfConfig, result: &RfResult) -> anyhow::Result<()> {
    crate::io::atomic::write_atomically(path, |out| {
        let mut w = csv::Writer::from_writer(out);
        w.write_record(PATHS_CSV_COLUMNS)?;
        for (t, tr) in config.transmitters.iter().zip(&result.transmitters) {
            for (r, ps) in config.receivers.iter().zip(&tr.receivers) {
                for (k, p) in paths_by_delay(&ps.records).into_iter().enumerate() {
                    let (aod_az, aod_ze) = azimuth_zenith_deg(p.departure);
                    let (aoa_az, aoa_ze) = azimuth_zenith_deg(p.arrival);
                    w.write_record([
                        t.name.clone(),
                        r.name.clone(),
                        k.to_string(),
                        format!("{:e}", p.delay_s),
                        format!("{:e}", p.amplitude.re),
                        format!("{:e}", p.amplitude.im),
                        gain_db_text(p.gain()),
                        format!("{aod_az:.6}"),
                        format!("{aod_ze:.6}"),
                        format!("{aoa_az:.6}"),
                        format!("{aoa_ze:.6}"),
                        interactions_text(&p.interactions, &result.surface_names),
                    ])?;
                }
            }
        }
        w.flush()?;
        Ok(())
    })
}

/// Writes `cfr.csv`: the channel frequency response `H(f)` of every (transmitter, receiver)
/// pair at the `spec.points` frequencies of the band centred on the transmitter's carrier
/// ([`CfrSpec::offset_hz`]); `gain_db = 10 log10 |H|^2` (empty when `H = 0`).
pub fn write_cfr_csv(
    path: &Path,
    config: &RfConfig,
    result: &RfResult,
    spec: &CfrSpec,
) -> anyhow::Result<()> {
    crate::io::atomic::write_atomically(path, |out| {
        let mut w = csv::Writer::from_writer(out);
        w.write_record(CFR_CSV_COLUMNS)?;
        for (t, tr) in config.transmitters.iter().zip(&result.transmitters) {
            let carrier_hz = t.freq_ghz * 1e9;
            for (r, ps) in config.receivers.iter().zip(&tr.receivers) {
                for i in 0..spec.points {
                    let offset = spec.offset_hz(i);
                    let h = frequency_response(&ps.records, offset);
                    w.write_record([
                        t.name.clone(),
                        r.name.clone(),
                        (carrier_hz + offset).to_string(),
                        format!("{:e}", h.re),
                        format!("{:e}", h.im),
                        gain_db_text(h.norm_sqr()),
                    ])?;
                }
            }
        }
        w.flush()?;
        Ok(())
    })
}

/// The columns of `paths.npy`: `paths.csv`'s numeric columns, the transmitter and receiver
/// by index (in the order of the config), a zero-amplitude path's gain as NaN.
pub const PATHS_NPY_COLUMNS: &[&str] = PATHS_CSV_COLUMNS.split_at(11).0;

/// `paths.csv` as numbers: one row per path, [`PATHS_NPY_COLUMNS`], float64, in the rows'
/// order of `paths.csv`. `paths.npy` holds it.
pub fn paths_array(config: &RfConfig, result: &RfResult) -> ndarray::Array2<f64> {
    let mut rows: Vec<[f64; PATHS_NPY_COLUMNS.len()]> = Vec::new();
    for (t, tr) in result.transmitters.iter().enumerate() {
        for (r, ps) in tr.receivers.iter().enumerate().take(config.receivers.len()) {
            for (k, p) in paths_by_delay(&ps.records).into_iter().enumerate() {
                let (aod_az, aod_ze) = azimuth_zenith_deg(p.departure);
                let (aoa_az, aoa_ze) = azimuth_zenith_deg(p.arrival);
                let g = p.gain();
                let gain_db = if g > 0.0 { 10.0 * g.log10() } else { f64::NAN };
                rows.push([
                    t as f64,
                    r as f64,
                    k as f64,
                    p.delay_s,
                    p.amplitude.re,
                    p.amplitude.im,
                    gain_db,
                    aod_az,
                    aod_ze,
                    aoa_az,
                    aoa_ze,
                ]);
            }
        }
    }
    let n = rows.len();
    ndarray::Array2::from_shape_vec((n, PATHS_NPY_COLUMNS.len()), rows.into_iter().flatten().collect())
        .unwrap_or_else(|_| ndarray::Array2::zeros((0, PATHS_NPY_COLUMNS.len())))
}

/// The channel frequency response `H(f)` of every (transmitter, receiver) pair at the
/// `spec.points` frequencies of `cfr.csv`, complex, shape (transmitters, receivers, points).
/// `cfr.npy` holds it.
pub fn cfr_array(
    config: &RfConfig,
    result: &RfResult,
    spec: &CfrSpec,
) -> ndarray::Array3<num_complex::Complex64> {
    let shape = (result.transmitters.len(), config.receivers.len(), spec.points);
    ndarray::Array3::from_shape_fn(shape, |(t, r, i)| {
        let h = frequency_response(&result.transmitters[t].receivers[r].records, spec.offset_hz(i));
        num_complex::Complex64::new(h.re, h.im)
    })
}

/// Writes the point receivers' outputs into `out`: `paths.csv`, `pdp_RECEIVER.png` for each
/// receiver (every transmitter's paths on one chart), and `cfr.csv` when the config asks for
/// it. Nothing when there is no receiver. Returns the files written.
pub fn write_receiver_outputs(
    out: &Path,
    config: &RfConfig,
    result: &RfResult,
) -> anyhow::Result<Vec<std::path::PathBuf>> {
    let mut written = Vec::new();
    if config.receivers.is_empty() {
        return Ok(written);
    }
    let paths = out.join("paths.csv");
    write_paths_csv(&paths, config, result)?;
    written.push(paths);
    let paths_npy = out.join("paths.npy");
    crate::io::npy::write_npy(&paths_npy, &paths_array(config, result))?;
    written.push(paths_npy);
    let mut stems = std::collections::BTreeSet::new();
    for (i, r) in config.receivers.iter().enumerate() {
        let mut stem = crate::io::file_stem(&r.name);
        if !stems.insert(stem.clone()) {
            stem = format!("{stem}_{}", i + 1);
            stems.insert(stem.clone());
        }
        let png = out.join(format!("pdp_{stem}.png"));
        let series: Vec<(String, Vec<(f64, f64)>)> = config
            .transmitters
            .iter()
            .zip(&result.transmitters)
            .map(|(t, tr)| {
                let points = tr.receivers[i]
                    .records
                    .iter()
                    .filter(|p| p.gain() > 0.0)
                    .map(|p| (p.delay_s * 1e9, 10.0 * p.gain().log10()))
                    .collect();
                (t.name.clone(), points)
            })
            .collect();
        super::plot::write_pdp_png(&png, &r.name, &series)?;
        written.push(png);
    }
    if let Some(spec) = &config.cfr {
        let cfr = out.join("cfr.csv");
        write_cfr_csv(&cfr, config, result, spec)?;
        written.push(cfr);
        let cfr_npy = out.join("cfr.npy");
        crate::io::npy::write_npy(&cfr_npy, &cfr_array(config, result, spec))?;
        written.push(cfr_npy);
    }
    Ok(written)
}
/// The map's one-line summary: grid, cells reached, rays and time.
pub fn map_line(scene_label: &str, config: &RfConfig, s: &Summary, seconds: f64) -> String {
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

/// Writes `coverage.csv`, `coverage.png` and `coverage.json` into `out`; with several
/// transmitters also `coverage_TX.png` per transmitter and `best_server.png`; with point
/// receivers `paths.csv`, a `pdp_RECEIVER.png` each and (if asked) `cfr.csv`.
pub fn write_outputs<'a>(
    out: &std::path::Path,
    scene_name: &str,
    world: &World,
    config: &'a RfConfig,
    result: &'a RfResult,
) -> anyhow::Result<Summary<'a>> {
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
        || write_coverage_png(&png, &result.coverage, range, &extras, config.png_width),
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
                config.png_width,
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
            config.png_width,
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
