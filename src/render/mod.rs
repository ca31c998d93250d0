//! The image simulator: a camera, BSDFs, lights and the integrators (`raycast`, `whitted`,
//! `distributed`, `path`, from the lights `light` and `bdpt`, the photon mappers `sppm` and
//! `ppm`, vertex connection and merging `vcm`, Metropolis light transport `pssmlt`, the view-independent `radiosity`, and through
//! participating media `volpath` and `raymarch`) over the shared tracing core.
//!
//! Rendering is tile-parallel (rayon) and deterministic: pixel `i` draws all its random numbers
//! from its own stream `rng::stream(seed, PIXEL_DOMAIN, i)`, so the image is bit-identical for
//! any thread count. Depends on `crate::core` and `crate::scene` only.
//!
//! ```no_run
//! use propsim::render::{self, RenderSettings};
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let scene = propsim::scene::load("builtin:cornell_box_classic".as_ref(), &Default::default())?;
//! let world = propsim::scene::World::build(scene);
//! let settings = RenderSettings { spp: 16, ..RenderSettings::default() };
//! let image = render::render_world(&world, &settings)?;
//! image.film.write("out/cornell.png".as_ref())?;
//! # Ok(())
//! # }
//! ```

pub mod bdpt;
pub mod bsdf;
pub mod camera;
pub mod distributed;
pub mod film;
pub mod job;
pub mod lanes;
pub mod light;
pub mod lights;
pub mod media;
pub mod medium;
pub mod options;
pub mod path;
pub mod photon_grid;
pub mod point_grid;
pub mod pssmlt;
pub mod radiosity;
pub mod raycast;
pub mod raymarch;
pub mod sampler;
pub mod shape_light;
pub mod spectral;
pub mod spectrum;
pub mod splat;
pub mod sppm;
pub mod vcm;
pub mod volpath;
pub mod whitted;

use std::str::FromStr;
use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use rand::RngCore;

use crate::core::flat::FlatRay;
use crate::core::rng::{Rng64, stream, uniform};
use crate::core::sampling::orthonormal_basis;
use crate::core::{Accel, Hit, Instance, PrimitiveKind, Ray, Sphere, TriangleMesh};
use crate::dist::Cluster;
use crate::render::sampler::Sampler;
use crate::scene::dispersion::Dispersion;
use crate::scene::materials::{OpticalKind, OpticalProps};
use crate::scene::{Surface, World};

pub use bsdf::Bsdf;
pub use camera::Camera;
pub use film::Film;
pub use job::RenderPlan;
pub use lights::{Light, Lights};
pub use options::RenderOptions;

/// Random-stream domain of the per-pixel streams (see [`crate::core::rng::stream`]).
pub const PIXEL_DOMAIN: u64 = 0x5245_4e44; // "REND"
/// Largest accepted image side, pixels.
pub const MAX_IMAGE_SIDE: u32 = 16_384;
/// Largest accepted samples per pixel.
pub const MAX_SPP: u32 = 1 << 20;
/// Largest accepted path depth.
pub const MAX_DEPTH: u32 = 1024;
/// Tile side in pixels: the unit of parallel work.
pub const TILE: u32 = 16;

/// The tiles (top-left corners) of a `width` x `height` image that `share` renders: tiles
/// numbered row-major and dealt round-robin over the processes.
pub(crate) fn owned_tiles(share: &crate::core::Share, width: u32, height: u32) -> Vec<(u32, u32)> {
    (0..height.div_ceil(TILE))
        .flat_map(|ty| (0..width.div_ceil(TILE)).map(move |tx| (tx * TILE, ty * TILE)))
        .enumerate()
        .filter(|(i, _)| share.owns(*i as u64))
        .map(|(_, t)| t)
        .collect()
}

/// The image indices of the pixels of the tile at `(x0, y0)`, in the order they are rendered
/// (row-major within the tile).
pub(crate) fn tile_pixels(x0: u32, y0: u32, width: u32, height: u32) -> impl Iterator<Item = usize> {
    let (x1, y1) = ((x0 + TILE).min(width), (y0 + TILE).min(height));
    (y0..y1).flat_map(move |y| (x0..x1).map(move |x| y as usize * width as usize + x as usize))
}

/// The integrators `--integrator` chooses from.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum IntegratorKind {
    /// Primary visibility and local Lambert/Blinn-Phong shading, no shadows.
    Raycast,
    /// Whitted 1980: shadow rays to point lights, mirror reflection, Fresnel-weighted refraction.
    Whitted,
    /// Cook, Porter, Carpenter 1984: jittered pixels, soft shadows, glossy reflection, depth of field.
    Distributed,
    /// Unidirectional path tracing with NEE and MIS (the default).
    #[default]
    Path,
    /// Light tracing: paths from the lights splatted onto the film through the camera.
    Light,
    /// Bidirectional path tracing, every connection strategy weighted by MIS (Veach 1997).
    Bdpt,
    /// Stochastic progressive photon mapping (Hachisuka and Jensen 2009), `spp` iterations.
    Sppm,
    /// Progressive photon mapping (Hachisuka, Ogaki, Jensen 2008): SPPM with visible points
    /// fixed after the first camera pass.
    Ppm,
    /// Hierarchical radiosity (Hanrahan et al. 1991), solved once and seen through the camera.
    Radiosity,
    /// Primary-sample-space Metropolis light transport over BDPT (Kelemen et al. 2002).
    Pssmlt,
    /// Volumetric path tracing through a fog (`RenderSettings::fog`) and the scene's
    /// `[[media]]` (homogeneous or density grids, global or inside closed meshes).
    Volpath,
    /// Ray marching through the same fog and media ([`raymarch`]): single scattering from
    /// the lights integrated along each segment, for comparison with `volpath`.
    Raymarch,
    /// Spectral path tracing ([`spectral`]): four wavelengths a path, RGB colours up-sampled
    /// to spectra, dispersive glass.
    Spectral,
    /// Vertex connection and merging ([`vcm`], Georgiev et al. 2012): BDPT's joins and photon
    /// merges under one MIS, `spp` iterations.
    Vcm,
}

