//! WAV output through hound.

use std::path::Path;

/// Writes mono 32-bit float samples at `sample_rate_hz`.
pub fn write_f32_mono(path: &Path, samples: &[f32], sample_rate_hz: u32) -> anyhow::Result<()> {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: sample_rate_hz,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    // Encoded in memory (hound seeks back to fill in the header), then written checked.
    let mut bytes = std::io::Cursor::new(Vec::with_capacity(44 + 4 * samples.len()));
    let mut w = hound::WavWriter::new(&mut bytes, spec)?;
    for &s in samples {
        w.write_sample(s)?;
    }
    w.finalize()?;
    super::atomic::write_bytes(path, bytes.get_ref())
}

/// Writes 32-bit float samples of several channels (each `channels[c]`, all as long as the
/// first; a shorter one is padded with zeros) at `sample_rate_hz`, interleaved.
pub fn write_f32(path: &Path, channels: &[Vec<f32>], sample_rate_hz: u32) -> anyhow::Result<()> {
    let n = channels.len();
    anyhow::ensure!((1..=usize::from(u16::MAX)).contains(&n), "{}: {n} channels", path.display());
    let spec = hound::WavSpec {
        channels: n as u16,
        sample_rate: sample_rate_hz,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let frames = channels[0].len();
    let mut bytes = std::io::Cursor::new(Vec::with_capacity(44 + 4 * n * frames));
    let mut w = hound::WavWriter::new(&mut bytes, spec)?;
    for i in 0..frames {
        for c in channels {
            w.write_sample(c.get(i).copied().unwrap_or(0.0))?;
        }
    }
    w.finalize()?;
    super::atomic::write_bytes(path, bytes.get_ref())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_through_hound() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("x.wav");
        write_f32_mono(&p, &[0.0, 0.5, -0.25], 48_000).unwrap();
        let mut r = hound::WavReader::open(&p).unwrap();
        assert_eq!(r.spec().sample_rate, 48_000);
        let s: Vec<f32> = r.samples::<f32>().map(Result::unwrap).collect();
        assert_eq!(s, vec![0.0, 0.5, -0.25]);
    }
}
