//! What a render looks like: the PNG's exposure and tone map (EXR untouched), the indirect
//! clamp, and the automatic camera inside a closed room.

mod common;

use std::path::Path;

use glam::Vec3;
use propsim::render::film::luminance;
use propsim::render::{Film, RenderScene, RenderSettings, render, scene_camera};
use propsim::scene::{self, LoadOptions, World};

fn propsim_in(dir: &Path, args: &[&str]) -> (bool, String, String) {
    common::propsim_in(Some(dir), args)
}

/// A scene whose camera sees only the background, of radiance `grey` in every channel.
fn constant_scene(dir: &Path, grey: f32) -> String {
    std::fs::write(dir.join("t.obj"), "v -10 0 0\nv -10 1 0\nv -10 0 1\nusemtl concrete\nf 1 2 3\n").unwrap();
    let name = format!("grey{grey}.toml");
    std::fs::write(
        dir.join(&name),
        format!(
            "obj = \"t.obj\"\n[camera]\neye = [0.0, 0.0, 0.0]\ntarget = [1.0, 0.0, 0.0]\n\
             [render]\nbackground = [{grey}, {grey}, {grey}]\n"
        ),
    )
    .unwrap();
    name
}

/// The PNG byte of every pixel of `scene` rendered with `extra` flags (all pixels equal).
fn png_value(dir: &Path, scene: &str, extra: &[&str]) -> u8 {
    let mut args = vec!["render", scene, "-o", "c.png", "--width", "4", "--height", "4", "--spp", "1"];
    args.extend(extra);
    let (ok, _, err) = propsim_in(dir, &args);
    assert!(ok, "{args:?}: {err}");
    let img = image::open(dir.join("c.png")).unwrap().to_rgb8();
    let v = img.get_pixel(0, 0).0[0];
    assert!(img.pixels().all(|p| p.0 == [v, v, v]), "{args:?}: not constant");
    v
}

fn srgb8(x: f32) -> u8 {
    let x = x.clamp(0.0, 1.0);
    let s = if x <= 0.003_130_8 { 12.92 * x } else { 1.055 * x.powf(1.0 / 2.4) - 0.055 };
    (s * 255.0 + 0.5) as u8
}

fn aces(x: f32) -> f32 {
    (x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14)
}

#[test]
fn png_of_a_constant_radiance_maps_as_the_formulas_say() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let s = constant_scene(d, 0.3);
    // ACES filmic is the default.
    assert_eq!(png_value(d, &s, &[]), srgb8(aces(0.3)));
    assert_eq!(png_value(d, &s, &["--tone-map", "aces"]), srgb8(aces(0.3)));
    assert_eq!(png_value(d, &s, &["--tone-map", "reinhard"]), srgb8(0.3 / 1.3));
    assert_eq!(png_value(d, &s, &["--tone-map", "none"]), srgb8(0.3));
    // +1 EV doubles what the tone map receives; -1 EV halves it.
    assert_eq!(png_value(d, &s, &["--exposure", "1"]), srgb8(aces(0.6)));
    assert_eq!(png_value(d, &s, &["--exposure", "-1", "--tone-map", "none"]), srgb8(0.15));
    let doubled = constant_scene(d, 0.6);
    assert_eq!(
        png_value(d, &s, &["--exposure", "1", "--tone-map", "none"]),
        png_value(d, &doubled, &["--tone-map", "none"])
    );
    // The scene's [render] keys set them; the flags override.
    let keyed = d.join("keyed.toml");
    let text = std::fs::read_to_string(d.join(&s)).unwrap();
    std::fs::write(&keyed, format!("{text}exposure_ev = 1.0\ntone_map = \"reinhard\"\n")).unwrap();
    assert_eq!(png_value(d, "keyed.toml", &[]), srgb8(0.6 / 1.6));
    assert_eq!(png_value(d, "keyed.toml", &["--exposure", "0", "--tone-map", "none"]), srgb8(0.3));
}

#[test]
fn exr_stays_linear_whatever_the_exposure_and_tone_map() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let common = ["builtin:cornell_box_classic", "--width", "24", "--height", "24", "--spp", "4"];
    let mut outputs = Vec::new();
    for (i, extra) in
        [&[][..], &["--exposure", "3", "--tone-map", "reinhard"][..], &["--tone-map", "none"][..]]
            .iter()
            .enumerate()
    {
        let name = format!("i{i}.exr");
        let mut args = vec!["render", "-o", &name];
        args.extend(common);
        args.extend(*extra);
        let (ok, _, err) = propsim_in(d, &args);
        assert!(ok, "{args:?}: {err}");
        outputs.push(std::fs::read(d.join(&name)).unwrap());
    }
    assert!(outputs.iter().all(|o| *o == outputs[0]), "EXR bytes differ");
}

#[test]
fn bad_exposures_tone_maps_and_clamps_fail_with_one_line() {
    for (flag, value, needle) in [
        ("--exposure", "nan", "exposure"),
        ("--exposure", "99", "exposure"),
        ("--tone-map", "filmic", "--tone-map"),
        ("--clamp-indirect", "-1", "clamp"),
        ("--clamp-indirect", "inf", "clamp"),
    ] {
        let dir = tempfile::tempdir().unwrap();
        let args = ["render", "--width", "8", "--height", "8", flag, value];
        let (ok, _, err) = propsim_in(dir.path(), &args);
        common::check_one_line_error(&args, ok, &err, &[needle]);
        assert!(!dir.path().join("out").exists(), "{args:?}: nothing written on error");
    }
}

