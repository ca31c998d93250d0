//! Renderer correctness on scenes with known answers, compared statistically (never against
//! a stored image), and determinism across thread counts.

mod common;

use common::render::{
    go, pooled_regions, settings, whole_image_t, with_glass_and_metal_balls, worst_welch_t,
};
use glam::Vec3;
use propsim::core::{Accel, BuildQuality, Sphere, TriangleMesh};
use propsim::render::medium::Medium;
use propsim::render::pssmlt::MltOptions;
use propsim::render::{Bsdf, Camera, Film, IntegratorKind, RenderScene, RenderSettings, SurfaceOptics};
use propsim::scene::{self, LoadOptions, World};

/// A closed box seen from inside: every wall has albedo `r` and emits `le` inwards.
/// Every pixel converges to `le / (1 - r)` (the white furnace), with every integrator
/// that is unbiased for it.
#[test]
fn white_furnace_converges_to_le_over_one_minus_r() {
    for (r, le) in [(0.5f32, 1.0f32), (0.8, 0.5)] {
        let mut mesh = TriangleMesh::default();
        let id = mesh.surface_id("wall");
        mesh.push_box(Vec3::ZERO, Vec3::new(2.0, 3.0, 1.5), 2, id);
        mesh.flip_winding();
        let accel = Accel::build(&mesh, vec![], BuildQuality::default());
        let optics =
            vec![SurfaceOptics { bsdf: Bsdf::Lambert { albedo: Vec3::splat(r) }, emission: Vec3::splat(le) }];
        let scene = RenderScene::from_parts(&accel, &mesh, &[], optics, &[], Vec3::ZERO);
        let cam =
            Camera::look_at(Vec3::new(1.0, 0.5, 0.7), Vec3::new(1.2, 3.0, 0.9), Vec3::Z, 90.0, 1.0).unwrap();
        let expect = le / (1.0 - r);
        // Path tracing, and the integrators that trace from the lights too.
        // (vcm's merges are biased, but not in a furnace: the light is the same everywhere.)
        for integrator in
            [IntegratorKind::Path, IntegratorKind::Light, IntegratorKind::Bdpt, IntegratorKind::Vcm]
        {
            let film = go(&scene, &cam, &settings(24, 32, 200, integrator, 1));
            let mean = film.mean();
            eprintln!("white furnace r {r}, Le {le}, {integrator:?}: mean {mean}, expected {expect}");
            // 24*24*32 = 18k paths; the per-path spread is about the mean, so 1 % is > 5 sigma.
            assert!(
                (mean - Vec3::splat(expect)).abs().max_element() < 0.01 * expect,
                "{integrator:?} r {r}: {mean} vs {expect}"
            );
            assert!(film.pixels.iter().all(|p| p.is_finite() && p.min_element() > 0.0));
        }
        // Metropolis light transport: its image is scaled by a bootstrap estimate of the
        // luminance integral (here 10,000 samples a depth); the chains spread the same
        // number of mutations as the others' paths, so the tolerance is the same 1 %.
        {
            let mut s = settings(24, 32, 200, IntegratorKind::Pssmlt, 1);
            s.mlt.bootstrap = 10_000;
            let film = go(&scene, &cam, &s);
            let mean = film.mean();
            eprintln!("white furnace r {r}, Le {le}, Pssmlt: mean {mean}, expected {expect}");
            assert!((mean - Vec3::splat(expect)).abs().max_element() < 0.01 * expect, "Pssmlt r {r}: {mean}");
            assert!(film.pixels.iter().all(|p| p.is_finite()));
        }
        // The photon mappers are biased: a visible point within its radius r of an edge of
        // the box gathers photons of the neighbouring wall, whose arrival directions half
        // miss its hemisphere, so about 1/4 of its indirect light is lost there. Radius 2 cm
        // on walls of 1.5 to 3 m puts at most 2 x 2 x 2 cm / 1.5 m = 5 % of the pixels in
        // such bands before the radius shrinks: at most 1.3 % of the indirect light (which
        // is r of the total), and it falls with every iteration; measured +0.45 %, -0.04 %
        // (r 0.5) and +0.10 %, +0.27 % (r 0.8) for sppm and ppm, unchanged from radius
        // 5 mm to 8 cm. Tolerance 2 %.
        for integrator in [IntegratorKind::Sppm, IntegratorKind::Ppm] {
            let mut s = settings(24, 32, 200, integrator, 1);
            s.photons.photons_per_iteration = Some(40_000);
            s.photons.initial_radius_m = Some(0.02);
            let film = go(&scene, &cam, &s);
            let mean = film.mean();
            eprintln!("white furnace r {r}, Le {le}, {integrator:?}: mean {mean}, expected {expect}");
            assert!(
                (mean - Vec3::splat(expect)).abs().max_element() < 0.02 * expect,
                "{integrator:?} r {r}: {mean} vs {expect}"
            );
            assert!(film.pixels.iter().all(|p| p.is_finite() && p.min_element() > 0.0));
        }
    }
}

