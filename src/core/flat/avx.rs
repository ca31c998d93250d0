//! [`super::FlatTriangles`]' tests in AVX: one 8-wide instruction per step of the portable
//! lane loops, in the same order (no fused multiply-add), so both give the same bits.

use std::arch::x86_64::*;

use glam::Vec2;

use super::{
    BlockHits, FlatRay, FlatTriangles, Kernel, LANES, Lanes, MAX_BLOCKS, any_with, closest_with,
    edge_functions_f64,
};

/// The 8-wide kernel. Every function here is `inline(always)` so that it ends up in the
/// `target_feature` functions below, where the intrinsics inline too.
struct Avx;

/// Loads a run of 8 floats of a block.
///
/// # Safety
/// The CPU must have AVX, and `lanes` must be 32-byte aligned (the runs of `Block` are: it is
/// `align(32)` and made of such runs).
#[inline(always)]
unsafe fn load(lanes: &Lanes) -> __m256 {
    // SAFETY: per the contract.
    unsafe { _mm256_load_ps(lanes.as_ptr()) }
}

/// Loads the boxes' run for blocks `8 g..8 g + 8`, `g` 0 or 1.
///
/// # Safety
/// The CPU must have AVX. (The runs are 32-byte aligned: `Boxes` is `align(64)` and its
/// rows are 16 floats.)
#[inline(always)]
unsafe fn load_half(row: &[f32; 2 * LANES], g: usize) -> __m256 {
    let half: &Lanes = if g == 0 { row.first_chunk() } else { row.last_chunk() }.unwrap_or(&[0.0; LANES]);
    // SAFETY: per the contract.
    unsafe { load(half) }
}

/// The 8 lanes of `x`.
///
/// # Safety
/// The CPU must have AVX.
#[inline(always)]
unsafe fn store(x: __m256) -> Lanes {
    let mut out = [0.0f32; LANES];
    // SAFETY: per the contract; `out` holds 8 floats and the store is unaligned.
    unsafe { _mm256_storeu_ps(out.as_mut_ptr(), x) };
    out
}

