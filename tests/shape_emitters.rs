//! Emissive analytic shapes and emissive instanced triangles are area lights (issue 24, point
//! 3): the irradiance they give a floor point against closed forms, through the path
//! tracer's next-event estimation and its MIS with BSDF sampling; the path tracer, the light
//! tracer, BDPT, pssmlt and SPPM agreeing on a scene lit only by shapes; bit-identical images
//! for one and two threads; an instanced emissive quad lighting a floor as the same quad
//! flattened.

mod common;

use std::f64::consts::PI;
use std::path::Path;

use common::render::{go, settings};
use glam::Vec3;
use propsim::core::Ray;
use propsim::core::rng::stream;
use propsim::render::sampler::Sampler;
use propsim::render::{Camera, IntegratorKind, Light, RenderScene, radiance};
use propsim::scene::{LoadOptions, World, load};

/// Albedo of the floor (grey, so one channel stands for all).
const ALBEDO: f64 = 0.5;
/// Radiance of the emitters.
const LE: f64 = 2.0;

/// A 40 m x 40 m floor at z = 0 facing up, material `white`.
const FLOOR_OBJ: &str = "v -20 -20 0\nv 20 -20 0\nv 20 20 0\nv -20 20 0\nusemtl white\nf 1 2 3 4\n";

/// The scene file: the floor, a white diffuse material, the emissive `glow`, and `extra`.
fn scene_text(extra: &str) -> String {
    format!(
        "obj = \"floor.obj\"\n[materials.white]\ncolor = [{ALBEDO}, {ALBEDO}, {ALBEDO}]\nkind = \"diffuse\"\n\
         [materials.glow]\ncolor = [0, 0, 0]\nkind = \"diffuse\"\nemission = [{LE}, {LE}, {LE}]\n{extra}"
    )
}

/// The world of `scene_text(extra)` written with its floor into `dir` as `name`.
fn world_of(dir: &Path, name: &str, extra: &str) -> World {
    std::fs::write(dir.join("floor.obj"), FLOOR_OBJ).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, scene_text(extra)).unwrap();
    World::build(load(&path, &LoadOptions::default()).unwrap())
}

/// The path tracer's radiance (direct lighting only, `max_depth` 1: one light sample and one
/// BSDF sample joined by MIS) leaving the floor point `at` towards `eye`, averaged over `n`
/// independent samples: (mean, standard error) of the first channel.
fn floor_radiance(scene: &RenderScene, eye: Vec3, at: Vec3, n: u64, seed: u64) -> (f64, f64) {
    let (mut sum, mut sum2) = (0.0f64, 0.0f64);
    for k in 0..n {
        let mut rng = stream(seed, 7, k);
        let scramble = (k as u32).wrapping_mul(0x9e37_79b9) ^ seed as u32;
        let mut sampler = Sampler::new(scramble, 0, false, &mut rng);
        let ray = Ray::new(eye, (at - eye).normalize());
        let mut rays = 0;
        let l = f64::from(radiance(scene, IntegratorKind::Path, ray, 1, &mut sampler, &mut rays, None).x);
        sum += l;
        sum2 += l * l;
    }
    let mean = sum / n as f64;
    let var = (sum2 / n as f64 - mean * mean).max(0.0) / (n as f64 - 1.0);
    (mean, var.sqrt())
}

/// Irradiance at the floor point `at` by the path tracer: `pi L_o / albedo` of a Lambertian
/// floor; (mean, standard error).
fn irradiance(scene: &RenderScene, at: Vec3, n: u64) -> (f64, f64) {
    // Seen obliquely from outside every emitter of these tests.
    let (l, se) = floor_radiance(scene, at + Vec3::new(3.0, 0.5, 0.8), at, n, 11);
    (l * PI / ALBEDO, se * PI / ALBEDO)
}

/// `|got - want|` within four standard errors plus 0.2 % (the f32 arithmetic).
fn assert_close(what: &str, (got, se): (f64, f64), want: f64) {
    eprintln!(
        "{what}: E = {got:.5} +- {se:.5} against the closed form {want:.5} ({:+.3} %)",
        100.0 * (got / want - 1.0)
    );
    assert!((got - want).abs() <= 4.0 * se + 2e-3 * want, "{what}: {got} +- {se} vs {want}");
    assert!(se < 0.01 * want, "{what}: too noisy to test ({se})");
}

/// Irradiance at the origin from a Lambertian emitter whose silhouette, seen from there, is
/// a disk of radius `r` centred on the normal at height `h`: `pi L r^2 / (r^2 + h^2)`.
fn disk_irradiance(r: f64, h: f64) -> f64 {
    PI * LE * r * r / (r * r + h * h)
}

