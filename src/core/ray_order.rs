//! Ray reordering for group traversal: coherent rays that arrive in scanline order (camera
//! rays, or the shadow rays of their hits) are regrouped into tiles. A run of
//! [`GROUP_WIDTH`] consecutive rays is a strip 32 pixels wide and one high; four strips
//! stacked in consecutive rows give four tiles of 8 x 4 pixels, and a tile's rays share more
//! of the tree walk than a strip's (ray reordering as in Pharr et al. 1997). The order
//! changes speed only: every ray still gets its single-ray answer.

use glam::Vec3;

use super::Ray;
use super::traverse::GROUP_WIDTH;

/// Rows of a tile: four strips give tiles of `GROUP_WIDTH / 4` = 8 x 4 rays.
const TILE_ROWS: usize = 4;

/// A run lies in the row under another when its first ray is nearer to the other's first ray
/// than this fraction of a run's length.
const NEIGHBOUR_FRACTION: f32 = 0.25;

/// Runs sampled for each candidate row stride.
const STRIDE_SAMPLES: usize = 32;

/// The ids of `grouped` (whole runs of [`GROUP_WIDTH`] consecutive rays, in increasing
/// order, as [`super::accel`]'s split makes them), reordered into 8 x 4 tiles when the runs
/// form rows of an image: when the run `stride` runs on is the one in the next row (found
/// by [`row_stride`]). Groups of [`GROUP_WIDTH`] consecutive ids of
/// the result are the tiles, and whole runs where a stack of four is incomplete (the last
/// rows of an image, or a run left out). Without rows, `grouped` is returned as it is.
pub(crate) fn order_in_tiles(rays: &[Ray], grouped: Vec<u32>, reach_m: f32) -> Vec<u32> {
    let full_runs = rays.len() / GROUP_WIDTH;
    let mut coherent = vec![false; full_runs];
    for &id in grouped.iter().step_by(GROUP_WIDTH) {
        if let Some(c) = coherent.get_mut(id as usize / GROUP_WIDTH) {
            *c = true;
        }
    }
    let Some(stride) = row_stride(rays, &coherent, reach_m) else { return grouped };
    let slice = GROUP_WIDTH / TILE_ROWS;
    let mut out = Vec::with_capacity(grouped.len());
    let run_ids = |run: usize| (run * GROUP_WIDTH) as u32..((run + 1) * GROUP_WIDTH) as u32;
    // Each coherent run in turn, unless an earlier stack took it: with the three below it,
    // as tiles, or alone. Stacks start wherever an image starts.
    let mut placed = vec![false; full_runs];
    for first in 0..full_runs {
        if placed[first] || !coherent[first] {
            continue;
        }
        let stack: [usize; TILE_ROWS] = std::array::from_fn(|row| first + row * stride);
        if stack.iter().all(|&run| run < full_runs && coherent[run] && !placed[run]) {
            for s in 0..TILE_ROWS {
                for &run in &stack {
                    out.extend(run_ids(run).skip(s * slice).take(slice));
                }
            }
            stack.iter().for_each(|&run| placed[run] = true);
        } else {
            out.extend(run_ids(first));
            placed[first] = true;
        }
    }
    // The batch's last, partial run, if coherent.
    out.extend(grouped.iter().filter(|&&id| id as usize >= full_runs * GROUP_WIDTH));
    out
}

