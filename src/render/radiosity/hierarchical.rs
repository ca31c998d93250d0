//! Linking elements: hierarchical radiosity (Hanrahan, Salzman and Aupperle 1991) with BF
//! refinement, and the classical full matrix (every pair of finest patches) for comparison.
//!
//! Hierarchical: every pair of roots is linked through `refine`: a link `p <- q` is split
//! while the radiance it would carry, estimated by the oracle
//! `rho_p · sum_ab F_ab(p -> q) · B_q,b` (luminances; `F` the unoccluded point form factor,
//! the largest over four points of `p`; `B_q` the source's current radiance), exceeds the
//! threshold `eps · L_ref` (`L_ref` the scene's mean radiance, [`super::reference_radiance`]) and an element is still larger
//! than the finest patch area. The element that looks larger from the other (the larger of
//! `F_pq` and `F_qp`) is split, and the link becomes four links at the children's level.
//! Once linked, the form factor is estimated by ray casting ([`super::form_factor`]).
//! After each solution the links are tested again with the new radiances (BF refinement,
//! Hanrahan et al. 1991 sec. 4.2), until none splits or [`MAX_ROUNDS`] have passed.

use rayon::prelude::*;

use super::form_factor::{Tri, estimate, from_point};
use super::patches::{Hierarchy, Link, NONE};
use crate::core::Accel;
use crate::core::rng::stream;
use crate::render::film::luminance;

/// Random-stream domain of the form factors (one stream per receiver-source pair).
pub const FORM_FACTOR_DOMAIN: u64 = 0x5241_4449; // "RADI"
/// Most rounds of solution and BF refinement.
pub const MAX_ROUNDS: usize = 8;

/// How the links are made and estimated.
#[derive(Clone, Copy, Debug)]
pub struct LinkSettings {
    /// Elements no larger than this are not split, m^2.
    pub min_area_m2: f32,
    /// Refinement threshold, radiance (luminance) a link may carry unsplit.
    pub threshold: f32,
    /// Receiver points per form factor.
    pub samples: u32,
    /// Seed of the form factors' random streams.
    pub seed: u64,
}

/// The largest unoccluded point form factor from `p` to `q`, per side pair, over `p`'s
/// centroid and the three points halfway from it to the corners.
fn oracle_f(p: &Tri, q: &Tri) -> [[f32; 2]; 2] {
    let c = p.centroid();
    let mut best = from_point(p, c, q);
    for corner in p.corners {
        let f = from_point(p, 0.5 * (c + corner), q);
        for a in 0..2 {
            for b in 0..2 {
                best[a][b] = best[a][b].max(f[a][b]);
            }
        }
    }
    best
}

/// The oracle's radiance carried by link `p <- q`, and the total form factors both ways.
fn oracle(h: &Hierarchy, p: u32, q: u32) -> (f32, f32, f32) {
    let (ep, eq) = (&h.elements[p as usize], &h.elements[q as usize]);
    let fpq = oracle_f(&ep.tri, &eq.tri);
    let fqp = oracle_f(&eq.tri, &ep.tri);
    let b = eq.radiance.map(luminance);
    let carried =
        luminance(ep.material.rho) * (0..2).map(|a| fpq[a][0] * b[0] + fpq[a][1] * b[1]).sum::<f32>();
    let total = |f: [[f32; 2]; 2]| f.iter().flatten().sum::<f32>();
    (carried, total(fpq), total(fqp))
}

/// Links `p <- q`, splitting first as the oracle asks; new links go to `pending`.
fn refine(
    h: &mut Hierarchy,
    s: &LinkSettings,
    p: u32,
    q: u32,
    pending: &mut Vec<(u32, u32)>,
) -> Result<(), String> {
    let can_p = h.elements[p as usize].tri.area_m2 > s.min_area_m2;
    let can_q = h.elements[q as usize].tri.area_m2 > s.min_area_m2;
    if can_p || can_q {
        let (carried, fpq, fqp) = oracle(h, p, q);
        if carried > s.threshold {
            if can_q && (!can_p || fpq > fqp) {
                let c = h.split(q)?;
                for i in 0..4 {
                    refine(h, s, p, c + i, pending)?;
                }
            } else {
                let c = h.split(p)?;
                for i in 0..4 {
                    refine(h, s, c + i, q, pending)?;
                }
            }
            return Ok(());
        }
    }
    pending.push((p, q));
    Ok(())
}

