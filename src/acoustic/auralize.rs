//! Auralization: a dry (anechoic) signal convolved with an impulse response, by FFT, and a
//! synthetic dry test signal (docs/acoustics.md, Auralization).
//!
//! The output has the impulse response's channels: a mono IR gives a mono result, a binaural
//! IR two ear signals, an Ambisonic IR an Ambisonic signal, each channel the dry signal
//! convolved with that channel. A dry signal of several channels is mixed down to mono
//! first (a dry source is one signal; a stereo recording is not a dry source). The result is
//! scaled by one gain for all channels (so interaural and Ambisonic relations hold) that puts
//! its peak at [`PEAK_DBFS`], so it cannot clip in any WAV format.

use std::path::Path;

use rustfft::FftPlanner;
use rustfft::num_complex::Complex;

/// Peak level of the written result, dB re full scale.
pub const PEAK_DBFS: f64 = -1.0;

/// A WAV file's content: the sample rate and each channel's samples in [-1, 1].
#[derive(Clone, Debug, PartialEq)]
pub struct Signal {
    pub sample_rate_hz: u32,
    pub channels: Vec<Vec<f32>>,
}

impl Signal {
    /// Samples per channel.
    pub fn len(&self) -> usize {
        self.channels.first().map_or(0, Vec::len)
    }

