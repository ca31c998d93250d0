//! Source directivity against closed forms (docs/acoustics.md, Directivity): the same power
//! gives the same late energy whatever the pattern, and the direct sound follows the
//! pattern's normalised weight, zero in its nulls.

mod common;

use common::box_room;
use propsim::acoustic::directivity::{Directivity, FirstOrder};
use propsim::acoustic::{AcousticResult, AcousticSettings, ReceiverSpec, SourceSpec, simulate};
use propsim::scene::{self, LoadOptions, World};

const SOURCE: [f32; 3] = [3.0, 4.0, 1.5];

fn run(
    world: &World,
    directivity: Directivity,
    receivers: &[[f32; 3]],
    settings: &AcousticSettings,
) -> AcousticResult {
    let sources = [SourceSpec { name: "S".into(), position: SOURCE, power_w: 1.0, directivity }];
    let receivers: Vec<ReceiverSpec> = receivers
        .iter()
        .enumerate()
        .map(|(i, &p)| ReceiverSpec {
            name: format!("R{i}"),
            position: p,
            radius_m: Some(0.3),
            listener: Default::default(),
            directivity: Default::default(),
        })
        .collect();
    simulate(world, &sources, &receivers, settings, &|_| {}).unwrap()
}

#[test]
fn a_cardioid_of_the_same_power_gives_the_omni_late_energy() {
    // A diffuse room (10 x 8 x 3 m, absorption 0.2, scattering 0.7): past the first
    // 100 ms (about 15 reflections, the mixing time sqrt(V) ms = 15 ms several times over)
    // the sound field holds the source's power whatever its pattern (the pattern's energy
    // over the sphere is the omni's), so the late energy is the same within the noise. The
    // cardioid faces away from the receiver (its direct sound is nearly nil) to make the
    // test hard.
    let dir = tempfile::tempdir().unwrap();
    let world = box_room(dir.path(), [10.0, 8.0, 3.0], 0.2, 0.7);
    let settings = AcousticSettings { rays: 100_000, air_absorption: false, ..Default::default() };
    let receiver = [[7.0, 5.0, 1.2]];
    let omni = run(&world, Directivity::OMNI, &receiver, &settings);
    let away = Directivity::uniform(FirstOrder::CARDIOID, glam::Vec3::new(-1.0, -0.25, 0.1)).unwrap();
    let cardioid = run(&world, away, &receiver, &settings);
    let late = |r: &AcousticResult, b: usize| r.pairs[0].histogram[100..].iter().map(|h| h[b]).sum::<f64>();
    for b in 0..8 {
        let ratio = late(&cardioid, b) / late(&omni, b);
        eprintln!("band {b}: late energy cardioid / omni = {ratio:.4}");
        assert!((ratio - 1.0).abs() < 0.05, "band {b}: late energy cardioid / omni = {ratio}");
    }
    // The direct sound is not the same: the receiver is at 166 degrees off the axis.
    let direct_bin = |r: &AcousticResult| {
        let p = &r.pairs[0];
        p.histogram[(p.direct_s / 1e-3) as usize][4]
    };
    assert!(direct_bin(&cardioid) < 0.1 * direct_bin(&omni));
}

#[test]
fn the_direct_sound_follows_the_pattern_and_vanishes_in_its_nulls() {
    // The direct sound of the image-source method, 1 / (4 pi d^2) times the normalised
    // weight w = g^2 / (a^2 + (1 - a)^2 / 3) (docs/acoustics.md, Directivity), from a source
    // facing +x: a receiver on the axis, one at 60 degrees and one at 90 degrees (the
    // figure-of-eight's null), and behind (the cardioid's null).
    let dir = tempfile::tempdir().unwrap();
    let world = box_room(dir.path(), [10.0, 8.0, 3.0], 0.2, 0.0);
    let settings =
        AcousticSettings { rays: 1000, air_absorption: false, max_time_s: Some(0.05), ..Default::default() };
    let d = 2.0f32;
    let at = |deg: f32| {
        let t = deg.to_radians();
        [SOURCE[0] + d * t.cos(), SOURCE[1] + d * t.sin(), SOURCE[2]]
    };
    let receivers = [at(0.0), at(60.0), at(90.0), at(180.0)];
    let free = 1.0 / (4.0 * std::f64::consts::PI * f64::from(d * d));
    for (pattern, want) in [
        // g = a + (1 - a) cos theta at 0, 60, 90, 180 degrees, squared, over the mean square.
        (FirstOrder::CARDIOID, [1.0, 0.5625, 0.25, 0.0].map(|g2| g2 / (1.0 / 3.0))),
        (FirstOrder::FIGURE_OF_EIGHT, [1.0, 0.25, 0.0, 1.0].map(|g2| g2 * 3.0)),
        (FirstOrder::HYPERCARDIOID, [1.0, 0.390625, 0.0625, 0.25].map(|g2| g2 * 4.0)),
    ] {
        let directivity = Directivity::uniform(pattern, glam::Vec3::X).unwrap();
        let r = run(&world, directivity, &receivers, &settings);
        for (i, p) in r.pairs.iter().enumerate() {
            let got = p.histogram[(p.direct_s / 1e-3) as usize][4];
            let expect = want[i] * free;
            assert!(
                (got - expect).abs() <= 1e-4 * free,
                "a = {}, receiver {i}: direct {got:e} vs {expect:e}",
                pattern.a
            );
        }
    }
}