/// A disk of radius R at height h facing down: E = pi L R^2 / (R^2 + h^2) below its centre;
/// and off the axis, the closed form of a point under a disk's edge region (Howell's
/// catalogue B-13: a disk parallel to the receiving element, offset by `a`):
/// `E = (pi L / 2) (1 - (h^2 + a^2 - R^2) / sqrt((h^2 + a^2 + R^2)^2 - 4 a^2 R^2))`.
#[test]
fn an_emissive_disk_gives_the_closed_form_irradiance() {
    let dir = tempfile::tempdir().unwrap();
    let (r, h) = (0.5f64, 1.0f64);
    let world = world_of(
        dir.path(),
        "disk.toml",
        &format!(
            "[[shapes]]\nkind = \"disk\"\nmaterial = \"glow\"\nscale = [{r}, {r}, 1]\nrotate_axis = [1, 0, 0]\nrotate_deg = 180\ntranslate = [0, 0, {h}]\n"
        ),
    );
    let scene = RenderScene::new(&world);
    assert_eq!(scene.lights.lights.len(), 1, "the disk is one light");
    assert_close("disk, below the centre", irradiance(&scene, Vec3::ZERO, 200_000), disk_irradiance(r, h));
    for a in [0.4f64, 1.2] {
        let (h2, a2, r2) = (h * h, a * a, r * r);
        let want = 0.5 * PI * LE * (1.0 - (h2 + a2 - r2) / ((h2 + a2 + r2).powi(2) - 4.0 * a2 * r2).sqrt());
        let got = irradiance(&scene, Vec3::new(a as f32, 0.0, 0.0), 200_000);
        assert_close(&format!("disk, {a} m off the axis"), got, want);
    }
}

/// Each closed shape hung over the origin shows it one flat face or a round silhouette, so
/// its irradiance there has a closed form: a cylinder or a cone standing on its base disk of
/// radius R at height h gives the disk's; a box of side s gives its bottom square's
/// (four corner form factors of a point below a rectangle, Howell's catalogue C-11); an
/// ellipsoid of revolution (semi-axes a, a, c, centre at height d, axis vertical) is bounded
/// by the tangent cone of half-angle asin(a / sqrt(a^2 + d^2 - c^2)), so E = pi L a^2 /
/// (a^2 + d^2 - c^2), and a round sphere (radius r, centre at height d) pi L r^2 / d^2. The ellipsoids are sampled with a density that varies over them: this
/// checks the density and its MIS weight, not only the area.
#[test]
fn emissive_closed_shapes_give_the_closed_form_irradiance() {
    let dir = tempfile::tempdir().unwrap();
    let square = |s: f64, h: f64| {
        let (x, y) = (s / (2.0 * h), s / (2.0 * h));
        let corner = 1.0 / (2.0 * PI)
            * (x / (1.0 + x * x).sqrt() * (y / (1.0 + x * x).sqrt()).atan()
                + y / (1.0 + y * y).sqrt() * (x / (1.0 + y * y).sqrt()).atan());
        PI * LE * 4.0 * corner
    };
    let cases: [(&str, String, f64); 6] = [
        (
            "round sphere r 0.4 at z = 1, turned",
            "kind = \"sphere\"\nscale = 0.4\nrotate_euler_deg = [10, 20, 30]\ntranslate = [0, 0, 1]".into(),
            PI * LE * 0.16,
        ),
        (
            "cylinder R 0.4 on z = 0.8",
            "kind = \"cylinder\"\nscale = [0.4, 0.4, 0.5]\ntranslate = [0, 0, 0.8]".into(),
            disk_irradiance(0.4, 0.8),
        ),
        (
            "cone R 0.6 on z = 1.1",
            "kind = \"cone\"\nscale = [0.6, 0.6, 0.7]\ntranslate = [0, 0, 1.1]".into(),
            disk_irradiance(0.6, 1.1),
        ),
        (
            "box of side 0.8, bottom at z = 0.6",
            "kind = \"box\"\nscale = 0.8\nrotate_euler_deg = [0, 0, 0]\ntranslate = [0, 0, 1.0]".into(),
            square(0.8, 0.6),
        ),
        (
            "oblate ellipsoid a 0.5, c 0.25 at z = 1",
            "kind = \"sphere\"\nscale = [0.5, 0.5, 0.25]\ntranslate = [0, 0, 1]".into(),
            PI * LE * 0.25 / (0.25 + 1.0 - 0.0625),
        ),
        (
            "prolate ellipsoid a 0.3, c 0.6 at z = 1.2",
            "kind = \"sphere\"\nscale = [0.3, 0.3, 0.6]\nrotate_axis = [0, 0, 1]\nrotate_deg = 40\ntranslate = [0, 0, 1.2]".into(),
            PI * LE * 0.09 / (0.09 + 1.44 - 0.36),
        ),
    ];
    for (k, (what, shape, want)) in cases.iter().enumerate() {
        let world = world_of(
            dir.path(),
            &format!("s{k}.toml"),
            &format!("[[shapes]]\nmaterial = \"glow\"\n{shape}\n"),
        );
        let scene = RenderScene::new(&world);
        assert_eq!(scene.lights.lights.len(), 1);
        // A round sphere is sampled by the cone it subtends, the other shapes by area.
        assert_eq!(matches!(scene.lights.lights[0], Light::Sphere { .. }), k == 0, "{what}");
        assert_close(what, irradiance(&scene, Vec3::ZERO, 500_000), *want);
    }
}