    /// Whether the signal holds no samples.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

/// Reads a WAV file of integer (8 to 32 bits, scaled to [-1, 1]) or 32-bit float samples.
/// Errors are one line naming the file.
pub fn read_wav(path: &Path) -> Result<Signal, String> {
    let name = path.display();
    let mut reader = hound::WavReader::open(path).map_err(|e| match e {
        hound::Error::IoError(io) if io.kind() == std::io::ErrorKind::NotFound => {
            format!("{name}: file not found")
        }
        hound::Error::IoError(io) => format!("{name}: cannot read: {io}"),
        other => format!("{name}: not a readable WAV file: {other}"),
    })?;
    let spec = reader.spec();
    let n = usize::from(spec.channels);
    if n == 0 || spec.sample_rate == 0 {
        return Err(format!("{name}: a WAV file with {n} channels at {} Hz", spec.sample_rate));
    }
    let interleaved: Vec<f32> = match spec.sample_format {
        hound::SampleFormat::Float if spec.bits_per_sample == 32 => reader
            .samples::<f32>()
            .collect::<Result<_, _>>()
            .map_err(|e| format!("{name}: malformed WAV data: {e}"))?,
        hound::SampleFormat::Int if (1..=32).contains(&spec.bits_per_sample) => {
            let full = 2f64.powi(i32::from(spec.bits_per_sample) - 1);
            reader
                .samples::<i32>()
                .map(|s| s.map(|v| (f64::from(v) / full) as f32))
                .collect::<Result<_, _>>()
                .map_err(|e| format!("{name}: malformed WAV data: {e}"))?
        }
        _ => {
            return Err(format!(
                "{name}: {}-bit {:?} samples are not supported (integer up to 32 bits or 32-bit float)",
                spec.bits_per_sample, spec.sample_format
            ));
        }
    };
    if let Some(bad) = interleaved.iter().find(|v| !v.is_finite()) {
        return Err(format!("{name}: holds a non-finite sample ({bad})"));
    }
    let frames = interleaved.len() / n;
    let channels =
        (0..n).map(|c| (0..frames).map(|i| interleaved[i * n + c]).collect::<Vec<f32>>()).collect();
    Ok(Signal { sample_rate_hz: spec.sample_rate, channels })
}

/// The result of [`auralize`]: the convolved channels and the gain applied to them.
#[derive(Clone, Debug, PartialEq)]
pub struct Auralized {
    pub signal: Signal,
    /// The one gain applied to every channel to put the peak at [`PEAK_DBFS`], dB.
    pub gain_db: f64,
}

/// Convolves `dry` (mixed down to mono if it has several channels) with each channel of `ir`
/// and normalises the result to a peak of [`PEAK_DBFS`] ([`Auralized::gain_db`] says by how
/// much). `ir_name` and `dry_name` name the files in the one-line errors: different sample
/// rates, or an empty signal.
pub fn auralize(ir: &Signal, dry: &Signal, ir_name: &str, dry_name: &str) -> Result<Auralized, String> {
    if ir.sample_rate_hz != dry.sample_rate_hz {
        return Err(format!(
            "{dry_name}: sample rate {} Hz, but the impulse response {ir_name} has {} Hz: resample one of them",
            dry.sample_rate_hz, ir.sample_rate_hz
        ));
    }
    if ir.is_empty() {
        return Err(format!("{ir_name}: the impulse response holds no samples"));
    }
    if dry.is_empty() {
        return Err(format!("{dry_name}: the dry signal holds no samples"));
    }
    let mono: Vec<f32> = if dry.channels.len() == 1 {
        dry.channels[0].clone()
    } else {
        let k = 1.0 / dry.channels.len() as f32;
        (0..dry.len()).map(|i| dry.channels.iter().map(|c| c[i]).sum::<f32>() * k).collect()
    };
    let mut channels: Vec<Vec<f64>> = convolve_each(&mono, &ir.channels);
    let peak = channels.iter().flatten().fold(0.0f64, |m, v| m.max(v.abs()));
    let target = 10f64.powf(PEAK_DBFS / 20.0);
    let gain = if peak > 0.0 { target / peak } else { 1.0 };
    for c in &mut channels {
        for v in c.iter_mut() {
            *v *= gain;
        }
    }
    Ok(Auralized {
        signal: Signal {
            sample_rate_hz: ir.sample_rate_hz,
            channels: channels.into_iter().map(|c| c.into_iter().map(|v| v as f32).collect()).collect(),
        },
        gain_db: 20.0 * gain.log10(),
    })
}

/// The linear convolution of `x` with each of `hs` (length `x + h - 1`), by one FFT of `x`
/// and one forward and one inverse FFT per channel, in f64 (a 2^20-point transform keeps
/// the result to about 1e-12 of its peak, far below a float WAV's resolution).
pub fn convolve_each(x: &[f32], hs: &[Vec<f32>]) -> Vec<Vec<f64>> {
    let longest = hs.iter().map(Vec::len).max().unwrap_or(0);
    if x.is_empty() || longest == 0 {
        return hs.iter().map(|_| Vec::new()).collect();
    }
    let n_fft = (x.len() + longest - 1).next_power_of_two();
    let mut planner = FftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(n_fft);
    let inverse = planner.plan_fft_inverse(n_fft);
    let spectrum = |s: &[f32]| {
        let mut v: Vec<Complex<f64>> = s.iter().map(|&a| Complex::new(f64::from(a), 0.0)).collect();
        v.resize(n_fft, Complex::new(0.0, 0.0));
        forward.process(&mut v);
        v
    };
    let xs = spectrum(x);
    let scale = 1.0 / n_fft as f64;
    hs.iter()
        .map(|h| {
            if h.is_empty() {
                return vec![0.0; x.len()];
            }
            let mut y = spectrum(h);
            for (a, b) in y.iter_mut().zip(&xs) {
                *a *= *b;
            }
            inverse.process(&mut y);
            y.truncate(x.len() + h.len() - 1);
            y.into_iter().map(|v| v.re * scale).collect()
        })
        .collect()
}

/// The dry test signal, `seconds` long at `sample_rate_hz` (mono, peak 0.5): first a click
/// train (one raised-cosine click of 1 ms every 0.5 s, four clicks), which shows the
/// response itself, then speech-like syllables (docs/acoustics.md, Auralization): a glottal
/// pulse train at a fundamental gliding between 110 and 140 Hz, shaped by three formant
/// resonators set to a sequence of vowels (/a/, /i/, /u/, /e/, /o/ from Peterson and
/// Barney's male averages), 180 ms each with 70 ms pauses and a raised-cosine envelope, so
/// the reverberation is heard in the gaps. Deterministic: no random numbers at all.
pub fn make_dry(sample_rate_hz: u32, seconds: f64) -> Vec<f32> {
    let fs = f64::from(sample_rate_hz.max(8000));
    let n = (seconds.clamp(0.5, 60.0) * fs) as usize;
    let mut out = vec![0.0f64; n];
    // The click train: 4 clicks over the first two seconds.
    let click_len = ((1e-3 * fs) as usize).max(2);
    for k in 0..4 {
        let at = (k as f64 * 0.5 * fs) as usize + (0.05 * fs) as usize;
        for i in 0..click_len {
            if let Some(o) = out.get_mut(at + i) {
                let x = i as f64 / (click_len - 1) as f64;
                *o += 0.5 - 0.5 * (2.0 * std::f64::consts::PI * x).cos();
            }
        }
    }
    // Syllables from 2 s on.
    const VOWELS: [[f64; 3]; 5] = [
        [730.0, 1090.0, 2440.0],
        [270.0, 2290.0, 3010.0],
        [300.0, 870.0, 2240.0],
        [530.0, 1840.0, 2480.0],
        [570.0, 840.0, 2410.0],
    ];
    let (syllable, pause) = ((0.18 * fs) as usize, (0.07 * fs) as usize);
    let mut start = (2.0 * fs) as usize;
    let mut v = 0;
    while start + syllable < n {
        // The source: a pulse train (one sample per glottal period) with a gliding pitch.
        let mut excitation = vec![0.0f64; syllable];
        let mut phase = 0.0f64;
        for (i, e) in excitation.iter_mut().enumerate() {
            let t = i as f64 / syllable as f64;
            let f0 = 110.0 + 30.0 * (std::f64::consts::PI * (t + 0.3 * v as f64)).sin().abs();
            phase += f0 / fs;
            if phase >= 1.0 {
                phase -= 1.0;
                *e = 1.0;
            }
        }
        // Three formant resonators in parallel (two-pole, bandwidth 80-120 Hz), normalised
        // to unit gain at their centre.
        let mut voiced = vec![0.0f64; syllable];
        for (j, &f) in VOWELS[v % VOWELS.len()].iter().enumerate() {
            let bw = 80.0 + 20.0 * j as f64;
            let r = (-std::f64::consts::PI * bw / fs).exp();
            let theta = 2.0 * std::f64::consts::PI * f.min(0.45 * fs) / fs;
            let (a1, a2) = (-2.0 * r * theta.cos(), r * r);
            let g = (1.0 - r) * (1.0 - 2.0 * r * (2.0 * theta).cos() + r * r).sqrt();
            let weight = [1.0, 0.5, 0.25][j] * g;
            let (mut y1, mut y2) = (0.0, 0.0);
            for (o, &x) in voiced.iter_mut().zip(&excitation) {
                let y = x - a1 * y1 - a2 * y2;
                y2 = y1;
                y1 = y;
                *o += weight * y;
            }
        }
        for (i, y) in voiced.iter().enumerate() {
            let envelope = 0.5 - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / syllable as f64).cos();
            out[start + i] += envelope * y;
        }
        start += syllable + pause;
        v += 1;
    }
    // Peak 0.5 for the syllables and the clicks alike.
    let syllables_from = ((2.0 * fs) as usize).min(n);
    let peak = out[syllables_from..].iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if peak > 0.0 {
        for o in &mut out[syllables_from..] {
            *o *= 0.5 / peak;
        }
    }
    for o in &mut out[..syllables_from] {
        *o *= 0.5;
    }
    out.into_iter().map(|v| v as f32).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fft_convolution_matches_the_direct_sum() {
        // y[n] = sum_k x[k] h[n - k], by the definition, for two impulse responses of
        // different lengths.
        let x: Vec<f32> = (0..300).map(|i| ((i * 37 % 101) as f32 / 50.0) - 1.0).collect();
        let hs = vec![
            (0..77).map(|i| (i as f32 * 0.3).sin() * 0.9f32.powi(i)).collect::<Vec<f32>>(),
            vec![0.0, 0.0, 1.0, -0.5],
        ];
        let y = convolve_each(&x, &hs);
        for (h, yc) in hs.iter().zip(&y) {
            assert_eq!(yc.len(), x.len() + h.len() - 1);
            for (n, &got) in yc.iter().enumerate() {
                let want: f64 = (0..x.len())
                    .filter(|&k| n >= k && n - k < h.len())
                    .map(|k| f64::from(x[k]) * f64::from(h[n - k]))
                    .sum();
                assert!((got - want).abs() < 1e-9, "n {n}: {got} vs {want}");
            }
        }
    }

