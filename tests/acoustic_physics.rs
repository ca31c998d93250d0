//! Room-acoustics physics against closed-form answers.

mod common;

use std::path::Path;

use common::{box_obj, box_room};
use propsim::acoustic::{AcousticSettings, ReceiverSpec, SourceSpec, simulate};
use propsim::scene::{self, LoadOptions, World};

fn src(p: [f32; 3]) -> Vec<SourceSpec> {
    vec![SourceSpec { name: "S".into(), position: p, power_w: 1.0, directivity: Default::default() }]
}

fn rcv(p: [f32; 3], r: Option<f32>) -> Vec<ReceiverSpec> {
    vec![ReceiverSpec {
        name: "R".into(),
        position: p,
        radius_m: r,
        listener: Default::default(),
        directivity: Default::default(),
    }]
}

#[test]
fn direct_sound_is_one_over_four_pi_d_squared_within_2_percent() {
    // A fully absorbing room: the receivers see the direct sound only. Rays alone (no
    // image sources), 10^6 rays, two radii.
    let dir = tempfile::tempdir().unwrap();
    let world = box_room(dir.path(), [20.0, 20.0, 20.0], 1.0, 0.0);
    let settings = AcousticSettings {
        rays: 1_000_000,
        use_image_sources: false,
        air_absorption: false,
        max_time_s: Some(0.1),
        ..Default::default()
    };
    for radius in [0.1, 0.4] {
        let d = 4.0f64;
        let r = simulate(
            &world,
            &src([8.0, 10.0, 10.0]),
            &rcv([12.0, 10.0, 10.0], Some(radius)),
            &settings,
            &|_| {},
        )
        .unwrap();
        let total: f64 = r.pairs[0].histogram.iter().map(|h| h[3]).sum();
        let expected = 1.0 / (4.0 * std::f64::consts::PI * d * d);
        let err = (total - expected).abs() / expected;
        assert!(err < 0.02, "radius {radius}: {total} vs {expected} ({:.2} %)", 100.0 * err);
    }
}

#[test]
fn closed_lossless_room_keeps_its_energy() {
    // No absorption, no air: nothing may leak through the mesh over 1 s.
    let dir = tempfile::tempdir().unwrap();
    let world = box_room(dir.path(), [10.0, 8.0, 3.0], 0.0, 0.5);
    let settings = AcousticSettings {
        rays: 20_000,
        use_image_sources: false,
        air_absorption: false,
        max_time_s: Some(1.0),
        ..Default::default()
    };
    let r = simulate(&world, &src([2.0, 3.0, 1.5]), &rcv([7.0, 5.0, 1.2], Some(0.5)), &settings, &|_| {})
        .unwrap();
    assert!(r.escaped_energy_fraction < 1e-3, "leak {}", r.escaped_energy_fraction);
    // In the diffuse steady state the fluence per unit time at any receiver is
    // E c / V (energy density times c): check the late histogram against it within 5 %.
    let h = &r.pairs[0].histogram;
    let late: f64 = h[200..1000].iter().map(|b| b[3]).sum::<f64>() / 0.8;
    let expected = r.speed_of_sound_m_s / 240.0;
    assert!((late - expected).abs() / expected < 0.05, "{late} vs {expected}");
}

