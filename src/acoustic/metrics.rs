//! Room-acoustic parameters of ISO 3382-1:2009 from an energy histogram of one band:
//! the Schroeder decay curve, EDT, T20, T30, C50, C80, D50 and the centre time Ts.

use serde::Serialize;

/// ISO 3382-1 parameters of one band. Times in seconds except `ts_ms`.
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

/// Least-squares slope (dB/s) of the decay curve between `hi_db` and `lo_db` (e.g. -5 and
/// -25), times `t_k = k * bin_s`; `None` when the curve never reaches `lo_db`.
fn decay_fit_slope(edc: &[f64], bin_s: f64, hi_db: f64, lo_db: f64) -> Option<f64> {
    let start = edc.iter().position(|&v| v <= hi_db)?;
    let end = edc.iter().position(|&v| v <= lo_db)?;
    if end <= start + 1 {
        return None;
    }
    let pts: Vec<(f64, f64)> = (start..=end).map(|k| (k as f64 * bin_s, edc[k])).collect();
    let n = pts.len() as f64;
    let (sx, sy) = pts.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + x, b + y));
    let (mx, my) = (sx / n, sy / n);
    let (sxy, sxx) =
        pts.iter().fold((0.0, 0.0), |(a, b), (x, y)| (a + (x - mx) * (y - my), b + (x - mx) * (x - mx)));
    (sxx > 0.0).then(|| sxy / sxx)
}

/// Decay time extrapolated to 60 dB from the fit between `hi_db` and `lo_db`.
fn decay_time(edc: &[f64], bin_s: f64, hi_db: f64, lo_db: f64) -> Option<f64> {
    let slope = decay_fit_slope(edc, bin_s, hi_db, lo_db)?;
    (slope < 0.0).then(|| -60.0 / slope)
}

/// The parameters of one band. `energy[k]` is the energy arriving in
/// `[k * bin_s, (k+1) * bin_s)`; `direct_s` is the arrival time of the direct sound, from which
/// the early/late boundaries count (ISO 3382-1 A.2.4). Energy in the bin containing the
/// boundary is split in proportion to time.
pub fn band_metrics(energy: &[f64], bin_s: f64, direct_s: f64) -> BandMetrics {
    let total: f64 = energy.iter().sum();
    if total.is_nan() || total <= 0.0 || energy.is_empty() {
        return BandMetrics::default();
    }
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
    let early = |ms: f64| before(direct_s + ms * 1e-3) - before(direct_s);
    let after_direct = total - before(direct_s);
    let e50 = early(50.0);
    let e80 = early(80.0);
    let clarity =
        |e: f64| (e > 0.0 && after_direct - e > 0.0).then(|| 10.0 * (e / (after_direct - e)).log10());
    let ts = {
        let first = (direct_s / bin_s).floor() as usize;
        let mut num = 0.0;
        for (k, e) in energy.iter().enumerate().skip(first) {
            let mid = (k as f64 + 0.5) * bin_s;
            num += e * (mid - direct_s).max(0.0);
        }
        (after_direct > 0.0).then(|| 1e3 * num / after_direct)
    };
    // The decay curve from the direct sound on.
    let first = (direct_s / bin_s).floor() as usize;
    let edc = schroeder_db(&energy[first.min(energy.len() - 1)..]);
    BandMetrics {
        edt_s: decay_time(&edc, bin_s, 0.0, -10.0),
        t20_s: decay_time(&edc, bin_s, -5.0, -25.0),
        t30_s: decay_time(&edc, bin_s, -5.0, -35.0),
        c50_db: clarity(e50),
        c80_db: clarity(e80),
        d50: (after_direct > 0.0).then(|| e50 / after_direct),
        ts_ms: ts,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Exactly integrated energy of an exponential decay with reverberation time `t60`.
    fn exponential(t60: f64, bin_s: f64, len_s: f64) -> Vec<f64> {
        let k = 6.0 * std::f64::consts::LN_10 / t60; // energy decay rate, 1/s
        let n = (len_s / bin_s).round() as usize;
        (0..n).map(|i| ((-k * i as f64 * bin_s).exp() - (-k * (i + 1) as f64 * bin_s).exp()) / k).collect()
    }

    #[test]
    fn ideal_single_slope_decay_t1() {
        // ../shared/DESIGN.md sec. 3: T = 1 s -> EDT = T20 = T30 = 1 s, C80 = 3.053 dB,
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
        // T = 2 s: C80 = -1.321 dB, D50 = 0.2921. The direct sound at 12.3 ms shifts the
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
}
