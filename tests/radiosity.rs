//! The radiosity integrator against closed forms (form factors of unit squares from the
//! catalogue, the white furnace) and statistically against the path tracer, its determinism
//! across thread counts, and its one-line errors.

mod common;

use common::render::{go, settings};
use glam::Vec3;
use propsim::core::rng::stream;
use propsim::core::{Accel, BuildQuality, TriangleMesh};
use propsim::render::radiosity::form_factor::{Tri, estimate};
use propsim::render::radiosity::{Method, RadiosityOptions};
use propsim::render::{Film, IntegratorKind, RenderScene, RenderSettings, render};
use propsim::scene::{self, LoadOptions, World};

/// Form factor between two directly opposed parallel rectangles `x` by `y` at distance `c`
/// (Howell's catalogue, C-11), in f64.
fn parallel_rectangles(x: f64, y: f64, c: f64) -> f64 {
    let (x, y) = (x / c, y / c);
    let (x1, y1) = ((1.0 + x * x).sqrt(), (1.0 + y * y).sqrt());
    2.0 / (std::f64::consts::PI * x * y)
        * ((x1 * x1 * y1 * y1 / (1.0 + x * x + y * y)).sqrt().ln()
            + x * y1 * (x / y1).atan()
            + y * x1 * (y / x1).atan()
            - x * x.atan()
            - y * y.atan())
}

/// Form factor from a rectangle `l` by `w` to a perpendicular rectangle `l` by `h` sharing its
/// edge of length `l` (Howell's catalogue, C-14), in f64.
fn perpendicular_rectangles(l: f64, w: f64, h: f64) -> f64 {
    let (h, w) = (h / l, w / l);
    let a = (1.0 + w * w) * (1.0 + h * h) / (1.0 + w * w + h * h);
    let b = (w * w * (1.0 + w * w + h * h) / ((1.0 + w * w) * (w * w + h * h))).powf(w * w);
    let c = (h * h * (1.0 + h * h + w * w) / ((1.0 + h * h) * (h * h + w * w))).powf(h * h);
    let r = (h * h + w * w).sqrt();
    1.0 / (std::f64::consts::PI * w)
        * (w * (1.0 / w).atan() + h * (1.0 / h).atan() - r * (1.0 / r).atan() + 0.25 * (a * b * c).ln())
}

/// The form factor from square `a` to square `b` (each two triangles, areas equal) by the
/// ray-cast estimator with `samples` receiver points per triangle pair, occlusion tested on
/// the scene of both squares.
fn square_to_square(a: [Vec3; 4], b: [Vec3; 4], samples: u32) -> f64 {
    let mut mesh = TriangleMesh::default();
    let id = mesh.surface_id("plate");
    mesh.push_quad(a[0], a[1], a[2], a[3], id);
    mesh.push_quad(b[0], b[1], b[2], b[3], id);
    let accel = Accel::build(&mesh, vec![], BuildQuality::default());
    let tris: Vec<Tri> = (0..4).map(|i| Tri::new(mesh.corners(i)).unwrap()).collect();
    let mut total = 0.0f64;
    for (i, p) in tris[..2].iter().enumerate() {
        for (j, q) in tris[2..].iter().enumerate() {
            let mut rng = stream(7, 1, (i * 2 + j) as u64);
            let (f, rays) = estimate(Some(&accel), p, q, samples, &mut rng);
            assert!(rays > 0);
            // Area-weighted: each receiver triangle is half of the square.
            total += 0.5 * f64::from(f.iter().flatten().sum::<f32>());
        }
    }
    total
}

