//! The render's options as a user gives them: the flags of `propsim render`, the keyword
//! arguments of the Python module's `render()`, one type with one set of defaults (the scene
//! file's `[render]` and `[camera]` tables fill what they leave out), and how they become
//! settings and a camera.

use anyhow::anyhow;
use glam::Vec3;
use serde::Deserialize;

use super::film::Display;
use super::medium::Medium;
use super::sppm::PhotonSettings;
use super::{Camera, IntegratorKind, RenderSettings};
use crate::scene::World;

/// Image size when neither the scene nor the command line gives one.
pub const DEFAULT_SIZE: (u32, u32) = (640, 480);
/// Memory a render holds per pixel, bytes: film and tile results (12 bytes of float RGB each)
/// and the 8-bit image written from them (16384 x 16384 peaked at 6.4 GB).
pub const BYTES_PER_PIXEL: u64 = 28;

/// What a user may set for one render; `None` means "the scene's value, else the built-in
/// default".
#[derive(clap::Args, Deserialize, Debug, Clone, PartialEq, Default)]
#[serde(default, deny_unknown_fields)]
pub struct RenderOptions {
    /// Image width in pixels (default: the scene's, else 640).
    #[arg(long)]
    pub width: Option<u32>,
    /// Image height in pixels (default: the scene's, else 480).
    #[arg(long)]
    pub height: Option<u32>,
    /// Samples per pixel (default: the scene's, else 64).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Maximum bounces; 1 = direct light only (default: the scene's, else 8).
    #[arg(long = "max-depth")]
    pub max_depth: Option<u32>,
    /// raycast, whitted, distributed, path, light (light tracing), bdpt (bidirectional path
    /// tracing), sppm (stochastic progressive photon mapping), ppm (progressive photon
    /// mapping), radiosity (hierarchical radiosity), pssmlt (Metropolis light transport) or
    /// volpath (volumetric path tracing through a fog, --fog-*, and the scene's [[media]]),
    /// raymarch (ray marching through the same media, single scattering), spectral
    /// (spectral path tracing, dispersive glass) or vcm (vertex connection and merging:
    /// bdpt plus photon merges) (default: the scene's, else path).
    #[arg(long)]
    pub integrator: Option<String>,
    /// Spectral rendering: the same as --integrator spectral.
    #[arg(long)]
    pub spectral: bool,
    /// Random seed: the same seed gives the same image for any thread count.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Camera position X,Y,Z (default: the scene's camera, else an automatic view).
    #[arg(long, value_parser = crate::scene::parse_point, allow_hyphen_values = true)]
    pub eye: Option<[f32; 3]>,
    /// Point looked at, X,Y,Z.
    #[arg(long, value_parser = crate::scene::parse_point, allow_hyphen_values = true)]
    pub target: Option<[f32; 3]>,
    /// Up direction, X,Y,Z (default 0,0,1).
    #[arg(long, value_parser = crate::scene::parse_point, allow_hyphen_values = true)]
    pub up: Option<[f32; 3]>,
    /// Vertical field of view, degrees.
    #[arg(long = "fov-deg")]
    pub fov_deg: Option<f32>,
    /// PNG exposure in stops: radiance x 2^EV before the tone map (default: the scene's, else
    /// 0). EXR output stays linear.
    #[arg(long = "exposure", value_name = "EV")]
    pub exposure_ev: Option<f32>,
    /// PNG tone map: aces (filmic, the default), reinhard (on luminance) or none (clip at 1).
    #[arg(long = "tone-map", value_name = "aces|reinhard|none")]
    pub tone_map: Option<String>,
    /// Largest luminance of each sample's indirect light (path and distributed integrators):
    /// removes fireflies at the cost of bias (some light is lost). Default: no clamp.
    #[arg(long = "clamp-indirect", value_name = "LUMINANCE")]
    pub clamp_indirect: Option<f32>,
    /// volpath and raymarch: a homogeneous fog's absorption coefficient R,G,B, 1/m (default 0,0,0).
    #[arg(long = "fog-sigma-a", value_parser = crate::scene::parse_point, value_name = "R,G,B", allow_hyphen_values = true)]
    pub fog_sigma_a: Option<[f32; 3]>,
    /// volpath and raymarch: the fog's scattering coefficient R,G,B, 1/m (default 0,0,0).
    #[arg(long = "fog-sigma-s", value_parser = crate::scene::parse_point, value_name = "R,G,B", allow_hyphen_values = true)]
    pub fog_sigma_s: Option<[f32; 3]>,
    /// volpath and raymarch: the fog's Henyey-Greenstein asymmetry g in (-1, 1) (default 0, isotropic).
    #[arg(long = "fog-g", allow_hyphen_values = true)]
    pub fog_g: Option<f32>,
    /// raymarch: the march step, metres (default: a quarter of the densest channel's mean
    /// free path, or of the grid's majorant, within 1/1024 to 1/16 of each segment).
    #[arg(long = "raymarch-step", value_name = "METRES", allow_hyphen_values = true)]
    pub raymarch_step_m: Option<f32>,
    /// sppm, ppm and vcm: iterations, each one camera sample a pixel and one photon pass (default:
    /// the samples per pixel, as pbrt-v4 reads its pixel samples).
    #[arg(long)]
    pub iterations: Option<u32>,
    /// sppm, ppm and vcm: photons (vcm: light subpaths, at least one a pixel) traced an
    /// iteration (default: one a pixel, as pbrt-v4).
    #[arg(long)]
    pub photons: Option<u64>,
    /// sppm and ppm: initial gather radius, metres, shrunk where a pilot pass finds photons
    /// crowding, then as photons arrive (alpha 2/3) (default: the radius at which the median
    /// pixel expects 50 photons an iteration). vcm: the initial merging radius, shrinking as
    /// i^-1/8 (default: 2 % of the light vertices' box diagonal at 1024 light subpaths an
    /// iteration, times sqrt(1024 / subpaths)).
    #[arg(long = "sppm-radius", value_name = "METRES", allow_hyphen_values = true)]
    pub sppm_radius_m: Option<f32>,
    /// The radiosity integrator's options.
    #[command(flatten)]
    pub radiosity: super::radiosity::RadiosityFlags,
    /// The pssmlt integrator's options.
    #[command(flatten)]
    pub mlt: super::pssmlt::MltFlags,
}

