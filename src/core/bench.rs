//! Benchmark workloads of the tracing core: a generated terrain, coherent and incoherent ray
//! sets, the ray file format shared with other tracers, and the timed queries of `propsim
//! bench trace` and `cargo bench`.

use std::path::Path;
use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::launcher::LAUNCH_BLOCK;
use super::rng::{stream, uniform};
use super::sampling::uniform_sphere;
use super::{Accel, BuildQuality, Hit, Ray, TriangleMesh};

/// Peak memory per generated terrain triangle, bytes: mesh, BVH and build scratch (1M
/// triangles and 3 x 1M rays peaked at 290 MB).
pub const BYTES_PER_TRIANGLE: u64 = 200;
/// Memory per generated ray, bytes: the ray and its hit record.
pub const BYTES_PER_RAY: u64 = 64;

/// Reads a ray file: little-endian f32, 6 per ray. Directions are normalised.
pub fn read_rays(path: &Path) -> anyhow::Result<Vec<Ray>> {
    let bytes = std::fs::read(path).map_err(|e| crate::scene::SceneError::io(path, &e))?;
    anyhow::ensure!(
        bytes.len() % 24 == 0 && !bytes.is_empty(),
        "{}: a ray file holds 24 bytes per ray (6 little-endian f32), found {} bytes",
        path.display(),
        bytes.len()
    );
    let mut rays = Vec::with_capacity(bytes.len() / 24);
    for (i, chunk) in bytes.chunks_exact(24).enumerate() {
        let f: Vec<f32> =
            chunk.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        let (o, d) = (Vec3::new(f[0], f[1], f[2]), Vec3::new(f[3], f[4], f[5]));
        anyhow::ensure!(
            o.is_finite() && d.is_finite() && d.length_squared() > 0.0,
            "{}: ray {i} is not finite or has a zero direction",
            path.display()
        );
        rays.push(Ray::new(o, d.normalize()));
    }
    Ok(rays)
}

/// Writes rays in the format [`read_rays`] reads.
pub fn write_rays(path: &Path, rays: &[Ray]) -> anyhow::Result<()> {
    let mut bytes = Vec::with_capacity(rays.len() * 24);
    for r in rays {
        for v in r.origin.to_array().into_iter().chain(r.dir.to_array()) {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    crate::io::atomic::write_bytes(path, &bytes)
}

/// Terrain height (m) at (x, y): a few octaves of smooth waves over 1 km.
fn terrain_height(x: f32, y: f32) -> f32 {
    30.0 * (x * 0.006).sin() * (y * 0.005).cos()
        + 12.0 * (x * 0.021 + 1.3).sin() * (y * 0.017 + 0.4).sin()
        + 4.0 * (x * 0.07 + y * 0.05).sin()
        + 1.5 * (x * 0.23).cos() * (y * 0.19).sin()
}

/// A square 1 km terrain height field with about `triangles` triangles.
pub fn terrain(triangles: usize) -> TriangleMesh {
    let cells = ((triangles as f64 / 2.0).sqrt().round() as usize).max(1);
    let n = cells + 1;
    let size = 1000.0;
    let mut mesh = TriangleMesh::default();
    let s = mesh.surface_id("terrain");
    mesh.positions = (0..n * n)
        .map(|k| {
            let (i, j) = (k % n, k / n);
            let (x, y) = (i as f32 / cells as f32 * size - 500.0, j as f32 / cells as f32 * size - 500.0);
            Vec3::new(x, y, terrain_height(x, y))
        })
        .collect();
    for j in 0..cells {
        for i in 0..cells {
            let a = (j * n + i) as u32;
            let (b, c, d) = (a + 1, a + n as u32 + 1, a + n as u32);
            mesh.triangles.push([a, b, c]);
            mesh.triangles.push([a, c, d]);
        }
    }
    mesh.surface_of_triangle = vec![s; mesh.triangles.len()];
    mesh
}

/// Primary rays of a pinhole camera looking down at the terrain at 45 degrees, with a
/// half-width of `half_angle_deg`: coherent. At 35 degrees 27 % of them hit the terrain (the
/// benchmark's coherent set); at 20 degrees 68 % do (its hit-heavy set).
pub fn coherent_rays(count: usize, half_angle_deg: f32) -> Vec<Ray> {
    let side = (count as f64).sqrt().ceil() as usize;
    let eye = Vec3::new(-700.0, -700.0, 600.0);
    let forward = (Vec3::new(0.0, 0.0, 0.0) - eye).normalize();
    let right = forward.cross(Vec3::Z).normalize();
    let up = right.cross(forward);
    let half = half_angle_deg.to_radians().tan();
    (0..count)
        .map(|k| {
            let (i, j) = (k % side, k / side);
            let u = ((i as f32 + 0.5) / side as f32 * 2.0 - 1.0) * half;
            let v = ((j as f32 + 0.5) / side as f32 * 2.0 - 1.0) * half;
            Ray::new(eye, (forward + u * right + v * up).normalize())
        })
        .collect()
}

/// Rays from random points 1-50 m above the terrain in uniformly random directions:
/// incoherent, like diffuse bounces or an acoustic/radio launcher after a few reflections.
pub fn incoherent_rays(count: usize, seed: u64) -> Vec<Ray> {
    (0..count)
        .map(|k| {
            let mut r = stream(seed, 0xbe7c, k as u64);
            let x = uniform(&mut r) * 900.0 - 450.0;
            let y = uniform(&mut r) * 900.0 - 450.0;
            let z = terrain_height(x, y) + 1.0 + 49.0 * uniform(&mut r);
            let d = uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            Ray::new(Vec3::new(x, y, z), d)
        })
        .collect()
}

/// Median of a list of seconds.
pub fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        0.0
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Peak resident memory of this process in MB (Linux `VmHWM`), if known.
pub fn peak_rss_mb() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb / 1024.0)
}

