//! Bidirectional path tracing (Veach and Guibas 1995; Veach 1997, ch. 10; the structure of
//! pbrt-v3 sec. 16.3 and pbrt-v4's `BDPTIntegrator`): for each camera sample, a subpath from
//! the camera and one from a light, joined in every way (`s` light vertices, `t` camera
//! vertices): `s = 0` the camera path hits an emitter, `s = 1` next-event estimation,
//! `t = 1` light tracing splatted onto the film through the camera's importance, and the
//! general joins of two subpath vertices. Every strategy is weighted by multiple importance
//! sampling with the balance heuristic, computed from each vertex's forward and reverse
//! area densities (Veach 1997, sec. 10.2; pbrt-v3 sec. 16.3.4). Each vertex keeps the running
//! sum of its subpath's part of the heuristic's denominator ([`Vertex::mis_joins`], the
//! recursive form of Georgiev et al. 2012, in docs/references.md), so a join's weight
//! reads the two vertices at each side of it and one stored sum, whatever the depth.
//!
//! Subpaths end by Russian roulette at every bounce, continuing with the probability of the
//! throughput's change (the albedo of the sampled lobe, as SmallVCM does), which keeps every
//! strategy unbiased and subpaths short; the MIS weights leave the roulette out, which keeps
//! them summing to one.
//! The background is reached only by camera subpaths (it is not sampled from the lights),
//! so escaping camera paths take it in full. Numbers come from each pixel's random stream;
//! the `t = 1` splats are summed in fixed point ([`super::splat`]), so the image is the same
//! for any thread count and any split over MPI ranks.

use std::time::Instant;

use glam::{Vec2, Vec3};
use rayon::prelude::*;

use super::bsdf::BsdfSample;
use super::light::importance_weight;
use super::sampler::Uniforms;
use super::splat::{HeldSplats, SplatFilm, finish};
use super::{Bsdf, Camera, Film, Frame, RenderOutput, RenderScene, RenderSettings, TILE, u2};
use crate::core::rng::Rng64;
use crate::core::{Hit, Ray};
use crate::dist::Cluster;

/// What a subpath vertex is.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum VertexKind {
    /// A point on the lens.
    Camera,
    /// The first vertex of a light subpath: a point on a light.
    Light,
    /// A surface scattering point.
    Surface,
}

/// A vertex of a camera or light subpath.
#[derive(Clone, Copy, Debug)]
pub struct Vertex {
    /// What it is.
    pub kind: VertexKind,
    /// Position, metres.
    pub p: Vec3,
    /// Unit geometric normal (zero on a pinhole, a lens point or a point light).
    pub n: Vec3,
    /// Shading frame about `n` (surfaces).
    pub frame: Frame,
    /// The BSDF (surfaces).
    pub bsdf: Bsdf,
    /// Unit direction to the previous vertex of its subpath (surfaces).
    pub wo: Vec3,
    /// `wo` in the shading frame (surfaces).
    pub wo_local: Vec3,
    /// In the shading frame, the unit direction to the previous vertex of its subpath taken
    /// between the two positions, as the joins' densities read it (surfaces after the first
    /// vertex; kept here since every join at this vertex reads the same).
    pub back_local: Vec3,
    /// The light this vertex lies on (light vertices, and surface hits on emitters).
    pub light: Option<usize>,
    /// Throughput of the subpath up to and including this vertex.
    pub beta: Vec3,
    /// Whether the vertex scattered by a Dirac lobe (mirror, glass).
    pub delta: bool,
    /// Density per area of this vertex as its subpath sampled it.
    pub pdf_fwd: f32,
    /// Density per area of this vertex if sampled from the other end.
    pub pdf_rev: f32,
    /// The balance heuristic's sum over the joins that make this vertex and the ones before
    /// it (back to its subpath's start) the other subpath's, each strategy's density over
    /// the one whose subpath ends here, once the next vertex has fixed this one's `pdf_rev`
    /// ([`prefix_sums`]): a join reads it two vertices back from each of its ends, so its
    /// weight costs the same whatever the subpaths' lengths.
    pub mis_joins: f32,
    /// As `mis_joins` for the merges (vertex connection and merging), over `eta`.
    pub mis_merges: f32,
}

/// Transport mode of a subpath: radiance from the camera, importance from the lights.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Mode {
    Radiance,
    Importance,
}

impl Vertex {
    pub(super) fn endpoint(kind: VertexKind, p: Vec3, n: Vec3, beta: Vec3, light: Option<usize>) -> Self {
        Self {
            kind,
            p,
            n,
            frame: Frame::new(if n == Vec3::ZERO { Vec3::Z } else { n }),
            bsdf: Bsdf::Lambert { albedo: Vec3::ZERO },
            wo: Vec3::ZERO,
            wo_local: Vec3::ZERO,
            back_local: Vec3::ZERO,
            light,
            beta,
            delta: false,
            pdf_fwd: 0.0,
            pdf_rev: 0.0,
            mis_joins: 0.0,
            mis_merges: 0.0,
        }
    }

    fn surface(scene: &RenderScene, hit: &Hit, wo: Vec3, beta: Vec3) -> Self {
        let frame = Frame::new(hit.normal);
        Self {
            kind: VertexKind::Surface,
            p: hit.point,
            n: hit.normal,
            frame,
            bsdf: scene.surfaces[hit.surface as usize].bsdf,
            wo,
            wo_local: frame.to_local(wo),
            back_local: Vec3::ZERO,
            light: scene.light_of(hit),
            beta,
            delta: false,
            pdf_fwd: 0.0,
            pdf_rev: 0.0,
            mis_joins: 0.0,
            mis_merges: 0.0,
        }
    }

    #[inline]
    fn on_surface(&self) -> bool {
        self.n != Vec3::ZERO
    }

    /// Whether a connection may end here (not at a Dirac BSDF).
    #[inline]
    fn connectible(&self) -> bool {
        self.kind != VertexKind::Surface || !self.bsdf.is_delta()
    }

    /// The BSDF value from the previous vertex towards `next` (surfaces; the BSDFs that can
    /// be evaluated, Lambert and GGX metal, are their own adjoints).
    #[cfg(test)]
    fn f(&self, next: &Vertex) -> Vec3 {
        let wi = (next.p - self.p).normalize_or_zero();
        self.bsdf.eval(self.frame.to_local(self.wo), self.frame.to_local(wi))
    }

    /// Radiance this vertex emits towards `v` (emitters only).
    fn le(&self, scene: &RenderScene, v: &Vertex) -> Vec3 {
        self.light.map_or(Vec3::ZERO, |l| {
            scene.lights.lights[l].le_towards(self.n, (v.p - self.p).normalize_or_zero())
        })
    }

    /// A density per solid angle at this vertex turned into one per area at `next`.
    #[inline]
    fn convert_density(&self, pdf: f32, next: &Vertex) -> f32 {
        let w = next.p - self.p;
        let d2 = w.length_squared();
        if d2 == 0.0 {
            return 0.0;
        }
        let inv = 1.0 / d2;
        let cos = if next.on_surface() { next.n.dot(w * inv.sqrt()).abs() } else { 1.0 };
        pdf * cos * inv
    }

    /// Density per area at `next` with which this vertex, reached from `prev`, samples it.
    fn pdf(&self, scene: &RenderScene, camera: &Camera, prev: Option<&Vertex>, next: &Vertex) -> f32 {
        if self.kind == VertexKind::Light {
            return self.pdf_light(scene, next);
        }
        let wn = (next.p - self.p).normalize_or_zero();
        let pdf = match self.kind {
            VertexKind::Camera => camera.pdf_we(self.p, wn).1,
            _ => {
                let Some(prev) = prev else { return 0.0 };
                let wp = (prev.p - self.p).normalize_or_zero();
                self.bsdf.pdf(self.frame.to_local(wp), self.frame.to_local(wn))
            }
        };
        self.convert_density(pdf, next)
    }

