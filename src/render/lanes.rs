//! The path tracer eight paths at a time, for scenes whose surfaces are all Lambertian and
//! whose lights are all emissive triangles: rooms, offices, Cornell boxes.
//!
//! One path's bounce is a chain of dependent steps (hit, frame, light sample, shadow ray, BSDF
//! sample, next hit), and the processor waits on each. Here eight lanes each render their own
//! pixel's samples, and every bounce runs as three phases over the lanes: their closest hits,
//! one after another (independent queries that the processor overlaps); their shading, as
//! eight-wide array code (which the compiler vectorises in part); their shadow rays and next
//! rays. The arithmetic is that of [`super::path::trace`] step for step, and each pixel still
//! draws from its own random stream in the same order, so the image is the scalar
//! integrator's bit for bit (tested): only the order of the work changes (the wavefront idea
//! of Laine, Karras and Aila 2013, "Megakernels considered harmful", on a CPU's vector
//! lanes). The whole loop, queries, shading and sampling, is compiled for the CPU's best
//! instruction set through [`crate::core::queries`].

use std::f32::consts::{FRAC_1_PI, PI};

use glam::Vec3;

use super::path::{RR_START_DEPTH, emitted};
use super::sampler::{SampleState, Sampler};
use super::{Bsdf, Camera, IntegratorKind, Light, RenderScene, RenderSettings, camera_ray, pixel_stream};
use crate::core::Ray;
use crate::core::flat::{FlatRay, LANES, Lanes, lanes};
use crate::core::queries::{Queries, QueryLoop};
use crate::core::ray::offset_origins;
use crate::core::rng::Rng64;
use crate::core::sampling::sin_cos_quarter;

/// Paths in flight on one thread: eight, the width of the core's block tests (one AVX
/// register of `f32`), so the core's lane helpers serve here too.
const N: usize = LANES;

/// Whether [`render_tile`] can render `scene` with `settings`: the path integrator, no
/// spheres, Lambertian surfaces only, triangle lights only, no indirect clamp.
pub fn applies(scene: &RenderScene, settings: &RenderSettings) -> bool {
    settings.integrator == IntegratorKind::Path
        && settings.clamp_indirect.is_none()
        && scene.accel.spheres.is_empty()
        && scene.accel.instances.is_empty()
        && scene.accel.shapes.is_empty()
        && scene.accel.sdfs.is_empty()
        && scene.surfaces.iter().all(|o| matches!(o.bsdf, Bsdf::Lambert { .. }))
        && scene.lights.lights.iter().all(|l| matches!(l, Light::Triangle { .. }))
}

/// One lane: the pixel it renders, its random stream and the path in flight.
struct Lane {
    /// Index of the pixel in the tile's output, row by row.
    pixel: usize,
    x: u32,
    y: u32,
    rng: Rng64,
    pixel_seed: u32,
    /// The sample being traced, where its numbers stand, and the sum of the finished ones.
    sample: u32,
    numbers: SampleState,
    sum: Vec3,
    ray: Ray,
    /// `FlatRay::new` of `ray`, for small meshes.
    flat_ray: FlatRay,
    l: Vec3,
    beta: Vec3,
    specular: bool,
    prev_pdf: f32,
    prev_point: Vec3,
    depth: u32,
}

/// What the shading phase reads, one array per quantity (structure of arrays).
#[derive(Default)]
struct Vertices {
    point: [Lanes; 3],
    normal: [Lanes; 3],
    dir: [Lanes; 3],
    albedo: [Lanes; 3],
    beta: [Lanes; 3],
    /// The chosen light: corner, edges, unit normal, area, radiance and choice probability.
    light_p0: [Lanes; 3],
    light_e1: [Lanes; 3],
    light_e2: [Lanes; 3],
    light_normal: [Lanes; 3],
    light_area: Lanes,
    light_le: [Lanes; 3],
    light_pmf: Lanes,
    /// The light pair (first coordinate stretched after the choice) and the BSDF pair.
    u_light: [Lanes; 2],
    u_bsdf: [Lanes; 2],
    /// The roulette number, or -1 before roulette starts.
    u_roulette: Lanes,
}

