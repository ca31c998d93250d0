//! Instancing (issue 24): `[[instances]]` in scene files, the two-level BVH seen by every
//! view, the instanced room checks, and bad input. The reference is always the same scene
//! flattened into one mesh by hand (closed forms for volumes and areas).

mod common;

use std::path::Path;

use glam::{Vec2, Vec3};
use propsim::core::rng::{stream, uniform};
use propsim::core::sampling::uniform_sphere;
use propsim::core::{PrimitiveKind, Ray};
use propsim::scene::{LoadOptions, World, load};

use common::{BOX_OBJ, assert_clean_error, propsim};

/// A closed unit-ish seat block [0,0.5]x[0,0.5]x[0,0.5], object "seat", normals out.
const SEAT: &str = "\
o seat
v 0 0 0
v 0.5 0 0
v 0.5 0.5 0
v 0 0.5 0
v 0 0 0.5
v 0.5 0 0.5
v 0.5 0.5 0.5
v 0 0.5 0.5
usemtl wood
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
";

/// The room of `BOX_OBJ` (4 x 3 x 2.5 m, normals out of the room, as propsim's rooms) with
/// the seat after it; the seat's vertices are numbered after the room's 8.
fn room_and_seat() -> String {
    let seat = SEAT
        .replace("f 1 4 3 2", "f 9 12 11 10")
        .replace("f 5 6 7 8", "f 13 14 15 16")
        .replace("f 1 2 6 5", "f 9 10 14 13")
        .replace("f 2 3 7 6", "f 10 11 15 14")
        .replace("f 3 4 8 7", "f 11 12 16 15")
        .replace("f 4 1 5 8", "f 12 9 13 16");
    format!("{BOX_OBJ}{seat}")
}

/// The transforms of the test scene, as TOML and as (scale, Euler degrees, translation).
const PLACEMENTS: [([f32; 3], [f32; 3], [f32; 3]); 4] = [
    ([1.0, 1.0, 1.0], [0.0, 0.0, 0.0], [0.5, 0.5, 0.0]),
    ([2.0, 2.0, 2.0], [0.0, 0.0, 30.0], [2.0, 1.0, 0.0]),
    ([1.0, 2.0, 0.5], [10.0, 20.0, 30.0], [3.0, 1.2, 1.0]),
    ([-1.0, 1.0, 1.0], [0.0, 0.0, 0.0], [1.5, 2.0, 0.5]),
];

fn scene_toml(extra: &str) -> String {
    let mut s = String::from("obj = \"room.obj\"\n[materials.wood]\nabsorption = 0.2\nscattering = 0.3\n");
    for (k, (scale, euler, t)) in PLACEMENTS.iter().enumerate() {
        s += &format!(
            "[[instances]]\nname = \"seat{k}\"\nmesh = \"seat\"\nscale = {scale:?}\nrotate_euler_deg = {euler:?}\ntranslate = {t:?}\n"
        );
    }
    s + extra
}

/// The same seats written out in world coordinates by hand (rotation z y x, then the scale
/// first): the flattened reference, with mirrored copies rewound.
fn flattened_obj() -> String {
    let mut out = String::from(BOX_OBJ);
    let corners: Vec<Vec3> = SEAT
        .lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let v: Vec<f32> = l.split_whitespace().map(|x| x.parse().unwrap()).collect();
            Vec3::new(v[0], v[1], v[2])
        })
        .collect();
    let faces: Vec<Vec<usize>> = SEAT
        .lines()
        .filter_map(|l| l.strip_prefix("f "))
        .map(|l| l.split_whitespace().map(|x| x.parse().unwrap()).collect())
        .collect();
    let mut base = 8;
    out += "o seats\nusemtl wood\n";
    for (scale, [ex, ey, ez], t) in PLACEMENTS {
        let rot = glam::Quat::from_rotation_z(ez.to_radians())
            * glam::Quat::from_rotation_y(ey.to_radians())
            * glam::Quat::from_rotation_x(ex.to_radians());
        for c in &corners {
            let p = rot * (*c * Vec3::from(scale)) + Vec3::from(t);
            out += &format!("v {} {} {}\n", p.x, p.y, p.z);
        }
        let mirrored = scale[0] * scale[1] * scale[2] < 0.0;
        for f in &faces {
            let mut f: Vec<usize> = f.iter().map(|i| i + base).collect();
            if mirrored {
                f.reverse();
            }
            out += &format!("f {}\n", f.iter().map(|i| i.to_string()).collect::<Vec<_>>().join(" "));
        }
        base += 8;
    }
    out
}