    /// Density per area at `v` of an emitted ray from this emitter point reaching it.
    fn pdf_light(&self, scene: &RenderScene, v: &Vertex) -> f32 {
        let Some(l) = self.light else { return 0.0 };
        let w = v.p - self.p;
        let d2 = w.length_squared();
        if d2 == 0.0 {
            return 0.0;
        }
        let w = w / d2.sqrt();
        let pdf = scene.lights.lights[l].pdf_le_dir(self.n, w) / d2;
        if v.on_surface() { pdf * v.n.dot(w).abs() } else { pdf }
    }

    /// Density per area of this emitter point as the start of a light subpath (light choice
    /// included).
    fn pdf_light_origin(&self, scene: &RenderScene) -> f32 {
        self.light.map_or(0.0, |l| scene.lights.pmf(l) * scene.lights.lights[l].pdf_le_pos(self.n))
    }
}

/// Extends `path` (holding its first vertex) by a random walk from `ray` with throughput
/// `beta`, `pdf` the density per solid angle of `ray`'s direction, to at most `max_vertices`
/// vertices. Returns the background radiance a camera subpath escaping the scene picks up.
#[allow(clippy::too_many_arguments)]
pub(super) fn random_walk<R: Uniforms>(
    scene: &RenderScene,
    mut ray: Ray,
    mut beta: Vec3,
    pdf: f32,
    max_vertices: usize,
    mode: Mode,
    rng: &mut R,
    path: &mut Vec<Vertex>,
    rays: &mut u64,
) -> Vec3 {
    let mut pdf_fwd = pdf;
    while path.len() < max_vertices {
        *rays += 1;
        let Some(hit) = scene.intersect(&ray) else {
            return if mode == Mode::Radiance { beta * scene.background } else { Vec3::ZERO };
        };
        let mut v = Vertex::surface(scene, &hit, -ray.dir, beta);
        let prev = path.len() - 1;
        v.pdf_fwd = path[prev].convert_density(pdf_fwd, &v);
        v.back_local = v.frame.to_local((path[prev].p - v.p).normalize_or_zero());
        let u = rng.next_2d();
        let (uc, u_rr) = (rng.next_1d(), rng.next_1d());
        path.push(v);
        if path.len() >= max_vertices {
            break;
        }
        let wo = v.wo_local;
        let Some(s) = v.bsdf.sample(wo, u, uc) else { break };
        let before = beta.max_element();
        beta *= if mode == Mode::Importance { importance_weight(&v.bsdf, wo, &s) } else { s.weight() };
        pdf_fwd = s.pdf;
        let mut pdf_rev = v.bsdf.pdf(s.wi, wo);
        if s.specular {
            // A Dirac lobe keeps its discrete probability as its "density", the same both
            // ways (Fresnel is reciprocal), rather than pbrt's zero: the MIS ratios' distances
            // and cosines then telescope across a specular chain to the exact ratio of the
            // strategies' densities, as with the generalised geometry term (Veach 1997,
            // sec. 10.3.5). With zeros, a caustic's eye path that hits the light kept most of
            // the weight and most of the noise.
            path.last_mut().expect("pushed").delta = true;
            pdf_rev = s.pdf;
        }
        let here = path.len() - 1;
        path[prev].pdf_rev = path[here].convert_density(pdf_rev, &path[prev]);
        prefix_sums(scene, path, prev);
        // Russian roulette at every bounce on the throughput's change, the scattering's albedo
        // (SmallVCM's continuation probability): each further vertex costs joins with every
        // vertex of the other subpath, so long subpaths of little weight are cut early.
        let q = if here >= RR_START_VERTEX { (beta.max_element() / before).min(1.0) } else { 1.0 };
        if q.is_nan() || q <= 0.0 || u_rr >= q {
            break;
        }
        beta /= q;
        ray = Ray::spawn(hit.point, hit.normal, v.frame.to_world(s.wi));
    }
    Vec3::ZERO
}

/// Sets `path[i]`'s [`Vertex::mis_joins`] and [`Vertex::mis_merges`] from `path[i - 1]`'s,
/// once `path[i].pdf_rev` is known: with `r` the vertex's `pdf_rev / pdf_fwd`, the joins'
/// sum is `r (1 + the previous sum)` (the `1` being the join whose other subpath starts
/// here, left out when either of the two vertices it would join across is Dirac), the
/// merges' `pdf_rev + r (the previous sum)` (no merge at a Dirac vertex). This is
/// [`other_strategies`]' sum over the subpath's vertices in Horner's form (Georgiev et al.
/// 2012's recursive weights, in docs/references.md, with pbrt-v3's densities): a camera
/// subpath's sums start at its second vertex (no strategy has no camera vertex), a light
/// subpath's at its first (the join with the light point is invalid for a Dirac emitter,
/// and no merge is at a light).
fn prefix_sums(scene: &RenderScene, path: &mut [Vertex], i: usize) {
    let v = &path[i];
    let r = remap(v.pdf_rev) / remap(v.pdf_fwd);
    let (joins, merges) = if i == 0 {
        let delta_light = v.light.is_some_and(|l| scene.lights.lights[l].is_delta());
        let lit = v.kind == VertexKind::Light && !delta_light;
        (if lit { r } else { 0.0 }, 0.0)
    } else {
        let before = &path[i - 1];
        let join = if !v.delta && !before.delta { 1.0 } else { 0.0 };
        let merge = if v.delta { 0.0 } else { v.pdf_rev };
        (r * (join + before.mis_joins), merge + r * before.mis_merges)
    };
    path[i].mis_joins = joins;
    path[i].mis_merges = merges;
}

/// A density as the MIS ratios read it: zero (a vertex no strategy samples from that side)
/// as one.
#[inline]
fn remap(pdf: f32) -> f32 {
    if pdf != 0.0 { pdf } else { 1.0 }
}

/// The first subpath vertex (after the camera or light point) that plays Russian roulette.
const RR_START_VERTEX: usize = 3;

/// Camera rays a split pixel spends, per sample, on the light it sees by way of mirrors and
/// glass alone ([`specular_emission`]): one in each cell of a 2 x 2 grid over the pixel.
pub(super) const SPECULAR_SPLIT: u32 = 4;
/// Dirac bounces at which [`specular_emission`] follows both the reflected and the refracted
/// ray (each weighted by its Fresnel factor) rather than choosing one; deeper, it chooses.
const BRANCH_BOUNCES: u32 = 3;
/// Directions [`specular_emission`] samples, under [`Split::WithSds`], at each non-Dirac
/// surface its Dirac chains from the camera reach, looking for a Dirac chain to an emitter.
const SDS_SAMPLES: u32 = 4;

/// Which light a pixel takes apart from the joins, and so leaves out of them. A choice made
/// per pixel from the geometry ([`splits_pixel`]), never from the samples, so the sum of the
/// two estimates stays unbiased.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Split {
    /// Nothing: every path is the joins'.
    Off,
    /// Emitters seen by way of Dirac bounces alone, `E S..S L` (`bdpt`, `vcm`, `sppm`).
    Specular,
    /// Those, and the specular-diffuse-specular paths `E S..S D S..S L` with one non-Dirac
    /// vertex between Dirac chains, such as a caustic seen through glass (`bdpt`: no join
    /// makes these paths, so the camera subpath's hit of the emitter has MIS weight 1 and
    /// may move here unchanged; `vcm` merges them and keeps them).
    WithSds,
}

