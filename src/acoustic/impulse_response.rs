//! Pressure impulse responses from energy histograms (Kuttruff, Room Acoustics, sec. 9.4;
//! Vorlaender, Auralization, sec. 11.4): a Poisson sequence of +/-1 Diracs whose rate grows
//! like the density of image sources, split into octave bands, each band weighted bin by bin
//! so its energy equals the histogram's, then summed.

use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

use super::air::exact_octave_midbands_hz;
use crate::core::rng::{stream, uniform};
use crate::scene::materials::BAND_COUNT;

/// Output sample rate, Hz.
pub const SAMPLE_RATE_HZ: u32 = 48_000;

/// Band edges, Hz: the geometric means of neighbouring exact midband frequencies (IEC 61260-1);
/// the lowest band reaches down to 0 Hz and the highest up to the Nyquist frequency, so the
/// bands tile the spectrum.
pub fn band_edges_hz(sample_rate_hz: f64) -> [(f64, f64); BAND_COUNT] {
    let mid = exact_octave_midbands_hz();
    std::array::from_fn(|b| {
        let lo = if b == 0 { 0.0 } else { (mid[b - 1] * mid[b]).sqrt() };
        let hi = if b == BAND_COUNT - 1 { sample_rate_hz / 2.0 + 1.0 } else { (mid[b] * mid[b + 1]).sqrt() };
        (lo, hi)
    })
}

/// The FFT bins of `n_fft` inside band `(lo, hi)`, as a mask; both signs of frequency.
fn band_mask(n_fft: usize, fs: f64, (lo, hi): (f64, f64)) -> Vec<bool> {
    let df = fs / n_fft as f64;
    (0..n_fft)
        .map(|i| {
            let f = if i <= n_fft / 2 { i as f64 * df } else { (n_fft - i) as f64 * df };
            f >= lo && f < hi
        })
        .collect()
}

/// The Dirac sequence: arrival rate 4 pi c^3 t^2 / V (the density of reflections in a room
/// of volume V, Kuttruff eq. 4.3), capped at a quarter of the sample rate, random signs.
fn dirac_sequence(samples: usize, volume_m3: f64, speed_m_s: f64, seed: u64) -> Vec<f32> {
    let fs = f64::from(SAMPLE_RATE_HZ);
    let mut out = vec![0.0f32; samples];
    let mut rng = stream(seed, 0x1d1a, 0);
    let max_rate = fs / 4.0;
    // Start where the expected count since t = 0 reaches one reflection.
    let mut t = (3.0 * volume_m3 / (4.0 * std::f64::consts::PI * speed_m_s.powi(3))).cbrt();
    loop {
        let rate = (4.0 * std::f64::consts::PI * speed_m_s.powi(3) * t * t / volume_m3).clamp(1.0, max_rate);
        t += -(1.0 - f64::from(uniform(&mut rng))).ln() / rate;
        let n = (t * fs) as usize;
        if n >= samples {
            break;
        }
        out[n] += if uniform(&mut rng) < 0.5 { -1.0 } else { 1.0 };
    }
    out
}

/// Synthesises a pressure impulse response at [`SAMPLE_RATE_HZ`] from a histogram of band
/// energies (`histogram[k][b]`, bins of `bin_s`). For each band the Dirac sequence is weighted
/// bin by bin and then band-filtered (an ideal FFT band-pass, so bands do not overlap): a unit
/// Dirac filtered to a band keeps exactly the band's share of its energy (Parseval), so the
/// weight sqrt(E / (sum d^2 x share)) gives each bin and band the histogram's energy while
/// the filtering after weighting keeps each band's spectrum inside the band.
pub fn synthesize(
    histogram: &[[f64; BAND_COUNT]],
    bin_s: f64,
    volume_m3: f64,
    speed_m_s: f64,
    seed: u64,
) -> Vec<f32> {
    let fs = f64::from(SAMPLE_RATE_HZ);
    let per_bin = (bin_s * fs).round().max(1.0) as usize;
    let samples = histogram.len() * per_bin;
    if samples == 0 {
        return Vec::new();
    }
    let mut diracs = dirac_sequence(samples, volume_m3, speed_m_s, seed);
    // Every bin that holds energy needs a Dirac to carry it (the direct sound arrives before
    // the sequence's first events).
    for (k, bin) in histogram.iter().enumerate() {
        let span = &mut diracs[k * per_bin..(k + 1) * per_bin];
        if bin.iter().any(|&e| e > 0.0) && span.iter().all(|&d| d == 0.0) {
            span[0] = 1.0;
        }
    }
    let dirac_energy: Vec<f64> =
        diracs.chunks(per_bin).map(|c| c.iter().map(|&d| f64::from(d) * f64::from(d)).sum()).collect();
    let n_fft = samples.next_power_of_two() * 2;
    let mut planner = FftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(n_fft);
    let inverse = planner.plan_fft_inverse(n_fft);
    let mut out = vec![0.0f64; samples];
    let scale = 1.0 / n_fft as f64;
    for (b, edges) in band_edges_hz(fs).into_iter().enumerate() {
        let mask = band_mask(n_fft, fs, edges);
        let share = mask.iter().filter(|&&m| m).count() as f64 / n_fft as f64;
        let mut band = vec![Complex::new(0.0, 0.0); n_fft];
        for (k, bin) in histogram.iter().enumerate() {
            if bin[b] <= 0.0 || dirac_energy[k] <= 0.0 {
                continue;
            }
            let gain = (bin[b] / (dirac_energy[k] * share)).sqrt();
            for n in k * per_bin..(k + 1) * per_bin {
                band[n].re = gain * f64::from(diracs[n]);
            }
        }
        forward.process(&mut band);
        for (v, &m) in band.iter_mut().zip(&mask) {
            if !m {
                *v = Complex::new(0.0, 0.0);
            }
        }
        inverse.process(&mut band);
        let filtered: Vec<f64> = band[..samples].iter().map(|v| v.re * scale).collect();
        // A few strong Diracs closer together than the band's coherence time (1 / bandwidth)
        // interfere, so one realisation misses the target energy; correct it over windows of
        // at least 4 / bandwidth with gains interpolated between window centres.
        let bandwidth = (edges.1.min(fs / 2.0) - edges.0).max(1.0);
        let window_bins = ((4.0 / bandwidth) / bin_s).ceil().max(1.0) as usize;
        let windows: Vec<(f64, f64)> = histogram
            .chunks(window_bins)
            .enumerate()
            .map(|(w, chunk)| {
                let target: f64 = chunk.iter().map(|h| h[b]).sum();
                let start = w * window_bins * per_bin;
                let end = (start + chunk.len() * per_bin).min(samples);
                let energy: f64 = filtered[start..end].iter().map(|v| v * v).sum();
                let gain = if energy > 0.0 { (target / energy).sqrt() } else { 0.0 };
                (0.5 * (start + end) as f64, gain)
            })
            .collect();
        let mut w = 0;
        let mut shaped = vec![0.0f64; samples];
        for (n, (o, v)) in shaped.iter_mut().zip(&filtered).enumerate() {
            let x = n as f64;
            while w + 1 < windows.len() && windows[w + 1].0 <= x {
                w += 1;
            }
            let gain = match windows.get(w + 1) {
                Some(&(c1, g1)) if x >= windows[w].0 => {
                    let (c0, g0) = windows[w];
                    g0 + (g1 - g0) * (x - c0) / (c1 - c0)
                }
                _ => windows[w].1,
            };
            *o = gain * v;
        }
        // Interpolated gains shift energy between neighbouring windows; one scalar restores
        // the band's total exactly.
        let target: f64 = histogram.iter().map(|h| h[b]).sum();
        let energy: f64 = shaped.iter().map(|v| v * v).sum();
        let correction = if energy > 0.0 { (target / energy).sqrt() } else { 0.0 };
        for (o, v) in out.iter_mut().zip(&shaped) {
            *o += correction * v;
        }
    }
    out.into_iter().map(|v| v as f32).collect()
}

