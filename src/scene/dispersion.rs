//! Dispersion of a glass: its index of refraction as a function of wavelength, by the
//! Sellmeier equation (three terms, as glass catalogues give it) or by Cauchy's two-term law
//! fitted to an index `n_d` and an Abbe number `V_d`. Only the spectral integrator sees the
//! variation ([`crate::render::spectral`]); the RGB integrators use `n_d`.

/// Wavelength of the helium d line, nm: where `n_d` (a material's `ior`) is given.
pub const D_LINE_NM: f64 = 587.56;
/// Wavelength of the hydrogen F line, nm (the blue end of the Abbe number).
pub const F_LINE_NM: f64 = 486.13;
/// Wavelength of the hydrogen C line, nm (the red end of the Abbe number).
pub const C_LINE_NM: f64 = 656.27;

/// How a glass's index varies with wavelength.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Dispersion {
    /// The Sellmeier equation `n^2 = 1 + sum_i B_i l^2 / (l^2 - C_i)`, `l` in micrometres
    /// (Sellmeier 1871; the form of the Schott catalogue).
    Sellmeier {
        /// The dimensionless coefficients `B_1..B_3`.
        b: [f64; 3],
        /// The resonance coefficients `C_1..C_3`, um^2.
        c_um2: [f64; 3],
    },
    /// Cauchy's law `n = A + B / l^2`, `l` in micrometres (Cauchy 1836).
    Cauchy {
        /// `A`, dimensionless.
        a: f64,
        /// `B`, um^2.
        b_um2: f64,
    },
}

impl Dispersion {
    /// The Sellmeier law, checked: every coefficient finite and each `C_i >= 0`; the index at
    /// the d line must come out real and at least 1 (a law with a resonance inside the visible
    /// range does not). The error is one line naming the bad key.
    pub fn sellmeier(b: [f64; 3], c_um2: [f64; 3]) -> Result<Self, String> {
        if let Some(x) = b.iter().find(|x| !x.is_finite()) {
            return Err(format!("sellmeier_b {x}: every coefficient must be a finite number"));
        }
        if let Some(x) = c_um2.iter().find(|x| !(x.is_finite() && **x >= 0.0)) {
            return Err(format!("sellmeier_c {x}: every coefficient must be a finite number >= 0 (um^2)"));
        }
        let law = Self::Sellmeier { b, c_um2 };
        for nm in [380.0, D_LINE_NM, 780.0] {
            let n = law.index_at(nm);
            if !(n.is_finite() && n >= 1.0) {
                return Err(format!(
                    "sellmeier_b/sellmeier_c give no index >= 1 at {nm} nm (a resonance C_i inside the visible range?)"
                ));
            }
        }
        Ok(law)
    }

    /// Cauchy's law through `n_d` at the d line with Abbe number `V_d = (n_d - 1) / (n_F - n_C)`:
    /// `B = (n_d - 1) / (V_d (1/l_F^2 - 1/l_C^2))`, `A = n_d - B / l_d^2`.
    pub fn from_abbe(n_d: f64, abbe_number: f64) -> Result<Self, String> {
        if !(abbe_number.is_finite() && abbe_number > 0.0) {
            return Err(format!("abbe_number {abbe_number}: must be a finite number > 0"));
        }
        if !(n_d.is_finite() && n_d >= 1.0) {
            return Err(format!("ior {n_d}: must be >= 1 for abbe_number"));
        }
        let inv2 = |nm: f64| 1.0 / (nm * 1e-3).powi(2);
        let b_um2 = (n_d - 1.0) / (abbe_number * (inv2(F_LINE_NM) - inv2(C_LINE_NM)));
        Ok(Self::Cauchy { a: n_d - b_um2 * inv2(D_LINE_NM), b_um2 })
    }

    /// The index of refraction at `wavelength_nm` (vacuum wavelength).
    pub fn index_at(&self, wavelength_nm: f64) -> f64 {
        let l2 = (wavelength_nm * 1e-3).powi(2);
        match *self {
            Self::Sellmeier { b, c_um2 } => {
                let sum: f64 = b.iter().zip(c_um2).map(|(b, c)| b * l2 / (l2 - c)).sum();
                (1.0 + sum).sqrt()
            }
            Self::Cauchy { a, b_um2 } => a + b_um2 / l2,
        }
    }

    /// The Abbe number `(n_d - 1) / (n_F - n_C)` the law gives.
    pub fn abbe_number(&self) -> f64 {
        (self.index_at(D_LINE_NM) - 1.0) / (self.index_at(F_LINE_NM) - self.index_at(C_LINE_NM))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Schott's N-BK7 data sheet: B = 1.03961212, 0.231792344, 1.01046945; C = 0.00600069867,
    /// 0.0200179144, 103.560653 um^2; catalogue n_d = 1.5168, V_d = 64.17.
    #[test]
    fn sellmeier_reproduces_the_bk7_catalogue() {
        let bk7 = Dispersion::sellmeier(
            [1.039_612_12, 0.231_792_344, 1.010_469_45],
            [0.006_000_698_67, 0.020_017_914_4, 103.560_653],
        )
        .unwrap();
        assert!((bk7.index_at(D_LINE_NM) - 1.5168).abs() < 5e-5, "{}", bk7.index_at(D_LINE_NM));
        assert!((bk7.abbe_number() - 64.17).abs() < 0.05, "{}", bk7.abbe_number());
    }

    #[test]
    fn the_abbe_fit_keeps_n_d_and_the_abbe_number() {
        let law = Dispersion::from_abbe(1.5168, 64.17).unwrap();
        let (nd, nf, nc) = (law.index_at(D_LINE_NM), law.index_at(F_LINE_NM), law.index_at(C_LINE_NM));
        assert!((nd - 1.5168).abs() < 1e-12);
        assert!(((nf - nc) - 0.5168 / 64.17).abs() < 1e-12);
        // Normal dispersion: blue bends more.
        assert!(law.index_at(400.0) > law.index_at(700.0));
    }

    #[test]
    fn bad_coefficients_are_refused_in_one_line() {
        for (b, c, key) in [
            ([1.0, f64::NAN, 0.0], [0.0; 3], "sellmeier_b"),
            ([1.0, 0.0, 0.0], [-0.01, 0.0, 0.0], "sellmeier_c"),
            ([1.0, 0.0, 0.0], [f64::INFINITY, 0.0, 0.0], "sellmeier_c"),
            ([1.0, 0.0, 0.0], [0.3, 0.0, 0.0], "resonance"),
        ] {
            let e = Dispersion::sellmeier(b, c).unwrap_err();
            assert!(e.contains(key) && !e.contains('\n'), "{e}");
        }
        for v in [0.0, -3.0, f64::NAN, f64::INFINITY] {
            assert!(Dispersion::from_abbe(1.5, v).unwrap_err().contains("abbe_number"));
        }
    }
}
