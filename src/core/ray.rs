//! Rays and the offset rule that keeps secondary rays off their own surface.

use glam::Vec3;

/// A ray `origin + t * dir` valid for `t` in `[t_min, t_max]`; `dir` need not be unit length,
/// but every simulator in propsim uses unit directions so that `t` is a distance in metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin.
    pub origin: Vec3,
    /// Direction.
    pub dir: Vec3,
    /// Start of the valid interval of `t`.
    pub t_min: f32,
    /// End of the valid interval of `t`.
    pub t_max: f32,
}

/// Relative size of the origin offset used by [`Ray::spawn`]; a few ulps of the largest
/// coordinate, after pbrt-v4's `OffsetRayOrigin` (Pharr, Jakob, Humphreys, sec. 6.8.6).
const OFFSET_RELATIVE: f32 = 4.0e-6;
/// Floor of the offset near the origin of the coordinate system, metres.
const OFFSET_ABSOLUTE_M: f32 = 1.0e-6;

impl Ray {
    /// A ray from `origin` along `dir` with an unbounded range.
    pub fn new(origin: Vec3, dir: Vec3) -> Self {
        Self { origin, dir, t_min: 0.0, t_max: f32::INFINITY }
    }

    /// A ray from `origin` along `dir` limited to `[0, t_max]`.
    pub fn segment(origin: Vec3, dir: Vec3, t_max: f32) -> Self {
        Self { origin, dir, t_min: 0.0, t_max }
    }

    /// The point at parameter `t`.
    #[inline]
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + t * self.dir
    }

    /// A secondary ray leaving a surface point: the origin is pushed off the surface along the
    /// geometric normal, to the side `dir` points to, by an amount that scales with the
    /// coordinates' magnitude, so the new ray cannot re-hit the surface it starts on.
    #[inline]
    pub fn spawn(point: Vec3, geometric_normal: Vec3, dir: Vec3) -> Self {
        Self::new(offset_origin(point, geometric_normal, dir), dir)
    }

    /// The visibility segment between two surface points, `x` (geometric normal `n`) and `y`
    /// (geometric normal `m`): both ends pushed off their surfaces towards each other and the
    /// direction taken between the pushed ends (pbrt-v4's `SpawnRayTo` between two
    /// interactions, [pbrt-v4] sec. 6.8.6), so that neither surface is hit. [`Self::spawn_to`]
    /// keeps the unpushed target, so at grazing angles near an edge two surfaces share, its
    /// segment can end inside the target's surface: the corner test below measured 3.3e-4 of
    /// the transport blocked that way.
    pub fn between(x: Vec3, n: Vec3, y: Vec3, m: Vec3) -> Self {
        // The sides by the unit direction, as the eight-lane path tracer computes it.
        let to = y - x;
        Self::between_along(x, n, y, m, to / to.length())
    }

    /// [`Self::between`] for a caller that has already computed the unit direction
    /// `w = (y - x) / |y - x|` (the same arithmetic gives the same segment, bit for bit).
    #[inline]
    pub fn between_along(x: Vec3, n: Vec3, y: Vec3, m: Vec3, w: Vec3) -> Self {
        let from = offset_origin(x, n, w);
        let to = offset_origin(y, m, -w);
        let d = to - from;
        let len = d.length();
        if !(len > 0.0 && len.is_finite()) {
            return Self::segment(from, n, 0.0);
        }
        Self::segment(from, d / len, len * (1.0 - 1.0e-5))
    }

    /// A shadow/visibility segment from a surface point towards `target`, stopping just short
    /// of it; `t` is in units of the (unit) direction, i.e. metres.
    pub fn spawn_to(point: Vec3, geometric_normal: Vec3, target: Vec3) -> Self {
        let to = target - point;
        let distance = to.length();
        let dir = if distance > 0.0 { to / distance } else { geometric_normal };
        let origin = offset_origin(point, geometric_normal, dir);
        let remaining = (target - origin).length();
        Self { origin, dir, t_min: 0.0, t_max: remaining * (1.0 - 1.0e-5) }
    }
}

/// The offset origin used by [`Ray::spawn`].
#[inline]
pub fn offset_origin(point: Vec3, geometric_normal: Vec3, dir: Vec3) -> Vec3 {
    let scale = OFFSET_ABSOLUTE_M + OFFSET_RELATIVE * point.abs().max_element();
    let side = if geometric_normal.dot(dir) >= 0.0 { 1.0 } else { -1.0 };
    point + geometric_normal * (scale * side)
}