impl IntegratorKind {
    /// Names of the integrators, in declaration order.
    pub const NAMES: [&'static str; 14] = [
        "raycast",
        "whitted",
        "distributed",
        "path",
        "light",
        "bdpt",
        "sppm",
        "ppm",
        "radiosity",
        "pssmlt",
        "volpath",
        "raymarch",
        "spectral",
        "vcm",
    ];

    /// The integrator's name.
    pub fn name(self) -> &'static str {
        Self::NAMES[self as usize]
    }

    /// Whether the pixel samples are jittered (stochastic integrators) or at strata centres.
    fn jitters(self) -> bool {
        matches!(
            self,
            Self::Distributed
                | Self::Path
                | Self::Bdpt
                | Self::Radiosity
                | Self::Volpath
                | Self::Raymarch
                | Self::Spectral
        )
    }

    /// Whether the integrator traces from the lights and splats onto the film (rendered by
    /// [`light::render_on`] or [`bdpt::render_on`], not pixel by pixel).
    pub fn splats(self) -> bool {
        matches!(self, Self::Light | Self::Bdpt | Self::Pssmlt | Self::Vcm)
    }
}

impl FromStr for IntegratorKind {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "raycast" => Ok(Self::Raycast),
            "whitted" => Ok(Self::Whitted),
            "distributed" => Ok(Self::Distributed),
            "path" => Ok(Self::Path),
            "light" => Ok(Self::Light),
            "bdpt" => Ok(Self::Bdpt),
            "sppm" => Ok(Self::Sppm),
            "ppm" => Ok(Self::Ppm),
            "radiosity" => Ok(Self::Radiosity),
            "pssmlt" => Ok(Self::Pssmlt),
            "volpath" => Ok(Self::Volpath),
            "raymarch" => Ok(Self::Raymarch),
            "spectral" => Ok(Self::Spectral),
            "vcm" => Ok(Self::Vcm),
            _ => Err(format!("unknown integrator \"{s}\" (known: {})", Self::NAMES.join(", "))),
        }
    }
}

/// What to render and how.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Samples per pixel.
    pub spp: u32,
    /// Maximum number of bounces (1 = direct lighting only; pbrt-v4's `maxdepth`).
    pub max_depth: u32,
    /// The integrator.
    pub integrator: IntegratorKind,
    /// Seed of the random number generator.
    pub seed: u64,
    /// Radiance of rays that leave the scene; `None` keeps the scene's (default black).
    pub background: Option<Vec3>,
    /// How a PNG shows the image (exposure and tone map); an EXR stays linear.
    pub display: film::Display,
    /// Largest luminance of a sample's indirect light (reaching the first visible surface
    /// after a bounce or more; path and distributed integrators): larger sums are scaled down
    /// to it. Biased (energy is lost) but removes fireflies; `None` (the default) leaves every
    /// sample as it is.
    pub clamp_indirect: Option<f32>,
    /// Photon-mapping settings (`sppm`, `ppm`; the others ignore them).
    pub photons: sppm::PhotonSettings,
    /// The radiosity integrator's options (patches, refinement, tolerance).
    pub radiosity: radiosity::RadiosityOptions,
    /// The pssmlt integrator's options (chains, mutations, steps, bootstrap).
    pub mlt: pssmlt::MltOptions,
    /// A homogeneous fog filling the scene, seen by `volpath` and `raymarch` (the others ignore it).
    pub fog: Option<medium::Medium>,
    /// The ray marcher's step, metres (`None`: [`raymarch::step_m`]'s default); `raymarch` only.
    pub raymarch_step_m: Option<f32>,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            width: 256,
            height: 256,
            spp: 64,
            max_depth: 8,
            integrator: IntegratorKind::Path,
            seed: 0,
            background: None,
            display: film::Display::default(),
            clamp_indirect: None,
            photons: sppm::PhotonSettings::default(),
            radiosity: radiosity::RadiosityOptions::default(),
            mlt: pssmlt::MltOptions::default(),
            fog: None,
            raymarch_step_m: None,
        }
    }
}

impl RenderSettings {
    /// Checks the numbers; the error is one line naming the bad setting.
    pub fn validate(&self) -> Result<(), String> {
        for (name, v) in [("width", self.width), ("height", self.height)] {
            if !(1..=MAX_IMAGE_SIDE).contains(&v) {
                return Err(format!("{name} {v}: must be between 1 and {MAX_IMAGE_SIDE} pixels"));
            }
        }
        if !(1..=MAX_SPP).contains(&self.spp) {
            return Err(format!("spp {}: must be between 1 and {MAX_SPP}", self.spp));
        }
        if self.max_depth > MAX_DEPTH {
            return Err(format!("max depth {}: must be at most {MAX_DEPTH}", self.max_depth));
        }
        if let Some(b) = self.background
            && !(b.is_finite() && b.min_element() >= 0.0)
        {
            return Err(format!("background {b} must be finite and non-negative"));
        }
        if let Some(h) = self.raymarch_step_m
            && !(h.is_finite() && h > 0.0)
        {
            return Err(format!("raymarch step {h} m: must be a finite length above 0"));
        }
        if let Some(c) = self.clamp_indirect
            && !(c.is_finite() && c >= 0.0)
        {
            return Err(format!("indirect clamp {c}: must be a finite luminance, 0 or more"));
        }
        self.photons.validate()?;
        self.radiosity.validate()?;
        self.mlt.validate(self.max_depth)?;
        self.display.validate()
    }
}

