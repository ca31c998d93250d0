//! Acceleration structures: an obvhs compressed wide BVH (CWBVH) over a mesh's triangles,
//! and a set of analytic spheres, with closest-hit, occlusion, all-hits and batch queries.
//!
//! Instancing: [`MeshBvh`] is self-contained in its own coordinate frame (triangles reordered
//! to the BVH leaf order, with a map back to mesh indices), so placed copies of a mesh share
//! one: [`InstanceSet`] is a top-level BVH over instance bounds whose leaves transform the
//! ray into a `MeshBvh`'s frame ([`instances`]).

use std::time::Duration;

use glam::{Vec2, Vec3, Vec4};
use obvhs::aabb::Aabb;
use obvhs::bvh2::reinsertion::ReinsertionOptimizer;
use obvhs::cwbvh::CwBvh;
use obvhs::cwbvh::builder::build_cwbvh;
use obvhs::cwbvh::node::CwBvhNode;
use obvhs::{Boundable, BvhBuildParams};
use rayon::prelude::*;

mod collapse;
pub mod instances;
mod ploc;

pub use instances::{Instance, InstanceSet};

use super::convex::{ConvexRoom, Exit};
use super::flat::{FLAT_LIMIT, FlatRay, FlatTriangles};
use super::hit::{Hit, PrimitiveKind};
use super::leaf::{LeafRay, LeafTriangles};
use super::mesh::TriangleMesh;
use super::ray::Ray;
use super::sphere::Sphere;
use super::traverse::prefetch;
use super::traverse::{AnyLeaves, ClosestLeaves, GROUP_WIDTH, NodeRay, Traverser, leaf_ranges};
use super::triangle::RayShear;

/// BVH build quality presets, from obvhs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum BuildQuality {
    /// obvhs' fast preset.
    Fast,
    /// obvhs' medium preset: about Embree's build time with faster traversal.
    #[default]
    Medium,
    /// obvhs' high preset.
    High,
}

impl BuildQuality {
    /// Every preset.
    pub const ALL: [BuildQuality; 3] = [BuildQuality::Fast, BuildQuality::Medium, BuildQuality::High];

    fn params(self) -> BvhBuildParams {
        let mut p = match self {
            BuildQuality::Fast => BvhBuildParams::fast_build(),
            BuildQuality::Medium => BvhBuildParams::medium_build(),
            BuildQuality::High => BvhBuildParams::slow_build(),
        };
        // Spatial pre-splits duplicate references; we keep one reference per triangle.
        p.pre_split = false;
        p.max_prims_per_leaf = 3;
        p
    }
}

struct Bounds(Aabb);

/// Relative padding of primitive bounds. obvhs' slab test has no rounding margin, so a ray
/// grazing a flat node box (an axis-aligned wall) could be culled by one ulp and miss a hit
/// the triangle test would find; a few ulps of padding keep traversal conservative
/// (cf. Ize 2013, "Robust BVH Ray Traversal").
const BOUNDS_PADDING: f32 = 1.0e-6;

fn padded_bounds(lo: Vec3, hi: Vec3) -> Bounds {
    let pad = Vec3::splat(BOUNDS_PADDING * (1.0 + lo.abs().max(hi.abs()).max_element()));
    Bounds(Aabb::new((lo - pad).into(), (hi + pad).into()))
}

/// The padded box of every triangle of `mesh`, in triangle order: the tree builder's input.
fn triangle_bounds(mesh: &TriangleMesh) -> Vec<Bounds> {
    (0..mesh.triangle_count())
        .into_par_iter()
        .map(|i| {
            let [a, b, c] = mesh.corners(i);
            padded_bounds(a.min(b).min(c), a.max(b).max(c))
        })
        .collect()
}

impl Boundable for Bounds {
    fn aabb(&self) -> Aabb {
        self.0
    }
}

/// The node-test constants of a ray (see [`NodeRay`] for the -0.0 fix).
#[inline]
fn node_ray(ray: &Ray) -> NodeRay {
    NodeRay::new(ray.origin, ray.dir, ray.t_min)
}

/// A CWBVH over one mesh's triangles (Ylitie et al. 2017), built by obvhs: PLOC, reinsertion,
/// then the SAH-driven collapse to 8 children.
///
/// (An uncompressed copy of the nodes with exact float child boxes, Embree's BVH8 layout at
/// 256 bytes a node, was measured 7-15 % slower on incoherent rays: the nodes no longer fit
/// the caches as well, and the quantised test's decompression is cheap next to the misses.)
pub struct MeshBvh {
    nodes: Vec<CwBvhNode>,
    traverser: Traverser,
    /// Triangles in BVH leaf order, packed leaf by leaf.
    leaves: LeafTriangles,
    /// Mesh triangle index of each entry of `tris`.
    mesh_index: Vec<u32>,
    /// Surface id of each entry of `tris`.
    surface: Vec<u32>,
    /// Small meshes: all triangles in blocks, tested without the tree (`nodes` is empty and
    /// `leaves` holds one triangle a leaf, in the blocks' slot order).
    flat: Option<FlatTriangles>,
    /// A flat mesh's geometric normal of each slot, made once: a launcher's hit needs it at
    /// every bounce, and recomputing it cost a third of the query on a 12-triangle room.
    flat_normals: Vec<Vec3>,
    /// A flat mesh that closes a convex polyhedron: rays from inside take the plane test
    /// (closest hits and occlusion; [`ConvexRoom`]).
    convex: Option<ConvexRoom>,
    /// Largest side of the root box (m): the scale of [`split_coherent`]'s origin test.
    size_m: f32,
}

/// Stage times of a build, printed to stderr when this variable is set.
const BUILD_TIMES_VARIABLE: &str = "PROPSIM_BUILD_TIMES";

impl MeshBvh {
    /// Builds the BVH of `mesh` at `quality`.
    pub fn build(mesh: &TriangleMesh, quality: BuildQuality) -> Self {
        if mesh.triangle_count() <= FLAT_LIMIT {
            return Self::build_flat(mesh);
        }
        Self::build_tree(mesh, quality)
    }

