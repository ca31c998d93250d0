//! Participating media (issue 26, point 2): density grids, delta tracking of free flights,
//! ratio tracking of transmittance, media inside closed meshes behind index-matched
//! boundaries, and the ray marcher against volumetric path tracing on rooms/smoke. Every
//! expected value is a closed form (Beer-Lambert, the collision estimator's totals, the
//! white furnace), never a number taken from the program.

mod common;

use std::sync::Arc;

use common::render::{go, pooled_regions, settings, whole_image_t, worst_welch_t};
use glam::Vec3;
use propsim::core::rng::stream;
use propsim::core::{Accel, BuildQuality, Ray, TriangleMesh};
use propsim::render::media::{SceneMedia, Volume};
use propsim::render::medium::Medium;
use propsim::render::sampler::Sampler;
use propsim::render::{Bsdf, Camera, Film, IntegratorKind, RenderScene, SurfaceOptics};
use propsim::scene::density_grid::DensityGrid;
use propsim::scene::{self, LoadOptions, World};

/// Eight voxels along x over `[0, 2] m`, densities `0.2 + 0.4 i`: along x the density is
/// `0.2 + 1.6 (clamp(x, 0.125, 1.875) - 0.125)` (linear between the first and last voxel
/// centres, constant in the half voxels at the faces).
fn ramp() -> DensityGrid {
    let values = (0..8).map(|i| 0.2 + 0.4 * i as f32).collect();
    DensityGrid::new([8, 1, 1], values, Vec3::ZERO, Vec3::new(2.0, 1.0, 1.0)).expect("valid grid")
}

/// `integral_0^x` of [`ramp`]'s density along x, in closed form.
fn ramp_integral(x: f64) -> f64 {
    let x = x.clamp(0.0, 2.0);
    let linear = if x <= 0.125 {
        0.0
    } else if x <= 1.875 {
        (x - 0.125).powi(2) / 2.0
    } else {
        1.75f64.powi(2) / 2.0 + 1.75 * (x - 1.875)
    };
    0.2 * x + 1.6 * linear
}

/// Runs `f` with `n` fresh samplers of one stream.
fn with_samplers(seed: u64, n: u32, mut f: impl FnMut(&mut Sampler)) {
    let mut rng = stream(seed, 7, 0);
    for k in 0..n {
        let mut s = Sampler::new(12345, k, false, &mut rng);
        f(&mut s);
    }
}

/// Mean and standard error of the mean of each channel.
fn mean_se(samples: &[Vec3]) -> (Vec3, Vec3) {
    let n = samples.len() as f32;
    let mean = samples.iter().copied().sum::<Vec3>() / n;
    let var = samples.iter().map(|s| (*s - mean) * (*s - mean)).sum::<Vec3>() / (n - 1.0);
    (mean, (var / n).map(f32::sqrt))
}

/// Ratio tracking through the ramp agrees with `exp(-sigma_t integral density)` per channel,
/// over the whole box and over a segment ending inside it, within 4 standard errors (each
/// under 5 % of the value; 400,000 estimates).
#[test]
fn ratio_tracking_follows_the_analytic_optical_depth_of_a_ramp() {
    let volume = Volume {
        medium: Medium {
            sigma_a_per_m: Vec3::new(0.3, 0.6, 1.2),
            sigma_s_per_m: Vec3::new(0.2, 0.4, 0.8),
            g: 0.0,
        },
        grid: Some(Arc::new(ramp())),
    };
    let sigma_t = volume.medium.sigma_t_per_m();
    let ray = Ray::new(Vec3::new(-1.0, 0.4, 0.6), Vec3::X);
    for (t_max, x_end, seed) in [(10.0f32, 2.0f64, 1u64), (2.0, 1.0, 11)] {
        let mut samples = Vec::new();
        with_samplers(seed, 400_000, |s| samples.push(volume.transmittance(&ray, t_max, s)));
        let (mean, se) = mean_se(&samples);
        let tau = ramp_integral(x_end) as f32;
        let expect = (-sigma_t * tau).exp();
        eprintln!("ratio tracking to x = {x_end}: {mean} +- {se} vs exp(-sigma_t {tau}) = {expect}");
        for c in 0..3 {
            assert!((mean[c] - expect[c]).abs() < 4.0 * se[c], "channel {c}: {mean} vs {expect}");
            // The standard error is small enough for the comparison to mean something.
            assert!(se[c] < 0.05 * expect[c], "channel {c}: standard error {se}");
        }
    }
    // The closed form itself, by hand: 0.2 x 1 + 1.6 x 0.875^2 / 2 to x = 1 (the mean
    // density over the box, 1.6, would give 1.6 there instead).
    assert!((ramp_integral(1.0) - 0.8125).abs() < 1e-12);
}

