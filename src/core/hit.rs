//! The record of a ray-surface intersection.

use glam::{Vec2, Vec3};

/// Index of a named surface (an OBJ `usemtl` group, or an analytic sphere's material).
pub type SurfaceId = u32;

/// What kind of primitive a [`Hit`] found.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PrimitiveKind {
    /// A mesh triangle.
    Triangle,
    /// An analytic sphere.
    Sphere,
    /// A transformed analytic shape (`Hit::primitive` indexes the scene's shapes).
    Shape,
    /// A signed distance field (`Hit::primitive` indexes the scene's fields).
    Sdf,
    /// A triangle of an instance's mesh (`Hit::primitive` indexes that mesh's triangles;
    /// `InstanceSet::closest_hit_placed` also gives the instance). The variant carries no
    /// index so that a `Hit` stays 48 bytes: the launcher keeps one per ray in flight.
    Instance,
}

/// A ray-surface intersection.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter of the hit (metres for a unit-direction ray).
    pub t: f32,
    /// World-space hit point.
    pub point: Vec3,
    /// Unit geometric normal as wound in the mesh (right-hand rule), not flipped towards the ray.
    pub normal: Vec3,
    /// Barycentric coordinates (u, v) of the hit: `p = (1-u-v) v0 + u v1 + v v2`.
    /// For spheres: (azimuth/2pi, polar/pi) of the hit direction from the centre.
    pub barycentric: Vec2,
    /// Index of the primitive in its list (the mesh's triangles, the spheres, or an
    /// instance's mesh's triangles).
    pub primitive: u32,
    /// Triangle or sphere.
    pub kind: PrimitiveKind,
    /// The surface (material slot) hit.
    pub surface: SurfaceId,
    /// True when the ray arrives on the side the normal points to (`dot(dir, normal) < 0`).
    pub front_face: bool,
}

impl Hit {
    /// The normal flipped to face the incoming ray.
    #[inline]
    pub fn facing_normal(&self) -> Vec3 {
        if self.front_face { self.normal } else { -self.normal }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn a_hit_stays_48_bytes() {
        // The launcher keeps one `Option<Hit>` per ray in flight; instancing must not grow it.
        assert_eq!(std::mem::size_of::<Option<super::Hit>>(), 48);
    }
}
