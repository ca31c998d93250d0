//! Instancing: one bottom-level BVH ([`MeshBvh`]) per distinct mesh, and a top-level CWBVH
//! over the placed copies, whose leaves carry the ray into the copy's own frame (the
//! two-level scheme of pbrt-v4's `TransformedPrimitive` over a shared `BVHAggregate`, and of
//! Embree's instances; Pharr, Jakob, Humphreys, Physically Based Rendering, 4th ed., sec.
//! 7.1.4).
//!
//! A ray `o + t d` becomes `M^-1 o + t M^-1 d` in the mesh's frame: the direction is not
//! renormalised, so `t` is the same in both frames and the bottom level's watertight
//! triangle test ([`super::leaf`]) runs unchanged. Normals go back by the inverse transpose
//! of the linear part, `n_world ~ M^-T n_object`, which keeps the side a normal points to (a
//! closed mesh's outward normals stay outward, mirrored copies included). Hit points are
//! taken on the world ray (`o + t d`), so secondary rays leave them with the world-space
//! offset of [`crate::core::ray::offset_origin`].

use std::time::Duration;

use glam::{Affine3A, Mat3A, Vec3};
use obvhs::BvhBuildParams;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::builder::build_cwbvh;

use super::{Bounds, BuildQuality, ClosestLane, MeshBvh, node_ray, padded_bounds, split_coherent};
use crate::core::hit::{Hit, PrimitiveKind, SurfaceId};
use crate::core::mesh::TriangleMesh;
use crate::core::ray::Ray;
use crate::core::traverse::GROUP_WIDTH;
use crate::core::traverse::{AnyLeaves, ClosestLeaves, Traverser};

/// One placed copy of a mesh.
#[derive(Clone, Debug, PartialEq)]
pub struct Instance {
    /// Index of the placed mesh in the set's mesh list.
    pub mesh: u32,
    /// Object-to-world transform; its linear part must be invertible.
    pub object_to_world: Affine3A,
    /// Scene surface id of each of the mesh's surfaces (indexed by the mesh's own
    /// `SurfaceId`): the instance's materials, overrides applied.
    pub surfaces: Vec<SurfaceId>,
}

impl Instance {
    /// Whether the transform is finite and invertible: its linear part's determinant is a
    /// finite number whose size is not negligible next to its entries' (a copy squashed flat
    /// would have no inside, and rays could not be carried into its frame).
    pub fn transform_is_valid(m: &Affine3A) -> bool {
        let det = m.matrix3.determinant();
        let size = m.matrix3.to_cols_array().iter().fold(0.0f32, |a, v| a.max(v.abs()));
        m.is_finite() && det.is_finite() && det.abs() > 1.0e-12 * size.powi(3) && size > 0.0
    }
}

/// A placed instance, ready for queries.
struct Placed {
    world_to_object: Affine3A,
    /// Inverse transpose of the linear part: object normals to world normals.
    normal_to_world: Mat3A,
    mesh: u32,
    surfaces: Box<[SurfaceId]>,
}

impl Placed {
    /// `ray` in the instance's frame, with the same parameter range.
    #[inline(always)]
    fn to_object(&self, ray: &Ray, t_max: f32) -> Ray {
        Ray {
            origin: self.world_to_object.transform_point3(ray.origin),
            dir: self.world_to_object.transform_vector3(ray.dir),
            t_min: ray.t_min,
            t_max,
        }
    }
}

/// Placed copies of shared meshes: the top level over the instances and one bottom-level
/// BVH per mesh.
#[derive(Default)]
pub struct InstanceSet {
    meshes: Vec<MeshBvh>,
    /// Triangle count of each mesh.
    mesh_triangles: Vec<usize>,
    placed: Vec<Placed>,
    /// The top level over the instances' world bounds.
    top: Option<(CwBvh, Traverser)>,
    /// Corners of a box holding every instance (lower above upper when empty).
    bounds: (Vec3, Vec3),
    /// Whether some mesh has a tree large enough for group walks ([`InstanceSet::groups`]).
    groups: bool,
}

