//! The spectral integrator against closed forms and against the RGB path tracer where the two
//! must agree (compared statistically, never against a stored image), the prism's deviation
//! per wavelength against Snell's law, and determinism across thread counts.

mod common;

use std::f64::consts::PI;

use common::render::{go, pooled_regions, settings, with_glass_and_metal_balls, worst_welch_t as worst_t};
use glam::Vec3;
use propsim::core::{Accel, BuildQuality, Ray, Sphere, TriangleMesh};
use propsim::render::{
    Bsdf, Camera, Film, Frame, IntegratorKind, RenderScene, RenderSettings, SurfaceOptics,
};
use propsim::scene::dispersion::Dispersion;
use propsim::scene::{self, LoadOptions, World};

fn cornell() -> World {
    World::build(scene::load("builtin:cornell_box_classic".as_ref(), &LoadOptions::default()).unwrap())
}

fn bits(f: &Film) -> Vec<u32> {
    f.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect()
}

/// The white furnace: a closed box of grey albedo `r` emitting white `le` inwards converges
/// to `le / (1 - r)` in every channel with the spectral integrator too (white is D65 there,
/// whose RGB is (1, 1, 1)).
#[test]
fn spectral_white_furnace_converges_to_le_over_one_minus_r() {
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
        let film = go(&scene, &cam, &settings(24, 32, 200, IntegratorKind::Spectral, 1));
        let mean = film.mean();
        eprintln!("spectral white furnace r {r}, Le {le}: mean {mean}, expected {expect}");
        // 24*24*32 = 18k paths, the wavelengths stratified per pixel: 1 % is several sigma.
        assert!(
            (mean - Vec3::splat(expect)).abs().max_element() < 0.01 * expect,
            "r {r}: {mean} vs {expect}"
        );
        assert!(film.pixels.iter().all(|p| p.is_finite() && p.min_element() > 0.0));
    }
}

/// Per 4 x 4 region and channel of a 16 x 16 image: the mean over 12 renders of different
/// seeds, and the variance of that mean.
fn pooled(
    scene: &RenderScene,
    cam: &Camera,
    integrator: IntegratorKind,
    spp: u32,
    depth: u32,
    seed: u64,
) -> Vec<(f64, f64)> {
    let films: Vec<_> =
        (0..12u64).map(|k| go(scene, cam, &settings(16, spp, depth, integrator, seed + 1000 * k))).collect();
    pooled_regions(&films, 16, 4, true)
}

/// The Cornell box's optics with its light made white, and with `grey` every surface grey
/// Lambert of albedo `albedo`.
fn grey_cornell(world: &World, albedo: f32, grey: bool) -> Vec<SurfaceOptics> {
    world
        .scene
        .surfaces
        .iter()
        .map(SurfaceOptics::from_surface)
        .map(|o| {
            let emission = if o.emission == Vec3::ZERO { Vec3::ZERO } else { Vec3::splat(12.0) };
            let bsdf = if grey { Bsdf::Lambert { albedo: Vec3::splat(albedo) } } else { o.bsdf };
            SurfaceOptics { bsdf, emission }
        })
        .collect()
}

