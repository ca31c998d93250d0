//! Measured directivity balloons from SOFA files ([AES69], docs/references.md): a loudspeaker's, a talker's or a
//! microphone's energy per octave band over the sphere (docs/acoustics.md, Directivity).
//!
//! A balloon is read from the `FreeFieldDirectivityTF` convention (AES69-2022: transfer
//! functions `Data.Real`/`Data.Imag` at the frequencies of `N`, one receiver per direction
//! around the source at the origin) or from impulse responses (`Data.IR` at
//! `Data.SamplingRate`, as `GeneralFIR` stores them, again one receiver per direction). Each
//! direction's band energy is the mean of `|H(f)|^2` over the band's frequencies (octave
//! edges `f_m / sqrt 2` to `f_m sqrt 2`), averaged over the file's measurements. The
//! directions are resampled onto a 5-degree azimuth-elevation grid by inverse-square angular
//! distance weighting of the three nearest measured directions, and each band is normalised
//! so that its mean over the sphere (the grid's solid-angle quadrature) is 1, as the
//! first-order patterns are: the file's absolute level is discarded and the source's power
//! stays its `power_w`. A lookup interpolates the grid bilinearly.
//!
//! The balloon's frame is SOFA's: +x the front, +y the left, +z the top.
//! The netCDF-4 (HDF5) container is read by the `netcdf-reader` crate (pure Rust; `sofar`'s
//! reader, used for HRIRs, cannot read the frequency variable `N`).

use std::path::Path;
use std::sync::Arc;

use glam::Vec3;
use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

use super::air::exact_octave_midbands_hz;
use crate::scene::materials::{BAND_COUNT, BandValues};

/// Grid step, degrees.
const STEP_DEG: f32 = 5.0;
/// Azimuths on the grid (0 to 355 degrees).
const AZIMUTHS: usize = 72;
/// Elevations on the grid (-90 to 90 degrees).
const ELEVATIONS: usize = 37;
/// The fewest measured directions a balloon may have (a tetrahedron's).
const MIN_DIRECTIONS: usize = 4;
/// Measured directions blended into each grid direction.
const NEAREST: usize = 3;

/// A measured directivity on the direction grid, normalised per band to a mean of 1 over the
/// sphere.
#[derive(Clone, PartialEq)]
pub struct Balloon {
    /// The file it was read from, as given (for reports and errors).
    pub file: String,
    /// Energy weight per band, elevation-major on the grid.
    weights: Vec<BandValues>,
}

