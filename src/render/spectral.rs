//! Spectral path tracing (`--integrator spectral`): the path tracer of [`super::path`] (NEE
//! and BSDF sampling joined by MIS, Russian roulette) carrying four wavelengths at once, a
//! hero and three companions ([`super::spectrum::Wavelengths`]; Wilkie et al. 2014), as
//! pbrt-v4's `PathIntegrator` does with `SampledWavelengths` (pbrt-v4 sec. 4.6.5).
//!
//! The scene's RGB colours are up-sampled to smooth spectra once per render
//! ([`SpectralScene::new`]; [`super::spectrum`] says how and why white stays white); a
//! path's throughput is one value per wavelength. The BSDFs are the RGB ones with a unit
//! colour times a per-wavelength colour factor (albedo, Schlick's Fresnel of the metal's
//! `f0`, the glass's tint), so their sampling and densities are shared with every other
//! integrator. A glass with a dispersion law ([`crate::scene::dispersion`]) refracts the
//! hero wavelength by its own index and drops the companions (pbrt-v4's
//! `TerminateSecondary`): one direction cannot serve four indices. The radiances at the
//! wavelengths are turned into the film's RGB through the CIE matching functions at the end
//! of each sample.

use glam::{Vec2, Vec3, Vec4};

use super::bsdf::fresnel_schlick;
use super::lights::Light;
use super::path::RR_START_DEPTH;
use super::sampler::Sampler;
use super::spectrum::{RgbIlluminant, RgbSpectrum, Wavelengths, reflectance_to_rgb};
use super::{Bsdf, Frame, RenderScene, power_heuristic};
use crate::core::{Hit, Ray};
use crate::scene::dispersion::Dispersion;

/// A surface's spectra: its BSDF colour (albedo, `f0` or tint) and its emission.
#[derive(Clone, Copy, Debug)]
struct SurfaceSpectra {
    colour: RgbSpectrum,
    emission: RgbIlluminant,
}

/// The up-sampled spectra of a render scene: per surface, per light, and the background.
#[derive(Clone, Debug)]
pub struct SpectralScene {
    surfaces: Vec<SurfaceSpectra>,
    /// Per light: the largest component of its RGB radiance (or intensity) and its spectrum;
    /// a light sample's spectrum is that one scaled to the sample's RGB.
    lights: Vec<(f32, RgbIlluminant)>,
    background: RgbIlluminant,
    /// Distinct reflectance colours fitted, and the largest error of their RGB round trip
    /// with the colour it belongs to (a saturated colour that no smooth reflectance reaches).
    fitted: usize,
    worst_fit: (f32, Vec3),
}

impl SpectralScene {
    /// Fits every colour of `scene` (each distinct one once).
    pub fn new(scene: &RenderScene) -> Self {
        let mut reflectances: Vec<(Vec3, RgbSpectrum)> = Vec::new();
        let mut illuminants: Vec<(Vec3, RgbIlluminant)> = Vec::new();
        let mut reflectance = |rgb: Vec3| match reflectances.iter().find(|(c, _)| *c == rgb) {
            Some(&(_, s)) => s,
            None => {
                let s = RgbSpectrum::fit(rgb);
                reflectances.push((rgb, s));
                s
            }
        };
        let mut illuminant = |rgb: Vec3| match illuminants.iter().find(|(c, _)| *c == rgb) {
            Some(&(_, s)) => s,
            None => {
                let s = RgbIlluminant::new(rgb);
                illuminants.push((rgb, s));
                s
            }
        };
        let surfaces = scene
            .surfaces
            .iter()
            .map(|o| SurfaceSpectra {
                colour: reflectance(o.bsdf.base_color()),
                emission: illuminant(o.emission),
            })
            .collect();
        let lights = scene
            .lights
            .lights
            .iter()
            .map(|l| {
                let rgb = match l {
                    Light::Point { intensity, .. } => *intensity,
                    Light::Triangle { le, .. } | Light::Sphere { le, .. } => *le,
                    Light::Shape(s) => s.le,
                };
                (rgb.max_element(), illuminant(rgb))
            })
            .collect();
        let background = illuminant(scene.background);
        let mut worst_fit = (0.0f32, Vec3::ZERO);
        for (rgb, s) in &reflectances {
            let error =
                (reflectance_to_rgb(|nm| s.eval(nm)) - rgb.clamp(Vec3::ZERO, Vec3::ONE)).abs().max_element();
            if error > worst_fit.0 {
                worst_fit = (error, *rgb);
            }
        }
        Self { surfaces, lights, background, fitted: reflectances.len(), worst_fit }
    }