/// What the shading phase gives back.
#[derive(Default)]
struct Shaded {
    /// Unoccluded direct light (`f |cos| Le w / pdf`), and the shadow ray: `Ray::between`
    /// the shading point and the light point, as origin, direction and length.
    direct: [Lanes; 3],
    /// 1 where a shadow ray is traced, else 0.
    shadow: Lanes,
    shadow_origin: [Lanes; 3],
    shadow_dir: [Lanes; 3],
    shadow_t_max: Lanes,
    /// The next ray (`Ray::spawn` along the sampled direction), the direction's density, the
    /// new throughput, and whether the path lives.
    origin: [Lanes; 3],
    dir: [Lanes; 3],
    pdf: Lanes,
    beta: [Lanes; 3],
    /// 1 where the path goes on, else 0.
    alive: Lanes,
}

/// A lane-wise vector: `f(k, i)` is component `k` of lane `i`.
#[inline(always)]
fn vec3(f: impl Fn(usize, usize) -> f32) -> [Lanes; 3] {
    [lanes(|i| f(0, i)), lanes(|i| f(1, i)), lanes(|i| f(2, i))]
}

/// `(a.b)` of lane-wise vectors, in glam's order of operations.
#[inline(always)]
fn dot(a: [&Lanes; 3], b: [&Lanes; 3]) -> Lanes {
    lanes(|i| a[0][i] * b[0][i] + a[1][i] * b[1][i] + a[2][i] * b[2][i])
}