/// Whether pixel `(x, y)` shows a Dirac surface (mirror, glass) or an emitter at any of 3 x 3
/// fixed points in it, through the lens centre: such pixels are split ([`specular_emission`]).
/// A fixed choice per pixel, independent of the samples, so the split stays unbiased.
pub(super) fn splits_pixel(scene: &RenderScene, camera: &Camera, s: &RenderSettings, x: u32, y: u32) -> bool {
    (0..9).any(|k| {
        let o = Vec2::new((k % 3) as f32 + 0.5, (k / 3) as f32 + 0.5) / 3.0;
        let fp = Vec2::new((x as f32 + o.x) / s.width as f32, (y as f32 + o.y) / s.height as f32);
        scene.intersect(&camera.ray(fp, Vec2::splat(0.5))).is_some_and(|hit| {
            scene.surfaces[hit.surface as usize].bsdf.is_delta() || scene.light_of(&hit).is_some()
        })
    })
}

/// The light pixel `(x, y)` sees directly or by way of Dirac bounces only (eye paths
/// `E S..S L`), averaged over [`SPECULAR_SPLIT`] camera rays stratified over the pixel, each
/// followed down both the reflected and the refracted branch of its first
/// [`BRANCH_BOUNCES`] glass hits (Whitted's tree, weighted by Fresnel rather than sampled).
/// Only the camera can sample these paths (no join or merge ends at a Dirac vertex), and a
/// bulb's highlight on glass is a small spot that a sample reaches only by choosing the
/// reflection (a few per cent): a split pixel takes these paths here, at the cost of a few
/// rays, rather than once a sample at the cost of a whole bidirectional sample, and leaves
/// them out of the joins ([`connect_all`]); the pixel's estimate is the sum, unbiased.
/// Under [`Split::WithSds`], each non-Dirac surface these rays reach after a Dirac bounce also
/// sends [`SDS_SAMPLES`] BSDF-sampled rays on, which count an emitter only at the end of a
/// Dirac chain (`E S..S D S..S L`, [`sds_emission`]).
#[allow(clippy::too_many_arguments)]
pub(super) fn specular_emission<R: Uniforms>(
    scene: &RenderScene,
    camera: &Camera,
    s: &RenderSettings,
    (x, y, split): (u32, u32, Split),
    rng: &mut R,
    rays: &mut u64,
) -> Vec3 {
    let mut sum = Vec3::ZERO;
    // Pending rays: (ray, throughput, Dirac bounces before it), depth first. Each branching
    // bounce adds at most one to the stack, so it never holds more than BRANCH_BOUNCES + 1.
    let mut stack = [(Ray::new(Vec3::ZERO, Vec3::Z), Vec3::ZERO, 0u32); BRANCH_BOUNCES as usize + 1];
    for k in 0..SPECULAR_SPLIT {
        let cell = Vec2::new((k % 2) as f32, (k / 2) as f32);
        let o = (cell + rng.next_2d()) * 0.5;
        let lens = if camera.aperture_radius_m > 0.0 { rng.next_2d() } else { Vec2::ZERO };
        let fp = Vec2::new((x as f32 + o.x) / s.width as f32, (y as f32 + o.y) / s.height as f32);
        stack[0] = (camera.ray(fp, lens), Vec3::ONE, 0);
        let mut len = 1;
        while len > 0 {
            len -= 1;
            let (ray, beta, bounce) = stack[len];
            *rays += 1;
            let Some(hit) = scene.intersect(&ray) else { continue };
            if let Some(l) = scene.light_of(&hit) {
                sum += beta * scene.lights.lights[l].le_towards(hit.normal, -ray.dir);
            }
            let bsdf = scene.surfaces[hit.surface as usize].bsdf;
            if bounce == s.max_depth {
                continue;
            }
            let frame = Frame::new(hit.normal);
            let wo = frame.to_local(-ray.dir);
            if !bsdf.is_delta() {
                if split == Split::WithSds && bounce > 0 {
                    sum += sds_emission(scene, s.max_depth, (&hit, frame, wo), beta, bounce + 1, rng, rays);
                }
                continue;
            }
            let (u, uc) = (rng.next_2d(), rng.next_1d());
            let mut follow = |bs: BsdfSample, beta: Vec3| {
                if beta != Vec3::ZERO && beta.is_finite() && len < stack.len() {
                    stack[len] = (Ray::spawn(hit.point, hit.normal, frame.to_world(bs.wi)), beta, bounce + 1);
                    len += 1;
                }
            };
            if bounce < BRANCH_BOUNCES {
                // Both lobes, each with its share: the reflection (uc = 0) and the refraction.
                let reflected = bsdf.sample(wo, u, 0.0);
                let refracted = bsdf.sample(wo, u, 1.0).filter(|r| reflected.is_none_or(|f| f.wi != r.wi));
                for bs in [reflected, refracted].into_iter().flatten() {
                    follow(bs, beta * bs.weight() * bs.pdf);
                }
            } else if let Some(bs) = bsdf.sample(wo, u, uc) {
                follow(bs, beta * bs.weight());
            }
        }
    }
    sum / SPECULAR_SPLIT as f32
}

/// The light reaching non-Dirac surface point `hit` (its `bounces`-th bounce from the camera,
/// with throughput `beta`, after Dirac bounces only) by paths that no join can make: every
/// non-Dirac vertex between Dirac ones, `D S..S (D S..S)* L`, such as a caustic seen
/// through glass or in a mirror. The mean over [`SDS_SAMPLES`] BSDF-sampled directions from
/// `hit`, each a walk that samples one direction at each later non-Dirac vertex, chooses a
/// glass lobe by its Fresnel share, stops when a non-Dirac vertex follows another (the joins
/// take that path) or at `max_depth` bounces, and counts an emitter met after a Dirac bounce.
fn sds_emission<R: Uniforms>(
    scene: &RenderScene,
    max_depth: u32,
    (hit, frame, wo): (&Hit, Frame, Vec3),
    beta: Vec3,
    bounces: u32,
    rng: &mut R,
    rays: &mut u64,
) -> Vec3 {
    // Russian roulette on the throughput: a faint branch (a Fresnel reflection off glass)
    // rarely pays for its walks.
    let q = beta.max_element().min(1.0);
    if rng.next_1d() >= q {
        return Vec3::ZERO;
    }
    let beta = beta / q;
    let bsdf = scene.surfaces[hit.surface as usize].bsdf;
    let mut sum = Vec3::ZERO;
    for _ in 0..SDS_SAMPLES {
        let Some(bs) = bsdf.sample(wo, rng.next_2d(), rng.next_1d()) else { continue };
        let mut beta = beta * bs.weight();
        let mut ray = Ray::spawn(hit.point, hit.normal, frame.to_world(bs.wi));
        // Bounces of the path so far, and whether the last one was Dirac.
        let (mut depth, mut after_dirac) = (bounces, false);
        while beta != Vec3::ZERO && beta.is_finite() {
            *rays += 1;
            let Some(next) = scene.intersect(&ray) else { break };
            let next_bsdf = scene.surfaces[next.surface as usize].bsdf;
            if !after_dirac && !next_bsdf.is_delta() {
                break;
            }
            if after_dirac && let Some(l) = scene.light_of(&next) {
                sum += beta * scene.lights.lights[l].le_towards(next.normal, -ray.dir);
            }
            if depth == max_depth {
                break;
            }
            let next_frame = Frame::new(next.normal);
            let Some(bs) = next_bsdf.sample(next_frame.to_local(-ray.dir), rng.next_2d(), rng.next_1d())
            else {
                break;
            };
            beta *= bs.weight();
            depth += 1;
            after_dirac = next_bsdf.is_delta();
            ray = Ray::spawn(next.point, next.normal, next_frame.to_world(bs.wi));
        }
    }
    sum / SDS_SAMPLES as f32
}