impl InstanceSet {
    /// Builds the bottom level of every mesh at `quality` and the top level over
    /// `instances`. Instances naming a mesh out of range or with an invalid transform
    /// ([`Instance::transform_is_valid`]) are the caller's to reject first; they are skipped.
    pub fn build(meshes: &[TriangleMesh], instances: &[Instance], quality: BuildQuality) -> Self {
        let bvhs: Vec<MeshBvh> = meshes.iter().map(|m| MeshBvh::build(m, quality)).collect();
        let mesh_bounds: Vec<Option<(Vec3, Vec3)>> = meshes.iter().map(TriangleMesh::bounds).collect();
        let mut placed = Vec::with_capacity(instances.len());
        let mut boxes = Vec::with_capacity(instances.len());
        let mut bounds = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        for inst in instances {
            let Some(Some((lo, hi))) = mesh_bounds.get(inst.mesh as usize) else { continue };
            if !Instance::transform_is_valid(&inst.object_to_world) {
                continue;
            }
            let (wlo, whi) = transformed_box(&inst.object_to_world, *lo, *hi);
            bounds = (bounds.0.min(wlo), bounds.1.max(whi));
            boxes.push(padded_bounds(wlo, whi));
            let linear = inst.object_to_world.matrix3;
            placed.push(Placed {
                world_to_object: inst.object_to_world.inverse(),
                normal_to_world: linear.inverse().transpose(),
                mesh: inst.mesh,
                surfaces: inst.surfaces.clone().into_boxed_slice(),
            });
        }
        let groups = bvhs.iter().any(|b| b.flat.is_none() && b.traverser.streams());
        let top = (!boxes.is_empty()).then(|| {
            let bvh = build_cwbvh::<Bounds>(&boxes, BvhBuildParams::medium_build(), &mut Duration::default());
            let traverser = Traverser::new(&bvh.nodes);
            (bvh, traverser)
        });
        Self {
            meshes: bvhs,
            mesh_triangles: meshes.iter().map(TriangleMesh::triangle_count).collect(),
            placed,
            top,
            bounds,
            groups,
        }
    }

    /// Whether batches should take [`InstanceSet::closest_hits_into`]: some mesh's tree is
    /// large enough for its coherent rays to walk it in groups.
    pub fn groups(&self) -> bool {
        self.groups && self.top.is_some()
    }

    /// Whether there is no instance.
    #[inline(always)]
    pub fn is_empty(&self) -> bool {
        self.placed.is_empty()
    }

    /// Number of instances.
    pub fn len(&self) -> usize {
        self.placed.len()
    }

    /// Number of distinct meshes.
    pub fn mesh_count(&self) -> usize {
        self.meshes.len()
    }

    /// Triangles stored once per mesh (the unique triangles).
    pub fn unique_triangles(&self) -> u64 {
        self.mesh_triangles.iter().map(|&n| n as u64).sum()
    }

    /// Triangles of every copy together (what a flattened scene would store).
    pub fn instanced_triangles(&self) -> u64 {
        self.placed.iter().map(|p| self.mesh_triangles[p.mesh as usize] as u64).sum()
    }

    /// Corners of a box holding every instance (lower above upper when there is none).
    pub fn bounds(&self) -> (Vec3, Vec3) {
        self.bounds
    }

    /// Bytes held: the bottom levels, the top level and the instance records.
    pub fn memory_bytes(&self) -> usize {
        self.meshes.iter().map(MeshBvh::memory_bytes).sum::<usize>()
            + self.top.as_ref().map_or(0, |(b, _)| {
                b.nodes.len() * std::mem::size_of::<obvhs::cwbvh::node::CwBvhNode>()
                    + b.primitive_indices.len() * 4
            })
            + self.placed.iter().map(|p| std::mem::size_of::<Placed>() + p.surfaces.len() * 4).sum::<usize>()
    }

    /// The world-space hit on instance `index` from its bottom level's closest lane `c`.
    #[inline(always)]
    fn world_hit(&self, index: u32, c: &ClosestLane, ray: &Ray) -> Hit {
        let p = &self.placed[index as usize];
        let local = p.to_object(ray, ray.t_max);
        let h = self.meshes[p.mesh as usize].make_hit((c.first, c.count, c.lane), c.t, c.uv, &local);
        self.to_world(index, h, ray)
    }