/// A closed box whose two end walls are perfect mirrors (reflectance 1, not emitting) and
/// whose other walls have albedo `r` and emit `le`: the radiance is `le / (1 - r)` everywhere
/// (on a mirror `L = 0 + 1 L` holds for any `L`). The camera looks into a mirror, so some of
/// the light arrives by paths that no join makes (`E S D S L`, a diffuse wall between mirror
/// bounces), which `bdpt` takes apart from its joins in such pixels: the furnace fails if that
/// light is lost or counted twice.
#[test]
fn a_furnace_between_facing_mirrors_converges_to_le_over_one_minus_r() {
    let (r, le) = (0.5f32, 1.0f32);
    let mut mesh = TriangleMesh::default();
    let wall = mesh.surface_id("wall");
    let mirror = mesh.surface_id("mirror");
    mesh.push_box(Vec3::ZERO, Vec3::new(2.0, 3.0, 1.5), 1, wall);
    mesh.flip_winding();
    // push_box's faces come as z = 0, z = max, y = 0, y = max, x = 0, x = max, two triangles
    // each: the y walls become the mirrors.
    mesh.surface_of_triangle[4..8].fill(mirror);
    let accel = Accel::build(&mesh, vec![], BuildQuality::default());
    let optics = vec![
        SurfaceOptics { bsdf: Bsdf::Lambert { albedo: Vec3::splat(r) }, emission: Vec3::splat(le) },
        SurfaceOptics { bsdf: Bsdf::Metal { f0: Vec3::ONE, alpha: 0.0 }, emission: Vec3::ZERO },
    ];
    let scene = RenderScene::from_parts(&accel, &mesh, &[], optics, &[], Vec3::ZERO);
    // Every pixel sees the mirror at y = 3 (1 m away, 60 degrees across; the mirror spans
    // 90 x 74 degrees from here).
    let cam =
        Camera::look_at(Vec3::new(1.0, 2.0, 0.75), Vec3::new(1.0, 3.0, 0.75), Vec3::Z, 60.0, 1.0).unwrap();
    let expect = le / (1.0 - r);
    for integrator in [IntegratorKind::Path, IntegratorKind::Bdpt, IntegratorKind::Vcm] {
        let film = go(&scene, &cam, &settings(24, 32, 200, integrator, 1));
        let mean = film.mean();
        eprintln!("furnace between mirrors, {integrator:?}: mean {mean}, expected {expect}");
        // As in the white furnace: 18k paths, the per-path spread about the mean, 1 % > 5 sigma.
        assert!((mean - Vec3::splat(expect)).abs().max_element() < 0.01 * expect, "{integrator:?}: {mean}");
        assert!(film.pixels.iter().all(|p| p.is_finite() && p.min_element() > 0.0));
    }
}

