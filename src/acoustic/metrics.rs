//! Room-acoustic parameters of ISO 3382-1:2009 from an energy histogram of one band:
//! the Schroeder decay curve (with Lundeby's truncation and late-decay compensation where the
//! histogram ends in a noise floor), EDT, T20, T30, C50, C80, D50, the centre time Ts and the
//! sound strength G, with the figures that say how far they can be trusted (dynamic range,
//! fit correlation, non-linearity and curvature, ISO 3382-2:2008 Annex B).

use serde::Serialize;

/// ISO 3382-1 parameters of one band, and their reliability figures. Times in seconds except
/// `ts_ms`. `None` where the histogram cannot give the value (silence, a decay too short).
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
pub struct BandMetrics {
    /// Early decay time: fit from 0 to -10 dB, times 6 (ISO 3382-1 A.2.2).
    pub edt_s: Option<f64>,
    /// Reverberation time from -5 to -25 dB, extrapolated to 60 dB.
    pub t20_s: Option<f64>,
    /// Reverberation time from -5 to -35 dB, extrapolated to 60 dB.
    pub t30_s: Option<f64>,
    /// Clarity, 50 ms boundary, dB (ISO 3382-1 eq. A.10).
    pub c50_db: Option<f64>,
    /// Clarity, 80 ms boundary, dB.
    pub c80_db: Option<f64>,
    /// Definition: early (0-50 ms) to total energy (ISO 3382-1 eq. A.11).
    pub d50: Option<f64>,
    /// Centre time, ms (ISO 3382-1 eq. A.12).
    pub ts_ms: Option<f64>,
    /// Sound strength G = 10 log10( sum_k e_k / (E / (4 pi 10^2)) ), dB: the total energy
    /// fluence re the fluence the same source (energy E) gives at 10 m in a free field
    /// (ISO 3382-1:2009 A.2.1). With a noise floor the total is the compensated one of the
    /// decay curve (noise removed, the decay extrapolated beyond the truncation point).
    pub g_db: Option<f64>,
    /// Where the Schroeder integration stops, s on the histogram's clock: the crossing point of
    /// the late decay with the noise floor found by Lundeby's method (Lundeby et al. 1995,
    /// Acta Acustica 81, 344-355). `None` when the decay shows no floor: the plain Schroeder
    /// integral to the end of the histogram.
    pub truncation_s: Option<f64>,
    /// Dynamic range of the decay, dB: from the highest bin (from the direct sound on) to the
    /// noise floor, or to the lowest 10 ms mean of the decay when it has no floor. ISO 3382-1:2009
    /// 5.3.2 asks the evaluation range to end 10 dB above the noise: T20 needs 35 dB, T30 45 dB.
    pub dynamic_range_db: Option<f64>,
    /// Correlation coefficient r of the T20 least-squares fit (negative for a decay;
    /// ISO 3382-2:2008 B.2).
    pub t20_r: Option<f64>,
    /// Correlation coefficient r of the T30 fit.
    pub t30_r: Option<f64>,
    /// Non-linearity of the T20 fit, xi = 1000 (1 - r^2), per mille (ISO 3382-2:2008 B.2;
    /// above 10 per mille the decay is not a straight line).
    pub t20_xi_permille: Option<f64>,
    /// Non-linearity of the T30 fit, per mille.
    pub t30_xi_permille: Option<f64>,
    /// Curvature C = 100 (T30 / T20 - 1), percent (ISO 3382-2:2008 B.3; 0-5 % is usual, above
    /// 10 % suggests a double-slope decay).
    pub curvature_percent: Option<f64>,
}

/// Schroeder backward integral in dB re the total, one value per bin start:
/// `edc[k] = 10 log10( sum_{j>=k} e[j] / sum_j e[j] )` (Schroeder 1965).
pub fn schroeder_db(energy: &[f64]) -> Vec<f64> {
    let total: f64 = energy.iter().sum();
    let mut out = vec![f64::NEG_INFINITY; energy.len()];
    if total <= 0.0 {
        return out;
    }
    let mut tail = 0.0;
    for k in (0..energy.len()).rev() {
        tail += energy[k];
        out[k] = 10.0 * (tail / total).log10();
    }
    out
}

/// `10 log10 x`, and minus infinity for `x <= 0` (and NaN).
fn db(x: f64) -> f64 {
    if x > 0.0 { 10.0 * x.log10() } else { f64::NEG_INFINITY }
}

/// A least-squares straight line `y = intercept + slope x` with its correlation coefficient.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Line {
    intercept: f64,
    slope: f64,
    /// Pearson correlation coefficient (`None` when y is constant).
    r: Option<f64>,
}

/// Least-squares line through the points with a finite `y`; `None` with fewer than two.
fn fit_line(points: impl Iterator<Item = (f64, f64)>) -> Option<Line> {
    let pts: Vec<(f64, f64)> = points.filter(|(x, y)| x.is_finite() && y.is_finite()).collect();
    if pts.len() < 2 {
        return None;
    }
    let n = pts.len() as f64;
    let (sx, sy) = pts.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (mx, my) = (sx / n, sy / n);
    let (sxy, sxx, syy) = pts.iter().fold((0.0, 0.0, 0.0), |(a, b, c), (x, y)| {
        (a + (x - mx) * (y - my), b + (x - mx) * (x - mx), c + (y - my) * (y - my))
    });
    if sxx <= 0.0 {
        return None;
    }
    let slope = sxy / sxx;
    let r = (syy > 0.0).then(|| (sxy / (sxx * syy).sqrt()).clamp(-1.0, 1.0));
    Some(Line { intercept: my - slope * mx, slope, r })
}