/// How a surface looks: its BSDF and emitted radiance.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfaceOptics {
    /// The BSDF.
    pub bsdf: Bsdf,
    /// Radiance emitted from the front face (the side the winding's normal points to).
    pub emission: Vec3,
}

impl SurfaceOptics {
    /// A Lambertian surface of albedo `albedo` that emits nothing.
    pub fn diffuse(albedo: Vec3) -> Self {
        Self { bsdf: Bsdf::Lambert { albedo }, emission: Vec3::ZERO }
    }

    /// From propsim's optical material properties; GGX `alpha = roughness^2` (Burley 2012).
    pub fn from_optical(o: &OpticalProps) -> Self {
        let bsdf = match o.kind {
            OpticalKind::Diffuse => Bsdf::Lambert { albedo: o.color },
            OpticalKind::Metal => Bsdf::Metal { f0: o.color, alpha: o.roughness * o.roughness },
            OpticalKind::Dielectric => Bsdf::Dielectric { eta: o.ior, tint: o.color },
        };
        Self { bsdf, emission: o.emission }
    }

    /// A surface's optics: the material's `optical` if it has one, else its MTL entry
    /// (`Kd`; `Ks`/`Ns` as a metal when specular dominates; `d < 1` or illum 4, 6, 7, 9 as glass
    /// of index `Ni`; `Ke`), else grey 0.7 Lambert.
    pub fn from_surface(s: &Surface) -> Self {
        if let Some(o) = s.material.as_ref().and_then(|m| m.optical.as_ref()) {
            return Self::from_optical(o);
        }
        let Some(m) = &s.mtl else {
            return Self::from_optical(&OpticalProps::default());
        };
        let v = |a: Option<[f32; 3]>| a.map(Vec3::from).filter(|v| v.is_finite()).map(|v| v.max(Vec3::ZERO));
        let kd = v(m.diffuse).unwrap_or(Vec3::splat(0.7)).min(Vec3::ONE);
        let ks = v(m.specular).unwrap_or(Vec3::ZERO).min(Vec3::ONE);
        let emission = v(m.emission).unwrap_or(Vec3::ZERO);
        let transparent = m.dissolve.is_some_and(|d| d < 1.0)
            || matches!(m.illumination_model, Some(4) | Some(6) | Some(7) | Some(9));
        let bsdf = if transparent {
            let eta = m.optical_density.filter(|n| n.is_finite() && *n >= 1.0).unwrap_or(1.5);
            Bsdf::Dielectric { eta, tint: Vec3::ONE }
        } else if ks.max_element() > kd.max_element() || m.illumination_model == Some(3) && ks != Vec3::ZERO {
            // Phong exponent to microfacet roughness: alpha = sqrt(2 / (Ns + 2)) (Walter et al.
            // 2007, sec. 5.2, the Beckmann-Phong correspondence, used for GGX too).
            let ns = m.shininess.filter(|n| n.is_finite() && *n >= 0.0).unwrap_or(100.0);
            Bsdf::Metal { f0: ks, alpha: (2.0 / (ns + 2.0)).sqrt() }
        } else {
            Bsdf::Lambert { albedo: kd }
        };
        Self { bsdf, emission }
    }
}

/// The renderer's view of a world: the acceleration structure, each surface's optics, the
/// lights and the background radiance.
pub struct RenderScene<'a> {
    /// The acceleration structure.
    pub accel: &'a Accel,
    /// Indexed by surface id.
    pub surfaces: Vec<SurfaceOptics>,
    /// The lights.
    pub lights: Lights,
    /// Radiance of rays that leave the scene.
    pub background: Vec3,
    /// Each surface's dispersion law, by surface id (glass with `sellmeier_*` or
    /// `abbe_number`; seen by the spectral integrator only). Empty when none disperses.
    pub dispersion: Vec<Option<Dispersion>>,
    /// The scene's participating media (`[[media]]`; `volpath` and `raymarch` see them).
    pub media: media::SceneMedia,
    /// The mesh (radiosity patches its triangles).
    mesh: &'a TriangleMesh,
    /// Unit geometric normal (as wound) and surface of each mesh triangle, by mesh index:
    /// a hit needs only these, so the renderer skips the core's barycentric recomputation.
    triangles: Vec<(Vec3, u32)>,
}

/// Why `world` renders black with any integrator but `raycast` (whose headlight lights every
/// scene): no `[[lights]]`, no emissive material and a black background. `None` when lit.
pub fn unlit_reason(world: &World) -> Option<&'static str> {
    let s = &world.scene;
    let background =
        s.desc.render.as_ref().and_then(|r| r.background).map_or(Vec3::ZERO, Vec3::from).max(Vec3::ZERO);
    let emitters =
        s.surfaces.iter().any(|surface| SurfaceOptics::from_surface(surface).emission.max_element() > 0.0);
    (s.desc.lights.is_empty() && !emitters && background == Vec3::ZERO).then_some(
        "no light: no [[lights]], no emissive material (OBJ `Ke`) and a black background, so the \
         image will be black (add [[lights]] or a `Ke` material, or use --integrator raycast)",
    )
}