    /// Every triangle tested by [`FlatTriangles`], without a tree (also the empty mesh).
    fn build_flat(mesh: &TriangleMesh) -> Self {
        let corners: Vec<[Vec3; 3]> = (0..mesh.triangle_count()).map(|i| mesh.corners(i)).collect();
        let flat = FlatTriangles::new(&corners);
        // Empty lanes' slots point at triangle 0; their lanes are never hit.
        let mesh_index: Vec<u32> = flat.slots().iter().map(|s| s.unwrap_or(0)).collect();
        let n = mesh_index.len();
        let singles: Vec<(u32, u32)> = (0..n as u32).map(|i| (i, 1)).collect();
        let leaves = LeafTriangles::new(n, &singles, |slot| corners[mesh_index[slot] as usize]);
        let occupied: Vec<(u32, [Vec3; 3])> = (flat.slots().iter().enumerate())
            .filter_map(|(slot, i)| i.map(|i| (slot as u32, corners[i as usize])))
            .collect();
        Self {
            convex: ConvexRoom::new(&occupied),
            nodes: Vec::new(),
            traverser: Traverser::new::<CwBvhNode>(&[]),
            flat_normals: (0..n as u32).map(|slot| leaves.triangle(slot, 1, 0).normal()).collect(),
            leaves,
            surface: mesh_index.iter().map(|&i| mesh.surface_of_triangle[i as usize]).collect(),
            mesh_index,
            flat: Some(flat),
            size_m: 0.0,
        }
    }

    /// The CWBVH over the mesh's triangles, whatever their count (the empty mesh gets the
    /// empty flat set).
    pub fn build_tree(mesh: &TriangleMesh, quality: BuildQuality) -> Self {
        let n = mesh.triangle_count();
        if n == 0 {
            return Self::build_flat(mesh);
        }
        let verbose = std::env::var_os(BUILD_TIMES_VARIABLE).is_some();
        let mut clock = std::time::Instant::now();
        let mut stage = |name: &str| {
            if verbose {
                crate::errln!("build {name}: {:.1} ms", clock.elapsed().as_secs_f64() * 1e3);
            }
            clock = std::time::Instant::now();
        };
        let bounds = triangle_bounds(mesh);
        stage("bounds");
        let p = quality.params();
        let (mut bvh2, guarded) = ploc::build(&bounds, &p);
        stage("ploc");
        // A tree the guard had to shape (degenerate input: copies of one triangle, one huge
        // polygon) is a long chain on which reinsertion's work grows faster than the size
        // (7 s of a 9.8 s build for one face of 900,000 indices): it is left as built.
        if !guarded {
            ReinsertionOptimizer::default().run(&mut bvh2, p.reinsertion_batch_ratio, None);
        }
        stage("reinsertion");
        let (nodes, mesh_index) = collapse::collapse(&bvh2, p.max_prims_per_leaf);
        drop(bvh2);
        stage("collapse");
        drop(bounds);
        let surface = mesh_index.par_iter().map(|&i| mesh.surface_of_triangle[i as usize]).collect();
        let leaves =
            LeafTriangles::new(n, &leaf_ranges(&nodes), |slot| mesh.corners(mesh_index[slot] as usize));
        stage("leaves");
        let traverser = Traverser::new(&nodes);
        stage("traverser");
        // The root's child planes span 255 steps of 2^e on each axis.
        let size_m =
            nodes[0].e.iter().map(|&e| f32::from_bits(u32::from(e) << 23) * 255.0).fold(0.0, f32::max);
        Self {
            nodes,
            traverser,
            leaves,
            mesh_index,
            surface,
            flat: None,
            flat_normals: Vec::new(),
            convex: None,
            size_m,
        }
    }

    /// Bytes held by the structure (nodes, triangles and index maps).
    pub fn memory_bytes(&self) -> usize {
        self.nodes.len() * std::mem::size_of::<CwBvhNode>()
            + self.leaves.memory_bytes()
            + self.flat.as_ref().map_or(0, FlatTriangles::memory_bytes)
            + self.mesh_index.len() * 8
    }

    /// The leaf test of a closest-hit query for `ray`.
    #[inline(always)]
    fn closest_visitor<'a>(&'a self, ray: &'a Ray) -> ClosestTriangle<'a> {
        ClosestTriangle { leaves: &self.leaves, mesh_index: &self.mesh_index, shear: None, ray, best: None }
    }

    /// The leaf test of an occlusion query for `ray`.
    #[inline(always)]
    fn occlusion_visitor<'a>(&'a self, ray: &'a Ray) -> Occlusion<'a> {
        Occlusion { leaves: &self.leaves, shear: None, ray }
    }

    /// The closest hit as (leaf, lane, distance, barycentrics).
    #[inline(always)]
    fn closest_lane(&self, ray: &Ray) -> Option<ClosestLane> {
        if let Some(room) = &self.convex {
            match room.exit(ray.origin, ray.dir, ray.t_min, ray.t_max) {
                Exit::Hit { slot, t, uv } => {
                    return Some(ClosestLane { first: slot, count: 1, lane: 0, t, uv });
                }
                Exit::Miss => return None,
                Exit::Unknown => {}
            }
        }
        if let Some(flat) = &self.flat {
            let flat_ray = FlatRay::new(ray.origin, ray.dir);
            return self
                .traverser
                .flat_closest(flat, &flat_ray, ray.t_min, ray.t_max)
                .map(|(first, t, uv)| ClosestLane { first, count: 1, lane: 0, t, uv });
        }
        let mut visitor = self.closest_visitor(ray);
        self.traverser.closest(&self.nodes, &node_ray(ray), ray.t_max, &mut visitor);
        visitor.best
    }

    /// The hit on triangle `lane` of leaf `(first, count)`.
    #[inline(always)]
    fn make_hit(&self, (first, count, lane): (u32, u32, u32), t: f32, uv: Vec2, ray: &Ray) -> Hit {
        let slot = (first + lane) as usize;
        let normal = match self.flat_normals.get(slot) {
            Some(&n) => n,
            None => self.leaves.triangle(first, count, lane as usize).normal(),
        };
        Hit {
            t,
            point: ray.at(t),
            normal,
            barycentric: uv,
            primitive: self.mesh_index[slot],
            kind: PrimitiveKind::Triangle,
            surface: self.surface[slot],
            front_face: normal.dot(ray.dir) < 0.0,
        }
    }