/// Delta tracking: in a constant grid (density 0.7 over 1.5 m) a flight reaches the far
/// side with weight expectation `exp(-k L)` per channel (`k = sigma_t density`), scatters
/// with expectation `sigma_s / sigma_t (1 - exp(-k L))`, and its scattering distance has the
/// first moment `sigma_s density (1 - exp(-k L)(1 + k L)) / k^2`; through the ramp, the
/// surface weight is `exp(-sigma_t integral density)` and the scattered total
/// `sigma_s / sigma_t (1 - that)` (the collision estimator, exact for any density profile).
#[test]
fn delta_tracking_reproduces_the_closed_form_flight_distribution() {
    let medium =
        Medium { sigma_a_per_m: Vec3::new(0.5, 0.0, 1.0), sigma_s_per_m: Vec3::new(0.5, 2.0, 0.2), g: 0.0 };
    let (sigma_s, sigma_t) = (medium.sigma_s_per_m, medium.sigma_t_per_m());
    let (density, length) = (0.7f32, 1.5f32);
    let constant =
        DensityGrid::new([1, 1, 1], vec![density], Vec3::ZERO, Vec3::new(length, 1.0, 1.0)).unwrap();
    let ray = Ray::new(Vec3::new(0.0, 0.5, 0.5), Vec3::X);
    for (grid, tau) in [(constant, density * length), (ramp(), ramp_integral(2.0) as f32)] {
        let constant_grid = grid.dims == [1, 1, 1];
        let volume = Volume { medium, grid: Some(Arc::new(grid)) };
        let (mut surface, mut scattered, mut moment) = (Vec::new(), Vec::new(), Vec::new());
        with_samplers(2, 200_000, |s| {
            let f = volume.sample_flight(&ray, 20.0, s);
            let (w_surface, w_scatter) =
                if f.scattered { (Vec3::ZERO, f.weight) } else { (f.weight, Vec3::ZERO) };
            surface.push(w_surface);
            scattered.push(w_scatter);
            moment.push(w_scatter * if f.scattered { f.t } else { 0.0 });
        });
        let beer = (-sigma_t * tau).exp();
        let scatter = sigma_s / sigma_t * (Vec3::ONE - beer);
        let ((ms, ses), (mc, sec), (mm, sem)) = (mean_se(&surface), mean_se(&scattered), mean_se(&moment));
        eprintln!("delta tracking, tau {tau}: surface {ms} vs {beer}; scattered {mc} vs {scatter}");
        for c in 0..3 {
            assert!((ms[c] - beer[c]).abs() < 4.0 * ses[c] + 1e-4, "surface, channel {c}: {ms} vs {beer}");
            assert!(
                (mc[c] - scatter[c]).abs() < 4.0 * sec[c] + 1e-4,
                "scattered, channel {c}: {mc} vs {scatter}"
            );
        }
        if constant_grid {
            let k = sigma_t * density;
            let first =
                sigma_s * density * (Vec3::ONE - (-k * length).exp() * (Vec3::ONE + k * length)) / (k * k);
            eprintln!("delta tracking, first moment of the scattering distance: {mm} vs {first}");
            for c in 0..3 {
                assert!(
                    (mm[c] - first[c]).abs() < 4.0 * sem[c] + 1e-4,
                    "moment, channel {c}: {mm} vs {first}"
                );
            }
        }
    }
}

