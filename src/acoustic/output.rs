//! The acoustic simulation's files: metrics.csv and .npy, histogram.csv and .npy, an impulse
//! response (WAV) with its plots per source-receiver pair, and acoustic.json; and the printed
//! summary table.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::Context as _;

use super::impulse_response::{SAMPLE_RATE_HZ, sum_bands, synthesize, synthesize_bands};
use super::metrics::decay_curve;
use super::spatial::{Head, PairDirections, ambisonic, binaural};
use super::{AcousticResult, Plan};
use crate::dist::Cluster;
use crate::io::atomic::write_atomically;
use crate::io::plot::{Chart, Series, line_chart};
use crate::io::{file_stem, wav};
use crate::scene::World;
use crate::scene::materials::BAND_COUNT;

/// The columns of metrics.csv: ISO 3382-1 parameters (the first ten, fixed), G (ISO 3382-1
/// A.2.1), the decay's dynamic range and truncation point, and the fit quality of T20 and T30
/// (r, xi = 1000 (1 - r^2) per mille, curvature C = 100 (T30/T20 - 1) %; ISO 3382-2 Annex B).
pub const METRICS_COLUMNS: [&str; 18] = [
    "source",
    "receiver",
    "band_hz",
    "edt_s",
    "t20_s",
    "t30_s",
    "c50_db",
    "c80_db",
    "d50",
    "ts_ms",
    "g_db",
    "dynamic_range_db",
    "truncation_s",
    "t20_r",
    "t30_r",
    "t20_xi_permille",
    "t30_xi_permille",
    "curvature_percent",
];

fn fmt_opt(v: Option<f64>, digits: usize) -> String {
    v.map_or(String::new(), |x| format!("{x:.digits$}"))
}

/// The bands whose surface data is extrapolated rather than given: a band is extrapolated
/// when some surface's material gave no value for it (the library's 125 Hz - 4 kHz tables
/// fill 63 Hz and 8 kHz from the nearest band).
pub fn extrapolated_bands(world: &World) -> [bool; BAND_COUNT] {
    std::array::from_fn(|b| {
        world
            .scene
            .surfaces
            .iter()
            .filter_map(|s| s.material.as_ref()?.acoustic.as_ref())
            .any(|a| !a.bands_given.contains(&b))
    })
}

/// The numbers of `metrics.csv` as an array of shape (pairs, bands, 15): the columns of
/// [`METRICS_COLUMNS`] after `source`, `receiver` and `band_hz`, unrounded, NaN where the CSV
/// is empty. `metrics.npy` holds it.
pub fn metrics_array(result: &AcousticResult) -> ndarray::Array3<f64> {
    let value = |v: Option<f64>| v.unwrap_or(f64::NAN);
    ndarray::Array3::from_shape_fn(
        (result.pairs.len(), BAND_COUNT, METRICS_COLUMNS.len() - 3),
        |(i, b, c)| {
            let m = &result.pairs[i].metrics[b];
            value(
                [
                    m.edt_s,
                    m.t20_s,
                    m.t30_s,
                    m.c50_db,
                    m.c80_db,
                    m.d50,
                    m.ts_ms,
                    m.g_db,
                    m.dynamic_range_db,
                    m.truncation_s,
                    m.t20_r,
                    m.t30_r,
                    m.t20_xi_permille,
                    m.t30_xi_permille,
                    m.curvature_percent,
                ][c],
            )
        },
    )
}