/// Estimates the form factors of `pending` in parallel (each pair from its own random
/// stream, so the result does not depend on the threads) and adds the non-zero links.
/// Returns the rays cast.
fn estimate_links(h: &mut Hierarchy, accel: &Accel, s: &LinkSettings, pending: &[(u32, u32)]) -> u64 {
    let el = &h.elements;
    let found: Vec<([[f32; 2]; 2], u64)> = pending
        .par_iter()
        .with_min_len(64)
        .map(|&(p, q)| {
            let mut rng = stream(s.seed, FORM_FACTOR_DOMAIN, (u64::from(p) << 32) | u64::from(q));
            estimate(Some(accel), &el[p as usize].tri, &el[q as usize].tri, s.samples, &mut rng)
        })
        .collect();
    let mut rays = 0;
    for (&(p, q), (f, r)) in pending.iter().zip(found) {
        rays += r;
        if f.iter().flatten().any(|&v| v > 0.0) {
            h.elements[p as usize].links.push(Link { source: q, f });
        }
    }
    rays
}

/// The first linking of hierarchical radiosity: every pair of roots, refined by the oracle
/// with the emitted radiances. Returns the rays cast.
pub fn link_roots(h: &mut Hierarchy, accel: &Accel, s: &LinkSettings) -> Result<u64, String> {
    let roots = h.root_elements();
    let mut pending = Vec::new();
    for &p in &roots {
        for &q in &roots {
            if p != q {
                refine(h, s, p, q, &mut pending)?;
            }
        }
    }
    Ok(estimate_links(h, accel, s, &pending))
}

/// One round of BF refinement with the current radiances: every link the oracle finds too
/// strong is replaced by links at a finer level. Returns (links refined, rays cast).
pub fn refine_links(h: &mut Hierarchy, accel: &Accel, s: &LinkSettings) -> Result<(usize, u64), String> {
    let mut pending = Vec::new();
    let mut refined = 0;
    let count = h.elements.len() as u32;
    for p in 0..count {
        let links = std::mem::take(&mut h.elements[p as usize].links);
        let mut kept = Vec::with_capacity(links.len());
        let mut split = Vec::new();
        for l in links {
            let can = h.elements[p as usize].tri.area_m2 > s.min_area_m2
                || h.elements[l.source as usize].tri.area_m2 > s.min_area_m2;
            if can && oracle(h, p, l.source).0 > s.threshold {
                split.push(l.source);
            } else {
                kept.push(l);
            }
        }
        h.elements[p as usize].links = kept;
        refined += split.len();
        for q in split {
            refine(h, s, p, q, &mut pending)?;
        }
    }
    Ok((refined, estimate_links(h, accel, s, &pending)))
}

/// The classical method: every root split down to the finest patch area, then every pair of
/// leaves linked. Returns the rays cast.
pub fn link_matrix(h: &mut Hierarchy, accel: &Accel, s: &LinkSettings) -> Result<u64, String> {
    let mut stack = h.root_elements();
    let mut leaves = Vec::new();
    while let Some(e) = stack.pop() {
        if h.elements[e as usize].tri.area_m2 > s.min_area_m2 {
            let c = h.split(e)?;
            stack.extend((c..c + 4).rev());
        } else {
            leaves.push(e);
        }
    }
    leaves.sort_unstable();
    let pending: Vec<(u32, u32)> =
        leaves.iter().flat_map(|&p| leaves.iter().filter(move |&&q| q != p).map(move |&q| (p, q))).collect();
    Ok(estimate_links(h, accel, s, &pending))
}

/// Whether element `e` is a leaf.
pub fn is_leaf(h: &Hierarchy, e: u32) -> bool {
    h.elements[e as usize].children == NONE
}
