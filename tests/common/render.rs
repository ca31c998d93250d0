//! Rendering helpers shared by the renderer's tests.

use propsim::render::{Camera, Film, IntegratorKind, RenderScene, RenderSettings, render};

/// A square image `w` x `w` at `spp` samples per pixel, the other settings at their defaults.
pub fn settings(w: u32, spp: u32, max_depth: u32, integrator: IntegratorKind, seed: u64) -> RenderSettings {
    RenderSettings { width: w, height: w, spp, max_depth, integrator, seed, ..RenderSettings::default() }
}

/// The film of one render (no progress reports).
pub fn go(scene: &RenderScene, cam: &Camera, s: &RenderSettings) -> Film {
    render(scene, cam, s, &|_| {}).expect("renders").film
}

/// Per region of `block` x `block` pixels of the square `w` x `w` films (independent renders
/// of one image): the mean over the films of the region's mean, per channel when
/// `per_channel` (regions first, then channels) or of the channels' mean, and the variance of
/// that mean (the sample variance over the films divided by their number), for Welch's t.
pub fn pooled_regions(films: &[Film], w: usize, block: usize, per_channel: bool) -> Vec<(f64, f64)> {
    let r = w / block;
    let per_film: Vec<Vec<f64>> = films
        .iter()
        .map(|f| {
            let mut v = Vec::new();
            for region in 0..r * r {
                let (rx, ry) = (region % r, region / r);
                let channels: &[usize] = if per_channel { &[0, 1, 2] } else { &[3] };
                for &c in channels {
                    let mut sum = 0.0;
                    for y in ry * block..(ry + 1) * block {
                        for x in rx * block..(rx + 1) * block {
                            let p = f.pixels[y * w + x];
                            sum += f64::from(if c == 3 { p.element_sum() / 3.0 } else { p[c] });
                        }
                    }
                    v.push(sum / (block * block) as f64);
                }
            }
            v
        })
        .collect();
    let n = films.len() as f64;
    (0..per_film[0].len())
        .map(|i| {
            let m = per_film.iter().map(|v| v[i]).sum::<f64>() / n;
            let var = per_film.iter().map(|v| (v[i] - m).powi(2)).sum::<f64>() / (n - 1.0) / n;
            (m, var)
        })
        .collect()
}

/// The largest Welch |t| between two pooled images from [`pooled_regions`] (regions with no
/// light on either side, both exactly zero, skipped).
pub fn worst_welch_t(a: &[(f64, f64)], b: &[(f64, f64)]) -> f64 {
    a.iter()
        .zip(b)
        .filter(|((m, _), (rm, _))| *m != 0.0 || *rm != 0.0)
        .map(|((m, v), (rm, rv))| (m - rm).abs() / (v + rv).sqrt().max(1e-12))
        .fold(0.0f64, f64::max)
}

/// The whole image's mean of pooled image `a` over `b`'s, and Welch's |t| of their
/// difference (the regions' variances summed).
pub fn whole_image_t(a: &[(f64, f64)], b: &[(f64, f64)]) -> (f64, f64) {
    let (mut sum_a, mut sum_b, mut var) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        sum_a += x.0;
        sum_b += y.0;
        var += x.1 + y.1;
    }
    (sum_a / sum_b, (sum_a - sum_b).abs() / var.sqrt())
}

/// The Cornell box's mesh and optics with two more surfaces, glass of index `eta` named
/// `glass` and a rough metal of `f0` named `metal`, and a ball of each (radius 8 cm, one in
/// the air, one on the short block): the thread-determinism scenes' specular setup.
pub fn with_glass_and_metal_balls(
    world: &propsim::scene::World,
    (glass, eta): (&str, f32),
    (metal, f0): (&str, glam::Vec3),
) -> (propsim::core::TriangleMesh, Vec<propsim::render::SurfaceOptics>, Vec<propsim::core::Sphere>) {
    use glam::Vec3;
    use propsim::core::Sphere;
    use propsim::render::{Bsdf, SurfaceOptics};
    let mut mesh = world.scene.mesh.clone();
    let glass = mesh.surface_id(glass);
    let metal = mesh.surface_id(metal);
    let mut optics: Vec<SurfaceOptics> =
        world.scene.surfaces.iter().map(SurfaceOptics::from_surface).collect();
    optics.push(SurfaceOptics { bsdf: Bsdf::Dielectric { eta, tint: Vec3::ONE }, emission: Vec3::ZERO });
    optics.push(SurfaceOptics { bsdf: Bsdf::Metal { f0, alpha: 0.2 }, emission: Vec3::ZERO });
    let spheres = vec![
        Sphere::new(Vec3::new(0.2, 0.2, 0.43), 0.08, glass),
        Sphere::new(Vec3::new(0.4, 0.3, 0.25), 0.08, metal),
    ];
    (mesh, optics, spheres)
}