/// A small scene lit only by shapes (a stretched, tilted box, an ellipsoid and a disk over a
/// floor and a back wall), rendered by the path tracer, the light tracer, BDPT and pssmlt: each
/// 4 x 4-pixel region's mean over 16 independent runs agrees with the path tracer's within
/// Welch's t at a Bonferroni-corrected alpha of 0.001 over the regions. The emitters are in
/// view, so the light tracer's and BDPT's direct view of an emitter is checked too.
#[test]
fn path_light_bdpt_and_pssmlt_agree_on_a_scene_lit_by_shapes() {
    let dir = tempfile::tempdir().unwrap();
    let world = lit_by_shapes(dir.path());
    let scene = RenderScene::new(&world);
    assert_eq!(scene.lights.lights.len(), 3);
    let cam =
        Camera::look_at(Vec3::new(0.0, -4.0, 2.2), Vec3::new(0.0, 0.0, 0.5), Vec3::Z, 50.0, 1.0).unwrap();
    let (w, runs, block) = (16u32, 16u64, 4usize);
    let pooled = |integrator: IntegratorKind, spp: u32, seed: u64| -> Vec<Vec<f64>> {
        (0..runs)
            .map(|k| {
                let mut s = settings(w, spp, 6, integrator, seed + 1000 * k);
                // pssmlt: 10,000 bootstrap samples a depth and 256 chains (as render_integrators).
                s.mlt.bootstrap = 10_000;
                s.mlt.chains = 256;
                let f = go(&scene, &cam, &s);
                let r = w as usize / block;
                (0..r * r)
                    .map(|region| {
                        let (rx, ry) = (region % r, region / r);
                        let mut sum = 0.0;
                        for y in ry * block..(ry + 1) * block {
                            for x in rx * block..(rx + 1) * block {
                                sum += f64::from(f.pixels[y * w as usize + x].x);
                            }
                        }
                        sum / (block * block) as f64
                    })
                    .collect()
            })
            .collect()
    };
    let stats = |runs_: &[Vec<f64>]| -> Vec<(f64, f64)> {
        let r = runs_.len() as f64;
        (0..runs_[0].len())
            .map(|i| {
                let m = runs_.iter().map(|v| v[i]).sum::<f64>() / r;
                let var = runs_.iter().map(|v| (v[i] - m).powi(2)).sum::<f64>() / (r - 1.0) / r;
                (m, var)
            })
            .collect()
    };
    let reference = stats(&pooled(IntegratorKind::Path, 64, 1));
    // Two-sided t quantile for p = 0.001 / 16 at 15 degrees of freedom (the fewest Welch's
    // test can have with 16 runs a side): 5.5.
    let threshold = 5.5;
    for (integrator, spp) in
        [(IntegratorKind::Light, 32), (IntegratorKind::Bdpt, 16), (IntegratorKind::Pssmlt, 64)]
    {
        let got = stats(&pooled(integrator, spp, 5));
        let mut worst = 0.0f64;
        let (mut sum_a, mut sum_b, mut var_sum) = (0.0, 0.0, 0.0);
        for ((m, v), (rm, rv)) in got.iter().zip(&reference) {
            let t = (m - rm).abs() / (v + rv).sqrt().max(1e-12);
            worst = worst.max(t);
            sum_a += m;
            sum_b += rm;
            var_sum += v + rv;
        }
        // The whole image's mean too (its own test, at alpha 0.001: |t| < 4.1 at 15 dof).
        let t_all = (sum_a - sum_b).abs() / var_sum.sqrt();
        eprintln!(
            "{integrator:?} against path: worst |t| {worst:.2} over 16 regions; image mean ratio {:.4}, |t| {t_all:.2}",
            sum_a / sum_b
        );
        assert!(worst < threshold, "{integrator:?}: |t| {worst}");
        assert!(t_all < 4.1, "{integrator:?}: image mean ratio {}, |t| {t_all}", sum_a / sum_b);
    }
}

