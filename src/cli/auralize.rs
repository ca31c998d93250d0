//! `propsim auralize`: a dry signal convolved with an impulse response (any of propsim's:
//! mono, binaural or Ambisonic, every channel passed through), and `--make-dry` for a
//! synthetic dry test signal (docs/acoustics.md, Auralization).

use std::path::PathBuf;

use clap::Args;

use crate::acoustic::auralize::{PEAK_DBFS, auralize, make_dry, read_wav};
use crate::acoustic::impulse_response::SAMPLE_RATE_HZ;

#[derive(Args, Debug)]
pub struct AuralizeArgs {
    /// The impulse response (WAV; its channels are the output's).
    pub ir: Option<PathBuf>,
    /// The dry (anechoic) signal (WAV, the IR's sample rate; several channels are mixed to mono).
    pub dry: Option<PathBuf>,
    /// The result (32-bit float WAV, peak normalised to -1 dBFS).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
    /// Write the synthetic dry test signal (48 kHz mono: four clicks, then speech-like
    /// syllables) to this file instead, and convolve nothing.
    #[arg(long, value_name = "FILE.wav", conflicts_with_all = ["ir", "dry", "output"])]
    pub make_dry: Option<PathBuf>,
    /// Length of the --make-dry signal, s (0.5 to 60).
    #[arg(long, default_value_t = 6.0)]
    pub seconds: f64,
}

pub fn run(args: &AuralizeArgs) -> anyhow::Result<()> {
    if let Some(path) = &args.make_dry {
        anyhow::ensure!(
            (0.5..=60.0).contains(&args.seconds),
            "--seconds {}: must be between 0.5 and 60",
            args.seconds
        );
        let dry = make_dry(SAMPLE_RATE_HZ, args.seconds);
        crate::io::wav::write_f32(path, &[dry], SAMPLE_RATE_HZ)?;
        say!(
            "wrote {} ({} s, 48 kHz mono: clicks, then speech-like syllables)",
            path.display(),
            args.seconds
        );
        return Ok(());
    }
    let (Some(ir_path), Some(dry_path), Some(out)) = (&args.ir, &args.dry, &args.output) else {
        anyhow::bail!("usage: propsim auralize IR.wav DRY.wav -o OUT.wav (or --make-dry FILE.wav)");
    };
    let ir = read_wav(ir_path).map_err(anyhow::Error::msg)?;
    let dry = read_wav(dry_path).map_err(anyhow::Error::msg)?;
    let (ir_name, dry_name) = (ir_path.display().to_string(), dry_path.display().to_string());
    let result = auralize(&ir, &dry, &ir_name, &dry_name).map_err(anyhow::Error::msg)?;
    crate::io::wav::write_f32(out, &result.signal.channels, result.signal.sample_rate_hz)?;
    if dry.channels.len() > 1 {
        tell!("note: {dry_name} has {} channels: mixed down to mono before convolving", dry.channels.len());
    }
    say!(
        "wrote {} ({} channel{}, {:.2} s); normalised by {:+.1} dB to a peak of {PEAK_DBFS} dBFS",
        out.display(),
        result.signal.channels.len(),
        if result.signal.channels.len() == 1 { "" } else { "s" },
        result.signal.len() as f64 / f64::from(result.signal.sample_rate_hz),
        result.gain_db
    );
    Ok(())
}
