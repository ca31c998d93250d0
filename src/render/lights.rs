//! Light sources: point lights, emissive triangles (area lights, the scene mesh's and those
//! of instanced meshes placed in the world), emissive spheres and emissive analytic shapes
//! ([`super::shape_light`]), with sampling by solid angle for next-event estimation and the
//! matching densities for multiple importance sampling (pbrt-v4 ch. 12; Veach 1997 ch. 9).
//!
//! Emitters are one-sided Lambertian: a triangle, sphere or shape emits radiance `Le` from the
//! side its normal points to (pbrt-v4's default area light).

use std::f32::consts::PI;

use glam::{Vec2, Vec3};

use super::shape_light::ShapeLight;
use crate::core::sampling::{to_world, uniform_sphere, uniform_triangle};
use crate::core::shapes::Shape;
use crate::core::{Instance, Sphere, SurfaceId, TriangleMesh};

/// Marks a primitive that is not a light in the primitive-to-light maps.
const NOT_A_LIGHT: u32 = u32::MAX;

/// The largest f32 below 1.
const ONE_MINUS_EPSILON: f32 = 1.0 - f32::EPSILON / 2.0;

/// One light.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Light {
    /// Isotropic point light of radiant intensity `intensity` (W/sr per channel).
    Point {
        /// Position, metres.
        position: Vec3,
        /// Radiant intensity, W/sr per channel.
        intensity: Vec3,
    },
    /// Emissive triangle `p0, p0 + e1, p0 + e2` with unit normal `normal` and radiance `le`.
    Triangle {
        /// First corner.
        p0: Vec3,
        /// Edge from `p0` to the second corner.
        e1: Vec3,
        /// Edge from `p0` to the third corner.
        e2: Vec3,
        /// Unit normal.
        normal: Vec3,
        /// Area, m^2.
        area: f32,
        /// Emitted radiance.
        le: Vec3,
    },
    /// Emissive sphere (emitting outwards) of radiance `le`.
    Sphere {
        /// Centre, metres.
        center: Vec3,
        /// Radius, metres.
        radius: f32,
        /// Emitted radiance.
        le: Vec3,
    },
    /// Emissive analytic shape (emitting outwards; a disk towards its normal).
    Shape(ShapeLight),
}

/// A point sampled on a light as seen from a shading point.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LightSample {
    /// Unit direction from the shading point to the light point.
    pub wi: Vec3,
    /// Distance to the light point, metres.
    pub distance: f32,
    /// The light point.
    pub point: Vec3,
    /// Incident radiance (area lights) or `intensity / distance^2` (point lights).
    pub li: Vec3,
    /// Density per solid angle at the shading point (1 for a point light, a Dirac).
    pub pdf: f32,
    /// Whether the light is a Dirac (a point light).
    pub delta: bool,
    /// Where a shadow ray towards the light should stop: the light point, or for a sphere a
    /// point 0.1 % of the distance short of it. Near a sphere's silhouette the near root has
    /// an error of about sqrt(f32 epsilon) times the distance, and a shadow ray ending at the
    /// computed point would often hit the light sphere itself: that lost 1.4 % of a 10 cm
    /// bulb's direct light on a floor against the closed form. The segment to the near side of
    /// a convex light cannot cross the light itself, so stopping short loses nothing.
    pub shadow_point: Vec3,
    /// The light's geometric normal at `shadow_point` when it lies on a flat emitter: the
    /// shadow segment is then pushed off both surfaces ([`crate::core::ray::Ray::between`]).
    pub shadow_normal: Option<Vec3>,
    /// The light's unit normal at `point` (zero for a point light).
    pub normal: Vec3,
}

impl Light {
    /// Emitted power, W per channel: `4 pi I` for points, `pi A Le` for one-sided emitters.
    pub fn power(&self) -> Vec3 {
        match *self {
            Light::Point { intensity, .. } => 4.0 * PI * intensity,
            Light::Triangle { area, le, .. } => PI * area * le,
            Light::Sphere { radius, le, .. } => PI * 4.0 * PI * radius * radius * le,
            Light::Shape(s) => PI * s.area_m2 * s.le,
        }
    }

    /// The centre of the light (its position, a triangle's centroid, a sphere's centre).
    pub fn center(&self) -> Vec3 {
        match *self {
            Light::Point { position, .. } => position,
            Light::Triangle { p0, e1, e2, .. } => p0 + (e1 + e2) / 3.0,
            Light::Sphere { center, .. } => center,
            Light::Shape(s) => s.centre(),
        }
    }