/// SPPM's photons leave the shape lights too: on the shape-lit scene its image mean (64
/// iterations of 20,000 photons, 4 runs) is the path tracer's within 2 %. SPPM is biased (a
/// photon counts within a radius of the visible point, which blurs the light near edges and
/// the emitters' rims), so the test is on the whole image's mean, not on regions.
#[test]
fn sppm_sees_the_shape_lights() {
    let dir = tempfile::tempdir().unwrap();
    let world = lit_by_shapes(dir.path());
    let scene = RenderScene::new(&world);
    let cam =
        Camera::look_at(Vec3::new(0.0, -4.0, 2.2), Vec3::new(0.0, 0.0, 0.5), Vec3::Z, 50.0, 1.0).unwrap();
    let mean = |integrator: IntegratorKind, spp: u32| -> f64 {
        (0..4u64)
            .map(|k| {
                let mut s = settings(16, spp, 6, integrator, 3 + 1000 * k);
                s.photons.photons_per_iteration = Some(20_000);
                let f = go(&scene, &cam, &s);
                f.pixels.iter().map(|p| f64::from(p.x)).sum::<f64>() / f.pixels.len() as f64
            })
            .sum::<f64>()
            / 4.0
    };
    let (path, sppm) = (mean(IntegratorKind::Path, 256), mean(IntegratorKind::Sppm, 64));
    eprintln!("sppm image mean {sppm:.5} against path {path:.5}: ratio {:.4}", sppm / path);
    assert!((sppm / path - 1.0).abs() < 0.02, "{sppm} vs {path}");
}

/// The scene of [`path_light_bdpt_and_pssmlt_agree_on_a_scene_lit_by_shapes`]: the floor, a back
/// wall at y = 1.5 and three emitters.
fn lit_by_shapes(dir: &Path) -> World {
    let wall =
        "[[shapes]]\nkind = \"box\"\nmaterial = \"white\"\nscale = [6, 0.1, 4]\ntranslate = [0, 1.55, 2]\n";
    let emitters = "[[shapes]]\nkind = \"box\"\nmaterial = \"glow\"\nscale = [0.6, 0.3, 0.15]\nrotate_euler_deg = [20, 30, 10]\ntranslate = [-0.7, 0.2, 1.1]\n\
                    [[shapes]]\nkind = \"sphere\"\nmaterial = \"glow\"\nscale = [0.35, 0.15, 0.2]\nrotate_euler_deg = [0, 40, 0]\ntranslate = [0.8, 0.6, 0.7]\n\
                    [[shapes]]\nkind = \"disk\"\nmaterial = \"glow\"\nscale = [0.3, 0.5, 1]\nrotate_axis = [1, 0, 0]\nrotate_deg = 150\ntranslate = [0.1, -0.3, 1.6]\n";
    world_of(dir, "lit.toml", &format!("{wall}{emitters}"))
}

/// Same seed, same image bit for bit on one thread and on two, for the path tracer, the
/// light tracer, BDPT, SPPM and pssmlt on the shape-lit scene.
#[test]
fn shape_lit_images_are_the_same_for_one_and_two_threads() {
    let dir = tempfile::tempdir().unwrap();
    let world = lit_by_shapes(dir.path());
    let scene = RenderScene::new(&world);
    let cam =
        Camera::look_at(Vec3::new(0.0, -4.0, 2.2), Vec3::new(0.0, 0.0, 0.5), Vec3::Z, 50.0, 1.0).unwrap();
    for integrator in [
        IntegratorKind::Path,
        IntegratorKind::Light,
        IntegratorKind::Bdpt,
        IntegratorKind::Sppm,
        IntegratorKind::Pssmlt,
    ] {
        let mut s = settings(24, 8, 6, integrator, 42);
        s.photons.photons_per_iteration = Some(5_000);
        s.mlt.bootstrap = 2_000;
        s.mlt.chains = 64;
        let on = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            let f = pool.install(|| go(&scene, &cam, &s));
            f.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<u32>>()
        };
        let one = on(1);
        assert!(one.iter().any(|&b| f32::from_bits(b) > 0.0), "{integrator:?}: the image is lit");
        assert_eq!(one, on(2), "{integrator:?}");
    }
}

