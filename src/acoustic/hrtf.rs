//! Measured head-related transfer functions from a SOFA file (AES69), reduced to what the
//! binaural response uses per segment: each ear's gain per octave band and delay, on a
//! direction grid (docs/acoustics.md, Ambisonic and binaural responses).
//!
//! The SOFA file is read by the `sofar` crate (pure Rust, no system library). For every
//! direction of a 5-degree grid in azimuth and elevation the interpolated HRIR pair is
//! taken; each ear's band gain is the RMS magnitude of its spectrum over the band's FFT bins
//! (4096 points), and its delay is the file's delay plus the HRIR's onset (the first sample
//! reaching a tenth of its peak), so that the interaural time difference survives.

use std::path::Path;

use glam::DVec3;
use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

use super::impulse_response::{SAMPLE_RATE_HZ, band_edges_hz};
use crate::scene::materials::BAND_COUNT;

/// Grid step, degrees.
const STEP_DEG: f64 = 5.0;
/// Azimuths on the grid (0 to 355 degrees).
const AZIMUTHS: usize = 72;
/// Elevations on the grid (-90 to 90 degrees).
const ELEVATIONS: usize = 37;
/// FFT size of the band gains.
const N_FFT: usize = 4096;

/// Each ear's (gain, delay in samples) per band, for one direction.
pub type Ears = [[(f64, f64); BAND_COUNT]; 2];

/// A measured head on the direction grid.
#[derive(Clone, Debug)]
pub struct EarTable {
    entries: Vec<Ears>,
}

impl EarTable {
    /// The table of `hrir`, which gives the left and right impulse responses (at
    /// [`SAMPLE_RATE_HZ`]) and extra delays (s) for a unit direction in the head's frame.
    pub fn from_hrirs(hrir: impl Fn(DVec3) -> ([Vec<f32>; 2], [f64; 2])) -> Self {
        let fs = f64::from(SAMPLE_RATE_HZ);
        let mut planner = FftPlanner::<f64>::new();
        let fft = planner.plan_fft_forward(N_FFT);
        let edges = band_edges_hz(fs);
        let df = fs / N_FFT as f64;
        let mut entries = Vec::with_capacity(AZIMUTHS * ELEVATIONS);
        for e in 0..ELEVATIONS {
            for a in 0..AZIMUTHS {
                let (irs, delays) = hrir(grid_direction(a, e));
                let mut ears = [[(0.0, 0.0); BAND_COUNT]; 2];
                for (ear, (ir, delay)) in ears.iter_mut().zip(irs.iter().zip(delays)) {
                    let peak = ir.iter().fold(0.0f32, |m, v| m.max(v.abs()));
                    let onset = ir.iter().position(|v| v.abs() >= 0.1 * peak).unwrap_or(0);
                    let mut x: Vec<Complex<f64>> =
                        ir.iter().take(N_FFT).map(|&v| Complex::new(f64::from(v), 0.0)).collect();
                    x.resize(N_FFT, Complex::new(0.0, 0.0));
                    fft.process(&mut x);
                    for (b, slot) in ear.iter_mut().enumerate() {
                        let (lo, hi) = edges[b];
                        let bins: Vec<f64> = (0..=N_FFT / 2)
                            .filter(|&k| {
                                let f = k as f64 * df;
                                f >= lo && f < hi
                            })
                            .map(|k| x[k].norm_sqr())
                            .collect();
                        let gain = if bins.is_empty() {
                            0.0
                        } else {
                            (bins.iter().sum::<f64>() / bins.len() as f64).sqrt()
                        };
                        let d = if delay.is_finite() { delay.max(0.0) } else { 0.0 };
                        *slot = (gain, onset as f64 + d * fs);
                    }
                }
                entries.push(ears);
            }
        }
        Self { entries }
    }