    /// One line for the render's notes: the colours fitted and the worst round trip.
    pub fn summary(&self) -> String {
        let (error, rgb) = self.worst_fit;
        let worst = match error > 0.0 {
            true => format!(
                "largest RGB round-trip error {error:.1e} (colour {:.3}, {:.3}, {:.3})",
                rgb.x, rgb.y, rgb.z
            ),
            false => "every round trip exact".to_string(),
        };
        format!("spectral: {} reflectance colours up-sampled; {worst}", self.fitted)
    }
}

/// The BSDF of a vertex with its colour set to one (sampled and evaluated by the RGB code),
/// the colour per wavelength, and the glass's index at the hero wavelength when it disperses.
fn unit_bsdf(bsdf: Bsdf, dispersion: Option<&Dispersion>, lambda: &mut Wavelengths) -> Bsdf {
    match bsdf {
        Bsdf::Lambert { .. } => Bsdf::Lambert { albedo: Vec3::ONE },
        Bsdf::Metal { alpha, .. } => Bsdf::Metal { f0: Vec3::ONE, alpha },
        Bsdf::Dielectric { eta, .. } => match dispersion {
            Some(law) => {
                lambda.terminate_secondary();
                Bsdf::Dielectric { eta: law.index_at(f64::from(lambda.hero_nm())) as f32, tint: Vec3::ONE }
            }
            None => Bsdf::Dielectric { eta, tint: Vec3::ONE },
        },
    }
}

/// What the colour contributes to `f(wo, wi)` at each wavelength: the albedo, Schlick's
/// Fresnel of the metal's `f0` at the half vector, or the glass's tint on transmission.
#[inline]
fn colour_factor(bsdf: &Bsdf, colour: Vec4, wo: Vec3, wi: Vec3) -> Vec4 {
    match bsdf {
        Bsdf::Lambert { .. } => colour,
        Bsdf::Metal { .. } => {
            let m = (wo + wi).normalize_or_zero();
            let cos = wo.dot(m);
            let a = fresnel_schlick(colour.truncate(), cos);
            let b = fresnel_schlick(Vec3::splat(colour.w), cos);
            a.extend(b.x)
        }
        Bsdf::Dielectric { .. } => {
            if wo.z * wi.z < 0.0 {
                colour
            } else {
                Vec4::ONE
            }
        }
    }
}

