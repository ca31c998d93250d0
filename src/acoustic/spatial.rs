//! Ambisonic and binaural impulse responses from the directions of arrival
//! (docs/acoustics.md, Ambisonic and binaural responses).
//!
//! Both start from the octave-band parts of the mono response
//! ([`super::impulse_response::synthesize_bands`]), whose sum is the mono response. Each
//! band is cut into segments (the direct sound's bin, then [`segment_bins`] bins each), and
//! each segment is given one direction, drawn with probability proportional to energy from
//! what arrives in it: the image-source arrivals at their exact directions, and the rays'
//! energy (the histogram less the image sources) spread over the direction cells in the
//! shares the rays deposited there, at a uniformly random point of the cell. A segment is
//! then encoded as a plane wave from its direction: Ambisonic channel k is the band signal
//! times `Y_k` (ACN, SN3D), the ears get the spherical head's gain and delay. Neighbouring
//! segments cross-fade linearly over the first quarter of the later one. The directions of
//! one realisation match the directional energy in expectation over many segments, as the
//! mono response's Diracs match the histogram's energy.
//!
//! Since `Y_0 = 1`, the W channel is the mono response (to rounding in the cross-fades, where
//! the higher orders are scaled back to one plane wave's energy): its
//! energy per band is the mono response's, which is the histogram's.

use glam::{DVec3, Vec3};

use super::ambisonics::{channels, sh_sn3d};
use super::directions::{CELLS, DirectionBins, direction_in};
use super::hrtf::EarTable;
use super::image_source::Arrival;
use super::impulse_response::SAMPLE_RATE_HZ;
use crate::core::rng::{stream, uniform};
use crate::scene::materials::{BAND_COUNT, OCTAVE_BANDS_HZ};

/// The listener's head: the unit vectors it looks along (front), to its left and up; the
/// Ambisonic responses are in this frame (x front, y left, z up, as AmbiX has it) and the
/// ears are on its left-right axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Listener {
    /// Unit vector the listener faces (x of the frame).
    pub front: DVec3,
    /// Unit vector to the listener's left (y of the frame).
    pub left: DVec3,
    /// Unit vector up (z of the frame).
    pub up: DVec3,
}

impl Default for Listener {
    /// Looking along +x with +z up: the scene's own frame.
    fn default() -> Self {
        Self { front: DVec3::X, left: DVec3::Y, up: DVec3::Z }
    }
}

impl Listener {
    /// The head looking along `front` with `up` as near its top as `front` allows (Gram-
    /// Schmidt); an error if either is zero, not finite, or they are parallel.
    pub fn looking(front: [f32; 3], up: [f32; 3]) -> Result<Self, String> {
        let f = Vec3::from(front).as_dvec3();
        let u = Vec3::from(up).as_dvec3();
        let front_n = f
            .try_normalize()
            .ok_or_else(|| format!("view direction {}: must be non-zero", crate::io::point(front)))?;
        let up_n = (u - front_n * u.dot(front_n)).try_normalize().ok_or_else(|| {
            format!(
                "up {}: must be non-zero and not along the view direction {}",
                crate::io::point(up),
                crate::io::point(front)
            )
        })?;
        Ok(Self { front: front_n, left: up_n.cross(front_n), up: up_n })
    }

    /// The scene direction `d` in the head's frame.
    pub fn to_head(&self, d: DVec3) -> DVec3 {
        DVec3::new(d.dot(self.front), d.dot(self.left), d.dot(self.up))
    }
}

/// What one source-receiver pair gives the spatial responses.
#[derive(Clone, Copy, Debug)]
pub struct PairDirections<'a> {
    /// Energy per bin and band, the image sources included.
    pub histogram: &'a [[f64; BAND_COUNT]],
    /// Histogram bin width, seconds.
    pub bin_s: f64,
    /// The rays' energy per direction bin, cell and band (index `bin * CELLS + cell`).
    pub directions: &'a [[f64; BAND_COUNT]],
    /// The direction bins in histogram bins.
    pub direction_bins: DirectionBins,
    /// The image-source arrivals with their exact directions.
    pub image_sources: &'a [Arrival],
    /// Speed of sound, m/s.
    pub speed_m_s: f64,
}

