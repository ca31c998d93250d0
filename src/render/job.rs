//! One render job: the pre-flight ([`plan`]: options and scene to checked settings and a
//! camera, before any ray is traced), then the run ([`execute`]: render and write the image).

use std::path::Path;

use anyhow::{Context as _, anyhow};

use super::options::{BYTES_PER_PIXEL, camera, settings};
use super::{Camera, IntegratorKind, RenderOptions, RenderOutput, RenderScene, RenderSettings, render_on};
use crate::dist::Cluster;
use crate::io::report::Report;
use crate::scene::World;

/// A checked render: its settings and camera, and what the user should be told before it
/// runs (a scene with no light).
#[derive(Clone, Debug)]
pub struct RenderPlan {
    /// The settings, defaults filled and validated.
    pub settings: RenderSettings,
    /// The camera, the scene's or the automatic one, with the options applied.
    pub camera: Camera,
    /// Warnings, one line each, naming the scene.
    pub warnings: Vec<String>,
}

/// The render's pre-flight: the settings and camera, and whether the image fits in memory.
/// The error is one line naming the scene `scene_label`.
pub fn plan(world: &World, options: &RenderOptions, scene_label: &str) -> anyhow::Result<RenderPlan> {
    let s = settings(world, options).with_context(|| scene_label.to_string())?;
    let pixels = u64::from(s.width) * u64::from(s.height);
    let bytes_per_pixel = match s.integrator {
        IntegratorKind::Sppm | IntegratorKind::Ppm => super::sppm::BYTES_PER_PIXEL,
        _ => BYTES_PER_PIXEL,
    };
    let light_paths = if s.integrator == IntegratorKind::Vcm { super::vcm::light_path_bytes(&s) } else { 0 };
    crate::io::memory::check_fits(
        &format!("a {}x{} render", s.width, s.height),
        (pixels * bytes_per_pixel).saturating_add(light_paths) + world.accel.memory_bytes() as u64,
    )?;
    let camera =
        camera(world, options, s.width as f32 / s.height as f32).with_context(|| scene_label.to_string())?;
    let mut warnings = Vec::new();
    if s.integrator != IntegratorKind::Raycast
        && let Some(why) = super::unlit_reason(world)
    {
        warnings.push(format!("{scene_label}: {why}"));
    }
    if s.integrator != IntegratorKind::Spectral {
        let dispersive: Vec<&str> = world
            .scene
            .surfaces
            .iter()
            .filter(|sf| {
                sf.material.as_ref().and_then(|m| m.optical.as_ref()).is_some_and(|o| o.dispersion.is_some())
            })
            .map(|sf| sf.name.as_str())
            .collect();
        if let Some(first) = dispersive.first() {
            warnings.push(format!(
                "{scene_label}: {} dispersive glass surface(s) (\"{first}\"...) refract every colour at n_d \
                 with --integrator {}; only --integrator spectral disperses",
                dispersive.len(),
                s.integrator.name()
            ));
        }
    }
    if s.integrator == IntegratorKind::Radiosity {
        let rs = RenderScene::new(world);
        super::radiosity::supported(&rs).map_err(|e| anyhow!("{scene_label}: {e}"))?;
        let approximated =
            rs.surfaces.iter().filter(|o| !matches!(o.bsdf, super::Bsdf::Lambert { .. })).count();
        if approximated > 0 {
            warnings.push(format!(
                "{scene_label}: radiosity treats {approximated} non-diffuse surface(s) as diffuse \
                 (a metal as albedo f0, a glass as albedo tint)"
            ));
        }
    }
    Ok(RenderPlan { settings: s, camera, warnings })
}

/// Renders a checked [`RenderPlan`] on this process's share of `cluster`; on rank 0 writes the
/// image to `output` (when given; the extension picks the format) and reports one line.
/// `None` on the other ranks.
pub fn execute(
    world: &World,
    plan: &RenderPlan,
    output: Option<&Path>,
    cluster: &Cluster,
    report: &dyn Report,
) -> anyhow::Result<Option<RenderOutput>> {
    let s = &plan.settings;
    let rs = RenderScene::new(world);
    let counter = report.progress(u64::from(s.width) * u64::from(s.height), "pixels");
    let out = render_on(cluster, &rs, &plan.camera, s, &|n| counter.inc(n)).map_err(|e| anyhow!("{e}"))?;
    drop(counter);
    // Only rank 0 holds the image and writes.
    let Some(out) = out else { return Ok(None) };
    if let Some(path) = output {
        out.film.write_with(path, &s.display)?;
        for note in &out.notes {
            report.say(note);
        }
        report.say(&summary(path, s, &out));
    }
    Ok(Some(out))
}

/// One line: what was written and how fast.
pub fn summary(path: &Path, s: &RenderSettings, out: &RenderOutput) -> String {
    format!(
        "wrote {}: {}x{}, {} spp, {}, max depth {}, {:.2} s, {:.2} M samples/s, {:.2} Mrays/s",
        path.display(),
        s.width,
        s.height,
        s.spp,
        s.integrator.name(),
        s.max_depth,
        out.seconds,
        out.samples as f64 / out.seconds / 1e6,
        out.rays as f64 / out.seconds / 1e6
    )
}