    #[test]
    fn auralize_keeps_channels_normalises_and_refuses_mismatched_rates() {
        let ir = Signal { sample_rate_hz: 48_000, channels: vec![vec![1.0, 0.5], vec![0.0, 0.0, 2.0]] };
        let dry = Signal { sample_rate_hz: 48_000, channels: vec![vec![1.0, 1.0, 1.0], vec![1.0, 1.0, 1.0]] };
        let a = auralize(&ir, &dry, "ir.wav", "dry.wav").unwrap();
        assert_eq!(a.signal.channels.len(), 2);
        // Channel 2 peaks at 2 (the dry mixed to 1.0 times 2): scaled to -1 dBFS, one gain.
        let target = 10f64.powf(-1.0 / 20.0) as f32;
        let peak = a.signal.channels.iter().flatten().fold(0.0f32, |m, v| m.max(v.abs()));
        assert!((peak - target).abs() < 1e-6);
        assert!((a.gain_db - (-1.0 - 20.0 * 2f64.log10())).abs() < 1e-9, "{}", a.gain_db);
        assert!((a.signal.channels[0][1] / a.signal.channels[0][0] - 1.5).abs() < 1e-5);
        let other = Signal { sample_rate_hz: 44_100, ..dry.clone() };
        let e = auralize(&ir, &other, "ir.wav", "dry.wav").unwrap_err();
        assert!(e.starts_with("dry.wav:") && e.contains("44100") && !e.contains('\n'), "{e}");
        let empty = Signal { sample_rate_hz: 48_000, channels: vec![Vec::new()] };
        assert!(auralize(&empty, &dry, "ir.wav", "dry.wav").unwrap_err().starts_with("ir.wav:"));
        assert!(auralize(&ir, &empty, "ir.wav", "dry.wav").unwrap_err().starts_with("dry.wav:"));
    }

