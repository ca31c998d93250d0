//! Room acoustics from the library API: T30 and C80 of the shoebox at 1 kHz, and its
//! impulse response as a WAV.
//!   cargo run --release --example acoustic_room

use propsim::acoustic::impulse_response::{SAMPLE_RATE_HZ, synthesize};
use propsim::acoustic::{AcousticSettings, ReceiverSpec, SourceSpec, simulate};
use propsim::scene::{self, World};

fn main() -> anyhow::Result<()> {
    let world = World::build(scene::load("builtin:shoebox".as_ref(), &Default::default())?);
    let source = SourceSpec {
        name: "S".into(),
        position: [2.0, 3.0, 1.5],
        power_w: 1.0,
        directivity: Default::default(),
    };
    let receiver = ReceiverSpec {
        name: "R".into(),
        position: [7.0, 5.0, 1.2],
        radius_m: None,
        listener: Default::default(),
        directivity: Default::default(),
    };
    let settings = AcousticSettings { rays: 100_000, ..Default::default() };
    let result = simulate(&world, &[source], &[receiver], &settings, &|_| {}).map_err(anyhow::Error::msg)?;
    let pair = &result.pairs[0];
    let m = &pair.metrics[4]; // 1 kHz
    println!(
        "1 kHz: T30 {:.3} s (Eyring {:.3} s), C80 {:.2} dB",
        m.t30_s.unwrap_or(f64::NAN),
        result.eyring_s[4],
        m.c80_db.unwrap_or(f64::NAN)
    );
    let ir = synthesize(&pair.histogram, result.bin_s, result.volume_m3, result.speed_of_sound_m_s, 1);
    std::fs::create_dir_all("out")?;
    propsim::io::wav::write_f32_mono("out/example_ir.wav".as_ref(), &ir, SAMPLE_RATE_HZ)?;
    println!("wrote out/example_ir.wav ({} samples at {SAMPLE_RATE_HZ} Hz)", ir.len());
    Ok(())
}