impl<'a> RenderScene<'a> {
    /// The render scene of a loaded world (materials resolved per [`SurfaceOptics::from_surface`],
    /// point lights from `[[lights]]`, background from `[render]`).
    pub fn new(world: &'a World) -> Self {
        let s = &world.scene;
        let surfaces: Vec<SurfaceOptics> = s.surfaces.iter().map(SurfaceOptics::from_surface).collect();
        let points: Vec<(Vec3, Vec3)> =
            s.desc.lights.iter().map(|l| (Vec3::from(l.position), Vec3::from(l.intensity))).collect();
        let background =
            s.desc.render.as_ref().and_then(|r| r.background).map_or(Vec3::ZERO, Vec3::from).max(Vec3::ZERO);
        let instances = (s.instances.meshes.as_slice(), s.instances.list.as_slice());
        let mut scene =
            Self::with_instances(&world.accel, &s.mesh, &s.spheres, instances, surfaces, &points, background);
        let dispersion: Vec<Option<Dispersion>> = s
            .surfaces
            .iter()
            .map(|surface| {
                surface.material.as_ref().and_then(|m| m.optical.as_ref()).and_then(|o| o.dispersion)
            })
            .collect();
        if dispersion.iter().any(Option::is_some) {
            scene.dispersion = dispersion;
        }
        scene.media = media::SceneMedia::of_world(world);
        scene
    }

    /// A render scene from its parts; `points` are (position, intensity) point lights, the
    /// shapes are `accel`'s. Emissive triangles of `accel`'s instances (if any) are not lights
    /// here, for want of their meshes: they glow where a path hits them (see
    /// [`RenderScene::with_instances`]).
    pub fn from_parts(
        accel: &'a Accel,
        mesh: &'a TriangleMesh,
        spheres: &[Sphere],
        surfaces: Vec<SurfaceOptics>,
        points: &[(Vec3, Vec3)],
        background: Vec3,
    ) -> Self {
        Self::with_instances(accel, mesh, spheres, (&[], &[]), surfaces, points, background)
    }

    /// [`RenderScene::from_parts`] with the meshes and placed copies `accel`'s instance set
    /// was built from, whose emissive triangles become lights.
    pub fn with_instances(
        accel: &'a Accel,
        mesh: &'a TriangleMesh,
        spheres: &[Sphere],
        instances: (&[TriangleMesh], &[Instance]),
        surfaces: Vec<SurfaceOptics>,
        points: &[(Vec3, Vec3)],
        background: Vec3,
    ) -> Self {
        let emission: Vec<Vec3> = surfaces.iter().map(|s| s.emission).collect();
        let emitters = lights::Emitters {
            mesh: Some(mesh),
            spheres,
            shapes: &accel.shapes.shapes,
            instance_meshes: instances.0,
            instances: instances.1,
        };
        let lights = Lights::from_emitters(points, &emitters, &emission);
        let triangles = (0..mesh.triangle_count())
            .map(|i| {
                let [a, b, c] = mesh.corners(i);
                ((b - a).cross(c - a).normalize_or_zero(), mesh.surface_of_triangle[i])
            })
            .collect();
        Self {
            accel,
            surfaces,
            lights,
            background,
            dispersion: Vec::new(),
            media: media::SceneMedia::default(),
            mesh,
            triangles,
        }
    }

