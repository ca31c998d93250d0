//! Writers for the radio outputs: `coverage.csv`, the JSON summary (the PNG is in
//! [`super::plot`]). No physics here.

use std::path::Path;

use anyhow::Context as _;
use serde::Serialize;

use super::{RfConfig, RfResult};

/// What `path_gain_db` means, repeated in the JSON summary and the README.
pub const ESTIMATOR: &str = "path_gain_db is the average path gain over the cell, 10 log10 g with \
g = (1/A) integral |h|^2 dA: the power (incoherent) sum of the ray paths crossing the cell at the \
grid height, each ray carrying P_tx G_tx(dir) / N times its product of |Gamma|^2 and counted with \
1/|cos theta|, times lambda^2 / (4 pi) / P_tx (isotropic receiver; transmitter gain included); \
summed over transmitters. rx_power_dbm = 10 log10(sum over transmitters of P_tx g). paths = ray \
crossings of the cell. Empty values: no ray reached the cell.";

/// The CSV columns, exactly.
pub const CSV_COLUMNS: [&str; 6] = ["x_m", "y_m", "z_m", "path_gain_db", "rx_power_dbm", "paths"];

fn db(v: f64) -> String {
    if v > 0.0 { format!("{:.3}", 10.0 * v.log10()) } else { String::new() }
}

/// Writes `coverage.csv`: one row per cell centre, x fastest; unreached cells have empty
/// `path_gain_db` and `rx_power_dbm`.
pub fn write_coverage_csv(path: &Path, result: &RfResult) -> anyhow::Result<()> {
    let mut w = csv::Writer::from_path(path).with_context(|| format!("{}", path.display()))?;
    w.write_record(CSV_COLUMNS)?;
    let cov = &result.coverage;
    let z = format!("{:.3}", cov.spec.height_m);
    for i in 0..cov.spec.cells() {
        let [x, y] = cov.spec.centre(i);
        let reached = cov.path_gain[i] > 0.0;
        w.write_record([
            format!("{x:.3}"),
            format!("{y:.3}"),
            z.clone(),
            db(cov.path_gain[i]),
            if reached { db(result.rx_power_mw[i]) } else { String::new() },
            cov.paths[i].to_string(),
        ])?;
    }
    w.flush().with_context(|| format!("{}", path.display()))?;
    Ok(())
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
    /// The coverage grid's value in the cell holding the receiver (all transmitters).
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

/// The JSON summary: every parameter, the estimator, timings and receivers.
#[derive(Serialize, Debug)]
pub struct Summary<'a> {
    pub propsim_version: &'static str,
    pub scene: String,
    pub estimator: &'static str,
    pub config: &'a RfConfig,
    pub threads: usize,
    pub seconds: f64,
    pub rays_per_second: f64,
    pub map: MapStats,
    /// Per transmitter: the surfaces' complex permittivities at its carrier.
    pub surfaces: Vec<TransmitterSurfaces>,
    pub receivers: Vec<ReceiverSummary>,
    pub outputs: Vec<String>,
}

fn opt_db(v: f64) -> Option<f64> {
    (v > 0.0).then(|| (1e4 * 10.0 * v.log10()).round() / 1e4)
}

/// Builds the summary of a run.
pub fn summary<'a>(
    scene: &str,
    config: &'a RfConfig,
    result: &RfResult,
    outputs: Vec<String>,
) -> Summary<'a> {
    let cov = &result.coverage;
    let mut reached: Vec<f64> = cov.path_gain.iter().copied().filter(|&g| g > 0.0).collect();
    reached.sort_by(f64::total_cmp);
    let map = MapStats {
        cells: cov.spec.cells(),
        reached_cells: reached.len(),
        max_path_gain_db: reached.last().copied().and_then(opt_db),
        min_path_gain_db: reached.first().copied().and_then(opt_db),
        median_path_gain_db: reached.get(reached.len() / 2).copied().and_then(opt_db),
        total_ray_crossings: cov.paths.iter().map(|&p| u64::from(p)).sum(),
    };
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
                grid_path_gain_db: cell.and_then(|c| opt_db(cov.path_gain[c])),
            });
        }
    }
    let trace: f64 = result.transmitters.iter().map(|t| t.trace_seconds).sum();
    Summary {
        propsim_version: env!("CARGO_PKG_VERSION"),
        scene: scene.to_string(),
        estimator: ESTIMATOR,
        config,
        threads: rayon::current_num_threads(),
        seconds: result.seconds,
        rays_per_second: if trace > 0.0 {
            (config.rays * config.transmitters.len() as u64) as f64 / trace
        } else {
            0.0
        },
        map,
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
    std::fs::write(path, text + "\n").with_context(|| format!("{}", path.display()))
}
