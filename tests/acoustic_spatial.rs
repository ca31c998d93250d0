//! Directions of arrival and the spatial responses from a whole simulation
//! (docs/acoustics.md, Directions of arrival; Ambisonic and binaural responses).

mod common;

use common::box_room;
use propsim::acoustic::ambisonics::steer_peak;
use propsim::acoustic::directions::CELLS;
use propsim::acoustic::impulse_response::synthesize_bands;
use propsim::acoustic::spatial::{Listener, PairDirections, ambisonic};
use propsim::acoustic::{AcousticSettings, ReceiverSpec, SourceSpec, simulate};

#[test]
fn the_directional_record_holds_the_rays_energy_and_the_direct_sound_decodes_to_the_source() {
    // A 10 x 8 x 3 m room (absorption 0.2, scattering 0.5), no air absorption: in every
    // direction bin the cells together hold what the histogram's bins hold less the image
    // sources (the same deposits, summed twice), to fixed-point rounding; and the third-order
    // Ambisonic response at the direct sound's peak, steered, points at the source.
    let dir = tempfile::tempdir().unwrap();
    let world = box_room(dir.path(), [10.0, 8.0, 3.0], 0.2, 0.5);
    let settings = AcousticSettings {
        rays: 20_000,
        air_absorption: false,
        ambisonic_order: 3,
        max_time_s: Some(0.6),
        ..Default::default()
    };
    let (src, rcv) = ([2.0f32, 3.0, 1.5], [7.0f32, 5.5, 1.2]);
    let sources =
        [SourceSpec { name: "S".into(), position: src, power_w: 1.0, directivity: Default::default() }];
    let receivers = [ReceiverSpec {
        name: "R".into(),
        position: rcv,
        radius_m: Some(0.3),
        listener: Default::default(),
        directivity: Default::default(),
    }];
    let r = simulate(&world, &sources, &receivers, &settings, &|_| {}).unwrap();
    let p = &r.pairs[0];
    let bins = settings.direction_bins();
    assert_eq!(p.directions.len(), bins.count(p.histogram.len()) * CELLS);
    for band in 0..8 {
        let mut from_hist = vec![0.0f64; bins.count(p.histogram.len())];
        for (k, h) in p.histogram.iter().enumerate() {
            from_hist[bins.of(k)] += h[band];
        }
        for a in &p.image_sources {
            let k = (a.length_m / r.speed_of_sound_m_s / r.bin_s) as usize;
            from_hist[bins.of(k)] -= a.energy[band];
        }
        let total: f64 = from_hist.iter().sum();
        for (db, want) in from_hist.iter().enumerate() {
            let got: f64 = p.directions[db * CELLS..(db + 1) * CELLS].iter().map(|e| e[band]).sum();
            // (The directional record sums each block in f32: 1e-4 covers its rounding.)
            assert!(
                (got - want).abs() <= 1e-4 * want.abs() + 1e-9 * total,
                "band {band}, direction bin {db}: {got:e} vs {want:e}"
            );
        }
    }
    let directions = PairDirections {
        histogram: &p.histogram,
        bin_s: r.bin_s,
        directions: &p.directions,
        direction_bins: bins,
        image_sources: &p.image_sources,
        speed_m_s: r.speed_of_sound_m_s,
    };
    let bands = synthesize_bands(&p.histogram, r.bin_s, r.volume_m3, r.speed_of_sound_m_s, 1);
    let amb = ambisonic(&directions, &bands, 3, &Listener::default(), 1);
    // The direct sound's 1 ms: the channels' correlation with W over it, sum_n W(n) c_k(n),
    // is Y_k(u) sum W^2 for a plane wave from u.
    let onset = (p.direct_s / r.bin_s) as usize * 48;
    let snapshot: Vec<f64> = amb
        .iter()
        .map(|c| (onset..onset + 48).map(|n| f64::from(amb[0][n]) * f64::from(c[n])).sum())
        .collect();
    let found = steer_peak(&snapshot);
    let want = (glam::Vec3::from(src) - glam::Vec3::from(rcv)).as_dvec3().normalize();
    let err = found.dot(want).clamp(-1.0, 1.0).acos().to_degrees();
    eprintln!("direct sound decoded {err:.3} degrees from the source");
    assert!(err < 2.0, "direct sound decoded {err} degrees from the source");
    // The late part is spread over the sphere: the first-order channels carry energy.
    let late = |c: &[f32]| c[(0.3 * 48_000.0) as usize..].iter().map(|v| f64::from(*v).powi(2)).sum::<f64>();
    let w = late(&amb[0]);
    for (k, channel) in amb.iter().enumerate().take(4).skip(1) {
        assert!(late(channel) > 0.05 * w, "channel {k}: {} of W's {w}", late(channel));
    }
}