/// A white furnace (walls of albedo 0.6 emitting 1) holding a purely scattering
/// heterogeneous medium (albedo 1, a 4 x 4 x 4 grid of densities 0 to 2 over most of the
/// room, g = 0.3) still converges to `Le / (1 - r)` = 2.5; the same medium absorbing a
/// fifth of what it scatters darkens it (the test can fail).
#[test]
fn a_furnace_filled_with_a_scattering_grid_returns_le_over_one_minus_r() {
    let (r, le) = (0.6f32, 1.0f32);
    let mut mesh = TriangleMesh::default();
    let id = mesh.surface_id("wall");
    mesh.push_box(Vec3::ZERO, Vec3::new(2.0, 3.0, 1.5), 2, id);
    mesh.flip_winding();
    let accel = Accel::build(&mesh, vec![], BuildQuality::default());
    let optics =
        vec![SurfaceOptics { bsdf: Bsdf::Lambert { albedo: Vec3::splat(r) }, emission: Vec3::splat(le) }];
    let mut scene = RenderScene::from_parts(&accel, &mesh, &[], optics, &[], Vec3::ZERO);
    let cam =
        Camera::look_at(Vec3::new(1.0, 0.5, 0.7), Vec3::new(1.2, 3.0, 0.9), Vec3::Z, 90.0, 1.0).unwrap();
    let values: Vec<f32> = (0..64).map(|i| ((i * 7) % 5) as f32 * 0.5).collect();
    let grid =
        DensityGrid::new([4, 4, 4], values, Vec3::new(0.2, 0.3, 0.1), Vec3::new(1.8, 2.7, 1.4)).unwrap();
    let medium = Medium { sigma_a_per_m: Vec3::ZERO, sigma_s_per_m: Vec3::new(0.8, 1.0, 1.25), g: 0.3 };
    let media = |medium: Medium| SceneMedia {
        volumes: vec![Volume { medium, grid: Some(Arc::new(grid.clone())) }],
        global: Some(0),
        inside: Vec::new(),
    };
    scene.media = media(medium);
    let s = settings(24, 32, 400, IntegratorKind::Volpath, 1);
    let expect = le / (1.0 - r);
    let mean = go(&scene, &cam, &s).mean();
    eprintln!("volpath furnace with a scattering grid: mean {mean}, expected {expect}");
    assert!((mean - Vec3::splat(expect)).abs().max_element() < 0.015 * expect, "{mean} vs {expect}");
    scene.media = media(Medium { sigma_a_per_m: medium.sigma_s_per_m * 0.2, ..medium });
    let darker = go(&scene, &cam, &s).mean();
    eprintln!("volpath furnace with an absorbing grid: mean {darker}");
    assert!(darker.max_element() < 0.95 * expect, "absorbing grid: {darker}");
}

/// A closed box `[-1, 1] x [1, 1.5] x [-1, 1]` (usemtl `slab`, normals out) between the
/// camera at the origin, looking along +y, and a wall at y = 3.
fn slab_obj(wall: &str) -> String {
    format!(
        "mtllib s.mtl
v -1 1 -1
v 1 1 -1
v 1 1.5 -1
v -1 1.5 -1
v -1 1 1
v 1 1 1
v 1 1.5 1
v -1 1.5 1
v -3 3 -3
v 3 3 -3
v 3 3 3
v -3 3 3
usemtl slab
f 1 4 3 2
f 5 6 7 8
f 1 2 6 5
f 2 3 7 6
f 3 4 8 7
f 4 1 5 8
usemtl {wall}
f 9 10 11 12
"
    )
}

const SLAB_MTL: &str =
    "newmtl slab\nKd 0.5 0.5 0.5\nnewmtl lamp\nKd 0 0 0\nKe 1 2 3\nnewmtl wall\nKd 0.8 0.8 0.8\n";

/// Loads a scene written into `dir`.
fn load(dir: &std::path::Path, obj: &str, toml: &str) -> World {
    std::fs::write(dir.join("s.obj"), obj).unwrap();
    std::fs::write(dir.join("s.mtl"), SLAB_MTL).unwrap();
    std::fs::write(dir.join("s.toml"), toml).unwrap();
    World::build(scene::load(&dir.join("s.toml"), &LoadOptions::default()).expect("scene loads"))
}