/// The spectral radiance along camera ray `ray`, returned as the film's linear sRGB, with at
/// most `max_depth` bounces; `u_lambda` in [0, 1) chooses the wavelengths.
pub fn li(
    scene: &RenderScene,
    spectra: &SpectralScene,
    mut ray: Ray,
    max_depth: u32,
    u_lambda: f32,
    sampler: &mut Sampler,
    rays: &mut u64,
) -> Vec3 {
    let mut lambda = Wavelengths::sample_visible(u_lambda);
    let mut l = Vec4::ZERO;
    let mut beta = Vec4::ONE;
    let mut specular = true;
    let mut prev_pdf = 0.0f32;
    let mut prev_point = ray.origin;
    let mut depth = 0u32;
    loop {
        *rays += 1;
        let Some(hit) = scene.intersect(&ray) else {
            l += beta * spectra.background.eval4(lambda.nm);
            break;
        };
        let optics = &scene.surfaces[hit.surface as usize];
        let spectrum = &spectra.surfaces[hit.surface as usize];
        if hit.front_face && optics.emission != Vec3::ZERO {
            let w = if specular {
                1.0
            } else {
                power_heuristic(prev_pdf, scene.light_pdf(prev_point, ray.dir, &hit))
            };
            l += beta * spectrum.emission.eval4(lambda.nm) * w;
        }
        if depth >= max_depth {
            break;
        }
        sampler.start_bounce(depth);
        let (u_light, u_bsdf) = (sampler.get_2d(), sampler.get_2d());
        depth += 1;
        let u_roulette = if depth >= RR_START_DEPTH { sampler.get_1d() } else { 0.0 };
        let dispersion = scene.dispersion.get(hit.surface as usize).and_then(Option::as_ref);
        let bsdf = unit_bsdf(optics.bsdf, dispersion, &mut lambda);
        if lambda.secondary_terminated() {
            beta *= Vec4::X;
        }
        let colour = spectrum.colour.eval4(lambda.nm);
        let frame = Frame::new(hit.normal);
        let wo = frame.to_local(-ray.dir);
        if !bsdf.is_delta() {
            l += beta
                * direct(
                    scene,
                    spectra,
                    &hit,
                    &frame,
                    wo,
                    (&bsdf, &optics.bsdf, colour),
                    &lambda,
                    u_light,
                    rays,
                );
        }
        let u_lobe = if bsdf.has_lobes() { sampler.get_1d() } else { 0.0 };
        let Some(s) = bsdf.sample(wo, u_bsdf, u_lobe) else {
            break;
        };
        beta *= s.weight().x * colour_factor(&optics.bsdf, colour, wo, s.wi);
        specular = s.specular;
        prev_pdf = s.pdf;
        prev_point = hit.point;
        ray = Ray::spawn(hit.point, hit.normal, frame.to_world(s.wi));
        if depth >= RR_START_DEPTH {
            let q = beta.max_element().min(1.0);
            if q <= 0.0 || u_roulette >= q {
                break;
            }
            beta /= q;
        } else if beta == Vec4::ZERO {
            break;
        }
    }
    lambda.to_rgb(l)
}

/// Next-event estimation at a vertex, per wavelength: as [`super::path::sample_direct`] with
/// the light's spectrum scaled to the sample's RGB and the BSDF's colour per wavelength.
#[allow(clippy::too_many_arguments)]
#[inline]
fn direct(
    scene: &RenderScene,
    spectra: &SpectralScene,
    hit: &Hit,
    frame: &Frame,
    wo: Vec3,
    (bsdf, coloured, colour): (&Bsdf, &Bsdf, Vec4),
    lambda: &Wavelengths,
    u: Vec2,
    rays: &mut u64,
) -> Vec4 {
    let Some((index, pmf, ux)) = scene.lights.choose_reusing(u.x) else {
        return Vec4::ZERO;
    };
    let Some(ls) = scene.lights.lights[index].sample(hit.point, Vec2::new(ux, u.y)) else {
        return Vec4::ZERO;
    };
    let wi = frame.to_local(ls.wi);
    let f = bsdf.eval(wo, wi).x * wi.z.abs();
    let (light_max, spectrum) = spectra.lights[index];
    if f == 0.0 || ls.li == Vec3::ZERO || light_max <= 0.0 {
        return Vec4::ZERO;
    }
    *rays += 1;
    if scene.light_blocked(hit, &ls) {
        return Vec4::ZERO;
    }
    let li = spectrum.eval4(lambda.nm) * (ls.li.max_element() / light_max);
    let fc = colour_factor(coloured, colour, wo, wi) * f;
    if ls.delta {
        return fc * li / pmf;
    }
    let light_pdf = ls.pdf * pmf;
    let w = power_heuristic(light_pdf, bsdf.pdf(wo, wi));
    fc * li * (w / light_pdf)
}
