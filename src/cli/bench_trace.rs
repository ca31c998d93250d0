//! `propsim bench trace`: the core's speed on a mesh and a ray file, in a form anyone can
//! reproduce with another tracer (same mesh, same rays, same checksum rule).

use std::path::{Path, PathBuf};

use crate::core::bench::*;
use crate::core::{BuildQuality, Ray, TriangleMesh};
use crate::scene::obj::load_obj;
use clap::Args;
use glam::Vec3;

#[derive(Args, Debug)]
pub struct TraceArgs {
    /// Mesh to trace against (OBJ). Without it a terrain of --triangles triangles is generated.
    pub mesh: Option<PathBuf>,
    /// Ray file: little-endian f32, 6 per ray (origin xyz, direction xyz). Without it,
    /// coherent, incoherent and hit-heavy coherent rays are generated.
    #[arg(long)]
    pub rays: Option<PathBuf>,
    /// Triangles in the generated terrain.
    #[arg(long, default_value_t = 1_000_000)]
    pub triangles: usize,
    /// Rays per generated set.
    #[arg(long, default_value_t = 1 << 20)]
    pub ray_count: usize,
    /// Timed repetitions; the median is reported.
    #[arg(long, default_value_t = 5)]
    pub repeat: usize,
    /// BVH build quality: fast, medium (the default everywhere in propsim) or high; to weigh
    /// build time against ray speed.
    #[arg(long, default_value = "medium", value_parser = ["fast", "medium", "high"])]
    pub quality: String,
    /// Place this many copies of the mesh (or of the generated terrain) on a grid and trace
    /// them twice on identical rays: as instances (two-level BVH) and flattened into one mesh
    /// (when that fits in memory), to weigh instancing's cost.
    #[arg(long)]
    pub instances: Option<usize>,
    /// Write the generated mesh (OBJ) and ray sets (PREFIX_coherent.bin, PREFIX_incoherent.bin,
    /// PREFIX_hit-heavy.bin) so other tracers can be run on the same input.
    #[arg(long)]
    pub write_inputs: Option<PathBuf>,
}

/// `--instances N`: the same rays through `N` instances of `mesh` and through their
/// flattened copy.
fn run_instanced(args: &TraceArgs, mesh: &TriangleMesh, label: &str, n: usize) -> anyhow::Result<()> {
    use crate::core::accel::instances::flatten;
    use crate::core::{Accel, InstanceSet};
    anyhow::ensure!((1..=10_000_000).contains(&n), "--instances {n}: must be between 1 and 10^7");
    let (lo, hi) = mesh.bounds().unwrap_or_default();
    let instances = grid_instances(n, lo, hi, 1);
    let quality = match args.quality.as_str() {
        "fast" => BuildQuality::Fast,
        "high" => BuildQuality::High,
        _ => BuildQuality::Medium,
    };
    let total = mesh.triangle_count() as u64 * n as u64;
    crate::outln!(
        "mesh:        {label}, {} triangles x {n} instances = {total} triangles",
        mesh.triangle_count()
    );
    crate::outln!("threads:     {}", rayon::current_num_threads());
    let t = std::time::Instant::now();
    let set = InstanceSet::build(std::slice::from_ref(mesh), &instances, quality);
    let (wlo, whi) = set.bounds();
    let instanced = Accel::build(&TriangleMesh::default(), Vec::new(), quality).with_instances(set);
    crate::outln!(
        "instanced:   build {:.3} s, BVHs + triangles {:.1} MB",
        t.elapsed().as_secs_f64(),
        instanced.memory_bytes() as f64 / 1e6
    );
    let (coherent, incoherent) = scene_rays(args.ray_count, wlo, whi, 2);
    let flat_bytes = total * BYTES_PER_TRIANGLE;
    let flat = match crate::io::memory::check_fits("the flattened copy", flat_bytes) {
        Ok(()) => {
            let t = std::time::Instant::now();
            let m = flatten(std::slice::from_ref(mesh), &instances);
            let a = Accel::build(&m, Vec::new(), quality);
            crate::outln!(
                "flattened:   build {:.3} s, BVH + triangles {:.1} MB",
                t.elapsed().as_secs_f64(),
                a.memory_bytes() as f64 / 1e6
            );
            Some(a)
        }
        Err(e) => {
            crate::outln!("flattened:   skipped ({e})");
            None
        }
    };
    crate::outln!("{FIGURE_LEGEND}");
    for (name, rays) in [("coherent", &coherent), ("incoherent", &incoherent)] {
        let i = trace_figures(&instanced, rays, args.repeat);
        crate::outln!(
            "{name:<12} {} rays: instanced render {:.2}, launcher {:.2}, occlusion {:.2} Mrays/s, hits {}, occluded {}, launcher distances differing {}",
            rays.len(),
            i.render_mrays_s,
            i.launcher_mrays_s,
            i.occlusion_mrays_s,
            i.hits,
            i.occluded,
            i.launcher_differs
        );
        if let Some(flat) = &flat {
            let f = trace_figures(flat, rays, args.repeat);
            crate::outln!(
                "{name:<12} {} rays: flattened render {:.2}, launcher {:.2}, occlusion {:.2} Mrays/s, hits {}, occluded {}; instanced/flattened {:.2} / {:.2} / {:.2}",
                rays.len(),
                f.render_mrays_s,
                f.launcher_mrays_s,
                f.occlusion_mrays_s,
                f.hits,
                f.occluded,
                i.render_mrays_s / f.render_mrays_s,
                i.launcher_mrays_s / f.launcher_mrays_s,
                i.occlusion_mrays_s / f.occlusion_mrays_s
            );
        }
    }
    if let Some(mb) = peak_rss_mb() {
        crate::outln!("peak memory: {mb:.0} MB resident");
    }
    Ok(())
}