/// Media inside a closed mesh: an absorbing medium (sigma_a 0.4 / 1.0 / 2.0 per m) fills
/// the 0.5 m slab, whose faces are index-matched. An emitter (Le 1 / 2 / 3) seen through it
/// (a 1-degree view) gives `Le exp(-sigma_a 0.5 m)`; a white wall lit by a point light
/// behind the camera gives `rho / pi I / d^2 exp(-sigma_a 1 m)` (the camera ray and the
/// shadow ray each cross the slab once, so the shadow ray must pass the interfaces and take
/// the slab's transmittance), for a homogeneous medium and for a constant grid filling the
/// slab (ratio tracking); a camera inside the slab sees the emitter through its remaining
/// 0.25 m. With `interface = false` the slab's own opaque material hides the emitter (the
/// test can fail).
#[test]
fn a_medium_inside_a_closed_mesh_follows_beer_lambert() {
    let dir = tempfile::tempdir().unwrap();
    let sigma_a = Vec3::new(0.4, 1.0, 2.0);
    let cam = Camera::look_at(Vec3::ZERO, Vec3::Y, Vec3::Z, 1.0, 1.0).unwrap();
    let medium = "[[media]]\nname = \"glass_of_ink\"\nboundary = \"slab\"\nsigma_a = [0.4, 1.0, 2.0]\n";
    let grid = "grid = \"g.txt\"\nbounds_min = [-1, 1, -1]\nbounds_max = [1, 1.5, 1]\n";
    std::fs::write(dir.path().join("g.txt"), "1 1 1\n1.0\n").unwrap();
    for extra in ["", grid] {
        let toml = format!("obj = \"s.obj\"\n{medium}{extra}");
        let world = load(dir.path(), &slab_obj("lamp"), &toml);
        let scene = RenderScene::new(&world);
        let film = go(&scene, &cam, &settings(16, 256, 1, IntegratorKind::Volpath, 3));
        let le = Vec3::new(1.0, 2.0, 3.0);
        let expect = le * (-sigma_a * 0.5).exp();
        let mean = film.mean();
        eprintln!(
            "emitter through the slab{}: {mean} vs {expect}",
            if extra.is_empty() { "" } else { " (grid)" }
        );
        for c in 0..3 {
            assert!((mean[c] / expect[c] - 1.0).abs() < 0.015, "channel {c}: {mean} vs {expect}");
        }

        let lit = format!("{toml}[[lights]]\nposition = [0, -1, 0]\nintensity = [10, 10, 10]\n");
        let world = load(dir.path(), &slab_obj("wall"), &lit);
        let scene = RenderScene::new(&world);
        let film = go(&scene, &cam, &settings(16, 256, 1, IntegratorKind::Volpath, 4));
        // The wall point seen at the image centre is 4 m from the light, at normal incidence;
        // across the 1-degree view the irradiance varies by under 1e-4.
        let expect = Vec3::splat(0.8 / std::f32::consts::PI * 10.0 / 16.0) * (-sigma_a * 1.0).exp();
        let mean = film.mean();
        eprintln!("wall lit through the slab: {mean} vs {expect}");
        for c in 0..3 {
            assert!((mean[c] / expect[c] - 1.0).abs() < 0.015, "channel {c}: {mean} vs {expect}");
        }
    }
    // The camera inside the slab, 0.25 m from its far face: the medium around the eye is
    // found by the parity of the boundary faces, so the emitter is dimmed by exp(-sigma_a 0.25 m).
    let world = load(dir.path(), &slab_obj("lamp"), &format!("obj = \"s.obj\"\n{medium}"));
    let inside =
        Camera::look_at(Vec3::new(0.0, 1.25, 0.0), Vec3::new(0.0, 2.0, 0.0), Vec3::Z, 1.0, 1.0).unwrap();
    let mean =
        go(&RenderScene::new(&world), &inside, &settings(16, 256, 1, IntegratorKind::Volpath, 5)).mean();
    let expect = Vec3::new(1.0, 2.0, 3.0) * (-sigma_a * 0.25).exp();
    eprintln!("emitter seen from inside the slab: {mean} vs {expect}");
    for c in 0..3 {
        assert!((mean[c] / expect[c] - 1.0).abs() < 0.015, "channel {c}: {mean} vs {expect}");
    }
    let opaque = format!("obj = \"s.obj\"\n{medium}interface = false\n");
    let world = load(dir.path(), &slab_obj("lamp"), &opaque);
    let film = go(&RenderScene::new(&world), &cam, &settings(8, 16, 1, IntegratorKind::Volpath, 3));
    assert!(film.mean().max_element() < 1e-3, "an opaque boundary lets light through: {}", film.mean());
}

fn smoke() -> World {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/rooms/smoke/scene.toml");
    World::build(scene::load(path.as_ref(), &LoadOptions::default()).expect("rooms/smoke loads"))
}