    /// Reads a SOFA file (resampled to [`SAMPLE_RATE_HZ`] if needed) and builds its table.
    /// The error is one line naming the file.
    pub fn load_sofa(path: &Path) -> Result<Self, String> {
        let name = path.display();
        let bytes = std::fs::read(path).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => format!("{name}: file not found"),
            _ => format!("{name}: cannot read: {e}"),
        })?;
        // The reader is a port of a C library: a malformed file must not take the run down
        // with a panic, whatever its parser does with it.
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        let opened = std::panic::catch_unwind(|| {
            sofar::reader::OpenOptions::new().sample_rate(SAMPLE_RATE_HZ as f32).open_data(&bytes)
        });
        std::panic::set_hook(previous);
        let sofa = match opened {
            Ok(Ok(s)) => s,
            Ok(Err(e)) => return Err(format!("{name}: not a readable SOFA file: {e}")),
            Err(_) => return Err(format!("{name}: not a readable SOFA file (its parser failed)")),
        };
        let len = sofa.filter_len();
        if len == 0 || len > 1 << 16 {
            return Err(format!("{name}: SOFA impulse responses of {len} samples"));
        }
        // sofar looks a direction up by distance to the measured positions: ask at their
        // radius (the median), or every lookup blends the nearest measurement with its
        // neighbours and the ears' onsets drift to the earliest of them.
        let mut radii: Vec<f32> = sofa
            .hrtf()
            .source_position
            .values
            .chunks_exact(3)
            .map(|p| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt())
            .filter(|r| r.is_finite() && *r > 0.0)
            .collect();
        radii.sort_by(f32::total_cmp);
        let radius = f64::from(radii.get(radii.len() / 2).copied().unwrap_or(1.0));
        let table = Self::from_hrirs(|d| {
            let mut f = sofar::reader::Filter::new(len);
            let p = d * radius;
            sofa.filter(p.x as f32, p.y as f32, p.z as f32, &mut f);
            ([f.left.to_vec(), f.right.to_vec()], [f64::from(f.ldelay), f64::from(f.rdelay)])
        });
        if table.entries.iter().all(|e| e.iter().all(|ear| ear.iter().all(|(g, _)| *g == 0.0))) {
            return Err(format!("{name}: the SOFA file gives no impulse response in any direction"));
        }
        Ok(table)
    }

    /// Both ears' (gain, delay in samples) in band `b` for the unit direction `d` in the
    /// head's frame (the nearest grid direction).
    pub fn ears(&self, d: DVec3, b: usize) -> [(f64, f64); 2] {
        let d = d.try_normalize().unwrap_or(DVec3::X);
        let el = d.z.clamp(-1.0, 1.0).asin().to_degrees();
        let az = d.y.atan2(d.x).to_degrees().rem_euclid(360.0);
        let e = (((el + 90.0) / STEP_DEG).round() as usize).min(ELEVATIONS - 1);
        let a = ((az / STEP_DEG).round() as usize) % AZIMUTHS;
        let entry = &self.entries[e * AZIMUTHS + a];
        [entry[0][b.min(BAND_COUNT - 1)], entry[1][b.min(BAND_COUNT - 1)]]
    }
}

/// [`EarTable::load_sofa`], loaded once per file and process: the plan checks the file
/// before any ray is traced, and the writers use the same table.
pub fn load_sofa_cached(path: &Path) -> Result<std::sync::Arc<EarTable>, String> {
    use std::sync::{Arc, Mutex};
    static CACHE: Mutex<Vec<(std::path::PathBuf, Arc<EarTable>)>> = Mutex::new(Vec::new());
    let mut cache = CACHE.lock().unwrap_or_else(|poisoned| poisoned.into_inner());
    if let Some((_, t)) = cache.iter().find(|(p, _)| p == path) {
        return Ok(Arc::clone(t));
    }
    let table = Arc::new(EarTable::load_sofa(path)?);
    cache.push((path.to_path_buf(), Arc::clone(&table)));
    Ok(table)
}