fn write(dir: &Path, name: &str, text: &str) -> String {
    let p = dir.join(name);
    std::fs::write(&p, text).unwrap();
    p.display().to_string()
}

fn world(path: &str) -> World {
    World::build(load(Path::new(path), &LoadOptions::default()).unwrap())
}

#[test]
fn info_reports_instanced_and_unique_triangles_and_the_scaled_volumes() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "room.obj", &room_and_seat());
    let scene = write(dir.path(), "scene.toml", &scene_toml(""));
    let (ok, out, err) = propsim(&["info", &scene, "--json"]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    // 12 room triangles + 4 copies of the 12-triangle seat; unique: 12 + 12.
    assert_eq!(v["triangles"], 12 + 4 * 12);
    assert_eq!(v["unique_triangles"], 24);
    assert_eq!(v["instances"], 4);
    assert_eq!(v["closed"], true);
    assert_eq!(v["components"], 5);
    assert_eq!(v["closed_components"], 5);
    // Air: 30 m^3 minus each seat's 0.125 m^3 times |det| (1, 8, 1, 1).
    let air = v["air_volume_m3"].as_f64().unwrap();
    assert!((air - (30.0 - 0.125 * 11.0)).abs() < 1e-5, "{air}");
    // Areas: a similarity scales by s^2; the stretched copy is mapped face by face.
    let wood = v["surfaces"].as_array().unwrap().iter().find(|s| s["name"] == "wood").unwrap();
    let stretched = 2.0 * (0.5 * 1.0 + 0.5 * 0.25 + 1.0 * 0.25);
    let want = 1.5 * (1.0 + 4.0 + 1.0) + stretched;
    assert!((wood["area_m2"].as_f64().unwrap() - want).abs() < 1e-4, "{wood}");
    // The flattened scene says the same.
    write(dir.path(), "flat.obj", &flattened_obj());
    let flat = write(
        dir.path(),
        "flat.toml",
        "obj = \"flat.obj\"\n[materials.wood]\nabsorption = 0.2\nscattering = 0.3\n",
    );
    let (ok, out, err) = propsim(&["info", &flat, "--json"]);
    assert!(ok, "{err}");
    let f: serde_json::Value = serde_json::from_str(&out).unwrap();
    assert_eq!(f["triangles"], v["triangles"]);
    assert!((f["air_volume_m3"].as_f64().unwrap() - air).abs() < 1e-4);
    let text = propsim(&["info", &scene]).1;
    assert!(text.contains("instances:  4 copies: 60 instanced triangles, 24 unique"), "{text}");
}