    /// The scene's triangle mesh (the one `accel` was built from).
    pub fn mesh(&self) -> &'a TriangleMesh {
        self.mesh
    }

    /// The closest hit along `ray` (barycentrics are not computed: zero; an instance's hit
    /// carries the light it is in `primitive`, as `hit_of` explains).
    #[inline]
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.hit_of(ray, self.accel.mesh.closest_triangle(ray))
    }

    /// [`RenderScene::intersect`] with the ray's [`FlatRay`] built beforehand (see
    /// [`crate::core::MeshBvh::closest_triangle_prepared`]).
    #[inline]
    pub fn intersect_prepared(&self, ray: &Ray, flat_ray: &FlatRay) -> Option<Hit> {
        self.hit_of(ray, self.accel.mesh.closest_triangle_prepared(ray, flat_ray))
    }

    /// The hit of `ray` given its closest triangle (mesh index, distance), spheres, instances
    /// and shapes included. An instance's hit carries in `primitive` the light its triangle is
    /// (`u32::MAX` when none) instead of the triangle's index in its mesh, which the renderer
    /// has no other use for: a [`Hit`] has no room for the instance, which that light depends
    /// on ([`RenderScene::light_of`]).
    #[inline(always)]
    pub(super) fn hit_of(&self, ray: &Ray, triangle: Option<(u32, f32)>) -> Option<Hit> {
        let mut best = triangle.map(|(i, t)| {
            let (normal, surface) = self.triangles[i as usize];
            Hit {
                t,
                point: ray.at(t),
                normal,
                barycentric: Vec2::ZERO,
                primitive: i,
                kind: PrimitiveKind::Triangle,
                surface,
                front_face: normal.dot(ray.dir) < 0.0,
            }
        });
        if !self.accel.spheres.is_empty()
            || !self.accel.instances.is_empty()
            || !self.accel.shapes.is_empty()
            || !self.accel.sdfs.is_empty()
        {
            let mut r = *ray;
            if let Some(h) = &best {
                r.t_max = h.t;
            }
            if let Some(h) = self.accel.spheres.closest_hit(&r) {
                r.t_max = h.t;
                best = Some(h);
            }
            if let Some((inst, mut h)) = self.accel.instances.closest_hit_placed(&r) {
                r.t_max = h.t;
                h.primitive = if self.lights.has_instance_lights() {
                    self.lights.of_instance_triangle(inst, h.primitive).map_or(u32::MAX, |l| l as u32)
                } else {
                    u32::MAX
                };
                best = Some(h);
            }
            if !self.accel.shapes.is_empty()
                && let Some(h) = self.accel.shapes_hit(&r)
            {
                r.t_max = h.t;
                best = Some(h);
            }
            if !self.accel.sdfs.is_empty()
                && let Some(h) = self.accel.sdfs_hit(&r)
            {
                best = Some(h);
            }
        }
        best
    }

    /// Radiance emitted by the surface at `hit` back along the ray.
    #[inline]
    pub fn emitted(&self, hit: &Hit) -> Vec3 {
        if hit.front_face { self.surfaces[hit.surface as usize].emission } else { Vec3::ZERO }
    }

    /// The light that the primitive at `hit` is, if any.
    #[inline]
    pub fn light_of(&self, hit: &Hit) -> Option<usize> {
        match hit.kind {
            PrimitiveKind::Triangle => self.lights.of_triangle(hit.primitive),
            PrimitiveKind::Sphere => self.lights.of_sphere(hit.primitive),
            PrimitiveKind::Shape => self.lights.of_shape(hit.primitive),
            // Set by `hit_of`: the light itself, or u32::MAX.
            PrimitiveKind::Instance => (hit.primitive != u32::MAX
                && (hit.primitive as usize) < self.lights.lights.len())
            .then_some(hit.primitive as usize),
            // Fields are never lights: the loader refuses an emissive one.
            PrimitiveKind::Sdf => None,
        }
    }

    /// Density per solid angle with which next-event estimation from `p` would have chosen the
    /// emitter point at `hit` reached along unit `dir` (light choice included).
    pub fn light_pdf(&self, p: Vec3, dir: Vec3, hit: &Hit) -> f32 {
        self.light_of(hit)
            .map_or(0.0, |l| self.lights.pmf(l) * self.lights.lights[l].pdf(p, dir, hit.point, hit.normal))
    }

    /// True when the segment from `hit` to `target` is blocked.
    #[inline]
    pub fn occluded(&self, hit: &Hit, target: Vec3) -> bool {
        self.accel.occluded(&Ray::spawn_to(hit.point, hit.normal, target))
    }

    /// True when the shadow segment from `hit` to the light sample `ls` is blocked (pushed
    /// off both surfaces when the light point lies on a flat emitter).
    #[inline]
    pub fn light_blocked(&self, hit: &Hit, ls: &lights::LightSample) -> bool {
        match ls.shadow_normal {
            Some(m) => self.accel.occluded(&Ray::between(hit.point, hit.normal, ls.shadow_point, m)),
            None => self.occluded(hit, ls.shadow_point),
        }
    }
}

/// A local shading frame whose z axis is a surface normal.
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// Tangent.
    pub t: Vec3,
    /// Bitangent.
    pub b: Vec3,
    /// Normal.
    pub n: Vec3,
}

impl Frame {
    /// A frame around the unit normal `n`.
    #[inline]
    pub fn new(n: Vec3) -> Self {
        let (t, b) = orthonormal_basis(n);
        Self { t, b, n }
    }

    /// `v` in the frame's coordinates.
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.t), v.dot(self.b), v.dot(self.n))
    }

    /// `v` in world coordinates.
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.t * v.x + self.b * v.y + self.n * v.z
    }
}

/// Two uniform numbers.
#[inline]
pub fn u2(rng: &mut Rng64) -> Vec2 {
    Vec2::new(uniform(rng), uniform(rng))
}

/// Veach's power heuristic with exponent 2 (Veach 1997, sec. 9.2.4).
#[inline]
pub fn power_heuristic(f: f32, g: f32) -> f32 {
    let (f2, g2) = (f * f, g * g);
    if f2.is_infinite() {
        return 1.0;
    }
    if f2 + g2 == 0.0 { 0.0 } else { f2 / (f2 + g2) }
}

/// A finished image and what it cost.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// The image.
    pub film: Film,
    /// Camera samples taken (pixels x spp).
    pub samples: u64,
    /// Rays traced: closest-hit and shadow queries.
    pub rays: u64,
    /// Photons traced from the lights (`sppm`, `ppm`; 0 for the others).
    pub photons: u64,
    /// Wall time, seconds.
    pub seconds: f64,
    /// What the integrator reports besides the image, one line each (radiosity: its
    /// elements, links and cost).
    pub notes: Vec<String>,
}

