//! Radiosity: the view-independent solution of diffuse light transport over patches of the
//! scene's surfaces (Goral, Torrance, Greenberg and Battaile 1984; Cohen and Wallace 1993),
//! rendered through the camera by `--integrator radiosity`.
//!
//! - [`patches`]: the mesh triangles as roots of an element hierarchy (midpoint subdivision),
//!   two-sided, with each surface's diffuse stand-in;
//! - [`form_factor`]: form factors by ray casting on the shared core (the closed-form point
//!   form factor, integrated over the receiver, visibility by shadow rays);
//! - [`hierarchical`]: hierarchical radiosity with BF refinement (Hanrahan, Salzman and
//!   Aupperle 1991), or the full matrix of the finest patches;
//! - [`solve`]: Jacobi iteration with gather and push-pull, to a tolerance.
//!
//! A camera ray that hits a mesh triangle shows the radiance of the leaf element it hits, on
//! the side it hits; emitters show their emission plus what they reflect, as in the path
//! tracer. Only mesh triangles are patched: the integrator refuses scenes with spheres,
//! shapes, instances or point lights ([`supported`]). Light leaving an open scene is lost and
//! the background lights nothing (it shows where camera rays escape).
//!
//! Deterministic: elements are created in a fixed order, each form factor draws from its own
//! random stream keyed by the seed and the pair, and the solve is Jacobi (every sweep reads
//! only the previous one), so every thread count and every MPI rank gets the same solution.

pub mod form_factor;
pub mod hierarchical;
pub mod patches;
pub mod solve;

use std::time::Instant;

use glam::Vec3;
use serde::Deserialize;

use super::RenderScene;
use crate::core::{Hit, PrimitiveKind};
use hierarchical::LinkSettings;
use patches::Hierarchy;

/// How the patches are linked.
#[derive(clap::ValueEnum, Deserialize, Debug, Clone, Copy, PartialEq, Eq, Default)]
#[serde(rename_all = "lowercase")]
pub enum Method {
    /// Hierarchical radiosity with BF refinement (Hanrahan et al. 1991).
    #[default]
    Hierarchical,
    /// Every pair of finest patches (the classical radiosity matrix): O(n^2) form factors.
    Matrix,
}

/// The radiosity integrator's options (flags `--radiosity-*`, given as [`RadiosityFlags`]).
#[derive(Deserialize, Debug, Clone, PartialEq)]
#[serde(default, deny_unknown_fields)]
pub struct RadiosityOptions {
    /// Linking: hierarchical (Hanrahan et al. 1991, BF refinement) or matrix (every pair of
    /// finest patches).
    pub method: Method,
    /// Target number of finest patches; the finest patch area is the meshes' total area over
    /// this.
    pub patches: u32,
    /// Finest patch area, m^2 (overrides `patches`).
    pub patch_area_m2: Option<f32>,
    /// Most patches (elements of every level) the solution may create; needing more is an
    /// error.
    pub max_patches: u32,
    /// BF refinement threshold, as a fraction of the scene's mean radiance (its furnace
    /// estimate): a link carrying more radiance than this is split.
    pub refine: f32,
    /// Convergence tolerance of the iterative solution, as a fraction of the scene's mean
    /// radiance (its furnace estimate).
    pub tolerance: f32,
    /// Points (and shadow rays) per form factor on the receiver, rounded down to a square.
    pub samples: u32,
}

/// The `--radiosity-*` flags as a user gives them: `None` is a flag not given (its
/// [`RadiosityOptions::default`] value then), so that a flag given with another integrator
/// can be refused by name ([`RadiosityFlags::given`]) rather than silently ignored.
#[derive(clap::Args, Deserialize, Debug, Clone, PartialEq, Default)]
#[serde(default, deny_unknown_fields)]
pub struct RadiosityFlags {
    /// Radiosity linking: hierarchical (Hanrahan et al. 1991, BF refinement) or matrix (every
    /// pair of finest patches) (default: hierarchical).
    #[arg(long = "radiosity-method", value_enum)]
    pub method: Option<Method>,
    /// Radiosity: target number of finest patches; the finest patch area is the meshes' total
    /// area over this (default: 4096).
    #[arg(long = "radiosity-patches")]
    pub patches: Option<u32>,
    /// Radiosity: finest patch area, m^2 (overrides --radiosity-patches).
    #[arg(long = "radiosity-patch-area", value_name = "M2")]
    pub patch_area_m2: Option<f32>,
    /// Radiosity: most patches (elements of every level) the solution may create; needing
    /// more is an error (default: 200000).
    #[arg(long = "radiosity-max-patches")]
    pub max_patches: Option<u32>,
    /// Radiosity: BF refinement threshold, as a fraction of the scene's mean radiance (its
    /// furnace estimate): a link carrying more radiance than this is split (default: 0.001).
    #[arg(long = "radiosity-refine")]
    pub refine: Option<f32>,
    /// Radiosity: convergence tolerance of the iterative solution, as a fraction of the
    /// scene's mean radiance (its furnace estimate) (default: 0.0001).
    #[arg(long = "radiosity-tolerance")]
    pub tolerance: Option<f32>,
    /// Radiosity: points (and shadow rays) per form factor on the receiver, rounded down to a
    /// square (default: 16).
    #[arg(long = "radiosity-samples")]
    pub samples: Option<u32>,
}