    /// The closest triangle hit along `ray`, if any.
    #[inline(always)]
    pub fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        self.closest_lane(ray).map(|c| self.make_hit((c.first, c.count, c.lane), c.t, c.uv, ray))
    }

    /// Mesh index of the closest triangle hit, without building a full [`Hit`].
    pub fn closest_triangle(&self, ray: &Ray) -> Option<(u32, f32)> {
        self.closest_lane(ray).map(|c| (self.mesh_index[(c.first + c.lane) as usize], c.t))
    }

    /// [`MeshBvh::closest_triangle`] with the ray's [`FlatRay`] built beforehand (it must be
    /// `FlatRay::new(ray.origin, ray.dir)`), so that a caller can build it early, off the way
    /// to the query. A mesh with a tree does not use it.
    #[inline]
    pub fn closest_triangle_prepared(&self, ray: &Ray, flat_ray: &FlatRay) -> Option<(u32, f32)> {
        let Some(flat) = &self.flat else {
            return self.closest_triangle(ray);
        };
        if self.convex.is_some() {
            return self.closest_triangle(ray);
        }
        let closest = self.traverser.flat_closest(flat, flat_ray, ray.t_min, ray.t_max);
        closest.map(|(first, t, _)| (self.mesh_index[first as usize], t))
    }

    /// A flat mesh's blocks and the mesh index of each of their slots.
    pub(crate) fn flat_parts(&self) -> Option<(&FlatTriangles, &[u32])> {
        self.flat.as_ref().map(|flat| (flat, self.mesh_index.as_slice()))
    }

    /// The traversal's choice of instruction set.
    pub(crate) fn traverser(&self) -> &Traverser {
        &self.traverser
    }

    /// True when any triangle lies on the segment `(t_min, t_max)`.
    pub fn occluded(&self, ray: &Ray) -> bool {
        if let Some(room) = &self.convex {
            match room.exit(ray.origin, ray.dir, ray.t_min, ray.t_max) {
                Exit::Hit { .. } => return true,
                Exit::Miss => return false,
                Exit::Unknown => {}
            }
        }
        if let Some(flat) = &self.flat {
            let flat_ray = FlatRay::new(ray.origin, ray.dir);
            return self.traverser.flat_any(flat, &flat_ray, ray.t_min, ray.t_max);
        }
        let mut visitor = self.occlusion_visitor(ray);
        self.traverser.any(&self.nodes, &node_ray(ray), ray.t_max, &mut visitor)
    }

    /// Closest hits of many rays, coherent groups walking the tree together and the others as a
    /// stream ([`split_coherent`]):
    /// `out(i, lane)` gets ray `i`'s closest leaf lane.
    fn closest_lanes_stream(&self, rays: &[Ray], mut out: impl FnMut(usize, Option<ClosestLane>)) {
        let (grouped, alone) = split_coherent(rays, self.size_m);
        let start = |i: usize| (node_ray(&rays[i]), rays[i].t_max, self.closest_visitor(&rays[i]));
        if grouped.is_empty() {
            // All incoherent: one stream, without the index list.
            self.traverser.closest_stream(&self.nodes, rays.len(), start, |i, visitor| out(i, visitor.best));
            return;
        }
        self.traverser.closest_groups(
            &self.nodes,
            grouped.len(),
            |k| start(grouped[k] as usize),
            |k, visitor| out(grouped[k] as usize, visitor.best),
        );
        if !alone.is_empty() {
            self.traverser.closest_stream(
                &self.nodes,
                alone.len(),
                |k| start(alone[k] as usize),
                |k, visitor| out(alone[k] as usize, visitor.best),
            );
        }
    }

    /// Closest lanes of at most [`GROUP_WIDTH`] coherent rays (close in direction and
    /// origin), each up to its `t_max`: on trees large enough for streams they walk the tree
    /// as one group (the same distances as [`MeshBvh::closest_lane`], bit for bit), else one
    /// by one. `out(k, lane)` gets ray `k`'s; `stack` is scratch space. The instanced batch
    /// query's bottom level.
    fn closest_lanes_grouped(
        &self,
        rays: &[Ray],
        stack: &mut Vec<(u32, u32, f32)>,
        mut out: impl FnMut(usize, Option<ClosestLane>),
    ) {
        if self.flat.is_some() || !self.traverser.streams() || rays.len() > GROUP_WIDTH {
            rays.iter().enumerate().for_each(|(k, r)| out(k, self.closest_lane(r)));
            return;
        }
        let node_rays: Vec<NodeRay> = rays.iter().map(node_ray).collect();
        let mut t_max: Vec<f32> = rays.iter().map(|r| r.t_max).collect();
        let mut visitors: Vec<ClosestTriangle<'_>> = rays.iter().map(|r| self.closest_visitor(r)).collect();
        self.traverser.closest_one_group(
            &self.nodes,
            &node_rays,
            &mut t_max,
            stack,
            |first, count, mut m, t| {
                while m != 0 {
                    let r = m.trailing_zeros() as usize;
                    m &= m - 1;
                    visitors[r].test(first, count, &mut t[r]);
                }
            },
        );
        visitors.into_iter().enumerate().for_each(|(k, v)| out(k, v.best));
    }

    /// [`MeshBvh::closest_hit`] of every ray, in groups and a stream, into `out`.
    pub fn closest_hits_into(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        if self.mesh_index.is_empty() {
            // No triangle (a scene of instances only): nothing to test.
            out.fill(None);
            return;
        }
        if !self.traverser.streams() {
            out.iter_mut().zip(rays).for_each(|(o, r)| *o = self.closest_hit(r));
            return;
        }
        self.closest_lanes_stream(rays, |i, best| {
            out[i] = best.map(|c| self.make_hit((c.first, c.count, c.lane), c.t, c.uv, &rays[i]));
        });
    }

    /// Calls `f` for every triangle hit on the ray, in no particular order.
    pub fn for_each_hit(&self, ray: &Ray, mut f: impl FnMut(Hit)) {
        if let Some(flat) = &self.flat {
            let flat_ray = FlatRay::new(ray.origin, ray.dir);
            flat.for_each_hit(&flat_ray, ray.t_min, ray.t_max, |i, t, uv| {
                f(self.make_hit((i, 1, 0), t, uv, ray))
            });
            return;
        }
        let mut visitor =
            AllHits { mesh: self, shear: LeafRay::new(&RayShear::new(ray.origin, ray.dir)), ray, f };
        self.traverser.any(&self.nodes, &node_ray(ray), ray.t_max, &mut visitor);
    }
}

/// The closest hit found so far: lane `lane` of the leaf `(first, count)`.
#[derive(Clone, Copy, Debug)]
struct ClosestLane {
    first: u32,
    count: u32,
    lane: u32,
    t: f32,
    uv: Vec2,
}

