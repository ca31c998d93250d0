//! Sound in air: speed of sound and atmospheric absorption after ISO 9613-1:1993.

use crate::scene::materials::{BAND_COUNT, BandValues};

/// Reference pressure p_r, kPa (ISO 9613-1 sec. 6.1).
const P_REF_KPA: f64 = 101.325;
/// Reference temperature T0, K (ISO 9613-1 sec. 6.1).
const T0_K: f64 = 293.15;
/// Triple-point isotherm temperature T01, K (ISO 9613-1 annex B).
const T01_K: f64 = 273.16;

/// Exact octave midband frequencies, Hz: 1000 x 10^(3k/10) for k = -4..3 (IEC 61260-1, base
/// 10), whose nominal names are 63 Hz .. 8 kHz. ISO 9613-1's tables use these.
pub fn exact_octave_midbands_hz() -> [f64; BAND_COUNT] {
    std::array::from_fn(|i| 1000.0 * 10f64.powf(0.3 * (i as f64 - 4.0)))
}

/// Atmospheric conditions.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Air {
    /// Temperature, degrees Celsius.
    pub temperature_c: f64,
    /// Relative humidity, percent.
    pub relative_humidity_percent: f64,
    /// Atmospheric pressure, kPa.
    pub pressure_kpa: f64,
}

impl Default for Air {
    /// 20 C, 50 % relative humidity, 101.325 kPa.
    fn default() -> Self {
        Self { temperature_c: 20.0, relative_humidity_percent: 50.0, pressure_kpa: P_REF_KPA }
    }
}

impl Air {
    /// Checks the ranges over which ISO 9613-1 is stated (-20..50 C, 10..100 % RH, and a
    /// generous pressure range), returning a one-line reason otherwise.
    pub fn validate(&self) -> Result<(), String> {
        if !(-20.0..=50.0).contains(&self.temperature_c) {
            return Err(format!("temperature {} C is outside -20..50 C", self.temperature_c));
        }
        if !(0.0..=100.0).contains(&self.relative_humidity_percent) {
            return Err(format!(
                "relative humidity {} % is outside 0..100 %",
                self.relative_humidity_percent
            ));
        }
        if !(50.0..=120.0).contains(&self.pressure_kpa) {
            return Err(format!("pressure {} kPa is outside 50..120 kPa", self.pressure_kpa));
        }
        Ok(())
    }

    /// Speed of sound, m/s: c = 343.2 sqrt(T / 293.15), the ideal-gas scaling of ISO 9613-1's
    /// reference value at 20 C.
    pub fn speed_of_sound_m_s(&self) -> f64 {
        343.2 * ((self.temperature_c + 273.15) / T0_K).sqrt()
    }

    /// Pure-tone attenuation coefficient alpha in dB/m at `freq_hz` (ISO 9613-1 eq. 5, with
    /// the relaxation frequencies of eqs. 3 and 4 and the humidity of annex B).
    pub fn attenuation_db_per_m(&self, freq_hz: f64) -> f64 {
        let t = self.temperature_c + 273.15;
        let pa = self.pressure_kpa / P_REF_KPA;
        let psat = 10f64.powf(-6.8346 * (T01_K / t).powf(1.261) + 4.6151);
        let h = self.relative_humidity_percent * psat / pa;
        let fr_o = pa * (24.0 + 4.04e4 * h * (0.02 + h) / (0.391 + h));
        let fr_n = pa
            * (t / T0_K).powf(-0.5)
            * (9.0 + 280.0 * h * (-4.170 * ((t / T0_K).powf(-1.0 / 3.0) - 1.0)).exp());
        let f2 = freq_hz * freq_hz;
        8.686
            * f2
            * (1.84e-11 / pa * (t / T0_K).sqrt()
                + (t / T0_K).powf(-2.5)
                    * (0.01275 * (-2239.1 / t).exp() / (fr_o + f2 / fr_o)
                        + 0.1068 * (-3352.0 / t).exp() / (fr_n + f2 / fr_n)))
    }

    /// Energy attenuation coefficient m in 1/m per octave band (at the exact midband):
    /// energy decays as exp(-m d); m = alpha / (10 log10 e) (ISO 9613-1; Kuttruff, Room
    /// Acoustics, eq. 4.19).
    pub fn energy_coefficient_per_m(&self) -> BandValues {
        let mut m = [0.0f32; BAND_COUNT];
        for (v, f) in m.iter_mut().zip(exact_octave_midbands_hz()) {
            *v = (self.attenuation_db_per_m(f) / (10.0 * std::f64::consts::LOG10_E)) as f32;
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn check(air: Air, expected_db_per_km: [f64; 8]) {
        for (f, e) in exact_octave_midbands_hz().iter().zip(expected_db_per_km) {
            let got = air.attenuation_db_per_m(*f) * 1000.0;
            // The published table rounds to 3 significant figures.
            assert!((got - e).abs() <= 0.006 * e + 0.001, "{f} Hz: {got} dB/km, expected {e}");
        }
    }

    #[test]
    fn iso_9613_1_test_values_20c_50_and_70_percent() {
        // docs/acoustics.md, Reference values (ISO 9613-1 Table 1 at the octave centres).
        let mut air = Air::default();
        check(air, [0.123, 0.445, 1.32, 2.73, 4.66, 9.86, 29.4, 104.0]);
        air.relative_humidity_percent = 70.0;
        check(air, [0.090, 0.339, 1.13, 2.80, 4.98, 9.02, 22.9, 76.6]);
    }

    #[test]
    fn speed_of_sound_and_energy_coefficient() {
        let air = Air::default();
        assert!((air.speed_of_sound_m_s() - 343.2).abs() < 1e-9);
        let m = air.energy_coefficient_per_m();
        // 4 kHz: 29.4 dB/km -> m = 0.0294 / 4.343 = 6.77e-3 1/m.
        assert!((m[6] - 0.0294 / 4.3429).abs() < 5e-5, "{}", m[6]);
        assert!((exact_octave_midbands_hz()[1] - 125.89).abs() < 0.01);
        assert!(Air { temperature_c: 80.0, ..air }.validate().is_err());
    }
}