/// Bins per segment of band `b` after the direct sound's: about two periods of the band's
/// centre frequency, at least one bin (32 ms at 63 Hz, 1 ms from 2 kHz up with 1 ms bins).
/// A direction cannot change faster than the band's own signal without spreading it out of
/// the band.
pub fn segment_bins(b: usize, bin_s: f64) -> usize {
    ((2.0 / f64::from(OCTAVE_BANDS_HZ[b]) / bin_s).round() as usize).max(1)
}

/// The segments of band `b` (sample ranges) and the unit direction of each, in the scene's
/// frame, for the band signal of `samples` samples; drawn from `seed`.
pub fn segment_directions(
    p: &PairDirections,
    b: usize,
    samples: usize,
    seed: u64,
) -> Vec<(usize, usize, DVec3)> {
    let fs = f64::from(SAMPLE_RATE_HZ);
    let per_bin = (p.bin_s * fs).round().max(1.0) as usize;
    let bins = p.histogram.len();
    let Some(onset) = p.histogram.iter().position(|h| h.iter().any(|&e| e > 0.0)) else {
        return Vec::new();
    };
    // Image-source energy per bin of this band, and the arrivals by bin.
    let bin_of = |a: &Arrival| (a.length_m / p.speed_m_s / p.bin_s) as usize;
    let mut ism = vec![0.0f64; bins];
    for a in p.image_sources {
        if let Some(e) = ism.get_mut(bin_of(a)) {
            *e += a.energy[b];
        }
    }
    let mut rng = stream(seed, 0x05ba_71a1, b as u64);
    let mut out = Vec::new();
    let mut k0 = onset;
    let mut previous = DVec3::X;
    let len = segment_bins(b, p.bin_s);
    while k0 < bins {
        let k1 = if k0 == onset { k0 + 1 } else { (k0 + len).min(bins) };
        // Candidates: the arrivals, and the cells with the rays' energy.
        let mut weights: Vec<(f64, Option<DVec3>, usize)> = p
            .image_sources
            .iter()
            .filter(|a| (k0..k1).contains(&bin_of(a)) && a.energy[b] > 0.0)
            .map(|a| (a.energy[b], Some(DVec3::from(a.incoming)), 0))
            .collect();
        let mut cells = [0.0f64; CELLS];
        let mut shares = [0.0f64; CELLS];
        for (k, ism_k) in ism.iter().enumerate().take(k1).skip(k0) {
            let rays = (p.histogram[k][b] - ism_k).max(0.0);
            if rays <= 0.0 {
                continue;
            }
            let db = p.direction_bins.of(k);
            for (c, s) in shares.iter_mut().enumerate() {
                *s = p.directions.get(db * CELLS + c).map_or(0.0, |e| e[b].max(0.0));
            }
            let total: f64 = shares.iter().sum();
            for (c, s) in cells.iter_mut().zip(&shares) {
                // No directional record there: the energy is taken as diffuse.
                *c += rays * if total > 0.0 { s / total } else { 1.0 / CELLS as f64 };
            }
        }
        weights.extend(cells.iter().enumerate().filter(|(_, e)| **e > 0.0).map(|(c, e)| (*e, None, c)));
        let total: f64 = weights.iter().map(|w| w.0).sum();
        let dir = if total > 0.0 {
            let mut pick = f64::from(uniform(&mut rng)) * total;
            let chosen = weights.iter().find(|w| {
                pick -= w.0;
                pick < 0.0
            });
            let (_, exact, cell) = *chosen.unwrap_or(&weights[weights.len() - 1]);
            let (fu, fv) = (uniform(&mut rng), uniform(&mut rng));
            exact.unwrap_or_else(|| direction_in(cell, fu, fv).as_dvec3())
        } else {
            previous
        };
        previous = dir;
        out.push((k0 * per_bin, (k1 * per_bin).min(samples), dir));
        k0 = k1;
    }
    out
}