impl Balloon {
    /// The balloon of band energies `energy[i]` measured in the unit directions `dirs[i]`
    /// (balloon frame). Errors: no direction, a non-finite or negative energy, or a band
    /// with no energy anywhere.
    pub fn from_measurements(
        file: &str,
        dirs: &[Vec3],
        energy: &[[f64; BAND_COUNT]],
    ) -> Result<Self, String> {
        if dirs.is_empty() || dirs.len() != energy.len() {
            return Err(format!("{file}: the directivity has no measured direction"));
        }
        if energy.iter().flatten().any(|e| !(e.is_finite() && *e >= 0.0)) {
            return Err(format!("{file}: the directivity has a non-finite or negative value"));
        }
        let mut grid = vec![[0.0f64; BAND_COUNT]; AZIMUTHS * ELEVATIONS];
        for (g, slot) in grid.iter_mut().enumerate() {
            let d = grid_direction(g % AZIMUTHS, g / AZIMUTHS);
            // The NEAREST measured directions by angle (largest dot product).
            let mut best: [(f32, usize); NEAREST] = [(f32::NEG_INFINITY, 0); NEAREST];
            for (i, m) in dirs.iter().enumerate() {
                let c = d.dot(*m);
                if c > best[NEAREST - 1].0 {
                    best[NEAREST - 1] = (c, i);
                    best.sort_by(|a, b| b.0.total_cmp(&a.0));
                }
            }
            let mut total_w = 0.0;
            for &(c, i) in best.iter().filter(|(c, _)| c.is_finite()) {
                let angle = f64::from(c.clamp(-1.0, 1.0)).acos();
                if angle < 1e-6 {
                    *slot = energy[i];
                    total_w = 0.0;
                    break;
                }
                let w = 1.0 / (angle * angle);
                for (s, e) in slot.iter_mut().zip(energy[i]) {
                    *s += w * e;
                }
                total_w += w;
            }
            if total_w > 0.0 {
                for s in slot.iter_mut() {
                    *s /= total_w;
                }
            }
        }
        // Normalise each band: the quadrature mean over the sphere becomes 1.
        let mut mean = [0.0f64; BAND_COUNT];
        for (g, e) in grid.iter().enumerate() {
            let w = cell_solid_angle(g / AZIMUTHS);
            for b in 0..BAND_COUNT {
                mean[b] += w * e[b];
            }
        }
        let mids = exact_octave_midbands_hz();
        for b in 0..BAND_COUNT {
            mean[b] /= 4.0 * std::f64::consts::PI;
            if !(mean[b] > 0.0 && mean[b].is_finite()) {
                return Err(format!(
                    "{file}: the directivity has no energy in the {:.0} Hz octave band",
                    mids[b]
                ));
            }
        }
        let weights = grid.iter().map(|e| std::array::from_fn(|b| (e[b] / mean[b]) as f32)).collect();
        Ok(Self { file: file.to_string(), weights })
    }

    /// Reads a SOFA file's balloon; the error is one line naming the file.
    pub fn load_sofa(path: &Path) -> Result<Self, String> {
        let name = path.display().to_string();
        let bytes = std::fs::read(path).map_err(|e| match e.kind() {
            std::io::ErrorKind::NotFound => format!("{name}: file not found"),
            _ => format!("{name}: cannot read: {e}"),
        })?;
        // A malformed file must not take the run down with a panic, whatever the parser
        // does with it.
        let previous = std::panic::take_hook();
        std::panic::set_hook(Box::new(|_| {}));
        let read = std::panic::catch_unwind(|| read_measurements(&name, &bytes));
        std::panic::set_hook(previous);
        let (dirs, energy) = match read {
            Ok(r) => r?,
            Err(_) => return Err(format!("{name}: not a readable SOFA file (its parser failed)")),
        };
        Self::from_measurements(&name, &dirs, &energy)
    }

    /// The energy weight of each band towards the unit direction `local` in the balloon's
    /// frame (mean 1 over the sphere).
    pub fn energy_weights(&self, local: Vec3) -> BandValues {
        let d = local.try_normalize().unwrap_or(Vec3::X);
        let el = d.z.clamp(-1.0, 1.0).asin().to_degrees() + 90.0;
        let az = d.y.atan2(d.x).to_degrees().rem_euclid(360.0);
        let (fe, fa) = (el / STEP_DEG, az / STEP_DEG);
        let e0 = (fe.floor() as usize).min(ELEVATIONS - 1);
        let e1 = (e0 + 1).min(ELEVATIONS - 1);
        let a0 = (fa.floor() as usize) % AZIMUTHS;
        let a1 = (a0 + 1) % AZIMUTHS;
        let (te, ta) = ((fe - e0 as f32).clamp(0.0, 1.0), (fa - fa.floor()).clamp(0.0, 1.0));
        let at = |e: usize, a: usize| &self.weights[e * AZIMUTHS + a];
        std::array::from_fn(|b| {
            let lo = at(e0, a0)[b] * (1.0 - ta) + at(e0, a1)[b] * ta;
            let hi = at(e1, a0)[b] * (1.0 - ta) + at(e1, a1)[b] * ta;
            lo * (1.0 - te) + hi * te
        })
    }

