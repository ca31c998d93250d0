//! Distributed ray tracing (Cook, Porter, Carpenter 1984, "Distributed ray tracing"):
//! stratified jittered pixel samples (anti-aliasing: Owen-scrambled Sobol points, one per
//! stratum, see [`super::sampler`]), soft shadows by
//! sampling points on area lights, glossy reflection by sampling the GGX lobe, mirror and
//! Fresnel-weighted refraction, and thin-lens depth of field (in [`super::Camera`]).
//! Diffuse surfaces receive direct light only: there is no diffuse interreflection.
//! (No motion blur: scenes carry no motion.)

use glam::Vec3;

use super::RenderScene;
use super::path::{PathMode, trace};
use super::sampler::Sampler;
use crate::core::Ray;

/// Radiance along camera ray `ray`, following at most `max_depth` specular/glossy bounces.
pub fn li(scene: &RenderScene, ray: Ray, max_depth: u32, sampler: &mut Sampler, rays: &mut u64) -> Vec3 {
    trace(scene, ray, max_depth, sampler, rays, PathMode::StopAtDiffuse, None)
}
