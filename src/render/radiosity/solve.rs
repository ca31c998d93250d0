//! The iterative solution of the radiosity system over the links: Jacobi iteration with
//! Hanrahan et al.'s gather and push-pull (1991, sec. 4.1).
//!
//! In radiance units (`B = pi L` for Lambert surfaces, the same equation), each sweep
//! 1. gathers, for every element `p` and side `a`, `G_p,a = sum_links sum_b F_ab B_q,b`;
//! 2. pushes the gathered light down to the leaves and pulls the radiance up: a leaf's
//!    radiance is `Le_p (front only) + rho_p (G_p + G of its ancestors)`, a parent's the
//!    area-weighted mean of its children's.
//!
//! Sweeps repeat until no element's radiance changes by more than the tolerance (absolute,
//! per channel). Each sweep reads the previous one's radiances only, so the elements gather in
//! parallel and the result does not depend on the threads.

use glam::Vec3;
use rayon::prelude::*;

use super::patches::{Hierarchy, NONE};

/// Most Jacobi sweeps before giving up: the error shrinks by at least the largest albedo per
/// sweep, so 0.99 needs ~900 sweeps for 1e-4.
pub const MAX_SWEEPS: u32 = 5000;

/// Solves for the radiances of `h` (starting from its current ones) to within `tolerance`
/// (absolute, radiance units). Returns the sweeps taken; an error when it does not converge.
pub fn solve(h: &mut Hierarchy, tolerance: f32) -> Result<u32, String> {
    let roots = h.root_elements();
    for sweep in 1..=MAX_SWEEPS {
        let el = &h.elements;
        let gathered: Vec<[Vec3; 2]> = el
            .par_iter()
            .with_min_len(256)
            .map(|e| {
                let mut g = [Vec3::ZERO; 2];
                for l in &e.links {
                    let b = el[l.source as usize].radiance;
                    for (a, ga) in g.iter_mut().enumerate() {
                        *ga += l.f[a][0] * b[0] + l.f[a][1] * b[1];
                    }
                }
                g
            })
            .collect();
        let mut fresh = vec![[Vec3::ZERO; 2]; el.len()];
        for &r in &roots {
            push_pull(h, &gathered, &mut fresh, r, [Vec3::ZERO; 2]);
        }
        let mut change = 0.0f32;
        for (e, new) in h.elements.iter_mut().zip(fresh) {
            for (n, old) in new.iter().zip(e.radiance) {
                change = change.max((*n - old).abs().max_element());
            }
            e.radiance = new;
        }
        if !change.is_finite() {
            return Err("radiosity: the solution diverged (a reflectance above 1?)".into());
        }
        if change <= tolerance {
            return Ok(sweep);
        }
    }
    Err(format!(
        "radiosity: no convergence to --radiosity-tolerance {tolerance} in {MAX_SWEEPS} sweeps \
         (a closed room with reflectances near 1?)"
    ))
}

/// Push-pull below element `e` with the light gathered by its ancestors `down`: writes the
/// new radiances of `e`'s subtree into `fresh` and returns `e`'s.
fn push_pull(
    h: &Hierarchy,
    gathered: &[[Vec3; 2]],
    fresh: &mut [[Vec3; 2]],
    e: u32,
    down: [Vec3; 2],
) -> [Vec3; 2] {
    let el = &h.elements[e as usize];
    let g = [gathered[e as usize][0] + down[0], gathered[e as usize][1] + down[1]];
    let b = if el.children == NONE {
        let m = el.material;
        [m.emission + m.rho * g[0], m.rho * g[1]]
    } else {
        // The four children have equal areas: the area-weighted mean is the plain mean.
        let mut sum = [Vec3::ZERO; 2];
        for c in el.children..el.children + 4 {
            let r = push_pull(h, gathered, fresh, c, g);
            sum[0] += r[0];
            sum[1] += r[1];
        }
        [sum[0] * 0.25, sum[1] * 0.25]
    };
    fresh[e as usize] = b;
    b
}