/// Parallel unit squares at unit distance: 0.19982 (closed form); perpendicular unit squares
/// sharing an edge: 0.20004. The estimator with 1,024 receiver points per triangle pair
/// (4,096 a square pair) is within 0.2 % of both.
#[test]
fn unit_square_form_factors_match_the_closed_forms() {
    let parallel = parallel_rectangles(1.0, 1.0, 1.0);
    let perpendicular = perpendicular_rectangles(1.0, 1.0, 1.0);
    assert!((parallel - 0.19982).abs() < 5e-6, "{parallel}");
    assert!((perpendicular - 0.20004).abs() < 5e-6, "{perpendicular}");
    let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
    // Floor square facing up, ceiling square facing down.
    let floor = [v(0.0, 0.0, 0.0), v(1.0, 0.0, 0.0), v(1.0, 1.0, 0.0), v(0.0, 1.0, 0.0)];
    let ceiling = [v(0.0, 0.0, 1.0), v(0.0, 1.0, 1.0), v(1.0, 1.0, 1.0), v(1.0, 0.0, 1.0)];
    // A wall on the floor's x = 0 edge, facing +x.
    let wall = [v(0.0, 0.0, 0.0), v(0.0, 1.0, 0.0), v(0.0, 1.0, 1.0), v(0.0, 0.0, 1.0)];
    let got_parallel = square_to_square(floor, ceiling, 1024);
    let got_perpendicular = square_to_square(floor, wall, 1024);
    let got_back = square_to_square(wall, floor, 1024);
    eprintln!(
        "parallel {got_parallel:.6} (closed form {parallel:.6}), perpendicular {got_perpendicular:.6} \
         and {got_back:.6} (closed form {perpendicular:.6})"
    );
    for (got, want) in
        [(got_parallel, parallel), (got_perpendicular, perpendicular), (got_back, perpendicular)]
    {
        assert!((got - want).abs() < 2e-3 * want, "{got} vs {want}");
    }
}

/// A closed box whose walls all emit `le` and reflect `r`: radiosity gives `le / (1 - r)`
/// everywhere (the white furnace), with both linkings.
#[test]
fn radiosity_furnace_is_le_over_one_minus_r() {
    for (r, le) in [(0.5f32, 1.0f32), (0.8, 0.5)] {
        let mut mesh = TriangleMesh::default();
        let id = mesh.surface_id("wall");
        mesh.push_box(Vec3::ZERO, Vec3::new(2.0, 3.0, 1.5), 2, id);
        mesh.flip_winding();
        let accel = Accel::build(&mesh, vec![], BuildQuality::default());
        let optics = vec![propsim::render::SurfaceOptics {
            bsdf: propsim::render::Bsdf::Lambert { albedo: Vec3::splat(r) },
            emission: Vec3::splat(le),
        }];
        let scene = RenderScene::from_parts(&accel, &mesh, &[], optics, &[], Vec3::ZERO);
        let cam = propsim::render::Camera::look_at(
            Vec3::new(1.0, 0.5, 0.7),
            Vec3::new(1.2, 3.0, 0.9),
            Vec3::Z,
            90.0,
            1.0,
        )
        .unwrap();
        let expect = le / (1.0 - r);
        for method in [Method::Hierarchical, Method::Matrix] {
            let mut s = settings(24, 2, 8, IntegratorKind::Radiosity, 1);
            s.radiosity = RadiosityOptions { method, patches: 256, ..RadiosityOptions::default() };
            let film = go(&scene, &cam, &s);
            let (lo, hi) = film
                .pixels
                .iter()
                .fold((f32::MAX, 0.0f32), |(lo, hi), p| (lo.min(p.min_element()), hi.max(p.max_element())));
            eprintln!(
                "radiosity furnace r {r}, Le {le}, {method:?}: mean {}, range {lo}..{hi}, expected {expect}",
                film.mean()
            );
            assert!((film.mean() - Vec3::splat(expect)).abs().max_element() < 0.01 * expect);
        }
    }
}

fn cornell_classic() -> World {
    World::build(scene::load("builtin:cornell_box_classic".as_ref(), &LoadOptions::default()).expect("loads"))
}

/// Rec. 709 luminance.
fn luminance(c: Vec3) -> f64 {
    f64::from(0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z)
}