/// Next-event estimation and BSDF sampling at eight Lambertian vertices: the arithmetic of
/// `Frame::new`, `Light::sample` (triangle), `Bsdf::eval`, `Bsdf::pdf`, `power_heuristic`,
/// `Bsdf::sample` (Lambert) and the path loop's Russian roulette, lane by lane. Conditions
/// are written as selects inside each lane loop, so that the loops vectorise.
#[inline(always)]
fn shade(v: &Vertices) -> Shaded {
    let [nx, ny, nz] = &v.normal;
    // Frame::new (Duff et al. 2017).
    let sign = lanes(|i| 1.0f32.copysign(nz[i]));
    let a = lanes(|i| -1.0 / (sign[i] + nz[i]));
    let b = lanes(|i| nx[i] * ny[i] * a[i]);
    let t = [
        lanes(|i| 1.0 + sign[i] * nx[i] * nx[i] * a[i]),
        lanes(|i| sign[i] * b[i]),
        lanes(|i| -sign[i] * nx[i]),
    ];
    let bt = [b, lanes(|i| sign[i] + ny[i] * ny[i] * a[i]), lanes(|i| -ny[i])];
    let frame = |w: [&Lanes; 3]| {
        [dot(w, [&t[0], &t[1], &t[2]]), dot(w, [&bt[0], &bt[1], &bt[2]]), dot(w, [nx, ny, nz])]
    };
    let minus_dir = vec3(|k, i| -v.dir[k][i]);
    let wo = frame([&minus_dir[0], &minus_dir[1], &minus_dir[2]]);

    // Light::sample for a triangle: a uniform point, its direction, distance and density.
    let [ux, uy] = &v.u_light;
    let half = lanes(|i| if ux[i] < uy[i] { ux[i] / 2.0 } else { uy[i] / 2.0 });
    let b0 = lanes(|i| if ux[i] < uy[i] { half[i] } else { ux[i] - half[i] });
    let b1 = lanes(|i| if ux[i] < uy[i] { uy[i] - half[i] } else { half[i] });
    let q = vec3(|k, i| v.light_p0[k][i] + b0[i] * v.light_e1[k][i] + b1[i] * v.light_e2[k][i]);
    let to = vec3(|k, i| q[k][i] - v.point[k][i]);
    let d2 = dot([&to[0], &to[1], &to[2]], [&to[0], &to[1], &to[2]]);
    let distance = lanes(|i| d2[i].sqrt());
    let wi = vec3(|k, i| to[k][i] / distance[i]);
    let ln = &v.light_normal;
    let n_dot_wi = dot([&ln[0], &ln[1], &ln[2]], [&wi[0], &wi[1], &wi[2]]);
    let cos_l = lanes(|i| -n_dot_wi[i]);
    let light_pdf_area = lanes(|i| d2[i] / (cos_l[i] * v.light_area[i]));
    // Bsdf::eval and Bsdf::pdf (Lambert; zero unless both directions are on one side), then
    // the power heuristic.
    let wi_local = frame([&wi[0], &wi[1], &wi[2]]);
    let side = lanes(|i| wo[2][i] * wi_local[2][i]);
    let cos_i = lanes(|i| wi_local[2][i].abs());
    let f = vec3(|k, i| (if side[i] <= 0.0 { 0.0 } else { v.albedo[k][i] * FRAC_1_PI }) * cos_i[i]);
    let light_pdf = lanes(|i| light_pdf_area[i] * v.light_pmf[i]);
    let bsdf_pdf = lanes(|i| if side[i] <= 0.0 { 0.0 } else { cos_i[i] * FRAC_1_PI });
    let (lp2, bp2) = (lanes(|i| light_pdf[i] * light_pdf[i]), lanes(|i| bsdf_pdf[i] * bsdf_pdf[i]));
    let sum = lanes(|i| lp2[i] + bp2[i]);
    let ratio_pdf = lanes(|i| lp2[i] / sum[i]);
    let weight = lanes(|i| if sum[i] == 0.0 { 0.0 } else { ratio_pdf[i] });
    let weight = lanes(|i| if lp2[i] == f32::INFINITY { 1.0 } else { weight[i] });
    let scale = lanes(|i| weight[i] / light_pdf[i]);
    let direct = vec3(|k, i| f[k][i] * v.light_le[k][i] * scale[i]);
    // Light::sample's `None`, and `sample_direct`'s zero `f` or `Le`: no shadow ray. (Flags
    // are 1.0 or 0.0 lanes: selects the compiler vectorises, where bit masks would not.)
    let le = &v.light_le;
    let shadow = lanes(|i| {
        let sampled = !((cos_l[i] <= 0.0) | (d2[i] == 0.0));
        let f_lit = (f[0][i] != 0.0) | (f[1][i] != 0.0) | (f[2][i] != 0.0);
        let le_lit = (le[0][i] != 0.0) | (le[1][i] != 0.0) | (le[2][i] != 0.0);
        if sampled & f_lit & le_lit { 1.0 } else { 0.0 }
    });

    // Bsdf::sample (Lambert): the concentric disk lifted to the cosine-weighted hemisphere.
    let [bx, by] = &v.u_bsdf;
    let ox = lanes(|i| 2.0 * bx[i] - 1.0);
    let oy = lanes(|i| 2.0 * by[i] - 1.0);
    let num = lanes(|i| if ox[i].abs() > oy[i].abs() { oy[i] } else { ox[i] });
    let den = lanes(|i| if ox[i].abs() > oy[i].abs() { ox[i] } else { oy[i] });
    let angle = lanes(|i| (PI / 4.0) * (num[i] / den[i]));
    let sin_cos = [lanes(|i| sin_cos_quarter(angle[i]).0), lanes(|i| sin_cos_quarter(angle[i]).1)];
    let [sin, cos] = &sin_cos;
    let centre = |i: usize| (ox[i] == 0.0) & (oy[i] == 0.0);
    let x_major = |i: usize| ox[i].abs() > oy[i].abs();
    let dx = lanes(|i| if centre(i) { 0.0 } else { den[i] * if x_major(i) { cos[i] } else { sin[i] } });
    let dy = lanes(|i| if centre(i) { 0.0 } else { den[i] * if x_major(i) { sin[i] } else { cos[i] } });
    let z = lanes(|i| (1.0 - (dx[i] * dx[i] + dy[i] * dy[i])).max(0.0).sqrt());
    let wz = lanes(|i| if wo[2][i] < 0.0 { -z[i] } else { z[i] });
    let pdf = lanes(|i| wz[i].abs() * FRAC_1_PI);
    let ratio = lanes(|i| wz[i].abs() / pdf[i]);
    let beta = vec3(|k, i| v.beta[k][i] * (v.albedo[k][i] * FRAC_1_PI * ratio[i]));
    let dir = vec3(|k, i| t[k][i] * dx[i] + bt[k][i] * dy[i] + v.normal[k][i] * wz[i]);

    // Russian roulette (lanes with `u_roulette >= 0`): survive with probability max(beta), at
    // most 1; before it, a path ends when its throughput is zero.
    let larger = |a: f32, b: f32| if a > b { a } else { b }; // glam's max_element, NaNs included
    let q_max = lanes(|i| larger(beta[0][i], larger(beta[1][i], beta[2][i])).min(1.0));
    let one_if = |c: bool| if c { 1.0 } else { 0.0 };
    let roulette = lanes(|i| one_if(v.u_roulette[i] >= 0.0));
    let survives = lanes(|i| one_if(!((q_max[i] <= 0.0) | (v.u_roulette[i] >= q_max[i]))));
    let nonzero = lanes(|i| one_if((beta[0][i] != 0.0) | (beta[1][i] != 0.0) | (beta[2][i] != 0.0)));
    // 0/1 arithmetic, which vectorises where a branch per lane would not.
    let alive =
        lanes(|i| one_if(pdf[i] > 0.0) * (roulette[i] * survives[i] + (1.0 - roulette[i]) * nonzero[i]));
    let beta = vec3(|k, i| if v.u_roulette[i] >= 0.0 { beta[k][i] / q_max[i] } else { beta[k][i] });
    // Ray::between the shading point and the light point (both pushed off their surfaces,
    // the same arithmetic) and Ray::spawn.
    let shadow_origin = offset_origins(&v.point, &v.normal, &wi);
    let minus_wi = vec3(|k, i| -wi[k][i]);
    let shadow_end = offset_origins(&q, ln, &minus_wi);
    let rest = vec3(|k, i| shadow_end[k][i] - shadow_origin[k][i]);
    let rest2 = dot([&rest[0], &rest[1], &rest[2]], [&rest[0], &rest[1], &rest[2]]);
    let rest_len = lanes(|i| rest2[i].sqrt());
    let shadow_dir = vec3(|k, i| rest[k][i] / rest_len[i]);
    let shadow_t_max = lanes(|i| rest_len[i] * (1.0 - 1.0e-5));
    let origin = offset_origins(&v.point, &v.normal, &dir);
    Shaded { direct, shadow, shadow_origin, shadow_dir, shadow_t_max, origin, dir, pdf, beta, alive }
}