impl Kernel for Avx {
    #[inline(always)]
    fn boxes(flat: &FlatTriangles, g: usize, ray: &FlatRay, t_min: f32, t_max: f32) -> (u32, Lanes) {
        // SAFETY: `Avx` is only used inside the `target_feature(enable = "avx")` functions
        // below, entered after `is_x86_feature_detected!` confirmed AVX; the boxes are
        // 32-byte aligned.
        unsafe {
            let b = &flat.boxes.b;
            let [o, inv] = [ray.world_origin, ray.inv_dir];
            let mut near = [_mm256_setzero_ps(); 3];
            let mut far = [_mm256_setzero_ps(); 3];
            for k in 0..3 {
                let (o, inv) = (_mm256_set1_ps(o[k]), _mm256_set1_ps(inv[k]));
                let t0 = _mm256_mul_ps(_mm256_sub_ps(load_half(&b[k], g), o), inv);
                let t1 = _mm256_mul_ps(_mm256_sub_ps(load_half(&b[3 + k], g), o), inv);
                (near[k], far[k]) = (_mm256_min_ps(t0, t1), _mm256_max_ps(t0, t1));
            }
            let ([nx, ny, nz], [fx, fy, fz]) = (near, far);
            let near = _mm256_max_ps(_mm256_max_ps(nx, ny), _mm256_max_ps(nz, _mm256_set1_ps(t_min)));
            let far = _mm256_min_ps(_mm256_min_ps(fx, fy), _mm256_min_ps(fz, _mm256_set1_ps(t_max)));
            let hit = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(near, far)) as u32;
            (hit & flat.block_mask(g), store(near))
        }
    }

    #[inline(always)]
    fn block(flat: &FlatTriangles, b: usize, ray: &FlatRay, t_min: f32, t_max: f32) -> BlockHits {
        // SAFETY: as in `boxes`; blocks are 32-byte aligned.
        unsafe {
            let c = &flat.blocks[b].c;
            let [kx, ky, kz] = ray.axis.map(|k| k.min(2));
            let [ox, oy, oz] = ray.origin;
            let [ox, oy, oz] = [_mm256_set1_ps(ox), _mm256_set1_ps(oy), _mm256_set1_ps(oz)];
            let [sx, sy, sz] = ray.shear;
            let [sx, sy, sz] = [_mm256_set1_ps(sx), _mm256_set1_ps(sy), _mm256_set1_ps(sz)];
            let sub = |a, b| _mm256_sub_ps(a, b);
            let mul = |a, b| _mm256_mul_ps(a, b);
            let zero = _mm256_setzero_ps();
            let az = sub(load(&c[kz]), oz);
            let bz = sub(load(&c[3 + kz]), oz);
            let cz = sub(load(&c[6 + kz]), oz);
            let ax = sub(sub(load(&c[kx]), ox), mul(sx, az));
            let ay = sub(sub(load(&c[ky]), oy), mul(sy, az));
            let bx = sub(sub(load(&c[3 + kx]), ox), mul(sx, bz));
            let by = sub(sub(load(&c[3 + ky]), oy), mul(sy, bz));
            let cx = sub(sub(load(&c[6 + kx]), ox), mul(sx, cz));
            let cy = sub(sub(load(&c[6 + ky]), oy), mul(sy, cz));
            let mut u = sub(mul(cx, by), mul(cy, bx));
            let mut v = sub(mul(ax, cy), mul(ay, cx));
            let mut w = sub(mul(bx, ay), mul(by, ax));
            let occupied = flat.occupied[b];
            let eq0 = |x| _mm256_cmp_ps::<_CMP_EQ_OQ>(x, zero);
            let zeros =
                _mm256_movemask_ps(_mm256_or_ps(_mm256_or_ps(eq0(u), eq0(v)), eq0(w))) as u32 & occupied;
            if zeros != 0 {
                let [mut uu, mut vv, mut ww] = [store(u), store(v), store(w)];
                let corners = [store(ax), store(ay), store(bx), store(by), store(cx), store(cy)];
                let [a0, a1, a2, a3, a4, a5] = &corners;
                edge_functions_f64(zeros, [a0, a1, a2, a3, a4, a5], [&mut uu, &mut vv, &mut ww]);
                [u, v, w] = [uu, vv, ww].map(|x| _mm256_loadu_ps(x.as_ptr()));
            }
            let lt0 = |x| _mm256_cmp_ps::<_CMP_LT_OQ>(x, zero);
            let gt0 = |x| _mm256_cmp_ps::<_CMP_GT_OQ>(x, zero);
            let negative = _mm256_or_ps(_mm256_or_ps(lt0(u), lt0(v)), lt0(w));
            let positive = _mm256_or_ps(_mm256_or_ps(gt0(u), gt0(v)), gt0(w));
            let det = _mm256_add_ps(_mm256_add_ps(u, v), w);
            let inside =
                _mm256_andnot_ps(_mm256_and_ps(negative, positive), _mm256_cmp_ps::<_CMP_NEQ_UQ>(det, zero));
            let t_scaled =
                _mm256_add_ps(_mm256_add_ps(mul(u, mul(sz, az)), mul(v, mul(sz, bz))), mul(w, mul(sz, cz)));
            let inv_det = _mm256_div_ps(_mm256_set1_ps(1.0), det);
            let t = mul(t_scaled, inv_det);
            let in_range = _mm256_and_ps(
                _mm256_cmp_ps::<_CMP_GT_OQ>(t, _mm256_set1_ps(t_min)),
                _mm256_cmp_ps::<_CMP_LE_OQ>(t, _mm256_set1_ps(t_max)),
            );
            let hits = _mm256_movemask_ps(_mm256_and_ps(inside, in_range)) as u32 & occupied;
            if hits == 0 {
                return (0, [[0.0; LANES]; 3]);
            }
            (hits, [store(t), store(mul(v, inv_det)), store(mul(w, inv_det))])
        }
    }
}

/// The AVX kernel with all 16 block boxes in one AVX-512 test, the same operations in the
/// same order as [`Avx::boxes`], so the same bits.
struct Avx512;

impl Kernel for Avx512 {
    #[inline(always)]
    fn boxes(flat: &FlatTriangles, g: usize, ray: &FlatRay, t_min: f32, t_max: f32) -> (u32, Lanes) {
        Avx::boxes(flat, g, ray, t_min, t_max)
    }

    #[inline(always)]
    fn block(flat: &FlatTriangles, b: usize, ray: &FlatRay, t_min: f32, t_max: f32) -> BlockHits {
        Avx::block(flat, b, ray, t_min, t_max)
    }