/// The unit direction of grid point (azimuth index `a`, elevation index `e`): x front,
/// y left, z up.
fn grid_direction(a: usize, e: usize) -> DVec3 {
    let (az, el) = ((a as f64 * STEP_DEG).to_radians(), (e as f64 * STEP_DEG - 90.0).to_radians());
    DVec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::acoustic::spatial::HEAD_RADIUS_M;

    #[test]
    fn a_table_of_delayed_impulses_keeps_woodworths_itd_and_the_gains() {
        // HRIRs that are impulses of gain 0.5 (left) and 0.25 (right), each at the spherical
        // head's delay (docs/acoustics.md, Binaural) plus 3 samples: the table gives the gains
        // in every band and the delays to a sample (onsets are whole samples), so a source at
        // azimuth 90 degrees has Woodworth's ITD (a / c)(pi / 2 + 1).
        let c = 343.0;
        let table = EarTable::from_hrirs(|d| {
            let ir = |gain: f32, axis: DVec3| {
                let (_, t) =
                    crate::acoustic::spatial::head_ear(d.dot(axis).clamp(-1.0, 1.0).acos(), 1000.0, c);
                let mut v = vec![0.0f32; 128];
                v[3 + (t * 48_000.0).round() as usize] = gain;
                v
            };
            ([ir(0.5, DVec3::Y), ir(0.25, -DVec3::Y)], [0.0, 0.0])
        });
        for b in 0..BAND_COUNT {
            let [l, r] = table.ears(DVec3::Y, b);
            assert!((l.0 - 0.5).abs() < 1e-9 && (r.0 - 0.25).abs() < 1e-9, "band {b}: {l:?} {r:?}");
            let itd = (r.1 - l.1) / 48_000.0;
            let want = HEAD_RADIUS_M / c * (std::f64::consts::FRAC_PI_2 + 1.0);
            assert!((itd - want).abs() * 48_000.0 <= 1.0, "band {b}: {itd} vs {want}");
        }
    }

    #[test]
    fn a_sofa_file_of_delayed_impulses_keeps_woodworths_itd() {
        // tests/data/hrir_delays.sofa (rooms/tools/gen_sofa.py, a SimpleFreeFieldHRIR file as
        // netCDF writes it): each ear's HRIR is a unit impulse at the spherical head's path to
        // it, a = 8.75 cm, on a 10-degree grid. Read through sofar, a lateral source keeps
        // Woodworth's ITD (a / c)(pi / 2 + 1) = 31.5 samples to 1.5 samples (each ear's
        // impulse was rounded to a sample), the frontal source none, and the left ear leads
        // for a source on the left.
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/hrir_delays.sofa");
        let table = EarTable::load_sofa(&path).unwrap();
        let want = 0.0875 / 343.0 * (std::f64::consts::FRAC_PI_2 + 1.0) * 48_000.0;
        for b in 0..BAND_COUNT {
            let [l, r] = table.ears(DVec3::Y, b);
            assert!((r.1 - l.1 - want).abs() <= 1.5, "band {b}: ITD {} samples vs {want:.2}", r.1 - l.1);
            let [l, r] = table.ears(-DVec3::Y, b);
            assert!((l.1 - r.1 - want).abs() <= 1.5, "band {b}: ITD {} samples vs {want:.2}", l.1 - r.1);
            let [l, r] = table.ears(DVec3::X, b);
            assert!((l.1 - r.1).abs() <= 1.0, "band {b}: frontal ITD {}", l.1 - r.1);
            assert!(l.0 > 0.0 && r.0 > 0.0);
        }
    }

    #[test]
    fn bad_sofa_files_are_one_line_errors_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing.sofa");
        let e = EarTable::load_sofa(&missing).unwrap_err();
        assert!(e.contains("missing.sofa") && e.contains("not found") && !e.contains('\n'), "{e}");
        let junk = dir.path().join("junk.sofa");
        std::fs::write(&junk, b"\x89HDF\r\n\x1a\nnot really").unwrap();
        let e = EarTable::load_sofa(&junk).unwrap_err();
        assert!(e.starts_with(&junk.display().to_string()) && !e.contains('\n'), "{e}");
    }
}