/// The settings the scene suggests, overridden by the flags.
pub fn settings(world: &World, options: &RenderOptions) -> anyhow::Result<RenderSettings> {
    let desc = world.scene.desc.render.clone().unwrap_or_default();
    if options.spectral
        && let Some(other) = options.integrator.as_deref().filter(|name| *name != "spectral")
    {
        anyhow::bail!("--spectral means --integrator spectral, not {other}");
    }
    let integrator_name = match options.spectral {
        true => "spectral".to_string(),
        false => options.integrator.clone().or(desc.integrator).unwrap_or_else(|| "path".into()),
    };
    let integrator: IntegratorKind =
        integrator_name.parse().map_err(|e: String| anyhow!("--integrator: {e}"))?;
    let d = RenderSettings::default();
    let tone_map = match options.tone_map.clone().or(desc.tone_map) {
        Some(name) => name.parse().map_err(|e: String| anyhow!("--tone-map: {e}"))?,
        None => d.display.tone_map,
    };
    let exposure_ev = options.exposure_ev.or(desc.exposure_ev).unwrap_or(d.display.exposure_ev);
    let display = Display { exposure_ev, tone_map };
    display.validate().map_err(|e| anyhow!("--exposure: {e}"))?;
    refuse_foreign_flags(options, integrator, &integrator_name)?;
    if options.iterations == Some(0) {
        anyhow::bail!("--iterations 0: must be between 1 and {}", super::MAX_SPP);
    }
    let photons =
        PhotonSettings { initial_radius_m: options.sppm_radius_m, photons_per_iteration: options.photons };
    photons.validate().map_err(|e| anyhow!("{e}"))?;
    // The fog: the flags (volpath and raymarch only: refused above with the others), else the scene's
    // `[render] fog_*` (which the other integrators ignore).
    let sigma_a = options.fog_sigma_a.or(desc.fog_sigma_a);
    let sigma_s = options.fog_sigma_s.or(desc.fog_sigma_s);
    let g = options.fog_g.or(desc.fog_g);
    let fog = if sigma_a.is_some() || sigma_s.is_some() || g.is_some() {
        let fog = Medium {
            sigma_a_per_m: Vec3::from(sigma_a.unwrap_or([0.0; 3])),
            sigma_s_per_m: Vec3::from(sigma_s.unwrap_or([0.0; 3])),
            g: g.unwrap_or(0.0),
        };
        fog.validate().map_err(|e| anyhow!("{e}"))?;
        if let Some(m) = world.scene.media.iter().find(|m| m.boundary.is_empty()) {
            anyhow::bail!(
                "{}: the fog (fog_* or --fog-*) and medium \"{}\" (a [[media]] entry without a boundary) both fill the scene; keep one",
                world.scene.path.display(),
                m.name
            );
        }
        Some(fog)
    } else {
        None
    };
    let s = RenderSettings {
        width: options.width.or(desc.width).unwrap_or(DEFAULT_SIZE.0),
        height: options.height.or(desc.height).unwrap_or(DEFAULT_SIZE.1),
        spp: options.iterations.or(options.spp).or(desc.spp).unwrap_or(d.spp),
        max_depth: options.max_depth.or(desc.max_depth).unwrap_or(d.max_depth),
        integrator,
        seed: options.seed,
        background: None,
        display,
        clamp_indirect: options.clamp_indirect,
        photons,
        radiosity: options.radiosity.options(),
        mlt: options.mlt.options(),
        fog,
        raymarch_step_m: options.raymarch_step_m,
    };
    s.validate().map_err(|e| anyhow!("{e}"))?;
    Ok(s)
}