/// Least-squares line (dB against s) of the decay curve between `hi_db` and `lo_db` (e.g. -5
/// and -25), times `t_k = k * bin_s`; `None` when the curve never reaches `lo_db`.
fn decay_fit(edc_db: &[f64], bin_s: f64, hi_db: f64, lo_db: f64) -> Option<Line> {
    let start = edc_db.iter().position(|&v| v <= hi_db)?;
    let end = edc_db.iter().position(|&v| v <= lo_db)?;
    if end <= start + 1 {
        return None;
    }
    fit_line((start..=end).map(|k| (k as f64 * bin_s, edc_db[k])))
}

/// Decay time extrapolated to 60 dB from a fitted line, and the line's r.
fn decay_time(line: Option<Line>) -> (Option<f64>, Option<f64>) {
    match line {
        Some(l) if l.slope < 0.0 => (Some(-60.0 / l.slope), l.r),
        _ => (None, None),
    }
}

/// The first local averaging interval of Lundeby's method, s (the paper asks 10-50 ms).
const LUNDEBY_FIRST_INTERVAL_S: f64 = 0.010;
/// Averaging intervals per 10 dB of decay after the first regression (the paper: 3-10).
const LUNDEBY_INTERVALS_PER_10_DB: f64 = 5.0;
/// The late-decay regression ends this far above the noise (the paper: 5-10 dB) ...
const LUNDEBY_ABOVE_NOISE_DB: f64 = 10.0;
/// ... and spans this range (the paper: 10-20 dB).
const LUNDEBY_FIT_RANGE_DB: f64 = 20.0;
/// The noise segment starts this much decay after the crossing point (the paper: 5-10 dB).
const LUNDEBY_NOISE_AFTER_CROSSING_DB: f64 = 10.0;
/// Iterations of steps 7-9 at most (the paper finds 5 enough).
const LUNDEBY_MAX_ITERATIONS: usize = 10;
/// The noise segment counts as a floor when its mean lies this many times above the late
/// decay line's continuation over the same bins (3 dB). Over a genuine floor the ratio is at
/// least 3.2 (the segment starts 10 dB of decay past the crossing point, where the line is
/// 10 dB below the floor); over a decay that carries on to the end of the histogram it is 1.
const FLOOR_RATIO: f64 = 2.0;

/// What Lundeby's iteration (Lundeby, Vigran, Bietz and Vorlaender 1995, Acta Acustica 81,
/// 344-355, sec. 4) finds in an energy decay: the late decay line, the noise level and their
/// crossing point. Times count from the first bin of the slice given.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Lundeby {
    /// Crossing point of the late decay line with the noise level, s.
    pub crossing_s: f64,
    /// Mean energy per bin of the noise segment (from 10 dB of decay past the crossing point,
    /// or at least the last 10 % of the histogram, to the end).
    pub noise_per_bin: f64,
    /// First bin of the noise segment.
    pub noise_start: usize,
    /// The late decay line: energy per bin in dB = `intercept_db + slope_db_per_s * t`.
    pub intercept_db: f64,
    /// Slope of the late decay line, dB/s.
    pub slope_db_per_s: f64,
    /// Whether the noise segment is a floor: its mean is more than 3 dB above the decay line's
    /// continuation over the same bins. When it is not, the decay carries on to the end of
    /// the histogram and nothing needs truncating.
    pub floor: bool,
}

/// Mean energy per bin over consecutive intervals of `width` bins, as (centre time s, mean).
fn smooth(energy: &[f64], bin_s: f64, width: usize) -> Vec<(f64, f64)> {
    let width = width.max(1);
    energy
        .chunks(width)
        .enumerate()
        .map(|(i, c)| {
            let start = i * width;
            ((start as f64 + 0.5 * c.len() as f64) * bin_s, c.iter().sum::<f64>() / c.len() as f64)
        })
        .collect()
}

fn mean(x: &[f64]) -> f64 {
    if x.is_empty() { 0.0 } else { x.iter().sum::<f64>() / x.len() as f64 }
}

/// Index of the largest mean of a smoothed envelope.
fn peak_index(env: &[(f64, f64)]) -> usize {
    env.iter().enumerate().fold(0, |best, (i, &(_, m))| if m > env[best].1 { i } else { best })
}