    #[inline(always)]
    fn entered(flat: &FlatTriangles, ray: &FlatRay, t_min: f32, t_max: f32) -> (u32, [f32; MAX_BLOCKS]) {
        // SAFETY: `Avx512` is only used inside the `target_feature(enable = "avx512f")`
        // functions below, entered after `is_x86_feature_detected!` confirmed AVX-512F; the
        // rows of the boxes are 64 bytes long and 64-byte aligned.
        unsafe {
            let b = &flat.boxes.b;
            let [o, inv] = [ray.world_origin, ray.inv_dir];
            let mut near = [_mm512_setzero_ps(); 3];
            let mut far = [_mm512_setzero_ps(); 3];
            for k in 0..3 {
                let (o, inv) = (_mm512_set1_ps(o[k]), _mm512_set1_ps(inv[k]));
                let t0 = _mm512_mul_ps(_mm512_sub_ps(_mm512_load_ps(b[k].as_ptr()), o), inv);
                let t1 = _mm512_mul_ps(_mm512_sub_ps(_mm512_load_ps(b[3 + k].as_ptr()), o), inv);
                (near[k], far[k]) = (_mm512_min_ps(t0, t1), _mm512_max_ps(t0, t1));
            }
            let ([nx, ny, nz], [fx, fy, fz]) = (near, far);
            let near = _mm512_max_ps(_mm512_max_ps(nx, ny), _mm512_max_ps(nz, _mm512_set1_ps(t_min)));
            let far = _mm512_min_ps(_mm512_min_ps(fx, fy), _mm512_min_ps(fz, _mm512_set1_ps(t_max)));
            let hit = u32::from(_mm512_cmp_ps_mask::<_CMP_LE_OQ>(near, far));
            let mut out = [0.0f32; MAX_BLOCKS];
            _mm512_storeu_ps(out.as_mut_ptr(), near);
            (hit & flat.blocks_mask(), out)
        }
    }
}

/// [`FlatTriangles::closest`] in AVX.
#[target_feature(enable = "avx")]
pub fn closest(flat: &FlatTriangles, ray: &FlatRay, t_min: f32, t_max: f32) -> Option<(u32, f32, Vec2)> {
    closest_with::<Avx>(flat, ray, t_min, t_max)
}

/// [`FlatTriangles::any`] in AVX.
#[target_feature(enable = "avx")]
pub fn any(flat: &FlatTriangles, ray: &FlatRay, t_min: f32, t_max: f32) -> bool {
    any_with::<Avx>(flat, ray, t_min, t_max)
}

/// [`FlatTriangles::closest`] in AVX with AVX-512's box test.
#[target_feature(enable = "avx512f")]
pub fn closest512(flat: &FlatTriangles, ray: &FlatRay, t_min: f32, t_max: f32) -> Option<(u32, f32, Vec2)> {
    closest_with::<Avx512>(flat, ray, t_min, t_max)
}

/// [`FlatTriangles::any`] in AVX with AVX-512's box test.
#[target_feature(enable = "avx512f")]
pub fn any512(flat: &FlatTriangles, ray: &FlatRay, t_min: f32, t_max: f32) -> bool {
    any_with::<Avx512>(flat, ray, t_min, t_max)
}

/// [`closest`] inlined into the caller, with AVX-512's box test when `WIDE`.
///
/// # Safety
/// Only from a function compiled with AVX (`target_feature`), and AVX-512F when `WIDE`, on a
/// CPU that has them.
#[inline(always)]
pub(crate) unsafe fn closest_inlined<const WIDE: bool>(
    flat: &FlatTriangles,
    ray: &FlatRay,
    t_min: f32,
    t_max: f32,
) -> Option<(u32, f32, Vec2)> {
    if WIDE {
        closest_with::<Avx512>(flat, ray, t_min, t_max)
    } else {
        closest_with::<Avx>(flat, ray, t_min, t_max)
    }
}

/// [`any`] inlined into the caller, with AVX-512's box test when `WIDE`.
///
/// # Safety
/// As for [`closest_inlined`].
#[inline(always)]
pub(crate) unsafe fn any_inlined<const WIDE: bool>(
    flat: &FlatTriangles,
    ray: &FlatRay,
    t_min: f32,
    t_max: f32,
) -> bool {
    if WIDE { any_with::<Avx512>(flat, ray, t_min, t_max) } else { any_with::<Avx>(flat, ray, t_min, t_max) }
}