/// A diffuse sphere lit by one point light, alone against black: each pixel fully on the
/// sphere equals `rho / pi * I cos / d^2` at the surface point it sees.
#[test]
fn point_lit_lambert_sphere_matches_closed_form() {
    let rho = 0.6f32;
    let intensity = 5.0f32;
    let light = Vec3::new(2.0, -3.0, 4.0);
    let mut mesh = TriangleMesh::default();
    let id = mesh.surface_id("ball");
    let spheres = vec![Sphere::new(Vec3::ZERO, 1.0, id)];
    let accel = Accel::build(&mesh, spheres.clone(), BuildQuality::default());
    let optics = vec![SurfaceOptics::diffuse(Vec3::splat(rho))];
    let scene = RenderScene::from_parts(
        &accel,
        &mesh,
        &spheres,
        optics,
        &[(light, Vec3::splat(intensity))],
        Vec3::ZERO,
    );
    let eye = Vec3::new(0.0, -4.0, 0.5);
    let w = 48;
    let cam = Camera::look_at(eye, Vec3::ZERO, Vec3::Z, 35.0, 1.0).unwrap();
    let expected = |film: glam::Vec2| -> Option<f32> {
        let ray = cam.ray(film, glam::Vec2::ZERO);
        let (t, n, _) = spheres[0].intersect(&ray)?;
        let p = ray.at(t);
        let to = light - p;
        let cos = n.dot(to.normalize()).max(0.0);
        Some(rho / std::f32::consts::PI * intensity * cos / to.length_squared())
    };
    for integrator in [IntegratorKind::Path, IntegratorKind::Whitted, IntegratorKind::Distributed] {
        let film = go(&scene, &cam, &settings(w, 16, 4, integrator, 2));
        let mut checked = 0;
        let mut worst = 0.0f32;
        for y in 0..w {
            for x in 0..w {
                let corners = [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0), (1.0, 1.0), (0.5, 0.5)].map(|(dx, dy)| {
                    expected(glam::Vec2::new((x as f32 + dx) / w as f32, (y as f32 + dy) / w as f32))
                });
                let Some(vals) = corners.iter().copied().collect::<Option<Vec<f32>>>() else { continue };
                // Only pixels fully on the sphere with smooth shading across the footprint.
                let centre = vals[4];
                if vals.iter().any(|v| (v - centre).abs() > 0.1 * centre.max(1e-3)) {
                    continue;
                }
                let got = film.get(x, y);
                assert!((got.x - got.z).abs() < 1e-5, "grey stays grey");
                assert!(
                    (got.x - centre).abs() <= 0.01 * centre + 2e-4,
                    "{integrator:?} pixel {x},{y}: {} vs {centre}",
                    got.x
                );
                worst = worst.max((got.x - centre).abs() / centre.max(1e-3));
                checked += 1;
            }
        }
        eprintln!("Lambert sphere, {integrator:?}: {checked} pixels, largest relative error {worst:.4}");
        assert!(checked > 300, "{checked} pixels checked");
    }
}

/// A diffuse floor with a diffuse sphere: lit by a point light, `whitted`, `distributed` and
/// `path` (max depth 1) compute the same direct lighting; with an area light, `distributed`
/// and `path` agree within their noise.
#[test]
fn integrators_agree_on_direct_light() {
    let mut mesh = TriangleMesh::default();
    let floor = mesh.surface_id("floor");
    let ball = mesh.surface_id("ball");
    let lamp = mesh.surface_id("lamp");
    let s = 3.0;
    mesh.push_quad(
        Vec3::new(-s, -s, 0.0),
        Vec3::new(s, -s, 0.0),
        Vec3::new(s, s, 0.0),
        Vec3::new(-s, s, 0.0),
        floor,
    );
    let spheres = vec![Sphere::new(Vec3::new(0.0, 0.0, 0.7), 0.7, ball)];
    let cam =
        Camera::look_at(Vec3::new(0.5, -5.0, 2.5), Vec3::new(0.0, 0.0, 0.5), Vec3::Z, 40.0, 1.0).unwrap();
    let base = vec![
        SurfaceOptics::diffuse(Vec3::new(0.7, 0.6, 0.5)),
        SurfaceOptics::diffuse(Vec3::new(0.2, 0.5, 0.8)),
        SurfaceOptics { bsdf: Bsdf::Lambert { albedo: Vec3::ZERO }, emission: Vec3::splat(8.0) },
    ];
    let w = 40;
    // Point light.
    let accel = Accel::build(&mesh, spheres.clone(), BuildQuality::default());
    let scene = RenderScene::from_parts(
        &accel,
        &mesh,
        &spheres,
        base.clone(),
        &[(Vec3::new(1.5, -1.0, 3.0), Vec3::splat(10.0))],
        Vec3::ZERO,
    );
    let whitted = go(&scene, &cam, &settings(w, 16, 1, IntegratorKind::Whitted, 3));
    let dist = go(&scene, &cam, &settings(w, 16, 1, IntegratorKind::Distributed, 4));
    let path = go(&scene, &cam, &settings(w, 16, 1, IntegratorKind::Path, 5));
    for (name, img) in [("distributed", &dist), ("path", &path)] {
        let (a, b) = (whitted.mean(), img.mean());
        assert!((a - b).abs().max_element() < 0.01 * a.max_element(), "{name} mean {b} vs whitted {a}");
        // Away from silhouettes (where jittered and regular pixel samples cover differently)
        // the pixels agree; count the pixels that differ by more than 2 %.
        let off = whitted
            .pixels
            .iter()
            .zip(&img.pixels)
            .filter(|(p, q)| (**p - **q).abs().max_element() > 0.02 * p.max_element() + 1e-3)
            .count();
        eprintln!("point light: {name} mean {b} vs whitted {a}, {off} of {} pixels differ by > 2 %", w * w);
        assert!(off < whitted.pixels.len() / 10, "{name}: {off} pixels differ");
    }
    // Area light: a square lamp above the scene, facing down.
    let mut mesh2 = mesh.clone();
    let (a, b, c, d) = (
        Vec3::new(-0.5, -0.5, 3.0),
        Vec3::new(-0.5, 0.5, 3.0),
        Vec3::new(0.5, 0.5, 3.0),
        Vec3::new(0.5, -0.5, 3.0),
    );
    mesh2.push_quad(a, b, c, d, lamp);
    let accel2 = Accel::build(&mesh2, spheres.clone(), BuildQuality::default());
    let scene2 = RenderScene::from_parts(&accel2, &mesh2, &spheres, base, &[], Vec3::ZERO);
    let dist = go(&scene2, &cam, &settings(w, 64, 1, IntegratorKind::Distributed, 6));
    let path = go(&scene2, &cam, &settings(w, 64, 1, IntegratorKind::Path, 7));
    let (a, b) = (dist.mean(), path.mean());
    eprintln!("area light: distributed mean {a} vs path {b}");
    assert!((a - b).abs().max_element() < 0.015 * a.max_element(), "area light: distributed {a} vs path {b}");
}