    /// A point that stands for the light in point-light approximations (Whitted, raycast) and
    /// the radiant intensity it sends along unit `dir` (from the light towards the receiver).
    pub fn as_point(&self, dir: Vec3) -> (Vec3, Vec3) {
        match *self {
            Light::Point { position, intensity } => (position, intensity),
            Light::Triangle { p0, e1, e2, normal, area, le } => {
                (p0 + (e1 + e2) / 3.0, le * (area * normal.dot(dir).max(0.0)))
            }
            Light::Sphere { center, radius, le } => (center + radius * dir, le * (PI * radius * radius)),
            Light::Shape(s) => (s.centre(), s.intensity_towards(dir)),
        }
    }

    /// Samples the light from shading point `p` with `u` in `[0,1)^2`.
    pub fn sample(&self, p: Vec3, u: Vec2) -> Option<LightSample> {
        match *self {
            Light::Point { position, intensity } => {
                let to = position - p;
                let d2 = to.length_squared();
                if d2 == 0.0 {
                    return None;
                }
                let distance = d2.sqrt();
                Some(LightSample {
                    wi: to / distance,
                    distance,
                    point: position,
                    li: intensity / d2,
                    pdf: 1.0,
                    delta: true,
                    shadow_point: position,
                    shadow_normal: None,
                    normal: Vec3::ZERO,
                })
            }
            Light::Triangle { p0, e1, e2, normal, area, le } => {
                let b = uniform_triangle(u);
                let q = p0 + b.x * e1 + b.y * e2;
                let to = q - p;
                let d2 = to.length_squared();
                let distance = d2.sqrt();
                let wi = to / distance;
                let cos_l = -normal.dot(wi);
                if cos_l <= 0.0 || d2 == 0.0 {
                    return None;
                }
                let pdf = d2 / (cos_l * area);
                Some(LightSample {
                    wi,
                    distance,
                    point: q,
                    li: le,
                    pdf,
                    delta: false,
                    shadow_point: q,
                    shadow_normal: Some(normal),
                    normal,
                })
            }
            Light::Sphere { center, radius, le } => {
                let to_c = center - p;
                let dc2 = to_c.length_squared();
                let r2 = radius * radius;
                if dc2 <= r2 * 1.0001 {
                    // Inside (or on) the sphere: uniform area sampling; an outward emitter
                    // sends nothing inwards.
                    let _ = uniform_sphere(u);
                    return None;
                }
                // Uniform sampling of the cone the sphere subtends (pbrt-v4 sec. 6.2.4).
                let dc = dc2.sqrt();
                let axis = to_c / dc;
                let sin2_max = r2 / dc2;
                let cos_max = (1.0 - sin2_max).max(0.0).sqrt();
                let one_minus_cos_max = if sin2_max < 1.0e-4 { 0.5 * sin2_max } else { 1.0 - cos_max };
                let cos_t = 1.0 - u.x * one_minus_cos_max;
                let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
                let phi = 2.0 * PI * u.y;
                let wi = to_world(Vec3::new(sin_t * phi.cos(), sin_t * phi.sin(), cos_t), axis);
                // Distance to the near intersection with the sphere.
                let b = dc * cos_t;
                let disc = (r2 - dc2 * sin_t * sin_t).max(0.0);
                let distance = b - disc.sqrt();
                let point = p + wi * distance;
                Some(LightSample {
                    wi,
                    distance,
                    point,
                    li: le,
                    pdf: 1.0 / (2.0 * PI * one_minus_cos_max),
                    delta: false,
                    shadow_point: p + wi * (distance * (1.0 - 1.0e-3)),
                    shadow_normal: None,
                    normal: (point - center).normalize_or_zero(),
                })
            }
            Light::Shape(s) => {
                // By area (see `shape_light`), the density turned per solid angle at `p`.
                let (q, n) = s.sample_area(u);
                let to = q - p;
                let d2 = to.length_squared();
                let distance = d2.sqrt();
                let wi = to / distance;
                let cos_l = -n.dot(wi);
                if cos_l <= 0.0 || d2 == 0.0 {
                    return None;
                }
                Some(LightSample {
                    wi,
                    distance,
                    point: q,
                    li: s.le,
                    pdf: s.pdf_area(n) * d2 / cos_l,
                    delta: false,
                    // Short of the point, as for spheres: on a curved face the ray's root
                    // near a silhouette is inexact and must not find the light itself, and
                    // the segment to the lit side of a convex shape cannot cross it.
                    shadow_point: p + wi * (distance * (1.0 - 1.0e-3)),
                    shadow_normal: None,
                    normal: n,
                })
            }
        }
    }