/// The leaf test of a closest-hit query.
struct ClosestTriangle<'a> {
    leaves: &'a LeafTriangles,
    /// [`MeshBvh::mesh_index`], whose entry for a new closest hit is prefetched: looking it
    /// up at the end was a cache miss a hit (6 % of the time on coherent rays).
    mesh_index: &'a [u32],
    /// The ray's leaf-test constants, made at the first leaf (as for [`Occlusion`]).
    shear: Option<LeafRay>,
    ray: &'a Ray,
    best: Option<ClosestLane>,
}

impl ClosestLeaves for ClosestTriangle<'_> {
    #[inline(always)]
    fn test(&mut self, first: u32, count: u32, t_max: &mut f32) {
        let ray = self.ray;
        let shear = self.shear.get_or_insert_with(|| LeafRay::new(&RayShear::new(ray.origin, ray.dir)));
        let hits = self.leaves.intersect(first, count, shear, ray.t_min, *t_max);
        let mut mask = hits.mask;
        while mask != 0 {
            let lane = mask.trailing_zeros();
            mask &= mask - 1;
            let (t, uv) = hits.lane(lane as usize);
            // Only a strictly closer hit replaces the best one.
            if t < *t_max {
                *t_max = t;
                self.best = Some(ClosestLane { first, count, lane, t, uv });
                if let Some(index) = self.mesh_index.get((first + lane) as usize) {
                    prefetch(index);
                }
            }
        }
    }

    #[inline(always)]
    fn prefetch(&self, first: u32, count: u32) {
        self.leaves.prefetch(first, count);
    }
}

/// The leaf test of an occlusion query.
struct Occlusion<'a> {
    leaves: &'a LeafTriangles,
    /// The ray's leaf-test constants, made at the first leaf: a ray that reaches none (most
    /// of a camera's sky rays) never needs them.
    shear: Option<LeafRay>,
    ray: &'a Ray,
}

impl AnyLeaves for Occlusion<'_> {
    #[inline(always)]
    fn test(&mut self, first: u32, count: u32) -> bool {
        let ray = self.ray;
        let shear = self.shear.get_or_insert_with(|| LeafRay::new(&RayShear::new(ray.origin, ray.dir)));
        let hits = self.leaves.intersect(first, count, shear, ray.t_min, ray.t_max);
        hits.mask & hits.t.cmplt(Vec4::splat(ray.t_max)).bitmask() != 0
    }

    #[inline(always)]
    fn prefetch(&self, first: u32, count: u32) {
        self.leaves.prefetch(first, count);
    }
}

/// The leaf test of an all-hits query.
struct AllHits<'a, F> {
    mesh: &'a MeshBvh,
    shear: LeafRay,
    ray: &'a Ray,
    f: F,
}

impl<F: FnMut(Hit)> AnyLeaves for AllHits<'_, F> {
    fn test(&mut self, first: u32, count: u32) -> bool {
        let hits = self.mesh.leaves.intersect(first, count, &self.shear, self.ray.t_min, self.ray.t_max);
        let mut mask = hits.mask;
        while mask != 0 {
            let lane = mask.trailing_zeros();
            mask &= mask - 1;
            let (t, uv) = hits.lane(lane as usize);
            (self.f)(self.mesh.make_hit((first, count, lane), t, uv, self.ray));
        }
        false
    }

    fn prefetch(&self, first: u32, count: u32) {
        self.mesh.leaves.prefetch(first, count);
    }
}

/// The leaf visit of a sphere BVH: every candidate sphere index goes to `f`.
struct SphereCandidates<'a, F> {
    order: &'a [u32],
    f: F,
}

impl<F: FnMut(usize)> AnyLeaves for SphereCandidates<'_, F> {
    fn test(&mut self, first: u32, count: u32) -> bool {
        let range = first as usize..(first + count) as usize;
        self.order[range].iter().for_each(|&i| (self.f)(i as usize));
        false
    }
}

/// Below this many spheres a linear scan beats a BVH.
const SPHERE_LINEAR_LIMIT: usize = 16;

/// Analytic spheres, with a CWBVH when there are many.
#[derive(Default)]
pub struct SphereSet {
    /// The spheres.
    pub spheres: Vec<Sphere>,
    bvh: Option<(CwBvh, Traverser)>,
}

impl SphereSet {
    /// A set of `spheres`, with a BVH when there are many.
    pub fn new(spheres: Vec<Sphere>) -> Self {
        let bvh = (spheres.len() > SPHERE_LINEAR_LIMIT).then(|| {
            let bounds: Vec<Bounds> =
                spheres.iter().map(|s| padded_bounds(s.aabb_min(), s.aabb_max())).collect();
            let bvh = build_cwbvh(&bounds, BvhBuildParams::medium_build(), &mut Duration::default());
            let traverser = Traverser::new(&bvh.nodes);
            (bvh, traverser)
        });
        Self { spheres, bvh }
    }

    /// Whether there is no sphere.
    pub fn is_empty(&self) -> bool {
        self.spheres.is_empty()
    }

    /// Calls `f(index)` for every sphere whose bounds the ray segment may cross.
    fn candidates(&self, ray: &Ray, f: impl FnMut(usize)) {
        match &self.bvh {
            None => (0..self.spheres.len()).for_each(f),
            Some((bvh, traverser)) => {
                let mut visitor = SphereCandidates { order: &bvh.primitive_indices, f };
                traverser.any(&bvh.nodes, &node_ray(ray), ray.t_max, &mut visitor);
            }
        }
    }

    /// The closest sphere hit along `ray`, if any.
    #[inline(always)]
    pub fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        let mut best: Option<Hit> = None;
        let mut r = *ray;
        self.candidates(ray, |i| {
            let s = &self.spheres[i];
            if let Some((t, n, uv)) = s.intersect(&r) {
                r.t_max = t;
                best = Some(Hit {
                    t,
                    point: ray.at(t),
                    normal: n,
                    barycentric: uv,
                    primitive: i as u32,
                    kind: PrimitiveKind::Sphere,
                    surface: s.surface,
                    front_face: n.dot(ray.dir) < 0.0,
                });
            }
        });
        best
    }

    /// Whether any sphere blocks `ray`.
    pub fn occluded(&self, ray: &Ray) -> bool {
        let mut any = false;
        self.candidates(ray, |i| any |= self.spheres[i].intersect(ray).is_some());
        any
    }

    /// Calls `f(index, chord_length)` for every sphere the segment passes through.
    pub fn for_each_crossing(&self, ray: &Ray, mut f: impl FnMut(usize, f32)) {
        self.candidates(ray, |i| {
            let chord = self.spheres[i].chord_length(ray);
            if chord > 0.0 {
                f(i, chord);
            }
        });
    }
}