/// The light subpath: a light chosen by power, a point and cosine-weighted direction on it,
/// then a walk of at most `max_depth` more vertices.
pub(super) fn light_subpath<R: Uniforms>(
    scene: &RenderScene,
    max_depth: u32,
    rng: &mut R,
    path: &mut Vec<Vertex>,
    rays: &mut u64,
) {
    path.clear();
    let Some((index, pmf)) = scene.lights.choose(rng.next_1d()) else { return };
    let light = &scene.lights.lights[index];
    let u_pos = rng.next_2d();
    let u_dir = rng.next_2d();
    let Some(e) = light.sample_le(u_pos, u_dir) else { return };
    let mut v0 = Vertex::endpoint(VertexKind::Light, e.point, e.normal, e.le, Some(index));
    v0.pdf_fwd = pmf * e.pdf_pos;
    path.push(v0);
    let on_surface = e.normal != Vec3::ZERO;
    let cos = if on_surface { e.normal.dot(e.dir).abs() } else { 1.0 };
    let beta = e.le * (cos / (pmf * e.pdf_pos * e.pdf_dir));
    let ray = if on_surface { Ray::spawn(e.point, e.normal, e.dir) } else { Ray::new(e.point, e.dir) };
    random_walk(scene, ray, beta, e.pdf_dir, max_depth as usize + 1, Mode::Importance, rng, path, rays);
}

/// The unit normal of light `l` at the point `ls` sampled on it (zero for a point light).
fn light_normal(scene: &RenderScene, l: usize, ls: &super::lights::LightSample) -> Vec3 {
    match scene.lights.lights[l] {
        super::Light::Point { .. } => Vec3::ZERO,
        super::Light::Triangle { normal, .. } => normal,
        super::Light::Sphere { center, .. } => (ls.point - center).normalize_or_zero(),
        super::Light::Shape(_) => ls.normal,
    }
}

/// Whether the segment between two vertices is blocked.
fn blocked(scene: &RenderScene, a: &Vertex, b: &Vertex, rays: &mut u64) -> bool {
    *rays += 1;
    let segment = if a.on_surface() && b.on_surface() {
        Ray::between(a.p, a.n, b.p, b.n)
    } else {
        Ray::spawn_to(a.p, a.n, b.p)
    };
    scene.accel.occluded(&segment)
}

/// `(pdf_rev, pdf_fwd, delta)` of a vertex, as the MIS weight reads them.
type Densities = (f32, f32, bool);

#[inline]
fn densities(v: &Vertex) -> Densities {
    (v.pdf_rev, v.pdf_fwd, v.delta)
}

/// The densities of the (at most two) vertices at each side of a join, which differ from the
/// subpaths' own: the rest of the joined path reads its vertices in place.
struct Junction {
    cam_last: Densities,
    cam_prev: Option<Densities>,
    lig_last: Option<Densities>,
    lig_prev: Option<Densities>,
    /// Whether the light end of the joined path is a Dirac emitter (a point light).
    delta_light: bool,
}

/// The sum, over every other strategy that could have made the joined path `light[..s]` +
/// `camera[..t]`, of its density over this connection's (pbrt-v3 sec. 16.3.4, `MISWeight`),
/// with the merging strategies of vertex connection and merging when `eta` (the merging
/// paths times the disc area, `N pi r^2`) is positive: a merge at vertex `x` has the density
/// of the connection that ends the eye subpath at `x` times `eta` and the light's density of
/// `x` (Georgiev et al. 2012, in docs/references.md). Merges need a non-Dirac vertex with at least one
/// light bounce before it and the camera vertex after.
fn other_strategies(light: &[Vertex], camera: &[Vertex], s: usize, t: usize, j: &Junction, eta: f32) -> f32 {
    let cam_at = |i: usize| -> Densities {
        if i + 1 == t {
            j.cam_last
        } else if i + 2 == t
            && let Some(c) = j.cam_prev
        {
            c
        } else {
            densities(&camera[i])
        }
    };
    let lig_at = |i: usize| -> Densities {
        if i + 1 == s
            && let Some(l) = j.lig_last
        {
            l
        } else if i + 2 == s
            && let Some(l) = j.lig_prev
        {
            l
        } else {
            densities(&light[i])
        }
    };
    let merging = eta > 0.0;
    // The vertices up to two before each end keep their subpath's densities: their part of
    // the sum is the stored prefix ([`prefix_sums`]); the two next to the join are added to
    // it in the same Horner form.
    let stored = |v: &Vertex| if merging { v.mis_joins + eta * v.mis_merges } else { v.mis_joins };
    let mut cam = if t >= 3 { stored(&camera[t - 3]) } else { 0.0 };
    for i in t.saturating_sub(2).max(1)..t {
        let (c, c_before) = (cam_at(i), cam_at(i - 1));
        let join = if !c.2 && !c_before.2 { 1.0 } else { 0.0 };
        cam = remap(c.0) / remap(c.1) * (join + cam);
        // A merge at camera vertex i (not the emitter point that ends an `s = 0` path).
        if merging && !c.2 && (s > 0 || i + 1 < t) {
            cam += eta * c.0;
        }
    }
    let mut lig = if s >= 3 { stored(&light[s - 3]) } else { 0.0 };
    for i in s.saturating_sub(2)..s {
        let l = lig_at(i);
        let delta_before = if i > 0 { lig_at(i - 1).2 } else { j.delta_light };
        let join = if !l.2 && !delta_before { 1.0 } else { 0.0 };
        lig = remap(l.0) / remap(l.1) * (join + lig);
        if merging && i >= 1 && !l.2 {
            lig += eta * l.0;
        }
    }
    cam + lig
}

/// The balance-heuristic weight of the path made by joining `light[..s]` and `camera[..t]`,
/// with `sampled` standing in for the sampled endpoint of the `s = 1` or `t = 1` strategies
/// (pbrt-v3 sec. 16.3.4, `MISWeight`); `eta` as in [`other_strategies`] (zero: BDPT alone).
/// [`connect`] computes the same through [`Join::weight`], reusing its BSDF values'
/// directions; the tests check this against the balance heuristic from scratch.
#[cfg(test)]
#[allow(clippy::too_many_arguments)]
fn mis_weight(
    scene: &RenderScene,
    camera_model: &Camera,
    light: &[Vertex],
    camera: &[Vertex],
    sampled: Option<&Vertex>,
    s: usize,
    t: usize,
    eta: f32,
) -> f32 {
    if s + t == 2 {
        return 1.0;
    }
    let join = Join::new(light, camera, sampled, s, t);
    let w = join.qs.map_or(Vec3::ZERO, |q| (q.p - join.pt.p).normalize_or_zero());
    let qe = (s >= 2).then(|| JoinEnd::new(&light[s - 1], light[s - 1].frame.to_local(-w)));
    let pe = (t >= 2 && s >= 1).then(|| JoinEnd::new(join.pt, join.pt.frame.to_local(w)));
    join.weight(scene, camera_model, qe.as_ref(), pe.as_ref(), eta)
}

/// The join `(s, t)` of `light[..s]` and `camera[..t]`: its end vertices (`sampled` standing
/// in for the sampled endpoint of the `s = 1` or `t = 1` strategies).
struct Join<'a> {
    light: &'a [Vertex],
    camera: &'a [Vertex],
    s: usize,
    t: usize,
    /// The light end (none for `s = 0`).
    qs: Option<&'a Vertex>,
    /// The camera end.
    pt: &'a Vertex,
}

impl<'a> Join<'a> {
    fn new(
        light: &'a [Vertex],
        camera: &'a [Vertex],
        sampled: Option<&'a Vertex>,
        s: usize,
        t: usize,
    ) -> Self {
        let qs = (s > 0).then(|| if s == 1 { sampled.unwrap_or(&light[0]) } else { &light[s - 1] });
        let pt = if t == 1 { sampled.unwrap_or(&camera[0]) } else { &camera[t - 1] };
        Self { light, camera, s, t, qs, pt }
    }