    /// Density per solid angle with which [`Light::sample`] from `p` would pick the point `q`
    /// (with unit surface normal `n`) hit along unit `wi`.
    pub fn pdf(&self, p: Vec3, wi: Vec3, q: Vec3, n: Vec3) -> f32 {
        match *self {
            Light::Point { .. } => 0.0,
            Light::Triangle { area, .. } => {
                let cos_l = n.dot(wi).abs();
                if cos_l == 0.0 {
                    return 0.0;
                }
                (q - p).length_squared() / (cos_l * area)
            }
            Light::Sphere { center, radius, .. } => {
                let dc2 = (center - p).length_squared();
                let sin2_max = radius * radius / dc2;
                if sin2_max >= 1.0 / 1.0001 {
                    return 0.0;
                }
                let one_minus_cos_max =
                    if sin2_max < 1.0e-4 { 0.5 * sin2_max } else { 1.0 - (1.0 - sin2_max).sqrt() };
                1.0 / (2.0 * PI * one_minus_cos_max)
            }
            Light::Shape(s) => {
                let cos_l = n.dot(wi).abs();
                if cos_l == 0.0 {
                    return 0.0;
                }
                s.pdf_area(n) * (q - p).length_squared() / cos_l
            }
        }
    }
}

/// A ray leaving a light, for tracing from the lights ([`Light::sample_le`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EmissionSample {
    /// The point on the light, metres.
    pub point: Vec3,
    /// Unit surface normal there (zero for a point light).
    pub normal: Vec3,
    /// Unit direction of emission.
    pub dir: Vec3,
    /// Emitted radiance along `dir` (radiant intensity for a point light).
    pub le: Vec3,
    /// Density of `point` per unit area on the light (1 for a point light, a Dirac).
    pub pdf_pos: f32,
    /// Density of `dir` per solid angle.
    pub pdf_dir: f32,
}

impl Light {
    /// Whether the light's position is a Dirac (a point light): no path can hit it.
    #[inline]
    pub fn is_delta(&self) -> bool {
        matches!(self, Light::Point { .. })
    }

    /// Samples a ray leaving the light: a point uniform by area with `u_pos` and a
    /// cosine-weighted direction about the normal with `u_dir` (uniform on the sphere for a
    /// point light); pbrt-v4's `SampleLe` (sec. 12.2, 12.3) for one-sided diffuse emitters.
    pub fn sample_le(&self, u_pos: Vec2, u_dir: Vec2) -> Option<EmissionSample> {
        let (point, normal, le, pdf_pos) = match *self {
            Light::Point { position, intensity } => {
                let dir = uniform_sphere(u_dir);
                return Some(EmissionSample {
                    point: position,
                    normal: Vec3::ZERO,
                    dir,
                    le: intensity,
                    pdf_pos: 1.0,
                    pdf_dir: 1.0 / (4.0 * PI),
                });
            }
            Light::Triangle { p0, e1, e2, normal, area, le } => {
                let b = uniform_triangle(u_pos);
                (p0 + b.x * e1 + b.y * e2, normal, le, 1.0 / area)
            }
            Light::Sphere { center, radius, le } => {
                let n = uniform_sphere(u_pos);
                (center + radius * n, n, le, 1.0 / (4.0 * PI * radius * radius))
            }
            Light::Shape(s) => {
                let (q, n) = s.sample_area(u_pos);
                (q, n, s.le, s.pdf_area(n))
            }
        };
        let local = crate::core::sampling::cosine_hemisphere(u_dir);
        let pdf_dir = local.z / PI;
        if pdf_dir <= 0.0 {
            return None;
        }
        Some(EmissionSample { point, normal, dir: to_world(local, normal), le, pdf_pos, pdf_dir })
    }

    /// Density per solid angle with which [`Light::sample_le`] emits along unit `dir` from a
    /// point of normal `normal`.
    #[inline]
    pub fn pdf_le_dir(&self, normal: Vec3, dir: Vec3) -> f32 {
        match self {
            Light::Point { .. } => 1.0 / (4.0 * PI),
            _ => normal.dot(dir).max(0.0) / PI,
        }
    }