/// Writes every output of `result` into `out`. `extrapolated[b]` marks the bands whose
/// surface data is extrapolated (dashed in the decay plots).
pub fn write_outputs(
    out: &Path,
    result: &AcousticResult,
    volume_m3: f64,
    seed: u64,
    extrapolated: &[bool; BAND_COUNT],
) -> anyhow::Result<Vec<PathBuf>> {
    std::fs::create_dir_all(out)
        .with_context(|| format!("{}: cannot create the output directory", out.display()))?;
    let mut written = Vec::new();
    // metrics.csv: the ten columns of the issue, then (appended, so the first ten keep their
    // places) G and the figures that say how far the decay parameters can be trusted.
    let metrics_path = out.join("metrics.csv");
    write_atomically(&metrics_path, |out| {
        let mut w = csv::Writer::from_writer(out);
        w.write_record(METRICS_COLUMNS)?;
        for p in &result.pairs {
            for (b, m) in p.metrics.iter().enumerate() {
                w.write_record([
                    p.source.clone(),
                    p.receiver.clone(),
                    format!("{}", result.bands_hz[b]),
                    fmt_opt(m.edt_s, 4),
                    fmt_opt(m.t20_s, 4),
                    fmt_opt(m.t30_s, 4),
                    fmt_opt(m.c50_db, 3),
                    fmt_opt(m.c80_db, 3),
                    fmt_opt(m.d50, 4),
                    fmt_opt(m.ts_ms, 2),
                    fmt_opt(m.g_db, 2),
                    fmt_opt(m.dynamic_range_db, 1),
                    fmt_opt(m.truncation_s, 3),
                    fmt_opt(m.t20_r, 5),
                    fmt_opt(m.t30_r, 5),
                    fmt_opt(m.t20_xi_permille, 2),
                    fmt_opt(m.t30_xi_permille, 2),
                    fmt_opt(m.curvature_percent, 1),
                ])?;
            }
        }
        w.flush()?;
        Ok(())
    })?;
    written.push(metrics_path);
    // histogram.csv: energy fluence per bin and band, J/m^2.
    let hist_path = out.join("histogram.csv");
    write_atomically(&hist_path, |out| {
        let mut w = csv::Writer::from_writer(out);
        let mut header = vec!["source".to_string(), "receiver".into(), "time_s".into()];
        header.extend(result.bands_hz.iter().map(|f| format!("energy_{f}hz_j_per_m2")));
        w.write_record(&header)?;
        for p in &result.pairs {
            for (k, bin) in p.histogram.iter().enumerate() {
                let mut row =
                    vec![p.source.clone(), p.receiver.clone(), format!("{:.4}", k as f64 * result.bin_s)];
                row.extend(bin.iter().map(|e| format!("{e:.6e}")));
                w.write_record(&row)?;
            }
        }
        w.flush()?;
        Ok(())
    })?;
    written.push(hist_path);
    for (name, array) in [("metrics.npy", metrics_array(result)), ("histogram.npy", result.histogram_array())]
    {
        let path = out.join(name);
        crate::io::npy::write_npy(&path, &array)?;
        written.push(path);
    }
    use rayon::prelude::*;
    let per_pair: Vec<anyhow::Result<Vec<PathBuf>>> = result
        .pairs
        .par_iter()
        .enumerate()
        .map(|(i, p)| write_pair(out, result, volume_m3, seed, extrapolated, i, p))
        .collect();
    for files in per_pair {
        written.extend(files?);
    }
    Ok(written)
}