    /// `h`, a hit in instance `index`'s frame of the world ray `ray`, in world terms.
    #[inline(always)]
    fn to_world(&self, index: u32, h: Hit, ray: &Ray) -> Hit {
        let p = &self.placed[index as usize];
        let normal = Vec3::from(p.normal_to_world * glam::Vec3A::from(h.normal)).normalize_or_zero();
        Hit {
            t: h.t,
            point: ray.at(h.t),
            normal,
            barycentric: h.barycentric,
            primitive: h.primitive,
            kind: PrimitiveKind::Instance,
            surface: p.surfaces.get(h.surface as usize).copied().unwrap_or(h.surface),
            front_face: normal.dot(ray.dir) < 0.0,
        }
    }

    /// The closest hit on any instance in `(t_min, t_max]`.
    pub fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        self.closest_hit_placed(ray).map(|(_, h)| h)
    }

    /// [`InstanceSet::closest_hit`] with the index of the instance hit (Embree's `instID`).
    pub fn closest_hit_placed(&self, ray: &Ray) -> Option<(u32, Hit)> {
        let (bvh, traverser) = self.top.as_ref()?;
        let mut visitor = ClosestInstance { set: self, order: &bvh.primitive_indices, ray, best: None };
        traverser.closest(&bvh.nodes, &node_ray(ray), ray.t_max, &mut visitor);
        visitor.best.map(|(i, c)| (i, self.world_hit(i, &c, ray)))
    }

    /// [`InstanceSet::closest_hit`] of every ray beyond its hit so far in `out` (an instance
    /// hit replaces it as in [`super::Accel::closest_hit`]): the launcher's batch query.
    /// Runs of [`GROUP_WIDTH`] coherent rays ([`split_coherent`]) walk the top level as a
    /// group, nearest boxes first, each ray culled by its closest hit so far; at each
    /// instance the run's rays that reach it go into its frame together and walk its tree as
    /// a group ([`MeshBvh::closest_lanes_grouped`]), as the rays of a flattened scene walk
    /// its one tree. The other rays go one by one. Each instance is tested with the same
    /// ray and distance limit as by the one-by-one query, so the distances are the same bit
    /// for bit; only on an exact tie may the triangle be another one.
    pub fn closest_hits_into(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        let Some((bvh, traverser)) = &self.top else { return };
        let limit = |ray: &Ray, hit: &Option<Hit>| Ray { t_max: hit.map_or(ray.t_max, |h| h.t), ..*ray };
        let size_m = (self.bounds.1 - self.bounds.0).max_element();
        let (grouped, alone) = split_coherent(rays, size_m);
        for &i in &alone {
            let i = i as usize;
            if let Some(h) = self.closest_hit(&limit(&rays[i], &out[i])) {
                out[i] = Some(h);
            }
        }
        let (mut top_stack, mut stack) = (Vec::new(), Vec::new());
        let (mut world, mut node_rays, mut t_max) = (Vec::new(), Vec::new(), Vec::new());
        let (mut local, mut ids) = (Vec::new(), Vec::new());
        let mut best: Vec<Option<(u32, ClosestLane)>> = Vec::new();
        for run in grouped.chunks(GROUP_WIDTH) {
            world.clear();
            world.extend(run.iter().map(|&i| limit(&rays[i as usize], &out[i as usize])));
            node_rays.clear();
            node_rays.extend(world.iter().map(node_ray));
            t_max.clear();
            t_max.extend(world.iter().map(|r| r.t_max));
            best.clear();
            best.resize(run.len(), None);
            let order = &bvh.primitive_indices;
            traverser.closest_one_group(
                &bvh.nodes,
                &node_rays,
                &mut t_max,
                &mut top_stack,
                |first, count, mask, t| {
                    for &inst in &order[first as usize..(first + count) as usize] {
                        let p = &self.placed[inst as usize];
                        local.clear();
                        ids.clear();
                        let mut m = mask;
                        while m != 0 {
                            let r = m.trailing_zeros() as usize;
                            m &= m - 1;
                            local.push(p.to_object(&world[r], t[r]));
                            ids.push(r);
                        }
                        self.meshes[p.mesh as usize].closest_lanes_grouped(&local, &mut stack, |k, lane| {
                            let r = ids[k];
                            // As in the single-ray query: only a strictly closer hit replaces one.
                            if let Some(c) = lane
                                && (best[r].is_none() || c.t < t[r])
                            {
                                t[r] = c.t;
                                best[r] = Some((inst, c));
                            }
                        });
                    }
                },
            );
            for (r, &i) in run.iter().enumerate() {
                if let Some((inst, c)) = &best[r] {
                    out[i as usize] = Some(self.world_hit(*inst, c, &rays[i as usize]));
                }
            }
        }
    }

    /// The mesh (index into the build's mesh list) that instance `index` places.
    pub fn mesh_of(&self, index: u32) -> u32 {
        self.placed[index as usize].mesh
    }

    /// Whether any instance blocks the segment `(t_min, t_max]`.
    pub fn occluded(&self, ray: &Ray) -> bool {
        let Some((bvh, traverser)) = &self.top else { return false };
        let mut visitor = AnyInstance { set: self, order: &bvh.primitive_indices, ray };
        traverser.any(&bvh.nodes, &node_ray(ray), ray.t_max, &mut visitor)
    }

    /// Calls `f(instance, hit)` for every instance triangle hit on the ray, in no particular
    /// order.
    pub fn for_each_hit(&self, ray: &Ray, f: impl FnMut(u32, Hit)) {
        let Some((bvh, traverser)) = &self.top else { return };
        let mut visitor = AllInstanceHits { set: self, order: &bvh.primitive_indices, ray, f };
        traverser.any(&bvh.nodes, &node_ray(ray), ray.t_max, &mut visitor);
    }
}