/// Radiance along a camera ray by the chosen integrator; counts traced rays into `rays`. The
/// integrators that splat from the lights ([`IntegratorKind::splats`]) and radiosity (which
/// needs its solution, see [`radiosity::Solution::radiance`]) have no per-ray estimate: they
/// get the path tracer's.
#[inline]
pub fn radiance(
    scene: &RenderScene,
    integrator: IntegratorKind,
    ray: Ray,
    max_depth: u32,
    sampler: &mut Sampler,
    rays: &mut u64,
    clamp: Option<f32>,
) -> Vec3 {
    match integrator {
        IntegratorKind::Raycast => raycast::li(scene, &ray, rays),
        IntegratorKind::Whitted => whitted::li(scene, &ray, 0, max_depth, rays),
        IntegratorKind::Distributed => {
            path::trace(scene, ray, max_depth, sampler, rays, path::PathMode::StopAtDiffuse, clamp)
        }
        IntegratorKind::Path
        | IntegratorKind::Light
        | IntegratorKind::Bdpt
        | IntegratorKind::Sppm
        | IntegratorKind::Ppm
        | IntegratorKind::Radiosity
        | IntegratorKind::Pssmlt
        | IntegratorKind::Volpath
        | IntegratorKind::Raymarch
        | IntegratorKind::Spectral
        | IntegratorKind::Vcm => {
            path::trace(scene, ray, max_depth, sampler, rays, path::PathMode::Full, clamp)
        }
    }
}

/// Renders pixel `(x, y)`: the box-filtered mean of `spp` samples, Owen-scrambled Sobol
/// points for the Monte Carlo integrators ([`sampler`]), the pixel centre for the others.
#[inline]
#[allow(clippy::too_many_arguments)]
fn render_pixel(
    scene: &RenderScene,
    camera: &Camera,
    s: &RenderSettings,
    x: u32,
    y: u32,
    rays: &mut u64,
    aid: Option<&PixelAid>,
    camera_medium: Option<usize>,
) -> Vec3 {
    let (mut rng, pixel_seed) = pixel_stream(s, x, y);
    let jitter = s.integrator.jitters();
    let has_lens = camera.aperture_radius_m > 0.0;
    let mut sum = Vec3::ZERO;
    for k in 0..s.spp {
        let mut sampler = Sampler::new(pixel_seed, k, has_lens, &mut rng);
        let ray = if jitter {
            camera_ray(camera, s, x, y, &mut sampler)
        } else {
            let film = Vec2::new((x as f32 + 0.5) / s.width as f32, (y as f32 + 0.5) / s.height as f32);
            camera.ray(film, Vec2::ZERO)
        };
        let l = match aid {
            Some(PixelAid::Radiosity(sol)) => {
                *rays += 1;
                scene.intersect(&ray).map_or(scene.background, |hit| sol.radiance(&hit))
            }
            Some(PixelAid::Spectral(spectra)) => {
                // The pixel's samples take the wavelengths stratified (sample k in the k-th of
                // spp equal intervals): colour noise falls faster than 1/sqrt(spp).
                let u = ((k as f32 + sampler.get_1d()) / s.spp as f32).min(1.0 - f32::EPSILON);
                spectral::li(scene, spectra, ray, s.max_depth, u, &mut sampler, rays)
            }
            None if s.integrator == IntegratorKind::Volpath => {
                volpath::li(scene, ray, s.max_depth, &mut sampler, rays, s.fog.as_ref(), camera_medium)
            }
            None if s.integrator == IntegratorKind::Raymarch => {
                let fog = s.fog.as_ref();
                raymarch::li(
                    scene,
                    ray,
                    s.max_depth,
                    &mut sampler,
                    rays,
                    fog,
                    camera_medium,
                    s.raymarch_step_m,
                )
            }
            None => radiance(scene, s.integrator, ray, s.max_depth, &mut sampler, rays, s.clamp_indirect),
        };
        // A NaN or infinity (a numerical accident) would poison the pixel: drop the sample.
        if l.is_finite() {
            sum += l;
        }
    }
    sum / s.spp as f32
}

/// What an integrator computes once per render before its pixels: the radiosity solution,
/// or the spectral integrator's up-sampled spectra.
pub enum PixelAid {
    /// The radiosity solution the pixels look up.
    Radiosity(radiosity::Solution),
    /// The spectra of the scene's colours.
    Spectral(spectral::SpectralScene),
}

/// Pixel `(x, y)`'s random stream and the seed of its Sobol scrambles (drawn first from it).
fn pixel_stream(s: &RenderSettings, x: u32, y: u32) -> (Rng64, u32) {
    let index = u64::from(y) * u64::from(s.width) + u64::from(x);
    let mut rng = stream(s.seed, PIXEL_DOMAIN, index);
    let pixel_seed = rng.next_u32();
    (rng, pixel_seed)
}

/// The camera ray of a Monte Carlo sample of pixel `(x, y)`: the film pair, jittered inside
/// the pixel, then the lens pair when the camera has a lens.
#[inline(always)]
fn camera_ray(camera: &Camera, s: &RenderSettings, x: u32, y: u32, sampler: &mut Sampler) -> Ray {
    let o = sampler.get_2d();
    let film = Vec2::new((x as f32 + o.x) / s.width as f32, (y as f32 + o.y) / s.height as f32);
    let lens = if camera.aperture_radius_m > 0.0 { sampler.get_2d() } else { Vec2::ZERO };
    camera.ray(film, lens)
}