#[test]
fn every_query_sees_the_instances_as_the_flattened_mesh() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "room.obj", &room_and_seat());
    write(dir.path(), "flat.obj", &flattened_obj());
    let mats = "[materials.wood]\nabsorption = 0.2\nscattering = 0.3\n";
    let inst = world(&write(dir.path(), "scene.toml", &scene_toml("")));
    let flat = world(&write(dir.path(), "flat.toml", &format!("obj = \"flat.obj\"\n{mats}")));
    assert!(inst.accel.instances.len() == 4 && inst.scene.mesh.triangle_count() == 12);
    let render_inst = propsim::render::RenderScene::new(&inst);
    let render_flat = propsim::render::RenderScene::new(&flat);
    let wood_inst = inst.scene.surfaces.iter().position(|s| s.name == "wood").unwrap() as u32;
    let (mut rays, mut on_seats) = (Vec::new(), 0);
    for k in 0..100_000u64 {
        let mut r = stream(24, 0, k);
        let o = Vec3::new(
            0.05 + 3.9 * uniform(&mut r),
            0.05 + 2.9 * uniform(&mut r),
            0.05 + 2.4 * uniform(&mut r),
        );
        let d = uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
        let ray = Ray::new(o, d);
        rays.push(ray);
        let (a, b) = (inst.accel.closest_hit(&ray).unwrap(), flat.accel.closest_hit(&ray).unwrap());
        assert!((a.t - b.t).abs() < 1e-4, "ray {k}: {} vs {}", a.t, b.t);
        if (a.t - b.t).abs() < 1e-6 * (1.0 + b.t) || a.normal.dot(b.normal) > 0.99 {
            assert!(a.normal.dot(b.normal) > 0.999 || (a.t - b.t).abs() < 1e-5, "ray {k}");
        }
        if a.kind == PrimitiveKind::Instance {
            on_seats += 1;
            assert_eq!(a.surface, wood_inst);
            assert_eq!(a.front_face, b.front_face, "ray {k}");
        }
        // Shadow rays to a point just before the hit are clear in both, past it blocked.
        let short = Ray::segment(o, d, (a.t.min(b.t) - 1e-5).max(0.0));
        assert!(
            !inst.accel.occluded(&short) && !flat.accel.occluded(&short),
            "ray {k}: {a:?} {b:?} {} {}",
            inst.accel.occluded(&short),
            flat.accel.occluded(&short)
        );
        let long = Ray::segment(o, d, a.t.max(b.t) + 1e-4);
        assert!(inst.accel.occluded(&long), "ray {k}");
        // The renderer's query.
        let (ra, rb) = (render_inst.intersect(&ray).unwrap(), render_flat.intersect(&ray).unwrap());
        assert!((ra.t - rb.t).abs() < 1e-4, "render ray {k}");
    }
    assert!(on_seats > 5_000, "{on_seats} rays on seats");
    // The launcher's batch query.
    let mut hits = vec![None; rays.len()];
    inst.accel.closest_hits_into(&rays, &mut hits);
    for (ray, hit) in rays.iter().zip(&hits) {
        assert_eq!(*hit, inst.accel.closest_hit(ray));
    }
    // Inside tests: in a seat is outside the air, between them inside.
    for (p, inside) in [(Vec3::new(0.75, 0.75, 0.25), false), (Vec3::new(3.5, 0.5, 2.0), true)] {
        assert_eq!(inst.is_inside(p), Some(inside), "{p}");
        assert_eq!(flat.is_inside(p), Some(inside), "{p}");
    }
    // The clearance of a point near a seat's face sees the instance.
    let d = inst.surface_distance_m(Vec3::new(0.75, 0.75, 0.6));
    assert!((d - 0.1).abs() < 1e-5, "{d}");
}

#[test]
fn acoustic_and_radio_see_the_instances() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "room.obj", &room_and_seat());
    write(dir.path(), "flat.obj", &flattened_obj());
    let extra = "[acoustic]\nrays = 20000\n[[acoustic.sources]]\nname = \"S\"\nposition = [3.5, 0.5, 1.5]\n\
                 [[acoustic.receivers]]\nname = \"R\"\nposition = [0.6, 2.6, 1.8]\n";
    let inst = write(dir.path(), "scene.toml", &scene_toml(extra));
    let flat = write(
        dir.path(),
        "flat.toml",
        &format!("obj = \"flat.obj\"\n[materials.wood]\nabsorption = 0.2\nscattering = 0.3\n{extra}"),
    );
    let mut summaries = Vec::new();
    for (name, scene) in [("inst", &inst), ("flat", &flat)] {
        let out = dir.path().join(name).display().to_string();
        let (ok, _, err) = propsim(&["acoustic", scene, "--out", &out]);
        assert!(ok, "{err}");
        summaries.push(std::fs::read_to_string(dir.path().join(name).join("metrics.csv")).unwrap());
    }
    // The rooms are the same: the reverberation times agree within the noise of 20,000 rays.
    let t30 = |csv: &str| -> Vec<f64> {
        let mut lines = csv.lines();
        let head: Vec<&str> = lines.next().unwrap().split(',').collect();
        let col = head.iter().position(|h| h.starts_with("t30")).expect("a t30 column");
        lines.map(|l| l.split(',').nth(col).unwrap().parse::<f64>().unwrap_or(f64::NAN)).collect()
    };
    let (a, b) = (t30(&summaries[0]), t30(&summaries[1]));
    let pairs: Vec<(f64, f64)> =
        a.iter().zip(&b).map(|(x, y)| (*x, *y)).filter(|(x, y)| x.is_finite() && y.is_finite()).collect();
    let close = pairs.iter().filter(|(x, y)| (x - y).abs() <= 0.05 * y.abs()).count();
    assert!(pairs.len() >= 4 && close * 4 >= pairs.len() * 3, "{a:?} vs {b:?}");
    // Radio runs on the instanced room (wood has no radio data: map it to a library material that has).
    let radio = write(
        dir.path(),
        "radio.toml",
        &scene_toml("[rf]\nfreq_ghz = 3.5\nrays = 20000\n[[rf.transmitters]]\nname = \"T\"\nposition = [3.5, 0.5, 1.5]\n")
            .replace("[materials.wood]\nabsorption = 0.2\nscattering = 0.3\n", "[surfaces]\nwood = \"door_solid_wood\"\n"),
    );
    let out = dir.path().join("rf").display().to_string();
    let (ok, _, err) = propsim(&["rf", &radio, "--out", &out]);
    assert!(ok, "{err}");
}