    /// A microphone's energy sensitivity per band to sound from `local` (balloon frame):
    /// the balloon relative to its front (+x), 1 there, as a microphone's response is
    /// normalised on its axis.
    pub fn sensitivity(&self, local: Vec3) -> BandValues {
        let w = self.energy_weights(local);
        let front = self.energy_weights(Vec3::X);
        std::array::from_fn(|b| if front[b] > 0.0 { w[b] / front[b] } else { 0.0 })
    }
}

impl std::fmt::Debug for Balloon {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Balloon({})", self.file)
    }
}

/// Reads balloons once per file and process (a scene may give the same file to many
/// sources).
pub fn load_sofa_cached(path: &Path) -> Result<Arc<Balloon>, String> {
    use std::collections::HashMap;
    use std::sync::Mutex;
    static CACHE: Mutex<Option<HashMap<std::path::PathBuf, Arc<Balloon>>>> = Mutex::new(None);
    let mut cache = CACHE.lock().unwrap_or_else(|e| e.into_inner());
    let map = cache.get_or_insert_with(HashMap::new);
    if let Some(b) = map.get(path) {
        return Ok(b.clone());
    }
    let b = Arc::new(Balloon::load_sofa(path)?);
    map.insert(path.to_path_buf(), b.clone());
    Ok(b)
}

/// The unit direction of grid cell (azimuth `a`, elevation `e`).
fn grid_direction(a: usize, e: usize) -> Vec3 {
    let az = (a as f32 * STEP_DEG).to_radians();
    let el = (e as f32 * STEP_DEG - 90.0).to_radians();
    Vec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
}

/// The solid angle of one grid cell of elevation row `e`: the band of sphere between the
/// row's half-steps, split among the azimuths (the poles' rows are caps).
fn cell_solid_angle(e: usize) -> f64 {
    let half = f64::from(STEP_DEG / 2.0).to_radians();
    let el = (e as f64 * f64::from(STEP_DEG) - 90.0).to_radians();
    let lo = (el - half).max(-std::f64::consts::FRAC_PI_2);
    let hi = (el + half).min(std::f64::consts::FRAC_PI_2);
    2.0 * std::f64::consts::PI * (hi.sin() - lo.sin()) / AZIMUTHS as f64
}

/// One named dataset of the file as numbers, with its shape and attributes.
struct Dataset {
    values: Vec<f64>,
    shape: Vec<usize>,
    attributes: Vec<(String, String)>,
}

impl Dataset {
    fn attribute(&self, name: &str) -> Option<&str> {
        self.attributes.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_str())
    }
}

/// Reads variable `name` of `nc` as numbers (`None` when the file has no such variable).
fn dataset(file: &str, nc: &netcdf_reader::NcFile, name: &str) -> Result<Option<Dataset>, String> {
    let Ok(var) = nc.variable(name) else { return Ok(None) };
    let shape: Vec<usize> = var.shape().iter().map(|&n| n as usize).collect();
    let attributes =
        var.attributes().iter().filter_map(|a| a.value.as_string().map(|v| (a.name.clone(), v))).collect();
    let values = nc
        .read_variable_as_f64(name)
        .map_err(|e| format!("{file}: cannot read the SOFA variable {name}: {e}"))?
        .iter()
        .copied()
        .collect::<Vec<f64>>();
    let expected: usize = shape.iter().product();
    if values.len() != expected {
        return Err(format!(
            "{file}: the SOFA variable {name} holds {} values for a shape {shape:?}",
            values.len()
        ));
    }
    Ok(Some(Dataset { values, shape, attributes }))
}

