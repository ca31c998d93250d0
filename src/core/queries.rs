//! A mesh's closest-hit and occlusion queries compiled into the caller's own loop.
//!
//! A query through [`MeshBvh`]'s methods is a call into a `target_feature` function, which
//! cannot be inlined into code built for the baseline instruction set: for the small meshes
//! of [`super::flat`], whose queries are short, the call, the dispatch on the instruction set
//! and the spills around it cost a good part of the query. [`MeshBvh::run_queries`] instead
//! compiles the caller's loop ([`QueryLoop::run`], which must be `#[inline(always)]`) once per
//! instruction set, with the queries inlined, and enters the best version once. The hits are
//! the same, bit for bit: the kernels are the same.

use super::flat::FlatRay;
#[cfg(target_arch = "x86_64")]
use super::flat::{FlatTriangles, avx};
#[cfg(target_arch = "x86_64")]
use super::traverse::Isa;
use super::{MeshBvh, Ray};

/// The queries a [`QueryLoop`] may make.
pub trait Queries {
    /// [`MeshBvh::closest_triangle_prepared`].
    fn closest(&self, ray: &Ray, flat_ray: &FlatRay) -> Option<(u32, f32)>;
    /// [`MeshBvh::occluded`].
    fn occluded(&self, ray: &Ray) -> bool;
}

/// A loop that makes queries: its `run` is compiled once per instruction set.
pub trait QueryLoop<R> {
    /// The loop. Mark it `#[inline(always)]`, and what it calls in its inner loop too, so that
    /// it is compiled into each instruction set's entry point.
    fn run<Q: Queries>(self, queries: &Q) -> R;
}

/// The queries through [`MeshBvh`]'s methods: trees, and CPUs without AVX.
struct Called<'m>(&'m MeshBvh);

impl Queries for Called<'_> {
    #[inline(always)]
    fn closest(&self, ray: &Ray, flat_ray: &FlatRay) -> Option<(u32, f32)> {
        self.0.closest_triangle_prepared(ray, flat_ray)
    }

    #[inline(always)]
    fn occluded(&self, ray: &Ray) -> bool {
        self.0.occluded(ray)
    }
}

/// A flat mesh's queries with AVX kernels inlined, the box test in AVX-512 when `WIDE`.
#[cfg(target_arch = "x86_64")]
struct Inlined<'m, const WIDE: bool> {
    flat: &'m FlatTriangles,
    mesh_index: &'m [u32],
}

#[cfg(target_arch = "x86_64")]
impl<const WIDE: bool> Queries for Inlined<'_, WIDE> {
    #[inline(always)]
    fn closest(&self, ray: &Ray, flat_ray: &FlatRay) -> Option<(u32, f32)> {
        // SAFETY: `Inlined` values are only made in the entry points below, compiled with
        // AVX (and AVX-512F when `WIDE`) and entered after the CPU was found to have them.
        let closest = unsafe { avx::closest_inlined::<WIDE>(self.flat, flat_ray, ray.t_min, ray.t_max) };
        closest.map(|(slot, t, _)| (self.mesh_index[slot as usize], t))
    }

    #[inline(always)]
    fn occluded(&self, ray: &Ray) -> bool {
        let flat_ray = FlatRay::new(ray.origin, ray.dir);
        // SAFETY: as in `closest`.
        unsafe { avx::any_inlined::<WIDE>(self.flat, &flat_ray, ray.t_min, ray.t_max) }
    }
}

impl MeshBvh {
    /// Runs `body` with this mesh's queries, compiled into it for the best instruction set
    /// the traversal may use.
    pub fn run_queries<R>(&self, body: impl QueryLoop<R>) -> R {
        #[cfg(target_arch = "x86_64")]
        if let Some((flat, mesh_index)) = self.flat_parts() {
            // SAFETY: the traversal picks a kernel only when the CPU has its instruction sets
            // (`is_x86_feature_detected!`), which the entry point's `target_feature` names.
            unsafe {
                match self.traverser().isa() {
                    Isa::Scalar => {}
                    Isa::Avx => return run_avx(Inlined::<false> { flat, mesh_index }, body),
                    Isa::Avx2 => return run_avx2(Inlined::<false> { flat, mesh_index }, body),
                    Isa::Avx512 => return run_avx512(Inlined::<true> { flat, mesh_index }, body),
                }
            }
        }
        body.run(&Called(self))
    }
}

/// `body` with AVX, FMA, SSE4.1 and POPCNT.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,fma,sse4.1,popcnt")]
fn run_avx<R>(queries: Inlined<'_, false>, body: impl QueryLoop<R>) -> R {
    body.run(&queries)
}

/// `body` with AVX2 and BMI1 as well.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma,bmi1,sse4.1,popcnt")]
fn run_avx2<R>(queries: Inlined<'_, false>, body: impl QueryLoop<R>) -> R {
    body.run(&queries)
}

/// `body` with AVX-512F as well.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,avx2,fma,bmi1,sse4.1,popcnt,avx512f")]
fn run_avx512<R>(queries: Inlined<'_, true>, body: impl QueryLoop<R>) -> R {
    body.run(&queries)
}