/// Lundeby's iterative method on `energy` (energy per bin, bins of `bin_s`, from the direct
/// sound on): 1. average into 10 ms intervals; 2. noise = mean of the last 10 %; 3. regression
/// from the peak interval to the first interval within 10 dB of the noise; 4. crossing point
/// of that line with the noise; 5.-6. re-average in intervals of 1/5 of the time the line
/// takes to fall 10 dB; then repeat 7. noise from 10 dB of decay past the crossing point (at
/// least the last 10 %), 8. regression of the late decay from 30 to 10 dB above the noise,
/// 9. new crossing point, until it moves less than a bin. `None` when the histogram is too
/// short, ends in silence (no noise to find), or no decaying line fits.
pub fn lundeby(energy: &[f64], bin_s: f64) -> Option<Lundeby> {
    let n = energy.len();
    if n < 20 || !(bin_s > 0.0 && bin_s.is_finite()) {
        return None;
    }
    let max_width = (n / 10).max(1);
    let width = ((LUNDEBY_FIRST_INTERVAL_S / bin_s).round() as usize).clamp(1, max_width);
    let env = smooth(energy, bin_s, width);
    let peak = peak_index(&env);
    // 2. Noise from the last 10 %.
    let tail_start = n - (n / 10).max(1);
    let noise = mean(&energy[tail_start..]);
    if !(noise > 0.0 && noise.is_finite()) {
        return None;
    }
    // 3. Regression from the peak to the first interval within 10 dB of the noise.
    let stop = (peak..env.len()).find(|&i| db(env[i].1) <= db(noise) + LUNDEBY_ABOVE_NOISE_DB)?;
    let mut line = fit_line(env[peak..stop].iter().map(|&(t, m)| (t, db(m))))?;
    if line.slope >= 0.0 {
        return None;
    }
    // 4. Preliminary crossing point.
    let mut crossing_s = (db(noise) - line.intercept) / line.slope;
    // 5.-6. New intervals: LUNDEBY_INTERVALS_PER_10_DB per 10 dB of decay.
    let width_s = 10.0 / -line.slope / LUNDEBY_INTERVALS_PER_10_DB;
    let width = ((width_s / bin_s).round() as usize).clamp(1, max_width);
    let env = smooth(energy, bin_s, width);
    let peak = peak_index(&env);
    let mut result = None;
    for _ in 0..LUNDEBY_MAX_ITERATIONS {
        if !crossing_s.is_finite() {
            return None;
        }
        // 7. Noise from 10 dB of decay past the crossing point, or the last 10 %.
        let past_s = crossing_s + LUNDEBY_NOISE_AFTER_CROSSING_DB / -line.slope;
        let noise_start = ((past_s / bin_s).round().max(0.0) as usize).min(tail_start);
        let noise = mean(&energy[noise_start..]);
        if !(noise > 0.0 && noise.is_finite()) {
            return None;
        }
        let noise_db = db(noise);
        // 8. The late decay from 30 dB to 10 dB above the noise.
        let top = noise_db + LUNDEBY_ABOVE_NOISE_DB + LUNDEBY_FIT_RANGE_DB;
        let start = (peak..env.len()).find(|&i| db(env[i].1) < top).unwrap_or(peak);
        let stop = (start..env.len()).find(|&i| db(env[i].1) < noise_db + LUNDEBY_ABOVE_NOISE_DB)?;
        let late = fit_line(env[start..stop].iter().map(|&(t, m)| (t, db(m))))
            .or_else(|| fit_line(env[peak..stop].iter().map(|&(t, m)| (t, db(m)))))?;
        if late.slope >= 0.0 {
            return None;
        }
        line = late;
        // 9. New crossing point.
        let next = (noise_db - line.intercept) / line.slope;
        let moved = (next - crossing_s).abs();
        crossing_s = next;
        result = Some((noise, noise_start));
        if moved < bin_s {
            break;
        }
    }
    let (noise, noise_start) = result?;
    if !crossing_s.is_finite() {
        return None;
    }
    // Floor or decay: the line's continuation over the noise segment against its mean.
    let continuation = mean(
        &(noise_start..n)
            .map(|k| 10f64.powf((line.intercept + line.slope * (k as f64 + 0.5) * bin_s) / 10.0))
            .collect::<Vec<_>>(),
    );
    let floor = crossing_s < n as f64 * bin_s && noise > FLOOR_RATIO * continuation;
    Some(Lundeby {
        crossing_s,
        noise_per_bin: noise,
        noise_start,
        intercept_db: line.intercept,
        slope_db_per_s: line.slope,
        floor,
    })
}

/// The energy decay curve of one band as the metrics use it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct DecayCurve {
    /// Histogram time of the first value, s: the start of the bin holding the direct sound.
    pub start_s: f64,
    /// Spacing of the values, s.
    pub bin_s: f64,
    /// Decay curve in dB re its first value, one value per bin from `start_s`; minus infinity
    /// where nothing is left. With a noise floor it stops at the truncation point.
    pub edc_db: Vec<f64>,
    /// The integral at `start_s` (J/m^2): the energy of the decay, compensated when truncated.
    pub total: f64,
    /// Truncation point, s on the histogram's clock (see [`BandMetrics::truncation_s`]).
    pub truncation_s: Option<f64>,
    /// Mean noise energy per bin, when the decay ends in a floor.
    pub noise_per_bin: Option<f64>,
    /// See [`BandMetrics::dynamic_range_db`].
    pub dynamic_range_db: Option<f64>,
}

/// Index of the bin holding `direct_s`, within `len` bins (0 for a negative or non-finite time).
fn direct_bin(direct_s: f64, bin_s: f64, len: usize) -> usize {
    let t = if direct_s.is_finite() { direct_s.max(0.0) } else { 0.0 };
    ((t / bin_s).floor() as usize).min(len.saturating_sub(1))
}

