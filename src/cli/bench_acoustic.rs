//! `propsim bench acoustic`: wall time and rays per second of the whole acoustic job
//! (rays, image sources, histograms, parameters and impulse responses, no file writing) on
//! the shoebox and on BRAS CR2 (10 source-receiver pairs, all bands).

use rayon::prelude::*;
use std::path::PathBuf;
use std::time::Instant;

use clap::Args;

use crate::acoustic::impulse_response::synthesize;
use crate::acoustic::{AcousticSettings, scene_points, simulate};
use crate::core::bench::{median, peak_rss_mb};
use crate::scene::{self, LoadOptions, World};

#[derive(Args, Debug)]
pub struct BenchAcousticArgs {
    /// Scenes to time (default: builtin:shoebox and builtin:bras_cr2).
    pub scenes: Vec<PathBuf>,
    /// Rays per source.
    #[arg(long, default_value_t = 100_000)]
    pub rays: u64,
    /// Timed repetitions; the median is reported.
    #[arg(long, default_value_t = 3)]
    pub repeat: usize,
}

pub fn run(args: &BenchAcousticArgs) -> anyhow::Result<()> {
    let scenes = if args.scenes.is_empty() {
        vec![PathBuf::from("builtin:shoebox"), PathBuf::from("builtin:bras_cr2")]
    } else {
        args.scenes.clone()
    };
    anyhow::ensure!(
        (1..=1000).contains(&args.repeat),
        "--repeat {}: must be between 1 and 1000",
        args.repeat
    );
    anyhow::ensure!(
        (1..=1_000_000_000).contains(&args.rays),
        "--rays {}: must be between 1 and 10^9",
        args.rays
    );
    crate::outln!("threads: {}", rayon::current_num_threads());
    for path in scenes {
        let world = World::build(scene::load(&path, &LoadOptions::default())?);
        let desc = world.scene.desc.acoustic.clone().unwrap_or_default();
        let (sources, receivers) = scene_points(&world);
        anyhow::ensure!(
            !sources.is_empty() && !receivers.is_empty(),
            "{}: the scene has no sources or receivers",
            path.display()
        );
        let settings = AcousticSettings {
            rays: args.rays,
            max_time_s: desc.max_time_s.map(f64::from),
            ..Default::default()
        };
        let mut times = Vec::new();
        let mut pairs = 0;
        let mut segments = 0;
        for _ in 0..args.repeat {
            let t = Instant::now();
            let r = simulate(&world, &sources, &receivers, &settings, &|_| {})
                .map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
            // The impulse responses, pair by pair in parallel as `propsim acoustic` makes them.
            r.pairs.par_iter().for_each(|p| {
                std::hint::black_box(synthesize(&p.histogram, r.bin_s, r.volume_m3, r.speed_of_sound_m_s, 1));
            });
            times.push(t.elapsed().as_secs_f64());
            pairs = r.pairs.len();
            segments = r.segments;
        }
        let wall = median(times);
        let rays = args.rays * sources.len() as u64;
        crate::outln!(
            "{}: {} pairs, {} rays per source, wall {:.2} s (median of {}), {:.0} rays/s, {:.1} M ray segments/s ({} segments)",
            path.display(),
            pairs,
            args.rays,
            wall,
            args.repeat,
            rays as f64 / wall,
            segments as f64 / wall / 1e6,
            segments
        );
    }
    if let Some(mb) = peak_rss_mb() {
        crate::outln!("peak memory: {mb:.0} MB resident");
    }
    Ok(())
}