#[test]
fn unknown_patterns_are_one_line_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let obj = dir.path().join("room.obj");
    std::fs::write(
        &obj,
        "v 0 0 0\nv 4 0 0\nv 4 4 0\nv 0 4 0\nv 0 0 3\nv 4 0 3\nv 4 4 3\nv 0 4 3\n\
         usemtl concrete\nf 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n",
    )
    .unwrap();
    let scene = dir.path().join("room.toml");
    std::fs::write(
        &scene,
        "obj = \"room.obj\"\n[[acoustic.sources]]\nname = \"S\"\nposition = [1, 1, 1]\ndirectivity = \"shotgun\"\n",
    )
    .unwrap();
    let e = scene::load(&scene, &LoadOptions::default()).unwrap_err().to_string();
    assert!(!e.contains('\n'), "{e}");
    assert!(e.contains("room.toml") && e.contains("shotgun"), "{e}");
    for name in propsim::acoustic::directivity::PATTERN_NAMES {
        assert!(e.contains(name), "{e} lacks {name}");
    }
}

/// The source of [`run`] (omni) heard by one receiver at `position` with `directivity`.
fn run_receiver(
    world: &World,
    position: [f32; 3],
    directivity: Directivity,
    settings: &AcousticSettings,
) -> AcousticResult {
    let sources =
        [SourceSpec { name: "S".into(), position: SOURCE, power_w: 1.0, directivity: Directivity::OMNI }];
    let receivers = [ReceiverSpec {
        name: "R".into(),
        position,
        radius_m: Some(0.3),
        listener: Default::default(),
        directivity,
    }];
    simulate(world, &sources, &receivers, settings, &|_| {}).unwrap()
}

#[test]
fn a_directional_receiver_hears_the_direct_sound_by_its_pattern_and_a_third_of_the_diffuse_field() {
    // A cardioid microphone's energy sensitivity is g^2 = ((1 + cos theta) / 2)^2, 1 on its
    // axis: the direct sound from 0, 90 and 180 degrees is 1, 1/4 and 0 times the omni's, and
    // in a diffuse field, where sound comes from every direction alike, it hears the mean of
    // g^2 over the sphere, a^2 + (1 - a)^2 / 3 = 1/3 of the omni's late energy.
    let dir = tempfile::tempdir().unwrap();
    let world = box_room(dir.path(), [10.0, 8.0, 3.0], 0.2, 0.7);
    let settings = AcousticSettings { rays: 100_000, air_absorption: false, ..Default::default() };
    let position = [7.0, 5.0, 1.2];
    let omni = run_receiver(&world, position, Directivity::OMNI, &settings);
    let to_source = glam::Vec3::from(SOURCE) - glam::Vec3::from(position);
    let facing = |axis: glam::Vec3| Directivity::uniform(FirstOrder::CARDIOID, axis).unwrap();
    let side = to_source.cross(glam::Vec3::Z);
    let direct = |r: &AcousticResult| {
        let p = &r.pairs[0];
        p.image_sources.iter().find(|a| a.order == 0).expect("the direct sound").energy[4]
    };
    for (axis, want) in [(to_source, 1.0), (side, 0.25), (-to_source, 0.0)] {
        let r = run_receiver(&world, position, facing(axis), &settings);
        let ratio = direct(&r) / direct(&omni);
        assert!((ratio - want).abs() < 1e-5, "axis {axis}: direct ratio {ratio} vs {want}");
        if want == 0.25 {
            let late =
                |r: &AcousticResult, b: usize| r.pairs[0].histogram[100..].iter().map(|h| h[b]).sum::<f64>();
            for b in 0..8 {
                let ratio = late(&r, b) / late(&omni, b);
                eprintln!("band {b}: late energy cardioid receiver / omni = {ratio:.4}");
                assert!((ratio - 1.0 / 3.0).abs() < 0.03, "band {b}: {ratio} vs 1/3");
            }
        }
    }
}