impl RadiosityFlags {
    /// The flags given, in the order of `--help`.
    pub fn given(&self) -> Vec<&'static str> {
        [
            ("--radiosity-method", self.method.is_some()),
            ("--radiosity-patches", self.patches.is_some()),
            ("--radiosity-patch-area", self.patch_area_m2.is_some()),
            ("--radiosity-max-patches", self.max_patches.is_some()),
            ("--radiosity-refine", self.refine.is_some()),
            ("--radiosity-tolerance", self.tolerance.is_some()),
            ("--radiosity-samples", self.samples.is_some()),
        ]
        .into_iter()
        .filter_map(|(flag, given)| given.then_some(flag))
        .collect()
    }

    /// The options: each flag given, else its default.
    pub fn options(&self) -> RadiosityOptions {
        let d = RadiosityOptions::default();
        RadiosityOptions {
            method: self.method.unwrap_or(d.method),
            patches: self.patches.unwrap_or(d.patches),
            patch_area_m2: self.patch_area_m2.or(d.patch_area_m2),
            max_patches: self.max_patches.unwrap_or(d.max_patches),
            refine: self.refine.unwrap_or(d.refine),
            tolerance: self.tolerance.unwrap_or(d.tolerance),
            samples: self.samples.unwrap_or(d.samples),
        }
    }
}

impl Default for RadiosityOptions {
    fn default() -> Self {
        Self {
            method: Method::Hierarchical,
            patches: 4096,
            patch_area_m2: None,
            max_patches: 200_000,
            refine: 1.0e-3,
            tolerance: 1.0e-4,
            samples: 16,
        }
    }
}

impl RadiosityOptions {
    /// Checks the numbers; the error is one line naming the flag.
    pub fn validate(&self) -> Result<(), String> {
        if self.patches == 0 {
            return Err("--radiosity-patches 0: must be at least 1".into());
        }
        if let Some(a) = self.patch_area_m2
            && !(a.is_finite() && a > 0.0)
        {
            return Err(format!("--radiosity-patch-area {a}: must be a positive area in m^2"));
        }
        if self.max_patches == 0 {
            return Err("--radiosity-max-patches 0: must be at least 1".into());
        }
        if !(self.refine.is_finite() && self.refine >= 0.0) {
            return Err(format!("--radiosity-refine {}: must be finite, 0 or more", self.refine));
        }
        if !(self.tolerance.is_finite() && self.tolerance > 0.0) {
            return Err(format!("--radiosity-tolerance {}: must be finite and positive", self.tolerance));
        }
        if !(1..=4096).contains(&self.samples) {
            return Err(format!("--radiosity-samples {}: must be between 1 and 4096", self.samples));
        }
        Ok(())
    }
}

/// Why `scene` cannot be rendered by radiosity, if it cannot: it patches mesh triangles only.
pub fn supported(scene: &RenderScene) -> Result<(), String> {
    let a = scene.accel;
    let what = [
        (!a.spheres.is_empty(), "spheres"),
        (!a.shapes.is_empty(), "shapes"),
        (!a.sdfs.is_empty(), "signed distance fields"),
        (!a.instances.is_empty(), "instances"),
        (scene.lights.lights.iter().any(|l| matches!(l, super::Light::Point { .. })), "point lights"),
    ];
    let found: Vec<&str> = what.iter().filter(|(b, _)| *b).map(|(_, n)| *n).collect();
    if found.is_empty() {
        Ok(())
    } else {
        Err(format!(
            "--integrator radiosity: the scene has {}; radiosity patches mesh triangles lit by \
             emissive materials only (use --integrator path)",
            found.join(", ")
        ))
    }
}

/// A solved radiosity system and what it cost.
#[derive(Clone, Debug)]
pub struct Solution {
    /// The elements with their radiances.
    pub hierarchy: Hierarchy,
    /// Rays cast for the form factors.
    pub rays: u64,
    /// Jacobi sweeps, over every round.
    pub sweeps: u32,
    /// Rounds of solution (and BF refinement between them).
    pub rounds: usize,
    /// Finest patch area, m^2.
    pub min_area_m2: f32,
    /// Wall time, seconds.
    pub seconds: f64,
}