#[test]
fn bad_instances_are_one_line_errors_naming_the_file_and_the_instance() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "room.obj", &room_and_seat());
    let cases: [(&str, &[&str]); 7] = [
        ("name = \"a\"\nmesh = \"seat\"\nscale = [1, 0, 1]", &["instance \"a\"", "singular"]),
        ("name = \"b\"\nmesh = \"seat\"\ntranslate = [nan, 0, 0]", &["instance \"b\"", "finite"]),
        (
            "name = \"c\"\nmesh = \"seat\"\nmatrix = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, inf, 1]]",
            &["instance \"c\"", "finite"],
        ),
        ("mesh = \"chair\"", &["instance #1", "unknown mesh \"chair\"", "room, seat"]),
        ("name = \"e\"\nmesh = \"tree.obj\"", &["instance \"e\"", "tree.obj not found"]),
        ("name = \"f\"\nmesh = \"scene.toml\"", &["instance \"f\"", "do not nest"]),
        (
            "name = \"g\"\nmesh = \"seat\"\nmaterial = \"unobtainium\"",
            &["instance \"g\"", "unknown material \"unobtainium\""],
        ),
    ];
    for (body, needles) in cases {
        let scene = write(dir.path(), "scene.toml", &format!("obj = \"room.obj\"\n[[instances]]\n{body}\n"));
        let mut all = vec![scene.as_str()];
        all.extend_from_slice(needles);
        assert_clean_error(&["info", &scene], &all);
    }
}

#[test]
fn the_shipped_instanced_rooms_load_with_their_closed_form_volumes() {
    let root = env!("CARGO_MANIFEST_DIR");
    let hall = world(&format!("{root}/rooms/auditorium/scene.toml"));
    let r = &hall.report;
    assert_eq!((r.instances, r.triangles, r.unique_triangles), (192, 12 + 192 * 20, 32));
    assert!(r.is_closed() && r.is_consistently_oriented());
    // 24 x 18 x 9 m minus 192 L-shaped seats of 0.5 x (0.5 x 0.45 + 0.1 x 0.45) m^3.
    let air = 24.0 * 18.0 * 9.0 - 192.0 * 0.5 * (0.5 * 0.45 + 0.1 * 0.45);
    assert!((r.air_volume_m3.unwrap() - air).abs() < 1e-3, "{:?}", r.air_volume_m3);
    assert!(hall.check_acoustic_points().is_ok());
    let city = world(&format!("{root}/rooms/city_block/scene.toml"));
    assert_eq!(city.accel.instances.len(), 48);
    assert_eq!(city.accel.instances.mesh_count(), 1);
    assert!(city.scene.surfaces.iter().any(|s| s.name == "concrete as brick"));
}