/// Builds the BVH `count` times (at least once), dropping each before the next so peak memory
/// holds one; returns the last build and every build time in seconds.
pub fn timed_builds(mesh: &TriangleMesh, count: usize, quality: BuildQuality) -> (Accel, Vec<f64>) {
    let mut builds = Vec::new();
    let mut t = Instant::now();
    let mut accel = Accel::build(mesh, Vec::new(), quality);
    builds.push(t.elapsed().as_secs_f64());
    for _ in 1..count {
        drop(accel);
        t = Instant::now();
        accel = Accel::build(mesh, Vec::new(), quality);
        builds.push(t.elapsed().as_secs_f64());
    }
    (accel, builds)
}

/// `count` placements of a mesh whose box is `lo..hi` on a square grid in the xy plane, the
/// cells 1.25 times the mesh's larger horizontal side, each copy turned about z by a random
/// angle and scaled by 0.8-1.2 (seeded): the instanced workload of `propsim bench trace
/// --instances` (a forest of one tree, a car park of one car).
pub fn grid_instances(count: usize, lo: Vec3, hi: Vec3, seed: u64) -> Vec<super::Instance> {
    let side = (count as f64).sqrt().ceil() as usize;
    let size = hi - lo;
    let cell = 1.25 * size.x.max(size.y).max(1e-3);
    let centre = 0.5 * (lo + hi);
    (0..count)
        .map(|k| {
            let mut r = stream(seed, 0x1257, k as u64);
            let (i, j) = ((k % side) as f32, (k / side) as f32);
            let at = Vec3::new(i * cell, j * cell, 0.0);
            let turn = glam::Quat::from_rotation_z(uniform(&mut r) * std::f32::consts::TAU);
            let scale = 0.8 + 0.4 * uniform(&mut r);
            let object_to_world = glam::Affine3A::from_translation(at)
                * glam::Affine3A::from_scale_rotation_translation(Vec3::splat(scale), turn, Vec3::ZERO)
                * glam::Affine3A::from_translation(-Vec3::new(centre.x, centre.y, lo.z));
            super::Instance { mesh: 0, object_to_world, surfaces: vec![] }
        })
        .collect()
}

/// Rays over a scene whose box is `lo..hi`: half from random points inside the box in random
/// directions (incoherent), half camera rays from above a corner towards the centre
/// (coherent, 60 degrees wide).
pub fn scene_rays(count: usize, lo: Vec3, hi: Vec3, seed: u64) -> (Vec<Ray>, Vec<Ray>) {
    let size = hi - lo;
    let incoherent = (0..count)
        .map(|k| {
            let mut r = stream(seed, 0x5ce7, k as u64);
            let o = lo + size * Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r));
            Ray::new(o, uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r))))
        })
        .collect();
    let eye =
        lo + Vec3::new(-0.1 * size.x, -0.1 * size.y, 0.0) + Vec3::new(0.0, 0.0, hi.z - lo.z + 0.1 * size.x);
    let forward = (0.5 * (lo + hi) - eye).normalize();
    let right = forward.cross(Vec3::Z).normalize();
    let up = right.cross(forward);
    let side = (count as f64).sqrt().ceil() as usize;
    let half = 30f32.to_radians().tan();
    let coherent = (0..count)
        .map(|k| {
            let (i, j) = (k % side, k / side);
            let u = ((i as f32 + 0.5) / side as f32 * 2.0 - 1.0) * half;
            let v = ((j as f32 + 0.5) / side as f32 * 2.0 - 1.0) * half;
            Ray::new(eye, (forward + u * right + v * up).normalize())
        })
        .collect();
    (coherent, incoherent)
}