/// The cross-fade weight of the later segment at sample `n` of a segment starting at
/// `start` and `len` samples long: 0 to 1 over its first quarter.
#[inline]
fn fade_in(n: usize, start: usize, len: usize) -> f64 {
    let fade = (len / 4).max(1);
    ((n - start) as f64 / fade as f64).min(1.0)
}

/// Scales each order `n >= 1` of the SN3D gains `mix` (ACN order) to unit norm: a plane
/// wave's gains have `sum_m Y_nm^2 = P_n(1) = 1` in every order (the addition theorem), so a
/// cross-fade between two directions, whose linear mix is shorter, keeps each order's energy
/// (the omnidirectional W stays the plain linear mix, 1). A mix that nearly vanishes (two
/// opposite directions half-way) is left as it is.
fn keep_order_energy(mix: &mut [f64], order: usize) {
    for n in 1..=order {
        let Some(block) = mix.get_mut(n * n..(n + 1) * (n + 1)) else { return };
        let norm = block.iter().map(|x| x * x).sum::<f64>().sqrt();
        if norm > 1.0e-3 {
            block.iter_mut().for_each(|x| *x /= norm);
        }
    }
}

/// The Ambisonic response of order `order` (1 to 3): `channels(order)` signals in ACN order,
/// SN3D, in the listener's frame, from the band signals `bands` (their sum is the mono
/// response).
pub fn ambisonic(
    p: &PairDirections,
    bands: &[Vec<f64>],
    order: usize,
    listener: &Listener,
    seed: u64,
) -> Vec<Vec<f32>> {
    let samples = bands.first().map_or(0, Vec::len);
    let n_ch = channels(order);
    let mut out = vec![vec![0.0f64; samples]; n_ch];
    for (b, band) in bands.iter().enumerate().take(BAND_COUNT) {
        let segments = segment_directions(p, b, samples, seed);
        let mut previous: Option<Vec<f64>> = None;
        for (start, end, dir) in segments {
            let gains = sh_sn3d(listener.to_head(dir), order);
            let before = previous.clone().unwrap_or_else(|| gains.clone());
            // The cross-fade, then the steady part channel by channel (a contiguous loop the
            // compiler vectorises).
            let fade_end = (start + ((end - start) / 4).max(1)).min(end);
            let mut mix = vec![0.0; n_ch];
            for (n, &v) in band.iter().enumerate().take(fade_end).skip(start) {
                let w = fade_in(n, start, end - start);
                for (m, (a, b)) in mix.iter_mut().zip(before.iter().zip(&gains)) {
                    *m = (1.0 - w) * a + w * b;
                }
                keep_order_energy(&mut mix, order);
                for (ch, &m) in out.iter_mut().zip(&mix) {
                    ch[n] += v * m;
                }
            }
            for (ch, &g) in out.iter_mut().zip(&gains) {
                for (o, &v) in ch[fade_end..end].iter_mut().zip(&band[fade_end..end]) {
                    *o += v * g;
                }
            }
            previous = Some(gains);
        }
    }
    out.into_iter().map(|c| c.into_iter().map(|v| v as f32).collect()).collect()
}

/// Head radius of the spherical-head model, m (Duda and Martens 1998).
pub const HEAD_RADIUS_M: f64 = 0.0875;