    /// Density per unit area with which [`Light::sample_le`] picks a point of unit normal
    /// `normal` (1 for a point light; a stretched shape's density varies with the normal).
    #[inline]
    pub fn pdf_le_pos(&self, normal: Vec3) -> f32 {
        match *self {
            Light::Point { .. } => 1.0,
            Light::Triangle { area, .. } => 1.0 / area,
            Light::Sphere { radius, .. } => 1.0 / (4.0 * PI * radius * radius),
            Light::Shape(s) => s.pdf_area(normal),
        }
    }

    /// Radiance (intensity for a point light) emitted from a point of normal `normal` along
    /// unit `dir`: one-sided emitters send nothing behind them.
    #[inline]
    pub fn le_towards(&self, normal: Vec3, dir: Vec3) -> Vec3 {
        match *self {
            Light::Point { intensity, .. } => intensity,
            Light::Triangle { le, .. } | Light::Sphere { le, .. } | Light::Shape(ShapeLight { le, .. }) => {
                if normal.dot(dir) > 0.0 {
                    le
                } else {
                    Vec3::ZERO
                }
            }
        }
    }
}

/// Every light of a scene, a power-proportional choice among them, and maps from emissive
/// primitives back to their light.
#[derive(Clone, Debug, Default)]
pub struct Lights {
    /// Every light.
    pub lights: Vec<Light>,
    /// Probability of choosing each light.
    pmf: Vec<f32>,
    /// Running sum of `pmf`.
    cdf: Vec<f32>,
    /// Running sum of `pmf` before each light (`cdf` shifted by one, from 0).
    cdf_below: Vec<f32>,
    /// `1 / pmf` (a multiply is quicker than a divide on this chain).
    inv_pmf: Vec<f32>,
    /// Light index of each mesh triangle, or `NOT_A_LIGHT`.
    triangle_light: Vec<u32>,
    /// Light index of each sphere, or `NOT_A_LIGHT`.
    sphere_light: Vec<u32>,
    /// Light index of each analytic shape, or `NOT_A_LIGHT`.
    shape_light: Vec<u32>,
    /// `(instance << 32 | triangle, light)` of every emissive triangle of an instance, sorted:
    /// only the emissive copies' triangles take entries, so a forest of plain trees costs
    /// nothing here.
    instance_light: Vec<(u64, u32)>,
}

/// The primitives of a scene that may emit, for [`Lights::from_emitters`].
#[derive(Clone, Copy, Default)]
pub struct Emitters<'a> {
    /// The scene's own triangles.
    pub mesh: Option<&'a TriangleMesh>,
    /// The analytic spheres.
    pub spheres: &'a [Sphere],
    /// The transformed analytic shapes and their surfaces.
    pub shapes: &'a [(Shape, SurfaceId)],
    /// The meshes that instances place.
    pub instance_meshes: &'a [TriangleMesh],
    /// The placed copies, in the order their set was built from
    /// ([`crate::core::InstanceSet::build`]).
    pub instances: &'a [Instance],
}

impl Lights {
    /// Collects point lights plus every triangle and sphere whose surface emits, per
    /// `emission[surface_id]`.
    pub fn new(points: &[(Vec3, Vec3)], mesh: &TriangleMesh, spheres: &[Sphere], emission: &[Vec3]) -> Self {
        Self::from_emitters(points, &Emitters { mesh: Some(mesh), spheres, ..Emitters::default() }, emission)
    }