/// The pixels `x0..x1` x `y0..y1` in row order, as `super::render_pixel` gives them, bit for
/// bit. Counts traced rays into `rays`.
pub fn render_tile(
    scene: &RenderScene,
    camera: &Camera,
    s: &RenderSettings,
    tile: (u32, u32, u32, u32),
    rays: &mut u64,
) -> Vec<Vec3> {
    scene.accel.mesh.run_queries(Tile { scene, camera, s, tile, rays })
}

/// [`render_tile`]'s arguments: the loop, compiled with the mesh's queries inlined.
struct Tile<'a> {
    scene: &'a RenderScene<'a>,
    camera: &'a Camera,
    s: &'a RenderSettings,
    tile: (u32, u32, u32, u32),
    rays: &'a mut u64,
}

impl QueryLoop<Vec<Vec3>> for Tile<'_> {
    #[inline(always)]
    fn run<Q: Queries>(self, queries: &Q) -> Vec<Vec3> {
        let Tile { scene, camera, s, tile, rays } = self;
        tile_loop(queries, scene, camera, s, tile, rays)
    }
}

/// [`render_tile`] with `queries`.
#[inline(always)]
fn tile_loop(
    queries: &impl Queries,
    scene: &RenderScene,
    camera: &Camera,
    s: &RenderSettings,
    (x0, y0, x1, y1): (u32, u32, u32, u32),
    rays: &mut u64,
) -> Vec<Vec3> {
    let tw = x1 - x0;
    let count = (tw * (y1 - y0)) as usize;
    let mut out = vec![Vec3::ZERO; count];
    let mut next = 0usize;
    let mut active: Vec<Lane> = Vec::with_capacity(N);
    let start = |pixel: usize| -> Lane {
        let (x, y) = (x0 + pixel as u32 % tw, y0 + pixel as u32 / tw);
        let (rng, pixel_seed) = pixel_stream(s, x, y);
        let mut lane = Lane {
            pixel,
            x,
            y,
            rng,
            pixel_seed,
            sample: 0,
            numbers: SampleState::default(),
            sum: Vec3::ZERO,
            ray: Ray::new(Vec3::ZERO, Vec3::Z),
            flat_ray: FlatRay::new(Vec3::ZERO, Vec3::Z),
            l: Vec3::ZERO,
            beta: Vec3::ONE,
            specular: true,
            prev_pdf: 0.0,
            prev_point: Vec3::ZERO,
            depth: 0,
        };
        start_sample(&mut lane, camera, s);
        lane
    };
    while active.len() < N && next < count {
        active.push(start(next));
        next += 1;
    }
    let mut v = Vertices::default();
    let mut hit_points = [Vec3::ZERO; N];
    while !active.is_empty() {
        // Phase 1: closest hits, emission, and the numbers and light of each live vertex.
        let mut live = [false; N];
        let mut finished = [false; N];
        for (i, lane) in active.iter_mut().enumerate() {
            *rays += 1;
            let Some(hit) = scene.hit_of(&lane.ray, queries.closest(&lane.ray, &lane.flat_ray)) else {
                lane.l += lane.beta * scene.background;
                finished[i] = true;
                continue;
            };
            let optics = &scene.surfaces[hit.surface as usize];
            let previous = (lane.specular, lane.prev_pdf, lane.prev_point);
            lane.l += emitted(scene, &hit, lane.ray.dir, lane.beta, previous);
            if lane.depth >= s.max_depth {
                finished[i] = true;
                continue;
            }
            let mut sampler = Sampler::resume(lane.numbers, &mut lane.rng);
            sampler.start_bounce(lane.depth);
            let (u_light, u_bsdf) = (sampler.get_2d(), sampler.get_2d());
            lane.depth += 1;
            v.u_roulette[i] = if lane.depth >= RR_START_DEPTH { sampler.get_1d() } else { -1.0 };
            lane.numbers = sampler.state();
            let Bsdf::Lambert { albedo } = optics.bsdf else {
                unreachable!("lanes::applies admits Lambertian surfaces only")
            };
            let light = scene.lights.choose_reusing(u_light.x);
            let (ux, pmf, le) = match light.map(|(l, pmf, ux)| (&scene.lights.lights[l], pmf, ux)) {
                Some((&Light::Triangle { p0, e1, e2, normal, area, le }, pmf, ux)) => {
                    for k in 0..3 {
                        v.light_p0[k][i] = p0[k];
                        v.light_e1[k][i] = e1[k];
                        v.light_e2[k][i] = e2[k];
                        v.light_normal[k][i] = normal[k];
                    }
                    v.light_area[i] = area;
                    (ux, pmf, le)
                }
                // No light (or, never, another kind): nothing to sample.
                _ => (u_light.x, 1.0, Vec3::ZERO),
            };
            v.light_pmf[i] = pmf;
            [v.u_light[0][i], v.u_light[1][i]] = [ux, u_light.y];
            [v.u_bsdf[0][i], v.u_bsdf[1][i]] = [u_bsdf.x, u_bsdf.y];
            for k in 0..3 {
                v.point[k][i] = hit.point[k];
                v.normal[k][i] = hit.normal[k];
                v.dir[k][i] = lane.ray.dir[k];
                v.albedo[k][i] = albedo[k];
                v.beta[k][i] = lane.beta[k];
                v.light_le[k][i] = le[k];
            }
            hit_points[i] = hit.point;
            live[i] = true;
        }
        // Phase 2: shading, eight lanes at once.
        let sh = if live.contains(&true) { shade(&v) } else { Shaded::default() };
        // Phase 3: shadow rays, the next rays, and lanes whose sample ends.
        let at = |x: &[Lanes; 3], i: usize| Vec3::new(x[0][i], x[1][i], x[2][i]);
        for (i, lane) in active.iter_mut().enumerate() {
            if !live[i] {
                continue;
            }
            if sh.shadow[i] != 0.0 {
                *rays += 1;
                let ray = Ray::segment(at(&sh.shadow_origin, i), at(&sh.shadow_dir, i), sh.shadow_t_max[i]);
                if !queries.occluded(&ray) {
                    let direct = Vec3::new(sh.direct[0][i], sh.direct[1][i], sh.direct[2][i]);
                    lane.l += lane.beta * direct;
                }
            }
            if sh.alive[i] == 0.0 {
                finished[i] = true;
                continue;
            }
            lane.beta = Vec3::new(sh.beta[0][i], sh.beta[1][i], sh.beta[2][i]);
            lane.specular = false;
            lane.prev_pdf = sh.pdf[i];
            lane.prev_point = hit_points[i];
            lane.ray = Ray::new(at(&sh.origin, i), at(&sh.dir, i));
            // Built here, its divisions off the way to the next closest hit.
            lane.flat_ray = FlatRay::new(lane.ray.origin, lane.ray.dir);
        }
        // Finished samples: add them up, start the pixel's next sample or the next pixel.
        let mut i = 0;
        let mut lane_index = 0;
        while i < active.len() {
            if !finished[lane_index] {
                i += 1;
                lane_index += 1;
                continue;
            }
            lane_index += 1;
            let lane = &mut active[i];
            if lane.l.is_finite() {
                lane.sum += lane.l;
            }
            lane.sample += 1;
            if lane.sample < s.spp {
                start_sample(lane, camera, s);
                i += 1;
            } else {
                out[lane.pixel] = lane.sum / s.spp as f32;
                if next < count {
                    *lane = start(next);
                    next += 1;
                    i += 1;
                } else {
                    active.remove(i);
                }
            }
        }
    }
    out
}