/// Ray marching against volumetric path tracing in the heterogeneous smoke of rooms/smoke,
/// direct light only (`max_depth` 1, where both estimate single scattering from the lights
/// plus the surfaces' direct light): each 4 x 4-pixel region's mean over 16 independent runs
/// (volpath 256 spp, raymarch 32) agrees by Welch's t at a Bonferroni-corrected alpha of
/// 0.001 over the 16 regions (|t| < 5.5 at 15 degrees of freedom), and so does the whole
/// image's mean (|t| < 4.1). The march's transmittance is a trapezoid sum of the optical
/// depth (biased by the step), which this tolerates at the default step. The test can fail:
/// raymarch in twice the scattering is told apart.
#[test]
fn raymarch_and_volpath_agree_on_the_smoke_scene() {
    let world = smoke();
    let mut scene = RenderScene::new(&world);
    let cam = propsim::render::scene_camera(&world, 1.0).unwrap();
    let (w, runs, block) = (16u32, 16u64, 4usize);
    let pooled = |scene: &RenderScene, integrator: IntegratorKind, spp: u32, seed: u64| {
        let films: Vec<_> =
            (0..runs).map(|k| go(scene, &cam, &settings(w, spp, 1, integrator, seed + 1000 * k))).collect();
        pooled_regions(&films, w as usize, block, false)
    };
    let worst_t = worst_welch_t;
    let reference = pooled(&scene, IntegratorKind::Volpath, 256, 1);
    let marched = pooled(&scene, IntegratorKind::Raymarch, 32, 5);
    let (ratio, t_all) = whole_image_t(&marched, &reference);
    let worst = worst_t(&marched, &reference);
    eprintln!(
        "smoke, raymarch against volpath: worst |t| {worst:.2} over 16 regions; image mean ratio {ratio:.4}, |t| {t_all:.2}"
    );
    assert!(t_all < 4.1, "image mean ratio {ratio}, |t| {t_all}");
    assert!(worst < 5.5, "|t| {worst}");
    scene.media.volumes[0].medium.sigma_s_per_m *= 2.0;
    let wrong = worst_t(&pooled(&scene, IntegratorKind::Raymarch, 32, 9), &reference);
    eprintln!("smoke, raymarch in twice the scattering against volpath: worst |t| {wrong:.2}");
    assert!(wrong > 5.5, "twice the scattering not told apart: |t| {wrong}");
}

/// The same seed gives the same image, bit for bit, on one and two threads: rooms/smoke
/// with volpath (delta and ratio tracking) and raymarch, at full depth.
#[test]
fn smoke_renders_are_the_same_on_one_and_two_threads() {
    let world = smoke();
    let scene = RenderScene::new(&world);
    let cam = propsim::render::scene_camera(&world, 1.0).unwrap();
    for integrator in [IntegratorKind::Volpath, IntegratorKind::Raymarch] {
        let s = settings(24, 4, 16, integrator, 42);
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build().unwrap();
            pool.install(|| go(&scene, &cam, &s))
        };
        let bits =
            |f: &Film| f.pixels.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<u32>>();
        let (one, two) = (run(1), run(2));
        assert_eq!(bits(&one), bits(&two), "{integrator:?}");
        assert!(one.pixels.iter().all(|p| p.is_finite()) && one.mean().max_element() > 0.0);
    }
}

/// The jittered march is stratified sampling, unbiased for any step in a homogeneous
/// medium: `raymarch` with a coarse user step (`--raymarch-step 0.2`, three points across
/// the 0.55 m box) and volpath agree on the mean of rooms/fog at `max_depth` 1 (16 runs
/// each, Welch's t < 4.1, alpha 0.001); the coarse step only adds variance (and the test
/// checks that it does, so that the flag is seen to reach the march).
#[test]
fn a_coarse_raymarch_step_stays_unbiased_in_a_homogeneous_fog() {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/rooms/fog/scene.toml");
    let world = World::build(scene::load(path.as_ref(), &LoadOptions::default()).expect("rooms/fog loads"));
    let scene = RenderScene::new(&world);
    let cam = propsim::render::scene_camera(&world, 1.0).unwrap();
    let fog = Medium { sigma_a_per_m: Vec3::splat(0.1), sigma_s_per_m: Vec3::new(0.3, 0.5, 0.7), g: 0.4 };
    let stats = |integrator: IntegratorKind, step: Option<f32>, seed: u64| {
        let means: Vec<f64> = (0..16u64)
            .map(|k| {
                let mut s = settings(12, 16, 1, integrator, seed + 100 * k);
                s.fog = Some(fog);
                s.raymarch_step_m = step;
                f64::from(go(&scene, &cam, &s).mean().element_sum()) / 3.0
            })
            .collect();
        let m = means.iter().sum::<f64>() / 16.0;
        (m, means.iter().map(|v| (v - m).powi(2)).sum::<f64>() / 15.0 / 16.0)
    };
    let (v, vv) = stats(IntegratorKind::Volpath, None, 1);
    let (r, rv) = stats(IntegratorKind::Raymarch, Some(0.2), 2);
    let t = (r - v).abs() / (vv + rv).sqrt();
    eprintln!("raymarch with a 0.2 m step against volpath in fog: ratio {:.4}, |t| {t:.2}", r / v);
    assert!(t < 4.1, "ratio {}, |t| {t}", r / v);
    // The flag is used: the default step (16 points or more a segment) spreads less.
    let (_, fine) = stats(IntegratorKind::Raymarch, None, 3);
    eprintln!("variance of the run means: step 0.2 m {rv:.3e}, default {fine:.3e}");
    assert!(fine < rv, "the coarse step did not add variance: {rv} vs {fine}");
}