/// Result of tracing one ray set through the queries the products make, each timed alone.
pub struct TraceFigures {
    /// `propsim render`'s rays (camera rays, path bounces): one closest-hit query a ray
    /// ([`crate::core::MeshBvh::closest_triangle`]), rays spread over the threads.
    pub render_mrays_s: f64,
    /// The acoustic and radio launcher's bounces: [`Accel::closest_hits_into`] on blocks of
    /// [`LAUNCH_BLOCK`] rays (coherent runs in groups, the rest as streams, on large trees).
    pub launcher_mrays_s: f64,
    /// Shadow rays of `propsim render` and the acoustic diffuse rain: one
    /// [`Accel::occluded`] query a ray.
    pub occlusion_mrays_s: f64,
    /// Rays that hit a triangle.
    pub hits: usize,
    /// Rays found occluded.
    pub occluded: usize,
    /// Rays whose launcher distance differs from the render query's (0: the batch and
    /// single-ray queries agree bit for bit).
    pub launcher_differs: usize,
    /// Sum over rays of (hit triangle index + 1), 0 for a miss, wrapping at 2^64.
    pub checksum: u64,
}

/// What [`trace_figures`] prints for each set, in order: which product path each figure is.
pub const FIGURE_LEGEND: &str = "per set, Mrays/s: render = `propsim render`'s closest hits (single-ray queries); \
launcher = acoustic/rf launcher bounces (closest_hits_into, 1024-ray blocks); \
occlusion = render shadow rays and acoustic diffuse rain (single-ray queries)";

/// Traces `rays` `repeat` times through each product path's query, reporting medians.
pub fn trace_figures(accel: &Accel, rays: &[Ray], repeat: usize) -> TraceFigures {
    let (mut render_s, mut launcher_s, mut occl_s) = (Vec::new(), Vec::new(), Vec::new());
    let mut checksum = 0u64;
    let mut hits = 0;
    let mut occluded = 0;
    let mut launcher_differs = 0;
    let mut launched: Vec<Option<Hit>> = vec![None; rays.len()];
    for _ in 0..repeat.max(1) {
        let t = Instant::now();
        let tri: Vec<Option<(u32, f32)>> = if accel.instances.is_empty() {
            rays.par_iter().map(|r| accel.mesh.closest_triangle(r)).collect()
        } else {
            rays.par_iter().map(|r| accel.closest_hit(r).map(|h| (h.primitive, h.t))).collect()
        };
        render_s.push(t.elapsed().as_secs_f64());
        checksum = tri.iter().fold(0u64, |acc, h| acc.wrapping_add(h.map_or(0, |(i, _)| u64::from(i) + 1)));
        hits = tri.iter().filter(|h| h.is_some()).count();
        let t = Instant::now();
        launched
            .par_chunks_mut(LAUNCH_BLOCK)
            .zip(rays.par_chunks(LAUNCH_BLOCK))
            .for_each(|(out, block)| accel.closest_hits_into(block, out));
        launcher_s.push(t.elapsed().as_secs_f64());
        launcher_differs = (launched.iter().zip(&tri))
            .filter(|(l, r)| l.map(|h| h.t.to_bits()) != r.map(|(_, t)| t.to_bits()))
            .count();
        let t = Instant::now();
        let occ: Vec<bool> = rays.par_iter().map(|r| accel.occluded(r)).collect();
        occl_s.push(t.elapsed().as_secs_f64());
        occluded = occ.iter().filter(|&&o| o).count();
    }
    let n = rays.len() as f64;
    TraceFigures {
        render_mrays_s: n / median(render_s) / 1e6,
        launcher_mrays_s: n / median(launcher_s) / 1e6,
        occlusion_mrays_s: n / median(occl_s) / 1e6,
        hits,
        occluded,
        launcher_differs,
        checksum,
    }
}