    /// Collects point lights plus every triangle, sphere, shape and instanced triangle of
    /// `emitters` whose surface emits, per `emission[surface_id]` (lights in that order). A
    /// quadric shape never emits (it has no closed-form area; the loader refuses one).
    pub fn from_emitters(points: &[(Vec3, Vec3)], emitters: &Emitters, emission: &[Vec3]) -> Self {
        let emits =
            |surface: SurfaceId| emission.get(surface as usize).copied().filter(|e| e.max_element() > 0.0);
        let mut lights: Vec<Light> =
            points.iter().map(|&(position, intensity)| Light::Point { position, intensity }).collect();
        let mesh_triangles = emitters.mesh.map_or(0, TriangleMesh::triangle_count);
        let mut triangle_light = vec![NOT_A_LIGHT; mesh_triangles];
        if let Some(mesh) = emitters.mesh {
            for (i, tl) in triangle_light.iter_mut().enumerate() {
                let Some(le) = emits(mesh.surface_of_triangle[i]) else { continue };
                if let Some(light) = triangle(mesh.corners(i), le) {
                    *tl = lights.len() as u32;
                    lights.push(light);
                }
            }
        }
        let mut sphere_light = vec![NOT_A_LIGHT; emitters.spheres.len()];
        for (s, sl) in emitters.spheres.iter().zip(&mut sphere_light) {
            if let Some(le) = emits(s.surface) {
                *sl = lights.len() as u32;
                lights.push(Light::Sphere { center: s.center, radius: s.radius_m, le });
            }
        }
        let mut shape_light = vec![NOT_A_LIGHT; emitters.shapes.len()];
        for ((shape, surface), sl) in emitters.shapes.iter().zip(&mut shape_light) {
            let Some(le) = emits(*surface) else { continue };
            // A round sphere (a similarity) takes the sphere light's sampling of the cone it
            // subtends, which wastes no sample on its far side; other shapes sample by area.
            let light = match round_sphere(shape) {
                Some((center, radius)) => Some(Light::Sphere { center, radius, le }),
                None => ShapeLight::new(shape, le).map(Light::Shape),
            };
            if let Some(light) = light {
                *sl = lights.len() as u32;
                lights.push(light);
            }
        }
        // Instances are numbered as `InstanceSet::build` places them: it skips a copy of an
        // empty mesh or with an invalid transform (the loader refuses the latter).
        let mut instance_light = Vec::new();
        let mut placed = 0u64;
        for inst in emitters.instances {
            let Some(mesh) = emitters.instance_meshes.get(inst.mesh as usize) else { continue };
            if mesh.bounds().is_none() || !Instance::transform_is_valid(&inst.object_to_world) {
                continue;
            }
            placed += 1;
            // Most copies emit nothing: one look at their few surfaces, not their triangles.
            let surface_of = |s: SurfaceId| inst.surfaces.get(s as usize).copied().unwrap_or(s);
            let ids = mesh.surface_names.len().max(inst.surfaces.len()) as SurfaceId;
            if !(0..ids).any(|s| emits(surface_of(s)).is_some()) {
                continue;
            }
            let mirrored = inst.object_to_world.matrix3.determinant() < 0.0;
            for (t, &s) in mesh.surface_of_triangle.iter().enumerate() {
                let Some(le) = emits(surface_of(s)) else { continue };
                let [a, b, c] = mesh.corners(t).map(|p| inst.object_to_world.transform_point3(p));
                // A mirrored copy is rewound so that its right-hand normal is the transformed
                // normal the instance's hits report (as `flatten` does).
                let corners = if mirrored { [a, c, b] } else { [a, b, c] };
                if let Some(light) = triangle(corners, le) {
                    instance_light.push(((placed - 1) << 32 | t as u64, lights.len() as u32));
                    lights.push(light);
                }
            }
        }
        let weights: Vec<f32> = lights.iter().map(|l| l.power().element_sum().max(0.0)).collect();
        let total: f32 = weights.iter().sum();
        let pmf: Vec<f32> = if total > 0.0 {
            weights.iter().map(|w| w / total).collect()
        } else {
            vec![1.0 / lights.len().max(1) as f32; lights.len()]
        };
        let mut acc = 0.0;
        let cdf: Vec<f32> = pmf
            .iter()
            .map(|p| {
                acc += p;
                acc
            })
            .collect();
        let cdf_below = std::iter::once(0.0).chain(cdf.iter().copied()).take(lights.len()).collect();
        let inv_pmf = pmf.iter().map(|p| if *p > 0.0 { 1.0 / p } else { 0.0 }).collect();
        Self {
            lights,
            pmf,
            cdf,
            cdf_below,
            inv_pmf,
            triangle_light,
            sphere_light,
            shape_light,
            instance_light,
        }
    }

    /// Whether there is no light.
    pub fn is_empty(&self) -> bool {
        self.lights.is_empty()
    }

    /// Chooses a light in proportion to its power: index and probability.
    #[inline]
    pub fn choose(&self, u: f32) -> Option<(usize, f32)> {
        if self.lights.is_empty() {
            return None;
        }
        let i = self.cdf.partition_point(|&c| c <= u).min(self.lights.len() - 1);
        Some((i, self.pmf[i]))
    }