#[test]
fn shapes_in_a_scene_file_are_hit_at_their_closed_forms() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "room.obj", BOX_OBJ);
    let scene = write(
        dir.path(),
        "scene.toml",
        "obj = \"room.obj\"\n\
         [[shapes]]\nkind = \"sphere\"\nmaterial = \"concrete\"\nscale = [1.0, 0.5, 0.25]\ntranslate = [2, 1.5, 1]\n\
         [[shapes]]\nkind = \"box\"\nmaterial = \"wood\"\nscale = [0.5, 0.5, 0.5]\ntranslate = [3, 2, 0.25]\n",
    );
    let w = world(&scene);
    assert_eq!(w.accel.shapes.shapes.len(), 2);
    // Along +y through the ellipsoid's centre: it is met at y = 1.5 - 0.5.
    let h = w.accel.closest_hit(&Ray::new(Vec3::new(2.0, 0.1, 1.0), Vec3::Y)).unwrap();
    assert!((h.t - 0.9).abs() < 1e-5 && h.kind == PrimitiveKind::Shape, "{h:?}");
    assert!((h.normal + Vec3::Y).length() < 1e-5);
    assert!(w.accel.occluded(&Ray::segment(Vec3::new(2.0, 0.1, 1.0), Vec3::Y, 1.0)));
    // Down onto the box's top at z = 0.5.
    let h = w.accel.closest_hit(&Ray::new(Vec3::new(3.1, 2.1, 2.0), -Vec3::Z)).unwrap();
    assert!((h.t - 1.5).abs() < 1e-5 && (h.normal - Vec3::Z).length() < 1e-5);
    let (ok, out, err) = propsim(&["info", &scene, "--json"]);
    assert!(ok, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let cube = v["surfaces"].as_array().unwrap().iter().find(|s| s["name"] == "shape:wood").unwrap();
    assert!((cube["area_m2"].as_f64().unwrap() - 1.5).abs() < 1e-5, "{cube}");
    let bad = write(
        dir.path(),
        "bad.toml",
        "obj = \"room.obj\"\n[[shapes]]\nkind = \"torus\"\nmaterial = \"wood\"\n",
    );
    assert_clean_error(&["info", &bad], &[&bad, "shape #1", "unknown kind \"torus\""]);
    // An emissive quadric has no closed-form area to sample: refused, not silently dark.
    let glowing = write(
        dir.path(),
        "glow.toml",
        "obj = \"room.obj\"\n[materials.glow]\nemission = [1, 1, 1]\n[[shapes]]\nkind = \"quadric\"\nmaterial = \"glow\"\n\
         coefficients = [1, 1, -1, 0, 0, 0, 0, 0, 0, -1]\nclip_min = [-1, -1, -1]\nclip_max = [1, 1, 1]\n",
    );
    assert_clean_error(&["info", &glowing], &[&glowing, "shape #1", "quadric", "cannot be a light"]);
}

/// A unit quad in its own frame (normal +z), material `MAT`: placed by a transform it
/// becomes a wall or a panel.
fn unit_quad(mat: &str) -> String {
    format!("o quad\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl {mat}\nf 1 2 3 4\n")
}

/// `[[instances]]` of `quad.obj` scaled by `[sx, sy, 1]`, turned 90 degrees about y (the
/// quad's normal +z to +x, its x axis to -z) and moved to `t`: the quad `(u, v)` lands at
/// `t + (0, sy v, -sx u)`.
fn quad_instance(sx: f32, sy: f32, t: [f32; 3]) -> String {
    format!(
        "[[instances]]\nmesh = \"quad.obj\"\nscale = [{sx:?}, {sy:?}, 1.0]\nrotate_axis = [0.0, 1.0, 0.0]\nrotate_deg = 90.0\ntranslate = {t:?}\n"
    )
}

/// The image-source and edge-diffraction arrivals of one source and receiver in the scene
/// `scene` (ISM order 3, diffraction on), sorted by path length.
fn deterministic_arrivals(
    scene: &str,
    s: [f32; 3],
    r: [f32; 3],
) -> Vec<propsim::acoustic::image_source::Arrival> {
    use propsim::acoustic::directivity::Directivity;
    use propsim::acoustic::{AcousticSettings, ReceiverSpec, SourceSpec, simulate};
    let world = world(scene);
    let sources =
        [SourceSpec { name: "S".into(), position: s, power_w: 1.0, directivity: Directivity::OMNI }];
    let receivers = [ReceiverSpec {
        name: "R".into(),
        position: r,
        radius_m: Some(0.2),
        listener: Default::default(),
        directivity: Default::default(),
    }];
    let settings = AcousticSettings { rays: 2000, ism_order: 3, diffraction: true, ..Default::default() };
    let mut a =
        simulate(&world, &sources, &receivers, &settings, &|_| {}).unwrap().pairs[0].image_sources.clone();
    a.sort_by(|x, y| x.length_m.total_cmp(&y.length_m));
    a
}