/// Whitted on spheres against a uniform background `B`, closed-form answers: a perfect
/// mirror (f0 = 1) shows `B` everywhere; with depth 0 it is black (the recursion stops); a
/// clear glass ball shows `B` too, up to what the depth cuts off, because the Fresnel weights
/// of reflection and refraction sum to one, the `1/eta^2` radiance scaling on entry cancels
/// on exit and total internal reflection loses nothing.
#[test]
fn whitted_mirror_and_glass_spheres_return_the_background() {
    let background = Vec3::new(0.3, 0.5, 0.7);
    let mut mesh = TriangleMesh::default();
    let id = mesh.surface_id("ball");
    let spheres = vec![Sphere::new(Vec3::ZERO, 1.0, id)];
    let accel = Accel::build(&mesh, spheres.clone(), BuildQuality::default());
    let cam = Camera::look_at(Vec3::new(0.0, -4.0, 0.0), Vec3::ZERO, Vec3::Z, 35.0, 1.0).unwrap();
    let w = 32;
    // Pixels whose centre ray hits the ball.
    let on_ball: Vec<(u32, u32)> = (0..w * w)
        .map(|k| (k % w, k / w))
        .filter(|&(x, y)| {
            let film = glam::Vec2::new((x as f32 + 0.5) / w as f32, (y as f32 + 0.5) / w as f32);
            spheres[0].intersect(&cam.ray(film, glam::Vec2::ZERO)).is_some()
        })
        .collect();
    assert!(on_ball.len() > 200);
    let whitted = |bsdf: Bsdf, depth: u32| {
        let optics = vec![SurfaceOptics { bsdf, emission: Vec3::ZERO }];
        let scene = RenderScene::from_parts(&accel, &mesh, &spheres, optics, &[], background);
        go(&scene, &cam, &settings(w, 1, depth, IntegratorKind::Whitted, 0))
    };
    let mirror = whitted(Bsdf::Metal { f0: Vec3::ONE, alpha: 0.0 }, 8);
    let glass = whitted(Bsdf::Dielectric { eta: 1.5, tint: Vec3::ONE }, 40);
    let cut = whitted(Bsdf::Metal { f0: Vec3::ONE, alpha: 0.0 }, 0);
    let mut worst = [0.0f32; 2];
    for &(x, y) in &on_ball {
        // Border pixels mix ball and background at 1 spp, which changes nothing here.
        for (k, film) in [&mirror, &glass].into_iter().enumerate() {
            worst[k] = worst[k].max(((film.get(x, y) - background) / background).abs().max_element());
        }
        assert_eq!(cut.get(x, y), Vec3::ZERO, "pixel {x},{y} at depth 0");
    }
    eprintln!(
        "Whitted against background {background}: mirror largest relative error {:.2e}, glass {:.2e} ({} pixels)",
        worst[0],
        worst[1],
        on_ball.len()
    );
    assert!(worst[0] < 1e-5, "mirror: {}", worst[0]);
    assert!(worst[1] < 0.01, "glass: {}", worst[1]);
}

