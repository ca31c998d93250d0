//! Distributed ray tracing (Cook, Porter, Carpenter 1984, "Distributed ray tracing"):
//! stratified jittered pixel samples (anti-aliasing, in [`super::render`]), soft shadows by
//! sampling points on area lights, glossy reflection by sampling the GGX lobe, mirror and
//! Fresnel-weighted refraction, and thin-lens depth of field (in [`super::Camera`]).
//! Diffuse surfaces receive direct light only: there is no diffuse interreflection.
//! (No motion blur: scenes carry no motion.)

use glam::Vec3;

use super::RenderScene;
use super::path::{FirstVertexSamples, PathMode, trace};
use crate::core::Ray;
use crate::core::rng::Rng64;

/// Radiance along camera ray `ray`, following at most `max_depth` specular/glossy bounces.
pub fn li(
    scene: &RenderScene,
    ray: Ray,
    max_depth: u32,
    first: Option<FirstVertexSamples>,
    rng: &mut Rng64,
    rays: &mut u64,
) -> Vec3 {
    trace(scene, ray, max_depth, first, rng, rays, PathMode::StopAtDiffuse)
}