/// The WAV and the two charts of one source-receiver pair.
fn write_pair(
    out: &Path,
    result: &AcousticResult,
    volume_m3: f64,
    seed: u64,
    extrapolated: &[bool; BAND_COUNT],
    i: usize,
    p: &crate::acoustic::PairResult,
) -> anyhow::Result<Vec<PathBuf>> {
    let mut written = Vec::new();
    {
        let stem = format!("{}_{}", file_stem(&p.source), file_stem(&p.receiver));
        let pair_seed = seed ^ (i as u64) << 20;
        let settings = &result.settings;
        // The spatial responses share the mono response's band parts (their sum is it).
        let (ir, bands) = if settings.keeps_directions() {
            let bands =
                synthesize_bands(&p.histogram, result.bin_s, volume_m3, result.speed_of_sound_m_s, pair_seed);
            (sum_bands(&bands), Some(bands))
        } else {
            (synthesize(&p.histogram, result.bin_s, volume_m3, result.speed_of_sound_m_s, pair_seed), None)
        };
        let wav_path = out.join(format!("ir_{stem}.wav"));
        wav::write_f32_mono(&wav_path, &ir, SAMPLE_RATE_HZ)?;
        written.push(wav_path);
        if let Some(bands) = &bands {
            let directions = PairDirections {
                histogram: &p.histogram,
                bin_s: result.bin_s,
                directions: &p.directions,
                direction_bins: settings.direction_bins(),
                image_sources: &p.image_sources,
                speed_m_s: result.speed_of_sound_m_s,
            };
            let listener = p.listener;
            if settings.ambisonic_order > 0 {
                let order = settings.ambisonic_order as usize;
                let channels = ambisonic(&directions, bands, order, &listener, pair_seed);
                let path = out.join(format!("ambix_{stem}.wav"));
                wav::write_f32(&path, &channels, SAMPLE_RATE_HZ)?;
                written.push(path);
            }
            if settings.binaural {
                let table = match &settings.hrtf {
                    Some(path) => Some(super::hrtf::load_sofa_cached(path).map_err(anyhow::Error::msg)?),
                    None => None,
                };
                let head = table.as_deref().map_or(Head::Sphere, Head::Measured);
                let ears = binaural(&directions, bands, &listener, &head, pair_seed);
                let path = out.join(format!("brir_{stem}.wav"));
                wav::write_f32(&path, &ears, SAMPLE_RATE_HZ)?;
                written.push(path);
            }
        }
        // Impulse response (level of the squared pressure, 1 ms RMS) and decay curves.
        let per_ms = (SAMPLE_RATE_HZ / 1000) as usize;
        let peak = ir.iter().fold(0.0f32, |m, v| m.max(v.abs())).max(f32::MIN_POSITIVE);
        let ir_points: Vec<(f64, f64)> = ir
            .chunks(per_ms)
            .enumerate()
            .map(|(k, c)| {
                let rms = (c.iter().map(|v| v * v).sum::<f32>() / c.len() as f32).sqrt();
                (k as f64 * 1e-3, (20.0 * f64::from((rms / peak).max(1e-6)).log10()).max(-100.0))
            })
            .collect();
        let t_end = p.histogram.len() as f64 * result.bin_s;
        let png = out.join(format!("ir_{stem}.png"));
        line_chart(
            &png,
            &Chart {
                title: &format!("Impulse response {} -> {}", p.source, p.receiver),
                x_label: "time (s)",
                y_label: "level re peak (dB)",
                x_range: (0.0, t_end),
                y_range: (-100.0, 0.0),
                marker_label: None,
            },
            &[Series::new("1 ms RMS", ir_points)],
        )?;
        written.push(png);
        let series = decay_series(&p.histogram, &result.bands_hz, result.bin_s, p.direct_s, extrapolated);
        let png = out.join(format!("decay_{stem}.png"));
        line_chart(
            &png,
            &Chart {
                title: &format!("Energy decay curves {} -> {}", p.source, p.receiver),
                x_label: "time (s)",
                y_label: "Schroeder decay (dB)",
                x_range: (0.0, decay_plot_end_s(&series, t_end)),
                y_range: (DECAY_PLOT_FLOOR_DB, 0.0),
                marker_label: Some("truncation (Lundeby)"),
            },
            &series,
        )?;
        written.push(png);
    }
    Ok(written)
}

/// Lowest level of the decay plots, dB: T30 needs the curves down to -35 dB.
const DECAY_PLOT_FLOOR_DB: f64 = -60.0;