/// The decay curve of `energy` (energy per bin, bins of `bin_s`) from the bin holding the
/// direct sound (`direct_s`) on. Where the histogram ends in a noise floor (Lundeby's
/// iteration finds one, see [`lundeby`]) the noise is subtracted from every bin before the
/// crossing point (Chu 1978, JASA 63, 1444-1450), the integration stops at the crossing point,
/// and the energy of the late decay line beyond it, `C = sum_{k>=k_c} 10^(L(t_k)/10)` (the
/// exponential extrapolation; ISO 3382-1:2009 5.3.3, Lundeby et al. 1995), is added to every
/// value: `E(t_k) = C + sum_{k<=j<k_c} (e_j - noise)`. This is the combined method Guski and
/// Vorlaender (2015, Acta Acustica u. A. 101) found least biased. Without a floor it is the
/// plain Schroeder integral (Schroeder 1965) to the end of the histogram.
pub fn decay_curve(energy: &[f64], bin_s: f64, direct_s: f64) -> DecayCurve {
    let mut out = DecayCurve { bin_s, ..DecayCurve::default() };
    if energy.is_empty() || !(bin_s > 0.0 && bin_s.is_finite()) {
        return out;
    }
    let first = direct_bin(direct_s, bin_s, energy.len());
    out.start_s = first as f64 * bin_s;
    let e = &energy[first..];
    let plain_total: f64 = e.iter().sum();
    if !(plain_total > 0.0 && plain_total.is_finite()) {
        out.edc_db = vec![f64::NEG_INFINITY; e.len()];
        return out;
    }
    let peak = e.iter().copied().fold(0.0f64, f64::max);
    let truncated = lundeby(e, bin_s).filter(|l| l.floor).and_then(|l| {
        let kc = ((l.crossing_s / bin_s).round().max(1.0) as usize).min(e.len());
        // The line's energy from bin kc on, a geometric series.
        let first_db = l.intercept_db + l.slope_db_per_s * (kc as f64 + 0.5) * bin_s;
        let ratio = 10f64.powf(l.slope_db_per_s * bin_s / 10.0);
        let tail = 10f64.powf(first_db / 10.0) / (1.0 - ratio);
        let mut acc = if tail.is_finite() && tail > 0.0 { tail } else { 0.0 };
        let mut integral = vec![0.0; kc];
        for k in (0..kc).rev() {
            acc += e[k] - l.noise_per_bin;
            integral[k] = acc;
        }
        // Noise subtraction cannot leave less than nothing at the start.
        (integral[0] > 0.0).then_some((integral, kc, l.noise_per_bin))
    });
    match truncated {
        Some((integral, kc, noise)) => {
            out.total = integral[0];
            out.edc_db = integral.iter().map(|&v| db(v / out.total)).collect();
            out.truncation_s = Some(out.start_s + kc as f64 * bin_s);
            out.noise_per_bin = Some(noise);
            out.dynamic_range_db = Some(db(peak / noise));
        }
        None => {
            out.total = plain_total;
            out.edc_db = schroeder_db(e);
            let width = ((LUNDEBY_FIRST_INTERVAL_S / bin_s).round() as usize).max(1);
            let lowest = smooth(e, bin_s, width)
                .iter()
                .map(|&(_, m)| m)
                .filter(|&m| m > 0.0)
                .fold(f64::INFINITY, f64::min);
            out.dynamic_range_db = lowest.is_finite().then(|| db(peak / lowest));
        }
    }
    out
}

/// Reference distance of the sound strength G, m (ISO 3382-1:2009 A.2.1).
pub const G_REFERENCE_DISTANCE_M: f64 = 10.0;

/// [`band_metrics_for_source`] for a source of energy 1 J (a histogram per joule emitted).
pub fn band_metrics(energy: &[f64], bin_s: f64, direct_s: f64) -> BandMetrics {
    band_metrics_for_source(energy, bin_s, direct_s, 1.0)
}