/// Corner form factor sum for a point below the centre of an `a` x `b` rectangle at height
/// `h` (Howell's catalogue C-11), as irradiance from radiance `LE`.
fn rectangle_irradiance(a: f64, b: f64, h: f64) -> f64 {
    let (x, y) = (a / (2.0 * h), b / (2.0 * h));
    let corner = 1.0 / (2.0 * PI)
        * (x / (1.0 + x * x).sqrt() * (y / (1.0 + x * x).sqrt()).atan()
            + y / (1.0 + y * y).sqrt() * (x / (1.0 + y * y).sqrt()).atan());
    PI * LE * 4.0 * corner
}

/// An emissive quad placed by `[[instances]]` (one copy turned over, one mirrored to face
/// down) lights the floor as the same quads written into the scene's OBJ: the irradiance at
/// three floor points agrees between the two scenes within their standard errors, and below
/// a quad's centre with the rectangle's closed form.
#[test]
fn an_instanced_emissive_quad_lights_the_floor_as_the_flattened_one() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    // A unit quad facing +z in its own frame, emissive.
    std::fs::write(d.join("lamp.obj"), "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nusemtl glow\nf 1 2 3 4\n")
        .unwrap();
    // Copy A: 0.8 x 0.6, turned over (180 degrees about x: (u, v) -> (u, -v), normal -z),
    // corner at (-1.4, 0.3, 1): it spans x in [-1.4, -0.6], y in [-0.3, 0.3] at z = 1.
    // Copy B: 0.5 x 0.5, mirrored by scale z = -1 (normal -z), at (0.5, -0.25, 0.7).
    let instanced = "[[instances]]\nmesh = \"lamp.obj\"\nscale = [0.8, 0.6, 1]\nrotate_axis = [1, 0, 0]\nrotate_deg = 180\ntranslate = [-1.4, 0.3, 1]\n\
                     [[instances]]\nmesh = \"lamp.obj\"\nscale = [0.5, 0.5, -1]\ntranslate = [0.5, -0.25, 0.7]\n";
    let inst = world_of(d, "inst.toml", instanced);
    // The same quads in the scene's own OBJ, wound to face down.
    let flat_obj = format!(
        "{FLOOR_OBJ}v -1.4 -0.3 1\nv -0.6 -0.3 1\nv -0.6 0.3 1\nv -1.4 0.3 1\nusemtl glow\nf 5 8 7 6\n\
         v 0.5 -0.25 0.7\nv 1 -0.25 0.7\nv 1 0.25 0.7\nv 0.5 0.25 0.7\nf 9 12 11 10\n"
    );
    std::fs::write(d.join("flat.obj"), flat_obj).unwrap();
    std::fs::write(d.join("flat.toml"), scene_text("").replace("floor.obj", "flat.obj")).unwrap();
    let flat = World::build(load(&d.join("flat.toml"), &LoadOptions::default()).unwrap());
    let (si, sf) = (RenderScene::new(&inst), RenderScene::new(&flat));
    assert_eq!(si.lights.lights.len(), 4, "two triangles per copy");
    assert_eq!(sf.lights.lights.len(), 4);
    let n = 100_000;
    for at in [Vec3::new(-1.0, 0.0, 0.0), Vec3::new(0.75, 0.0, 0.0), Vec3::new(-0.2, 0.4, 0.0)] {
        let (a, b) = (irradiance(&si, at, n), irradiance(&sf, at, n));
        eprintln!("E at {at}: instanced {:.5} +- {:.5}, flattened {:.5} +- {:.5}", a.0, a.1, b.0, b.1);
        assert!((a.0 - b.0).abs() <= 4.0 * (a.1 * a.1 + b.1 * b.1).sqrt() + 1e-3 * b.0, "{at}");
    }
    // Below copy A's centre the other copy adds a little: the sum of both closed forms would
    // need B's off-centre form factor, so B is taken out of this check by a second scene.
    let only_a = world_of(
        d,
        "a.toml",
        instanced.split("[[instances]]").nth(1).map(|s| format!("[[instances]]{s}")).as_deref().unwrap(),
    );
    let sa = RenderScene::new(&only_a);
    assert_close(
        "instanced 0.8 x 0.6 quad at 1 m",
        irradiance(&sa, Vec3::new(-1.0, 0.0, 0.0), n),
        rectangle_irradiance(0.8, 0.6, 1.0),
    );
}