/// The decay curves of one pair as chart series: the curves the parameters are computed from
/// ([`decay_curve`]: from the direct sound's bin on, ending at the truncation point where the
/// band has a noise floor, that point marked), down to [`DECAY_PLOT_FLOOR_DB`]; bands whose
/// surface data is extrapolated dashed and labelled so.
fn decay_series(
    histogram: &[[f64; BAND_COUNT]],
    bands_hz: &[f32],
    bin_s: f64,
    direct_s: f64,
    extrapolated: &[bool; BAND_COUNT],
) -> Vec<Series> {
    (0..BAND_COUNT.min(bands_hz.len()))
        .map(|b| {
            let band: Vec<f64> = histogram.iter().map(|h| h[b]).collect();
            let curve = decay_curve(&band, bin_s, direct_s);
            let points: Vec<(f64, f64)> = curve
                .edc_db
                .iter()
                .enumerate()
                .map(|(k, v)| (curve.start_s + k as f64 * curve.bin_s, *v))
                .take_while(|(_, v)| v.is_finite() && *v >= DECAY_PLOT_FLOOR_DB)
                .collect();
            let markers = match (curve.truncation_s, points.last()) {
                (Some(_), Some(&last)) if points.len() == curve.edc_db.len() => vec![last],
                _ => Vec::new(),
            };
            let extrap = extrapolated[b];
            Series {
                label: format!("{} Hz{}", bands_hz[b], if extrap { " (extrap.)" } else { "" }),
                points,
                dashed: extrap,
                markers,
            }
        })
        .collect()
}

/// End of the decay plots' time axis: the latest point any curve shows, plus 5 %, within
/// the histogram.
fn decay_plot_end_s(series: &[Series], histogram_s: f64) -> f64 {
    let last = series.iter().filter_map(|s| s.points.last()).map(|p| p.0).fold(0.0f64, f64::max);
    if last > 0.0 { (1.05 * last).min(histogram_s) } else { histogram_s }
}

/// The printed summary: room estimates and parameters averaged over the pairs.
pub fn summary_text(r: &AcousticResult) -> String {
    let mut o = String::new();
    let _ = writeln!(
        o,
        "room: {:.2} m^3, {:.2} m^2, c = {:.2} m/s",
        r.volume_m3, r.surface_m2, r.speed_of_sound_m_s
    );
    let _ = write!(o, "{:<10}", "band Hz");
    for f in r.bands_hz {
        let _ = write!(o, "{f:>8}");
    }
    let _ = writeln!(o);
    let mut line = |name: &str, v: &dyn Fn(usize) -> Option<f64>, digits: usize| {
        let _ = write!(o, "{name:<10}");
        for b in 0..r.bands_hz.len() {
            let _ = match v(b) {
                Some(x) => write!(o, "{x:>8.digits$}"),
                None => write!(o, "{:>8}", "-"),
            };
        }
        let _ = writeln!(o);
    };
    line("Sabine s", &|b| Some(r.sabine_s[b]), 3);
    line("Eyring s", &|b| Some(r.eyring_s[b]), 3);
    let mean = |f: &dyn Fn(&crate::acoustic::metrics::BandMetrics) -> Option<f64>, b: usize| {
        let v: Vec<f64> = r.pairs.iter().filter_map(|p| f(&p.metrics[b])).collect();
        (!v.is_empty()).then(|| v.iter().sum::<f64>() / v.len() as f64)
    };
    line("EDT s", &|b| mean(&|m| m.edt_s, b), 3);
    line("T20 s", &|b| mean(&|m| m.t20_s, b), 3);
    line("T30 s", &|b| mean(&|m| m.t30_s, b), 3);
    line("C80 dB", &|b| mean(&|m| m.c80_db, b), 2);
    line("D50", &|b| mean(&|m| m.d50, b), 3);
    line("G dB", &|b| mean(&|m| m.g_db, b), 1);
    let _ = writeln!(o, "(parameters averaged over {} source-receiver pairs)", r.pairs.len());
    o
}