/// The parameters of one band. `energy[k]` is the energy fluence (J/m^2) arriving in
/// `[k * bin_s, (k+1) * bin_s)` from a source that emitted `source_energy_j` in the band;
/// `direct_s` is the arrival time of the direct sound. The early/late boundaries count from
/// the direct sound (ISO 3382-1 A.2.4) and the whole bin holding it counts as early, so all of
/// the direct sound is in the early energy for any `direct_s` within its bin: the early energy
/// is `E(t_d + 50 ms) - E(t_0)` with `t_0` the start of that bin and `E(t)` the energy arriving
/// before `t`, linear within the bin holding the boundary; the total is `E(inf) - E(t_0)`.
/// The centre time counts the direct sound's bin at `t_d` and every later bin at its centre:
/// `Ts = sum_k (t_k - t_d) e_k / sum_k e_k`.
pub fn band_metrics_for_source(
    energy: &[f64],
    bin_s: f64,
    direct_s: f64,
    source_energy_j: f64,
) -> BandMetrics {
    let total: f64 = energy.iter().sum();
    if energy.is_empty() || !(total.is_finite() && total > 0.0) || !(bin_s > 0.0 && bin_s.is_finite()) {
        return BandMetrics::default();
    }
    let first = direct_bin(direct_s, bin_s, energy.len());
    let t_d = if direct_s.is_finite() {
        direct_s.clamp(first as f64 * bin_s, (first + 1) as f64 * bin_s)
    } else {
        0.0
    };
    // Energy arriving before `t` (seconds), linear within bins.
    let before = |t: f64| -> f64 {
        let pos = (t / bin_s).max(0.0);
        let whole = (pos.floor() as usize).min(energy.len());
        let mut sum: f64 = energy[..whole].iter().sum();
        if whole < energy.len() {
            sum += energy[whole] * (pos - whole as f64);
        }
        sum
    };
    let before_first: f64 = energy[..first].iter().sum();
    let after = total - before_first;
    let early = |ms: f64| before(t_d + ms * 1e-3) - before_first;
    let e50 = early(50.0);
    let e80 = early(80.0);
    let clarity = |e: f64| (e > 0.0 && after - e > 0.0).then(|| 10.0 * (e / (after - e)).log10());
    let ts = {
        let num: f64 = energy
            .iter()
            .enumerate()
            .skip(first + 1)
            .map(|(k, e)| e * ((k as f64 + 0.5) * bin_s - t_d).max(0.0))
            .sum();
        (after > 0.0).then(|| 1e3 * num / after)
    };
    let curve = decay_curve(energy, bin_s, direct_s);
    let edc = &curve.edc_db;
    let (edt_s, _) = decay_time(decay_fit(edc, bin_s, 0.0, -10.0));
    let (t20_s, t20_r) = decay_time(decay_fit(edc, bin_s, -5.0, -25.0));
    let (t30_s, t30_r) = decay_time(decay_fit(edc, bin_s, -5.0, -35.0));
    let xi = |r: Option<f64>| r.map(|r| 1000.0 * (1.0 - r * r));
    let reference = source_energy_j / (4.0 * std::f64::consts::PI * G_REFERENCE_DISTANCE_M.powi(2));
    let fluence = before_first + curve.total;
    BandMetrics {
        edt_s,
        t20_s,
        t30_s,
        c50_db: clarity(e50),
        c80_db: clarity(e80),
        d50: (after > 0.0).then(|| e50 / after),
        ts_ms: ts,
        g_db: (reference > 0.0 && reference.is_finite() && fluence > 0.0).then(|| db(fluence / reference)),
        truncation_s: curve.truncation_s,
        dynamic_range_db: curve.dynamic_range_db,
        t20_r,
        t30_r,
        t20_xi_permille: xi(t20_r),
        t30_xi_permille: xi(t30_r),
        curvature_percent: t30_s.zip(t20_s).map(|(t30, t20)| 100.0 * (t30 / t20 - 1.0)),
    }
}

/// Detections per millisecond below which a pair's parameters are flagged. The project's
/// receiver-radius rule aims at ten per 1 ms bin in the diffuse field; at that rate the 50 ms
/// early window of C50 and D50 holds about 500 detections, a relative standard error of
/// 1/sqrt(500) = 4.5 % (0.2 dB on C50 and C80, a fifth of the 1 dB just-noticeable difference
/// of ISO 3382-1 Table A.1), and one 1 ms bin about 1/sqrt(10) = 32 %. Below it the early
/// parameters' Monte-Carlo scatter nears their just-noticeable differences.
pub const MIN_DETECTIONS_PER_MS: f64 = 10.0;