#[test]
fn an_unknown_receiver_pattern_is_a_one_line_error() {
    common::assert_clean_error(
        &[
            "acoustic",
            "builtin:shoebox",
            "--rays",
            "100",
            "--receiver-directivity",
            "shotgun",
            "--out",
            "/nonexistent/x",
        ],
        &["--receiver-directivity shotgun", "cardioid"],
    );
}

/// A committed test file of `rooms/tools/gen_sofa.py`.
fn data(name: &str) -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data").join(name)
}

#[test]
fn a_measured_balloon_gives_its_patterns_per_band_and_the_omni_late_energy() {
    // directivity_cardioid.sofa (FreeFieldDirectivityTF, a 10-degree grid, third octaves) holds
    // a(f) + (1 - a(f)) cos theta with a = 1 in the 63 and 125 Hz bands, 1/2 (cardioid) in
    // 250 Hz-1 kHz, 1/4 (hypercardioid) in 2-8 kHz, at an arbitrary level. Its direct sound
    // must follow w = g^2 / (a^2 + (1 - a)^2 / 3) like the analytic patterns, to the grid's
    // interpolation (3 % of the on-axis value), and its late energy must be the omni's.
    let dir = tempfile::tempdir().unwrap();
    let world = box_room(dir.path(), [10.0, 8.0, 3.0], 0.2, 0.7);
    let balloon = propsim::acoustic::balloon::Balloon::load_sofa(&data("directivity_cardioid.sofa")).unwrap();
    let measured = Directivity::measured(std::sync::Arc::new(balloon), glam::Vec3::X, None).unwrap();
    let d = 2.0f32;
    let at = |deg: f32| {
        let t = deg.to_radians();
        [SOURCE[0] + d * t.cos(), SOURCE[1] + d * t.sin(), SOURCE[2]]
    };
    let angles = [0.0f32, 60.0, 90.0, 135.0, 180.0];
    let receivers: Vec<[f32; 3]> = angles.iter().map(|&a| at(a)).collect();
    let settings =
        AcousticSettings { rays: 1000, air_absorption: false, max_time_s: Some(0.05), ..Default::default() };
    let r = run(&world, measured.clone(), &receivers, &settings);
    let free = 1.0 / (4.0 * std::f64::consts::PI * f64::from(d * d));
    let mut worst = 0.0f64;
    for (i, p) in r.pairs.iter().enumerate() {
        let direct = p.image_sources.iter().find(|a| a.order == 0).expect("the direct sound");
        for b in 0..8 {
            let a = if b < 2 {
                1.0
            } else if b < 5 {
                0.5
            } else {
                0.25
            };
            let pattern = FirstOrder { a };
            let c = angles[i].to_radians().cos();
            let want = f64::from(pattern.energy_weight(c)) * free;
            let on_axis = f64::from(pattern.directivity_factor()) * free;
            worst = worst.max((direct.energy[b] - want).abs() / on_axis);
            assert!(
                (direct.energy[b] - want).abs() <= 0.03 * on_axis,
                "band {b}, {} degrees: direct {:e} vs {want:e}",
                angles[i],
                direct.energy[b]
            );
        }
    }
    eprintln!("largest direct-sound error: {:.4} of the on-axis value", worst);
    // The same power as the omni: the same late energy in every band.
    let settings = AcousticSettings { rays: 100_000, air_absorption: false, ..Default::default() };
    let receiver = [[7.0, 5.0, 1.2]];
    let omni = run(&world, Directivity::OMNI, &receiver, &settings);
    let away = measured.turned(glam::Vec3::new(-1.0, -0.25, 0.1)).unwrap();
    let turned = run(&world, away, &receiver, &settings);
    let late = |r: &AcousticResult, b: usize| r.pairs[0].histogram[100..].iter().map(|h| h[b]).sum::<f64>();
    for b in 0..8 {
        let ratio = late(&turned, b) / late(&omni, b);
        eprintln!("band {b}: late energy balloon / omni = {ratio:.4}");
        assert!((ratio - 1.0).abs() < 0.05, "band {b}: late energy balloon / omni = {ratio}");
    }
}