    /// The balance-heuristic weight of the join (pbrt-v3 sec. 16.3.4, `MISWeight`; `eta` as
    /// in [`other_strategies`], zero for BDPT alone), `qe` and `pe` the [`JoinEnd`]s of the
    /// surface ends (`s >= 2`; `t >= 2` with `s >= 1`), whose directions the join's BSDF
    /// values have already computed. The tests check it against the balance heuristic
    /// computed from scratch.
    fn weight(
        &self,
        scene: &RenderScene,
        camera_model: &Camera,
        qe: Option<&JoinEnd>,
        pe: Option<&JoinEnd>,
        eta: f32,
    ) -> f32 {
        let (light, camera, s, t, qs, pt) = (self.light, self.camera, self.s, self.t, self.qs, self.pt);
        let qs_minus = (s > 1).then(|| &light[s - 2]);
        let pt_minus = (t > 1).then(|| &camera[t - 2]);
        // The joined vertices are not Dirac, whatever their BSDF.
        let mut cam_last = densities(pt);
        cam_last.2 = false;
        cam_last.0 = match (qs, qe) {
            (Some(q), Some(e)) => q.convert_density(q.bsdf.pdf(e.back, e.w), pt),
            (Some(q), None) => q.pdf(scene, camera_model, qs_minus, pt),
            (None, _) => pt.pdf_light_origin(scene),
        };
        let cam_prev = pt_minus.map(|pm| {
            let mut c = densities(pm);
            c.0 = match (qs, pe) {
                (Some(_), Some(e)) => pt.convert_density(pt.bsdf.pdf(e.w, e.back), pm),
                (Some(q), None) => pt.pdf(scene, camera_model, Some(q), pm),
                (None, _) => pt.pdf_light(scene, pm),
            };
            c
        });
        let lig_last = qs.map(|q| {
            let mut l = densities(q);
            l.2 = false;
            l.0 = match pe {
                Some(e) => pt.convert_density(pt.bsdf.pdf(e.back, e.w), q),
                None => pt.pdf(scene, camera_model, pt_minus, q),
            };
            l
        });
        let lig_prev = match (qs, qs_minus) {
            (Some(q), Some(qm)) => {
                let mut l = densities(qm);
                l.0 = match qe {
                    Some(e) => q.convert_density(q.bsdf.pdf(e.w, e.back), qm),
                    None => q.pdf(scene, camera_model, Some(pt), qm),
                };
                Some(l)
            }
            _ => None,
        };
        let first = if s == 1 { qs.unwrap_or(&light[0]) } else { light.first().unwrap_or(pt) };
        let delta_light = s > 0 && first.light.is_some_and(|l| scene.lights.lights[l].is_delta());
        let junction = Junction { cam_last, cam_prev, lig_last, lig_prev, delta_light };
        let w = 1.0 / (1.0 + other_strategies(light, camera, s, t, &junction, eta));
        if w.is_finite() { w } else { 0.0 }
    }
}

/// A surface vertex at one end of a join, in its own frame: the unit direction to the other
/// end and the one to the previous vertex of its subpath ([`Vertex::back_local`]), the same
/// arithmetic as [`Vertex::pdf`] does, done once for the join's BSDF values and its junction
/// densities ([`Join::weight`]).
struct JoinEnd {
    /// Towards the other end, local.
    w: Vec3,
    /// Towards the previous vertex of its subpath, local.
    back: Vec3,
}

impl JoinEnd {
    /// `w`: the local direction from `v` to the other end.
    #[inline]
    fn new(v: &Vertex, w: Vec3) -> Self {
        Self { w, back: v.back_local }
    }
}

/// The weight of merging the eye vertex `camera[t - 1]` with the light vertex `light[m]`
/// (`m = light.len() - 1 >= 1`, a photon within the merging radius), `eta = N pi r^2`: the
/// merge's density over the sum of every strategy's, the path read as the eye subpath
/// `camera[..t]` and the light subpath `light[..m]` (Georgiev et al. 2012). At the
/// junction the light's density of the merged vertex is the photon's own; a Dirac light
/// vertex before it keeps its subpath's densities (no connection could end there).
pub(super) fn merge_weight(
    scene: &RenderScene,
    light: &[Vertex],
    camera: &[Vertex],
    t: usize,
    eta: f32,
) -> f32 {
    let m = light.len() - 1;
    let (photon, q, pt) = (&light[m], &light[m - 1], &camera[t - 1]);
    let pt_minus = &camera[t - 2];
    let mut cam_last = densities(pt);
    cam_last.0 = photon.pdf_fwd;
    // The directions at the junction, computed once (as in [`Join::weight`]).
    let w = (q.p - pt.p).normalize_or_zero();
    let pw = pt.frame.to_local(w);
    let mut cam_prev = densities(pt_minus);
    cam_prev.0 = pt.convert_density(pt.bsdf.pdf(pw, pt.back_local), pt_minus);
    let mut lig_last = densities(q);
    lig_last.0 = pt.convert_density(pt.bsdf.pdf(pt.back_local, pw), q);
    let lig_prev = (m >= 2).then(|| {
        let mut l = densities(&light[m - 2]);
        if !q.delta {
            l.0 = q.convert_density(q.bsdf.pdf(q.frame.to_local(-w), q.back_local), &light[m - 2]);
        }
        l
    });
    let delta_light = light[0].light.is_some_and(|l| scene.lights.lights[l].is_delta());
    let junction =
        Junction { cam_last, cam_prev: Some(cam_prev), lig_last: Some(lig_last), lig_prev, delta_light };
    let connection = if q.delta || pt.delta { 0.0 } else { 1.0 };
    let others = other_strategies(&light[..m], camera, m, t, &junction, eta);
    let w = eta * cam_last.0 / (connection + others);
    if w.is_finite() { w.clamp(0.0, 1.0) } else { 0.0 }
}

/// One camera sample of pixel `(x, y)`: its radiance estimate (strategies with `t >= 2`), with
/// the `t = 1` light-image contributions held in `splats`.
#[allow(clippy::too_many_arguments)]
fn sample(
    scene: &RenderScene,
    camera_model: &Camera,
    s: &RenderSettings,
    (x, y, split): (u32, u32, Split),
    rng: &mut Rng64,
    paths: &mut (Vec<Vertex>, Vec<Vertex>),
    splats: &mut HeldSplats,
    rays: &mut u64,
) -> Vec3 {
    let (camera, light) = paths;
    let o = u2(rng);
    let lens = if camera_model.aperture_radius_m > 0.0 { u2(rng) } else { Vec2::ZERO };
    let fp = Vec2::new((x as f32 + o.x) / s.width as f32, (y as f32 + o.y) / s.height as f32);
    let mut l = camera_subpath(scene, camera_model, fp, lens, s.max_depth as usize + 2, rng, camera, rays);
    light_subpath(scene, s.max_depth, rng, light, rays);
    l += connect_all(scene, camera_model, s.max_depth, light, camera, 0.0, split, rng, splats, rays);
    if split != Split::Off {
        l += specular_emission(scene, camera_model, s, (x, y, split), rng, rays);
    }
    l
}