/// Everything a simulator traces against: one triangle mesh, a set of opaque spheres and
/// placed copies of other meshes (instances).
pub struct Accel {
    /// The triangle mesh's BVH.
    pub mesh: MeshBvh,
    /// The spheres.
    pub spheres: SphereSet,
    /// The instances (empty for most scenes).
    pub instances: InstanceSet,
    /// Transformed analytic shapes (empty for most scenes).
    pub shapes: super::shapes::ShapeSet,
    /// Signed distance fields (empty for most scenes).
    pub sdfs: super::sdf::SdfSet,
    /// True when there are neither spheres nor instances: the queries stop at the mesh.
    mesh_only: bool,
    /// Corners of a box holding every triangle and sphere (empty: lower above upper).
    bounds: (Vec3, Vec3),
}

impl Accel {
    /// Builds the structure over `mesh` and `spheres` at `quality`.
    pub fn build(mesh: &TriangleMesh, spheres: Vec<Sphere>, quality: BuildQuality) -> Self {
        let empty = (Vec3::INFINITY, Vec3::NEG_INFINITY);
        let bounds = spheres
            .iter()
            .fold(mesh.bounds().unwrap_or(empty), |(lo, hi), s| (lo.min(s.aabb_min()), hi.max(s.aabb_max())));
        let mesh_only = spheres.is_empty();
        Self {
            mesh: MeshBvh::build(mesh, quality),
            spheres: SphereSet::new(spheres),
            instances: InstanceSet::default(),
            shapes: super::shapes::ShapeSet::default(),
            sdfs: super::sdf::SdfSet::default(),
            mesh_only,
            bounds,
        }
    }

    /// This structure with `instances` added (their bounds join the scene's).
    pub fn with_instances(mut self, instances: InstanceSet) -> Self {
        let (lo, hi) = instances.bounds();
        self.bounds = (self.bounds.0.min(lo), self.bounds.1.max(hi));
        self.mesh_only &= instances.is_empty();
        self.instances = instances;
        self
    }

    /// This structure with `shapes` added (their bounds join the scene's).
    pub fn with_shapes(mut self, shapes: super::shapes::ShapeSet) -> Self {
        for (s, _) in &shapes.shapes {
            let (lo, hi) = s.bounds();
            self.bounds = (self.bounds.0.min(lo), self.bounds.1.max(hi));
        }
        self.mesh_only &= shapes.is_empty();
        self.shapes = shapes;
        self
    }

    /// This structure with the signed distance fields `sdfs` added (their bounds join the
    /// scene's).
    pub fn with_sdfs(mut self, sdfs: super::sdf::SdfSet) -> Self {
        for (s, _) in &sdfs.sdfs {
            let (lo, hi) = s.bounds();
            self.bounds = (self.bounds.0.min(lo), self.bounds.1.max(hi));
        }
        self.mesh_only &= sdfs.is_empty();
        self.sdfs = sdfs;
        self
    }

    /// Bytes held by the mesh's BVH and the instances.
    pub fn memory_bytes(&self) -> usize {
        self.mesh.memory_bytes() + self.instances.memory_bytes()
    }

    /// True when `ray` cannot meet anything: its origin is on or beyond a face of the box
    /// that holds the scene and it moves away from that face (so no query needs to run; the
    /// launcher's rays through a floor into the void below end this way).
    #[inline(always)]
    pub fn leaves_bounds(&self, ray: &Ray) -> bool {
        let (lo, hi) = self.bounds;
        let (o, d) = (ray.origin, ray.dir);
        (o.x <= lo.x && d.x < 0.0)
            || (o.y <= lo.y && d.y < 0.0)
            || (o.z <= lo.z && d.z < 0.0)
            || (o.x >= hi.x && d.x > 0.0)
            || (o.y >= hi.y && d.y > 0.0)
            || (o.z >= hi.z && d.z > 0.0)
            || lo.x > hi.x
    }

    /// The closest triangle or sphere hit in `(t_min, t_max]` (inlined into the launcher's
    /// AVX2 loop).
    #[inline(always)]
    pub fn closest_hit(&self, ray: &Ray) -> Option<Hit> {
        let tri = self.mesh.closest_hit(ray);
        if self.mesh_only {
            return tri;
        }
        self.closest_beyond_mesh(ray, tri)
    }

    /// The closest of `best` (the mesh's hit) and the spheres' and instances' hits.
    #[inline(never)]
    fn closest_beyond_mesh(&self, ray: &Ray, mut best: Option<Hit>) -> Option<Hit> {
        let mut r = *ray;
        if let Some(h) = &best {
            r.t_max = h.t;
        }
        if !self.spheres.is_empty()
            && let Some(h) = self.spheres.closest_hit(&r)
        {
            r.t_max = h.t;
            best = Some(h);
        }
        if !self.instances.is_empty()
            && let Some(h) = self.instances.closest_hit(&r)
        {
            r.t_max = h.t;
            best = Some(h);
        }
        if !self.shapes.is_empty()
            && let Some(h) = self.shapes_hit(&r)
        {
            r.t_max = h.t;
            best = Some(h);
        }
        if !self.sdfs.is_empty()
            && let Some(h) = self.sdfs_hit(&r)
        {
            best = Some(h);
        }
        best
    }

    /// The closest signed-distance-field hit as a [`Hit`].
    #[inline(never)]
    pub fn sdfs_hit(&self, ray: &Ray) -> Option<Hit> {
        self.sdfs.closest(ray).map(|(i, t, normal)| Hit {
            t,
            point: ray.at(t),
            normal,
            barycentric: Vec2::ZERO,
            primitive: i as u32,
            kind: PrimitiveKind::Sdf,
            surface: self.sdfs.sdfs[i].1,
            front_face: normal.dot(ray.dir) < 0.0,
        })
    }

    /// The closest shape hit as a [`Hit`].
    #[inline(never)]
    pub fn shapes_hit(&self, ray: &Ray) -> Option<Hit> {
        self.shapes.closest(ray).map(|(i, t, normal)| Hit {
            t,
            point: ray.at(t),
            normal,
            barycentric: Vec2::ZERO,
            primitive: i as u32,
            kind: PrimitiveKind::Shape,
            surface: self.shapes.shapes[i].1,
            front_face: normal.dot(ray.dir) < 0.0,
        })
    }