/// The same paths (order, kind, length) and, per band, the same specular energies and the
/// same total of the direct and diffracted sound within 1% (their coherent sum's cross terms
/// are shared out in the order of the edges, which the copy's winding may change).
fn assert_same_arrivals(
    flat: &[propsim::acoustic::image_source::Arrival],
    inst: &[propsim::acoustic::image_source::Arrival],
) {
    assert_eq!(flat.len(), inst.len(), "arrival counts");
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-4 * a.abs() + 1e-15;
    let mut totals = [[0.0f64; 2]; 8];
    for (f, i) in flat.iter().zip(inst) {
        assert_eq!((f.order, f.diffracted), (i.order, i.diffracted));
        assert!((f.length_m - i.length_m).abs() < 1e-4, "{} vs {} m", f.length_m, i.length_m);
        for (b, (ef, ei)) in f.energy.iter().zip(&i.energy).enumerate() {
            if f.diffracted || f.order == 0 {
                totals[b][0] += ef;
                totals[b][1] += ei;
            } else {
                assert!(close(*ef, *ei), "energy {ef} vs {ei}: {f:?}");
            }
        }
    }
    // (1%: the mirrored reflector's coherent sum differs by 0.4% in the 250 Hz band.)
    for [a, b] in totals {
        assert!((a - b).abs() <= 1e-2 * a, "direct and diffracted energy {a} vs {b}");
    }
}

#[test]
fn an_instanced_reflector_panel_gives_the_image_sources_of_the_flat_one() {
    // A 2 m x 1.5 m reflector (normal +x) hung at x = 3.5 in front of BOX_OBJ's x = 4 wall,
    // given flat and as a placed unit quad ((u, v) lands at (3.5, 0.5 + 2 v, 2 - 1.5 u)).
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let panel = "o panel\nv 3.5 0.5 2\nv 3.5 0.5 0.5\nv 3.5 2.5 0.5\nv 3.5 2.5 2\nusemtl plasterboard\nf 9 12 11 10\n";
    let flat = write(d, "flat.obj", &format!("{BOX_OBJ}{panel}"));
    write(d, "room.obj", BOX_OBJ);
    // The flat panel faces -x (towards the source): mirror the quad's normal with scale z -1.
    write(d, "quad.obj", &unit_quad("plasterboard"));
    let inst = write(
        d,
        "inst.toml",
        &format!(
            "obj = \"room.obj\"\n{}",
            quad_instance(1.5, 2.0, [3.5, 0.5, 2.0]).replace(", 1.0]", ", -1.0]")
        ),
    );
    let (s, r) = ([1.0, 1.0, 1.2], [2.6, 2.2, 1.6]);
    let (a, b) = (deterministic_arrivals(&flat, s, r), deterministic_arrivals(&inst, s, r));
    // The panel's first-order image at x = 7 - 1 = 6: |(6, 1, 1.2) - r|.
    let panel_m = ((6.0f64 - 2.6).powi(2) + 1.2f64.powi(2) + 0.4f64.powi(2)).sqrt();
    assert!(a.iter().any(|x| x.order == 1 && (x.length_m - panel_m).abs() < 1e-4), "the panel's reflection");
    assert!(b.iter().any(|x| x.order == 1 && (x.length_m - panel_m).abs() < 1e-4), "the copy's reflection");
    assert_same_arrivals(&a, &b);
}