/// Every join of `light` and `camera` of at most `max_depth` bounces, weighted by MIS (with
/// merging strategies counted when `eta > 0`): the radiance of the strategies with `t >= 2`;
/// the `t = 1` ones are held in `splats` for the light image. The camera subpath's hits of
/// emitters that `split` takes apart are left out ([`specular_emission`] takes them).
#[allow(clippy::too_many_arguments)]
pub(super) fn connect_all<R: Uniforms>(
    scene: &RenderScene,
    camera_model: &Camera,
    max_depth: u32,
    light: &[Vertex],
    camera: &[Vertex],
    eta: f32,
    split: Split,
    rng: &mut R,
    splats: &mut HeldSplats,
    rays: &mut u64,
) -> Vec3 {
    let mut l = Vec3::ZERO;
    // Camera vertices up to which every bounce was Dirac (vertex `specular_prefix` is the first
    // non-Dirac one), and up to which no non-Dirac vertex followed another, the first being
    // Dirac (vertex `sds_end`).
    let specular_prefix = 1 + camera.iter().skip(1).take_while(|v| v.delta).count();
    let sds_end = match camera.get(1) {
        Some(v) if v.delta => 1 + camera[1..].windows(2).take_while(|p| p[0].delta || p[1].delta).count(),
        _ => 0,
    };
    // The emitter hits split off: reached by Dirac bounces alone (`t - 1 <= specular_prefix`),
    // or (WithSds) by a path that no join makes, its vertex before the emitter Dirac.
    let split_off = |t: usize| match split {
        Split::Off => false,
        Split::Specular => t <= specular_prefix + 1,
        Split::WithSds => t <= specular_prefix + 1 || (t - 2 <= sds_end && camera[t - 2].delta),
    };
    for t in 1..=camera.len() {
        for si in 0..=light.len() {
            let depth = (si + t) as i64 - 2;
            if (si == 1 && t == 1) || depth < 0 || depth > i64::from(max_depth) {
                continue;
            }
            if si == 0 && split_off(t) {
                // Still draw the numbers, so a pixel's stream does not depend on the split.
                rng.next_2d();
                continue;
            }
            let u = rng.next_2d();
            if let Some((c, splat)) = connect(scene, camera_model, light, camera, si, t, u, eta, rays) {
                match splat {
                    Some(p) => splats.push(p, c),
                    None => l += c,
                }
            }
        }
    }
    l
}

/// The camera subpath through film point `fp` and lens point `lens` (both in [0,1)^2), at most
/// `max_vertices` vertices with the lens point; returns the background radiance it picks up
/// if it escapes the scene.
#[allow(clippy::too_many_arguments)]
pub(super) fn camera_subpath<R: Uniforms>(
    scene: &RenderScene,
    camera_model: &Camera,
    fp: Vec2,
    lens: Vec2,
    max_vertices: usize,
    rng: &mut R,
    camera: &mut Vec<Vertex>,
    rays: &mut u64,
) -> Vec3 {
    camera.clear();
    let ray = camera_model.ray(fp, lens);
    camera.push(Vertex::endpoint(VertexKind::Camera, ray.origin, Vec3::ZERO, Vec3::ONE, None));
    let pdf_dir = camera_model.pdf_we(ray.origin, ray.dir).1;
    random_walk(scene, ray, Vec3::ONE, pdf_dir, max_vertices, Mode::Radiance, rng, camera, rays)
}

/// The weighted contribution of strategy `(s, t)`, and for `t = 1` the film point to splat it on.
#[allow(clippy::too_many_arguments)]
pub(super) fn connect(
    scene: &RenderScene,
    camera_model: &Camera,
    light: &[Vertex],
    camera: &[Vertex],
    s: usize,
    t: usize,
    u: Vec2,
    eta: f32,
    rays: &mut u64,
) -> Option<(Vec3, Option<Vec2>)> {
    let mut sampled = None;
    let mut splat = None;
    // The surface ends' directions, computed once for the BSDF values and the weight.
    let (mut qe, mut pe) = (None, None);
    let l = if s == 0 {
        let pt = &camera[t - 1];
        pt.light?;
        pt.le(scene, &camera[t - 2]) * pt.beta
    } else if t == 1 {
        let qs = &light[s - 1];
        if !qs.connectible() {
            return None;
        }
        let c = camera_model.sample_wi(qs.p, u)?;
        let v = Vertex::endpoint(
            VertexKind::Camera,
            c.point,
            Vec3::ZERO,
            Vec3::splat(c.importance / c.pdf),
            None,
        );
        let qw = qs.frame.to_local(-(qs.p - v.p).normalize_or_zero());
        let mut l = qs.beta * qs.bsdf.eval(qs.wo_local, qw) * v.beta;
        if qs.on_surface() {
            l *= qs.n.dot(c.wi).abs();
        }
        if l == Vec3::ZERO || blocked(scene, qs, &v, rays) {
            return None;
        }
        qe = Some(JoinEnd::new(qs, qw));
        sampled = Some(v);
        splat = Some(c.film);
        l
    } else if s == 1 {
        let pt = &camera[t - 1];
        if !pt.connectible() {
            return None;
        }
        let (index, pmf, ux) = scene.lights.choose_reusing(u.x)?;
        let light_model = &scene.lights.lights[index];
        let ls = light_model.sample(pt.p, Vec2::new(ux, u.y))?;
        let n = light_normal(scene, index, &ls);
        let mut v = Vertex::endpoint(VertexKind::Light, ls.point, n, ls.li / (pmf * ls.pdf), Some(index));
        v.pdf_fwd = v.pdf_light_origin(scene);
        let pw = pt.frame.to_local((v.p - pt.p).normalize_or_zero());
        let mut l = pt.beta * pt.bsdf.eval(pt.wo_local, pw) * v.beta;
        if pt.on_surface() {
            l *= pt.n.dot(ls.wi).abs();
        }
        if l == Vec3::ZERO {
            return None;
        }
        *rays += 1;
        let segment = match ls.shadow_normal {
            Some(m) if pt.on_surface() => Ray::between(pt.p, pt.n, ls.shadow_point, m),
            _ => Ray::spawn_to(pt.p, pt.n, ls.shadow_point),
        };
        if scene.accel.occluded(&segment) {
            return None;
        }
        pe = Some(JoinEnd::new(pt, pw));
        sampled = Some(v);
        l
    } else {
        let (qs, pt) = (&light[s - 1], &camera[t - 1]);
        if !qs.connectible() || !pt.connectible() {
            return None;
        }
        let d = qs.p - pt.p;
        let w = d.normalize_or_zero();
        let (qw, pw) = (qs.frame.to_local(-w), pt.frame.to_local(w));
        let mut l = qs.beta * qs.bsdf.eval(qs.wo_local, qw) * pt.bsdf.eval(pt.wo_local, pw) * pt.beta;
        if l == Vec3::ZERO {
            return None;
        }
        let d2 = d.length_squared();
        if d2 == 0.0 {
            return None;
        }
        let wn = d / d2.sqrt();
        l *= qs.n.dot(wn).abs() * pt.n.dot(wn).abs() / d2;
        if l == Vec3::ZERO {
            return None;
        }
        // blocked(), with the unit direction `wn` already at hand (`d / |d|`, as Ray::between
        // computes it).
        *rays += 1;
        let segment = if pt.on_surface() && qs.on_surface() {
            Ray::between_along(pt.p, pt.n, qs.p, qs.n, wn)
        } else {
            Ray::spawn_to(pt.p, pt.n, qs.p)
        };
        if scene.accel.occluded(&segment) {
            return None;
        }
        qe = Some(JoinEnd::new(qs, qw));
        pe = Some(JoinEnd::new(pt, pw));
        l
    };
    if l == Vec3::ZERO || !l.is_finite() {
        return None;
    }
    let w = if s + t == 2 {
        1.0
    } else {
        Join::new(light, camera, sampled.as_ref(), s, t).weight(
            scene,
            camera_model,
            qe.as_ref(),
            pe.as_ref(),
            eta,
        )
    };
    Some((l * w, splat))
}