    /// True when anything blocks the segment `(t_min, t_max]`: the cheap shadow-ray query.
    #[inline]
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.mesh.occluded(ray) || !self.mesh_only && self.occluded_beyond_mesh(ray)
    }

    /// Whether a sphere, an instance or a shape blocks the segment.
    #[inline(never)]
    fn occluded_beyond_mesh(&self, ray: &Ray) -> bool {
        !self.spheres.is_empty() && self.spheres.occluded(ray)
            || !self.instances.is_empty() && self.instances.occluded(ray)
            || !self.shapes.is_empty() && self.shapes.occluded(ray)
            || !self.sdfs.is_empty() && self.sdfs.occluded(ray)
    }

    /// Calls `f` for every triangle hit on the ray, the mesh's and the instances', in no
    /// particular order (spheres and shapes are not included).
    pub fn for_each_hit(&self, ray: &Ray, mut f: impl FnMut(Hit)) {
        self.mesh.for_each_hit(ray, &mut f);
        self.instances.for_each_hit(ray, |_, h| f(h));
    }

    /// [`Accel::closest_hit`] of every ray into `out`, on this thread: the mesh's batch query
    /// (coherent groups and streams on large trees, the same code `propsim bench trace`
    /// measures), then the spheres up to each triangle hit. The launcher traces its blocks
    /// of rays bounce by bounce through this.
    /// Instances whose meshes have large trees go through their own batch query
    /// ([`InstanceSet::closest_hits_into`]: coherent runs walk each instance's tree as
    /// groups), between the spheres and the shapes as in [`Accel::closest_hit`], with the
    /// same hits.
    pub fn closest_hits_into(&self, rays: &[Ray], out: &mut [Option<Hit>]) {
        self.mesh.closest_hits_into(rays, out);
        if self.mesh_only {
            return;
        }
        if !self.instances.groups() {
            for (hit, ray) in out.iter_mut().zip(rays) {
                *hit = self.closest_beyond_mesh(ray, *hit);
            }
            return;
        }
        let limited = |ray: &Ray, hit: &Option<Hit>| Ray { t_max: hit.map_or(ray.t_max, |h| h.t), ..*ray };
        if !self.spheres.is_empty() {
            for (hit, ray) in out.iter_mut().zip(rays) {
                if let Some(h) = self.spheres.closest_hit(&limited(ray, hit)) {
                    *hit = Some(h);
                }
            }
        }
        self.instances.closest_hits_into(rays, out);
        if !self.shapes.is_empty() {
            for (hit, ray) in out.iter_mut().zip(rays) {
                if let Some(h) = self.shapes_hit(&limited(ray, hit)) {
                    *hit = Some(h);
                }
            }
        }
        if !self.sdfs.is_empty() {
            for (hit, ray) in out.iter_mut().zip(rays) {
                if let Some(h) = self.sdfs_hit(&limited(ray, hit)) {
                    *hit = Some(h);
                }
            }
        }
    }
}

/// Directions of a coherent group differ by at most this much in each component.
const COHERENT_DIRECTION_SPREAD: f32 = 0.25;
/// Origins of a coherent group lie in a box whose sides are at most this fraction of the
/// scene's size.
const COHERENT_ORIGIN_SPREAD: f32 = 1.0 / 16.0;

/// Splits a batch into the rays of coherent groups (runs of [`GROUP_WIDTH`] consecutive rays
/// with nearly parallel directions and nearby origins, judged by four of them, such as the
/// polar-cap rays of a launcher's Fibonacci lattice), traced group by group
/// ([`Traverser::closest_groups`]), and the others, traced as a stream of single rays. Measured on the 1M-triangle benchmark
/// (2 threads, Mrays/s closest hit / occlusion, 3 alternating rounds): on the coherent rays
/// that hit, groups 9.0 / 11.6 against 6.8 / 8.6 for streams; on incoherent rays, where
/// groups share hardly any node, groups were half as fast (occlusion 5.4 against 10.8).
fn split_coherent(rays: &[Ray], size_m: f32) -> (Vec<u32>, Vec<u32>) {
    let (mut grouped, mut alone) = (Vec::new(), Vec::new());
    for (k, group) in rays.chunks(GROUP_WIDTH).enumerate() {
        // Four rays spread over the run stand for it (testing all 32 cost 8 % of the
        // occlusion time on coherent rays); a run they misjudge is traced right, only slower.
        let n = group.len();
        let (mut dir_lo, mut dir_hi, mut org_lo, mut org_hi) =
            (group[0].dir, group[0].dir, group[0].origin, group[0].origin);
        for r in [&group[n / 3], &group[2 * n / 3], &group[n - 1]] {
            (dir_lo, dir_hi) = (dir_lo.min(r.dir), dir_hi.max(r.dir));
            (org_lo, org_hi) = (org_lo.min(r.origin), org_hi.max(r.origin));
        }
        let coherent = (dir_hi - dir_lo).max_element() <= COHERENT_DIRECTION_SPREAD
            && (org_hi - org_lo).max_element() <= COHERENT_ORIGIN_SPREAD * size_m;
        let ids = (k * GROUP_WIDTH) as u32..(k * GROUP_WIDTH + group.len()) as u32;
        if coherent { grouped.extend(ids) } else { alone.extend(ids) }
    }
    (grouped, alone)
}

/// Fixed, irrational-looking directions for inside tests: they rarely graze edges.
const PARITY_DIRECTIONS: [[f32; 3]; 5] = [
    [0.5773, 0.5774, 0.5776],
    [-0.2673, 0.5345, 0.8018],
    [0.7072, -0.6, -0.3741],
    [-0.6, -0.48, 0.64],
    [0.05, 0.2, -0.9785],
];