/// The measured directions (unit, balloon frame) and band energies of a SOFA file.
fn read_measurements(file: &str, bytes: &[u8]) -> Result<(Vec<Vec3>, Vec<[f64; BAND_COUNT]>), String> {
    let nc = netcdf_reader::NcFile::from_bytes(bytes)
        .map_err(|e| format!("{file}: not a readable SOFA (netCDF-4) file: {e}"))?;
    let attribute = |n: &str| nc.global_attribute(n).ok().and_then(|a| a.value.as_string());
    if attribute("Conventions").as_deref() != Some("SOFA") {
        return Err(format!("{file}: not a SOFA file (no Conventions = \"SOFA\" attribute)"));
    }
    let conventions = attribute("SOFAConventions").unwrap_or_default();
    if ["HRIR", "HRTF", "BRIR", "SRIR"].iter().any(|c| conventions.contains(c)) {
        return Err(format!(
            "{file}: a {conventions} file holds ears' or a room's responses, not a directivity"
        ));
    }
    let receivers = dataset(file, &nc, "ReceiverPosition")?
        .ok_or_else(|| format!("{file}: a directivity needs its directions as ReceiverPosition"))?;
    let dirs = directions(file, &receivers)?;
    let per_direction: Vec<[f64; BAND_COUNT]> = if let Some(real) = dataset(file, &nc, "Data.Real")? {
        let imag =
            dataset(file, &nc, "Data.Imag")?.ok_or_else(|| format!("{file}: Data.Real without Data.Imag"))?;
        let freqs = dataset(file, &nc, "N")?
            .ok_or_else(|| format!("{file}: transfer functions without their frequencies (N)"))?;
        if imag.shape != real.shape {
            return Err(format!("{file}: Data.Real and Data.Imag differ in shape"));
        }
        let (m, r, e, n) = mren(file, "Data.Real", &real.shape)?;
        if r != dirs.len() || freqs.values.len() != n {
            return Err(format!(
                "{file}: Data.Real has {r} receivers and {n} frequencies for {} directions and {} frequencies",
                dirs.len(),
                freqs.values.len()
            ));
        }
        band_energies(m, r, e, n, |at| {
            let k = at % n;
            (freqs.values[k], real.values[at].powi(2) + imag.values[at].powi(2))
        })?
        .into_iter()
        .map(|b| b.map_err(|f| format!("{file}: no frequency of N near the {f:.0} Hz band")))
        .collect::<Result<_, _>>()?
    } else if let Some(ir) = dataset(file, &nc, "Data.IR")? {
        let fs = dataset(file, &nc, "Data.SamplingRate")?
            .and_then(|d| d.values.first().copied())
            .ok_or_else(|| format!("{file}: impulse responses without Data.SamplingRate"))?;
        if !(fs.is_finite() && fs > 0.0) {
            return Err(format!("{file}: Data.SamplingRate {fs}: must be > 0"));
        }
        let (m, r, e, n) = mren(file, "Data.IR", &ir.shape)?;
        if r != dirs.len() {
            return Err(format!("{file}: Data.IR has {r} receivers for {} directions", dirs.len()));
        }
        if n == 0 || n > 1 << 20 {
            return Err(format!("{file}: impulse responses of {n} samples"));
        }
        // Each impulse response's power spectrum, then the same band means as for TFs.
        let n_fft = n.next_power_of_two().max(4096);
        let fft = FftPlanner::<f64>::new().plan_fft_forward(n_fft);
        let mut spectra = Vec::with_capacity(m * r * e * (n_fft / 2 + 1));
        let mut x = vec![Complex::new(0.0, 0.0); n_fft];
        for chunk in ir.values.chunks_exact(n) {
            x.iter_mut().for_each(|v| *v = Complex::new(0.0, 0.0));
            for (v, &s) in x.iter_mut().zip(chunk) {
                v.re = s;
            }
            fft.process(&mut x);
            spectra.extend(x[..=n_fft / 2].iter().map(|c| c.norm_sqr()));
        }
        let bins = n_fft / 2 + 1;
        band_energies(m, r, e, bins, |at| ((at % bins) as f64 * fs / n_fft as f64, spectra[at]))?
            .into_iter()
            .map(|b| {
                b.map_err(|f| format!("{file}: the sampling rate leaves no frequency in the {f:.0} Hz band"))
            })
            .collect::<Result<_, _>>()?
    } else {
        return Err(format!("{file}: neither Data.Real/Data.Imag nor Data.IR: not a directivity"));
    };
    Ok((dirs, per_direction))
}

