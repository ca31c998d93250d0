//! Ray splitting (docs/acoustics.md, Ray splitting): the built-in showcase's decay curves are
//! smooth down to -35 dB at its default ray count, where without splitting a few rays on the
//! flutter path between its parallel walls made steps of several dB.

use std::path::Path;

use propsim::acoustic::metrics::schroeder_db;
use propsim::acoustic::{AcousticResult, AcousticSettings, scene_points, simulate};
use propsim::scene::{self, LoadOptions, World};

/// The showcase at its scene's ray count (10^5), seed 1, with `split_copies` (1: no splitting).
fn showcase(split_copies: u32) -> AcousticResult {
    let world = World::build(scene::load(Path::new("builtin:showcase"), &LoadOptions::default()).unwrap());
    let (sources, receivers) = scene_points(&world);
    let rays = world.scene.desc.acoustic.as_ref().and_then(|a| a.rays).unwrap();
    assert_eq!(rays, 100_000);
    let settings = AcousticSettings { rays, split_copies, ..Default::default() };
    simulate(&world, &sources, &receivers, &settings, &|_| {}).unwrap()
}

/// Steps in a Schroeder curve `level_db` (1 ms bins): the largest distance, dB, between the
/// curve and its least-squares line over the 51 ms around each point, over the points from
/// -5 to -35 dB. A decay that is straight over 50 ms gives 0; one lone strong arrival gives
/// about half the step it makes.
fn roughness_db(level_db: &[f64]) -> f64 {
    const HALF: usize = 25;
    let mut worst = 0.0f64;
    for k in (0..level_db.len()).filter(|&k| (-35.0..=-5.0).contains(&level_db[k])) {
        let (a, b) = (k.saturating_sub(HALF), (k + HALF + 1).min(level_db.len()));
        let n = (b - a) as f64;
        let xs = || (a..b).map(|x| x as f64);
        let mx = xs().sum::<f64>() / n;
        let my = level_db[a..b].iter().sum::<f64>() / n;
        let sxx: f64 = xs().map(|x| (x - mx) * (x - mx)).sum();
        let sxy: f64 = xs().zip(&level_db[a..b]).map(|(x, y)| (x - mx) * (y - my)).sum();
        let fit = my + sxy / sxx * (k as f64 - mx);
        worst = worst.max((level_db[k] - fit).abs());
    }
    worst
}

/// The roughest of the showcase's 16 decay curves (two receivers, eight bands), dB.
fn roughest(r: &AcousticResult) -> (f64, String) {
    let mut worst = (0.0, String::new());
    for p in &r.pairs {
        for b in 0..8 {
            let band: Vec<f64> = p.histogram.iter().map(|h| h[b]).collect();
            let rough = roughness_db(&schroeder_db(&band));
            if rough > worst.0 {
                worst = (rough, format!("{} {} Hz", p.receiver, r.bands_hz[b]));
            }
        }
    }
    worst
}

/// Reference: the Schroeder level, dB, every 50 ms from 50 to 700 ms, per receiver and band
/// (63 Hz to 8 kHz), of a 4 x 10^6-ray run (seed 7, splitting on).
const REFERENCE_DB: [[[f64; 14]; 8]; 2] = include!("data/showcase_decay_reference.in");

#[test]
fn the_showcase_decay_curves_are_smooth_to_35_db_at_the_default_ray_count() {
    let with = showcase(AcousticSettings::default().split_copies);
    let (rough, at) = roughest(&with);
    assert!(rough < 1.5, "splitting: a decay curve has steps of {rough:.2} dB ({at})");
    // The test can fail: without splitting, the same rays give steps of several dB.
    let without = showcase(1);
    let (rough_without, at_without) = roughest(&without);
    assert!(rough_without > 4.0, "without splitting: {rough_without:.2} dB ({at_without})");
    // And the smooth curves are the right ones: near a high-ray-count reference.
    let mut far = (0.0f64, String::new());
    for (p, reference) in with.pairs.iter().zip(&REFERENCE_DB) {
        for (b, levels) in reference.iter().enumerate() {
            let band: Vec<f64> = p.histogram.iter().map(|h| h[b]).collect();
            let edc = schroeder_db(&band);
            for (i, want) in levels.iter().enumerate().filter(|(_, w)| (-35.0..=-5.0).contains(*w)) {
                let d = (edc[50 * (i + 1)] - want).abs();
                if d > far.0 {
                    far = (d, format!("{} {} Hz at {} ms", p.receiver, with.bands_hz[b], 50 * (i + 1)));
                }
            }
        }
    }
    assert!(far.0 < TOLERANCE_DB, "{:.2} dB from the reference ({})", far.0, far.1);
}

/// How far the 10^5-ray curves may be from the reference down to -35 dB.
const TOLERANCE_DB: f64 = 2.5;