/// T30 of the 10 x 8 x 3 m shoebox (scattering 0.5) against Eyring within `eyring_tol`, and
/// against Eyring corrected for the spread of free path lengths (Kuttruff, Room Acoustics,
/// sec. 5.5; gamma^2 of this box by Monte Carlo) within 5 %.
fn shoebox_t30(absorption: f32, air: bool, eyring_tol: f64) {
    use propsim::acoustic::room::{box_free_path_statistics, kuttruff_time_s};
    let dir = tempfile::tempdir().unwrap();
    let world = box_room(dir.path(), [10.0, 8.0, 3.0], absorption, 0.5);
    let settings = AcousticSettings { rays: 100_000, air_absorption: air, ..Default::default() };
    let r = simulate(&world, &src([2.0, 3.0, 1.5]), &rcv([7.0, 5.0, 1.2], None), &settings, &|_| {}).unwrap();
    let (_, gamma2) = box_free_path_statistics([10.0, 8.0, 3.0], 200_000, 3);
    let air_m = if air { settings.air.energy_coefficient_per_m() } else { [0.0; 8] };
    for b in [1, 3, 5, 6] {
        let t30 = r.pairs[0].metrics[b].t30_s.unwrap();
        let eyring = r.eyring_s[b];
        let kuttruff = kuttruff_time_s(
            240.0,
            268.0,
            f64::from(absorption),
            f64::from(air_m[b]),
            gamma2,
            r.speed_of_sound_m_s,
        );
        let hz = r.bands_hz[b];
        assert!(
            (t30 - eyring).abs() / eyring < eyring_tol,
            "a = {absorption}, air {air}, {hz} Hz: T30 {t30:.3} s vs Eyring {eyring:.3} s"
        );
        assert!(
            (t30 - kuttruff).abs() / kuttruff < 0.05,
            "a = {absorption}, air {air}, {hz} Hz: T30 {t30:.3} s vs Kuttruff {kuttruff:.3} s"
        );
    }
}

#[test]
fn shoebox_t30_matches_eyring_at_absorption_01() {
    shoebox_t30(0.1, false, 0.05);
    shoebox_t30(0.1, true, 0.05);
}

/// At a = 0.3 the spread of path lengths matters: diffuse-field theory puts T30 about 8 %
/// above Eyring for this box (gamma^2 = 0.40), and so does the simulation.
#[test]
fn shoebox_t30_at_absorption_03_follows_the_path_length_corrected_eyring() {
    shoebox_t30(0.3, false, 0.12);
    shoebox_t30(0.3, true, 0.12);
}

#[test]
fn a_single_ray_in_a_cube_gives_the_hand_computed_histogram() {
    use glam::Vec3;
    use propsim::acoustic::tracer::{SoundPropagation, SurfaceAcoustics};
    use propsim::core::TimeBins;
    use propsim::core::launcher::{Launch, LaunchPattern, launch};
    use propsim::core::{Accel, BuildQuality, Sphere, TriangleMesh};

    // A 4 m cube, absorption 0.2, purely specular; one ray from (1, 2, 2) along +x through a
    // receiver of radius 0.25 m at (3, 2, 2). The ray bounces between x = 4 and x = 0 and
    // crosses the receiver (chord 0.5 m) with its centre at path lengths 2, 4, 10, 12, 18,
    // 20, ... m after 0, 1, 2, 3, 4, 5, ... reflections.
    let mut mesh = TriangleMesh::default();
    let s = mesh.surface_id("wall");
    mesh.push_box(Vec3::ZERO, Vec3::splat(4.0), 1, s);
    let accel = Accel::build(&mesh, Vec::new(), BuildQuality::default());
    let receivers = [Sphere::new(Vec3::new(3.0, 2.0, 2.0), 0.25, 0)];
    let surfaces = [SurfaceAcoustics { absorption: [0.2; 8], scattering: [0.0; 8] }];
    let c = 343.2f32;
    let prop = SoundPropagation {
        surfaces: &surfaces,
        receivers: &receivers,
        ray_energy_j: 1.0,
        air_per_m: [0.0; 8],
        bins: TimeBins { speed_m_s: f64::from(c), bin_s: 1e-3, bins: 100 },
        skip_specular_up_to: None,
        roulette_factor: 1e-9,
        diffuse_rain: None,
        splitting: None,
        rain_in_view: &[],
        directivity: None,
        directions: None,
        edge_scattering: None,
        receiver_directivity: &[],
        ray_diffraction: None,
        scene_bounds: (Vec3::splat(-0.01), Vec3::splat(4.01)),
    };
    let spec = Launch {
        origin: Vec3::new(1.0, 2.0, 2.0),
        rays: 1,
        seed: 1,
        domain: 0,
        pattern: LaunchPattern::Fixed(Vec3::X),
        max_reflections: 1000,
        max_path_m: 30.0,
    };
    let record = launch(&accel, &prop, &spec, &|_| {});
    let volume = 4.0 / 3.0 * std::f32::consts::PI * 0.25f32.powi(3);
    let per_crossing = 0.5 / volume;
    let expected: Vec<(u32, f32)> = [2.0f32, 4.0, 10.0, 12.0, 18.0, 20.0, 26.0, 28.0]
        .iter()
        .enumerate()
        .map(|(k, path)| ((path / c / 1e-3) as u32, per_crossing * 0.8f32.powi(k as i32)))
        .collect();
    // The record's histogram, in fixed point of the launch energy (1 J here).
    let got: Vec<(u32, f32)> = record.fixed[0]
        .iter()
        .enumerate()
        .filter(|(_, e)| e[3] > 0)
        .map(|(k, e)| (k as u32, propsim::core::fixed::from_fixed(e[3], 1.0) as f32))
        .collect();
    assert_eq!(record.detections, vec![8]);
    assert_eq!(got.len(), expected.len(), "{got:?}");
    for ((gb, ge), (eb, ee)) in got.iter().zip(&expected) {
        assert_eq!(gb, eb);
        assert!((ge - ee).abs() < 1e-4 * ee, "{ge} vs {ee}");
    }
    // Bins by hand: 2 m / 343.2 m/s = 5.83 ms -> bin 5; 4 m -> 11; 10 m -> 29; 12 m -> 34.
    assert_eq!(&got.iter().map(|g| g.0).collect::<Vec<_>>()[..4], &[5, 11, 29, 34]);
    assert_eq!(record.rays_escaped, 0);
}

