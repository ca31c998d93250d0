//! Line segments (edges) that a ray passes near: an obvhs tree over the segments' boxes, each
//! grown by its own reach, so that a flight meets only the few segments within reach instead
//! of all of them. The acoustic simulator asks it where rays pass free edges (its stochastic
//! diffraction); the core knows only segments and distances.

use std::time::Duration;

use glam::{Vec3, Vec3A};
use obvhs::aabb::Aabb;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::{Boundable, BvhBuildParams};

use super::ray::Ray;

/// A straight segment from `start` along the unit `dir` for `length_m`, passed by rays
/// within `reach_m` of it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Segment {
    /// One end.
    pub start: Vec3,
    /// Unit direction towards the other end.
    pub dir: Vec3,
    /// Length, metres.
    pub length_m: f32,
    /// Rays passing farther than this from the segment do not pass it, metres.
    pub reach_m: f32,
}

/// Where a ray passes closest to a segment's line.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pass {
    /// The segment's index.
    pub segment: usize,
    /// Distance along the ray, metres.
    pub at_m: f32,
    /// Distance from the segment there, metres.
    pub distance_m: f32,
    /// Sine of the angle between the ray and the segment.
    pub sin_beta: f32,
}

/// A segment's box grown by its reach (the obvhs builder's input).
struct Grown(Aabb);

impl Boundable for Grown {
    fn aabb(&self) -> Aabb {
        self.0
    }
}

/// Segments and a tree over their boxes grown by their reaches.
pub struct NearSegments {
    segments: Vec<Segment>,
    tree: Option<CwBvh>,
}

impl NearSegments {
    /// A tree over `segments` for passes within each one's reach.
    pub fn new(segments: Vec<Segment>) -> Self {
        let grown: Vec<Grown> = segments
            .iter()
            .map(|s| {
                let end = s.start + s.length_m * s.dir;
                let pad = Vec3::splat(
                    s.reach_m * 1.001 + 1e-6 * (1.0 + s.start.abs().max(end.abs()).max_element()),
                );
                Grown(Aabb::new(Vec3A::from(s.start.min(end) - pad), Vec3A::from(s.start.max(end) + pad)))
            })
            .collect();
        let tree = (!grown.is_empty())
            .then(|| build_cwbvh(&grown, BvhBuildParams::medium_build(), &mut Duration::default()));
        Self { segments, tree }
    }

    /// The segments.
    pub fn segments(&self) -> &[Segment] {
        &self.segments
    }

    /// Of the segments that `ray` over `(0, length_m]` passes within their reach (the closest
    /// point inside both the flight and the segment), the one closest in the measure
    /// `distance * sin(beta)` (the distance seen across the segment). Rays within 0.6
    /// degrees of a segment's direction pass none of it.
    pub fn closest_pass(&self, ray: &Ray, length_m: f32) -> Option<Pass> {
        let tree = self.tree.as_ref()?;
        let query = obvhs::ray::Ray::new(Vec3A::from(ray.origin), Vec3A::from(ray.dir), 0.0, length_m);
        let mut best: Option<Pass> = None;
        tree.ray_traverse_anyhit(query, |_, id| {
            let i = tree.primitive_indices[id] as usize;
            if let Some(p) = pass(&self.segments[i], i, ray, length_m)
                && p.distance_m < self.segments[i].reach_m
                && best.is_none_or(|b| p.distance_m * p.sin_beta < b.distance_m * b.sin_beta)
            {
                best = Some(p);
            }
        });
        best
    }
}

/// Where `ray` over `(0, length_m]` comes closest to the line of `s` (segment index `i`),
/// if that point lies on both.
#[inline]
fn pass(s: &Segment, i: usize, ray: &Ray, length_m: f32) -> Option<Pass> {
    let w0 = ray.origin - s.start;
    let b = ray.dir.dot(s.dir);
    let sin2 = 1.0 - b * b;
    if sin2 < 1e-4 {
        return None;
    }
    let (dw, ew) = (ray.dir.dot(w0), s.dir.dot(w0));
    let t = (b * ew - dw) / sin2;
    let along = (ew - b * dw) / sin2;
    if !(t > 1e-4 && t < length_m - 1e-4 && (0.0..=s.length_m).contains(&along)) {
        return None;
    }
    let distance_m = (w0 + t * ray.dir - along * s.dir).length();
    Some(Pass { segment: i, at_m: t, distance_m, sin_beta: sin2.sqrt() })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rng::{stream, uniform};

    #[test]
    fn the_tree_finds_the_same_pass_as_a_scan_of_every_segment() {
        let mut rng = stream(9, 0, 0);
        let mut u = || uniform(&mut rng);
        let segments: Vec<Segment> = (0..300)
            .map(|_| Segment {
                start: Vec3::new(u(), u(), u()) * 10.0,
                dir: crate::core::sampling::uniform_sphere(glam::Vec2::new(u(), u())),
                length_m: 3.0 * u(),
                reach_m: 0.2 + 0.4 * u(),
            })
            .collect();
        let near = NearSegments::new(segments.clone());
        let mut found = 0;
        for _ in 0..2000 {
            let ray = Ray::new(
                Vec3::new(u(), u(), u()) * 10.0,
                crate::core::sampling::uniform_sphere(glam::Vec2::new(u(), u())),
            );
            let scan = segments
                .iter()
                .enumerate()
                .filter_map(|(i, s)| pass(s, i, &ray, 5.0))
                .filter(|p| p.distance_m < segments[p.segment].reach_m)
                .min_by(|a, b| (a.distance_m * a.sin_beta).total_cmp(&(b.distance_m * b.sin_beta)));
            let tree = near.closest_pass(&ray, 5.0);
            assert_eq!(scan.map(|p| p.segment), tree.map(|p| p.segment));
            found += usize::from(tree.is_some());
        }
        assert!(found > 200, "{found} passes");
    }

    #[test]
    fn a_pass_is_where_the_ray_comes_closest() {
        let s = Segment { start: Vec3::new(0.0, 0.0, -10.0), dir: Vec3::Z, length_m: 20.0, reach_m: 1.0 };
        let near = NearSegments::new(vec![s]);
        let ray = Ray::new(Vec3::new(-5.0, 0.3, 2.0), Vec3::X);
        let p = near.closest_pass(&ray, 10.0).unwrap();
        assert!((p.at_m - 5.0).abs() < 1e-5 && (p.distance_m - 0.3).abs() < 1e-5);
        assert!((p.sin_beta - 1.0).abs() < 1e-6);
        // Not before the ray reaches it, nor past the segment's ends, nor out of reach.
        assert!(near.closest_pass(&ray, 4.0).is_none());
        assert!(near.closest_pass(&Ray::new(Vec3::new(-5.0, 0.3, 12.0), Vec3::X), 10.0).is_none());
        assert!(near.closest_pass(&Ray::new(Vec3::new(-5.0, 1.3, 2.0), Vec3::X), 10.0).is_none());
    }
}