impl Solution {
    /// The radiance the camera sees at `hit` (reached along a ray): the hit leaf's radiance on
    /// the side hit, black off the mesh.
    #[inline]
    pub fn radiance(&self, hit: &Hit) -> Vec3 {
        if hit.kind != PrimitiveKind::Triangle {
            return Vec3::ZERO;
        }
        match self.hierarchy.leaf_at(hit.primitive, hit.point) {
            Some(e) => self.hierarchy.elements[e as usize].radiance[usize::from(!hit.front_face)],
            None => Vec3::ZERO,
        }
    }

    /// One line: what the solution holds and cost.
    pub fn summary(&self) -> String {
        format!(
            "radiosity: {} elements ({} leaves, finest {:.3e} m^2), {} links, {} rounds, {} sweeps, {:.2} M form-factor rays, {:.2} s",
            self.hierarchy.elements.len(),
            self.hierarchy.leaves(),
            self.min_area_m2,
            self.hierarchy.links(),
            self.rounds,
            self.sweeps,
            self.rays as f64 / 1e6,
            self.seconds
        )
    }
}

/// The scale of the scene's radiances, for the relative thresholds: the furnace estimate
/// `(sum A Le / sum A) / (1 - rho_mean)` (luminances, area-weighted means over the roots;
/// `1 - rho_mean` at least 0.01), the mean radiance of a closed room with that emission and
/// reflectance spread evenly.
pub fn reference_radiance(h: &Hierarchy) -> f32 {
    let (mut area, mut emitted, mut reflected) = (0.0f64, 0.0f64, 0.0f64);
    for e in &h.elements {
        let a = f64::from(e.tri.area_m2);
        area += a;
        emitted += a * f64::from(super::film::luminance(e.material.emission));
        reflected += a * f64::from(super::film::luminance(e.material.rho));
    }
    if area <= 0.0 {
        return 0.0;
    }
    ((emitted / area) / (1.0 - reflected / area).max(0.01)) as f32
}

/// Solves the radiosity of `scene` with `options`, its form factors seeded by `seed`.
pub fn solve_scene(scene: &RenderScene, options: &RadiosityOptions, seed: u64) -> Result<Solution, String> {
    let start = Instant::now();
    options.validate()?;
    supported(scene)?;
    let mut h = Hierarchy::roots(scene, options.max_patches as usize)?;
    let total_area: f32 = h.elements.iter().map(|e| e.tri.area_m2).sum();
    let min_area_m2 = options.patch_area_m2.unwrap_or(total_area / options.patches as f32);
    let l_ref = reference_radiance(&h);
    let s = LinkSettings { min_area_m2, threshold: options.refine * l_ref, samples: options.samples, seed };
    let tolerance = options.tolerance * l_ref;
    let mut rounds = 1;
    let mut sweeps = 0;
    let mut rays;
    if l_ref <= 0.0 || h.elements.is_empty() {
        // Nothing emits: every radiance is zero.
        return Ok(Solution { hierarchy: h, rays: 0, sweeps: 0, rounds: 0, min_area_m2, seconds: 0.0 });
    }
    match options.method {
        Method::Matrix => {
            rays = hierarchical::link_matrix(&mut h, scene.accel, &s)?;
            sweeps += solve::solve(&mut h, tolerance)?;
        }
        Method::Hierarchical => {
            rays = hierarchical::link_roots(&mut h, scene.accel, &s)?;
            sweeps += solve::solve(&mut h, tolerance)?;
            while rounds < hierarchical::MAX_ROUNDS {
                let (refined, r) = hierarchical::refine_links(&mut h, scene.accel, &s)?;
                rays += r;
                if refined == 0 {
                    break;
                }
                rounds += 1;
                sweeps += solve::solve(&mut h, tolerance)?;
            }
        }
    }
    Ok(Solution { hierarchy: h, rays, sweeps, rounds, min_area_m2, seconds: start.elapsed().as_secs_f64() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use clap::Parser;

    #[derive(Parser)]
    struct Cmd {
        #[command(flatten)]
        flags: RadiosityFlags,
    }

    #[test]
    fn the_command_line_and_the_library_share_one_set_of_defaults() {
        let parsed = Cmd::try_parse_from(["render"]).expect("no flags parse");
        assert_eq!(parsed.flags, RadiosityFlags::default());
        assert!(parsed.flags.given().is_empty());
        assert_eq!(parsed.flags.options(), RadiosityOptions::default());
        let from_json: RadiosityOptions = serde_json::from_str("{}").expect("empty options parse");
        assert_eq!(from_json, RadiosityOptions::default());
        assert!(RadiosityOptions::default().validate().is_ok());
        let parsed =
            Cmd::try_parse_from(["render", "--radiosity-samples", "4", "--radiosity-method", "matrix"])
                .expect("flags parse");
        assert_eq!(parsed.flags.given(), ["--radiosity-method", "--radiosity-samples"]);
        let o = parsed.flags.options();
        assert_eq!(
            (o.samples, o.method, o.patches),
            (4, Method::Matrix, RadiosityOptions::default().patches)
        );
    }
}