fn cornell() -> World {
    World::build(scene::load("builtin:cornell_box_classic".as_ref(), &LoadOptions::default()).unwrap())
}

fn rmse(a: &Film, b: &Film) -> f64 {
    let s: f64 = a.pixels.iter().zip(&b.pixels).map(|(p, q)| f64::from((*p - *q).length_squared())).sum();
    (s / a.pixels.len() as f64).sqrt()
}

/// Monte Carlo error falls at least as 1/sqrt(spp): 4x the samples, at least about half the
/// RMSE (stratified Sobol samples do better). The RMSE is pooled over four seeds, because at
/// this size a handful of pixels on the light's edge carry much of the error of one image.
#[test]
fn rmse_falls_by_about_two_from_16_to_64_spp() {
    let world = cornell();
    let scene = RenderScene::new(&world);
    let cam = propsim::render::scene_camera(&world, 1.0).unwrap();
    let w = 48;
    let reference = go(&scene, &cam, &settings(w, 2048, 8, IntegratorKind::Path, 100));
    let pooled = |spp: u32| {
        let mse: f64 = (1..=4)
            .map(|seed| {
                rmse(&go(&scene, &cam, &settings(w, spp, 8, IntegratorKind::Path, seed)), &reference).powi(2)
            })
            .sum();
        (mse / 4.0).sqrt()
    };
    let (e16, e64) = (pooled(16), pooled(64));
    eprintln!("Cornell box RMSE: 16 spp {e16:.5}, 64 spp {e64:.5}, ratio {:.3}", e16 / e64);
    assert!(e16 / e64 >= 1.8, "RMSE 16 spp {e16}, 64 spp {e64}: ratio {}", e16 / e64);
}

/// The same seed gives bit-identical images on 1 and 2 threads, for every integrator, on a
/// scene with glass, metal, an area light and depth of field.
#[test]
fn same_seed_same_image_on_one_and_two_threads() {
    let world = cornell();
    let (mesh, optics, spheres) =
        with_glass_and_metal_balls(&world, ("glass", 1.5), ("metal", Vec3::new(0.9, 0.8, 0.5)));
    let accel = Accel::build(&mesh, spheres.clone(), BuildQuality::default());
    let scene = RenderScene::from_parts(&accel, &mesh, &spheres, optics, &[], Vec3::ZERO);
    let mut cam = propsim::render::scene_camera(&world, 1.5).unwrap();
    cam.set_lens(0.01, Some(1.0)).unwrap();
    // (The integrators that trace from the lights sum their splats and photon deposits in
    // fixed point, so the order in which threads add them does not matter either.)
    for integrator in [
        IntegratorKind::Raycast,
        IntegratorKind::Whitted,
        IntegratorKind::Distributed,
        IntegratorKind::Path,
        IntegratorKind::Light,
        IntegratorKind::Bdpt,
        IntegratorKind::Sppm,
        IntegratorKind::Ppm,
        IntegratorKind::Pssmlt,
        IntegratorKind::Volpath,
        IntegratorKind::Raymarch,
        IntegratorKind::Vcm,
    ] {
        let s = RenderSettings {
            // (Only volpath and raymarch see the fog.)
            fog: Some(Medium {
                sigma_a_per_m: Vec3::splat(0.1),
                sigma_s_per_m: Vec3::new(0.5, 0.8, 1.1),
                g: 0.3,
            }),
            width: 45,
            height: 30,
            spp: 6,
            max_depth: 8,
            integrator,
            seed: 42,
            // pssmlt: fewer bootstrap samples and chains than the defaults, for speed.
            mlt: MltOptions { bootstrap: 4000, chains: 64, ..MltOptions::default() },
            ..RenderSettings::default()
        };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| go(&scene, &cam, &s))
        };
        let (one, two) = (run(1), run(2));
        let bits =
            |f: &Film| f.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<u32>>();
        assert_eq!(bits(&one), bits(&two), "{integrator:?}");
        assert!(one.pixels.iter().all(|p| p.is_finite()));
        assert!(one.mean().max_element() > 0.0);
        // A different seed gives a different (stochastic) image.
        if !matches!(integrator, IntegratorKind::Raycast | IntegratorKind::Whitted) {
            let other = go(&scene, &cam, &RenderSettings { seed: 43, ..s.clone() });
            assert_ne!(bits(&one), bits(&other), "{integrator:?}");
        }
    }
    // The plain Cornell box takes the eight-lane path tracer; the same holds there.
    let plain = RenderScene::new(&world);
    let s =
        RenderSettings { width: 45, height: 30, spp: 6, max_depth: 8, seed: 42, ..RenderSettings::default() };
    assert!(propsim::render::lanes::applies(&plain, &s));
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| go(&plain, &cam, &s))
    };
    let bits = |f: &Film| f.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<u32>>();
    assert_eq!(bits(&run(1)), bits(&run(2)));
}