/// `(M, R, E, N)` of a data variable shaped `[M, R, N]` or `[M, R, E, N]`.
fn mren(file: &str, name: &str, shape: &[usize]) -> Result<(usize, usize, usize, usize), String> {
    match *shape {
        [m, r, n] => Ok((m, r, 1, n)),
        [m, r, e, n] => Ok((m, r, e, n)),
        _ => Err(format!("{file}: {name} has shape {shape:?}; expected [M, R, N] or [M, R, E, N]")),
    }
}

/// Per receiver, its band energies: the mean over each octave band's frequencies of the
/// power `value(at)` (`at` the flat index into `[M, R, E, K]`, giving (frequency, power)),
/// averaged over measurements and emitters. A band with no frequency inside takes the power
/// at its midband, interpolated linearly in log frequency (or the nearest end); `Err(f)`
/// when there is no frequency at all.
#[allow(clippy::type_complexity)]
fn band_energies(
    m: usize,
    r: usize,
    e: usize,
    k: usize,
    value: impl Fn(usize) -> (f64, f64),
) -> Result<Vec<Result<[f64; BAND_COUNT], f64>>, String> {
    let mids = exact_octave_midbands_hz();
    let mut out = Vec::with_capacity(r);
    for ri in 0..r {
        let mut sum = [0.0f64; BAND_COUNT];
        let mut missing = None;
        for mi in 0..m {
            for ei in 0..e {
                let base = ((mi * r + ri) * e + ei) * k;
                let spectrum: Vec<(f64, f64)> = (0..k).map(|i| value(base + i)).collect();
                for b in 0..BAND_COUNT {
                    let (lo, hi) = (mids[b] / std::f64::consts::SQRT_2, mids[b] * std::f64::consts::SQRT_2);
                    let inside: Vec<f64> =
                        spectrum.iter().filter(|(f, _)| *f >= lo && *f < hi).map(|(_, p)| *p).collect();
                    if !inside.is_empty() {
                        sum[b] += inside.iter().sum::<f64>() / inside.len() as f64;
                        continue;
                    }
                    match interpolate_log(&spectrum, mids[b]) {
                        Some(p) => sum[b] += p,
                        None => missing = Some(mids[b]),
                    }
                }
            }
        }
        let count = (m * e).max(1) as f64;
        out.push(match missing {
            Some(f) => Err(f),
            None => Ok(sum.map(|s| s / count)),
        });
    }
    Ok(out)
}

/// The power at `f_hz` interpolated linearly in log frequency between the spectrum's
/// neighbouring positive frequencies (the nearest end outside them).
fn interpolate_log(spectrum: &[(f64, f64)], f_hz: f64) -> Option<f64> {
    let mut pts: Vec<(f64, f64)> =
        spectrum.iter().copied().filter(|(f, _)| *f > 0.0 && f.is_finite()).collect();
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let (first, last) = (pts.first()?, pts.last()?);
    if f_hz <= first.0 {
        return Some(first.1);
    }
    if f_hz >= last.0 {
        return Some(last.1);
    }
    let i = pts.iter().position(|(f, _)| *f > f_hz)?;
    let (f0, p0) = pts[i - 1];
    let (f1, p1) = pts[i];
    let t = (f_hz.ln() - f0.ln()) / (f1.ln() - f0.ln());
    Some(p0 + t * (p1 - p0))
}