/// Renders by BDPT on this process's share of `cluster` (16x16 tiles dealt round-robin, as
/// `path` does); rank 0 returns the image: each pixel's mean over its samples plus the light
/// image over every process.
pub fn render_on(
    cluster: &Cluster,
    scene: &RenderScene,
    camera: &Camera,
    settings: &RenderSettings,
    progress: &(dyn Fn(u64) + Sync),
) -> Option<RenderOutput> {
    let start = Instant::now();
    let share = cluster.share();
    let (w, h) = (settings.width, settings.height);
    let mine = super::owned_tiles(&share, w, h);
    let min_len = (mine.len() / (8 * rayon::current_num_threads())).max(1);
    type Acc = (Vec<((u32, u32), Vec<Vec3>)>, SplatFilm, u64);
    let (done, splats, rays): Acc = mine
        .par_iter()
        .with_min_len(min_len)
        .fold(
            || (Vec::new(), SplatFilm::new(w, h), 0u64),
            |(mut done, mut film, mut rays), &(x0, y0)| {
                let (x1, y1) = ((x0 + TILE).min(w), (y0 + TILE).min(h));
                let mut paths = (Vec::new(), Vec::new());
                let mut held = HeldSplats::default();
                let mut px = Vec::with_capacity(((x1 - x0) * (y1 - y0)) as usize);
                for y in y0..y1 {
                    for x in x0..x1 {
                        let (mut rng, _) = super::pixel_stream(settings, x, y);
                        let split = if splits_pixel(scene, camera, settings, x, y) {
                            Split::WithSds
                        } else {
                            Split::Off
                        };
                        let mut sum = Vec3::ZERO;
                        for _ in 0..settings.spp {
                            let l = sample(
                                scene,
                                camera,
                                settings,
                                (x, y, split),
                                &mut rng,
                                &mut paths,
                                &mut held,
                                &mut rays,
                            );
                            if l.is_finite() {
                                sum += l;
                            }
                            held.add_to_when_full(&mut film);
                        }
                        px.push(sum / settings.spp as f32);
                    }
                }
                held.add_to(&mut film);
                progress(u64::from((x1 - x0) * (y1 - y0)));
                done.push(((x0, y0), px));
                (done, film, rays)
            },
        )
        .reduce(
            || (Vec::new(), SplatFilm::new(w, h), 0),
            |(mut da, fa, ra), (db, fb, rb)| {
                da.extend(db);
                (da, fa.merge(&fb), ra + rb)
            },
        );
    let mut film = Film::new(w, h);
    for ((x0, y0), px) in done {
        for (i, p) in super::tile_pixels(x0, y0, w, h).zip(px) {
            film.pixels[i] = p;
        }
    }
    finish(cluster, film, splats, settings.spp, rays, start)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rng::stream;
    use crate::scene::{self, LoadOptions, World};

    /// The balance weight of strategy `(s, t)` computed from scratch: every strategy's density
    /// of the whole path, products of per-vertex densities recomputed from the positions. With
    /// `eta > 0` the merges at the path's inner non-Dirac vertices count too (density of the
    /// join that ends the eye path there, times `eta` and the light's density of the vertex),
    /// and with `merge` the weight is that of the merge at `camera[t - 1]`.
    #[allow(clippy::too_many_arguments)]
    fn brute_weight(
        scene: &RenderScene,
        cam: &Camera,
        light: &[Vertex],
        camera: &[Vertex],
        sampled: Option<&Vertex>,
        s: usize,
        t: usize,
        eta: f64,
        merge: bool,
    ) -> f64 {
        let mut xs: Vec<Vertex> = camera[..t].to_vec();
        if t == 1 {
            xs[0] = *sampled.unwrap();
        }
        for j in (0..s).rev() {
            xs.push(if s == 1 { *sampled.unwrap() } else { light[j] });
        }
        let k = xs.len() - 1;
        let mut p_cam = vec![0.0f64; k + 1];
        let mut p_light = vec![0.0f64; k + 1];
        for i in 1..=k {
            p_cam[i] = f64::from(if i == 1 {
                xs[0].pdf(scene, cam, None, &xs[1])
            } else {
                xs[i - 1].pdf(scene, cam, Some(&xs[i - 2]), &xs[i])
            });
        }
        p_light[k] = f64::from(xs[k].pdf_light_origin(scene));
        p_light[k - 1] = f64::from(xs[k].pdf_light(scene, &xs[k - 1]));
        for j in (1..k.saturating_sub(1)).rev() {
            p_light[j] = f64::from(xs[j + 1].pdf(scene, cam, Some(&xs[j + 2]), &xs[j]));
        }
        let delta = |i: usize| {
            if i == k {
                xs[k].light.is_some_and(|l| scene.lights.lights[l].is_delta())
            } else {
                xs[i].kind == VertexKind::Surface && xs[i].bsdf.is_delta()
            }
        };
        let density = |tp: usize| -> f64 {
            (1..tp).map(|i| p_cam[i]).product::<f64>() * (tp..=k).map(|j| p_light[j]).product::<f64>()
        };
        let mut total = 0.0;
        for tp in 1..=k + 1 {
            let valid = if tp == k + 1 { !delta(k) } else { !delta(tp - 1) && !delta(tp) };
            if valid {
                total += density(tp);
            }
        }
        let merged = |i: usize| density(i + 1) * eta * p_light[i];
        if eta > 0.0 {
            total += (1..k).filter(|&i| !delta(i)).map(merged).sum::<f64>();
        }
        // Vertices a few millimetres apart (densities above 1e4 per m^2) leave f32 positions
        // too few digits for a 1 % comparison.
        if p_cam.iter().chain(&p_light).any(|&p| p > 1e4) {
            return f64::NAN;
        }
        if merge { merged(t - 1) / total } else { density(t) / total }
    }

    /// A camera subpath of at most 8 vertices through the centre of pixel `n` of a 16x16
    /// image, and a light subpath of at most `light_depth` bounces.
    fn subpaths(
        scene: &RenderScene,
        cam: &Camera,
        n: u32,
        light_depth: u32,
        rng: &mut Rng64,
        (camera, light): (&mut Vec<Vertex>, &mut Vec<Vertex>),
        rays: &mut u64,
    ) {
        let (x, y) = (n % 16, (n / 16) % 16);
        camera.clear();
        let ray = cam.ray(Vec2::new((x as f32 + 0.5) / 16.0, (y as f32 + 0.5) / 16.0), Vec2::ZERO);
        camera.push(Vertex::endpoint(VertexKind::Camera, ray.origin, Vec3::ZERO, Vec3::ONE, None));
        let pdf_dir = cam.pdf_we(ray.origin, ray.dir).1;
        random_walk(scene, ray, Vec3::ONE, pdf_dir, 8, Mode::Radiance, rng, camera, rays);
        light_subpath(scene, light_depth, rng, light, rays);
    }

    #[test]
    fn mis_weights_match_the_balance_heuristic_from_scratch() {
        join_weights_match_the_balance_heuristic_from_scratch(0.0);
    }

    /// The joins' weights when merges are strategies too (VCM), with a merging disc large
    /// enough that merges and joins share the weight.
    #[test]
    fn join_weights_with_merges_match_the_balance_heuristic_from_scratch() {
        join_weights_match_the_balance_heuristic_from_scratch(2.0);
    }

    fn join_weights_match_the_balance_heuristic_from_scratch(eta: f32) {
        let world = World::build(
            scene::load("builtin:cornell_box_classic".as_ref(), &LoadOptions::default()).unwrap(),
        );
        let scene = RenderScene::new(&world);
        let cam = super::super::scene_camera(&world, 1.0).unwrap();
        let settings = RenderSettings { width: 16, height: 16, max_depth: 6, ..RenderSettings::default() };
        let mut rng = stream(5, 0, 0);
        let (mut camera, mut light) = (Vec::new(), Vec::new());
        let mut rays = 0;
        let (mut checked, mut deep) = (0, 0);
        for n in 0..400 {
            subpaths(&scene, &cam, n, settings.max_depth, &mut rng, (&mut camera, &mut light), &mut rays);
            for t in 1..=camera.len() {
                for s in 0..=light.len() {
                    if (s == 1 && t == 1) || s + t < 3 || s + t > 8 {
                        continue;
                    }
                    // The sampled endpoints of connect(), rebuilt without the visibility test.
                    let sampled = if t == 1 {
                        let Some(c) = cam.sample_wi(light[s - 1].p, u2(&mut rng)) else { continue };
                        Some(Vertex::endpoint(VertexKind::Camera, c.point, Vec3::ZERO, Vec3::ONE, None))
                    } else if s == 1 {
                        let pt = &camera[t - 1];
                        let u = u2(&mut rng);
                        let Some((index, _, ux)) = scene.lights.choose_reusing(u.x) else { continue };
                        let Some(ls) = scene.lights.lights[index].sample(pt.p, Vec2::new(ux, u.y)) else {
                            continue;
                        };
                        let nrm = light_normal(&scene, index, &ls);
                        let mut v =
                            Vertex::endpoint(VertexKind::Light, ls.point, nrm, Vec3::ONE, Some(index));
                        v.pdf_fwd = v.pdf_light_origin(&scene);
                        Some(v)
                    } else {
                        None
                    };
                    if s == 0 && camera[t - 1].light.is_none() {
                        continue;
                    }
                    // Only paths that carry light: the joined vertices scatter towards each other.
                    let pt = if t == 1 { sampled.unwrap() } else { camera[t - 1] };
                    let qs = if s == 1 {
                        sampled.unwrap()
                    } else if s > 0 {
                        light[s - 1]
                    } else {
                        pt
                    };
                    let carries = match (s, t) {
                        (0, _) => pt.le(&scene, &camera[t - 2]) != Vec3::ZERO,
                        (_, 1) => qs.f(&pt) != Vec3::ZERO,
                        (1, _) => pt.f(&qs) != Vec3::ZERO && qs.le(&scene, &pt) != Vec3::ZERO,
                        _ => qs.f(&pt) != Vec3::ZERO && pt.f(&qs) != Vec3::ZERO,
                    };
                    if !carries {
                        continue;
                    }
                    let w = mis_weight(&scene, &cam, &light, &camera, sampled.as_ref(), s, t, eta);
                    let b = brute_weight(
                        &scene,
                        &cam,
                        &light,
                        &camera,
                        sampled.as_ref(),
                        s,
                        t,
                        f64::from(eta),
                        false,
                    );
                    if !b.is_finite() || b == 0.0 {
                        continue;
                    }
                    checked += 1;
                    // Joins that read a subpath's stored prefix sums (Vertex::mis_joins).
                    deep += usize::from(s >= 3 || t >= 4);
                    assert!((f64::from(w) - b).abs() <= 1e-2 * b.max(1e-2), "s {s} t {t}: {w} vs {b}");
                }
            }
        }
        assert!(checked > 1000, "{checked}");
        assert!(deep > 300, "{deep} of {checked}");
    }

    /// The weight of a merge (the eye vertex `camera[t - 1]` with a light vertex at the same
    /// point, reached from `light[m - 1]`) against the balance heuristic from scratch over
    /// every join and merge of the path.
    #[test]
    fn merge_weights_match_the_balance_heuristic_from_scratch() {
        let world = World::build(
            scene::load("builtin:cornell_box_classic".as_ref(), &LoadOptions::default()).unwrap(),
        );
        let scene = RenderScene::new(&world);
        let cam = super::super::scene_camera(&world, 1.0).unwrap();
        let eta = 2.0f32;
        let mut rng = stream(9, 0, 0);
        let (mut camera, mut light) = (Vec::new(), Vec::new());
        let mut rays = 0;
        let (mut checked, mut deep, mut weight_sum) = (0, 0, 0.0f64);
        for n in 0..400 {
            subpaths(&scene, &cam, n, 6, &mut rng, (&mut camera, &mut light), &mut rays);
            for t in 2..=camera.len() {
                for m in 1..=light.len() {
                    if m + t > 8 || camera[t - 1].bsdf.is_delta() {
                        continue;
                    }
                    let mut photon = camera[t - 1];
                    photon.wo = (light[m - 1].p - photon.p).normalize();
                    photon.pdf_fwd = if m == 1 {
                        light[0].pdf_light(&scene, &photon)
                    } else {
                        light[m - 1].pdf(&scene, &cam, Some(&light[m - 2]), &photon)
                    };
                    // Only paths that carry light: the photon could have arrived, and the eye
                    // vertex scatters it towards the camera.
                    let q = &light[m - 1];
                    let arrives = if m == 1 { q.le(&scene, &photon) } else { q.f(&photon) };
                    if arrives == Vec3::ZERO || camera[t - 1].f(q) == Vec3::ZERO {
                        continue;
                    }
                    let mut joined: Vec<Vertex> = light[..m].to_vec();
                    joined.push(photon);
                    let w = merge_weight(&scene, &joined, &camera, t, eta);
                    let sampled = (m == 1).then_some(&light[0]);
                    let b = brute_weight(&scene, &cam, &light, &camera, sampled, m, t, f64::from(eta), true);
                    if !b.is_finite() || b == 0.0 {
                        continue;
                    }
                    checked += 1;
                    deep += usize::from(m >= 3 || t >= 4);
                    weight_sum += b;
                    assert!((f64::from(w) - b).abs() <= 1e-2 * b.max(1e-2), "m {m} t {t}: {w} vs {b}");
                }
            }
        }
        let mean = weight_sum / f64::from(checked);
        assert!(checked > 1000, "{checked}");
        assert!(deep > 300, "{deep} of {checked}");
        // Merges neither negligible nor alone, so the joins' terms are tested too.
        assert!((0.02..0.98).contains(&mean), "mean merge weight {mean}");
    }

    /// Eye paths `E D S..S L` (a Lambert vertex, then mirrors and glass, then a cosine emitter):
    /// only the hit (`s = 0`) and light tracing (`t = 1`) can make them, and through the
    /// specular chain their area densities share the chain's generalised geometry term, so
    /// the exact balance weight of the hit is `p_E / (p_E + p_L)`: `p_E` the camera's area
    /// density of the Lambert vertex, `p_L` the light's of its point (Lambert `cos / pi`
    /// and the emitter's `cos / pi` cancel the chain's end cosines; Veach 1997, sec. 10.3.5).
    #[test]
    fn caustic_eye_paths_get_the_exact_balance_weight_across_specular_chains() {
        let world =
            World::build(scene::load("rooms/caustics/scene.toml".as_ref(), &LoadOptions::default()).unwrap());
        let scene = RenderScene::new(&world);
        let cam = super::super::scene_camera(&world, 1.0).unwrap();
        let mut rng = stream(7, 0, 0);
        let (mut camera, light) = (Vec::new(), Vec::new());
        let mut rays = 0;
        let (mut checked, mut worst) = (0, 0.0f64);
        for _ in 0..400_000 {
            let ray = cam.ray(u2(&mut rng), Vec2::ZERO);
            camera.clear();
            camera.push(Vertex::endpoint(VertexKind::Camera, ray.origin, Vec3::ZERO, Vec3::ONE, None));
            let pdf_dir = cam.pdf_we(ray.origin, ray.dir).1;
            random_walk(&scene, ray, Vec3::ONE, pdf_dir, 8, Mode::Radiance, &mut rng, &mut camera, &mut rays);
            let Some(t) = camera.iter().position(|v| v.light.is_some()).map(|i| i + 1) else { continue };
            let lambert = matches!(camera[1].bsdf, Bsdf::Lambert { .. });
            if t < 4 || !lambert || camera[1].delta || !camera[2..t - 1].iter().all(|v| v.delta) {
                continue;
            }
            if camera[t - 1].le(&scene, &camera[t - 2]) == Vec3::ZERO {
                continue;
            }
            let w = f64::from(mis_weight(&scene, &cam, &light, &camera, None, 0, t, 0.0));
            let (e, d) = (camera[0].p, camera[1].p);
            let to_d = (d - e).normalize();
            let p_e =
                f64::from(cam.pdf_we(e, to_d).1 * camera[1].n.dot(to_d).abs() / (d - e).length_squared());
            let p_l = f64::from(camera[t - 1].pdf_light_origin(&scene));
            let exact = p_e / (p_e + p_l);
            worst = worst.max((w - exact).abs() / exact);
            checked += 1;
        }
        assert!(checked >= 20, "only {checked} caustic eye paths");
        assert!(worst < 1e-3, "worst relative error {worst} over {checked} paths");
    }
}