/// Renders an image. `progress(pixels)` is called as tiles finish (from worker threads).
pub fn render(
    scene: &RenderScene,
    camera: &Camera,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<RenderOutput, String> {
    render_on(&Cluster::solo(), scene, camera, settings, progress)?
        .ok_or_else(|| "a single process returned no image".into())
}

/// [`render`] as one process of `cluster`: tiles are dealt round-robin, each process renders
/// its own, and rank 0 gathers every pixel bit for bit and returns the image (`None`
/// elsewhere). Pixels draw from their own random streams, so the image is the same for any
/// number of processes.
pub fn render_on(
    cluster: &Cluster,
    scene: &RenderScene,
    camera: &Camera,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Result<Option<RenderOutput>, String> {
    settings.validate()?;
    let share = cluster.share();
    let start = Instant::now();
    let scene_bg;
    let scene = match settings.background {
        Some(background) => {
            scene_bg = RenderScene {
                accel: scene.accel,
                surfaces: scene.surfaces.clone(),
                lights: scene.lights.clone(),
                background,
                dispersion: scene.dispersion.clone(),
                media: scene.media.clone(),
                mesh: scene.mesh,
                triangles: scene.triangles.clone(),
            };
            &scene_bg
        }
        None => scene,
    };
    match settings.integrator {
        IntegratorKind::Light => return Ok(light::render_on(cluster, scene, camera, settings, progress)),
        IntegratorKind::Bdpt => return Ok(bdpt::render_on(cluster, scene, camera, settings, progress)),
        IntegratorKind::Pssmlt => return Ok(pssmlt::render_on(cluster, scene, camera, settings, progress)),
        IntegratorKind::Vcm => return Ok(vcm::render_on(cluster, scene, camera, settings, progress)),
        IntegratorKind::Sppm | IntegratorKind::Ppm => {
            return Ok(sppm::render_on(cluster, scene, camera, settings, progress));
        }
        _ => {}
    }
    // Radiosity: every process solves the same system (deterministically), then renders its
    // tiles from it; the form-factor rays are counted once, on rank 0.
    let aid = match settings.integrator {
        IntegratorKind::Radiosity => {
            Some(PixelAid::Radiosity(radiosity::solve_scene(scene, &settings.radiosity, settings.seed)?))
        }
        IntegratorKind::Spectral => Some(PixelAid::Spectral(spectral::SpectralScene::new(scene))),
        _ => None,
    };
    let solution = match &aid {
        Some(PixelAid::Radiosity(sol)) => Some(sol),
        _ => None,
    };
    let (w, h) = (settings.width, settings.height);
    let mine = owned_tiles(&share, w, h);
    // The bounded medium around the eye, if any (volpath and raymarch).
    let camera_medium = match settings.integrator {
        IntegratorKind::Volpath | IntegratorKind::Raymarch => scene.media.enclosing(scene, camera.eye),
        _ => None,
    };
    let use_lanes = lanes::applies(scene, settings) && std::env::var_os("PROPSIM_NO_LANES").is_none();
    let done: Vec<(Vec<Vec3>, u64)> = mine
        .par_iter()
        .map(|&(x0, y0)| {
            let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
            let mut rays = 0u64;
            let px = if use_lanes {
                lanes::render_tile(scene, camera, settings, (x0, y0, x1, y1), &mut rays)
            } else {
                let mut px = Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize);
                for y in y0..y1 {
                    for x in x0..x1 {
                        px.push(render_pixel(
                            scene,
                            camera,
                            settings,
                            x,
                            y,
                            &mut rays,
                            aid.as_ref(),
                            camera_medium,
                        ));
                    }
                }
                px
            };
            progress(u64::from((x1 - x0) * (y1 - y0)));
            (px, rays)
        })
        .collect();
    let mut film = Film::new(w, h);
    let mut rays = match &solution {
        Some(sol) if cluster.is_root() => sol.rays,
        _ => 0,
    };
    for (&(x0, y0), (px, r)) in mine.iter().zip(done) {
        rays += r;
        for (i, p) in tile_pixels(x0, y0, w, h).zip(px) {
            film.pixels[i] = p;
        }
    }
    if cluster.size() > 1 {
        // Every pixel belongs to one process; the others hold zeros there.
        let mut channels: Vec<f32> = film.pixels.iter().flat_map(|p| p.to_array()).collect();
        cluster.gather_disjoint_f32(&mut channels);
        let mut total_rays = [rays];
        cluster.sum_u64(&mut total_rays);
        if !cluster.is_root() {
            return Ok(None);
        }
        for (p, c) in film.pixels.iter_mut().zip(channels.chunks_exact(3)) {
            *p = Vec3::new(c[0], c[1], c[2]);
        }
        rays = total_rays[0];
    }
    Ok(Some(RenderOutput {
        film,
        samples: u64::from(w) * u64::from(h) * u64::from(settings.spp),
        rays,
        photons: 0,
        seconds: start.elapsed().as_secs_f64(),
        notes: match &aid {
            Some(PixelAid::Radiosity(sol)) => vec![sol.summary()],
            Some(PixelAid::Spectral(spectra)) => vec![spectra.summary()],
            None => Vec::new(),
        },
    }))
}

/// The camera of a world: the scene's `[camera]`, else an automatic view of the bounds.
pub fn scene_camera(world: &World, aspect: f32) -> Result<Camera, String> {
    match &world.scene.desc.camera {
        Some(d) => Camera::from_desc(d, aspect),
        None => {
            let v = auto_camera(world, Vec3::Z, None);
            Camera::look_at(v.eye, v.target, Vec3::Z, v.fov_deg, aspect)
        }
    }
}

/// Vertical field of view of the automatic camera outside a model, degrees.
pub const AUTO_FOV_DEG: f32 = 40.0;
/// Vertical field of view of the automatic camera inside a closed room, degrees: wide, as a
/// photographer's interior lens.
pub const AUTO_INTERIOR_FOV_DEG: f32 = 70.0;
/// Height of the automatic camera above the floor of a closed room, metres (eye height).
pub const AUTO_EYE_HEIGHT_M: f32 = 1.6;
/// How far in from the room's corner the interior camera stands, as a fraction of the room's
/// length and width.
pub const AUTO_CORNER_INSET: f32 = 0.12;

/// Where the automatic camera stands and looks.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AutoView {
    /// Camera position.
    pub eye: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Vertical field of view, degrees.
    pub fov_deg: f32,
    /// Whether the camera stands inside a closed room.
    pub inside: bool,
}