/// Refuses a flag of one integrator given with another (`--mlt-chains` with `path`): it
/// would have no effect, and a silent no-op hides a typo in `--integrator`. The error is one
/// line naming the flag and both integrators.
fn refuse_foreign_flags(
    options: &RenderOptions,
    integrator: IntegratorKind,
    name: &str,
) -> anyhow::Result<()> {
    let photon_flags = [
        ("--iterations", options.iterations.is_some()),
        ("--photons", options.photons.is_some()),
        ("--sppm-radius", options.sppm_radius_m.is_some()),
    ]
    .into_iter()
    .filter_map(|(flag, given)| given.then_some(flag))
    .collect();
    let fog_flags = [
        ("--fog-sigma-a", options.fog_sigma_a.is_some()),
        ("--fog-sigma-s", options.fog_sigma_s.is_some()),
        ("--fog-g", options.fog_g.is_some()),
    ]
    .into_iter()
    .filter_map(|(flag, given)| given.then_some(flag))
    .collect();
    let march_flags = if options.raymarch_step_m.is_some() { vec!["--raymarch-step"] } else { vec![] };
    let clamp_flags = if options.clamp_indirect.is_some() { vec!["--clamp-indirect"] } else { vec![] };
    let owners: [(Vec<&str>, bool, &str); 6] = [
        (
            photon_flags,
            matches!(integrator, IntegratorKind::Sppm | IntegratorKind::Ppm | IntegratorKind::Vcm),
            "sppm, ppm or vcm",
        ),
        (options.mlt.given(), integrator == IntegratorKind::Pssmlt, "pssmlt"),
        (options.radiosity.given(), integrator == IntegratorKind::Radiosity, "radiosity"),
        (
            fog_flags,
            matches!(integrator, IntegratorKind::Volpath | IntegratorKind::Raymarch),
            "volpath or raymarch",
        ),
        (march_flags, integrator == IntegratorKind::Raymarch, "raymarch"),
        (
            clamp_flags,
            matches!(integrator, IntegratorKind::Path | IntegratorKind::Distributed),
            "path or distributed",
        ),
    ];
    for (flags, applies, owner) in owners {
        if let Some(flag) = flags.first()
            && !applies
        {
            anyhow::bail!("{flag} applies to --integrator {owner}, not {name}");
        }
    }
    Ok(())
}

/// The camera: the scene's `[camera]` or the automatic one ([`super::auto_camera`]:
/// inside a closed room, else outside the bounds), then the flags.
pub fn camera(world: &World, options: &RenderOptions, aspect: f32) -> anyhow::Result<Camera> {
    let (eye, target, up, fov, lens) = match &world.scene.desc.camera {
        Some(c) => (
            Vec3::from(c.eye),
            Vec3::from(c.target),
            Vec3::from(c.up),
            c.fov_deg,
            (c.aperture_radius_m, c.focus_distance_m),
        ),
        None => {
            let up = options.up.map_or(Vec3::Z, Vec3::from);
            let v = super::auto_camera(world, up, options.fov_deg);
            (v.eye, v.target, up, v.fov_deg, (0.0, None))
        }
    };
    let eye = options.eye.map_or(eye, Vec3::from);
    let target = options.target.map_or(target, Vec3::from);
    let up = options.up.map_or(up, Vec3::from);
    let fov = options.fov_deg.unwrap_or(fov);
    let mut cam = Camera::look_at(eye, target, up, fov, aspect).map_err(|e| anyhow!("{e}"))?;
    cam.set_lens(lens.0, lens.1).map_err(|e| anyhow!("{e}"))?;
    Ok(cam)
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cmd {
        #[command(flatten)]
        options: RenderOptions,
    }

    #[test]
    fn the_command_line_and_the_library_share_one_set_of_defaults() {
        let parsed = Cmd::try_parse_from(["render"]).expect("no flags parse");
        assert_eq!(parsed.options, RenderOptions::default());
        let from_json: RenderOptions = serde_json::from_str("{}").expect("empty options parse");
        assert_eq!(from_json, RenderOptions::default());
    }
}