    #[test]
    fn the_dry_signal_is_deterministic_bounded_and_has_gaps() {
        let a = make_dry(48_000, 4.0);
        assert_eq!(a, make_dry(48_000, 4.0));
        assert_eq!(a.len(), 4 * 48_000);
        let peak = a.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        assert!((peak - 0.5).abs() < 1e-6, "{peak}");
        // The pause after the first syllable (2.18 s to 2.25 s) is silent.
        assert!(a[(2.185 * 48_000.0) as usize..(2.245 * 48_000.0) as usize].iter().all(|&v| v == 0.0));
        // The syllables carry energy at their fundamental and formants, not only clicks.
        let e: f32 = a[2 * 48_000..(2.18 * 48_000.0) as usize].iter().map(|v| v * v).sum();
        assert!(e > 1.0, "{e}");
    }

    #[test]
    fn unreadable_wavs_are_one_line_errors_naming_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let missing = dir.path().join("missing.wav");
        let e = read_wav(&missing).unwrap_err();
        assert!(e.contains("missing.wav") && e.contains("not found") && !e.contains('\n'), "{e}");
        let junk = dir.path().join("junk.wav");
        std::fs::write(&junk, b"RIFF1234WAVEjunk").unwrap();
        let e = read_wav(&junk).unwrap_err();
        assert!(e.starts_with(&junk.display().to_string()) && !e.contains('\n'), "{e}");
        let good = dir.path().join("good.wav");
        crate::io::wav::write_f32(&good, &[vec![0.25, -0.5], vec![1.0, 0.0]], 48_000).unwrap();
        let s = read_wav(&good).unwrap();
        assert_eq!(s, Signal { sample_rate_hz: 48_000, channels: vec![vec![0.25, -0.5], vec![1.0, 0.0]] });
    }
}