/// The energy histogram of a purely specular box room by the exact image-source method
/// (Allen and Berkley 1979): every image of the source in the lattice of mirrored boxes up
/// to `max_time_s`, each adding (1 - a)^n / (4 pi d^2) exp(-m d) after its n reflections.
fn box_image_source_histogram(
    size: [f64; 3],
    (source, receiver): ([f64; 3], [f64; 3]),
    reflection: f64,
    air_per_m: [f64; 8],
    speed_m_s: f64,
    bin_s: f64,
    max_time_s: f64,
) -> Vec<[f64; 8]> {
    let max_path = speed_m_s * max_time_s;
    let mut histogram = vec![[0.0; 8]; (max_time_s / bin_s).ceil() as usize];
    // Images along one axis: 2 n L + (1 - 2 u) x_s after |2 n - u| reflections.
    let axis = |k: usize| -> Vec<(f64, i32)> {
        let reach = (max_path / (2.0 * size[k])).ceil() as i32 + 1;
        let mut out = Vec::new();
        for n in -reach..=reach {
            for u in 0..2 {
                let at = 2.0 * f64::from(n) * size[k] + (1.0 - 2.0 * f64::from(u)) * source[k];
                out.push((at - receiver[k], (2 * n - u).abs()));
            }
        }
        out
    };
    let (xs, ys, zs) = (axis(0), axis(1), axis(2));
    for &(dx, nx) in &xs {
        for &(dy, ny) in &ys {
            let dxy2 = dx * dx + dy * dy;
            if dxy2 > max_path * max_path {
                continue;
            }
            for &(dz, nz) in &zs {
                let d = (dxy2 + dz * dz).sqrt();
                let bin = (d / speed_m_s / bin_s) as usize;
                if bin >= histogram.len() {
                    continue;
                }
                let e = reflection.powi(nx + ny + nz) / (4.0 * std::f64::consts::PI * d * d);
                for b in 0..8 {
                    histogram[bin][b] += e * (-air_per_m[b] * d).exp();
                }
            }
        }
    }
    histogram
}