/// Warnings about one source-receiver pair: `distance_m` apart, with `detections` ray
/// detections at the receiver over `span_s` seconds of histogram (e.g. from the direct sound
/// to the end of the decay). Warns when the receiver is within 1 m of the source (the near
/// field of a real source, and a direct sound that dominates every parameter), and when the
/// detections average fewer than [`MIN_DETECTIONS_PER_MS`] per millisecond.
pub fn pair_warnings(distance_m: f64, detections: u64, span_s: f64) -> Vec<String> {
    let mut out = Vec::new();
    if distance_m.is_finite() && distance_m < 1.0 {
        out.push(format!("receiver within 1 m of the source ({distance_m:.2} m)"));
    }
    let span_ms = if span_s.is_finite() { (span_s * 1e3).max(1.0) } else { 1.0 };
    if (detections as f64) < MIN_DETECTIONS_PER_MS * span_ms {
        out.push(format!("few detections ({detections}): increase --rays or the receiver radius"));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::rng::{stream, uniform};

    /// Exactly integrated energy of an exponential decay with reverberation time `t60`.
    fn exponential(t60: f64, bin_s: f64, len_s: f64) -> Vec<f64> {
        let k = 6.0 * std::f64::consts::LN_10 / t60; // energy decay rate, 1/s
        let n = (len_s / bin_s).round() as usize;
        (0..n).map(|i| ((-k * i as f64 * bin_s).exp() - (-k * (i + 1) as f64 * bin_s).exp()) / k).collect()
    }

    #[test]
    fn ideal_single_slope_decay_t1() {
        // docs/acoustics.md, Reference values: T = 1 s -> EDT = T20 = T30 = 1 s, C80 = 3.053 dB,
        // C50 = -0.021 dB, D50 = 0.4988, Ts = 72.38 ms. 4 s long so truncation is negligible.
        let e = exponential(1.0, 1e-3, 4.0);
        let m = band_metrics(&e, 1e-3, 0.0);
        for t in [m.edt_s, m.t20_s, m.t30_s] {
            assert!((t.unwrap() - 1.0).abs() < 0.005, "{m:?}");
        }
        assert!((m.c80_db.unwrap() - 3.053).abs() < 0.005, "{m:?}");
        assert!((m.c50_db.unwrap() + 0.021).abs() < 0.005, "{m:?}");
        assert!((m.d50.unwrap() - 0.4988).abs() < 0.0005, "{m:?}");
        assert!((m.ts_ms.unwrap() - 72.38).abs() < 0.1, "{m:?}");
    }

    #[test]
    fn ideal_decay_t2_and_a_late_direct_sound() {
        // T = 2 s: C80 = -1.321 dB, D50 = 0.2921. The direct sound at 12 ms shifts the
        // boundaries but not the values.
        let mut e = vec![0.0; 12];
        e.extend(exponential(2.0, 1e-3, 8.0));
        let m = band_metrics(&e, 1e-3, 0.012);
        assert!((m.c80_db.unwrap() + 1.321).abs() < 0.005, "{m:?}");
        assert!((m.d50.unwrap() - 0.2921).abs() < 0.0005, "{m:?}");
        assert!((m.t30_s.unwrap() - 2.0).abs() < 0.01, "{m:?}");
    }

    #[test]
    fn silence_and_short_decays_give_none() {
        assert_eq!(band_metrics(&[0.0; 100], 1e-3, 0.0), BandMetrics::default());
        // A single bin has no decay to fit.
        let m = band_metrics(&[1.0], 1e-3, 0.0);
        assert!(m.t30_s.is_none() && m.edt_s.is_none() && m.d50 == Some(1.0));
        let edc = schroeder_db(&[1.0, 1.0, 0.0]);
        assert!((edc[0] - 0.0).abs() < 1e-12 && (edc[1] + 3.0103).abs() < 1e-3);
    }

    #[test]
    fn bad_input_gives_none_not_a_panic() {
        let e = exponential(1.0, 1e-3, 2.0);
        for (bin, direct) in
            [(0.0, 0.0), (-1e-3, 0.0), (f64::NAN, 0.0), (1e-3, f64::NAN), (1e-3, -5.0), (1e-3, 1e9)]
        {
            let _ = band_metrics(&e, bin, direct);
        }
        assert_eq!(band_metrics(&[1.0, f64::NAN], 1e-3, 0.0), BandMetrics::default());
        assert_eq!(band_metrics(&[1.0, f64::INFINITY], 1e-3, 0.0), BandMetrics::default());
        assert_eq!(band_metrics(&[], 1e-3, 0.0), BandMetrics::default());
        assert!(band_metrics_for_source(&e, 1e-3, 0.0, 0.0).g_db.is_none());
        assert!(band_metrics_for_source(&e, 1e-3, 0.0, f64::NAN).g_db.is_none());
    }

    /// An exponential decay with T = `t60` whose first bin holds `peak` J/m^2, plus a constant
    /// floor `floor_db` below that bin, `len_s` long.
    fn decay_with_floor(t60: f64, len_s: f64, floor_db: f64) -> (Vec<f64>, f64) {
        let e = exponential(t60, 1e-3, len_s);
        let floor = e[0] * 10f64.powf(floor_db / 10.0);
        (e.iter().map(|v| v + floor).collect(), floor)
    }

    /// Time (s) where an exponential decay of T = `t60` whose first bin is `e0` falls to `level`.
    fn crossing_time(t60: f64, e0: f64, level: f64) -> f64 {
        -(level / e0).log10() * 10.0 / (60.0 / t60)
    }

    #[test]
    fn a_noise_floor_is_truncated_and_compensated() {
        // T = 1 s and a constant floor 50 or 40 dB below the first bin, 2 s long (the floor
        // alone in the last 1.2 s): without Lundeby's truncation the plain Schroeder curve
        // bends into the floor (T30 more than 5 % long); with it T20, T30 and EDT are within
        // 2 % of 1 s, and the truncation point is near the true crossing.
        for floor_db in [-50.0, -40.0] {
            let (e, floor) = decay_with_floor(1.0, 2.0, floor_db);
            let plain = schroeder_db(&e);
            let plain_t30 = decay_time(decay_fit(&plain, 1e-3, -5.0, -35.0)).0.unwrap();
            assert!(plain_t30 > 1.05, "{floor_db} dB: plain T30 {plain_t30}");
            let m = band_metrics(&e, 1e-3, 0.0);
            for (name, t) in [("EDT", m.edt_s), ("T20", m.t20_s), ("T30", m.t30_s)] {
                let t = t.unwrap_or_else(|| panic!("{floor_db} dB: no {name}: {m:?}"));
                assert!((t - 1.0).abs() < 0.02, "{floor_db} dB: {name} {t}: {m:?}");
            }
            let cross = crossing_time(1.0, e[0] - floor, floor);
            let tc = m.truncation_s.unwrap();
            assert!((tc - cross).abs() < 0.05, "{floor_db} dB: truncation {tc} vs crossing {cross}");
            // Peak bin to floor: the floor's level re the first bin (which includes it).
            let range = m.dynamic_range_db.unwrap();
            assert!((range + floor_db).abs() < 0.1, "{floor_db} dB: range {range}");
            // The fits of a straight decay are straight: r near -1, xi and C near 0.
            assert!(m.t30_r.unwrap() < -0.999 && m.t30_xi_permille.unwrap() < 2.0, "{m:?}");
            assert!(m.curvature_percent.unwrap().abs() < 2.0, "{m:?}");
        }
    }

    #[test]
    fn a_clean_decay_is_not_truncated() {
        // No floor: the plain Schroeder integral, unchanged, and the range down to the end.
        let e = exponential(1.0, 1e-3, 4.0);
        let found = lundeby(&e, 1e-3).unwrap();
        assert!(!found.floor, "{found:?}");
        let curve = decay_curve(&e, 1e-3, 0.0);
        assert_eq!(curve.truncation_s, None);
        assert_eq!(curve.edc_db, schroeder_db(&e));
        let m = band_metrics(&e, 1e-3, 0.0);
        assert_eq!(m.truncation_s, None);
        // Over 4 s the decay falls 240 dB: the lowest 10 ms mean is centred 5 ms before the
        // end, 239.7 dB below the first bin.
        assert!((m.dynamic_range_db.unwrap() - 239.7).abs() < 0.1, "{m:?}");
        // A decay that ends in silence (empty tail bins) has no noise to find.
        let mut silent_tail = exponential(0.5, 1e-3, 1.0);
        silent_tail.extend(vec![0.0; 500]);
        assert!(lundeby(&silent_tail, 1e-3).is_none());
        assert_eq!(decay_curve(&silent_tail, 1e-3, 0.0).edc_db, schroeder_db(&silent_tail));
    }

    #[test]
    fn a_noisy_decay_with_a_random_floor() {
        // Monte-Carlo-like data (seeded): every bin of a T = 0.8 s decay scaled by a random
        // factor of mean 1 (uniform in [0.5, 1.5]), plus a sparse floor 45 dB below the first
        // bin: each bin holds a detection with probability 0.2, of 5 times the floor's mean.
        // T20 and T30 within 3 % of 0.8 s (the scatter of the noise averages over the fitted
        // 0.1-0.5 s), truncation within 60 ms of the crossing of decay and floor mean.
        let t60 = 0.8;
        for seed in 0..4u64 {
            let mut rng = stream(seed, 0x4e015e, 0);
            let clean = exponential(t60, 1e-3, 1.5);
            let floor = clean[0] * 10f64.powf(-4.5);
            let e: Vec<f64> = clean
                .iter()
                .map(|&v| {
                    let scale = 0.5 + f64::from(uniform(&mut rng));
                    let spike = if uniform(&mut rng) < 0.2 { 5.0 * floor } else { 0.0 };
                    v * scale + spike
                })
                .collect();
            let m = band_metrics(&e, 1e-3, 0.0);
            for (name, t) in [("T20", m.t20_s), ("T30", m.t30_s)] {
                let t = t.unwrap();
                assert!((t - t60).abs() / t60 < 0.03, "seed {seed}: {name} {t}: {m:?}");
            }
            let cross = crossing_time(t60, clean[0], floor);
            let tc = m.truncation_s.unwrap();
            assert!((tc - cross).abs() < 0.06, "seed {seed}: truncation {tc} vs crossing {cross}");
        }
    }

    /// A direct sound `ed` at `t_d` and an exponential tail of total `er` and decay rate `k`
    /// (1/s) starting at `t_d`, integrated exactly over 1 ms bins.
    fn direct_and_tail(t_d: f64, ed: f64, er: f64, k: f64, len_s: f64) -> Vec<f64> {
        let bin = 1e-3;
        let n = (len_s / bin).round() as usize;
        let above = |t: f64| er * (-k * (t - t_d).max(0.0)).exp(); // tail energy after t
        let mut e: Vec<f64> = (0..n)
            .map(|j| {
                if (j + 1) as f64 * bin <= t_d {
                    0.0
                } else {
                    above(j as f64 * bin) - above((j + 1) as f64 * bin)
                }
            })
            .collect();
        e[(t_d / bin).floor() as usize] += ed;
        e
    }

    #[test]
    fn early_parameters_count_the_whole_direct_sound_for_any_offset_in_its_bin() {
        // Closed forms for a direct sound Ed at t_d and a tail Er k exp(-k (t - t_d)):
        // E(t_d..t_d+tau) = Ed + Er (1 - exp(-k tau)), late = Er exp(-k tau),
        // Ts = (Er / k) / (Ed + Er).
        let k = 6.0 * std::f64::consts::LN_10 / 1.0; // T = 1 s
        let (ed, er) = (0.5, 1.0);
        let early = |tau: f64| ed + er * (1.0 - (-k * tau).exp());
        let late = |tau: f64| er * (-k * tau).exp();
        let c50 = 10.0 * (early(0.05) / late(0.05)).log10();
        let c80 = 10.0 * (early(0.08) / late(0.08)).log10();
        let d50 = early(0.05) / (ed + er);
        let ts_ms = 1e3 * (er / k) / (ed + er);
        for t_d_ms in [12.0, 12.3, 12.5, 12.97] {
            let t_d = t_d_ms * 1e-3;
            let e = direct_and_tail(t_d, ed, er, k, 4.0);
            let m = band_metrics(&e, 1e-3, t_d);
            assert!((m.c50_db.unwrap() - c50).abs() < 1e-3, "{t_d_ms} ms: C50 {m:?} vs {c50}");
            assert!((m.c80_db.unwrap() - c80).abs() < 1e-3, "{t_d_ms} ms: C80 {m:?} vs {c80}");
            assert!((m.d50.unwrap() - d50).abs() < 1e-4, "{t_d_ms} ms: D50 {m:?} vs {d50}");
            // The tail inside the direct sound's bin counts at t_d: at most k (1 ms)^2 / 2
            // Er / (Ed + Er) = 0.005 ms early.
            assert!((m.ts_ms.unwrap() - ts_ms).abs() < 0.01, "{t_d_ms} ms: Ts {m:?} vs {ts_ms}");
        }
    }

    #[test]
    fn sound_strength_against_closed_forms() {
        // Free field, direct sound only at d: G = 20 log10(10 / d), for any source energy.
        for (d, source_j) in [(1.0, 1.0), (5.0, 1.0), (10.0, 2.0), (23.0, 0.1)] {
            let c = 343.0;
            let mut e = vec![0.0; 200];
            e[(d / c / 1e-3) as usize] = source_j / (4.0 * std::f64::consts::PI * d * d);
            let m = band_metrics_for_source(&e, 1e-3, d / c, source_j);
            let want = 20.0 * (10.0 / d).log10();
            assert!((m.g_db.unwrap() - want).abs() < 1e-9, "d {d}: {m:?} vs {want}");
        }
        // Diffuse field (Barron 1988): an impulse E in a room of volume V and reverberation
        // time T gives the reverberant fluence E c T / (6 ln 10 V), so
        // G = 10 log10(100 / d^2 + 4 pi 100 c T / (6 ln 10 V)) (= 100/d^2 + 31200 T/V, c = 343).
        let (d, c, v, t60) = (8.0, 343.0, 2000.0, 1.6);
        let k = 6.0 * std::f64::consts::LN_10 / t60;
        let er = c * t60 / (6.0 * std::f64::consts::LN_10 * v);
        let ed = 1.0 / (4.0 * std::f64::consts::PI * d * d);
        let e = direct_and_tail(d / c, ed, er, k, 8.0 * t60);
        let m = band_metrics(&e, 1e-3, d / c);
        let want = 10.0
            * (100.0 / (d * d)
                + 400.0 * std::f64::consts::PI * c * t60 / (6.0 * std::f64::consts::LN_10 * v))
                .log10();
        assert!((m.g_db.unwrap() - want).abs() < 1e-6, "{m:?} vs {want}");
        assert!((want - 10.0 * (100.0 / (d * d) + 31_200.0 * t60 / v).log10()).abs() < 0.01);
    }

    #[test]
    fn a_double_slope_decay_shows_curvature() {
        // Two exponentials, T = 0.5 s and T = 2 s, the slow one 20 dB below at the start: the
        // T30 fit is not a straight line, T30 > T20, so C > 0 and xi grows.
        let fast = exponential(0.5, 1e-3, 6.0);
        let slow = exponential(2.0, 1e-3, 6.0);
        let e: Vec<f64> = fast.iter().zip(&slow).map(|(a, b)| a + 0.01 * b * fast[0] / slow[0]).collect();
        let m = band_metrics(&e, 1e-3, 0.0);
        assert!(m.curvature_percent.unwrap() > 10.0, "{m:?}");
        assert!(m.t30_xi_permille.unwrap() > m.t20_xi_permille.unwrap(), "{m:?}");
        let straight = band_metrics(&exponential(0.5, 1e-3, 3.0), 1e-3, 0.0);
        assert!(straight.curvature_percent.unwrap().abs() < 0.5, "{straight:?}");
        assert!(straight.t30_xi_permille.unwrap() < 0.01, "{straight:?}");
    }

    #[test]
    fn warnings_for_close_receivers_and_few_detections() {
        assert!(pair_warnings(5.0, 50_000, 1.0).is_empty());
        let w = pair_warnings(0.6, 50_000, 1.0);
        assert_eq!(w.len(), 1);
        assert!(w[0].contains("within 1 m"), "{w:?}");
        // 9 999 detections over 1 s is fewer than 10 per ms; 10 000 is not.
        let w = pair_warnings(3.0, 9_999, 1.0);
        assert_eq!(w, vec!["few detections (9999): increase --rays or the receiver radius".to_string()]);
        assert!(pair_warnings(3.0, 10_000, 1.0).is_empty());
        assert_eq!(pair_warnings(0.2, 0, 0.5).len(), 2);
        // Nonsense spans or distances do not panic.
        let _ = pair_warnings(f64::NAN, 0, f64::NAN);
        let _ = pair_warnings(-1.0, u64::MAX, f64::INFINITY);
    }
}