/// Radiosity and the path tracer (100 bounces, so that the missing tail is negligible) agree
/// on the purely diffuse Cornell box: the image means within 4 % per channel and the means of
/// 16 x 16 pixel regions within 12 % in luminance. The tolerance is radiosity's, not the path
/// tracer's noise (at 256 spp a region mean has a relative standard error under 0.5 %): the
/// patches are constant (a region that straddles an edge or the light's rim mixes patches of
/// the wrong side), each link's form factor is estimated from 16 points, and the hierarchy
/// keeps coarse links whose radiance falls below the threshold. Measured with the
/// defaults: image means 1.1 % apart (radiosity lower), regions at most 4.0 %.
#[test]
fn radiosity_agrees_with_the_path_tracer_on_the_diffuse_cornell_box() {
    let world = cornell_classic();
    let scene = RenderScene::new(&world);
    let cam = propsim::render::scene_camera(&world, 1.0).unwrap();
    let w = 64;
    let path = go(&scene, &cam, &settings(w, 256, 100, IntegratorKind::Path, 3));
    let rad = go(&scene, &cam, &settings(w, 4, 100, IntegratorKind::Radiosity, 3));
    let (mp, mr) = (path.mean(), rad.mean());
    eprintln!("image mean: path {mp}, radiosity {mr}");
    assert!(((mr - mp) / mp).abs().max_element() < 0.03, "{mr} vs {mp}");
    let region = |f: &Film, rx: u32, ry: u32| {
        let mut sum = 0.0;
        for y in ry * 16..ry * 16 + 16 {
            for x in rx * 16..rx * 16 + 16 {
                sum += luminance(f.get(x, y));
            }
        }
        sum / 256.0
    };
    let mut worst = 0.0f64;
    for ry in 0..w / 16 {
        for rx in 0..w / 16 {
            let (p, r) = (region(&path, rx, ry), region(&rad, rx, ry));
            worst = worst.max((r - p).abs() / p);
        }
    }
    eprintln!("worst region: {:.2} %", 100.0 * worst);
    assert!(worst < 0.08, "{worst}");
}

/// The same seed gives bit-identical images on 1 and 2 threads (the form factors draw from
/// one stream per pair and the solution is Jacobi), and another seed a different one.
#[test]
fn radiosity_is_the_same_on_one_and_two_threads() {
    let world = cornell_classic();
    let scene = RenderScene::new(&world);
    let cam = propsim::render::scene_camera(&world, 1.5).unwrap();
    let mut s = RenderSettings {
        width: 45,
        height: 30,
        spp: 2,
        integrator: IntegratorKind::Radiosity,
        seed: 42,
        ..RenderSettings::default()
    };
    s.radiosity.patches = 512;
    let bits = |f: &Film| f.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<u32>>();
    let run = |threads: usize, s: &RenderSettings| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| go(&scene, &cam, s))
    };
    let (one, two) = (run(1, &s), run(2, &s));
    assert_eq!(bits(&one), bits(&two));
    assert!(one.mean().min_element() > 0.0);
    let other = run(2, &RenderSettings { seed: 43, ..s.clone() });
    assert_ne!(bits(&one), bits(&other));
}

/// A patch budget too small for the refinement is one error line naming the flag; so are bad
/// options and scenes radiosity cannot patch.
#[test]
fn radiosity_bad_input_is_one_line() {
    let world = cornell_classic();
    let scene = RenderScene::new(&world);
    let cam = propsim::render::scene_camera(&world, 1.0).unwrap();
    let mut s = settings(8, 1, 8, IntegratorKind::Radiosity, 0);
    s.radiosity.max_patches = 100;
    let err = render(&scene, &cam, &s, &|_| {}).unwrap_err();
    eprintln!("{err}");
    assert!(err.contains("--radiosity-max-patches") && !err.contains('\n'), "{err}");
    s.radiosity = RadiosityOptions { tolerance: -1.0, ..RadiosityOptions::default() };
    let err = render(&scene, &cam, &s, &|_| {}).unwrap_err();
    assert!(err.contains("--radiosity-tolerance") && !err.contains('\n'), "{err}");
    let mut mesh = TriangleMesh::default();
    let id = mesh.surface_id("ball");
    let spheres = vec![propsim::core::Sphere::new(Vec3::ZERO, 1.0, id)];
    let accel = Accel::build(&mesh, spheres.clone(), BuildQuality::default());
    let optics = vec![propsim::render::SurfaceOptics::diffuse(Vec3::splat(0.5))];
    let balls = RenderScene::from_parts(&accel, &mesh, &spheres, optics, &[], Vec3::ZERO);
    let err = render(&balls, &cam, &settings(8, 1, 8, IntegratorKind::Radiosity, 0), &|_| {}).unwrap_err();
    assert!(err.contains("spheres") && !err.contains('\n'), "{err}");
}