/// The spherical head's ear response to a plane wave whose direction makes the angle `theta`
/// (radians, 0 to pi) with the ear's axis (Duda and Martens 1998; docs/acoustics.md,
/// Binaural): the head-shadow filter's magnitude at `f_hz`,
/// `|1 + i alpha w / (2 w0)| / |1 + i w / (2 w0)|`, `w0 = c / a`,
/// `alpha(theta) = (1 + alpha_min / 2) + (1 - alpha_min / 2) cos(theta / theta_min pi)`,
/// alpha_min = 0.1, theta_min = 150 degrees; and the delay, s, of the Woodworth-style
/// formula `-(a / c) cos theta` below pi / 2 and `(a / c)(theta - pi / 2)` above, plus `a / c`
/// (so that it is never negative).
pub fn head_ear(theta: f64, f_hz: f64, speed_m_s: f64) -> (f64, f64) {
    let theta = theta.clamp(0.0, std::f64::consts::PI);
    let (alpha_min, theta_min) = (0.1, 150f64.to_radians());
    let alpha =
        (1.0 + alpha_min / 2.0) + (1.0 - alpha_min / 2.0) * (theta / theta_min * std::f64::consts::PI).cos();
    let w0 = speed_m_s / HEAD_RADIUS_M;
    let x = 2.0 * std::f64::consts::PI * f_hz / (2.0 * w0);
    let gain = ((1.0 + (alpha * x).powi(2)) / (1.0 + x * x)).sqrt();
    let a_c = HEAD_RADIUS_M / speed_m_s;
    let delay = if theta < std::f64::consts::FRAC_PI_2 {
        -a_c * theta.cos()
    } else {
        a_c * (theta - std::f64::consts::FRAC_PI_2)
    };
    (gain, delay + a_c)
}

/// The head of the binaural response.
#[derive(Clone, Copy, Debug)]
pub enum Head<'a> {
    /// The built-in spherical head ([`head_ear`]).
    Sphere,
    /// A measured head from a SOFA file: per band gains and delays ([`EarTable`]).
    Measured(&'a EarTable),
}

/// Adds `v` at the fractional sample position `x` of `out` (linear interpolation, split
/// between the two neighbouring samples; nothing outside).
#[inline]
fn splat(out: &mut [f64], x: f64, v: f64) {
    let i = x.floor() as usize;
    let f = x - i as f64;
    if let Some(o) = out.get_mut(i) {
        *o += (1.0 - f) * v;
    }
    if let Some(o) = out.get_mut(i + 1) {
        *o += f * v;
    }
}