fn cornell() -> World {
    World::build(scene::load(Path::new("builtin:cornell_box_classic"), &LoadOptions::default()).unwrap())
}

fn go(world: &World, s: &RenderSettings) -> Film {
    let scene = RenderScene::new(world);
    let cam = scene_camera(world, 1.0).unwrap();
    render(&scene, &cam, s, &|_| {}).unwrap().film
}

#[test]
fn the_indirect_clamp_bounds_each_sample_and_zero_leaves_direct_light() {
    let world = cornell();
    let base = RenderSettings { width: 24, height: 24, spp: 8, max_depth: 8, seed: 3, ..Default::default() };
    let full = go(&world, &base);
    let direct = go(&world, &RenderSettings { max_depth: 1, ..base.clone() });
    let zero = go(&world, &RenderSettings { clamp_indirect: Some(0.0), ..base.clone() });
    let bits = |f: &Film| f.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
    // A clamp of 0 removes every indirect contribution and nothing else.
    assert_eq!(bits(&zero), bits(&direct));
    let max = 0.05;
    let clamped = go(&world, &RenderSettings { clamp_indirect: Some(max), ..base.clone() });
    // A pixel is the mean of its samples, each with at most `max` of indirect luminance.
    for (c, d) in clamped.pixels.iter().zip(&direct.pixels) {
        assert!(luminance(*c) <= luminance(*d) + max + 1e-5, "{c} vs direct {d}");
    }
    let y = |f: &Film| luminance(f.mean());
    assert!(
        y(&direct) < y(&clamped) && y(&clamped) < y(&full),
        "{} {} {}",
        y(&direct),
        y(&clamped),
        y(&full)
    );
    // The same image on any number of threads.
    let pool = |n: usize| rayon::ThreadPoolBuilder::new().num_threads(n).build().unwrap();
    let on = |n: usize| {
        pool(n).install(|| go(&world, &RenderSettings { clamp_indirect: Some(max), ..base.clone() }))
    };
    assert_eq!(bits(&on(1)), bits(&clamped));
    assert_eq!(bits(&on(3)), bits(&clamped));
    // A clamp above every sample changes nothing but the order of the sums.
    let loose = go(&world, &RenderSettings { clamp_indirect: Some(1e30), ..base.clone() });
    assert!((y(&loose) - y(&full)).abs() < 1e-4 * y(&full));
}

/// `common::BOX_OBJ` in `dir`, without the faces whose line is in `drop`, as a world.
fn box_world(dir: &Path, drop: &[&str]) -> World {
    let text: String =
        common::BOX_OBJ.lines().filter(|l| !drop.contains(l)).map(|l| format!("{l}\n")).collect();
    let path = dir.join("box.obj");
    std::fs::write(&path, text).unwrap();
    World::build(scene::load(&path, &LoadOptions::default()).unwrap())
}

#[test]
fn the_automatic_camera_of_a_closed_room_stands_inside_at_eye_height() {
    let dir = tempfile::tempdir().unwrap();
    let world = box_world(dir.path(), &[]);
    let v = propsim::render::auto_camera(&world, Vec3::Z, None);
    assert!(v.inside, "{v:?}");
    assert_eq!(world.is_inside(v.eye), Some(true));
    // 2.5 m room: eye at 60 % of the height (1.5 m) rather than 1.6 m; a wide lens; looking
    // across the floor plan's diagonal, a little down.
    assert!((v.eye.z - 1.5).abs() < 1e-5, "{v:?}");
    assert_eq!(v.fov_deg, propsim::render::AUTO_INTERIOR_FOV_DEG);
    let look = v.target - v.eye;
    assert!(look.x > 2.0 && look.y > 1.5 && look.z < 0.0, "{v:?}");
    assert_eq!(propsim::render::auto_camera(&world, Vec3::Z, Some(50.0)).fov_deg, 50.0);
    // From the command line: every pixel of a head-lit raycast sees a wall from inside.
    let (ok, _, err) = propsim_in(
        dir.path(),
        &["render", "box.obj", "-o", "in.png", "--integrator", "raycast", "--width", "32", "--height", "24"],
    );
    assert!(ok, "{err}");
    let img = image::open(dir.path().join("in.png")).unwrap().to_rgb8();
    assert!(img.pixels().all(|p| p.0.iter().any(|&c| c > 0)), "a black (outside) pixel");
    // An open box keeps the outside view.
    let open = tempfile::tempdir().unwrap();
    let world = box_world(open.path(), &["f 1 2 6 5"]);
    let v = propsim::render::auto_camera(&world, Vec3::Z, None);
    assert!(!v.inside);
    let (lo, hi) = world.scene.mesh.bounds().unwrap();
    assert!(v.eye.cmplt(lo).any() || v.eye.cmpgt(hi).any(), "{v:?}");
}