/// Grey surfaces (Lambert walls, a clear glass ball, a grey metal ball) under white light:
/// products of flat spectra are flat, so the spectral render
/// must match the RGB one statistically in every region and channel, through all bounces
/// (16 regions x 3 channels, 11 degrees of freedom: |t| > 6 has a chance of about 1e-4 each).
/// An albedo 10 % higher must be told apart (the test can fail).
#[test]
fn grey_scene_spectral_matches_the_rgb_path_tracer() {
    let world = cornell();
    // A clear glass ball (no dispersion) and a grey rough metal ball on the floor.
    let mut mesh = world.scene.mesh.clone();
    let glass = mesh.surface_id("clear_glass");
    let metal = mesh.surface_id("grey_metal");
    let spheres = vec![
        Sphere::new(Vec3::new(0.2, 0.2, 0.43), 0.08, glass),
        Sphere::new(Vec3::new(0.4, 0.3, 0.25), 0.08, metal),
    ];
    let accel = Accel::build(&mesh, spheres.clone(), BuildQuality::default());
    let cam = propsim::render::scene_camera(&world, 1.0).unwrap();
    let scene_of = |albedo: f32| {
        let mut optics = grey_cornell(&world, albedo, true);
        optics.push(SurfaceOptics {
            bsdf: Bsdf::Dielectric { eta: 1.5, tint: Vec3::ONE },
            emission: Vec3::ZERO,
        });
        optics.push(SurfaceOptics {
            bsdf: Bsdf::Metal { f0: Vec3::splat(0.8), alpha: 0.3 },
            emission: Vec3::ZERO,
        });
        RenderScene::from_parts(&accel, &mesh, &spheres, optics, &[], Vec3::ZERO)
    };
    let grey = scene_of(0.6);
    let rgb = pooled(&grey, &cam, IntegratorKind::Path, 64, 8, 1);
    let spectral = pooled(&grey, &cam, IntegratorKind::Spectral, 64, 8, 7);
    let t = worst_t(&spectral, &rgb);
    let (sum_s, sum_r): (f64, f64) =
        spectral.iter().zip(&rgb).fold((0.0, 0.0), |(a, b), (s, r)| (a + s.0, b + r.0));
    eprintln!(
        "grey Cornell box, spectral against path: worst |t| {t:.2}, image mean ratio {:.4}",
        sum_s / sum_r
    );
    assert!(t < 6.0, "spectral against path on grey surfaces: |t| {t}");
    let brighter = pooled(&scene_of(0.66), &cam, IntegratorKind::Spectral, 64, 8, 11);
    let wrong = worst_t(&brighter, &rgb);
    eprintln!("albedo 0.66 spectral against 0.6 path: worst |t| {wrong:.2}");
    assert!(wrong > 6.0, "a 10 % brighter albedo not told apart: |t| {wrong}");
}

/// Coloured walls under white light, direct light only: each pixel is one reflection of D65,
/// whose RGB is the wall's colour up to the up-sampling's round trip (under 1 %, tested in
/// `render::spectrum`), so spectral and RGB renders agree statistically per region and
/// channel. (Over several bounces they may not: a product of spectra is not the product of
/// their RGB colours.)
#[test]
fn coloured_direct_light_spectral_matches_the_rgb_path_tracer() {
    let world = cornell();
    let cam = propsim::render::scene_camera(&world, 1.0).unwrap();
    let optics = grey_cornell(&world, 0.0, false);
    let scene = RenderScene::from_parts(&world.accel, &world.scene.mesh, &[], optics, &[], Vec3::ZERO);
    let rgb = pooled(&scene, &cam, IntegratorKind::Path, 64, 1, 3);
    let spectral = pooled(&scene, &cam, IntegratorKind::Spectral, 64, 1, 5);
    let t = worst_t(&spectral, &rgb);
    eprintln!("coloured Cornell box, direct light, spectral against path: worst |t| {t:.2}");
    assert!(t < 6.0, "spectral against path, direct light on colours: |t| {t}");
}

/// The deviation of a ray through a 60-degree prism at incidence `theta1`, by Snell's law at
/// both faces (Hecht, Optics, sec. 5.5.1): `delta = theta1 + asin(n sin(A - asin(sin theta1 / n))) - A`.
fn snell_deviation(n: f64, theta1: f64, apex: f64) -> f64 {
    let t1 = (theta1.sin() / n).asin();
    let t2 = apex - t1;
    theta1 + (n * t2.sin()).asin() - apex
}