/// Energy per bin and band of a signal, measured with the same band split: the inverse of
/// [`synthesize`], used to check it.
pub fn band_energies(signal: &[f32], bin_s: f64) -> Vec<[f64; BAND_COUNT]> {
    let fs = f64::from(SAMPLE_RATE_HZ);
    let per_bin = (bin_s * fs).round().max(1.0) as usize;
    let bins = signal.len() / per_bin;
    let n_fft = signal.len().next_power_of_two() * 2;
    let mut planner = FftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(n_fft);
    let inverse = planner.plan_fft_inverse(n_fft);
    let mut spectrum: Vec<Complex<f64>> =
        (0..n_fft).map(|i| Complex::new(signal.get(i).map_or(0.0, |&d| f64::from(d)), 0.0)).collect();
    forward.process(&mut spectrum);
    let mut out = vec![[0.0; BAND_COUNT]; bins];
    for (b, edges) in band_edges_hz(fs).into_iter().enumerate() {
        let mask = band_mask(n_fft, fs, edges);
        let mut band: Vec<Complex<f64>> =
            spectrum.iter().zip(&mask).map(|(v, &m)| if m { *v } else { Complex::new(0.0, 0.0) }).collect();
        inverse.process(&mut band);
        let scale = 1.0 / n_fft as f64;
        for (k, o) in out.iter_mut().enumerate() {
            o[b] = band[k * per_bin..(k + 1) * per_bin].iter().map(|v| (v.re * scale).powi(2)).sum();
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn band_energy_is_preserved() {
        // An exponential decay (T = 0.8 s) with a band-dependent level, 0.5 s long.
        let bins = 500;
        let hist: Vec<[f64; BAND_COUNT]> = (0..bins)
            .map(|k| std::array::from_fn(|b| 1e-3 * (b as f64 + 1.0) * (-13.8 * k as f64 * 1e-3 / 0.8).exp()))
            .collect();
        let ir = synthesize(&hist, 1e-3, 200.0, 343.0, 1);
        let measured = band_energies(&ir, 1e-3);
        for b in 1..BAND_COUNT {
            let want: f64 = hist.iter().map(|h| h[b]).sum();
            let got: f64 = measured.iter().map(|h| h[b]).sum();
            assert!((got - want).abs() / want < 0.03, "band {b}: {got} vs {want}");
            // Early and late halves separately: the time structure survives too.
            let want_late: f64 = hist[250..].iter().map(|h| h[b]).sum();
            let got_late: f64 = measured[250..].iter().map(|h| h[b]).sum();
            assert!(
                (got_late - want_late).abs() / want_late < 0.1,
                "band {b} late: {got_late} vs {want_late}"
            );
        }
        let total_want: f64 = hist.iter().flatten().sum();
        let total_got: f64 = ir.iter().map(|&v| f64::from(v).powi(2)).sum();
        assert!((total_got - total_want).abs() / total_want < 0.03, "{total_got} vs {total_want}");
    }

    #[test]
    fn the_band_edges_tile_the_spectrum() {
        let e = band_edges_hz(48_000.0);
        assert_eq!(e[0].0, 0.0);
        for b in 1..BAND_COUNT {
            assert!((e[b].0 - e[b - 1].1).abs() < 1e-9);
        }
        assert!(e[BAND_COUNT - 1].1 > 24_000.0);
    }
}
