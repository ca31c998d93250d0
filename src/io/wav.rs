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