/// A purely specular shoebox (10 x 8 x 3 m, absorption 0.2, scattering 0) decays more
/// slowly than Eyring's formula says; the simulation must follow its exact image-source
/// decay to the end: T30 within 2 % in every band (the decay is no longer cut off).
#[test]
fn specular_shoebox_t30_matches_the_exact_image_source_decay_in_every_band() {
    use propsim::acoustic::metrics::band_metrics;
    let dir = tempfile::tempdir().unwrap();
    let world = box_room(dir.path(), [10.0, 8.0, 3.0], 0.2, 0.0);
    let settings = AcousticSettings { rays: 300_000, ..Default::default() };
    let (s, r) = ([2.0, 3.0, 1.5], [7.0, 5.0, 1.6]);
    let result = simulate(&world, &src(s), &rcv(r, Some(0.3)), &settings, &|_| {}).unwrap();
    let air = settings.air.energy_coefficient_per_m().map(f64::from);
    let c = result.speed_of_sound_m_s;
    let reference = box_image_source_histogram(
        [10.0, 8.0, 3.0],
        (s.map(f64::from), r.map(f64::from)),
        0.8,
        air,
        c,
        1e-3,
        1.6,
    );
    let pair = &result.pairs[0];
    let direct_s = pair.direct_s;
    for b in 0..8 {
        let band = |h: &[[f64; 8]]| h.iter().map(|e| e[b]).collect::<Vec<_>>();
        let exact_metrics = band_metrics(&band(&reference), 1e-3, direct_s);
        let exact = exact_metrics.t30_s.unwrap();
        let simulated = pair.metrics[b].t30_s.unwrap();
        let hz = result.bands_hz[b];
        let (edt, exact_edt) = (pair.metrics[b].edt_s.unwrap(), exact_metrics.edt_s.unwrap());
        eprintln!(
            "{hz} Hz: T30 {simulated:.4} s, exact image sources {exact:.4} s; EDT {edt:.4} s vs {exact_edt:.4} s"
        );
        assert!(
            (edt - exact_edt).abs() / exact_edt < 0.02,
            "{hz} Hz: EDT {edt:.4} s vs exact {exact_edt:.4} s"
        );
        assert!(
            (simulated - exact).abs() / exact < 0.02,
            "{hz} Hz: T30 {simulated:.4} s vs exact image sources {exact:.4} s"
        );
    }
}

/// A box room (material "test_wall") with one analytic sphere (material "ball") in it.
fn box_room_with_sphere(
    dir: &Path,
    size: [f32; 3],
    wall: (f32, f32),
    ball: (f32, f32),
    sphere: ([f32; 3], f32),
) -> World {
    let obj = box_obj(size);
    std::fs::write(dir.join("room.obj"), obj).unwrap();
    let ([cx, cy, cz], r) = sphere;
    let toml = format!(
        "obj = \"room.obj\"\n\
         [materials.test_wall]\nabsorption = {}\nscattering = {}\n\
         [materials.ball]\nabsorption = {}\nscattering = {}\n\
         [[spheres]]\ncenter = [{cx}, {cy}, {cz}]\nradius_m = {r}\nmaterial = \"ball\"\n",
        wall.0, wall.1, ball.0, ball.1
    );
    let path = dir.join("scene.toml");
    std::fs::write(&path, toml).unwrap();
    World::build(scene::load(&path, &LoadOptions::default()).unwrap())
}