/// The world box of the object box `lo..hi` under `m`: the bounds of its eight corners.
pub fn transformed_box(m: &Affine3A, lo: Vec3, hi: Vec3) -> (Vec3, Vec3) {
    let mut out = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    for k in 0..8 {
        let c = Vec3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        let w = m.transform_point3(c);
        out = (out.0.min(w), out.1.max(w));
    }
    out
}

/// The top level's leaf test of a closest-hit query: each instance's bottom level, up to the
/// closest hit so far.
struct ClosestInstance<'a> {
    set: &'a InstanceSet,
    order: &'a [u32],
    ray: &'a Ray,
    best: Option<(u32, ClosestLane)>,
}

impl ClosestLeaves for ClosestInstance<'_> {
    #[inline(always)]
    fn test(&mut self, first: u32, count: u32, t_max: &mut f32) {
        for &i in &self.order[first as usize..(first + count) as usize] {
            let p = &self.set.placed[i as usize];
            let local = p.to_object(self.ray, *t_max);
            if let Some(c) = self.set.meshes[p.mesh as usize].closest_lane(&local) {
                // Only a strictly closer hit replaces the best one (the first may equal t_max).
                if self.best.is_none() || c.t < *t_max {
                    *t_max = c.t;
                    self.best = Some((i, c));
                }
            }
        }
    }
}

/// The top level's leaf test of an occlusion query.
struct AnyInstance<'a> {
    set: &'a InstanceSet,
    order: &'a [u32],
    ray: &'a Ray,
}

impl AnyLeaves for AnyInstance<'_> {
    #[inline(always)]
    fn test(&mut self, first: u32, count: u32) -> bool {
        self.order[first as usize..(first + count) as usize].iter().any(|&i| {
            let p = &self.set.placed[i as usize];
            self.set.meshes[p.mesh as usize].occluded(&p.to_object(self.ray, self.ray.t_max))
        })
    }
}

/// The top level's leaf test of an all-hits query.
struct AllInstanceHits<'a, F> {
    set: &'a InstanceSet,
    order: &'a [u32],
    ray: &'a Ray,
    f: F,
}