/// The row length of the batch in runs: the stride `s` for which run `k + s` starts next to
/// run `k`, nearer than [`NEIGHBOUR_FRACTION`] of a run's mean length in the median over
/// sampled coherent runs (so that the seams between images do not count). The candidates are
/// the strides from three coherent runs to the runs that start nearest after them; the
/// smallest median wins, and `None` means no candidate passes. Rays are compared by the points
/// `origin + reach_m * dir`, so rays from one eye compare by direction and parallel rays by
/// origin.
fn row_stride(rays: &[Ray], coherent: &[bool], reach_m: f32) -> Option<usize> {
    let point = |i: usize| rays[i].origin + reach_m * rays[i].dir;
    let starts: Vec<Vec3> = (0..coherent.len()).map(|run| point(run * GROUP_WIDTH)).collect();
    let coherent_runs: Vec<usize> = (0..coherent.len()).filter(|&run| coherent[run]).collect();
    let length: f32 = coherent_runs
        .iter()
        .map(|&run| point(run * GROUP_WIDTH + GROUP_WIDTH - 1).distance(starts[run]))
        .sum();
    if !(length > 0.0 && length.is_finite()) {
        return None;
    }
    let limit = NEIGHBOUR_FRACTION * length / coherent_runs.len() as f32;
    let max_stride = coherent.len() / TILE_ROWS;
    let nearest_after = |k: usize| {
        (1..=max_stride.min(coherent.len() - 1 - k))
            .filter(|&s| coherent[k + s])
            .min_by(|&a, &b| starts[k].distance(starts[k + a]).total_cmp(&starts[k].distance(starts[k + b])))
    };
    let mut candidates: Vec<usize> = [1, 2, 3]
        .iter()
        .filter_map(|q| nearest_after(coherent_runs[q * (coherent_runs.len() - 1) / 4]))
        .collect();
    candidates.sort_unstable();
    candidates.dedup();
    let median_gap = |stride: usize| {
        let pairs = coherent.len() - stride;
        let step = pairs.div_ceil(STRIDE_SAMPLES).max(1);
        let mut gaps: Vec<f32> = (0..pairs)
            .step_by(step)
            .filter(|&k| coherent[k] && coherent[k + stride])
            .map(|k| starts[k].distance(starts[k + stride]))
            .collect();
        if gaps.is_empty() {
            return f32::INFINITY;
        }
        let middle = gaps.len() / 2;
        *gaps.select_nth_unstable_by(middle, f32::total_cmp).1
    };
    candidates
        .into_iter()
        .map(|stride| (stride, median_gap(stride)))
        .filter(|&(_, gap)| gap < limit)
        .min_by(|a, b| a.1.total_cmp(&b.1))
        .map(|(stride, _)| stride)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rays of a `w` x `h` pinhole image in scanline order.
    fn camera_rays(w: usize, h: usize) -> Vec<Ray> {
        let eye = Vec3::new(3.0, -2.0, 1.0);
        let forward = Vec3::new(0.3, 0.9, -0.3).normalize();
        let (right, up) = forward.any_orthonormal_pair();
        (0..w * h)
            .map(|k| {
                let (i, j) = ((k % w) as f32 - w as f32 / 2.0, (k / w) as f32 - h as f32 / 2.0);
                Ray::new(eye, (forward + 0.002 * (i * right + j * up)).normalize())
            })
            .collect()
    }

    /// The widest and tallest pixel span of a group of consecutive ids, in a `w`-wide image.
    fn group_spans(ids: &[u32], w: usize) -> (usize, usize) {
        ids.chunks(GROUP_WIDTH).fold((0, 0), |(cols, rows), g| {
            let (c, r) = g
                .iter()
                .map(|&k| (k as usize % w, k as usize / w))
                .fold(((usize::MAX, 0), (usize::MAX, 0)), |((c0, c1), (r0, r1)), (c, r)| {
                    ((c0.min(c), c1.max(c)), (r0.min(r), r1.max(r)))
                });
            (cols.max(c.1 - c.0 + 1), rows.max(r.1 - r.0 + 1))
        })
    }

    fn is_permutation(ids: &[u32], n: usize) -> bool {
        let mut sorted = ids.to_vec();
        sorted.sort_unstable();
        sorted.iter().copied().eq(0..n as u32)
    }

    #[test]
    fn scanline_images_regroup_into_8_by_4_tiles() {
        // A 4-row strip of 1024-pixel rows (one batch chunk of the benchmark), a 64 x 64
        // image, and an image one run wide: a run's group spans 32 x 1 pixels, a tile 8 x 4.
        for (w, h) in [(1024, 4), (64, 64), (32, 12)] {
            let rays = camera_rays(w, h);
            let ids: Vec<u32> = (0..rays.len() as u32).collect();
            assert_eq!(group_spans(&ids, w), (32, 1));
            let tiled = order_in_tiles(&rays, ids, 50.0);
            assert!(is_permutation(&tiled, rays.len()));
            assert_eq!(group_spans(&tiled, w), (8, 4), "{w} x {h}");
        }
    }

    #[test]
    fn incomplete_stacks_and_partial_runs_stay_whole() {
        // 64 x 6 pixels (two runs a row), run 2 incoherent (left out of `grouped`), and a
        // partial last run of 10 rays.
        let mut rays = camera_rays(64, 6);
        rays.extend(camera_rays(64, 6).into_iter().take(10));
        let grouped: Vec<u32> = (0..rays.len() as u32).filter(|&i| !(64..96).contains(&i)).collect();
        let tiled = order_in_tiles(&rays, grouped.clone(), 50.0);
        let mut expected = grouped.clone();
        expected.sort_unstable();
        let mut got = tiled.clone();
        got.sort_unstable();
        assert_eq!(got, expected, "the same ids");
        // Run 0 (its stack lacks run 2): whole; runs 1, 3, 5, 7: tiles; runs 4, 6, 8, 10:
        // tiles (a stack starts wherever four coherent runs line up).
        assert!(tiled[..32].iter().copied().eq(0..32));
        assert_eq!(group_spans(&tiled[32..32 + 256], 64), (8, 4));
        assert!(tiled[tiled.len() - 10..].iter().copied().eq(384..394), "partial run last");
    }

    #[test]
    fn rays_without_rows_keep_their_order() {
        // Random directions; a single row; all rays alike.
        let mut state = 7u32;
        let mut next = || {
            state = state.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (state >> 8) as f32 / (1 << 24) as f32 - 0.5
        };
        let random: Vec<Ray> =
            (0..1024).map(|_| Ray::new(Vec3::ZERO, Vec3::new(next(), next(), next()).normalize())).collect();
        let same = vec![Ray::new(Vec3::ONE, Vec3::X); 1024];
        for rays in [random, camera_rays(1024, 1), same] {
            let ids: Vec<u32> = (0..rays.len() as u32).collect();
            assert_eq!(order_in_tiles(&rays, ids.clone(), 50.0), ids);
        }
    }
}