/// The automatic camera for a scene without one. Inside a closed room (Z up): near a corner of
/// the bounding box, at eye height ([`AUTO_EYE_HEIGHT_M`], at most 60 % of the room's height),
/// looking across the diagonal at the far corner a little below eye level, with a wide lens
/// ([`AUTO_INTERIOR_FOV_DEG`]): from outside, a closed room shows only its outer walls. The
/// first of the four corners whose point is in the room's air and clear of every surface is
/// taken. Otherwise (open scenes, other up directions, rooms with no such corner): the
/// outside view of [`Camera::auto_view`]. `fov_deg` overrides the field of view.
pub fn auto_camera(world: &World, up: Vec3, fov_deg: Option<f32>) -> AutoView {
    let (lo, hi) = world.scene.mesh.bounds().unwrap_or((Vec3::ZERO, Vec3::ONE));
    let fov = fov_deg.filter(|f| f.is_finite() && *f > 0.0 && *f < 179.0);
    let size = hi - lo;
    let z_up = up.normalize_or_zero().z > 0.999;
    if z_up && world.report.air_volume_m3.is_some() && size.min_element() > 0.0 {
        let eye_z = lo.z + AUTO_EYE_HEIGHT_M.min(0.6 * size.z);
        let target_z = lo.z + 0.4 * size.z;
        let inset = AUTO_CORNER_INSET * size;
        let near = |fx: bool, fy: bool| {
            Vec3::new(
                if fx { hi.x - inset.x } else { lo.x + inset.x },
                if fy { hi.y - inset.y } else { lo.y + inset.y },
                0.0,
            )
        };
        for (fx, fy) in [(false, false), (true, false), (true, true), (false, true)] {
            let eye = near(fx, fy).with_z(eye_z);
            let clear = world.surface_distance_m(eye) >= 0.1 * size.min_element().min(1.0);
            if clear && world.is_inside(eye) == Some(true) {
                let target = near(!fx, !fy).with_z(target_z);
                let fov_deg = fov.unwrap_or(AUTO_INTERIOR_FOV_DEG);
                return AutoView { eye, target, fov_deg, inside: true };
            }
        }
    }
    let fov_deg = fov.unwrap_or(AUTO_FOV_DEG);
    let (eye, target) = Camera::auto_view(lo, hi, up, fov_deg);
    AutoView { eye, target, fov_deg, inside: false }
}

/// Renders a world with its own camera: the few-line library entry point.
pub fn render_world(world: &World, settings: &RenderSettings) -> Result<RenderOutput, String> {
    let scene = RenderScene::new(world);
    let camera = scene_camera(world, settings.width as f32 / settings.height as f32)?;
    render(&scene, &camera, settings, &|_| {})
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::load::Surface;
    use crate::scene::obj::MtlEntry;

    /// The MTL keys map to the documented optics: `Kd` Lambert, `Ks`/`Ns` a rough metal
    /// (alpha = sqrt(2 / (Ns + 2))), `d < 1` or illum 4-9 glass of index `Ni`, `Ke` emission.
    #[test]
    fn mtl_entries_become_the_documented_optics() {
        let optics = |mtl: MtlEntry| {
            SurfaceOptics::from_surface(&Surface { name: "s".into(), material: None, mtl: Some(mtl) })
        };
        let lambert = optics(MtlEntry { diffuse: Some([0.8, 0.1, 0.1]), ..MtlEntry::default() });
        assert_eq!(lambert.bsdf, Bsdf::Lambert { albedo: Vec3::new(0.8, 0.1, 0.1) });
        assert_eq!(lambert.emission, Vec3::ZERO);
        let metal = optics(MtlEntry {
            diffuse: Some([0.1; 3]),
            specular: Some([0.9, 0.8, 0.5]),
            shininess: Some(48.0),
            ..MtlEntry::default()
        });
        assert_eq!(metal.bsdf, Bsdf::Metal { f0: Vec3::new(0.9, 0.8, 0.5), alpha: (2.0f32 / 50.0).sqrt() });
        for glass in [
            MtlEntry { dissolve: Some(0.2), optical_density: Some(1.33), ..MtlEntry::default() },
            MtlEntry { illumination_model: Some(7), optical_density: Some(1.33), ..MtlEntry::default() },
        ] {
            assert_eq!(optics(glass).bsdf, Bsdf::Dielectric { eta: 1.33, tint: Vec3::ONE });
        }
        let lamp = optics(MtlEntry {
            diffuse: Some([0.0; 3]),
            emission: Some([17.0, 12.0, 4.0]),
            ..MtlEntry::default()
        });
        assert_eq!(lamp.emission, Vec3::new(17.0, 12.0, 4.0));
        assert_eq!(lamp.bsdf, Bsdf::Lambert { albedo: Vec3::ZERO });
    }
}