#[test]
fn an_instanced_free_standing_panel_reflects_and_diffracts_as_the_flat_one() {
    // A 2 m x 1.5 m panel at x = 2 (y in [0.5, 2.5], z in [0.5, 2]) between source and
    // receiver: no direct sound, edge paths over its rims, reflections on both rooms' walls.
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let panel = "o panel\nv 2 0.5 2\nv 2 0.5 0.5\nv 2 2.5 0.5\nv 2 2.5 2\nusemtl wood\nf 9 10 11 12\n";
    let mats = "[materials.wood]\nabsorption = 0.1\nscattering = 0.2\n";
    write(d, "flat.obj", &format!("{BOX_OBJ}{panel}"));
    let flat = write(d, "flat.toml", &format!("obj = \"flat.obj\"\n{mats}"));
    write(d, "room.obj", BOX_OBJ);
    write(d, "quad.obj", &unit_quad("wood"));
    let inst = write(
        d,
        "inst.toml",
        &format!("obj = \"room.obj\"\n{mats}{}", quad_instance(1.5, 2.0, [2.0, 0.5, 2.0])),
    );
    let (s, r) = ([1.0, 1.4, 1.2], [3.2, 1.6, 1.3]);
    let (a, b) = (deterministic_arrivals(&flat, s, r), deterministic_arrivals(&inst, s, r));
    let diffracted = a.iter().filter(|x| x.diffracted).count();
    assert!(diffracted >= 2, "paths over the panel's rims: {diffracted}");
    assert!(a.iter().all(|x| x.order > 0 || x.diffracted), "the panel hides the direct sound");
    assert_same_arrivals(&a, &b);
}

/// A radio coverage run (library API) on the room with its four instanced seats (scaled,
/// turned and one mirrored) gives the map of the same room with the seats written out flat.
/// The launch is the same Fibonacci lattice of rays in both, so a ray's path differs only
/// where rounding puts it on the other side of a seat's edge: the maps must agree to 0.5 % in
/// their total and cell by cell to 0.5 dB wherever both have 100 or more crossings.
#[test]
fn radio_coverage_of_the_instanced_room_is_the_flattened_rooms() {
    use propsim::rf::{RfConfig, RfOptions, simulate};
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "room.obj", &room_and_seat());
    write(dir.path(), "flat.obj", &flattened_obj());
    // Wood has no radio data: map it to a library material that has.
    let radio = "[surfaces]\nwood = \"door_solid_wood\"\n[rf]\nfreq_ghz = 3.5\n\
                 [[rf.transmitters]]\nname = \"T\"\nposition = [3.5, 0.5, 1.5]\n";
    let inst = write(
        dir.path(),
        "inst.toml",
        &scene_toml(radio).replace("[materials.wood]\nabsorption = 0.2\nscattering = 0.3\n", ""),
    );
    let flat = write(dir.path(), "flat.toml", &format!("obj = \"flat.obj\"\n{radio}"));
    let options = RfOptions {
        rays: Some(400_000),
        cell_m: Some(0.25),
        grid_height_m: Some(0.6),
        ..RfOptions::default()
    };
    let maps: Vec<_> = [&inst, &flat]
        .iter()
        .map(|scene| {
            let w = world(scene);
            let config = RfConfig::from_scene(&w, &options).unwrap();
            simulate(&w, &config, &|_| {}).unwrap().coverage
        })
        .collect();
    let (a, b) = (&maps[0], &maps[1]);
    assert_eq!(a.spec, b.spec);
    let (ta, tb) = (a.path_gain.iter().sum::<f64>(), b.path_gain.iter().sum::<f64>());
    let (mut compared, mut worst_db) = (0, 0.0f64);
    for i in 0..a.path_gain.len() {
        if a.paths[i] >= 100 && b.paths[i] >= 100 {
            compared += 1;
            worst_db = worst_db.max((10.0 * (a.path_gain[i] / b.path_gain[i]).log10()).abs());
        }
    }
    let same_paths = a.paths.iter().zip(&b.paths).filter(|(x, y)| x == y).count();
    eprintln!(
        "rf coverage, instanced against flattened: total path gain ratio {:.6}; {compared} cells of {} \
         compared, worst {worst_db:.4} dB; {same_paths} cells with the same crossing count",
        ta / tb,
        a.path_gain.len()
    );
    assert!(compared >= 100, "{compared} cells compared");
    assert!((ta / tb - 1.0).abs() < 5e-3, "total path gain {ta} vs {tb}");
    assert!(worst_db < 0.5, "worst cell {worst_db} dB");
}
