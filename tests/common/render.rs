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