#[test]
fn impulse_response_balloons_and_their_frame_follow_orientation_and_up() {
    // directivity_fir.sofa (GeneralFIR, cartesian receivers) is a cardioid in every band. Its
    // front follows `orientation`: facing +y, the receiver on +y gets Q = 3 times the free
    // field and the one on -y nothing. A balloon that is not symmetric about its axis turns
    // with `up`: checked on the grid through the frame, left (+y) against top (+z).
    let b = propsim::acoustic::balloon::Balloon::load_sofa(&data("directivity_fir.sofa")).unwrap();
    let b = std::sync::Arc::new(b);
    let d = Directivity::measured(b.clone(), glam::Vec3::Y, Some(glam::Vec3::Z)).unwrap();
    for band in 0..8 {
        let front = d.energy_weights(glam::Vec3::Y)[band];
        let back = d.energy_weights(-glam::Vec3::Y)[band];
        let side = d.energy_weights(glam::Vec3::X)[band];
        assert!((front - 3.0).abs() < 0.06, "band {band}: front {front}");
        assert!(back < 0.01, "band {band}: back {back}");
        assert!((side - 0.75).abs() < 0.03, "band {band}: side {side}");
    }
    // Facing +y with its top +z, the balloon's left (+y in its frame) is world -x.
    assert_eq!(Vec::from(d.up), vec![0.0, 0.0, 1.0]);
    let d2 = Directivity::measured(b, glam::Vec3::Y, Some(glam::Vec3::new(0.0, 0.3, 1.0))).unwrap();
    assert!((glam::Vec3::from(d2.up) - glam::Vec3::Z).length() < 1e-6, "up projected normal to the axis");
}

#[test]
fn bad_balloons_are_one_line_errors_naming_the_file() {
    let dir = tempfile::tempdir().unwrap();
    // An HRIR set is not a directivity: two receivers (the ears) are not a balloon's
    // directions, and its directions are in SourcePosition.
    let e = propsim::acoustic::balloon::Balloon::load_sofa(&data("hrir_delays.sofa")).unwrap_err();
    assert!(e.contains("hrir_delays.sofa") && !e.contains('\n'), "{e}");
    let junk = dir.path().join("junk.sofa");
    std::fs::write(&junk, b"\x89HDF\r\n\x1a\n not really").unwrap();
    let junk = junk.to_str().unwrap();
    for (file, needles) in [(junk, &["junk.sofa"][..]), ("/nonexistent/b.sofa", &["b.sofa", "not found"][..])]
    {
        common::assert_clean_error(
            &[
                "acoustic",
                "builtin:shoebox",
                "--rays",
                "100",
                "--directivity",
                file,
                "--out",
                "/nonexistent/x",
            ],
            needles,
        );
    }
}

#[test]
fn scene_files_and_the_command_line_take_balloons() {
    // `directivity_sofa` on a scene-file source, relative to the scene file; with
    // `directivity` too it is a one-line error naming the file. `--directivity FILE.sofa`
    // gives every source the balloon.
    let dir = tempfile::tempdir().unwrap();
    std::fs::copy(data("directivity_fir.sofa"), dir.path().join("speaker.sofa")).unwrap();
    std::fs::write(
        dir.path().join("room.obj"),
        "v 0 0 0\nv 4 0 0\nv 4 4 0\nv 0 4 0\nv 0 0 3\nv 4 0 3\nv 4 4 3\nv 0 4 3\n\
         usemtl concrete\nf 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n",
    )
    .unwrap();
    let scene_text = |extra: &str| {
        format!(
            "obj = \"room.obj\"\n[[acoustic.sources]]\nname = \"S\"\nposition = [1, 1, 1.5]\n\
             directivity_sofa = \"speaker.sofa\"\norientation = [0, 1, 0]\n{extra}\
             [[acoustic.receivers]]\nname = \"R\"\nposition = [1, 3, 1.5]\n"
        )
    };
    let scene = dir.path().join("room.toml");
    std::fs::write(&scene, scene_text("")).unwrap();
    let world = World::build(scene::load(&scene, &LoadOptions::default()).unwrap());
    let (sources, _) = propsim::acoustic::scene_points(&world);
    let d = &sources[0].directivity;
    assert!(d.balloon.is_some());
    assert!((d.energy_weights(glam::Vec3::Y)[4] - 3.0).abs() < 0.06);
    std::fs::write(&scene, scene_text("directivity = \"cardioid\"\n")).unwrap();
    common::assert_clean_error(
        &["acoustic", scene.to_str().unwrap(), "--rays", "100", "--out", "/nonexistent/x"],
        &["room.toml", "directivity_sofa"],
    );
    let out = dir.path().join("out");
    let (ok, _, err) = common::propsim(&[
        "acoustic",
        "builtin:shoebox",
        "--rays",
        "2000",
        "--directivity",
        data("directivity_cardioid.sofa").to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(ok, "{err}");
}