/// Rays of fixed wavelengths traced through the prism of rooms/prism with the renderer's
/// intersection and glass BSDF, at the index the scene's Sellmeier law gives: the exit
/// direction turns by Snell's two-face deviation, per wavelength; and blue turns more.
#[test]
fn prism_deviation_per_wavelength_follows_snell() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/rooms/prism/scene.toml");
    let world = World::build(scene::load(path.as_ref(), &LoadOptions::default()).unwrap());
    let scene = RenderScene::new(&world);
    let law: Dispersion = scene.dispersion.iter().flatten().copied().next().expect("the prism disperses");
    // The left face's outward normal and middle point (the prism is centred on the origin,
    // side 0.30 m, apex at +y), from the geometry written in prism.obj.
    let s = 0.30f64;
    let normal1 = (-(3f64.sqrt()) / 2.0, 0.5);
    let middle1 = (-s / 4.0, s * 3f64.sqrt() / 12.0);
    let mut previous = f64::NEG_INFINITY;
    for nm in [404.66, 486.13, 546.07, 587.56, 656.27, 706.52] {
        let n = law.index_at(nm);
        for theta1_deg in [60.0f64, 70.0, 80.0] {
            let theta1 = theta1_deg.to_radians();
            // Incoming direction: the inward normal (-normal1) turned by theta1 towards +y.
            let inward = (-normal1.0, -normal1.1);
            let (c, si) = (theta1.cos(), theta1.sin());
            let d = (inward.0 * c - inward.1 * si, inward.0 * si + inward.1 * c);
            let dir0 = Vec3::new(d.0 as f32, d.1 as f32, 0.0);
            let origin = Vec3::new((middle1.0 - d.0) as f32, (middle1.1 - d.1) as f32, 0.0);
            let mut ray = Ray::new(origin, dir0);
            let glass = Bsdf::Dielectric { eta: n as f32, tint: Vec3::ONE };
            for face in 0..2 {
                let hit = scene.intersect(&ray).unwrap_or_else(|| panic!("{nm} nm: face {face} missed"));
                let frame = Frame::new(hit.normal);
                let wo = frame.to_local(-ray.dir);
                // A lobe number of 1 - 1e-6 picks refraction unless the Fresnel reflectance is 1.
                let sample = glass.sample(wo, glam::Vec2::new(0.5, 0.5), 1.0 - 1e-6).expect("refracts");
                assert!(sample.wi.z * wo.z < 0.0, "{nm} nm, {theta1_deg} deg: reflected at face {face}");
                ray = Ray::spawn(hit.point, hit.normal, frame.to_world(sample.wi));
            }
            let turned = f64::from(dir0.angle_between(ray.dir));
            let expect = snell_deviation(n, theta1, PI / 3.0);
            eprintln!(
                "{nm} nm, n {n:.5}, incidence {theta1_deg} deg: deviation {:.4} deg, Snell {:.4} deg",
                turned.to_degrees(),
                expect.to_degrees()
            );
            assert!((turned - expect).abs() < 2e-4, "{nm} nm, {theta1_deg} deg: {turned} vs {expect}");
            if theta1_deg == 70.0 {
                // Wavelengths in increasing order: the deviation must fall (normal dispersion).
                assert!(
                    previous == f64::NEG_INFINITY || turned < previous,
                    "{nm} nm: {turned} >= {previous}"
                );
                previous = turned;
            }
        }
    }
}

/// Same seed, same image on one and two threads, through dispersive glass (the companions
/// dropped), a metal and coloured walls; another seed gives another image.
#[test]
fn spectral_same_seed_same_image_on_one_and_two_threads() {
    let world = cornell();
    let (mesh, optics, spheres) =
        with_glass_and_metal_balls(&world, ("flint", 1.6), ("gold", Vec3::new(0.9, 0.7, 0.3)));
    let glass = spheres[0].surface;
    let accel = Accel::build(&mesh, spheres.clone(), BuildQuality::default());
    let mut scene = RenderScene::from_parts(&accel, &mesh, &spheres, optics, &[], Vec3::ZERO);
    scene.dispersion = vec![None; scene.surfaces.len()];
    scene.dispersion[glass as usize] = Some(Dispersion::from_abbe(1.6, 30.0).unwrap());
    let cam = propsim::render::scene_camera(&world, 1.5).unwrap();
    let s = RenderSettings {
        width: 45,
        height: 30,
        spp: 6,
        max_depth: 8,
        integrator: IntegratorKind::Spectral,
        seed: 42,
        ..RenderSettings::default()
    };
    let run = |threads: usize| {
        let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
        pool.install(|| go(&scene, &cam, &s))
    };
    let one = run(1);
    assert_eq!(bits(&one), bits(&run(2)));
    assert!(one.pixels.iter().all(|p| p.is_finite()) && one.mean().max_element() > 0.0);
    assert_ne!(bits(&one), bits(&go(&scene, &cam, &RenderSettings { seed: 43, ..s.clone() })));
}