/// Whether `p` is enclosed by the triangles for which `counts(instance, hit)` holds (the
/// mesh's, `instance` `None`, and the instances'), by the parity of crossings along five fixed directions and a majority
/// vote. Hits at the same distance (a ray through a shared edge meets both triangles) count
/// once.
pub fn point_enclosed(accel: &Accel, p: Vec3, counts: impl Fn(Option<u32>, &Hit) -> bool) -> bool {
    let votes = PARITY_DIRECTIONS
        .iter()
        .filter(|d| {
            let mut ts: Vec<f32> = Vec::new();
            let ray = Ray::new(p, Vec3::from(**d).normalize());
            accel.mesh.for_each_hit(&ray, |h| {
                if counts(None, &h) {
                    ts.push(h.t);
                }
            });
            accel.instances.for_each_hit(&ray, |i, h| {
                if counts(Some(i), &h) {
                    ts.push(h.t);
                }
            });
            ts.sort_by(f32::total_cmp);
            ts.dedup_by(|a, b| (*a - *b).abs() <= 1e-5 * b.abs().max(1.0));
            ts.len() % 2 == 1
        })
        .count();
    votes * 2 > PARITY_DIRECTIONS.len()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::queries::{Queries, QueryLoop};
    use crate::core::rng::{stream, uniform};
    use crate::core::sampling::uniform_sphere;

    #[test]
    fn simd_and_portable_traversals_agree() {
        let mut mesh = random_triangles(3, 3000, Vec3::splat(-20.0), 3.0);
        // Axis-aligned triangles too, for flat boxes and -0.0 directions.
        let s = mesh.surface_id("a");
        mesh.push_box(Vec3::splat(-25.0), Vec3::splat(25.0), 6, s);
        let reference = {
            let mut m = MeshBvh::build(&mesh, BuildQuality::default());
            m.traverser = Traverser::all_available(&m.nodes)[0];
            m
        };
        let mut simd = MeshBvh::build(&mesh, BuildQuality::default());
        let variants = Traverser::all_available(&simd.nodes);
        eprintln!("traversals compared to the portable one: {:?}", &variants[1..]);
        for variant in &variants[1..] {
            simd.traverser = *variant;
            compare(&reference, &simd);
        }
        // Batches as streams (this small tree would otherwise take single rays), for every
        // traversal, the portable one included.
        for variant in &variants {
            simd.traverser = variant.with_streams(true);
            compare(&reference, &simd);
        }
    }

    #[test]
    fn small_meshes_without_a_tree_match_the_tree() {
        // Random triangles and two boxes: 72 + 24 = 96 triangles, the most tested without a
        // tree; and 3 triangles, one partly filled block.
        let mut mesh = random_triangles(6, 72, Vec3::splat(-20.0), 8.0);
        let s = mesh.surface_id("a");
        mesh.push_box(Vec3::splat(-25.0), Vec3::splat(25.0), 1, s);
        mesh.push_box(Vec3::new(-3.0, -2.0, -1.0), Vec3::new(2.0, 1.0, 4.0), 1, s);
        assert_eq!(mesh.triangle_count(), FLAT_LIMIT);
        for mesh in [mesh, random_triangles(7, 3, Vec3::splat(-20.0), 30.0)] {
            let tree = MeshBvh::build_tree(&mesh, BuildQuality::default());
            let mut flat = MeshBvh::build(&mesh, BuildQuality::default());
            assert!(flat.flat.is_some() && tree.flat.is_none());
            for variant in Traverser::all_available(&flat.nodes) {
                flat.traverser = variant;
                compare(&tree, &flat);
                // Rays at points just inside every corner and edge midpoint, on or near the
                // blocks' boxes.
                let mut r = stream(6, 9, 0);
                let mut blocked = 0;
                for i in 0..mesh.triangle_count() {
                    let [a, b, c] = mesh.corners(i);
                    let at = |u: f32, v: f32| a * (1.0 - u - v) + b * u + c * v;
                    let (e, h) = (1.0e-5, 0.5 - 1.0e-5);
                    for target in
                        [at(e, e), at(1.0 - 2.0 * e, e), at(e, 1.0 - 2.0 * e), at(h, e), at(e, h), at(h, h)]
                    {
                        let o = Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 40.0 - 20.0;
                        let ray = Ray::new(o, (target - o).normalize());
                        assert_eq!(
                            flat.closest_triangle(&ray).map(|h| h.1),
                            tree.closest_triangle(&ray).map(|h| h.1)
                        );
                        let segment = Ray::segment(o, ray.dir, (target - o).length() * 1.001);
                        assert_eq!(flat.occluded(&segment), tree.occluded(&segment), "triangle {i}");
                        blocked += usize::from(tree.occluded(&segment));
                    }
                }
                assert!(blocked > 6 * mesh.triangle_count() * 9 / 10, "{blocked} blocked");
            }
        }
        // No triangles at all.
        let empty = MeshBvh::build(&TriangleMesh::default(), BuildQuality::default());
        let ray = Ray::new(Vec3::ZERO, Vec3::X);
        assert!(empty.closest_hit(&ray).is_none() && !empty.occluded(&ray));
    }

    #[test]
    fn parallel_collapse_matches_obvhs() {
        use obvhs::ploc::PlocBuilder;
        let mesh = random_triangles(5, 20_000, Vec3::ZERO, 1.0);
        let bounds = triangle_bounds(&mesh);
        for quality in BuildQuality::ALL {
            let p = quality.params();
            let n = bounds.len() as u32;
            let mut bvh2 = PlocBuilder::with_capacity(bounds.len()).build(
                p.ploc_search_distance,
                &bounds,
                (0..n).collect(),
                p.sort_precision,
                p.search_depth_threshold,
            );
            ReinsertionOptimizer::default().run(&mut bvh2, p.reinsertion_batch_ratio, None);
            let reference = obvhs::cwbvh::bvh2_to_cwbvh::bvh2_to_cwbvh(&bvh2, 3, false, false);
            let (nodes, prims) = collapse::collapse(&bvh2, 3);
            assert!(nodes == reference.nodes, "{quality:?}: nodes differ");
            assert_eq!(prims, reference.primitive_indices, "{quality:?}");
        }
    }

    #[test]
    fn ploc_matches_obvhs() {
        use obvhs::ploc::PlocBuilder;
        // Random triangles (parallel and sequential neighbour searches), and a regular grid of
        // quads, whose costs tie everywhere.
        let mut grid = TriangleMesh::default();
        let s = grid.surface_id("a");
        for i in 0..100 {
            for j in 0..60 {
                let p = |di: i32, dj: i32| Vec3::new((i + di) as f32 * 0.5, (j + dj) as f32 * 0.5, 0.0);
                grid.push_triangle([p(0, 0), p(1, 0), p(1, 1)], s);
                grid.push_triangle([p(0, 0), p(1, 1), p(0, 1)], s);
            }
        }
        for mesh in
            [random_triangles(5, 20_000, Vec3::ZERO, 1.0), random_triangles(6, 3_000, Vec3::ZERO, 2.0), grid]
        {
            let bounds = triangle_bounds(&mesh);
            for quality in BuildQuality::ALL {
                let p = quality.params();
                let reference = PlocBuilder::with_capacity(bounds.len()).build(
                    p.ploc_search_distance,
                    &bounds,
                    (0..bounds.len() as u32).collect(),
                    p.sort_precision,
                    p.search_depth_threshold,
                );
                let (ours, guarded) = ploc::build(&bounds, &p);
                assert!(!guarded, "{quality:?}: an ordinary mesh needed the guard");
                assert_eq!(format!("{:?}", ours.nodes), format!("{:?}", reference.nodes), "{quality:?}");
                assert_eq!(ours.primitive_indices, reference.primitive_indices, "{quality:?}");
                assert_eq!(ours.max_depth, reference.max_depth, "{quality:?}");
            }
        }
    }

    /// `count` random triangles of surface "a", each within a cube of side `size` whose
    /// corner is uniform in the 40 m cube from `low`.
    fn random_triangles(seed: u64, count: usize, low: Vec3, size: f32) -> TriangleMesh {
        let mut mesh = TriangleMesh::default();
        let s = mesh.surface_id("a");
        let mut r = stream(seed, 0, 0);
        for _ in 0..count {
            let c = Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 40.0 + low;
            let mut corner = || c + Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * size;
            let tri = [corner(), corner(), corner()];
            mesh.push_triangle(tri, s);
        }
        mesh
    }

    fn compare(portable: &MeshBvh, simd: &MeshBvh) {
        // Streams and groups give every ray the answer of its single-ray query, for every
        // traversal.
        let mut rays: Vec<Ray> = (0..5_000u64)
            .map(|k| {
                let mut r = stream(4, 2, k);
                let o = Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 44.0 - 22.0;
                let d = uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
                Ray::segment(o, d, 5.0 + 40.0 * uniform(&mut r))
            })
            .collect();
        rays.truncate(rays.len() / GROUP_WIDTH * GROUP_WIDTH);
        let random = rays.len();
        // Camera rays, 64 x 64 pixels over 23 degrees from three eyes towards the centre: the
        // coherent groups; every third ray a segment that may end short of the hit.
        for (e, eye) in [Vec3::new(-30.0, -30.0, 25.0), Vec3::new(28.0, -5.0, 2.0), Vec3::new(0.5, 0.3, 0.2)]
            .into_iter()
            .enumerate()
        {
            let forward = (Vec3::new(-1.0, 2.0, 0.5) - eye).normalize();
            let right = forward.cross(Vec3::Z).normalize();
            let up = right.cross(forward);
            for k in 0..64 * 64 {
                let (i, j) = ((k % 64) as f32, (k / 64) as f32);
                let (u, v) = ((i + 0.5) / 32.0 - 1.0, (j + 0.5) / 32.0 - 1.0);
                let dir = (forward + 0.2 * (u * right + v * up)).normalize();
                let length = 10.0 + 30.0 * ((k * 7 + e) % 11) as f32 / 10.0;
                rays.push(if k % 3 == 0 { Ray::segment(eye, dir, length) } else { Ray::new(eye, dir) });
            }
        }
        let size_m = if portable.nodes.is_empty() { 50.0 } else { portable.size_m };
        let (grouped, alone) = split_coherent(&rays, size_m);
        assert!(grouped.iter().all(|&i| i as usize >= random) && grouped.len() == rays.len() - random);
        assert!(alone.iter().all(|&i| (i as usize) < random));
        for bvh in [portable, simd] {
            let mut hits = vec![None; rays.len()];
            bvh.closest_hits_into(&rays, &mut hits);
            // The same distance bit for bit; the triangle may differ only on an exact tie
            // (a ray through a shared edge), which streams and single rays may break apart.
            let mut ties = 0;
            for (i, ray) in rays.iter().enumerate() {
                let single = portable.closest_triangle(ray);
                assert_eq!(hits[i].map(|h| h.t), single.map(|h| h.1), "stream ray {i}");
                ties += usize::from(hits[i].map(|h| h.primitive) != single.map(|h| h.0));
            }
            assert!(ties <= rays.len() / 1000, "{ties} ties");
            // A batch whose last group is partly filled (77 = 2 x 32 + 13 camera rays).
            let part = &rays[random + 100..random + 177];
            let mut hits = vec![None; part.len()];
            bvh.closest_hits_into(part, &mut hits);
            for (i, ray) in part.iter().enumerate() {
                assert_eq!(hits[i].map(|h| h.t), portable.closest_triangle(ray).map(|h| h.1), "ray {i}");
            }
        }
        for k in 0..20_000u64 {
            let mut r = stream(4, 1, k);
            let o = Vec3::new(uniform(&mut r), uniform(&mut r), uniform(&mut r)) * 44.0 - 22.0;
            let mut d = uniform_sphere(Vec2::new(uniform(&mut r), uniform(&mut r)));
            if k % 7 == 0 {
                d = [Vec3::X, -Vec3::Y, -Vec3::Z][(k % 3) as usize];
            }
            let ray = Ray::segment(o, d, 5.0 + 40.0 * uniform(&mut r));
            assert_eq!(simd.closest_triangle(&ray), portable.closest_triangle(&ray), "ray {k}");
            assert_eq!(simd.occluded(&ray), portable.occluded(&ray), "ray {k}");
            assert_eq!(simd.occluded(&ray), simd.closest_triangle(&ray).is_some(), "ray {k}");
            let (mut a, mut b) = (Vec::new(), Vec::new());
            simd.for_each_hit(&ray, |h| a.push(h.primitive));
            portable.for_each_hit(&ray, |h| b.push(h.primitive));
            a.sort_unstable();
            b.sort_unstable();
            assert_eq!(a, b, "ray {k}");
        }
        // The queries compiled into a caller's loop answer as the methods do.
        struct Answers<'r>(&'r [Ray]);
        impl QueryLoop<Vec<(Option<(u32, f32)>, bool)>> for Answers<'_> {
            #[inline(always)]
            fn run<Q: Queries>(self, q: &Q) -> Vec<(Option<(u32, f32)>, bool)> {
                self.0.iter().map(|r| (q.closest(r, &FlatRay::new(r.origin, r.dir)), q.occluded(r))).collect()
            }
        }
        let rays = &rays[..2_000];
        for (i, (closest, occluded)) in simd.run_queries(Answers(rays)).into_iter().enumerate() {
            assert_eq!(closest, portable.closest_triangle(&rays[i]), "ray {i}");
            assert_eq!(occluded, portable.occluded(&rays[i]), "ray {i}");
        }
    }
}