/// Starts sample `lane.sample` of the lane's pixel: its camera ray and a fresh path.
#[inline(always)]
fn start_sample(lane: &mut Lane, camera: &Camera, s: &RenderSettings) {
    let has_lens = camera.aperture_radius_m > 0.0;
    let mut sampler = Sampler::new(lane.pixel_seed, lane.sample, has_lens, &mut lane.rng);
    lane.ray = camera_ray(camera, s, lane.x, lane.y, &mut sampler);
    lane.numbers = sampler.state();
    lane.flat_ray = FlatRay::new(lane.ray.origin, lane.ray.dir);
    lane.l = Vec3::ZERO;
    lane.beta = Vec3::ONE;
    lane.specular = true;
    lane.prev_pdf = 0.0;
    lane.prev_point = lane.ray.origin;
    lane.depth = 0;
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::{SurfaceOptics, render_pixel, scene_camera};
    use crate::scene::{self, LoadOptions, World};

    fn cornell() -> Result<World, String> {
        let scene = scene::load("builtin:cornell_box_classic".as_ref(), &LoadOptions::default());
        Ok(World::build(scene.map_err(|e| e.to_string())?))
    }

    #[test]
    fn lanes_give_the_scalar_integrators_pixels_bit_for_bit() -> Result<(), String> {
        let world = cornell()?;
        let mut scene = RenderScene::new(&world);
        assert!(applies(&scene, &RenderSettings::default()));
        let pinhole = scene_camera(&world, 1.0)?;
        let lens = Camera { aperture_radius_m: 0.02, focus_distance_m: 1.0, ..pinhole };
        // Sample counts, depths (0: emitters seen directly only; 1: direct light only; past the
        // roulette's start), a lens, a background seen through the open front, other seeds.
        for (spp, max_depth, camera, background, seed) in [
            (8, 8, pinhole, Vec3::ZERO, 0),
            (5, 1, pinhole, Vec3::ZERO, 1),
            (3, 0, pinhole, Vec3::ZERO, 2),
            (6, 12, lens, Vec3::new(0.3, 0.2, 0.1), 3),
        ] {
            scene.background = background;
            let s =
                RenderSettings { width: 40, height: 36, spp, max_depth, seed, ..RenderSettings::default() };
            // A partial tile (fewer pixels than lanes in its last row), then a whole one.
            for (x0, y0, x1, y1) in [(3, 30, 14, 36), (16, 8, 32, 24)] {
                let mut rays = [0u64; 2];
                let lanes = render_tile(&scene, &camera, &s, (x0, y0, x1, y1), &mut rays[0]);
                let mut scalar = Vec::new();
                for y in y0..y1 {
                    for x in x0..x1 {
                        scalar.push(render_pixel(&scene, &camera, &s, x, y, &mut rays[1], None, None));
                    }
                }
                let bits =
                    |v: &[Vec3]| v.iter().flat_map(|p| p.to_array().map(f32::to_bits)).collect::<Vec<_>>();
                assert_eq!(bits(&lanes), bits(&scalar), "spp {spp}, depth {max_depth}, tile {x0},{y0}");
                assert_eq!(rays[0], rays[1]);
                assert!(max_depth == 0 || lanes.iter().any(|p| p.max_element() > 0.0));
            }
        }
        // No emitter at all, lit by the background alone: no light to sample at any vertex.
        let mut optics = scene.surfaces.clone();
        optics.iter_mut().for_each(|o| o.emission = Vec3::ZERO);
        let mesh = &world.scene.mesh;
        let unlit = RenderScene::from_parts(&world.accel, mesh, &[], optics, &[], Vec3::new(0.5, 0.6, 0.7));
        assert!(unlit.lights.is_empty() && applies(&unlit, &RenderSettings::default()));
        let s = RenderSettings { width: 40, height: 36, spp: 4, ..RenderSettings::default() };
        let mut rays = [0u64; 2];
        let lanes = render_tile(&unlit, &pinhole, &s, (0, 0, 16, 16), &mut rays[0]);
        let scalar: Vec<Vec3> = (0..256)
            .map(|k| render_pixel(&unlit, &pinhole, &s, k % 16, k / 16, &mut rays[1], None, None))
            .collect();
        assert!(
            lanes
                .iter()
                .zip(&scalar)
                .all(|(a, b)| a.to_array().map(f32::to_bits) == b.to_array().map(f32::to_bits))
        );
        assert!(lanes.iter().any(|p| p.max_element() > 0.0));
        Ok(())
    }

    #[test]
    fn lanes_apply_to_lambertian_scenes_lit_by_triangles_only() -> Result<(), String> {
        let world = cornell()?;
        let mut scene = RenderScene::new(&world);
        let path = RenderSettings::default();
        assert!(applies(&scene, &path));
        for integrator in [IntegratorKind::Raycast, IntegratorKind::Whitted, IntegratorKind::Distributed] {
            assert!(!applies(&scene, &RenderSettings { integrator, ..path.clone() }));
        }
        let lambert = scene.surfaces[0];
        scene.surfaces[0] = SurfaceOptics { bsdf: Bsdf::Metal { f0: Vec3::ONE, alpha: 0.2 }, ..lambert };
        assert!(!applies(&scene, &path));
        scene.surfaces[0] = lambert;
        scene.lights.lights.push(Light::Point { position: Vec3::ZERO, intensity: Vec3::ONE });
        assert!(!applies(&scene, &path));
        Ok(())
    }
}