/// The binaural response (left, right) of the spherical head ([`head_ear`]) in the
/// listener's frame, from the band signals `bands`: each segment's part of each band
/// reaches each ear delayed and scaled by the head's response at the band's centre
/// frequency in the segment's direction (during a cross-fade, the sample is shared between
/// the two segments' delays and gains).
pub fn binaural(
    p: &PairDirections,
    bands: &[Vec<f64>],
    listener: &Listener,
    head: &Head,
    seed: u64,
) -> [Vec<f32>; 2] {
    let samples = bands.first().map_or(0, Vec::len);
    let fs = f64::from(SAMPLE_RATE_HZ);
    let mut ears = [vec![0.0f64; samples], vec![0.0f64; samples]];
    for (b, band) in bands.iter().enumerate().take(BAND_COUNT) {
        let f_hz = f64::from(OCTAVE_BANDS_HZ[b]);
        let segments = segment_directions(p, b, samples, seed);
        let mut previous: Option<[(f64, f64); 2]> = None;
        for (start, end, dir) in segments {
            let d = listener.to_head(dir);
            // Left ear on +y, right ear on -y: (gain, delay in samples).
            let ear = |axis: DVec3| {
                let (g, t) = head_ear(d.dot(axis).clamp(-1.0, 1.0).acos(), f_hz, p.speed_m_s);
                (g, t * fs)
            };
            let now = match head {
                Head::Sphere => [ear(DVec3::Y), ear(-DVec3::Y)],
                Head::Measured(table) => table.ears(d, b),
            };
            let before = previous.unwrap_or(now);
            for (m, &v) in band.iter().enumerate().take(end).skip(start) {
                let w = fade_in(m, start, end - start);
                for (e, out) in ears.iter_mut().enumerate() {
                    let ((g0, t0), (g1, t1)) = (before[e], now[e]);
                    if w < 1.0 {
                        splat(out, m as f64 + t0, (1.0 - w) * g0 * v);
                    }
                    splat(out, m as f64 + t1, w * g1 * v);
                }
            }
            previous = Some(now);
        }
    }
    ears.map(|c| c.into_iter().map(|v| v as f32).collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::acoustic::ambisonics::steer_peak;
    use crate::acoustic::impulse_response::{band_energies, synthesize, synthesize_bands};

    /// A direct sound at 20 ms from `from` (unit) and nothing else: the histogram and the
    /// image-source list of a free field.
    fn plane_wave(from: DVec3) -> (Vec<[f64; BAND_COUNT]>, Vec<Arrival>) {
        let c = 343.0;
        let length_m = 0.0205 * c;
        let mut hist = vec![[0.0; BAND_COUNT]; 200];
        hist[20] = [1e-3; BAND_COUNT];
        let arrival = Arrival {
            length_m,
            order: 0,
            energy: [1e-3; BAND_COUNT],
            emitted: (-from).to_array(),
            incoming: from.to_array(),
            diffracted: false,
        };
        (hist, vec![arrival])
    }

    fn pair<'a>(hist: &'a [[f64; BAND_COUNT]], arrivals: &'a [Arrival]) -> PairDirections<'a> {
        PairDirections {
            histogram: hist,
            bin_s: 1e-3,
            directions: &[],
            direction_bins: DirectionBins { fine: 10, early: 20, coarse: 100 },
            image_sources: arrivals,
            speed_m_s: 343.0,
        }
    }

    fn dir(az_deg: f64, el_deg: f64) -> DVec3 {
        let (az, el) = (az_deg.to_radians(), el_deg.to_radians());
        DVec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
    }

    #[test]
    fn a_plane_wave_encoded_decodes_to_its_direction() {
        // Steering a beam over the channels at the W channel's peak finds the arrival's
        // direction within 2 degrees, for orders 1 to 3; and in a turned head's frame the
        // direction turns with it.
        for (a, e) in [(0.0, 0.0), (65.0, 20.0), (-150.0, -40.0)] {
            let u = dir(a, e);
            let (hist, arrivals) = plane_wave(u);
            let p = pair(&hist, &arrivals);
            let bands = synthesize_bands(&hist, 1e-3, 100.0, 343.0, 7);
            for order in 1..=3 {
                let amb = ambisonic(&p, &bands, order, &Listener::default(), 3);
                let peak =
                    (0..amb[0].len()).max_by(|&i, &j| amb[0][i].abs().total_cmp(&amb[0][j].abs())).unwrap();
                let snapshot: Vec<f64> = amb.iter().map(|ch| f64::from(ch[peak])).collect();
                let found = steer_peak(&snapshot);
                let err = found.dot(u).clamp(-1.0, 1.0).acos().to_degrees();
                assert!(err < 2.0, "order {order}, ({a}, {e}): {err} degrees off");
            }
            // Looking along +y (z up) the arrival from +y is straight ahead.
            let turned = Listener::looking([0.0, 1.0, 0.0], [0.0, 0.0, 1.0]).unwrap();
            let amb = ambisonic(&p, &bands, 1, &turned, 3);
            let peak =
                (0..amb[0].len()).max_by(|&i, &j| amb[0][i].abs().total_cmp(&amb[0][j].abs())).unwrap();
            let found = steer_peak(&amb.iter().map(|ch| f64::from(ch[peak])).collect::<Vec<_>>());
            let want = turned.to_head(u);
            assert!(found.dot(want) > 2f64.to_radians().cos(), "turned head: {found} vs {want}");
        }
    }

    #[test]
    fn a_cross_fade_keeps_each_orders_energy_and_w() {
        // Half-way between two directions 120 degrees apart the linear mix of the first-order
        // gains has |c|^2 = 1/4 + 1/4 + 2/4 cos(120 deg) = 1/4 (-6 dB); after the scaling each
        // order has the energy of one plane wave again, 1, and W stays 1.
        let (a, b) = (sh_sn3d(dir(0.0, 0.0), 3), sh_sn3d(dir(120.0, 0.0), 3));
        let mut mix: Vec<f64> = a.iter().zip(&b).map(|(x, y)| 0.5 * x + 0.5 * y).collect();
        let first: f64 = mix[1..4].iter().map(|x| x * x).sum();
        assert!((first - 0.25).abs() < 1e-12, "{first}");
        keep_order_energy(&mut mix, 3);
        assert!((mix[0] - 1.0).abs() < 1e-12);
        for n in 1..=3 {
            let e: f64 = mix[n * n..(n + 1) * (n + 1)].iter().map(|x| x * x).sum();
            assert!((e - 1.0).abs() < 1e-12, "order {n}: {e}");
        }
        // The mix still points between the two: its first-order part decodes to 60 degrees.
        let (y, x) = (mix[1], mix[3]);
        assert!((y.atan2(x).to_degrees() - 60.0).abs() < 1e-9);
    }

    #[test]
    fn the_w_channel_carries_the_mono_energy_per_band() {
        // A direct sound and a diffuse tail whose rays came from two cells: W is the mono
        // response, so its band energies (the band split of impulse_response) equal the
        // mono response's to float rounding, 1e-5.
        let (mut hist, arrivals) = plane_wave(dir(30.0, 0.0));
        for (k, h) in hist.iter_mut().enumerate().skip(25) {
            *h = std::array::from_fn(|b| 1e-4 * (-(k as f64) / (30.0 + 5.0 * b as f64)).exp());
        }
        let mut directions = vec![[0.0; BAND_COUNT]; 20 * CELLS];
        for db in 2..20 {
            directions[db * CELLS + 4] = [1.0; BAND_COUNT];
            directions[db * CELLS + 30] = [0.5; BAND_COUNT];
        }
        let p = PairDirections { directions: &directions, ..pair(&hist, &arrivals) };
        let bands = synthesize_bands(&hist, 1e-3, 100.0, 343.0, 11);
        let mono = synthesize(&hist, 1e-3, 100.0, 343.0, 11);
        let amb = ambisonic(&p, &bands, 3, &Listener::default(), 5);
        let (em, ew) = (band_energies(&mono, 1e-3), band_energies(&amb[0], 1e-3));
        for b in 0..BAND_COUNT {
            let m: f64 = em.iter().map(|h| h[b]).sum();
            let w: f64 = ew.iter().map(|h| h[b]).sum();
            assert!((w / m - 1.0).abs() < 1e-5, "band {b}: W {w:e} vs mono {m:e}");
        }
    }

    #[test]
    fn interaural_time_difference_follows_woodworth() {
        // A plane wave from azimuth phi in the horizontal plane: the lag of the right ear's
        // response behind the left one's (cross-correlation peak, refined by a parabola)
        // is Woodworth's (a / c)(phi + sin phi) within 1.5 samples at 48 kHz.
        for phi_deg in [90.0, 45.0, 20.0] {
            let phi = f64::to_radians(phi_deg);
            let (hist, arrivals) = plane_wave(dir(phi_deg, 0.0));
            let p = pair(&hist, &arrivals);
            let bands = synthesize_bands(&hist, 1e-3, 100.0, 343.0, 13);
            let [l, r] = binaural(&p, &bands, &Listener::default(), &Head::Sphere, 1);
            let xcorr = |lag: i64| -> f64 {
                (0..l.len() as i64)
                    .filter_map(|n| {
                        let m = n + lag;
                        (m >= 0 && (m as usize) < r.len())
                            .then(|| f64::from(l[n as usize]) * f64::from(r[m as usize]))
                    })
                    .sum()
            };
            let (best, _) =
                (-60..=60).map(|lag| (lag, xcorr(lag))).max_by(|a, b| a.1.total_cmp(&b.1)).unwrap();
            let (y0, y1, y2) = (xcorr(best - 1), xcorr(best), xcorr(best + 1));
            let lag = best as f64 + 0.5 * (y0 - y2) / (y0 - 2.0 * y1 + y2);
            let want = HEAD_RADIUS_M / 343.0 * (phi + phi.sin()) * 48_000.0;
            assert!(
                (lag - want).abs() < 1.5,
                "{phi_deg} degrees: ITD {lag:.2} samples vs Woodworth {want:.2}"
            );
            // The far (right) ear is quieter at high frequencies: the head's shadow.
            let (el, er) = (band_energies(&l, 1e-3), band_energies(&r, 1e-3));
            let band = |h: &[[f64; BAND_COUNT]], b: usize| h.iter().map(|v| v[b]).sum::<f64>();
            assert!(band(&er, 6) < band(&el, 6));
        }
    }
}