/// Spheres are part of the room: an absorbing one between source and receiver casts an
/// acoustic shadow (no direct sound, from rays or image sources), and a source inside one
/// is an error.
#[test]
fn a_sphere_blocks_the_direct_sound() {
    let dir = tempfile::tempdir().unwrap();
    let world = box_room_with_sphere(
        dir.path(),
        [20.0, 20.0, 20.0],
        (1.0, 0.0),
        (1.0, 0.0),
        ([10.0, 10.0, 10.0], 1.0),
    );
    let (s, r) = ([6.0, 10.0, 10.0], [14.0, 10.0, 10.0]);
    for use_image_sources in [true, false] {
        let settings = AcousticSettings {
            rays: 200_000,
            use_image_sources,
            air_absorption: false,
            max_time_s: Some(0.2),
            ..Default::default()
        };
        let result = simulate(&world, &src(s), &rcv(r, Some(0.3)), &settings, &|_| {}).unwrap();
        let total: f64 = result.pairs[0].histogram.iter().map(|h| h[3]).sum();
        let free_field = 1.0 / (4.0 * std::f64::consts::PI * 64.0);
        assert!(total < 1e-3 * free_field, "image sources {use_image_sources}: {total} behind the sphere");
    }
    let inside =
        simulate(&world, &src([10.2, 10.0, 10.0]), &rcv(r, None), &AcousticSettings::default(), &|_| {});
    assert!(inside.unwrap_err().contains("inside the sphere"));
}

/// A lossless sphere in a closed lossless room: no energy is lost, and in the diffuse steady
/// state the fluence per unit time is E c / V with V the air around the sphere.
#[test]
fn a_lossless_sphere_in_a_lossless_room_reflects_and_takes_up_air() {
    let dir = tempfile::tempdir().unwrap();
    let radius = 2.5f64;
    let world = box_room_with_sphere(
        dir.path(),
        [10.0, 8.0, 6.0],
        (0.0, 0.5),
        (0.0, 0.0),
        ([5.0, 4.0, 3.0], radius as f32),
    );
    let settings = AcousticSettings {
        rays: 20_000,
        use_image_sources: false,
        air_absorption: false,
        max_time_s: Some(1.0),
        ..Default::default()
    };
    let r = simulate(&world, &src([1.0, 1.0, 1.0]), &rcv([8.5, 6.5, 4.5], Some(0.5)), &settings, &|_| {})
        .unwrap();
    assert!(r.escaped_energy_fraction < 1e-3, "leak {}", r.escaped_energy_fraction);
    let air = 480.0 - 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3);
    assert!((r.volume_m3 - air).abs() < 1e-6 * air, "{} m^3 of air", r.volume_m3);
    let h = &r.pairs[0].histogram;
    let late: f64 = h[200..1000].iter().map(|b| b[3]).sum::<f64>() / 0.8;
    let expected = r.speed_of_sound_m_s / air;
    let ignoring_the_sphere = r.speed_of_sound_m_s / 480.0;
    assert!(
        (late - expected).abs() / expected < 0.03,
        "{late} vs {expected} (without the sphere {ignoring_the_sphere})"
    );
}

/// Decays are simulated to their end: in the built-in showcase every band's Schroeder curve
/// falls at least 60 dB below its start (the histogram used to stop at 1.2 x Eyring, about
/// 36 dB down).
#[test]
fn the_showcase_decays_reach_60_db_in_every_band() {
    use propsim::acoustic::metrics::schroeder_db;
    let world = World::build(scene::load(Path::new("builtin:showcase"), &LoadOptions::default()).unwrap());
    let (sources, receivers) = propsim::acoustic::scene_points(&world);
    assert_eq!((sources.len(), receivers.len()), (1, 2));
    let settings = AcousticSettings { rays: 30_000, ..Default::default() };
    let r = simulate(&world, &sources, &receivers, &settings, &|_| {}).unwrap();
    for pair in &r.pairs {
        for b in 0..8 {
            let band: Vec<f64> = pair.histogram.iter().map(|h| h[b]).collect();
            // The Schroeder level 50 ms before the last non-empty bin: a decay cut off early
            // still holds tens of dB of its energy there.
            let last = band.iter().rposition(|&e| e > 0.0).unwrap();
            let level = schroeder_db(&band)[last.saturating_sub(50)];
            assert!(
                level <= -60.0,
                "{} {} Hz: the decay ends {level:.1} dB down",
                pair.receiver,
                r.bands_hz[b]
            );
        }
    }
}