fn write_obj(path: &Path, mesh: &TriangleMesh) -> anyhow::Result<()> {
    crate::io::atomic::write_atomically(path, |w| {
        for p in &mesh.positions {
            writeln!(w, "v {} {} {}", p.x, p.y, p.z)?;
        }
        for t in &mesh.triangles {
            writeln!(w, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
        }
        Ok(())
    })
}

pub fn run(args: &TraceArgs) -> anyhow::Result<()> {
    anyhow::ensure!(
        (1..=100_000_000).contains(&args.triangles),
        "--triangles {}: must be between 1 and 10^8",
        args.triangles
    );
    anyhow::ensure!(
        (1..=100_000_000).contains(&args.ray_count),
        "--ray-count {}: must be between 1 and 10^8",
        args.ray_count
    );
    anyhow::ensure!(
        (1..=1000).contains(&args.repeat),
        "--repeat {}: must be between 1 and 1000",
        args.repeat
    );
    if args.mesh.is_none() {
        let bytes = args.triangles as u64 * BYTES_PER_TRIANGLE + 3 * args.ray_count as u64 * BYTES_PER_RAY;
        crate::io::memory::check_fits(
            &format!("bench trace with {} triangles and 3 x {} rays", args.triangles, args.ray_count),
            bytes,
        )?;
    }
    let (mesh, label) = match &args.mesh {
        Some(p) => {
            let obj = load_obj(p)?;
            anyhow::ensure!(
                obj.mesh.triangle_count() > 0,
                "{}: the mesh has no usable triangles",
                p.display()
            );
            (obj.mesh, p.display().to_string())
        }
        None => (terrain(args.triangles), "generated terrain".to_string()),
    };
    // Generated rays are made after the timed builds, in memory the builds have freed: made
    // before, they raised the peak to 354-391 MB (now 286-292 MB, 2 threads). A ray file is
    // read first, so that a bad file fails before the build.
    let generated = || -> Vec<(String, Vec<Ray>)> {
        if args.mesh.is_none() {
            return vec![
                ("coherent".into(), coherent_rays(args.ray_count, 35.0)),
                ("incoherent".into(), incoherent_rays(args.ray_count, 1)),
                ("hit-heavy".into(), coherent_rays(args.ray_count, 20.0)),
            ];
        }
        let (lo, hi) = mesh.bounds().unwrap_or_default();
        let c = 0.5 * (lo + hi);
        let rays = incoherent_rays(args.ray_count, 1)
            .into_iter()
            .map(|r| Ray::new(c + (r.origin - Vec3::new(0.0, 0.0, 25.0)) * (hi - lo) / 1000.0, r.dir))
            .collect();
        vec![("random".into(), rays)]
    };
    let sets: Option<Vec<(String, Vec<Ray>)>> = match &args.rays {
        Some(p) => Some(vec![(p.display().to_string(), read_rays(p)?)]),
        None => None,
    };
    if let Some(prefix) = &args.write_inputs {
        write_obj(&prefix.with_extension("obj"), &mesh)?;
        // Generated sets are written, dropped and made again after the builds, which keeps
        // the peak as low as without this option.
        let fresh;
        let to_write = match &sets {
            Some(s) => s,
            None => {
                fresh = generated();
                &fresh
            }
        };
        for (name, rays) in to_write {
            let p = PathBuf::from(format!("{}_{name}.bin", prefix.display()));
            write_rays(&p, rays)?;
            crate::outln!("wrote {}", p.display());
        }
    }
    if let Some(n) = args.instances {
        return run_instanced(args, &mesh, &label, n);
    }
    crate::outln!("mesh:        {label}, {} triangles", mesh.triangle_count());
    crate::outln!("threads:     {}", rayon::current_num_threads());
    let quality = match args.quality.as_str() {
        "fast" => BuildQuality::Fast,
        "high" => BuildQuality::High,
        _ => BuildQuality::Medium,
    };
    let (accel, builds) = timed_builds(&mesh, args.repeat.clamp(1, 3), quality);
    crate::outln!(
        "build:       {:.3} s (median of {}), BVH + triangles {:.1} MB",
        median(builds.clone()),
        builds.len(),
        accel.mesh.memory_bytes() as f64 / 1e6
    );
    let sets = sets.unwrap_or_else(generated);
    crate::outln!("{FIGURE_LEGEND}");
    for (name, rays) in &sets {
        let f = trace_figures(&accel, rays, args.repeat);
        crate::outln!(
            "{name:<12} {} rays: render {:.2}, launcher {:.2}, occlusion {:.2} Mrays/s, hits {}, occluded {}, checksum {:#018x}",
            rays.len(),
            f.render_mrays_s,
            f.launcher_mrays_s,
            f.occlusion_mrays_s,
            f.hits,
            f.occluded,
            f.checksum
        );
    }
    if let Some(mb) = peak_rss_mb() {
        crate::outln!("peak memory: {mb:.0} MB resident");
    }
    Ok(())
}