impl<F: FnMut(u32, Hit)> AnyLeaves for AllInstanceHits<'_, F> {
    fn test(&mut self, first: u32, count: u32) -> bool {
        for &i in &self.order[first as usize..(first + count) as usize] {
            let p = &self.set.placed[i as usize];
            let local = p.to_object(self.ray, self.ray.t_max);
            let (set, ray, f) = (self.set, self.ray, &mut self.f);
            set.meshes[p.mesh as usize].for_each_hit(&local, |h| f(i, set.to_world(i, h, ray)));
        }
        false
    }
}

/// Every instance's triangles in world space in one mesh (mirrored copies rewound so that
/// each triangle's right-hand normal is the instance's transformed normal), with the
/// instances' scene surface ids; `surface_names` are the caller's. For tests and for the
/// flattened figure of `propsim bench trace`.
pub fn flatten(meshes: &[TriangleMesh], instances: &[Instance]) -> TriangleMesh {
    let mut out = TriangleMesh::default();
    for inst in instances {
        let m = &meshes[inst.mesh as usize];
        let mirrored = inst.object_to_world.matrix3.determinant() < 0.0;
        let base = out.positions.len() as u32;
        out.positions.extend(m.positions.iter().map(|&p| inst.object_to_world.transform_point3(p)));
        for (t, s) in m.triangles.iter().zip(&m.surface_of_triangle) {
            let [a, b, c] = t.map(|i| base + i);
            out.triangles.push(if mirrored { [a, c, b] } else { [a, b, c] });
            out.surface_of_triangle.push(inst.surfaces.get(*s as usize).copied().unwrap_or(*s));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use glam::{Quat, Vec2};

    use super::*;
    use crate::core::accel::Accel;
    use crate::core::rng::{stream, uniform};
    use crate::core::sampling::uniform_sphere;

    /// A tree-sized mesh (random triangles in a 2 m cube) and a 12-triangle box: one with a
    /// BVH, one flat.
    fn meshes() -> Vec<TriangleMesh> {
        let mut a = TriangleMesh::default();
        let s0 = a.surface_id("bark");
        let s1 = a.surface_id("leaf");
        let mut r = stream(11, 0, 0);
        for i in 0..3000 {
            let c = Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 2.0 - 1.0;
            let mut corner = || c + Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 0.3;
            a.push_triangle([corner(), corner(), corner()], if i % 2 == 0 { s0 } else { s1 });
        }
        let mut b = TriangleMesh::default();
        let s = b.surface_id("box");
        b.push_box(Vec3::splat(-0.5), Vec3::splat(0.5), 1, s);
        vec![a, b]
    }

    fn instances(count: usize) -> Vec<Instance> {
        let mut r = stream(12, 0, 0);
        (0..count)
            .map(|i| {
                let t = Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 30.0 - 15.0;
                let axis = uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
                let rot = Quat::from_axis_angle(axis, uniform(&mut r) * 6.0);
                let mut scale = Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 2.0 + 1.0;
                if i % 5 == 0 {
                    scale.x = -scale.x; // mirrored
                }
                let mesh = (i % 2) as u32;
                let surfaces = if mesh == 0 { vec![3, 4 + (i % 2) as u32] } else { vec![7] };
                Instance {
                    mesh,
                    object_to_world: Affine3A::from_scale_rotation_translation(scale, rot, t),
                    surfaces,
                }
            })
            .collect()
    }

    #[test]
    fn instanced_queries_match_the_flattened_mesh() {
        let meshes = meshes();
        let instances = instances(200);
        let set = InstanceSet::build(&meshes, &instances, BuildQuality::default());
        assert_eq!(set.len(), 200);
        assert_eq!(set.instanced_triangles(), 100 * 3000 + 100 * 12);
        let flat = flatten(&meshes, &instances);
        let reference = MeshBvh::build(&flat, BuildQuality::default());
        let mut accel = Accel::build(&TriangleMesh::default(), Vec::new(), BuildQuality::default());
        accel = accel.with_instances(InstanceSet::build(&meshes, &instances, BuildQuality::default()));
        let (mut same, mut rays) = (0, Vec::new());
        for k in 0..20_000u64 {
            let mut r = stream(13, 0, k);
            let o = Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 40.0 - 20.0;
            let d = uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            let ray = Ray::segment(o, d, 5.0 + 40.0 * uniform(&mut r));
            rays.push(ray);
            let a = set.closest_hit(&ray);
            let b = reference.closest_hit(&ray);
            assert_eq!(a.is_some(), b.is_some(), "ray {k}");
            assert_eq!(set.occluded(&ray), b.is_some(), "ray {k}");
            if let (Some(a), Some(b)) = (a, b) {
                assert!((a.t - b.t).abs() <= 1e-4 * (1.0 + b.t), "ray {k}: {} vs {}", a.t, b.t);
                if a.normal.dot(b.normal) > 0.999 && a.surface == b.surface {
                    same += 1;
                }
                assert_eq!(a.front_face, a.normal.dot(ray.dir) < 0.0);
                assert!((a.point - ray.at(a.t)).length() < 1e-5 * (1.0 + a.point.length()));
            }
            let (mut na, mut nb) = (0usize, 0usize);
            set.for_each_hit(&ray, |_, _| na += 1);
            reference.for_each_hit(&ray, |_| nb += 1);
            assert!(na.abs_diff(nb) <= 1, "ray {k}: {na} vs {nb} hits");
        }
        // Normals and surfaces agree but for ties between overlapping copies.
        let hits = rays.iter().filter(|r| reference.closest_hit(r).is_some()).count();
        assert!(hits > 4_000 && same * 1000 >= hits * 998, "{same} of {hits}");
        // The batch query gives the single-ray answers.
        let mut out = vec![None; rays.len()];
        accel.closest_hits_into(&rays, &mut out);
        for (ray, hit) in rays.iter().zip(&out) {
            assert_eq!(*hit, accel.closest_hit(ray));
            assert_eq!(hit.is_some(), accel.occluded(ray));
        }
    }

    #[test]
    fn the_grouped_batch_query_gives_the_single_ray_hits() {
        let meshes = meshes();
        let instances = instances(200);
        let mut set = InstanceSet::build(&meshes, &instances, BuildQuality::default());
        // The 3000-triangle tree is below the stream size: walk it in groups all the same.
        set.meshes[0].traverser = set.meshes[0].traverser.with_streams(true);
        set.groups = true;
        let spheres = vec![
            crate::core::sphere::Sphere::new(Vec3::new(1.0, 2.0, 0.5), 3.0, 9),
            crate::core::sphere::Sphere::new(Vec3::new(-8.0, 5.0, -2.0), 2.0, 9),
        ];
        let accel =
            Accel::build(&TriangleMesh::default(), spheres, BuildQuality::default()).with_instances(set);
        assert!(accel.instances.groups());
        // Camera-like fans (coherent runs of 32) from several eyes, then random rays.
        let mut rays = Vec::new();
        for (e, eye) in [Vec3::new(-25.0, -25.0, 20.0), Vec3::new(0.0, 0.0, 0.0), Vec3::new(30.0, 3.0, -4.0)]
            .into_iter()
            .enumerate()
        {
            let forward = -eye.normalize_or(Vec3::X);
            let right = forward.cross(Vec3::Z).normalize();
            let up = right.cross(forward);
            for k in 0..4096 {
                let (u, v) = ((k % 64) as f32 / 64.0 - 0.5, (k / 64) as f32 / 64.0 - 0.5);
                let dir = (forward + 0.3 * u * right + 0.3 * v * up).normalize();
                let t_max = if e == 1 { 12.0 } else { f32::INFINITY };
                rays.push(Ray::segment(eye, dir, t_max));
            }
        }
        for k in 0..2048u64 {
            let mut r = stream(15, 0, k);
            let o = Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 40.0 - 20.0;
            rays.push(Ray::new(o, uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)))));
        }
        let (lo, hi) = accel.instances.bounds();
        let (grouped, _) = split_coherent(&rays, (hi - lo).max_element());
        assert!(grouped.len() >= 3 * 4096, "{} rays in coherent runs", grouped.len());
        let mut out = vec![None; rays.len()];
        for (block, hits) in rays.chunks(1024).zip(out.chunks_mut(1024)) {
            accel.closest_hits_into(block, hits);
        }
        let (mut hits, mut same) = (0, 0);
        for (k, (ray, hit)) in rays.iter().zip(&out).enumerate() {
            let want = accel.closest_hit(ray);
            assert_eq!(hit.map(|h| h.t.to_bits()), want.map(|h| h.t.to_bits()), "ray {k}");
            if let (Some(a), Some(b)) = (hit, want) {
                hits += 1;
                same += usize::from(*a == b);
            }
        }
        // Only exact ties (an edge shared by two triangles) may pick the other triangle.
        assert!(hits > 8_000 && same * 1000 >= hits * 999, "{same} of {hits}");
    }

    #[test]
    fn normals_use_the_inverse_transpose_and_stay_outward() {
        let mut b = TriangleMesh::default();
        let s = b.surface_id("box");
        b.push_box(Vec3::splat(-1.0), Vec3::splat(1.0), 1, s);
        // A shear: the x = 1 face's normal becomes M^-T (1, 0, 0), not M (1, 0, 0).
        let shear = Mat3A::from_cols(
            Vec3::X.into(),
            Vec3::new(0.0, 1.0, 0.0).into(),
            Vec3::new(1.0, 0.0, 1.0).into(),
        );
        for m in [Affine3A::from_mat3(shear.into()), Affine3A::from_scale(Vec3::new(-2.0, 1.0, 1.0))] {
            let inst = Instance { mesh: 0, object_to_world: m, surfaces: vec![5] };
            let set = InstanceSet::build(
                std::slice::from_ref(&b),
                std::slice::from_ref(&inst),
                BuildQuality::Medium,
            );
            let world_face = m.transform_point3(Vec3::new(1.0, 0.2, 0.1));
            let from = world_face + Vec3::new(3.0, 0.1, 0.2) * m.matrix3.determinant().signum();
            let ray = Ray::new(from, (world_face - from).normalize());
            let h = set.closest_hit(&ray).expect("hit");
            let want = Vec3::from(m.matrix3.inverse().transpose() * glam::Vec3A::X).normalize();
            let want = if m.matrix3.determinant() < 0.0 { -want } else { want };
            // The face hit is x = +1 (object) for the shear and x = -1 for the mirror, both
            // facing the ray's origin: outward.
            assert!(h.front_face, "{m:?}");
            assert!(h.normal.dot(ray.dir) < 0.0);
            assert!((h.normal.abs() - want.abs()).length() < 1e-5, "{} vs {want}", h.normal);
            assert_eq!(h.surface, 5);
            assert_eq!(h.kind, PrimitiveKind::Instance);
        }
    }

    #[test]
    fn bounces_off_far_instances_never_rehit_their_surface() {
        let mut b = TriangleMesh::default();
        let s = b.surface_id("box");
        b.push_box(Vec3::splat(-0.5), Vec3::splat(0.5), 4, s);
        let instances: Vec<Instance> = (0..16)
            .map(|i| Instance {
                mesh: 0,
                object_to_world: Affine3A::from_scale_rotation_translation(
                    Vec3::splat(0.01 + i as f32),
                    Quat::from_rotation_z(i as f32),
                    Vec3::new(2000.0 + 40.0 * i as f32, -1500.0, 300.0),
                ),
                surfaces: vec![0],
            })
            .collect();
        let set = InstanceSet::build(std::slice::from_ref(&b), &instances, BuildQuality::Medium);
        let mut rehits = 0;
        for k in 0..20_000u64 {
            let mut r = stream(14, 0, k);
            let i = (k % 16) as usize;
            let c: Vec3 = instances[i].object_to_world.translation.into();
            let d = uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            let Some(h) = set.closest_hit(&Ray::new(c + d * 100.0, -d)) else { continue };
            // Leave the surface on the side the ray came from, in a random direction there.
            let mut out = uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            if out.dot(h.facing_normal()) < 0.0 {
                out = -out;
            }
            let next = Ray::spawn(h.point, h.normal, out);
            if set.closest_hit(&next).is_some_and(|n| n.t < 1e-3 * (1.0 + i as f32)) {
                rehits += 1;
            }
        }
        assert_eq!(rehits, 0);
    }
}