/// [`offset_origin`] of `N` points at once, lane by lane: the same arithmetic, written so
/// that it vectorises (for renderers that shade eight paths together).
#[inline(always)]
pub fn offset_origins<const N: usize>(
    point: &[[f32; N]; 3],
    normal: &[[f32; N]; 3],
    dir: &[[f32; N]; 3],
) -> [[f32; N]; 3] {
    // glam's `max_element` and `dot`, in their order of operations.
    let larger = |a: f32, b: f32| if a > b { a } else { b };
    let mut out = [[0.0; N]; 3];
    let mut side_scale = [0.0; N];
    for i in 0..N {
        let largest = larger(point[0][i].abs(), larger(point[1][i].abs(), point[2][i].abs()));
        let scale = OFFSET_ABSOLUTE_M + OFFSET_RELATIVE * largest;
        let cos = normal[0][i] * dir[0][i] + normal[1][i] * dir[1][i] + normal[2][i] * dir[2][i];
        side_scale[i] = scale * if cos >= 0.0 { 1.0 } else { -1.0 };
    }
    for k in 0..3 {
        for i in 0..N {
            out[k][i] = point[k][i] + normal[k][i] * side_scale[i];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eight_offsets_at_once_match_one_at_a_time_bit_for_bit() {
        let mut rng = crate::core::rng::stream(5, 6, 7);
        let mut u = || crate::core::rng::uniform(&mut rng) * 2.0 - 1.0;
        for scale in [1.0e-3f32, 1.0, 1.0e4] {
            let rays: Vec<[Vec3; 3]> = (0..8)
                .map(|i| {
                    let p = Vec3::new(u(), u(), u()) * scale;
                    let n = Vec3::new(u(), u(), u()).normalize();
                    // Lane 7 grazes the surface exactly.
                    let d = if i == 7 {
                        n.any_orthonormal_vector()
                    } else {
                        Vec3::new(u(), u(), u()).normalize()
                    };
                    [p, n, d]
                })
                .collect();
            let one: Vec<Vec3> = rays.iter().map(|&[p, n, d]| offset_origin(p, n, d)).collect();
            let lanes: [[[f32; 8]; 3]; 3] =
                std::array::from_fn(|v| std::array::from_fn(|c| std::array::from_fn(|i| rays[i][v][c])));
            let eight = offset_origins(&lanes[0], &lanes[1], &lanes[2]);
            for (i, o) in one.iter().enumerate() {
                assert_eq!(o.to_array().map(f32::to_bits), [0, 1, 2].map(|c| eight[c][i].to_bits()));
            }
        }
    }

    #[test]
    fn at_moves_along_direction() {
        let r = Ray::new(Vec3::new(1.0, 2.0, 3.0), Vec3::X);
        assert_eq!(r.at(2.5), Vec3::new(3.5, 2.0, 3.0));
    }

    #[test]
    fn spawn_offsets_to_the_side_of_the_direction() {
        let n = Vec3::Z;
        let up = Ray::spawn(Vec3::new(100.0, 0.0, 0.0), n, Vec3::new(0.0, 0.6, 0.8));
        assert!(up.origin.z > 0.0);
        let down = Ray::spawn(Vec3::new(100.0, 0.0, 0.0), n, Vec3::new(0.0, 0.6, -0.8));
        assert!(down.origin.z < 0.0);
        // The offset is tiny compared with scene scale.
        assert!(up.origin.z < 1e-2);
    }

    #[test]
    fn shadow_rays_between_two_walls_of_a_corner_are_never_blocked() {
        // A floor (z = 0) and a wall (x = 0) meeting at a right angle, at coordinates up to
        // 10 m from the origin: every point of the floor sees every point of the wall, so no
        // shadow segment from one to the other may be blocked, even at the grazing angles near
        // the common edge. Counted over 20,000 pairs weighted by the light transport's
        // geometric term cos cos / r^2, the blocked share must be nil (below 1e-5) with
        // `Ray::between`; `Ray::spawn_to`, which does not push the target off its surface,
        // loses 3.3e-4 (the test can fail).
        use crate::core::accel::{Accel, BuildQuality};
        use crate::core::mesh::TriangleMesh;
        use crate::core::rng::{Rng64, uniform};
        let mut m = TriangleMesh::default();
        let s = m.surface_id("s");
        let base = Vec3::new(0.0, 7.0, 0.0);
        m.push_quad(
            base,
            base + Vec3::new(3.0, 0.0, 0.0),
            base + Vec3::new(3.0, 3.0, 0.0),
            base + Vec3::new(0.0, 3.0, 0.0),
            s,
        );
        m.push_quad(
            base,
            base + Vec3::new(0.0, 3.0, 0.0),
            base + Vec3::new(0.0, 3.0, 3.0),
            base + Vec3::new(0.0, 0.0, 3.0),
            s,
        );
        let accel = Accel::build(&m, Vec::new(), BuildQuality::High);
        let mut rng = crate::core::rng::stream(7, 0, 0);
        let (mut blocked, mut blocked_one_end, mut total) = (0.0f64, 0.0f64, 0.0f64);
        for _ in 0..20_000 {
            // Points bunched towards the common edge (u^4), where the angles graze.
            let f = |rng: &mut Rng64| 3.0 * uniform(rng).powi(4);
            let x = base + Vec3::new(f(&mut rng), 3.0 * uniform(&mut rng), 0.0);
            let y = base + Vec3::new(0.0, 3.0 * uniform(&mut rng), f(&mut rng));
            let d = y - x;
            let g = f64::from(d.z.max(0.0) * (-d.x).max(0.0) / d.length_squared().powi(2));
            total += g;
            if accel.occluded(&Ray::between(x, Vec3::Z, y, Vec3::X)) {
                blocked += g;
            }
            if accel.occluded(&Ray::spawn_to(x, Vec3::Z, y)) {
                blocked_one_end += g;
            }
        }
        eprintln!("blocked share {:.3e}, one end pushed {:.3e}", blocked / total, blocked_one_end / total);
        assert!(blocked / total < 1e-5, "blocked share {:.3e}", blocked / total);
        assert!(blocked_one_end / total > 1e-5, "spawn_to lost {:.3e}", blocked_one_end / total);
    }

    #[test]
    fn spawn_to_stops_short_of_the_target() {
        let r = Ray::spawn_to(Vec3::ZERO, Vec3::Z, Vec3::new(0.0, 0.0, 2.0));
        assert!(r.t_max < 2.0 && r.t_max > 1.999);
        assert!((r.dir - Vec3::Z).length() < 1e-6);
    }
}