    /// Chooses a light as [`Lights::choose`] does and returns `u` stretched back to [0, 1)
    /// within the chosen light's interval, so one stratified number picks the light and
    /// places the point on it (pbrt-v4 sec. 2.2.2's sample reuse): index, probability, `u`.
    #[inline]
    pub fn choose_reusing(&self, u: f32) -> Option<(usize, f32, f32)> {
        let (i, pmf) = self.choose(u)?;
        // A load, not a branch on `i == 0`: the choice is a coin toss per sample.
        let below = self.cdf_below[i];
        Some((i, pmf, ((u - below) * self.inv_pmf[i]).clamp(0.0, ONE_MINUS_EPSILON)))
    }

    /// Probability that [`Lights::choose`] picks light `i`.
    #[inline]
    pub fn pmf(&self, i: usize) -> f32 {
        self.pmf[i]
    }

    /// The light that mesh triangle `t` is, if any.
    #[inline]
    pub fn of_triangle(&self, t: u32) -> Option<usize> {
        self.triangle_light.get(t as usize).filter(|&&l| l != NOT_A_LIGHT).map(|&l| l as usize)
    }

    /// The light that sphere `s` is, if any.
    #[inline]
    pub fn of_sphere(&self, s: u32) -> Option<usize> {
        self.sphere_light.get(s as usize).filter(|&&l| l != NOT_A_LIGHT).map(|&l| l as usize)
    }

    /// The light that analytic shape `s` is, if any.
    #[inline]
    pub fn of_shape(&self, s: u32) -> Option<usize> {
        self.shape_light.get(s as usize).filter(|&&l| l != NOT_A_LIGHT).map(|&l| l as usize)
    }

    /// Whether some instanced triangle is a light.
    #[inline]
    pub fn has_instance_lights(&self) -> bool {
        !self.instance_light.is_empty()
    }

    /// The light that triangle `triangle` of instance `instance` (numbered as its set
    /// places it) is, if any.
    #[inline]
    pub fn of_instance_triangle(&self, instance: u32, triangle: u32) -> Option<usize> {
        let key = u64::from(instance) << 32 | u64::from(triangle);
        self.instance_light
            .binary_search_by_key(&key, |e| e.0)
            .ok()
            .map(|i| self.instance_light[i].1 as usize)
    }
}

/// Centre and radius of a sphere shape whose transform is a similarity (`M^T M = s^2 I` to
/// 1e-5), else `None`.
fn round_sphere(shape: &Shape) -> Option<(Vec3, f32)> {
    if shape.kind != crate::core::shapes::ShapeKind::Sphere {
        return None;
    }
    let m = glam::Mat3::from(shape.object_to_world.matrix3);
    let g = m.transpose() * m;
    let s2 = (g.x_axis.x + g.y_axis.y + g.z_axis.z) / 3.0;
    let off = (g - glam::Mat3::from_diagonal(Vec3::splat(s2)))
        .to_cols_array()
        .iter()
        .fold(0.0f32, |a, v| a.max(v.abs()));
    (s2 > 0.0 && off <= 1e-5 * s2).then(|| (Vec3::from(shape.object_to_world.translation), s2.sqrt()))
}

