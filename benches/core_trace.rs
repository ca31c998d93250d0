//! `cargo bench --bench core_trace`: build time and Mrays/s of the tracing core on the
//! generated 1M-triangle terrain, coherent, incoherent and hit-heavy coherent rays, through
//! the queries each product path makes (medians of 5 runs).
//! The same figures come from `propsim bench trace`, which also takes your own mesh and rays.

use std::time::Instant;

use propsim::core::bench::{
    FIGURE_LEGEND, coherent_rays, incoherent_rays, median, peak_rss_mb, terrain, timed_builds, trace_figures,
};

fn main() {
    let mesh = terrain(1_000_000);
    let (accel, builds) = timed_builds(&mesh, 3, propsim::core::BuildQuality::default());
    println!("terrain {} triangles, {} threads", mesh.triangle_count(), rayon::current_num_threads());
    println!("build: {:.3} s (median of 3)", median(builds));
    println!("{FIGURE_LEGEND}");
    for name in ["coherent", "incoherent", "hit-heavy"] {
        // One set in memory at a time.
        let rays = match name {
            "coherent" => coherent_rays(1 << 20, 35.0),
            "incoherent" => incoherent_rays(1 << 20, 1),
            _ => coherent_rays(1 << 20, 20.0),
        };
        let t = Instant::now();
        let f = trace_figures(&accel, &rays, 5);
        println!(
            "{name}: render {:.2}, launcher {:.2}, occlusion {:.2} Mrays/s (medians of 5; wall {:.2} s), checksum {:#018x}",
            f.render_mrays_s,
            f.launcher_mrays_s,
            f.occlusion_mrays_s,
            t.elapsed().as_secs_f64(),
            f.checksum
        );
    }
    if let Some(mb) = peak_rss_mb() {
        println!("peak memory: {mb:.0} MB resident");
    }
}