/// Writes every output of a finished run into `out` (rank 0 only: the caller holds the
/// result) and `acoustic.json` with the plan, the result and the times since `started`
/// (tracing ends as this is called); returns the files.
pub fn write_all(
    out: &Path,
    world: &World,
    plan: &Plan,
    result: &AcousticResult,
    scene_label: &str,
    cluster: &Cluster,
    started: std::time::Instant,
) -> anyhow::Result<Vec<PathBuf>> {
    let trace_time_s = started.elapsed().as_secs_f64();
    let mut written =
        write_outputs(out, result, result.volume_m3, plan.settings.seed, &extrapolated_bands(world))?;
    let summary_path = out.join("acoustic.json");
    let json = serde_json::json!({
        "propsim_version": env!("CARGO_PKG_VERSION"),
        "scene": scene_label,
        "sources": plan.sources,
        "receivers": plan.receivers,
        "result": result,
        "wall_time_s": started.elapsed().as_secs_f64(),
        "trace_time_s": trace_time_s,
        "processes": cluster.size(),
        "reduce": cluster.reduce_cost(),
        "notes": {
            "histogram": "energy fluence per 1 ms bin and octave band, J/m^2 per joule emitted (times source power in W): the direct sound at d metres gives 1/(4 pi d^2)",
            "wav": "48 kHz float pressure impulse response; the sum of squared band-filtered samples over a bin equals the histogram's energy there",
            "ambix": "48 kHz float Ambisonic impulse response, ACN channel order, SN3D normalisation, in the receiver's head frame (x front, y left, z up); channel 0 (W) is the mono response",
            "brir": "48 kHz float binaural impulse response (left, right) of a spherical head of radius 8.75 cm (Duda and Martens 1998) in the receiver's head frame",
            "metrics": "ISO 3382-1 from the Schroeder curve, truncated at the noise floor with late-decay compensation (Lundeby et al. 1995) where the decay has one; C50, C80, D50 and Ts counted from the direct-sound arrival d/c, with the whole 1 ms bin holding the direct sound early; G re the same source at 10 m in a free field",
        },
    });
    crate::io::atomic::write_bytes(&summary_path, serde_json::to_string_pretty(&json)?.as_bytes())?;
    written.push(summary_path);
    Ok(written)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decay_series_mark_truncation_and_extrapolated_bands() {
        // Band 3 decays with T = 1 s into a floor 40 dB below its first bin; the others
        // decay cleanly (T = 0.5 s) to the end. The direct sound arrives at 12.4 ms.
        let k3 = 6.0 * std::f64::consts::LN_10;
        let hist: Vec<[f64; BAND_COUNT]> = (0..2000)
            .map(|i| {
                let t = i as f64 * 1e-3 - 0.012;
                std::array::from_fn(|b| match (t < 0.0, b) {
                    (true, _) => 0.0,
                    (false, 3) => (-k3 * t).exp() + 1e-4,
                    (false, _) => (-2.0 * k3 * t).exp(),
                })
            })
            .collect();
        let mut extrapolated = [false; BAND_COUNT];
        extrapolated[0] = true;
        extrapolated[7] = true;
        let bands = crate::scene::materials::OCTAVE_BANDS_HZ;
        let series = decay_series(&hist, &bands, 1e-3, 0.0124, &extrapolated);
        assert_eq!(series.len(), BAND_COUNT);
        for (b, s) in series.iter().enumerate() {
            assert_eq!(s.dashed, b == 0 || b == 7, "{}", s.label);
            assert_eq!(s.label.ends_with("(extrap.)"), b == 0 || b == 7, "{}", s.label);
            // Every curve starts at 0 dB at the start of the direct sound's bin.
            assert!(s.points[0].0 == 0.012 && s.points[0].1.abs() < 1e-9, "{}: {:?}", s.label, s.points[0]);
            assert!(s.points.iter().all(|p| p.1 >= DECAY_PLOT_FLOOR_DB && p.1 <= 1e-9));
        }
        // Only band 3 is truncated: one marker, on the curve's last point, near the crossing
        // of the decay with the floor (40 dB below the first bin at T = 1 s: 0.67 s later).
        for (b, s) in series.iter().enumerate() {
            assert_eq!(s.markers.len(), usize::from(b == 3), "{}", s.label);
        }
        let marker = series[3].markers[0];
        assert_eq!(Some(&marker), series[3].points.last());
        assert!((marker.0 - (0.012 + 0.667)).abs() < 0.03, "{marker:?}");
    }
}