/// Volumetric path tracing: a white furnace filled with a fog that only scatters (albedo 1,
/// forward-scattering) still converges to `le / (1 - r)`, since a medium in equilibrium with
/// an isotropic radiance field changes nothing; and an emitter seen through a fog that only
/// absorbs is dimmed by Beer-Lambert's `exp(-sigma_a d)`, per channel.
#[test]
fn volpath_keeps_the_furnace_and_follows_beer_lambert() {
    let (r, le) = (0.6f32, 1.0f32);
    let mut mesh = TriangleMesh::default();
    let id = mesh.surface_id("wall");
    mesh.push_box(Vec3::ZERO, Vec3::new(2.0, 3.0, 1.5), 2, id);
    mesh.flip_winding();
    let accel = Accel::build(&mesh, vec![], BuildQuality::default());
    let optics =
        vec![SurfaceOptics { bsdf: Bsdf::Lambert { albedo: Vec3::splat(r) }, emission: Vec3::splat(le) }];
    let scene = RenderScene::from_parts(&accel, &mesh, &[], optics, &[], Vec3::ZERO);
    let cam =
        Camera::look_at(Vec3::new(1.0, 0.5, 0.7), Vec3::new(1.2, 3.0, 0.9), Vec3::Z, 90.0, 1.0).unwrap();
    let expect = le / (1.0 - r);
    // Mean free paths of 0.8 to 1.25 m in a room of 1.5 to 3 m: most paths scatter in the
    // fog. (Fogs whose channels differ several-fold converge too, but slowly: the weights of
    // the per-flight spectral MIS multiply along a path, see docs/render.md.)
    let fog = Medium { sigma_a_per_m: Vec3::ZERO, sigma_s_per_m: Vec3::new(0.8, 1.0, 1.25), g: 0.5 };
    let mut s = settings(24, 32, 400, IntegratorKind::Volpath, 1);
    s.fog = Some(fog);
    let mean = go(&scene, &cam, &s).mean();
    eprintln!("volpath furnace in fog: mean {mean}, expected {expect}");
    assert!((mean - Vec3::splat(expect)).abs().max_element() < 0.015 * expect, "{mean} vs {expect}");
    // The test can fail: the same fog absorbing a tenth of what it scatters darkens it.
    s.fog = Some(Medium { sigma_a_per_m: fog.sigma_s_per_m * 0.1, ..fog });
    let darker = go(&scene, &cam, &s).mean();
    assert!(darker.max_element() < 0.9 * expect, "absorbing fog: {darker}");

    // An emissive wall 2 m ahead, seen through a 1-degree view: every camera ray crosses
    // 2 m of fog (to 1.5e-4), so each pixel tends to Le exp(-sigma_a 2 m).
    let mut wall = TriangleMesh::default();
    let id = wall.surface_id("emitter");
    wall.push_quad(
        Vec3::new(1.0, 2.0, -1.0),
        Vec3::new(1.0, 2.0, 1.0),
        Vec3::new(-1.0, 2.0, 1.0),
        Vec3::new(-1.0, 2.0, -1.0),
        id,
    );
    let accel = Accel::build(&wall, vec![], BuildQuality::default());
    let le = Vec3::new(1.0, 2.0, 3.0);
    let optics = vec![SurfaceOptics { bsdf: Bsdf::Lambert { albedo: Vec3::ZERO }, emission: le }];
    let scene = RenderScene::from_parts(&accel, &wall, &[], optics, &[], Vec3::ZERO);
    let cam = Camera::look_at(Vec3::ZERO, Vec3::new(0.0, 1.0, 0.0), Vec3::Z, 1.0, 1.0).unwrap();
    let sigma_a = Vec3::new(0.2, 0.5, 1.0);
    let mut s = settings(16, 256, 4, IntegratorKind::Volpath, 3);
    s.fog = Some(Medium { sigma_a_per_m: sigma_a, sigma_s_per_m: Vec3::ZERO, g: 0.0 });
    let film = go(&scene, &cam, &s);
    let mean = film.mean();
    let beer = le * (-sigma_a * 2.0).exp();
    eprintln!("volpath through absorbing fog: {mean} vs Beer-Lambert {beer}");
    // 65,536 flights, each reaching the wall with probability >= exp(-2): 1.5 % is > 4 sigma.
    for c in 0..3 {
        assert!((mean[c] / beer[c] - 1.0).abs() < 0.015, "channel {c}: {mean} vs {beer}");
    }
}