/// The light of an emissive triangle with corners `a, b, c` (normal by the right-hand rule),
/// `None` when it has no area.
fn triangle([a, b, c]: [Vec3; 3], le: Vec3) -> Option<Light> {
    let cross = (b - a).cross(c - a);
    let area = 0.5 * cross.length();
    (area > 0.0).then(|| Light::Triangle { p0: a, e1: b - a, e2: c - a, normal: cross.normalize(), area, le })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rng::{stream, uniform};

    /// Light sampling estimates the irradiance of a known configuration: a small triangle
    /// and a sphere seen from a point on their axis (E = Le * solid-angle-weighted cosine).
    #[test]
    fn sampled_irradiance_matches_closed_form() {
        // Sphere of radius r at distance d on the normal: E = pi Le (r/d)^2.
        let s = Light::Sphere { center: Vec3::new(0.0, 0.0, 2.0), radius: 0.5, le: Vec3::ONE };
        let mut rng = stream(1, 0, 0);
        let n = 100_000;
        let mut e = 0.0;
        for _ in 0..n {
            let ls = s.sample(Vec3::ZERO, Vec2::new(uniform(&mut rng), uniform(&mut rng))).unwrap();
            assert!((ls.point - Vec3::new(0.0, 0.0, 2.0)).length() - 0.5 < 1e-4);
            assert!((s.pdf(Vec3::ZERO, ls.wi, ls.point, Vec3::ZERO) - ls.pdf).abs() < 1e-3 * ls.pdf);
            e += ls.li.x * ls.wi.z / ls.pdf;
        }
        let expect = PI * 0.25 / 4.0;
        eprintln!("sphere light irradiance: {} against pi Le (r/d)^2 = {expect}", e / n as f32);
        assert!((e / n as f32 - expect).abs() < 0.01 * expect, "{} vs {expect}", e / n as f32);
        // Square light 2 x 2 at height 1 facing down, as two triangles: E = Le * 4 * F, with the
        // point-to-parallel-rectangle form factor, corner formula summed over four quadrants.
        let le = Vec3::ONE;
        let corners = [Vec3::new(-1.0, -1.0, 1.0), Vec3::new(1.0, -1.0, 1.0), Vec3::new(1.0, 1.0, 1.0)];
        let corners2 = [Vec3::new(-1.0, -1.0, 1.0), Vec3::new(1.0, 1.0, 1.0), Vec3::new(-1.0, 1.0, 1.0)];
        let mut mesh = TriangleMesh::default();
        let id = mesh.surface_id("light");
        // Wound so the normal points down (-z).
        mesh.push_triangle([corners[0], corners[2], corners[1]], id);
        mesh.push_triangle([corners2[0], corners2[2], corners2[1]], id);
        let lights = Lights::new(&[], &mesh, &[], &[le]);
        assert_eq!(lights.lights.len(), 2);
        let mut e = 0.0;
        for _ in 0..n {
            let (i, p) = lights.choose(uniform(&mut rng)).unwrap();
            if let Some(ls) =
                lights.lights[i].sample(Vec3::ZERO, Vec2::new(uniform(&mut rng), uniform(&mut rng)))
            {
                e += ls.li.x * ls.wi.z / (ls.pdf * p);
            }
        }
        // Corner form factor for a 1 x 1 rectangle at height 1 (pbrt / Howell catalogue C-11):
        // F = 1/(2 pi) [a/sqrt(1+a^2) atan(b/sqrt(1+a^2)) + b/sqrt(1+b^2) atan(a/sqrt(1+b^2))].
        let f = (1.0 / (2.0 * PI)) * 2.0 * (1.0 / 2f32.sqrt()) * (1.0 / 2f32.sqrt()).atan();
        let expect = PI * 4.0 * f;
        eprintln!("quad light irradiance: {} against the form factor's {expect}", e / n as f32);
        assert!((e / n as f32 - expect).abs() < 0.01 * expect, "{} vs {expect}", e / n as f32);
    }

    #[test]
    fn reused_choice_numbers_pick_by_power_and_stay_uniform() {
        // Three point lights of powers 1 : 2 : 5; 8,000 evenly spaced numbers choose among them.
        let points = [1.0f32, 2.0, 5.0].map(|w| (Vec3::ZERO, Vec3::splat(w)));
        let lights = Lights::new(&points, &TriangleMesh::default(), &[], &[]);
        let n = 8000;
        let (mut count, mut sum, mut sum2) = ([0u32; 3], [0.0f64; 3], [0.0f64; 3]);
        for k in 0..n {
            let u = (k as f32 + 0.5) / n as f32;
            let Some((i, pmf, v)) = lights.choose_reusing(u) else { panic!("three lights, none chosen") };
            assert_eq!(Some((i, pmf)), lights.choose(u));
            assert!((0.0..1.0).contains(&v), "{v}");
            count[i] += 1;
            sum[i] += f64::from(v);
            sum2[i] += f64::from(v) * f64::from(v);
        }
        for (i, share) in [1.0 / 8.0, 2.0 / 8.0, 5.0 / 8.0].into_iter().enumerate() {
            let c = f64::from(count[i]);
            assert!((c / f64::from(n) - share).abs() < 1e-3, "light {i}: {c}");
            // Evenly spread over [0, 1): mean 1/2, mean square 1/3.
            assert!((sum[i] / c - 0.5).abs() < 1e-3 && (sum2[i] / c - 1.0 / 3.0).abs() < 1e-3, "light {i}");
        }
    }
}