/// The unit directions of a `ReceiverPosition` shaped `[R, C]` or `[R, C, I or M]` (the
/// first of the last axis), in cartesian metres or spherical degrees (its `Type`).
fn directions(file: &str, pos: &Dataset) -> Result<Vec<Vec3>, String> {
    let (r, c, last) = match *pos.shape.as_slice() {
        [r, c] => (r, c, 1),
        [r, c, l] => (r, c, l),
        _ => return Err(format!("{file}: ReceiverPosition has shape {:?}", pos.shape)),
    };
    if c != 3 || r < MIN_DIRECTIONS || last == 0 {
        return Err(format!(
            "{file}: a directivity needs ReceiverPosition of at least {MIN_DIRECTIONS} directions by 3 coordinates (it has {r} by {c})"
        ));
    }
    let spherical = pos.attribute("Type").is_some_and(|t| t.eq_ignore_ascii_case("spherical"));
    (0..r)
        .map(|i| {
            let v = |j: usize| pos.values[(i * c + j) * last];
            let d = if spherical {
                let (az, el) = (v(0).to_radians(), v(1).to_radians());
                glam::DVec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
            } else {
                glam::DVec3::new(v(0), v(1), v(2))
            };
            d.try_normalize()
                .map(|d| d.as_vec3())
                .ok_or_else(|| format!("{file}: receiver {i}: a direction of zero length or not finite"))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_grid_quadrature_covers_the_sphere() {
        let total: f64 = (0..ELEVATIONS).map(|e| cell_solid_angle(e) * AZIMUTHS as f64).sum();
        assert!((total / (4.0 * std::f64::consts::PI) - 1.0).abs() < 1e-12, "{total}");
    }

    #[test]
    fn a_sampled_cardioid_becomes_the_analytic_one() {
        // The cardioid's energy (1 + cos)^2 / 4 sampled on a Fibonacci set of 2000 directions,
        // normalised: w(theta) = (1 + cos theta)^2 / 4 / (1/3) (docs/acoustics.md).
        let n = 2000;
        let dirs: Vec<Vec3> = (0..n)
            .map(|i| {
                let z = 1.0 - (2 * i + 1) as f32 / n as f32;
                let phi = i as f32 * std::f32::consts::PI * (3.0 - 5f32.sqrt());
                let s = (1.0 - z * z).sqrt();
                Vec3::new(s * phi.cos(), s * phi.sin(), z)
            })
            .collect();
        let energy: Vec<[f64; BAND_COUNT]> =
            dirs.iter().map(|d| [(1.0 + f64::from(d.x)).powi(2) / 4.0 * 7.5; BAND_COUNT]).collect();
        let b = Balloon::from_measurements("test", &dirs, &energy).unwrap();
        for (d, expected) in [(Vec3::X, 3.0), (Vec3::Y, 0.75), (Vec3::new(0.5, 0.5, 0.70710677), 1.6875)] {
            let w = b.energy_weights(d)[3];
            assert!((w - expected).abs() < 0.02 * expected, "{d}: {w} vs {expected}");
        }
        assert!(b.energy_weights(-Vec3::X)[3] < 0.01);
        let s = b.sensitivity(Vec3::Y)[0];
        assert!((s - 0.25).abs() < 0.01, "{s}");
    }

    #[test]
    fn bad_balloons_are_one_line_errors() {
        let e = Balloon::from_measurements("f.sofa", &[], &[]).unwrap_err();
        assert!(e.starts_with("f.sofa: ") && !e.contains('\n'), "{e}");
        let e = Balloon::from_measurements("f.sofa", &[Vec3::X], &[[f64::NAN; BAND_COUNT]]).unwrap_err();
        assert!(e.contains("non-finite"), "{e}");
        let e = Balloon::from_measurements("f.sofa", &[Vec3::X], &[[0.0; BAND_COUNT]]).unwrap_err();
        assert!(e.contains("no energy") && e.contains("63 Hz"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let junk = dir.path().join("junk.sofa");
        std::fs::write(&junk, b"not an hdf5 file at all").unwrap();
        let e = Balloon::load_sofa(&junk).unwrap_err();
        assert!(e.contains("junk.sofa") && !e.contains('\n'), "{e}");
        let e = Balloon::load_sofa(&dir.path().join("none.sofa")).unwrap_err();
        assert!(e.contains("none.sofa") && e.contains("not found"), "{e}");
    }
}