/// Ray marching against volumetric path tracing: the Cornell box in a thin fog (optical depth
/// about 0.3 across the box), direct light only (`max_depth` 1, where both estimate exactly
/// single scattering from the lights plus the surfaces' direct light, and the background is
/// black). Each 4 x 4-pixel region's mean over 16 independent runs (volpath 256 spp,
/// raymarch 64) agrees by Welch's t at a
/// Bonferroni-corrected alpha of 0.001 over the 16 regions (|t| < 5.5 at 15 degrees of
/// freedom, as in tests/shape_emitters.rs). The test can fail: raymarch in twice the
/// scattering is told apart.
#[test]
fn raymarch_and_volpath_agree_in_a_thin_fog() {
    let world = cornell();
    let scene = RenderScene::new(&world);
    let cam = propsim::render::scene_camera(&world, 1.0).unwrap();
    let fog = Medium { sigma_a_per_m: Vec3::splat(0.1), sigma_s_per_m: Vec3::new(0.3, 0.5, 0.7), g: 0.4 };
    let (w, runs, block) = (16u32, 16u64, 4usize);
    let pooled = |integrator: IntegratorKind, fog: Medium, spp: u32, seed: u64| {
        let films: Vec<_> = (0..runs)
            .map(|k| {
                let mut s = settings(w, spp, 1, integrator, seed + 1000 * k);
                s.fog = Some(fog);
                go(&scene, &cam, &s)
            })
            .collect();
        pooled_regions(&films, w as usize, block, false)
    };
    let worst_t = worst_welch_t;
    let reference = pooled(IntegratorKind::Volpath, fog, 256, 1);
    let marched = pooled(IntegratorKind::Raymarch, fog, 64, 5);
    // The whole image's mean too (its own test, at alpha 0.001: |t| < 4.1 at 15 dof).
    let (ratio, t_all) = whole_image_t(&marched, &reference);
    let worst = worst_t(&marched, &reference);
    eprintln!(
        "raymarch against volpath: worst |t| {worst:.2} over 16 regions; image mean ratio {ratio:.4}, |t| {t_all:.2}"
    );
    assert!(t_all < 4.1, "raymarch against volpath: image mean ratio {ratio}, |t| {t_all}");
    assert!(worst < 5.5, "raymarch against volpath: |t| {worst}");
    let thicker = Medium { sigma_s_per_m: fog.sigma_s_per_m * 2.0, ..fog };
    let wrong = worst_t(&pooled(IntegratorKind::Raymarch, thicker, 64, 9), &reference);
    eprintln!("raymarch in twice the scattering against volpath: worst |t| {wrong:.2}");
    assert!(wrong > 5.5, "twice the scattering not told apart: |t| {wrong}");
}
